//! The phase-based visual microphone (thesis ch. 3-4) against ground truth:
//! the forward model's known motion, and a real recording with known
//! physics (guitar strings E2 82.4 Hz and A2 110 Hz, filmed at 600 fps).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;

/// Frequencies of the `k` strongest local maxima within [lo, hi] Hz.
fn top_peaks(p: &[f64], df: f64, lo: f64, hi: f64, k: usize) -> Vec<f64> {
    let mut peaks: Vec<(f64, f64)> = (1..p.len() - 1)
        .filter(|&i| p[i] > p[i - 1] && p[i] >= p[i + 1])
        .map(|i| (i as f64 * df, p[i]))
        .filter(|&(f, _)| f >= lo && f <= hi)
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.into_iter().take(k).map(|p| p.0).collect()
}

#[test]
fn guitar_strings_are_heard_at_their_pitches() {
    let Some(video) = guitar_with_ffmpeg() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "run",
            "visual-microphone",
            "--replay",
            video.to_str().unwrap(),
            "--fps",
            "600",
            "--set",
            "out.path=g.wav",
            "--quiet",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let (rate, x) = read_wav(&dir.path().join("g.wav"));
    assert_eq!((rate, x.len()), (600, 300));
    let (p, df) = power_spectrum(&x, rate as f64, 4096);
    let peaks = top_peaks(&p, df, 40.0, 290.0, 3);
    eprintln!("strongest peaks: {peaks:?} Hz");
    for want in [82.4, 110.0] {
        assert!(
            peaks.iter().any(|f| (f - want).abs() <= 3.0),
            "no peak within 3 Hz of {want} Hz among {peaks:?}"
        );
    }
}

#[test]
fn synthetic_chirp_is_recovered() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "--set",
        "src.width=128",
        "--set",
        "src.height=128",
        "--set",
        "src.duration_s=0.5",
        "--set",
        "src.signal={ type = \"tone\", freq_hz = 440.0 }",
        "--set",
        "out.path=s.wav",
        "--quiet",
    ];
    let mut all = vec!["run", "visual-microphone"];
    all.extend_from_slice(&args);
    let o = run_in(dir.path(), &all);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let (rate, x) = read_wav(&dir.path().join("s.wav"));
    assert_eq!((rate, x.len()), (2200, 1100));
    let (p, df) = power_spectrum(&x, rate as f64, 8192);
    let peaks = top_peaks(&p, df, 50.0, 1100.0, 1);
    assert!((peaks[0] - 440.0).abs() < 2.0, "{peaks:?}");
}

/// Output SNR (dB) of the visual-microphone pipeline (phase, align; no
/// high-pass, so the output is compared with the motion itself) against the
/// forward model's true motion, for a scene given as `--set` overrides.
fn snr_of(dir: &std::path::Path, sets: &[String]) -> f64 {
    let text = "[[stage]]\nid = \"src\"\nkind = \"synthetic\"\nwidth = 256\nheight = 256\nfps = 2200.0\nduration_s = 0.5\n\n\
                [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\n\n\
                [[stage]]\nid = \"align\"\nkind = \"align\"\ninput = \"phase\"\n\n\
                [[stage]]\nid = \"out\"\nkind = \"wav\"\ninput = \"align\"\npath = \"law.wav\"\n";
    std::fs::write(dir.join("law.toml"), text).unwrap();
    let mut args: Vec<String> = vec!["run".into(), "law.toml".into(), "--quiet".into()];
    for s in sets {
        args.push("--set".into());
        args.push(s.clone());
    }
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run_in(dir, &argv);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let (_, est) = read_wav(&dir.join("law.wav"));
    // Ground truth from the same forward model and parameters.
    let mut decl = vibroscope_engine::config::parse("law.toml", text).unwrap();
    for s in sets {
        vibroscope_engine::config::apply_set(&mut decl, s).unwrap();
    }
    let truth = true_motion(&decl, "src", est.len());
    let est: Vec<f64> = est.iter().map(|&v| v as f64).collect();
    vibroscope_math::truth::snr_db_fit(&truth, &est)
}

