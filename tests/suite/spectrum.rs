//! Motion spectra, peaks and damping (issue 5, thesis ch. 3.3 and 5):
//! a simulated cantilever under random excitation against its known modes
//! and damping ratios, a real guitar recording against its strings, the
//! sliding (live) spectrum on the shipped pipeline, and bad input.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use vibroscope_engine::stages::transform::spectrum::{SegmentFft, Taper, TaperExt};
use vibroscope_math::peaks::{find_peaks, PeakOptions};

/// Thesis Table 5.5: the cantilever beam's first three modes (Hz), with
/// damping ratios of our choosing in the 0.002-0.02 range.
const MODES_HZ: [f64; 3] = [7.3, 58.3, 128.0];
const DAMPING: [f64; 3] = [0.02, 0.01, 0.005];
/// Gains of the shared force into each mode (modal participation).
const GAINS: [f64; 3] = [0.3, 1.0, 1.0];
const FPS: f64 = 300.0;

/// SplitMix64 and Box-Muller: a seeded white Gaussian force.
struct Gauss(u64);
impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// Displacement of a beam whose modes are driven by one white random force:
/// per mode a second-order section with poles r e^{±iωd/fs},
/// r = e^{-ξ ωn / fs}, ωd = ωn √(1-ξ²) (the exact discrete image of a
/// damped oscillator's poles, so its spectral peak has half width ξ fn).
fn beam_motion(seed: u64, n: usize) -> Vec<f32> {
    let mut force = Gauss(seed);
    let warm = (20.0 * FPS / (DAMPING[0] * 2.0 * std::f64::consts::PI * MODES_HZ[0])) as usize;
    let mut state = [[0.0f64; 2]; 3];
    let coef: Vec<(f64, f64)> = MODES_HZ
        .iter()
        .zip(DAMPING)
        .map(|(&f, xi)| {
            let wn = 2.0 * std::f64::consts::PI * f;
            let r = (-xi * wn / FPS).exp();
            let wd = wn * (1.0 - xi * xi).sqrt();
            (2.0 * r * (wd / FPS).cos(), -r * r)
        })
        .collect();
    let mut out = Vec::with_capacity(n);
    for i in 0..warm + n {
        let e = force.next();
        let mut y = 0.0;
        for ((s, &(a1, a2)), g) in state.iter_mut().zip(&coef).zip(GAINS) {
            let v = a1 * s[0] + a2 * s[1] + g * e;
            s[1] = s[0];
            s[0] = v;
            y += v;
        }
        if i >= warm {
            out.push(y as f32);
        }
    }
    out
}

fn write_wav(path: &std::path::Path, x: &[f32], rate: u32) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for &v in x {
        w.write_sample(v).unwrap();
    }
    w.finalize().unwrap();
}

fn welch(x: &[f32], segments: usize) -> (Vec<f64>, f64) {
    let n = ((2 * x.len()) / (segments + 1)) & !1;
    let hop = n / 2;
    let mut fft = SegmentFft::new(n, Taper::Hann, FPS);
    let mut acc = vec![0.0; fft.bins()];
    let mut k = 0;
    let mut s = 0;
    while s + n <= x.len() {
        fft.accumulate(&x[s..s + n], 1, 0, &mut acc);
        s += hop;
        k += 1;
    }
    acc.iter_mut().for_each(|p| *p /= k as f64);
    (acc, FPS / n as f64)
}

