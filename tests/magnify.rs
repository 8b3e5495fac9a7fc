//! `vibroscope magnify` against the forward model's ground truth: an object
//! moving with two tones, one inside the band and one outside; the motion
//! is measured in the magnified video by the engine's own estimator
//! (`gradient_motion`, pixels) and compared with the simulator's truth.
//! Also its bad input (exit 2, nothing written).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::*;
use std::f64::consts::PI;
use std::path::Path;
use vibroscope::magnify::{magnify, MagnifyOptions};
use vibroscope::math::magnify::temporal;
use vibroscope::pipeline::{self, PipelineOptions, Pyramid, RunSettings};

const FPS: f64 = 500.0;
const BAND: (f64, f64) = (35.0, 45.0);
const OUT_HZ: f64 = 150.0;
/// Peak displacement of each tone, px (the two tones share `amplitude_px`).
const TONE_PX: f64 = 0.02;
const FRAMES: usize = 500;
/// Frames left out of the fit while the band-pass settles.
const SETTLE: usize = 150;

/// The in-band tone: the band-pass's centre (unit gain, zero phase).
fn in_hz() -> f64 {
    temporal::design(2, BAND.0, BAND.1, FPS).centre_hz
}

/// Renders the two-tone scene to `dir/scene.y4m`.
fn render(dir: &Path) {
    let signal = format!(
        "cam.signal={{type=\"tones\", freqs_hz=[{}, {OUT_HZ}]}}",
        in_hz()
    );
    let set: Vec<String> = vec![
        signal,
        format!("cam.fps={FPS}"),
        format!("cam.frames={FRAMES}"),
        format!("cam.amplitude_px={}", 2.0 * TONE_PX),
        "cam.noise_std=0".into(),
        format!("out.path={}", dir.join("scene.y4m").display()),
    ];
    let decl = pipeline::prepare(&PipelineOptions {
        pipeline: "render".into(),
        set,
        replay: None,
        fps: None,
    })
    .unwrap();
    pipeline::run(&decl, RunSettings::default()).unwrap();
}

/// Amplitudes (px) of the tones `freqs` in the motion of `video`'s object,
/// measured by the `motion` pipeline (gradient least squares) and fitted
/// by least squares (sine, cosine and an offset per tone) after `SETTLE`.
fn measured(dir: &Path, video: &Path, roi: &str) -> Vec<f64> {
    let wav = dir.join("motion.wav");
    let decl = pipeline::prepare(&PipelineOptions {
        pipeline: "motion".into(),
        set: vec![
            format!("src.path={}", video.display()),
            format!("src.fps={FPS}"),
            format!("motion.roi={roi}"),
            format!("out.path={}", wav.display()),
        ],
        replay: None,
        fps: None,
    })
    .unwrap();
    pipeline::run(&decl, RunSettings::default()).unwrap();
    let (_, x) = read_wav(&wav);
    tone_amplitudes(&x[SETTLE..], SETTLE, &[in_hz(), OUT_HZ])
}

/// Least-squares amplitudes of sinusoids at `freqs` (plus an offset and a
/// linear drift) in `x`, whose first sample is frame `k0`.
#[allow(clippy::needless_range_loop)]
fn tone_amplitudes(x: &[f32], k0: usize, freqs: &[f64]) -> Vec<f64> {
    let basis = |k: usize| -> Vec<f64> {
        let t = (k + k0) as f64 / FPS;
        let mut b = vec![1.0, t];
        for f in freqs {
            b.push((2.0 * PI * f * t).sin());
            b.push((2.0 * PI * f * t).cos());
        }
        b
    };
    let m = 2 + 2 * freqs.len();
    let mut ata = vec![vec![0.0; m]; m];
    let mut atb = vec![0.0; m];
    for (k, &v) in x.iter().enumerate() {
        let b = basis(k);
        for i in 0..m {
            atb[i] += b[i] * v as f64;
            for j in 0..m {
                ata[i][j] += b[i] * b[j];
            }
        }
    }
    // Gaussian elimination (small, well-conditioned system).
    for c in 0..m {
        let p = (c..m)
            .max_by(|&a, &b| ata[a][c].abs().total_cmp(&ata[b][c].abs()))
            .unwrap();
        ata.swap(c, p);
        atb.swap(c, p);
        for r in 0..m {
            if r != c {
                let f = ata[r][c] / ata[c][c];
                for j in 0..m {
                    ata[r][j] -= f * ata[c][j];
                }
                atb[r] -= f * atb[c];
            }
        }
    }
    let coef: Vec<f64> = (0..m).map(|i| atb[i] / ata[i][i]).collect();
    (0..freqs.len())
        .map(|i| coef[2 + 2 * i].hypot(coef[3 + 2 * i]))
        .collect()
}