/// Thesis Eq. 4.3 in the noise-limited regime, for one driving signal:
/// SNR grows 6 dB when the motion doubles or the object has four times the
/// pixels, and drops 6 dB when the sensor noise doubles (each +/- 1.5 dB).
fn check_noise_law(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let base = |amp: f64, noise: f64, obj: u32| {
        let off = (256 - obj) / 2;
        vec![
            format!("src.signal={signal}"),
            format!("src.amplitude_px={amp}"),
            format!("src.noise_std={noise}"),
            format!("src.object=[{off}, {off}, {obj}, {obj}]"),
            format!("phase.roi=[{off}, {off}, {obj}, {obj}]"),
        ]
    };
    let s0 = snr_of(dir.path(), &base(0.02, 2.0, 120));
    let amp2 = snr_of(dir.path(), &base(0.04, 2.0, 120)) - s0;
    let pix4 = snr_of(dir.path(), &base(0.02, 2.0, 240)) - s0;
    let noise2 = snr_of(dir.path(), &base(0.02, 4.0, 120)) - s0;
    eprintln!("{signal}: base SNR {s0:.1} dB; 2x amplitude {amp2:+.2} dB; 4x pixels {pix4:+.2} dB; 2x noise {noise2:+.2} dB");
    assert!((amp2 - 6.0).abs() <= 1.5, "2x amplitude: {amp2:+.2} dB");
    assert!((pix4 - 6.0).abs() <= 1.5, "4x pixels: {pix4:+.2} dB");
    assert!((noise2 + 6.0).abs() <= 1.5, "2x noise: {noise2:+.2} dB");
}

#[test]
fn snr_law_on_a_chirp() {
    check_noise_law("{ type = \"chirp\", f0_hz = 100.0, f1_hz = 1000.0, duration_s = 0.5 }");
}

#[test]
fn snr_law_on_speech() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("speech.wav");
    let spoke = std::process::Command::new("espeak-ng")
        .args([
            "-w",
            wav.to_str().unwrap(),
            "Visual microphones recover sound from video.",
        ])
        .output();
    if !spoke.map(|o| o.status.success()).unwrap_or(false) {
        eprintln!("skipping: espeak-ng is not installed (Debian package espeak-ng)");
        return;
    }
    check_noise_law(&format!(
        "{{ type = \"wav\", path = \"{}\" }}",
        wav.display()
    ));
}

/// Writes `ref.wav` in `d`: an espeak-ng sentence at 2200 Hz. False (with
/// the reason printed) when espeak-ng or sox is missing.
fn speech_reference(d: &std::path::Path) -> bool {
    let ok = std::process::Command::new("espeak-ng")
        .args([
            "-w",
            d.join("sp.wav").to_str().unwrap(),
            "Visual microphones recover sound from the tiny vibrations of objects.",
        ])
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
        && std::process::Command::new("sox")
            .args([
                // Repeatable: sox dithers its 16-bit output with a seed
                // taken from the clock, so without -R the reference (and
                // every figure measured on it) moved from run to run.
                "-R",
                d.join("sp.wav").to_str().unwrap(),
                "-r",
                "2200",
                "-c",
                "1",
                d.join("ref.wav").to_str().unwrap(),
            ])
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
    if !ok {
        eprintln!("skipping: espeak-ng and sox are needed (Debian packages espeak-ng, sox)");
    }
    ok
}

/// Renders `sp.y4m` in `d`: a `size` x `size` scene moved by `ref.wav`
/// (`amplitude` a `--set`, `extra` more arguments); returns the reference.
fn render_speech(d: &std::path::Path, size: usize, amplitude: &str, extra: &[&str]) -> Vec<f64> {
    let (_, reference) = vibroscope_io::wav::read_mono(&d.join("ref.wav")).unwrap();
    let signal = format!(
        "cam.signal={{ type = \"wav\", path = \"{}\" }}",
        d.join("ref.wav").display()
    );
    let dur = format!("cam.duration_s={}", reference.len() as f64 / 2200.0);
    let (w, h) = (format!("cam.width={size}"), format!("cam.height={size}"));
    let mut args = vec![
        "--set", &signal, "--set", &dur, "--set", &w, "--set", &h, "--set", amplitude,
    ];
    args.extend_from_slice(extra);
    render_y4m(d, "sp.y4m", &args);
    reference
}

/// `listen VIDEO --denoise MODE --rate native -o MODE.wav` on `sp.y4m` in
/// `d`, then `score ref.wav MODE.wav`: its JSON.
fn listen_and_score(d: &std::path::Path, mode: &str) -> serde_json::Value {
    listen_scored(d, "sp.y4m", &format!("{mode}.wav"), &["--denoise", mode])
}