/// The analysis alone, over seeds, on 40 minutes of the true motion (no
/// video, so it takes about a second): the regime where even mode 1's decay
/// (σT = 2200 decay times, spread ≥ √(2/σT) = 3%) can be pinned to 15%.
/// Every mode of every seed within 0.3% and 15%, by the method the JSON
/// names. `BEAM_S`, `K` (Welch segments) and `SEEDS` vary the run.
#[test]
fn damping_within_15_percent_over_seeds() {
    let secs: f64 = std::env::var("BEAM_S").map_or(2400.0, |v| v.parse().unwrap());
    let k: usize = std::env::var("K").map_or(64, |v| v.parse().unwrap());
    let seeds: u64 = std::env::var("SEEDS").map_or(8, |v| v.parse().unwrap());
    let mut worst = [0.0f64; 3];
    for seed in 1..=seeds {
        let x = beam_motion(seed, (secs * FPS) as usize);
        let (p, df) = welch(&x, k);
        let opts = PeakOptions {
            max_peaks: 3,
            window_kernel: Taper::Hann.power_kernel(2 * (p.len() - 1), 4),
            segments: k,
            ..Default::default()
        };
        let mut peaks = find_peaks(&p, 0.0, df, &opts);
        assert_eq!(peaks.len(), 3, "seed {seed}: {peaks:?}");
        // Strongest first from find_peaks; the modes in frequency order here.
        peaks.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
        for (m, pk) in peaks.iter().enumerate() {
            let want_f = MODES_HZ[m] * (1.0 - 2.0 * DAMPING[m] * DAMPING[m]).sqrt();
            let ferr = (pk.frequency_hz - want_f) / want_f;
            let xerr = (pk.damping_ratio - DAMPING[m]) / DAMPING[m];
            let hp = &pk.damping_estimates[pk.damping_estimates.len() - 1];
            eprintln!(
                "seed {seed} mode {}: {:.3} Hz ({:+.3}%) ξ {:.5} ± {:.5} ({:+.1}%) [{}]; half power {:.5} ± {:.5}",
                m + 1,
                pk.frequency_hz,
                100.0 * ferr,
                pk.damping_ratio,
                pk.damping_ratio_std,
                100.0 * xerr,
                pk.damping_method,
                hp.damping_ratio,
                hp.damping_ratio_std
            );
            assert!(ferr.abs() < 0.003, "seed {seed} mode {}: {pk:?}", m + 1);
            assert!(xerr.abs() < 0.15, "seed {seed} mode {}: {pk:?}", m + 1);
            worst[m] = worst[m].max(xerr.abs());
        }
    }
    eprintln!("worst damping error per mode: {worst:?}");
}

/// Writes the beam's motion as a WAV, renders it through the forward model
/// as video, and runs `vibroscope spectrum` on the video.
fn beam_through_video(dir: &std::path::Path, seed: u64, seconds: f64) -> serde_json::Value {
    beam_through_video_with(dir, seed, seconds, "riesz")
}

