//! Filters on replay and live (issue 14 part 1, issue 18 parts 3 and 5):
//! zero-phase alignment against the simulator's truth, `--band`/`--notch`,
//! `--rate` and the WAV headers every common reader takes.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;
use std::process::Command;

/// The render pipeline's settings for a scene whose motion has much of its
/// energy near the high-pass corner (a 30-250 Hz chirp at 2200 fps).
const LOW_CHIRP: &[&str] = &[
    "cam.duration_s=1.0",
    "cam.width=96",
    "cam.height=96",
    "cam.signal={ type = \"chirp\", f0_hz = 30.0, f1_hz = 250.0, duration_s = 1.0 }",
];

fn render(dir: &Path, sets: &[&str], path: &str) {
    let mut args = Vec::new();
    for s in sets {
        args.extend_from_slice(&["--set", s]);
    }
    render_y4m(dir, path, &args);
}

/// Lag (samples, within ±`max`) where |cross-correlation| of `est` with
/// `truth` peaks.
fn xcorr_peak(truth: &[f64], est: &[f32], max: i64) -> i64 {
    let n = truth.len().min(est.len()) as i64;
    let c = |l: i64| -> f64 {
        (max..n - max)
            .map(|k| truth[k as usize] * f64::from(est[(k + l) as usize]))
            .sum::<f64>()
            .abs()
    };
    (-max..=max).max_by(|&a, &b| c(a).total_cmp(&c(b))).unwrap()
}

/// A replay's output is aligned with the simulator's true motion at lag 0
/// (default `listen`: the high-pass resolves to zero-phase, and `--stats`
/// says so); the same graph with the causal high-pass lags behind the truth.
#[test]
fn replay_is_aligned_with_the_truth_at_lag_0() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, LOW_CHIRP, "low.y4m");
    let mut decl = vibroscope::pipeline::load("render").unwrap();
    for s in LOW_CHIRP {
        vibroscope_engine::config::apply_set(&mut decl, s).unwrap();
    }
    let o = run_in(
        d,
        &[
            "listen", "low.y4m", "--rate", "native", "--float", "--stats", "-o", "zp.wav",
        ],
    );
    let err = stderr(&o);
    assert_eq!(code(&o), 0, "{err}");
    assert!(err.contains("highpass: zero-phase"), "{err}");
    let (rate, zp) = read_wav(&d.join("zp.wav"));
    assert_eq!(rate, 2200);
    let truth = true_motion(&decl, "cam", zp.len());
    let lag = xcorr_peak(&truth, &zp, 20);
    let o = run_in(
        d,
        &[
            "run",
            "visual-microphone",
            "--replay",
            "low.y4m",
            "--quiet",
            "--stats",
            "--set",
            "highpass.mode=\"causal\"",
            "--set",
            "out.path=\"causal.wav\"",
        ],
    );
    let err = stderr(&o);
    assert_eq!(code(&o), 0, "{err}");
    assert!(err.contains("highpass: causal"), "{err}");
    let (_, causal) = read_wav(&d.join("causal.wav"));
    let causal_lag = xcorr_peak(&truth, &causal, 20);
    eprintln!("cross-correlation peak against the true motion: zero-phase lag {lag}, causal lag {causal_lag} samples");
    assert_eq!(lag, 0, "zero-phase replay is not aligned with the truth");
    assert_ne!(
        causal_lag, 0,
        "the causal high-pass should lag (this test could not tell)"
    );
}

/// Index of the strongest bin of `p` between `lo` and `hi` Hz.
fn peak_hz(p: &[f64], df: f64, lo: f64, hi: f64) -> f64 {
    let (a, b) = ((lo / df) as usize, ((hi / df) as usize).min(p.len() - 1));
    let k = (a..=b).max_by(|&i, &j| p[i].total_cmp(&p[j])).unwrap();
    k as f64 * df
}

/// Power (sum over bins) of `p` within `f ± w` Hz.
fn band_power(p: &[f64], df: f64, f: f64, w: f64) -> f64 {
    (((f - w) / df) as usize..=((f + w) / df) as usize)
        .map(|k| p[k])
        .sum()
}