/// `listen VIDEO -o OUT --rate native` with `args` in `d`, then `score
/// ref.wav OUT`: its JSON.
fn listen_scored(d: &std::path::Path, video: &str, out: &str, args: &[&str]) -> serde_json::Value {
    let mut a = vec!["listen", video, "-o", out, "--rate", "native"];
    a.extend_from_slice(args);
    let o = run_in(d, &a);
    assert_eq!(code(&o), 0, "{args:?}: {}", stderr(&o));
    let o = run_in(d, &["score", "ref.wav", out]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    serde_json::from_str(&stdout(&o)).unwrap()
}

/// `listen` with each denoiser on a rendered speech scene: the output keeps
/// one sample per frame, aligned, and every denoiser raises SNR and
/// segmental SNR against the sound that drove the scene.
#[test]
fn listen_with_denoising_improves_speech() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    if !speech_reference(d) {
        return;
    }
    let reference = render_speech(d, 192, "cam.amplitude_px=0.02", &[]);
    let mut scores = Vec::new();
    for mode in ["none", "subtract", "enhance", "wiener"] {
        let v = listen_and_score(d, mode);
        assert_eq!(
            read_wav(&d.join(format!("{mode}.wav"))).1.len(),
            reference.len(),
            "{mode}: one sample per frame"
        );
        eprintln!("{mode}: {v}");
        scores.push((
            v["snr_db"].as_f64().unwrap(),
            v["ssnr_db"].as_f64().unwrap(),
        ));
    }
    for (i, mode) in [(1, "subtract"), (2, "enhance"), (3, "wiener")] {
        assert!(
            scores[i].0 >= scores[0].0 + 1.0,
            "{mode}: SNR {:.2} vs {:.2} dB without",
            scores[i].0,
            scores[0].0
        );
        assert!(
            scores[i].1 >= scores[0].1 + 1.0,
            "{mode}: segSNR {:.2} vs {:.2} dB without",
            scores[i].1,
            scores[0].1
        );
    }
}

#[test]
fn listen_rejects_a_bad_roi_and_a_missing_video() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(dir.path(), &["listen", "nope.y4m", "--roi", "1,2,3"]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("--roi"), "{}", stderr(&o));
    let o = run_in(dir.path(), &["listen", "nope.y4m"]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("nope.y4m"), "{}", stderr(&o));
}

/// The method's flags: `--sources` out of 1-4 or with `--method phase`,
/// `--pyramid riesz` or `--calibration` with `--method gradient`, `--method`
/// with `--rolling-shutter`: a message naming the flag, exit 2, no WAV.
#[test]
fn listen_refuses_flags_its_method_does_not_take() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(
        d,
        "v.y4m",
        &[
            "--set",
            "cam.width=32",
            "--set",
            "cam.height=32",
            "--set",
            "cam.duration_s=0.1",
        ],
    );
    std::fs::write(d.join("cal.json"), "{}").unwrap();
    for (args, flag) in [
        (&["--sources", "0"][..], "--sources"),
        (&["--sources", "5"][..], "--sources"),
        (&["--sources", "2", "--method", "phase"][..], "--sources"),
        (&["--pyramid", "riesz"][..], "--pyramid"),
        (&["--half-grids"][..], "--half-grids"),
        (
            &["--half-grids", "--method", "phase", "--pyramid", "riesz"][..],
            "--half-grids",
        ),
        (
            &[
                "--half-grids",
                "--method",
                "phase",
                "--calibration",
                "cal.json",
            ][..],
            "--half-grids",
        ),
        (
            &["--pyramid", "riesz", "--method", "gradient"][..],
            "--pyramid",
        ),
        (
            &["--method", "gradient", "--calibration", "cal.json"][..],
            "--method",
        ),
        (
            &[
                "--method",
                "phase",
                "--rolling-shutter",
                "--line-delay-us",
                "20",
            ][..],
            "--method",
        ),
    ] {
        let mut a = vec!["listen", "v.y4m", "-o", "out.wav"];
        a.extend_from_slice(args);
        let o = run_in(d, &a);
        eprintln!("{args:?}: exit {} {}", code(&o), stderr(&o).trim());
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(flag), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{args:?}");
        assert!(!d.join("out.wav").exists(), "{args:?}");
    }
    // Both methods run on the same video, and --sources 2 with the default.
    for args in [
        &["--method", "phase", "--pyramid", "riesz"][..],
        &["--method", "phase", "--half-grids"][..],
        &["--sources", "2"][..],
    ] {
        let mut a = vec!["listen", "v.y4m", "-o", "out.wav"];
        a.extend_from_slice(args);
        let o = run_in(d, &a);
        assert_eq!(code(&o), 0, "{args:?}: {}", stderr(&o));
        std::fs::remove_file(d.join("out.wav")).unwrap();
    }
}