fn beam_through_video_with(
    dir: &std::path::Path,
    seed: u64,
    seconds: f64,
    pyramid: &str,
) -> serde_json::Value {
    let n = (seconds * FPS) as usize;
    write_wav(&dir.join("beam.wav"), &beam_motion(seed, n), FPS as u32);
    let frames = format!("cam.frames={n}");
    let fps = format!("cam.fps={FPS}");
    render_y4m(
        dir,
        "beam.y4m",
        &[
            "--set",
            &fps,
            "--set",
            &frames,
            "--set",
            "cam.width=24",
            "--set",
            "cam.height=24",
            "--set",
            "cam.amplitude_px=0.3",
            "--set",
            "cam.signal={ type = \"wav\", path = \"beam.wav\" }",
        ],
    );
    let o = run_in(
        dir,
        &[
            "spectrum",
            "beam.y4m",
            "--json",
            "beam.json",
            // Room for more than the three modes: the significant peaks
            // (the default) must be exactly the modes.
            "--peaks",
            "10",
            "--pyramid",
            pyramid,
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    serde_json::from_slice(&std::fs::read(dir.join("beam.json")).unwrap()).unwrap()
}

/// Issue 14: the steerable and the Riesz pyramid agree on the significant
/// peaks of one recording (the simulated cantilever, 5 minutes; seeds 3
/// and 4 measured, seed 3 here): the same three, each within three of its
/// combined frequency uncertainties.
#[test]
fn csp_and_riesz_agree_on_the_significant_peaks() {
    for seed in [3u64] {
        let dir = tempfile::tempdir().unwrap();
        let freqs = |doc: &serde_json::Value| {
            let mut f: Vec<(f64, f64)> = doc["peaks"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| {
                    (
                        p["frequency_hz"].as_f64().unwrap(),
                        p["frequency_std_hz"].as_f64().unwrap(),
                    )
                })
                .collect();
            f.sort_by(|a, b| a.0.total_cmp(&b.0));
            f
        };
        let riesz = freqs(&beam_through_video_with(dir.path(), seed, 300.0, "riesz"));
        let csp = freqs(&beam_through_video_with(dir.path(), seed, 300.0, "csp"));
        eprintln!("seed {seed}: riesz {riesz:?}, csp {csp:?}");
        assert_eq!(riesz.len(), 3, "seed {seed}: {riesz:?}");
        assert_eq!(csp.len(), 3, "seed {seed}: {csp:?}");
        for (r, c) in riesz.iter().zip(&csp) {
            let tol = 3.0 * r.1.hypot(c.1);
            assert!((r.0 - c.0).abs() <= tol, "seed {seed}: {r:?} vs {c:?}");
        }
    }
}

/// Thesis Table 5.5 beam under ambient (white) excitation, 40 minutes at
/// 300 fps (720k frames of 24×24) through the simulator and
/// `vibroscope spectrum`: every mode within 0.3% of its damped peak
/// fn √(1 - 2ξ²), every damping ratio within 15%. The length is set by
/// mode 1: its decay rate σ = ξ ωn = 0.92/s, and the spread of any estimate
/// of σ from T seconds of a randomly driven mode is at least √(2/σT); at
/// 10 minutes that is 6% (13% measured with this estimator over 12 seeds,
/// so 15% fails for some seeds), at 40 minutes 3% (4% measured).
/// `BEAM_SEED=n` varies the seed, `BEAM_S` the length; `BEAM_KEEP=1` keeps
/// the WAV, video and JSON.
#[test]
fn cantilever_modes_and_damping_through_video() {
    let seconds: f64 = std::env::var("BEAM_S").map_or(2400.0, |v| v.parse().unwrap());
    let seed: u64 = std::env::var("BEAM_SEED").map_or(7, |v| v.parse().unwrap());
    let dir = tempfile::tempdir().unwrap();
    let doc = beam_through_video(dir.path(), seed, seconds);
    if std::env::var_os("BEAM_KEEP").is_some() {
        // For comparisons with other tools (README: pyOMA2).
        eprintln!("kept {}", dir.keep().display());
    }
    let mut peaks = doc["peaks"].as_array().unwrap().clone();
    assert_eq!(doc["sample_rate_hz"].as_f64(), Some(FPS), "{doc}");
    assert_eq!(peaks.len(), 3, "{doc}");
    // Strongest first in the document; the modes in frequency order here.
    peaks.sort_by(|a, b| {
        a["frequency_hz"]
            .as_f64()
            .unwrap()
            .total_cmp(&b["frequency_hz"].as_f64().unwrap())
    });
    for (k, pk) in peaks.iter().enumerate() {
        let f = pk["frequency_hz"].as_f64().unwrap();
        let xi = pk["damping_ratio"].as_f64().unwrap();
        let sd = pk["damping_ratio_std"].as_f64().unwrap();
        let method = pk["damping_method"].as_str().unwrap();
        let want_f = MODES_HZ[k] * (1.0 - 2.0 * DAMPING[k] * DAMPING[k]).sqrt();
        let ferr = (f - want_f) / want_f;
        let xerr = (xi - DAMPING[k]) / DAMPING[k];
        eprintln!(
            "mode {}: {f:.4} Hz ({:+.3}%), ξ {xi:.5} ± {sd:.5} ({:+.1}%, true {}), {method}",
            k + 1,
            100.0 * ferr,
            100.0 * xerr,
            DAMPING[k]
        );
        assert!(
            ferr.abs() < 0.003,
            "mode {} frequency {f} vs {want_f}",
            k + 1
        );
        assert_eq!(method, "lorentzian_ls", "mode {}", k + 1);
        let tol = if k == 0 {
            0.15f64.max(3.0 * sd / DAMPING[k])
        } else {
            0.15
        };
        assert!(
            xerr.abs() < tol,
            "mode {} damping {xi} ± {sd} vs {}",
            k + 1,
            DAMPING[k]
        );
        // The reported uncertainty is neither absurdly small nor vacuous.
        assert!(
            sd > 0.02 * xi && sd < 0.5 * xi,
            "mode {} std {sd} for {xi}",
            k + 1
        );
    }
}

/// The guitar (E2 82.4 Hz and A2 110 Hz strings, filmed at 600 fps; 300
/// frames, so 2 Hz bins): both strings among the five most prominent peaks.
#[test]
fn guitar_strings_are_spectral_peaks() {
    let Some(video) = guitar_with_ffmpeg() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "spectrum",
            video.to_str().unwrap(),
            "--fps",
            "600",
            "--json",
            "g.json",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("g.json")).unwrap()).unwrap();
    assert_eq!(doc["sample_rate_hz"].as_f64(), Some(600.0));
    let f: Vec<f64> = doc["peaks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["frequency_hz"].as_f64().unwrap())
        .collect();
    eprintln!("guitar peaks: {f:?}");
    for want in [82.4, 110.0] {
        assert!(
            f.iter().any(|f| (f - want).abs() <= 3.0),
            "no peak within 3 Hz of {want} Hz among {f:?}"
        );
    }
}

/// The shipped live pipeline (sliding 2048-frame window every 220 frames,
/// Welch over 4), run faster than real time: one spectrum per hop, and the
/// three tones of the synthetic scene as its peaks, each within a bin.
#[test]
fn sliding_spectrum_emits_every_hop_and_finds_the_tones() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "run",
            "live-spectrum",
            "--quiet",
            "--set",
            "src.realtime=false",
            "--set",
            "src.width=64",
            "--set",
            "src.height=64",
            "--set",
            "src.duration_s=2.0",
            "--set",
            "out.peaks=3",
            "--set",
            "out.path=s.json",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    // 4400 frames: windows end at 2048, 2268, ..., i.e. (4400-2048)/220 + 1.
    assert_eq!(doc["spectra_averaged"].as_u64(), Some(11), "{doc}");
    let df = doc["resolution_hz"].as_f64().unwrap();
    assert!((df - 2200.0 / 2048.0).abs() < 1e-9);
    let mut f: Vec<f64> = doc["peaks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["frequency_hz"].as_f64().unwrap())
        .collect();
    // Peaks come strongest first; the tones are listed by frequency.
    f.sort_by(f64::total_cmp);
    assert_eq!(f.len(), 3, "{f:?}");
    for (got, want) in f.iter().zip([180.0, 440.0, 610.0]) {
        assert!((got - want).abs() < df, "{got} vs {want} Hz ({f:?})");
    }
}

/// Issue 14: a 0.2 Hz sway in a 10 s, 24 fps clip (two cycles: the
/// second bin above DC) is reported, and it alone; a clip of sensor noise
/// only reports no peak at the default 1% false-alarm probability (it
/// reported four to five noise peaks before significance was tested).
/// Three seeds each.
#[test]
fn a_slow_sway_is_reported_and_noise_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for seed in 1..=3u64 {
        for (name, amplitude) in [("sway", 0.3), ("still", 0.0)] {
            std::fs::write(
                d.join("s.toml"),
                format!(
                    "width = 64\nheight = 64\nfps = 24.0\nduration_s = 10.0\nseed = {seed}\n\
                     amplitude_px = {amplitude}\nnoise_std = 1.0\n\
                     signal = {{ type = \"tone\", freq_hz = 0.2 }}\n"
                ),
            )
            .unwrap();
            let o = run_in(d, &["simulate", "s.toml", "-o", "s.y4m"]);
            assert_eq!(code(&o), 0, "{}", stderr(&o));
            let o = run_in(
                d,
                &["spectrum", "s.y4m", "--json", "s.json", "--peaks", "10"],
            );
            assert_eq!(code(&o), 0, "{}", stderr(&o));
            let doc: serde_json::Value =
                serde_json::from_slice(&std::fs::read(d.join("s.json")).unwrap()).unwrap();
            let peaks = doc["peaks"].as_array().unwrap();
            let f: Vec<f64> = peaks
                .iter()
                .map(|p| p["frequency_hz"].as_f64().unwrap())
                .collect();
            eprintln!("{name} seed {seed}: {f:?}");
            if amplitude > 0.0 {
                assert_eq!(f.len(), 1, "{name} seed {seed}: {f:?}");
                // Within a bin (0.1 Hz): two cycles say little more.
                assert!((f[0] - 0.2).abs() < 0.1, "{name} seed {seed}: {f:?}");
                let p = peaks[0]["false_alarm"].as_f64().unwrap();
                assert!(p <= 0.01, "{p}");
            } else {
                assert!(f.is_empty(), "{name} seed {seed}: {f:?}");
            }
        }
    }
}

