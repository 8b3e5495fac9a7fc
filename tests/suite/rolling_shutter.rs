//! Rolling shutter (issue 4, thesis ch. 4.5) against the forward model:
//! tones far above the frame rate heard through row timing, AR against
//! linear gap filling on speech, line-delay calibration, and bad
//! parameters rejected by name.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;

/// Power spectrum (Hann window, zero-padded to a power of two >= 2·len) and bin spacing.
fn spectrum(x: &[f32], rate: f64) -> (Vec<f64>, f64) {
    power_spectrum(x, rate, (2 * x.len()).next_power_of_two())
}

/// Frequencies (parabolic interpolation) and powers of the `k` strongest local maxima in [lo, hi] Hz.
fn top_peaks(p: &[f64], df: f64, lo: f64, hi: f64, k: usize) -> Vec<(f64, f64)> {
    let mut peaks: Vec<(f64, f64)> = (1..p.len() - 1)
        .filter(|&i| p[i] > p[i - 1] && p[i] >= p[i + 1])
        .map(|i| {
            let (a, b, c) = (p[i - 1].ln(), p[i].ln(), p[i + 1].ln());
            let off = 0.5 * (a - c) / (a - 2.0 * b + c);
            ((i as f64 + off) * df, p[i])
        })
        .filter(|&(f, _)| f >= lo && f <= hi)
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.truncate(k);
    peaks
}

/// Median power in [lo, hi] Hz away from the listed frequencies (± `guard` Hz).
fn noise_floor(p: &[f64], df: f64, lo: f64, hi: f64, avoid: &[f64], guard: f64) -> f64 {
    let mut v: Vec<f64> = (0..p.len())
        .filter(|&i| {
            let f = i as f64 * df;
            f >= lo && f <= hi && avoid.iter().all(|a| (f - a).abs() > guard)
        })
        .map(|i| p[i])
        .collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run_ok(dir: &Path, args: &[&str]) -> String {
    let o = run_in(dir, args);
    assert_eq!(code(&o), 0, "{args:?}: {}", stderr(&o));
    stderr(&o)
}

#[test]
fn two_tones_far_above_the_frame_rate_are_heard() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The shipped camera (frame period 1032 line delays, so rows land on the
    // 1/d grid), and the same camera at exactly 60 fps (1041.67 line delays
    // per frame: rows fall between grid points and are read off in time).
    // At 60 fps, 1200 Hz is the frame rate's 20th harmonic: every frame then
    // sees the same shear, indistinguishable from the scene's own shape (the
    // per-row reference removes it), so only 440 Hz is checked there.
    for (extra, tones) in [
        ("src.seed=1", &[440.0, 1200.0][..]),
        ("src.fps=60.0", &[440.0][..]),
    ] {
        run_ok(
            d,
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "out.path=rs.wav",
                "--set",
                extra,
            ],
        );
        let (rate, x) = read_wav(&d.join("rs.wav"));
        assert_eq!(rate, 62_500, "one sample per line delay");
        let (p, df) = spectrum(&x, rate as f64);
        let peaks = top_peaks(&p, df, 100.0, 5000.0, 6);
        let floor = noise_floor(&p, df, 100.0, 3000.0, &[440.0, 1200.0], 20.0);
        let rel: Vec<(f64, f64)> = peaks
            .iter()
            .map(|(f, pw)| (*f, 10.0 * (pw / peaks[0].1).log10()))
            .collect();
        eprintln!("{extra}: strongest peaks (Hz, dB) {rel:.1?}");
        for &want in tones {
            let (f, pw) = peaks
                .iter()
                .copied()
                .find(|(f, _)| (f - want).abs() <= 1.0)
                .unwrap_or_else(|| panic!("{extra}: no peak within 1 Hz of {want} Hz: {peaks:?}"));
            let snr = 10.0 * (pw / floor).log10();
            eprintln!("{extra}: {want} Hz found at {f:.2} Hz, {snr:.1} dB above the noise floor");
            assert!(
                snr >= 20.0,
                "{extra}: {want} Hz only {snr:.1} dB above the floor"
            );
        }
    }
}

/// Band-limits to 80-2000 Hz (Butterworth high-pass, FIR low-pass): the
/// band the issue scores speech in; applied identically to truth and test.
fn band(x: &[f64], fs: f64) -> Vec<f64> {
    use vibroscope_math::exposure::{design, Fir, Mode};
    use vibroscope_math::iir::Sos;
    let mut hp = Sos::butterworth_highpass(4, 80.0, fs).unwrap();
    let mut lp = Fir::new(design(Mode::Lowpass, 1.0 / 2000.0, fs, 129, -12.0));
    x.iter().map(|&v| lp.step(hp.step(v))).collect()
}