/// Motion of pixels, where the default method's linearised least squares
/// distort: a 100 Hz tone of 3 px peak makes `listen` warn and point to
/// `--method phase`; one of 0.1 px does not. It is a warning, not an error:
/// the WAV is written.
#[test]
fn a_motion_of_pixels_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (amplitude, warned) in [("3.0", true), ("0.1", false)] {
        let amp = format!("cam.amplitude_px={amplitude}");
        let sets = [
            "cam.width=64 cam.height=64 cam.duration_s=0.5",
            "cam.signal={ type = \"tone\", freq_hz = 100.0 }",
        ];
        let mut args: Vec<&str> = sets[0].split(' ').flat_map(|s| ["--set", s]).collect();
        args.extend(["--set", sets[1], "--set", &amp]);
        render_y4m(d, "v.y4m", &args);
        let o = run_in(d, &["listen", "v.y4m", "-o", "out.wav"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let err = stderr(&o);
        eprintln!("{amplitude} px: {}", err.trim());
        assert_eq!(
            err.contains("--method phase"),
            warned,
            "{amplitude} px: {err}"
        );
        assert!(d.join("out.wav").exists());
        std::fs::remove_file(d.join("out.wav")).unwrap();
    }
}

/// Writes a binary PGM of 256x256 with `inside(x, y)` pixels at 255.
fn write_mask(path: &std::path::Path, inside: impl Fn(usize, usize) -> bool) {
    let mut b = b"P5\n256 256\n255\n".to_vec();
    for y in 0..256 {
        for x in 0..256 {
            b.push(if inside(x, y) { 255 } else { 0 });
        }
    }
    std::fs::write(path, b).unwrap();
}

/// A PGM mask selects the pixels that count (issue 3, item 2): a mask equal
/// to the object's rectangle gives the rectangle's result; a disc inside
/// the object, with 44% of its pixels, loses what Eq. 4.3 predicts
/// (10 log10 of the pixel ratio, -3.5 dB); the still background alone
/// hears nothing.
#[test]
fn a_pgm_mask_selects_the_pixels_that_count() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let object = |x: usize, y: usize| (64..192).contains(&x) && (64..192).contains(&y);
    write_mask(&dir.join("object.pgm"), object);
    write_mask(&dir.join("disc.pgm"), |x, y| {
        let (dx, dy) = (x as f64 - 127.5, y as f64 - 127.5);
        dx * dx + dy * dy <= 48.0 * 48.0
    });
    write_mask(&dir.join("background.pgm"), |x, y| {
        !object(x, y) && (x < 40 || y < 40)
    });
    let base = ["src.noise_std=4.0".to_string()];
    let with = |extra: &str| {
        let mut v = base.to_vec();
        v.push(extra.to_string());
        snr_of(dir, &v)
    };
    let rect = with("phase.roi=[64, 64, 128, 128]");
    let mask = with("phase.mask=\"object.pgm\"");
    let disc = with("phase.mask=\"disc.pgm\"");
    let bg = with("phase.mask=\"background.pgm\"");
    let disc_pixels = (0..256 * 256)
        .filter(|i| {
            let (dx, dy) = ((i % 256) as f64 - 127.5, (i / 256) as f64 - 127.5);
            dx * dx + dy * dy <= 48.0 * 48.0
        })
        .count() as f64;
    let predicted = 10.0 * (disc_pixels / (128.0 * 128.0)).log10();
    eprintln!(
        "SNR: roi {rect:.2} dB, object mask {mask:.2} dB, disc {disc:.2} dB ({:+.2}, Eq. 4.3 predicts {predicted:+.2}), background {bg:.2} dB",
        disc - mask
    );
    assert!((mask - rect).abs() < 1.0, "mask {mask} vs roi {rect}");
    assert!(
        (disc - mask - predicted).abs() < 1.5,
        "disc {disc} vs {mask}"
    );
    assert!(bg < rect - 20.0, "background {bg} vs object {rect}");
    // A mask of the wrong size, and one that does not exist, are named.
    std::fs::write(dir.join("small.pgm"), b"P5\n2 2\n255\n\x01\x01\x01\x01").unwrap();
    for (m, needle, want) in [("small.pgm", "2x2", 1), ("missing.pgm", "missing.pgm", 2)] {
        let o = run_in(
            dir,
            &[
                "run",
                "law.toml",
                "--quiet",
                "--set",
                &format!("phase.mask=\"{m}\""),
            ],
        );
        assert_eq!(code(&o), want, "{}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{}", stderr(&o));
    }
}

