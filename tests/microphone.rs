//! The phase-based visual microphone (thesis ch. 3-4) against ground truth:
//! the forward model's known motion, and a real recording with known
//! physics (guitar strings E2 82.4 Hz and A2 110 Hz, filmed at 600 fps).

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::*;

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
    let mut decl = vibroscope::engine::config::parse("law.toml", text).unwrap();
    for s in sets {
        vibroscope::engine::config::apply_set(&mut decl, s).unwrap();
    }
    let truth = true_motion(&decl, "src", est.len());
    let est: Vec<f64> = est.iter().map(|&v| v as f64).collect();
    vibroscope::dsp::truth::snr_db_fit(&truth, &est)
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

/// `listen` with each denoiser on a rendered speech scene: the output keeps
/// one sample per frame, aligned, and both denoisers raise SNR and
/// segmental SNR against the sound that drove the scene.
#[test]
fn listen_with_denoising_improves_speech() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
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
        return;
    }
    let (_, reference) = vibroscope::cli::read_wav_mono(&d.join("ref.wav")).unwrap();
    let secs = reference.len() as f64 / 2200.0;
    let signal = format!(
        "cam.signal={{ type = \"wav\", path = \"{}\" }}",
        d.join("ref.wav").display()
    );
    let dur = format!("cam.duration_s={secs}");
    render_y4m(
        d,
        "sp.y4m",
        &[
            "--set",
            &signal,
            "--set",
            &dur,
            "--set",
            "cam.width=192",
            "--set",
            "cam.height=192",
            "--set",
            "cam.amplitude_px=0.02",
        ],
    );
    let mut scores = Vec::new();
    for mode in ["none", "subtract", "enhance"] {
        let out = format!("{mode}.wav");
        let o = run_in(d, &["listen", "sp.y4m", "-o", &out, "--denoise", mode]);
        assert_eq!(code(&o), 0, "{mode}: {}", stderr(&o));
        assert_eq!(
            read_wav(&d.join(&out)).1.len(),
            reference.len(),
            "{mode}: one sample per frame"
        );
        let o = run_in(d, &["score", "ref.wav", &out]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        eprintln!("{mode}: {v}");
        scores.push((
            v["snr_db"].as_f64().unwrap(),
            v["ssnr_db"].as_f64().unwrap(),
        ));
    }
    for (i, mode) in [(1, "subtract"), (2, "enhance")] {
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