/// Speech (espeak-ng) through the thesis' DSLR: scores against the true
/// motion in 80-2000 Hz for AR and for linear gap filling.
#[test]
fn speech_through_a_rolling_shutter_ar_beats_linear() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let wav = d.join("speech.wav");
    let spoke = std::process::Command::new("espeak-ng")
        .args([
            "-w",
            wav.to_str().unwrap(),
            "Visual microphones hear through the rolling shutter.",
        ])
        .output();
    if !spoke.map(|o| o.status.success()).unwrap_or(false) {
        eprintln!("skipping: espeak-ng is not installed (Debian package espeak-ng)");
        return;
    }
    let (r, x) = read_wav_any(&wav);
    let secs = x.len() as f64 / r as f64;
    let sets = [
        format!(
            "src.signal={{ type = \"wav\", path = \"{}\" }}",
            wav.display()
        ),
        format!("src.duration_s={secs}"),
        "exposure.rate_hz=16000.0".to_string(),
    ];
    let fs = 16_000.0;
    let mut decl = vibroscope::pipeline::load("rolling-shutter").unwrap();
    // Extra `--set`s for diagnosis, e.g. RS_SPEECH_SETS="src.noise_std=0.0;src.exposure_us=0.0"
    // (the README's breakdown of the limits was measured this way).
    let extra: Vec<String> = std::env::var("RS_SPEECH_SETS")
        .map(|v| v.split(';').map(String::from).collect())
        .unwrap_or_default();
    for s in sets.iter().chain(&extra) {
        vibroscope_engine::config::apply_set(&mut decl, s).unwrap();
    }
    let mut results = Vec::new();
    for method in ["ar", "linear"] {
        let out = format!("{method}.wav");
        let mut args: Vec<String> = vec!["run".into(), "rolling-shutter".into(), "-q".into()];
        for s in sets
            .iter()
            .cloned()
            .chain([
                format!("fill.method=\"{method}\""),
                format!("out.path=\"{out}\""),
            ])
            .chain(extra.iter().cloned())
        {
            args.push("--set".into());
            args.push(s);
        }
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        run_ok(d, &argv);
        let (rate, est) = read_wav(&d.join(&out));
        assert_eq!(rate, 16_000);
        let truth: Vec<f64> = {
            let t = true_motion_at(&decl, "src", est.len(), fs);
            band(&t, fs)
        };
        let est: Vec<f64> = band(&est.iter().map(|&v| v as f64).collect::<Vec<_>>(), fs);
        let s = vibroscope_math::metrics::score(&truth, &est, fs, 800);
        eprintln!(
            "{method}: SNR {:.2} dB, segmental SNR {:.2} dB, STOI {:.3} (80-2000 Hz, against the true motion)",
            s.snr_db, s.ssnr_db, s.stoi
        );
        results.push(s);
    }
    let (ar, lin) = (results[0], results[1]);
    assert!(
        ar.snr_db >= lin.snr_db + 2.0,
        "AR {:.2} dB vs linear {:.2} dB",
        ar.snr_db,
        lin.snr_db
    );
}

/// The object's true displacement at `n` instants `k / fs` (ground truth).
fn true_motion_at(decl: &vibroscope_engine::PipelineDecl, id: &str, n: usize, fs: f64) -> Vec<f64> {
    use vibroscope_engine::stages::sources::synthetic::SyntheticParams;
    let st = decl.stages.iter().find(|s| s.id == id).unwrap();
    let p: SyntheticParams = vibroscope_engine::Params {
        file: &decl.file,
        stage: st,
    }
    .parse()
    .unwrap();
    let scene = p.scene().unwrap();
    (0..n)
        .map(|k| scene.displacement_px(k as f64 / fs))
        .collect()
}

/// Any WAV's rate and first channel.
fn read_wav_any(p: &Path) -> (u32, Vec<f64>) {
    vibroscope_io::wav::read_mono(p).unwrap()
}

/// Renders the shipped rolling-shutter camera (two tones) to Y4M, 1 s.
fn render_two_tones(d: &Path) {
    render_y4m(
        d,
        "rs.y4m",
        &[
            "--set",
            "cam.width=96",
            "--set",
            "cam.height=720",
            "--set",
            "cam.fps=60.56201550387597",
            "--set",
            "cam.duration_s=1.0",
            "--set",
            "cam.object=[16, 0, 64, 720]",
            "--set",
            "cam.amplitude_px=0.1",
            "--set",
            "cam.line_delay_us=16.0",
            "--set",
            "cam.frame_delay_us=4992.0",
            "--set",
            "cam.exposure_us=500.0",
            "--set",
            "cam.signal={ type = \"tones\", freqs_hz = [440.0, 1200.0] }",
        ],
    );
}