/// Two tones (150 and 600 Hz) seen by the camera, replayed through
/// `listen` at 48 kHz (16-bit, the default format): each tone's spectral
/// peak is at its frequency; `--band 400,800` lowers the 150 Hz tone
/// against the 600 Hz one by at least 20 dB (|H|² of the order-2 design is
/// -28 dB there), and `--notch 600,60` does the reverse.
#[test]
fn band_and_notch_on_a_replay_at_48k() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(
        d,
        &[
            "cam.duration_s=0.5",
            "cam.width=96",
            "cam.height=96",
            "cam.signal={ type = \"tones\", freqs_hz = [150.0, 600.0], weights = [1.0, 1.0] }",
        ],
        "two.y4m",
    );
    let ratio_db = |args: &[&str], out: &str| -> (f64, f64, f64) {
        let mut a = vec!["listen", "two.y4m", "--rate", "48000", "-o", out];
        a.extend_from_slice(args);
        let o = run_in(d, &a);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let (rate, x) = read_wav(&d.join(out));
        assert_eq!(rate, 48_000);
        assert_eq!(x.len(), 24_000, "0.5 s at 48 kHz");
        let (p, df) = power_spectrum(&x, 48_000.0, 1 << 17);
        let r = 10.0 * (band_power(&p, df, 150.0, 5.0) / band_power(&p, df, 600.0, 5.0)).log10();
        (
            r,
            peak_hz(&p, df, 100.0, 300.0),
            peak_hz(&p, df, 400.0, 900.0),
        )
    };
    let (plain, f1, f2) = ratio_db(&[], "plain.wav");
    eprintln!("plain: 150/600 Hz power {plain:.1} dB, peaks {f1:.1} and {f2:.1} Hz");
    assert!(
        (f1 - 150.0).abs() < 1.0 && (f2 - 600.0).abs() < 1.0,
        "{f1} {f2}"
    );
    let (band, ..) = ratio_db(&["--band", "400,800"], "band.wav");
    let (notch, ..) = ratio_db(&["--notch", "600,60"], "notch.wav");
    eprintln!("--band 400,800: {band:.1} dB; --notch 600,60: {notch:.1} dB");
    assert!(
        band < plain - 20.0,
        "--band 400,800: {plain:.1} -> {band:.1} dB"
    );
    assert!(
        notch > plain + 20.0,
        "--notch 600,60: {plain:.1} -> {notch:.1} dB"
    );
}

/// Bad bands: a clear message naming the flag and the value, exit 2, no
/// panic, and no WAV written.
#[test]
fn bad_bands_are_usage_errors_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(
        d,
        &["cam.duration_s=0.05", "cam.width=32", "cam.height=32"],
        "s.y4m",
    );
    for (args, words) in [
        (
            &["--band", "100,1500"][..],
            &["--band", "100,1500", "Nyquist", "1100"][..],
        ),
        (&["--band", "500,300"], &["--band", "500,300"]),
        (&["--notch", "50,0"], &["--notch", "50,0", "width"]),
        (&["--notch", "50,-4"], &["--notch", "50,-4", "width"]),
        (&["--notch", "-50"], &["--notch", "-50"]),
        (&["--notch", "1090,40"], &["--notch", "Nyquist"]),
        (&["--band", "abc"], &["--band", "abc"]),
        (&["--rate", "12"], &["--rate", "12"]),
    ] {
        let mut a = vec!["listen", "s.y4m", "-o", "bad.wav"];
        a.extend_from_slice(args);
        let o = run_in(d, &a);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        for w in words {
            assert!(err.contains(w), "{args:?}: `{w}` not in: {err}");
        }
        assert!(!d.join("bad.wav").exists(), "{args:?} wrote a file");
    }
}