/// Least-squares fit of `x` on the columns `cols` (each `x.len()` long):
/// the coefficients and the residual energy.
fn lstsq(cols: &[Vec<f64>], x: &[f64]) -> (Vec<f64>, f64) {
    let k = cols.len();
    let mut a = vec![vec![0.0; k + 1]; k];
    for i in 0..k {
        for j in 0..k {
            a[i][j] = cols[i].iter().zip(&cols[j]).map(|(p, q)| p * q).sum();
        }
        a[i][k] = cols[i].iter().zip(x).map(|(p, q)| p * q).sum();
    }
    // Gauss-Jordan with partial pivoting.
    for c in 0..k {
        let p = (c..k)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        let pivot = a[c].clone();
        for (r, row) in a.iter_mut().enumerate() {
            if r != c {
                let f = row[c] / pivot[c];
                for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                    *x -= f * p;
                }
            }
        }
    }
    let coef: Vec<f64> = (0..k).map(|i| a[i][k] / a[i][i]).collect();
    let res = x
        .iter()
        .enumerate()
        .map(|(n, v)| {
            let m: f64 = (0..k).map(|i| coef[i] * cols[i][n]).sum();
            (v - m) * (v - m)
        })
        .sum();
    (coef, res)
}

/// Drift beyond half a wavelength (issue 3, item 2): the object slides
/// 6 px over 3 s (the finest band's wavelength is 4 px) while it vibrates
/// 0.05 px at 150 Hz. With the reference renewed every second (the
/// default) the tone keeps its amplitude to the end and the output follows
/// the drift; with the first frame as the only reference (the comparison,
/// which shows the test can fail) the phase wraps: the tone's amplitude
/// wanders and the output no longer follows the drift.
#[test]
fn a_slow_drift_beyond_half_a_wavelength_is_followed() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let (fps, secs, drift_px, tone_px, f0) = (1000.0, 3.0, 6.0, 0.05, 150.0);
    let rate = 16000u32;
    let n = (secs * rate as f64) as usize;
    let motion: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / rate as f64;
            drift_px * t / secs + tone_px * (2.0 * std::f64::consts::PI * f0 * t).sin()
        })
        .collect();
    let peak = motion.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(dir.join("drift.wav"), spec).unwrap();
    for v in &motion {
        w.write_sample((v / peak) as f32).unwrap();
    }
    w.finalize().unwrap();
    let text = format!(
        "[[stage]]\nid = \"src\"\nkind = \"synthetic\"\nwidth = 96\nheight = 96\nfps = {fps}\nduration_s = {secs}\n\
         object = [16, 16, 64, 64]\namplitude_px = {peak}\nsignal = {{ type = \"wav\", path = \"drift.wav\" }}\n\n\
         [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\nroi = [16, 16, 64, 64]\n\n\
         [[stage]]\nid = \"align\"\nkind = \"align\"\ninput = \"phase\"\n\n\
         [[stage]]\nid = \"out\"\nkind = \"wav\"\ninput = \"align\"\npath = \"drift-out.wav\"\n"
    );
    std::fs::write(dir.join("drift.toml"), text).unwrap();
    let frames = (secs * fps) as usize;
    let truth_drift: Vec<f64> = (0..frames)
        .map(|i| drift_px * i as f64 / fps / secs)
        .collect();
    // Per 0.25 s segment: the tone's amplitude, from a fit of
    // [sin, cos, 1, t, t²] (the polynomial takes the drift).
    let seg = (0.25 * fps) as usize;
    let analyse = |interval: &str| {
        let o = run_in(
            dir,
            &[
                "run",
                "drift.toml",
                "--quiet",
                "--set",
                &format!("phase.reference_interval_s={interval}"),
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let (_, est) = read_wav(&dir.join("drift-out.wav"));
        assert_eq!(est.len(), frames);
        let est: Vec<f64> = est.iter().map(|&v| v as f64).collect();
        let amps: Vec<f64> = est
            .chunks_exact(seg)
            .enumerate()
            .map(|(s, x)| {
                let t = |i: usize| (s * seg + i) as f64 / fps;
                let w = 2.0 * std::f64::consts::PI * f0;
                let cols = vec![
                    (0..seg).map(|i| (w * t(i)).sin()).collect(),
                    (0..seg).map(|i| (w * t(i)).cos()).collect(),
                    vec![1.0; seg],
                    (0..seg).map(|i| i as f64 / seg as f64).collect(),
                    (0..seg).map(|i| (i as f64 / seg as f64).powi(2)).collect(),
                ];
                let (c, _) = lstsq(&cols, x);
                c[0].hypot(c[1])
            })
            .collect();
        // How well a gain and an offset on the true drift explain the
        // output once the tone is fitted out too.
        let w = 2.0 * std::f64::consts::PI * f0;
        let cols = vec![
            truth_drift.clone(),
            vec![1.0; frames],
            (0..frames).map(|i| (w * i as f64 / fps).sin()).collect(),
            (0..frames).map(|i| (w * i as f64 / fps).cos()).collect(),
        ];
        let (_, res) = lstsq(&cols, &est);
        let mean = est.iter().sum::<f64>() / frames as f64;
        let var: f64 = est.iter().map(|v| (v - mean) * (v - mean)).sum();
        let r2 = 1.0 - res / var;
        (amps, r2)
    };
    let (renewed, r2) = analyse("1.0");
    let (fixed, r2_fixed) = analyse("0");
    eprintln!(
        "tone amplitude per 0.25 s, renewed every 1 s: {renewed:.4?} drift R² {r2:.5}\n\
         first frame as the only reference: {fixed:.4?}, drift R² {r2_fixed:.5}"
    );
    // The tone keeps its amplitude within 10% in every segment, and the
    // drift explains the rest of the output (R² > 0.999).
    let holds = |amps: &[f64], r2: f64| -> Result<(), String> {
        if let Some((i, a)) = amps
            .iter()
            .enumerate()
            .find(|(_, a)| (*a / amps[0] - 1.0).abs() >= 0.1)
        {
            return Err(format!(
                "segment {i}: tone amplitude {a} vs {} at the start",
                amps[0]
            ));
        }
        if r2 <= 0.999 {
            return Err(format!("the output does not follow the drift: R² {r2}"));
        }
        Ok(())
    };
    holds(&renewed, r2).unwrap();
    assert!(
        holds(&fixed, r2_fixed).is_err(),
        "without renewal the check should fail"
    );
}

/// The MMSE (Wiener) denoiser against the limit of any fixed filter (issue
/// 14): on rendered speech scenes with two textures (the simulator's random
/// one and a smooth picture) at two noise levels, `listen --denoise wiener`
/// scores within 1 dB of (or above) the SNR that a stationary Wiener filter
/// built from the true signal and noise spectra reaches on the undenoised
/// recovery (`score`'s `wiener_bound_db`).
#[test]
fn the_wiener_denoiser_reaches_the_stationary_wiener_bound() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    if !speech_reference(d) {
        return;
    }
    smooth_picture(&d.join("pic.pgm"), 48);
    let picture = format!("cam.texture=\"{}\"", d.join("pic.pgm").display());
    let mut failed = Vec::new();
    for (texture, extra) in [
        ("random texture", "cam.seed=1"),
        ("picture", picture.as_str()),
    ] {
        for noise in [1.0, 3.0] {
            let noise_set = format!("cam.noise_std={noise}");
            render_speech(
                d,
                96,
                "cam.amplitude_px=0.1",
                &["--set", &noise_set, "--set", extra],
            );
            let snr = ["none", "wiener"].map(|mode| listen_and_score(d, mode));
            let before = snr[0]["snr_db"].as_f64().unwrap();
            let bound = snr[0]["wiener_bound_db"].as_f64().unwrap();
            let after = snr[1]["snr_db"].as_f64().unwrap();
            eprintln!(
                "{texture}, {noise} DN: SNR {before:.2} dB undenoised, stationary Wiener bound {bound:.2} dB, wiener {after:.2} dB ({:+.2} dB from the bound)",
                after - bound
            );
            assert!(
                bound > before,
                "{texture}, {noise} DN: the bound {bound:.2} dB should exceed the undenoised {before:.2} dB"
            );
            if after < bound - 1.0 {
                failed.push(format!(
                    "{texture}, {noise} DN: {after:.2} dB vs bound {bound:.2}"
                ));
            }
        }
    }
    assert!(
        failed.is_empty(),
        "more than 1 dB under the stationary Wiener bound: {failed:?}"
    );
}