/// `listen --rolling-shutter` on a recording hears both tones at their
/// frequencies; the same video through the frame-rate visual microphone
/// (global-shutter processing) yields one sample per frame, whose Nyquist
/// limit (30 Hz) is far below both tones: they can only alias.
#[test]
fn listen_rolling_shutter_on_a_recording_and_the_global_shutter_view() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_two_tones(d);
    run_ok(
        d,
        &[
            "listen",
            "rs.y4m",
            "--rolling-shutter",
            "--line-delay-us",
            "16",
            "--frame-delay-us",
            "4992",
            "--exposure-us",
            "500",
            "--rate",
            "16000",
            "--roi",
            "16,0,64,720",
            "-o",
            "l.wav",
        ],
    );
    let (rate, x) = read_wav(&d.join("l.wav"));
    assert_eq!(rate, 16_000);
    let (p, df) = spectrum(&x, rate as f64);
    let peaks = top_peaks(&p, df, 100.0, 5000.0, 2);
    eprintln!("listen --rolling-shutter: strongest peaks {peaks:.2?}");
    for want in [440.0, 1200.0] {
        assert!(
            peaks.iter().any(|(f, _)| (f - want).abs() <= 1.0),
            "no peak within 1 Hz of {want} Hz: {peaks:?}"
        );
    }
    run_ok(
        d,
        &[
            "listen",
            "rs.y4m",
            "--roi",
            "16,0,64,720",
            "--rate",
            "native",
            "-o",
            "g.wav",
        ],
    );
    let (grate, g) = read_wav(&d.join("g.wav"));
    let (gp, gdf) = spectrum(&g, grate as f64);
    let gpeaks = top_peaks(&gp, gdf, 1.0, grate as f64 / 2.0, 2);
    eprintln!(
        "global shutter: {} samples at {grate} Hz (Nyquist {:.1} Hz), strongest peaks {gpeaks:.2?}",
        g.len(),
        grate as f64 / 2.0
    );
    assert!(
        (grate as f64) / 2.0 < 440.0,
        "one sample per frame cannot represent 440 Hz"
    );
}

