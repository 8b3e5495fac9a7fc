//! `vibroscope pitch` (YIN, thesis 4.6 and Fig. 4-11): the pitch of speech
//! recovered through the visual microphone against the pitch of the sound
//! that moved the object, on espeak-ng voices whose pitch is set.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;

/// One row of the CSV: (time, f0, voiced).
fn track(p: &Path) -> Vec<(f64, f64, bool)> {
    let text = std::fs::read_to_string(p).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("time_s,f0_hz,confidence,voiced"));
    lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            (v[0].parse().unwrap(), v[1].parse().unwrap(), v[3] == "1")
        })
        .collect()
}

/// The rows of a `pitch` stage's CSV (`t_s,ch0,ch1,ch2`): (time, f0, voiced).
fn stage_track(p: &Path) -> Vec<(f64, f64, bool)> {
    let text = std::fs::read_to_string(p).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_s,ch0,ch1,ch2"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[0], v[1], v[3] == 1.0)
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// espeak-ng speech of `voice` at pitch `p` (0-99), at 2200 Hz mono.
fn speech(dir: &Path, voice: &str, p: u32) -> Option<std::path::PathBuf> {
    let raw = dir.join(format!("{voice}-{p}.raw.wav"));
    let out = dir.join(format!("{voice}-{p}.wav"));
    let ok = std::process::Command::new("espeak-ng")
        .args(["-v", voice, "-p", &p.to_string(), "-w"])
        .arg(&raw)
        .arg("Visual microphones recover sound from the tiny vibrations of objects.")
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
        && std::process::Command::new("sox")
            .arg("-R") // repeatable dither (see microphone.rs)
            .arg(&raw)
            .args(["-r", "2200", "-c", "1"])
            .arg(&out)
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
    ok.then_some(out)
}

/// Three voices, pitch set low, middle and high: the scene (96x96, 2200
/// fps, 0.15 px peak, sensor noise 2 DN) recovers speech at a few dB of
/// SNR, and its pitch on the frames the clean sound voices is within 2%
/// (median), as on the frames the recovery itself calls voiced; both for
/// `vibroscope pitch VIDEO` and for the live graph's `pitch` stage
/// (`run live-pitch --replay VIDEO`).
#[test]
fn pitch_survives_the_visual_microphone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut medians = Vec::new();
    for (voice, p) in [("en+m3", 20), ("en-us", 50), ("en+f3", 80)] {
        let Some(wav) = speech(d, voice, p) else {
            eprintln!("skipping: espeak-ng and sox are needed (Debian packages espeak-ng, sox)");
            return;
        };
        let (_, samples) = read_wav(&wav);
        let secs = samples.len() as f64 / 2200.0;
        let video = format!("{voice}-{p}.y4m");
        render_y4m(
            d,
            &video,
            &[
                "--set",
                &format!(
                    "cam.signal={{ type = \"wav\", path = \"{}\" }}",
                    wav.display()
                ),
                "--set",
                &format!("cam.duration_s={secs}"),
                "--set",
                "cam.width=96",
                "--set",
                "cam.height=96",
                "--set",
                "cam.amplitude_px=0.15",
            ],
        );
        let truth_csv = format!("{voice}-{p}.truth.csv");
        let o = run_in(d, &["pitch", wav.to_str().unwrap(), "-o", &truth_csv]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let est_csv = format!("{voice}-{p}.csv");
        let png = format!("{voice}-{p}.png");
        let o = run_in(d, &["pitch", &video, "-o", &est_csv, "--png", &png]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("wrote {est_csv}")),
            "{}",
            stderr(&o)
        );
        let img = image::open(d.join(&png)).unwrap();
        assert_eq!((img.width(), img.height()), (1000, 500));

        let truth = track(&d.join(&truth_csv));
        let est = track(&d.join(&est_csv));
        assert_eq!(truth.len(), est.len(), "one frame each, same times");
        let errors: Vec<f64> = truth
            .iter()
            .zip(&est)
            .filter(|(t, _)| t.2)
            .map(|(t, e)| {
                assert!((t.0 - e.0).abs() < 1e-6);
                (e.1 / t.1 - 1.0).abs()
            })
            .collect();
        let voiced_truth: Vec<f64> = truth.iter().filter(|t| t.2).map(|t| t.1).collect();
        // Frames both call voiced: the recovery's own voicing picks right.
        let both: Vec<f64> = truth
            .iter()
            .zip(&est)
            .filter(|(t, e)| t.2 && e.2)
            .map(|(t, e)| (e.1 / t.1 - 1.0).abs())
            .collect();
        let false_voiced = truth.iter().zip(&est).filter(|(t, e)| e.2 && !t.2).count();
        assert!(
            voiced_truth.len() >= 50,
            "{voice}: {} voiced",
            voiced_truth.len()
        );
        assert!(both.len() >= 5, "{voice}: {} voiced in both", both.len());
        let err = median(errors.clone());
        let err_both = median(both.clone());
        let mt = median(voiced_truth.clone());
        eprintln!(
            "{voice} -p {p}: truth median {mt:.1} Hz over {} voiced frames; recovered: median \
             error {:.2}% on those frames; {} of them also voiced in the recovery (median error \
             {:.2}%), {false_voiced} voiced only in the recovery",
            voiced_truth.len(),
            100.0 * err,
            both.len(),
            100.0 * err_both
        );
        assert!(err < 0.02, "{voice}: median error {:.2}%", 100.0 * err);
        assert!(
            err_both < 0.02,
            "{voice}: median error {:.2}%",
            100.0 * err_both
        );
        assert!(
            false_voiced <= both.len(),
            "{voice}: {false_voiced} false voiced"
        );
        medians.push(mt);

        // The live graph on the same video (`pipelines/live-pitch.toml`
        // replayed): the `pitch` stage frame by frame, after a high-pass.
        let live_csv = format!("{voice}-{p}.live.csv");
        let o = run_in(
            d,
            &[
                "run",
                "live-pitch",
                "--quiet",
                "--replay",
                &video,
                "--set",
                &format!("track.path={live_csv}"),
                "--set",
                &format!("out.path={voice}-{p}.live.wav"),
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let live = stage_track(&d.join(&live_csv));
        // Rows matched by time (the truth's frames are at the same hop).
        let mut live_err = Vec::new();
        let mut live_both = Vec::new();
        for t in truth.iter().filter(|t| t.2) {
            let Some(l) = live.iter().find(|l| (l.0 - t.0).abs() < 0.004) else {
                continue;
            };
            live_err.push((l.1 / t.1 - 1.0).abs());
            if l.2 {
                live_both.push((l.1 / t.1 - 1.0).abs());
            }
        }
        assert!(
            live_err.len() + 5 >= voiced_truth.len(),
            "{voice}: {} of {} truth frames have a live row",
            live_err.len(),
            voiced_truth.len()
        );
        let live_false = live
            .iter()
            .filter(|l| l.2)
            .filter(|l| {
                truth
                    .iter()
                    .find(|t| (l.0 - t.0).abs() < 0.004)
                    .is_some_and(|t| !t.2)
            })
            .count();
        let (le, lb) = (median(live_err.clone()), median(live_both.clone()));
        eprintln!(
            "{voice} -p {p}, live pitch stage: median error {:.2}% on the truth's voiced frames, \
             {:.2}% on the {} it also calls voiced, {live_false} voiced only live",
            100.0 * le,
            100.0 * lb,
            live_both.len()
        );
        assert!(
            live_false <= live_both.len(),
            "{voice}: {live_false} false voiced live"
        );
        assert!(live_both.len() >= 5, "{voice}: {}", live_both.len());
        assert!(le < 0.02, "{voice}: live median error {:.2}%", 100.0 * le);
        assert!(lb < 0.02, "{voice}: live median error {:.2}%", 100.0 * lb);
    }
    // The pitch set with -p shows: low, middle and high voices in order.
    assert!(
        medians[0] < medians[1] && medians[1] < medians[2],
        "{medians:?}"
    );
}

/// A silent file, a file too short for the lowest pitch, a highest pitch
/// above a quarter of the rate, and the output onto the input: each a
/// clear message and exit 2, no output written.
#[test]
fn pitch_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_wav_f32(&d.join("silent.wav"), 8000, &[0.0; 8000]);
    write_wav_f32(&d.join("short.wav"), 8000, &[0.5; 100]);
    let tone: Vec<f32> = (0..8000)
        .map(|n| (2.0 * std::f32::consts::PI * 200.0 * n as f32 / 8000.0).sin())
        .collect();
    write_wav_f32(&d.join("tone.wav"), 8000, &tone);
    let cases: [(&[&str], &str); 5] = [
        (&["pitch", "silent.wav"], "silent"),
        (&["pitch", "short.wav"], "needs at least"),
        (&["pitch", "tone.wav", "--fmax", "3000"], "--fmax"),
        (&["pitch", "tone.wav", "--fmin", "-1"], "--fmin"),
        (
            &["pitch", "tone.wav", "-o", "tone.wav"],
            "same file as the input",
        ),
    ];
    for (args, expect) in cases {
        let o = run_in(d, args);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(!d.join("pitch.csv").exists(), "{args:?}");
    }
    // The tone itself: 200 Hz, every frame voiced.
    let o = run_in(d, &["pitch", "tone.wav", "--json", "t.json"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("t.json")).unwrap()).unwrap();
    assert!(
        (v["median_hz"].as_f64().unwrap() - 200.0).abs() < 0.5,
        "{v}"
    );
    assert_eq!(v["voiced_frames"], v["frames"], "{v}");
}