/// Default `listen` against the Cramér-Rao bound (issue 14): on rendered
/// speech scenes with two textures (the simulator's random one and a smooth
/// picture) at two noise levels (and the issue's scene, 0.03 px at 2 DN),
/// with no region given, `listen` scores
/// within 1 dB of the SNR that the bound allows an unbiased estimator of
/// the object's per-frame motion. The bound comes from the simulator's
/// truth: the exact derivatives of its continuous texture over the object's
/// pixels along the motion, the sensor noise plus quantisation (1/12 DN²),
/// and the true motion's mean square. The thesis pipeline (`--method
/// phase`) is scored too, and printed.
#[test]
fn listen_comes_within_1_db_of_the_cramer_rao_bound() {
    use vibroscope_engine::stages::sources::synthetic::SyntheticParams;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    if !speech_reference(d) {
        return;
    }
    smooth_picture(&d.join("pic.pgm"), 48);
    let (_, reference) = vibroscope_io::wav::read_mono(&d.join("ref.wav")).unwrap();
    let (size, object) = (96usize, [24usize, 24, 48, 48]);
    let picture = format!("texture = \"{}\"\n", d.join("pic.pgm").display());
    let mut failed = Vec::new();
    for (texture, extra) in [("random texture", "seed = 1\n"), ("picture", &picture[..])] {
        // Two noise levels at 0.1 px, and the issue's own scene (0.03 px
        // at 2 DN), where the weights are hardest to learn.
        for (amplitude, noise) in [(0.1, 1.0), (0.1, 3.0), (0.03, 2.0)] {
            let text = simulate_speech(d, size, reference.len(), (amplitude, noise), extra);
            let p: SyntheticParams = toml::from_str(&text).unwrap();
            let scene = p.scene().unwrap();
            // Fisher information of the object's pixels along x (the
            // motion's direction) over the noise variance.
            let h = 1e-3;
            let mut info = 0.0;
            for y in object[1]..object[1] + object[3] {
                for x in object[0]..object[0] + object[2] {
                    let (x, y) = (x as f64, y as f64);
                    let g = (scene.object_value(x + h, y, 0.0) - scene.object_value(x - h, y, 0.0))
                        / (2.0 * h);
                    info += g * g;
                }
            }
            let crb = (noise * noise + 1.0 / 12.0) / info;
            let power = (0..reference.len())
                .map(|k| scene.displacement_px(k as f64 / p.fps).powi(2))
                .sum::<f64>()
                / reference.len() as f64;
            let bound = 10.0 * (power / crb).log10();
            let snr = ["gradient", "phase"].map(|m| listen_snr(d, "sp.y4m", &["--method", m]));
            eprintln!(
                "{texture}, {amplitude} px, {noise} DN: Cramér-Rao SNR {bound:.2} dB; listen {:.2} dB ({:+.2} dB from the bound); --method phase {:.2} dB ({:+.2})",
                snr[0],
                snr[0] - bound,
                snr[1],
                snr[1] - bound
            );
            if snr[0] < bound - 1.0 {
                failed.push(format!(
                    "{texture}, {amplitude} px, {noise} DN: {:.2} dB vs bound {bound:.2}",
                    snr[0]
                ));
            }
        }
    }
    assert!(
        failed.is_empty(),
        "more than 1 dB under the Cramér-Rao bound: {failed:?}"
    );
}