/// The `phase` stage's `tiles` (Eq. 3.17's local signals): a plate's
/// twist, whose halves move in opposite phase, cancels in the power of
/// the region's mean motion but not in the sum of local power spectra. A
/// bend (uniform across) of the same amplitude is the yardstick.
#[test]
fn tiles_keep_a_twist_that_the_mean_motion_cancels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut twist_db = Vec::new();
    for tiles in [1, 4] {
        std::fs::write(
            d.join("p.toml"),
            format!(
                "[[stage]]\nid = \"src\"\nkind = \"synthetic\"\nwidth = 96\nheight = 64\n\
                 fps = 200.0\nduration_s = 4.0\nnoise_std = 1.0\nobject = [8, 8, 80, 48]\n\
                 modal = {{ modes = [\
                 {{ freq_hz = 13.0, amplitude_px = 0.2, shape = 1, drive = \"tone\" }}, \
                 {{ freq_hz = 31.0, amplitude_px = 0.2, shape = 1, across = 1, drive = \"tone\" }}] }}\n\
                 [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\ntiles = {tiles}\n\
                 [[stage]]\nid = \"spectrum\"\nkind = \"spectrum\"\ninput = \"phase\"\nmode = \"whole\"\n\
                 [[stage]]\nid = \"out\"\nkind = \"peaks\"\ninput = \"spectrum\"\npath = \"s.json\"\n\
                 include_spectrum = true\n"
            ),
        )
        .unwrap();
        let o = run_in(d, &["run", "p.toml", "-q"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("s.json")).unwrap()).unwrap();
        let s = &doc["spectrum"];
        let res = s["resolution_hz"].as_f64().unwrap();
        let db: Vec<f64> = s["power_db"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap_or(-400.0))
            .collect();
        // Strongest bin within a bin of each mode.
        let at = |f: f64| {
            let k = (f / res).round() as usize;
            db[k - 1..=k + 1].iter().cloned().fold(f64::MIN, f64::max)
        };
        let rel = at(31.0) - at(13.0);
        eprintln!("tiles {tiles}: twist {rel:.1} dB against the bend");
        twist_db.push(rel);
    }
    // Mean motion: the twist's halves cancel (to the texture's asymmetry).
    assert!(twist_db[0] < -15.0, "{twist_db:?}");
    // Local spectra: the twist's power is that of a mode of its amplitude
    // (its RMS over the rows is 1/√3 of its edge value: -4.8 dB).
    assert!(twist_db[1] > -8.0, "{twist_db:?}");
}

