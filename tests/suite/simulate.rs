//! `vibroscope simulate` (issue 6, item 1): the forward model's object and
//! camera effects, each checked by what a plain recovery (gradient motion,
//! `run motion --replay`) measures on the rendered video.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;

const BASE: &str = "width = 64\nheight = 64\nfps = 2200.0\nnoise_std = 0.5\n";

/// Renders `scene` (TOML text) and recovers the motion as a WAV.
fn render_and_recover(dir: &Path, name: &str, scene: &str) -> (u32, Vec<f32>) {
    let toml = dir.join(format!("{name}.toml"));
    std::fs::write(&toml, format!("{BASE}{scene}")).unwrap();
    let y4m = format!("{name}.y4m");
    let o = run_in(dir, &["simulate", toml.to_str().unwrap(), "-o", &y4m]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let wav = format!("{name}.wav");
    let o = run_in(
        dir,
        &[
            "run",
            "motion",
            "--replay",
            &y4m,
            "--set",
            &format!("out.path={wav}"),
            "--quiet",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    read_wav(&dir.join(wav))
}

/// Frequency of the strongest peak in `[lo, hi]` Hz (zero-padded FFT and a
/// parabola through the top three bins), and its power.
fn peak(x: &[f32], rate: f64, lo: f64, hi: f64) -> (f64, f64) {
    let (p, df) = power_spectrum(x, rate, (16 * x.len()).next_power_of_two());
    let (a, b) = ((lo / df) as usize, (hi / df) as usize);
    let k = (a..b).max_by(|&i, &j| p[i].total_cmp(&p[j])).unwrap();
    let (l, c, r) = (p[k - 1].ln(), p[k].ln(), p[k + 1].ln());
    let d = 0.5 * (l - r) / (l - 2.0 * c + r);
    ((k as f64 + d) * df, p[k])
}

/// Power in a band, summed over bins.
fn band_power(x: &[f32], rate: f64, lo: f64, hi: f64) -> f64 {
    let (p, df) = power_spectrum(x, rate, x.len().next_power_of_two());
    p[(lo / df) as usize..(hi / df) as usize].iter().sum()
}

/// A camera clock 2000 ppm fast, frames stamped at the stated rate: a
/// 440 Hz tone is heard at 440 / 1.002 Hz; without the error, at 440 Hz.
#[test]
fn clock_error_shifts_the_heard_frequency() {
    let d = tempfile::tempdir().unwrap();
    let tone = "duration_s = 2.0\nsignal = { type = \"tone\", freq_hz = 440.0 }\n";
    let (rate, x) = render_and_recover(d.path(), "exact", tone);
    let (f0, _) = peak(&x, rate as f64, 300.0, 600.0);
    let (_, y) = render_and_recover(
        d.path(),
        "fast",
        &format!("{tone}clock_error_ppm = 2000.0\n"),
    );
    let (f1, _) = peak(&y, rate as f64, 300.0, 600.0);
    eprintln!(
        "exact clock: {f0:.3} Hz; +2000 ppm: {f1:.3} Hz (expected {:.3})",
        440.0 / 1.002
    );
    assert!((f0 - 440.0).abs() < 0.05, "{f0}");
    assert!((f1 - 440.0 / 1.002).abs() < 0.05, "{f1}");
}

/// Dropped and duplicated captures: the count changes accordingly, a
/// duplicate is byte-identical to the capture before it, and every frame
/// keeps its nominal stamp.
#[test]
fn dropped_and_duplicated_frames() {
    let d = tempfile::tempdir().unwrap();
    let scene = format!(
        "{BASE}frames = 100\ndrop_frames = [10, 11, 50, 500]\nduplicate_frames = [20, 20, 70]\n"
    );
    std::fs::write(d.path().join("s.toml"), scene).unwrap();
    let o = run_in(d.path(), &["simulate", "s.toml", "-o", "s.y4m"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let bytes = std::fs::read(d.path().join("s.y4m")).unwrap();
    // Frames: header line, then "FRAME Xts=...\n" + 64*64 bytes each.
    let mut frames = Vec::new();
    let mut stamps = Vec::new();
    let mut i = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
    while i < bytes.len() {
        let nl = i + bytes[i..].iter().position(|&b| b == b'\n').unwrap();
        let head = std::str::from_utf8(&bytes[i..nl]).unwrap();
        let ts: i64 = head
            .split("Xts=")
            .nth(1)
            .and_then(|s| s.split_whitespace().next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no timestamp in `{head}`"));
        stamps.push(ts);
        frames.push(&bytes[nl + 1..nl + 1 + 64 * 64]);
        i = nl + 1 + 64 * 64;
    }
    // 100 captured, 3 of them dropped (500 is past the end), 2 duplicated.
    assert_eq!(frames.len(), 99);
    for (k, &t) in stamps.iter().enumerate() {
        assert_eq!(t, (k as f64 * 1e9 / 2200.0).round() as i64);
    }
    // Capture 20 is delivery 18 (10 and 11 lost), repeated as delivery 19.
    assert_eq!(frames[18], frames[19]);
    // Capture 70: deliveries 68 and 69 (three lost before it, one repeat).
    assert_eq!(frames[68], frames[69]);
    let same = frames.windows(2).filter(|w| w[0] == w[1]).count();
    assert_eq!(same, 2, "exactly the two duplicates repeat");
}

/// A +12 dB resonance at 500 Hz (Q = 3) in the object's transfer function:
/// recovered power near 500 Hz rises by 12 dB against a flat object, and
/// far from it (150-200 Hz) by much less.
#[test]
fn object_resonance_shapes_the_recovered_spectrum() {
    let d = tempfile::tempdir().unwrap();
    let chirp = "duration_s = 2.0\namplitude_px = 0.03\nsignal = { type = \"chirp\", f0_hz = 100.0, f1_hz = 1000.0, duration_s = 2.0 }\n";
    let (rate, flat) = render_and_recover(d.path(), "flat", chirp);
    let (_, res) = render_and_recover(
        d.path(),
        "res",
        &format!("{chirp}resonances = [{{ freq_hz = 500.0, q = 3.0, gain_db = 12.0 }}]\n"),
    );
    let fs = rate as f64;
    let gain =
        |lo, hi| 10.0 * (band_power(&res, fs, lo, hi) / band_power(&flat, fs, lo, hi)).log10();
    let (at, away) = (gain(490.0, 510.0), gain(150.0, 200.0));
    eprintln!("resonance: {at:+.2} dB at 490-510 Hz, {away:+.2} dB at 150-200 Hz");
    assert!((at - 12.0).abs() < 1.5, "{at}");
    assert!(away.abs() < 2.0, "{away}");
}

/// Narrowband interference: a 0.025 px line at 137 Hz beside a 0.05 px
/// tone at 440 Hz shows up 6 dB below it.
#[test]
fn interference_adds_a_line() {
    let d = tempfile::tempdir().unwrap();
    let (rate, x) = render_and_recover(
        d.path(),
        "i",
        "signal = { type = \"tone\", freq_hz = 440.0 }\ninterference = [{ freq_hz = 137.0, amplitude_px = 0.025 }]\n",
    );
    let fs = rate as f64;
    let (f1, p1) = peak(&x, fs, 100.0, 200.0);
    let (f2, p2) = peak(&x, fs, 300.0, 600.0);
    let rel = 10.0 * (p1 / p2).log10();
    eprintln!("interference at {f1:.2} Hz, {rel:+.2} dB against the tone at {f2:.2} Hz");
    assert!((f1 - 137.0).abs() < 0.1 && (f2 - 440.0).abs() < 0.1);
    assert!((rel + 6.02).abs() < 1.0, "{rel}");
}

/// Errors name the scene file, the line and the field.
#[test]
fn scene_errors_name_the_file_line_and_field() {
    let d = tempfile::tempdir().unwrap();
    for (text, needles) in [
        ("width = 64\nfpss = 3\n", &["s.toml:2", "fpss"][..]),
        (
            "resonances = [{ freq_hz = 500.0, q = 0.0, gain_db = 3.0 }]\n",
            &["s.toml", "resonances", "q"][..],
        ),
        ("clock_error_ppm = 1e9\n", &["clock_error_ppm"][..]),
        (
            "width = \n",
            &["s.toml:1", "field `width`", "value is missing"][..],
        ),
    ] {
        std::fs::write(d.path().join("s.toml"), text).unwrap();
        let o = run_in(d.path(), &["simulate", "s.toml", "-o", "s.y4m"]);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{text}: {err}");
        for n in needles {
            assert!(err.contains(n), "`{n}` not in: {err}");
        }
        assert!(!err.contains("panicked"), "{err}");
    }
    let o = run_in(d.path(), &["simulate", "missing.toml"]);
    assert_eq!(code(&o), 2);
    assert!(stderr(&o).contains("missing.toml"));
}

/// A picture as the object's texture and a silhouette (issue 6, item 1):
/// the rendered object shows the picture (low-passed by the texture's
/// Gaussian), sub-pixel shifts of it stay exact against the continuous
/// model, the silhouette's outside shows the background and its inside the
/// object, and bad files are named.
#[test]
fn a_picture_texture_and_a_silhouette() {
    use vibroscope_engine::stages::sources::synthetic::SyntheticParams;
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    // Smooth stripes and a ramp: 64x64, the object's size.
    let pic = |x: usize, y: usize| {
        let v = 128.0
            + 60.0 * (x as f64 * std::f64::consts::TAU / 16.0).sin()
            + 40.0 * (y as f64 / 63.0 - 0.5);
        v.round() as u8
    };
    write_pgm(&dir.join("pic.pgm"), 64, 64, pic);
    // The silhouette: a disc of radius 24 in the 128x128 frame.
    let inside = |x: usize, y: usize| {
        let (dx, dy) = (x as f64 - 63.5, y as f64 - 63.5);
        dx * dx + dy * dy <= 24.0 * 24.0
    };
    write_pgm(&dir.join("disc.pgm"), 128, 128, |x, y| {
        if inside(x, y) {
            255
        } else {
            0
        }
    });
    let text = format!(
        "width = 128\nheight = 128\nobject = [32, 32, 64, 64]\nnoise_std = 0.0\namplitude_px = 1.0\n\
         texture = \"{}\"\nobject_mask = \"{}\"\n",
        dir.join("pic.pgm").display(),
        dir.join("disc.pgm").display()
    );
    let p: SyntheticParams = toml::from_str(&text).unwrap();
    let mut scene = p.scene().unwrap();
    let mut frame = vec![0.0f32; 128 * 128];
    for d_px in [0.0, 0.37, -0.81] {
        scene.render_clean_displaced(d_px, &mut frame);
        let mut worst = 0.0f64;
        for y in 0..128 {
            for x in 0..128 {
                let got = frame[y * 128 + x] as f64;
                let want = if inside(x, y) {
                    scene.object_value(x as f64, y as f64, d_px)
                } else {
                    scene.background_value(x as u32, y as u32)
                };
                worst = worst.max((got - want).abs());
            }
        }
        eprintln!("shift {d_px} px: worst error against the continuous model {worst:.2e} DN");
        assert!(worst < 1e-3, "shift {d_px}: {worst}");
    }
    // At rest the disc shows the picture: correlation of the object pixels
    // with the stripes (the Gaussian keeps 73% of their amplitude).
    scene.render_clean_displaced(0.0, &mut frame);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for y in 32..96 {
        for x in 32..96 {
            if inside(x, y) {
                a.push(frame[y * 128 + x] as f64);
                b.push(pic(x - 32, y - 32) as f64);
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (ma, mb) = (mean(&a), mean(&b));
    let cov: f64 = a.iter().zip(&b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma) * (x - ma)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb) * (y - mb)).sum();
    let r = cov / (va * vb).sqrt();
    eprintln!("correlation of the rendered object with the picture: {r:.4}");
    assert!(r > 0.98, "{r}");
    // Bad files: named, exit 2.
    for (extra, needles) in [
        ("texture = \"nope.png\"\n", &["texture", "nope.png"][..]),
        (
            "object_mask = \"pic.pgm\"\n",
            &["object_mask", "64x64", "128x128"][..],
        ),
    ] {
        std::fs::write(
            dir.join("s.toml"),
            format!("width = 128\nheight = 128\nduration_s = 0.01\n{extra}"),
        )
        .unwrap();
        let o = run_in(dir, &["simulate", "s.toml", "-o", "s.y4m"]);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{err}");
        for n in needles {
            assert!(err.contains(n), "`{n}` not in: {err}");
        }
    }
}