fn magnified(dir: &Path, factor: f64, pyramid: Pyramid, name: &str) -> std::path::PathBuf {
    let out = dir.join(name);
    magnify(&MagnifyOptions {
        video: dir.join("scene.y4m"),
        output: out.clone(),
        lo_hz: BAND.0,
        hi_hz: BAND.1,
        factor,
        fps: Some(FPS),
        pyramid,
        ..Default::default()
    })
    .unwrap();
    out
}

/// The object is the central half of the frame; its interior, away from
/// the edges that the background does not share.
const ROI: &str = "[96,96,64,64]";

#[test]
fn magnified_motion_is_the_factor_times_the_truth_in_band_only() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path());
    // The estimator on the original recovers the truth.
    let orig = measured(dir.path(), &dir.path().join("scene.y4m"), ROI);
    eprintln!(
        "original: in-band {:.5} px, out-of-band {:.5} px (truth {TONE_PX} each)",
        orig[0], orig[1]
    );
    for a in &orig {
        assert!(
            (a / TONE_PX - 1.0).abs() < 0.10,
            "estimator on the original: {orig:?}"
        );
    }
    for (pyramid, factors) in [(Pyramid::Csp, &[0.5, 10.0][..])] {
        for &factor in factors {
            let v = magnified(dir.path(), factor, pyramid, "m.y4m");
            let m = measured(dir.path(), &v, ROI);
            // Gains against the estimator's own reading of the original (its
            // bias, about +6% on this texture, cancels).
            let (gain_in, gain_out) = (m[0] / orig[0], m[1] / orig[1]);
            eprintln!(
                "{pyramid:?} factor {factor}: in-band x{gain_in:.3} (want {factor}), out-of-band x{gain_out:.3} (want 1)"
            );
            if pyramid == Pyramid::Csp {
                assert!(
                    (gain_in / factor - 1.0).abs() < 0.10,
                    "{pyramid:?} {factor}: in-band x{gain_in}"
                );
                assert!(
                    (gain_out - 1.0).abs() < 0.10,
                    "{pyramid:?} {factor}: out-of-band x{gain_out}"
                );
            }
        }
    }
}

#[test]
fn factor_zero_removes_the_in_band_motion() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path());
    let v = magnified(dir.path(), 0.0, Pyramid::Csp, "still.y4m");
    let m = measured(dir.path(), &v, ROI);
    let db = 20.0 * (m[0] / TONE_PX).log10();
    eprintln!(
        "factor 0: in-band {db:.1} dB, out-of-band x{:.3}",
        m[1] / TONE_PX
    );
    assert!(db <= -20.0, "in-band motion only {db:.1} dB down");
    assert!(
        (m[1] / TONE_PX - 1.0).abs() < 0.10,
        "out-of-band x{}",
        m[1] / TONE_PX
    );
}

/// Bad input: a clear message naming the flag or file, exit 2, no panic,
/// and no output left behind.
#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(
        dir.path(),
        "scene.y4m",
        &["--set", "cam.frames=20", "--set", "cam.fps=500"],
    );
    // A Y4M in a colour space no reader handles.
    std::fs::write(
        dir.path().join("rgb.y4m"),
        b"YUV4MPEG2 W4 H4 F25:1 Crgb\nFRAME\n000000000000000000000000000000000000000000000000",
    )
    .unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["scene.y4m", "--band", "200,300"], "Nyquist"),
        (&["scene.y4m", "--band", "45,35"], "inverted"),
        (&["scene.y4m", "--band", "40,40"], "--band"),
        (&["scene.y4m", "--band", "abc"], "--band"),
        (
            &["scene.y4m", "--band", "35,45", "--factor", "-2"],
            "--factor",
        ),
        (
            &["scene.y4m", "--band", "35,45", "--factor", "ten"],
            "--factor",
        ),
        (
            &["scene.y4m", "--band", "35,45", "--factor", "NaN"],
            "--factor",
        ),
        (&["rgb.y4m", "--band", "5,10"], "colour space"),
    ];
    for (args, want) in cases {
        let mut a: Vec<&str> = vec!["magnify"];
        a.extend_from_slice(args);
        if !a.contains(&"--factor") {
            a.extend_from_slice(&["--factor", "10"]);
        }
        a.extend_from_slice(&["-o", "out.y4m"]);
        let o = run_in(dir.path(), &a);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{a:?}: {err}");
        assert!(err.contains(want), "{a:?}: `{want}` not in: {err}");
        assert!(!err.contains("panicked"), "{a:?}: {err}");
        let left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n != "scene.y4m" && n != "rgb.y4m")
            .collect();
        assert!(left.is_empty(), "{a:?} left {left:?}");
    }
}