/// `rs-calibrate` recovers a simulated line delay (25 us, 480 rows, 30 fps)
/// from a 317 Hz tone, within 3%, and the frame delay that follows.
#[test]
fn rs_calibrate_recovers_the_line_delay() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ld, rows, fps) = (25.0, 480.0, 30.0);
    render_y4m(
        d,
        "cal.y4m",
        &[
            "--set",
            "cam.width=96",
            "--set",
            "cam.height=480",
            "--set",
            "cam.fps=30.0",
            "--set",
            "cam.duration_s=1.0",
            "--set",
            "cam.object=[16, 0, 64, 480]",
            "--set",
            "cam.amplitude_px=0.2",
            "--set",
            "cam.line_delay_us=25.0",
            "--set",
            "cam.exposure_us=200.0",
            "--set",
            "cam.signal={ type = \"tone\", freq_hz = 317.0 }",
        ],
    );
    let o = run_in(
        d,
        &[
            "rs-calibrate",
            "cal.y4m",
            "--tone-hz",
            "317",
            "--json",
            "rs.json",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let json = std::fs::read_to_string(d.join("rs.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let got = v["line_delay_us"].as_f64().unwrap();
    let gap = v["frame_delay_us"].as_f64().unwrap();
    let want_gap = 1e6 / fps - rows * ld;
    eprintln!("rs-calibrate: line delay {got:.3} us (true {ld}), frame delay {gap:.1} us (true {want_gap:.1})");
    assert!((got / ld - 1.0).abs() < 0.03, "line delay {got} us vs {ld}");
    assert!(
        (gap - want_gap).abs() < 0.03 * rows * ld,
        "frame delay {gap} vs {want_gap}"
    );
}

/// Same input, same output, bit for bit.
#[test]
fn rolling_shutter_output_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for out in ["a.wav", "b.wav"] {
        let path = format!("out.path={out}");
        run_ok(
            d,
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "src.duration_s=0.3",
                "--set",
                &path,
            ],
        );
    }
    assert_eq!(
        std::fs::read(d.join("a.wav")).unwrap(),
        std::fs::read(d.join("b.wav")).unwrap()
    );
}

/// Wrong, absent and inconsistent timing parameters: a message naming the
/// field and the value, a non-zero exit, no panic.
#[test]
fn bad_rolling_shutter_parameters_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: &[(&[&str], i32, &[&str])] = &[
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "src.line_delay_us=0",
            ],
            2,
            &["line_delay_us", "got 0"],
        ),
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "rows.line_delay_us=-3",
            ],
            2,
            &["line_delay_us", "-3"],
        ),
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "src.frame_delay_us=9000.0",
            ],
            2,
            &["frame_delay_us", "9000"],
        ),
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "src.line_delay_us=30.0",
            ],
            2,
            &["line_delay_us", "30"],
        ),
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "exposure.exposure_us=0.0",
            ],
            2,
            &["exposure_us", "got 0"],
        ),
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "fill.method=\"cubic\"",
            ],
            2,
            &["method"],
        ),
        (
            &[
                "run",
                "rolling-shutter",
                "-q",
                "--set",
                "rows.frame_delay_us=9000.0",
            ],
            1,
            &["frame_delay_us", "9000"],
        ),
        (
            &["listen", "x.y4m", "--rolling-shutter"],
            2,
            &["--line-delay-us"],
        ),
        (
            &["listen", "x.y4m", "--line-delay-us", "16"],
            2,
            &["--line-delay-us", "--rolling-shutter"],
        ),
        (
            &[
                "listen",
                "x.y4m",
                "--rolling-shutter",
                "--line-delay-us",
                "0",
            ],
            2,
            &["line_delay_us", "got 0"],
        ),
        (
            &["rs-calibrate", "x.y4m", "--tone-hz", "0"],
            2,
            &["--tone-hz", "got 0"],
        ),
        (
            &["rs-calibrate", "missing.y4m", "--tone-hz", "440"],
            1,
            &["missing.y4m"],
        ),
    ];
    for (args, want, needles) in cases {
        let o = run_in(d, args);
        let err = stderr(&o);
        assert_eq!(code(&o), *want, "{args:?}: {err}");
        for n in *needles {
            assert!(err.contains(n), "{args:?}: `{n}` not in: {err}");
        }
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// Amplitude ratio (dB) of the 1200 Hz to the 440 Hz tone in `path`.
fn tone_ratio_db(path: &Path) -> f64 {
    let (rate, x) = read_wav(path);
    let (p, df) = spectrum(&x, rate as f64);
    let at = |f: f64| {
        let i = (f / df).round() as usize;
        p[i - 3..=i + 3].iter().cloned().fold(0.0, f64::max)
    };
    10.0 * (at(1200.0) / at(440.0)).log10()
}

/// The two tones drive the object equally. Through the exposure boxcar the
/// 1200 Hz tone comes back weaker by |H(1200)| / |H(440)| (sinc, E =
/// 1/2000 s: -5.2 dB); compensation undoes it.
#[test]
fn exposure_compensation_restores_the_tone_balance() {
    use vibroscope_math::exposure::boxcar_gain;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let e = 1.0 / 2000.0;
    let want = 20.0 * (boxcar_gain(1200.0, e) / boxcar_gain(440.0, e)).log10();
    run_ok(
        d,
        &["run", "rolling-shutter", "-q", "--set", "out.path=lp.wav"],
    );
    let set = "exposure.mode=\"compensate\"";
    run_ok(
        d,
        &[
            "run",
            "rolling-shutter",
            "-q",
            "--set",
            "out.path=c.wav",
            "--set",
            set,
        ],
    );
    let (lp, comp) = (
        tone_ratio_db(&d.join("lp.wav")),
        tone_ratio_db(&d.join("c.wav")),
    );
    eprintln!("1200/440 Hz: low-pass {lp:+.2} dB (boxcar predicts {want:+.2} dB), compensated {comp:+.2} dB (truth 0)");
    assert!(
        (lp - want).abs() < 1.0,
        "low-pass {lp:+.2} vs {want:+.2} dB"
    );
    assert!(comp.abs() < 1.0, "compensated {comp:+.2} dB");
}

/// A flickering light (row brightness 128 + 40 sin 2π f (t_n + y d)) in a
/// hand-written Y4M: `rs-calibrate --signal intensity` finds d within 3%.
#[test]
fn rs_calibrate_from_a_flickering_light() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h, fps, ld, f) = (32usize, 400usize, 25.0, 40e-6, 233.0);
    let mut y4m = format!("YUV4MPEG2 W{w} H{h} F25:1 Ip A1:1 Cmono\n").into_bytes();
    for n in 0..25 {
        y4m.extend_from_slice(b"FRAME\n");
        for y in 0..h {
            let t = n as f64 / fps + y as f64 * ld;
            let v = 128.0 + 40.0 * (2.0 * std::f64::consts::PI * f * t).sin();
            y4m.extend(std::iter::repeat_n(v.round() as u8, w));
        }
    }
    std::fs::write(d.join("flicker.y4m"), y4m).unwrap();
    let o = run_in(
        d,
        &[
            "rs-calibrate",
            "flicker.y4m",
            "--tone-hz",
            "233",
            "--signal",
            "intensity",
            "--json",
            "flicker.json",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let json = std::fs::read_to_string(d.join("flicker.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let got = v["line_delay_us"].as_f64().unwrap();
    eprintln!("flicker: line delay {got:.3} us (true {})", ld * 1e6);
    assert!((got / (ld * 1e6) - 1.0).abs() < 0.03, "{got} us");
}