/// The `phase` stage's `normalise`: under a rigid motion of an object
/// that fills the frame, each of 2 x 2 tiles reads about what the whole
/// region reads when every channel is divided by its own tile's A²
/// and band (`channel`, the tile's mean phase change) or by its own
/// tile's A² over all bands (`tile`, the tile's share of each band as
/// the whole region's), and about a quarter of it when all are divided
/// by the region's total (`region`, the default: each tile weighs by its
/// share of the texture).
#[test]
fn channel_and_tile_normalisation_make_each_tile_count_alike() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // RMS of each channel of the first scale, by tiles and normalise.
    let rms = |tiles: usize, normalise: &str| -> Vec<f64> {
        std::fs::write(
            d.join("p.toml"),
            format!(
                "[[stage]]\nid = \"src\"\nkind = \"synthetic\"\nwidth = 64\nheight = 64\n\
                 fps = 100.0\nduration_s = 2.0\nnoise_std = 0.5\nobject = [0, 0, 64, 64]\n\
                 amplitude_px = 0.2\nsignal = {{ type = \"tone\", freq_hz = 5.0 }}\n\
                 [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\n\
                 pyramid = \"riesz\"\nscales = 2\norientations = 1\ntiles = {tiles}\n\
                 normalise = \"{normalise}\"\nreference_interval_s = 0.0\n\
                 [[stage]]\nid = \"out\"\nkind = \"csv\"\ninput = \"phase\"\npath = \"m.csv\"\n"
            ),
        )
        .unwrap();
        let o = run_in(d, &["run", "p.toml", "-q"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let text = std::fs::read_to_string(d.join("m.csv")).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .filter_map(|l| l.split(',').map(|v| v.parse::<f64>().ok()).collect())
            .collect();
        assert!(rows.len() > 100, "{text:.200}");
        // Columns: t_s, then tile-major channels of 2 bands (scales 0, 1).
        (0..tiles * tiles)
            .map(|t| {
                let c = 1 + t * 2;
                (rows.iter().map(|r| r[c] * r[c]).sum::<f64>() / rows.len() as f64).sqrt()
            })
            .collect()
    };
    // One tile: the band's mean, or its share of both bands' A².
    let (mean, share) = (rms(1, "channel")[0], rms(1, "region")[0]);
    // With one tile, the tile is the region.
    let whole_tile = rms(1, "tile")[0];
    let by_channel = rms(2, "channel");
    let shared = rms(2, "region");
    let by_tile = rms(2, "tile");
    eprintln!(
        "whole region: channel {mean:.4}, region {share:.4}, tile {whole_tile:.4}; \
         2 x 2 tiles: channel {by_channel:.4?}, region {shared:.4?}, tile {by_tile:.4?}"
    );
    assert!(mean > share && share > 0.01, "{mean} {share}");
    assert!(
        (whole_tile / share - 1.0).abs() < 1e-4,
        "{whole_tile} {share}"
    );
    for ((c, r), t) in by_channel.iter().zip(&shared).zip(&by_tile) {
        assert!((c / mean - 1.0).abs() < 0.25, "{c} against {mean}");
        assert!((r / share - 0.25).abs() < 0.1, "{r} against {share}");
        assert!((t / share - 1.0).abs() < 0.25, "{t} against {share}");
    }
}

/// Bad input: exit 2 naming the field and value, or 1 naming the file.
#[test]
fn bad_input_is_reported_not_panicked() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &["run", "live-spectrum", "--set", "spectrum.window=1001"],
    );
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("window") && stderr(&o).contains("1001"),
        "{}",
        stderr(&o)
    );
    let o = run_in(
        dir.path(),
        &["run", "live-spectrum", "--set", "out.taper=\"kaiser\""],
    );
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("kaiser"), "{}", stderr(&o));
    let o = run_in(dir.path(), &["spectrum", "missing.y4m", "--json", "x.json"]);
    assert_ne!(code(&o), 0);
    assert!(stderr(&o).contains("missing.y4m"), "{}", stderr(&o));
    let o = run_in(
        dir.path(),
        &["spectrum", "x.y4m", "--json", "x.json", "--roi", "1,2,3"],
    );
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("--roi"), "{}", stderr(&o));
}