/// Renders `sp.y4m` in `d` with `simulate`: a `size`² frame whose central
/// half moves along x by `ref.wav` (`frames` of it at 2200 fps, `amplitude`
/// px peak), sensor noise `noise` DN, `extra` more scene lines. Returns the
/// scene's TOML.
fn simulate_speech(
    d: &std::path::Path,
    size: usize,
    frames: usize,
    (amplitude, noise): (f64, f64),
    extra: &str,
) -> String {
    let text = format!(
        "width = {size}\nheight = {size}\nfps = 2200.0\nframes = {frames}\namplitude_px = {amplitude}\n\
         noise_std = {noise}\nsignal = {{ type = \"wav\", path = \"{}\" }}\n{extra}",
        d.join("ref.wav").display()
    );
    std::fs::write(d.join("s.toml"), &text).unwrap();
    let o = run_in(d, &["simulate", "s.toml", "-o", "sp.y4m"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    text
}

/// `listen VIDEO --rate native` with `args` in `d`, scored against
/// `ref.wav`: the SNR (dB).
fn listen_snr(d: &std::path::Path, video: &str, args: &[&str]) -> f64 {
    listen_scored(d, video, "l.wav", args)["snr_db"]
        .as_f64()
        .unwrap()
}

/// `--half-grids` (the steerable pyramid's orientations 0 and 90° on half
/// grids) hears what the full grids hear: on the speech scene at 0.1 px
/// with 1 and 3 DN of noise its SNR is within 0.5 dB of the full grids'
/// (measured: -0.02 and -0.16 dB, docs/performance.md; the sums see half
/// the samples, which the noisier scene feels).
#[test]
fn half_grids_hear_what_the_full_grids_hear() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    if !speech_reference(d) {
        return;
    }
    let (_, reference) = vibroscope_io::wav::read_mono(&d.join("ref.wav")).unwrap();
    for noise in [1.0, 3.0] {
        simulate_speech(
            d,
            96,
            reference.len(),
            (0.1, noise),
            "seed = 1
",
        );
        let phase = ["--method", "phase", "--pyramid", "csp"];
        let full = listen_snr(d, "sp.y4m", &phase);
        let half = listen_snr(d, "sp.y4m", &[&phase[..], &["--half-grids"]].concat());
        eprintln!(
            "0.1 px, {noise} DN: --method phase {full:.2} dB, with --half-grids {half:.2} dB ({:+.2})",
            half - full
        );
        assert!(
            (half - full).abs() < 0.5,
            "{noise} DN: {full} against {half}"
        );
    }
}

/// A flickering light does not read as sound: the speech scene's frames
/// with their brightness modulated by a 2% gain at 100 Hz and a 1 DN offset
/// at 120 Hz (mains lighting) keep default `listen` within 1 dB of its SNR
/// on the steady frames. The gradient method's channels see a brightness
/// change wherever a tile's gradients do not sum to zero; it projects the
/// two directions an offset and a gain take in them out of every frame.
#[test]
fn a_flickering_light_is_not_heard() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    if !speech_reference(d) {
        return;
    }
    let (_, reference) = vibroscope_io::wav::read_mono(&d.join("ref.wav")).unwrap();
    simulate_speech(d, 96, reference.len(), (0.1, 1.0), "seed = 1\n");
    let steady = listen_snr(d, "sp.y4m", &[]);
    // Y4M: a header line, then per frame a FRAME line and the 8-bit plane.
    let bytes = std::fs::read(d.join("sp.y4m")).unwrap();
    let line = |from: usize| from + bytes[from..].iter().position(|&b| b == b'\n').unwrap() + 1;
    let mut out = Vec::with_capacity(bytes.len());
    let mut pos = line(0);
    out.extend_from_slice(&bytes[..pos]);
    let mut k = 0;
    while pos < bytes.len() {
        let start = line(pos);
        out.extend_from_slice(&bytes[pos..start]);
        let t = k as f64 / 2200.0;
        let gain = 1.0 + 0.02 * (2.0 * std::f64::consts::PI * 100.0 * t).sin();
        let offset = (2.0 * std::f64::consts::PI * 120.0 * t).sin();
        out.extend(
            bytes[start..start + 96 * 96]
                .iter()
                .map(|&v| (v as f64 * gain + offset).round().clamp(0.0, 255.0) as u8),
        );
        pos = start + 96 * 96;
        k += 1;
    }
    assert_eq!(k, reference.len());
    std::fs::write(d.join("flicker.y4m"), out).unwrap();
    let flicker = listen_snr(d, "flicker.y4m", &[]);
    eprintln!("steady light: {steady:.2} dB; flickering: {flicker:.2} dB");
    assert!(flicker > steady - 1.0, "{flicker:.2} dB vs {steady:.2} dB");
}
