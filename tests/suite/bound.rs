//! `vibroscope bound` (issue 14, part 2): the noise and the Cramér-Rao
//! floor it estimates from a rendered video, against the simulator's truth
//! (its noise and the exact derivatives of its continuous texture), on two
//! textures at three noise levels; and its refusals.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;
use vibroscope_engine::stages::sources::synthetic::SyntheticParams;

/// The region measured: inside the object `[32, 32, 64, 64]`.
const ROI: [usize; 4] = [40, 40, 48, 48];

/// The true per-frame floor along x and y (px RMS) of `ROI` in the scene
/// `text`: the Fisher matrix of the continuous texture's derivatives over
/// the region's pixels, with the sensor noise plus quantisation (1/12 DN²).
fn truth(text: &str, noise_std: f64) -> (f64, [f64; 2]) {
    let p: SyntheticParams = toml::from_str(text).unwrap();
    let scene = p.scene().unwrap();
    let h = 1e-3;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    let [x0, y0, w, hh] = ROI;
    for y in y0..y0 + hh {
        for x in x0..x0 + w {
            let (x, y) = (x as f64, y as f64);
            let gx =
                (scene.object_value(x + h, y, 0.0) - scene.object_value(x - h, y, 0.0)) / (2.0 * h);
            let gy =
                (scene.object_value(x, y + h, 0.0) - scene.object_value(x, y - h, 0.0)) / (2.0 * h);
            sxx += gx * gx;
            syy += gy * gy;
            sxy += gx * gy;
        }
    }
    let s2 = noise_std * noise_std + 1.0 / 12.0;
    let det = sxx * syy - sxy * sxy;
    (
        s2.sqrt(),
        [(s2 * syy / det).sqrt(), (s2 * sxx / det).sqrt()],
    )
}

fn bound_json(dir: &Path, video: &str, extra: &[&str]) -> serde_json::Value {
    let roi = format!("{},{},{},{}", ROI[0], ROI[1], ROI[2], ROI[3]);
    let mut args = vec!["bound", video, "--region", &roi, "--json", "b.json"];
    args.extend_from_slice(extra);
    let _ = std::fs::remove_file(dir.join("b.json"));
    let o = run_in(dir, &args);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    serde_json::from_slice(&std::fs::read(dir.join("b.json")).unwrap()).unwrap()
}

#[test]
fn the_bound_matches_the_simulators_truth() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    smooth_picture(&dir.join("pic.pgm"), 64);
    let base = "width = 128\nheight = 128\nobject = [32, 32, 64, 64]\nfps = 1000.0\nframes = 48\n\
                amplitude_px = 0.05\nsignal = { type = \"tone\", freq_hz = 120.0 }\n";
    let picture = format!("texture = \"{}\"\n", dir.join("pic.pgm").display());
    let cases: [(&str, String, f64); 4] = [
        ("random texture", String::new(), 1.0),
        ("random texture", String::new(), 3.0),
        (
            "random texture, contrast 12",
            "contrast = 12.0\n".into(),
            2.0,
        ),
        ("picture", picture, 2.0),
    ];
    for (name, extra, noise) in cases {
        let text = format!("{base}noise_std = {noise}\n{extra}");
        std::fs::write(dir.join("s.toml"), &text).unwrap();
        let o = run_in(dir, &["simulate", "s.toml", "-o", "v.y4m"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let (sigma, crb) = truth(&text, noise);
        let j = bound_json(dir, "v.y4m", &["--amplitude-px", "0.05"]);
        let r = &j["regions"][0];
        let got_sigma = r["noise_dn"].as_f64().unwrap();
        let got = [
            r["crb_px"][0].as_f64().unwrap(),
            r["crb_px"][1].as_f64().unwrap(),
        ];
        eprintln!(
            "{name}, noise {noise} DN: noise {got_sigma:.3} (truth {sigma:.3}), floor x {:.3e} (truth {:.3e}), y {:.3e} (truth {:.3e}) px; SNR bound for 0.05 px {:.1} dB",
            got[0],
            crb[0],
            got[1],
            crb[1],
            r["snr_db"][0].as_f64().unwrap()
        );
        assert!((got_sigma / sigma - 1.0).abs() < 0.10, "{name}: noise");
        for a in 0..2 {
            assert!((got[a] / crb[a] - 1.0).abs() < 0.10, "{name}: axis {a}");
        }
        // The SNR it prints follows from the floor.
        let snr = 10.0 * (0.05f64 * 0.05 / 2.0 / (got[0] * got[0])).log10();
        assert!((r["snr_db"][0].as_f64().unwrap() - snr).abs() < 1e-9);
    }
}

/// A still video, a flat one, one too short, a region outside the frame
/// and a bad amplitude: a message naming what is wrong, a non-zero exit,
/// no JSON.
#[test]
fn bad_input_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let scene = |name: &str, text: &str| {
        std::fs::write(dir.join("s.toml"), text).unwrap();
        let o = run_in(dir, &["simulate", "s.toml", "-o", name]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
    };
    scene(
        "still.y4m",
        "width = 64\nheight = 64\nframes = 30\nnoise_std = 0.0\namplitude_px = 0.0\n",
    );
    // No texture anywhere: a grey level with noise (-1, 0 or +1 DN).
    let mut flat = b"YUV4MPEG2 W64 H64 F30:1 Ip A1:1 Cmono\n".to_vec();
    let mut state = 12345u64;
    for _ in 0..30 {
        flat.extend_from_slice(b"FRAME\n");
        for _ in 0..64 * 64 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            flat.push(100 + (state >> 62) as u8 % 3 - 1);
        }
    }
    std::fs::write(dir.join("flat.y4m"), flat).unwrap();
    scene(
        "short.y4m",
        "width = 64\nheight = 64\nframes = 10\nnoise_std = 2.0\n",
    );
    let cases: [(&[&str], &str); 6] = [
        (&["still.y4m"], "no noise measured"),
        (&["flat.y4m"], "no texture"),
        (&["short.y4m"], "needs at least 18"),
        (&["short.y4m", "--region", "60,60,10,10"], "not inside"),
        (&["short.y4m", "--amplitude-px", "-1"], "--amplitude-px"),
        (&["missing.y4m"], "missing.y4m"),
    ];
    for (args, want) in cases {
        let mut a = vec!["bound"];
        a.extend_from_slice(args);
        a.extend_from_slice(&["--json", "b.json"]);
        let o = run_in(dir, &a);
        let err = stderr(&o);
        eprintln!("{args:?}: exit {} {}", code(&o), err.trim());
        assert_ne!(code(&o), 0, "{args:?}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(!dir.join("b.json").exists(), "{args:?}");
    }
}