/// Issue 14: a vibration that a small part of the frame carries is found
/// on the whole frame, without a region drawn by hand. The scene: a 57x57
/// object (5% of a 256x256 frame) singing 120 Hz at 0.003 px over the
/// still textured background, 1000 fps, 3 s. With `--combine snr` (the
/// default) both pyramids report 120 Hz as the strongest peak; the plain
/// sum of the bands (`--combine sum`) is printed beside it (with the
/// steerable pyramid it found nothing). A tone this short leaves SSI-cov
/// one stable order: its damping's uncertainty is then unknown (null),
/// not 0.
#[test]
fn a_small_vibrating_region_is_the_top_peak_without_a_roi() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(
        d,
        "small.y4m",
        &[
            "--set",
            "cam.fps=1000",
            "--set",
            "cam.duration_s=3",
            "--set",
            "cam.object=[100, 100, 57, 57]",
            "--set",
            "cam.amplitude_px=0.003",
            "--set",
            "cam.signal={ type = \"tone\", freq_hz = 120.0 }",
        ],
    );
    let peaks = |pyramid: &str, combine: &str| -> Vec<(f64, f64)> {
        let o = run_in(
            d,
            &[
                "spectrum",
                "small.y4m",
                "--json",
                "small.json",
                "--pyramid",
                pyramid,
                "--combine",
                combine,
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("small.json")).unwrap()).unwrap();
        assert_eq!(doc["combine"], combine, "the document says how it combined");
        // An SSI-cov estimate from one stable order and no segments has no
        // uncertainty to give: null ("n/a"), never a confident 0.
        for e in doc["peaks"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|p| p["damping_estimates"].as_array().unwrap())
            .filter(|e| e["method"] == "ssi_cov")
        {
            eprintln!("{pyramid} {combine}: {e}");
            if e["stable_orders"].as_u64().unwrap() < 2 && e["segment_std"].is_null() {
                assert!(e["damping_ratio_std"].is_null(), "{e}");
            }
            assert_ne!(e["damping_ratio_std"].as_f64(), Some(0.0), "{e}");
        }
        doc["peaks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                (
                    p["frequency_hz"].as_f64().unwrap(),
                    p["prominence_db"].as_f64().unwrap(),
                )
            })
            .collect()
    };
    for pyramid in ["csp", "riesz"] {
        let snr = peaks(pyramid, "snr");
        let sum = peaks(pyramid, "sum");
        eprintln!("{pyramid}: snr {snr:?}; sum {sum:?}");
        assert!(!snr.is_empty(), "{pyramid}: no peak");
        assert!(
            (snr[0].0 - 120.0).abs() < 0.5,
            "{pyramid}: the strongest peak is at {} Hz: {snr:?}",
            snr[0].0
        );
    }
}