/// A Python interpreter that imports `module`, if any.
fn python_with(module: &str) -> Option<&'static str> {
    ["python3", "/usr/bin/python3"].into_iter().find(|p| {
        Command::new(p)
            .args(["-c", &format!("import {module}")])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// Every kind of WAV the project writes (listen's 16-bit default and
/// `--float`, the wav sink's f32 and i16, io::wav's whole-file f32 and
/// i16) is read by `sox --i`, Python's `wave` (PCM) and
/// `scipy.io.wavfile` without a warning. Each tool is skipped, with a
/// reason, when absent.
#[test]
fn sox_and_python_read_every_wav_without_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(
        d,
        &["cam.duration_s=0.1", "cam.width=48", "cam.height=48"],
        "s.y4m",
    );
    let mut files: Vec<(&str, bool)> = Vec::new();
    for (args, out, pcm) in [
        (&[][..], "listen.wav", true),
        (&["--float"][..], "listen-f32.wav", false),
    ] {
        let mut a = vec!["listen", "s.y4m", "-o", out];
        a.extend_from_slice(args);
        let o = run_in(d, &a);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        files.push((out, pcm));
    }
    for (fmt, out, pcm) in [
        ("f32", "sink-f32.wav", false),
        ("i16", "sink-i16.wav", true),
    ] {
        let set_fmt = format!("out.format=\"{fmt}\"");
        let set_out = format!("out.path=\"{out}\"");
        let o = run_in(
            d,
            &[
                "run",
                "visual-microphone",
                "--replay",
                "s.y4m",
                "--quiet",
                "--set",
                &set_fmt,
                "--set",
                &set_out,
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        files.push((out, pcm));
    }
    let x: Vec<f64> = (0..1000).map(|i| (i as f64 * 0.1).sin() * 0.5).collect();
    vibroscope_io::wav::write_mono_f32(&d.join("io-f32.wav"), 8000, &x).unwrap();
    vibroscope_io::wav::write_mono_i16(&d.join("io-i16.wav"), 8000, &x, 1.0).unwrap();
    files.push(("io-f32.wav", false));
    files.push(("io-i16.wav", true));
    let mut checked = 0;
    if Command::new("sox").arg("--version").output().is_ok() {
        for (f, _) in &files {
            let o = Command::new("sox")
                .current_dir(d)
                .args(["--i", f])
                .output()
                .unwrap();
            let err = stderr(&o);
            assert!(o.status.success(), "sox --i {f}: {err}");
            assert!(!err.to_lowercase().contains("warn"), "sox --i {f}: {err}");
            checked += 1;
        }
    } else {
        eprintln!("skipping sox: not installed (Debian package sox)");
    }
    let script = |f: &str, pcm: bool| {
        format!(
            "import warnings\nwarnings.simplefilter('error')\nimport scipy.io.wavfile as w\nr, x = w.read('{f}')\nassert len(x) > 0\n{}",
            if pcm {
                format!("import wave\nv = wave.open('{f}')\nassert v.getsampwidth() == 2 and v.getnframes() == len(x)\n")
            } else {
                String::new()
            }
        )
    };
    match python_with("scipy.io.wavfile") {
        Some(py) => {
            for (f, pcm) in &files {
                let o = Command::new(py)
                    .current_dir(d)
                    .args(["-c", &script(f, *pcm)])
                    .output()
                    .unwrap();
                assert!(o.status.success(), "{py} on {f}: {}", stderr(&o));
                assert!(stderr(&o).is_empty(), "{py} on {f}: {}", stderr(&o));
                checked += 1;
            }
        }
        None => eprintln!("skipping Python: no python3 with scipy (Debian package python3-scipy)"),
    }
    eprintln!(
        "{checked} reads of {} WAV files without a warning",
        files.len()
    );
}

/// The guitar clip (shared data) at 48 kHz: the spectrum of
/// `listen --rate 48000` peaks within 3 Hz of the two low strings (~81 and
/// ~108 Hz, the README's figures at the frame rate).
#[test]
fn guitar_at_48k_peaks_at_the_string_frequencies() {
    let Some(g) = guitar_with_ffmpeg() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let g = g.to_str().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "listen",
            g,
            "--fps",
            "600",
            "--roi",
            "80,20,120,110",
            "--rate",
            "48000",
            "-o",
            "g.wav",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let (rate, x) = read_wav(&dir.path().join("g.wav"));
    assert_eq!(rate, 48_000);
    let (p, df) = power_spectrum(&x, 48_000.0, 1 << 20);
    let (e, a) = (peak_hz(&p, df, 60.0, 95.0), peak_hz(&p, df, 95.0, 125.0));
    let top = peak_hz(&p, df, 30.0, 300.0);
    eprintln!("guitar at 48 kHz: strongest {top:.1} Hz; E2 band {e:.1} Hz, A2 band {a:.1} Hz");
    assert!(
        (top - e).abs() < 0.5,
        "the strongest peak {top:.1} Hz is not the E string's"
    );
    assert!((e - 81.0).abs() < 3.0, "E2 peak at {e:.1} Hz");
    assert!((a - 108.5).abs() < 3.0, "A2 peak at {a:.1} Hz");
}
