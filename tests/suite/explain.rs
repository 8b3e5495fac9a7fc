//! The residual explainer of `vibroscope calibrate` (issue 50): effects
//! outside the object that no family of the catalog models, rendered by
//! the simulator (the camera moving the whole image, another vibrating
//! thing in view, a light changing across the image), found in the
//! recording's own observables (the tiles around the region) and named
//! by what they most likely are; and nothing found where there is nothing.
//!
//! Every scene: 128x128, 2 s at 2200 fps, the object [48, 48, 32, 32]
//! moving 0.05 px with a 100-1000 Hz chirp, noise 2 DN, calibrated on the
//! region [32, 32, 64, 64] (the object and a ring of background).
//!
//! Which cases were looked at while the explainer was designed and tuned:
//! all of those in this file (the camera, the light, another object, no
//! effect on seed 1). The no-effect seeds 2 and 3 were run only by this
//! test. Held-out effects and the transfer to a second recording are
//! issue 50's remaining work (see docs/calibration.md).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use vibroscope_math::calibrate::{Calibration, Explanation};

/// Renders the scene (signal `wav`, `extra` keys) to `dir/NAME.y4m`.
fn render(
    dir: &Path,
    name: &str,
    (wav, amplitude_px): (&Path, f64),
    extra: &str,
) -> std::path::PathBuf {
    let scene = format!(
        "width = 128\nheight = 128\nfps = 2200.0\nnoise_std = 2.0\nduration_s = 2.0\namplitude_px = {amplitude_px}\nobject = [48, 48, 32, 32]\nsignal = {{ type = \"wav\", path = {:?} }}\n{extra}\n",
        wav.display().to_string()
    );
    let toml = dir.join(format!("{name}.toml"));
    std::fs::write(&toml, scene).unwrap();
    let y4m = dir.join(format!("{name}.y4m"));
    let o = vibroscope::simulate::SimulateOptions {
        scene: toml,
        output: y4m.clone(),
        ..Default::default()
    };
    vibroscope::simulate::simulate(&o).unwrap();
    y4m
}

/// Renders the scene with `extra` keys and calibrates it on the region.
fn calibrate(name: &str, extra: &str) -> Calibration {
    let dir = tempfile::tempdir().unwrap();
    calibrate_in(dir.path(), name, extra)
}

/// [`calibrate`] in `dir` (its chirp and video stay there).
fn calibrate_in(dir: &Path, name: &str, extra: &str) -> Calibration {
    let wav = dir.join("chirp.wav");
    crate::calibrate::write_chirp(&wav);
    let y4m = render(dir, name, (&wav, 0.05), extra);
    let region = vibroscope::pipeline::Region {
        roi: Some(vibroscope::pipeline::Roi {
            x: 32,
            y: 32,
            w: 64,
            h: 64,
        }),
        ..Default::default()
    };
    let cal = vibroscope::calibrate::calibrate_video(
        &y4m,
        &wav,
        None,
        &region,
        None,
        Default::default(),
        None,
    )
    .unwrap()
    .calibration;
    eprintln!(
        "{name}: SNR {:.2} -> {:.2} dB, effects {:?}",
        cal.report.before.snr_db,
        cal.report.after.snr_db,
        cal.report
            .effects
            .iter()
            .map(|e| e.name.as_str())
            .collect::<Vec<_>>()
    );
    for e in &cal.report.explained {
        eprintln!(
            "  {} {:?} {:?} (seen at {:?}): +{:.2} dB without it, kept with +{:.2} dB, {:.0}% of the residual: {}",
            e.cause,
            e.observable,
            e.rect,
            e.seen_at,
            e.snr_gain_db,
            e.kept_gain_db,
            100.0 * e.residual_share,
            e.label
        );
    }
    cal
}

/// The held-out SNR of the same scene without any effect (seed 1).
fn plain_snr_db() -> f64 {
    static PLAIN: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *PLAIN.get_or_init(|| calibrate("plain", "").report.before.snr_db)
}

/// The one explanation kept, named `cause`; with it removed, the SNR
/// comes back to within 0.5 dB of the scene without the effect, which the
/// effect lowered by at least `cost_db`.
fn one(cal: &Calibration, cause: &str, cost_db: f64) -> Explanation {
    let e = &cal.report.explained;
    assert_eq!(e.len(), 1, "{e:#?}");
    assert_eq!(e[0].cause, cause, "{e:#?}");
    let plain = plain_snr_db();
    let (before, after) = (cal.report.before.snr_db, cal.report.after.snr_db);
    eprintln!(
        "{cause}: without the effect {plain:.2} dB, with it {before:.2}, explained {after:.2}"
    );
    assert!(
        plain - before >= cost_db,
        "the effect costs {:.2} dB",
        plain - before
    );
    assert!(
        after >= plain - 0.5,
        "{after:.2} dB vs {plain:.2} without the effect"
    );
    e[0].clone()
}

/// The camera's mount shakes with broadband noise (0.03 px): every tile
/// outside the region moves with it, and removing it recovers the SNR it
/// cost (measured: 7.1 dB without it, 5.1 with it).
#[test]
fn the_camera_moving_the_whole_image_is_found() {
    let cal = calibrate(
        "camera",
        "camera_motion = { signal = { type = \"noise\", rate_hz = 2200.0, duration_s = 3.0, seed = 7 }, amplitude_px = 0.03 }",
    );
    let e = one(&cal, "camera", 1.0);
    assert!(e.tiles_with_it * 4 >= e.tiles_of * 3, "{e:#?}");
}

/// A light whose brightness changes (noise to 400 Hz, 30% from one side
/// of the frame to the other): found as the light, in the intensities.
#[test]
fn a_light_changing_across_the_image_is_found() {
    let cal = calibrate(
        "light",
        "light = { signal = { type = \"noise\", rate_hz = 400.0, duration_s = 3.0, seed = 3 }, depth = 0.3 }",
    );
    one(&cal, "light", 1.0);
}

/// Another thing in view vibrates (the lower part of the background,
/// rows 80-127, with broadband noise): it is named where it is, not as the
/// camera.
#[test]
fn another_vibrating_thing_is_named_where_it_is() {
    let cal = calibrate(
        "other",
        "background_motion = [{ rect = [0, 80, 128, 48], signal = { type = \"noise\", rate_hz = 1500.0, duration_s = 3.0, seed = 11 }, amplitude_px = 0.3 }]",
    );
    let e = one(&cal, "other_object", 0.5);
    // Seen in the lower half only.
    assert!(e.seen_at[1] >= 64, "{e:#?}");
}

/// No effect: nothing is kept, on three seeds.
#[test]
fn nothing_is_explained_where_there_is_nothing() {
    for seed in [1, 2, 3] {
        let cal = calibrate(&format!("plain{seed}"), &format!("seed = {seed}"));
        assert!(
            cal.report.explained.is_empty(),
            "seed {seed}: {:#?}",
            cal.report.explained
        );
    }
}

/// What the explainer kept carries to the next recording: calibrated on
/// the chirp with the mount shaking, `listen --calibration` on speech
/// recorded afterwards (another texture, seed 2, another shake, seed 9,
/// both larger) measures the tiles again and subtracts the stored FIR; the speech's
/// held-out SNR rises, against the same listen with an empty report.
#[test]
fn the_camera_explained_on_a_chirp_is_removed_from_speech() {
    let d = tempfile::tempdir().unwrap();
    let Some(speech) = crate::calibrate::speech_wav(d.path()) else {
        return;
    };
    let shake = |seed: u32, px: f64| {
        format!("camera_motion = {{ signal = {{ type = \"noise\", rate_hz = 2200.0, duration_s = 3.0, seed = {seed} }}, amplitude_px = {px} }}")
    };
    let cal = calibrate_in(d.path(), "chirp", &shake(7, 0.03));
    one(&cal, "camera", 1.0);
    let report = serde_json::to_value(&cal.report).unwrap();
    std::fs::write(d.path().join("report.json"), report.to_string()).unwrap();
    std::fs::write(d.path().join("none.json"), r#"{"effects": []}"#).unwrap();
    // Speech has less power than the chirp for its peak: the object moves
    // 0.2 px at the peak, the mount 0.06 px.
    render(
        d.path(),
        "speech",
        (&speech, 0.2),
        &format!("{}\nseed = 2", shake(9, 0.06)),
    );
    // A report whose term measures a tile outside this frame (fitted on
    // another camera) is refused before the run, naming the file and the
    // field, and leaves no WAV.
    let mut moved = report.clone();
    moved["explained"][0]["tiles"] = serde_json::json!([[1000, 1000, 10, 10]]);
    std::fs::write(d.path().join("moved.json"), moved.to_string()).unwrap();
    let o = crate::common::run_in(
        d.path(),
        &[
            "listen",
            "speech.y4m",
            "-o",
            "moved.wav",
            "--calibration",
            "moved.json",
        ],
    );
    let err = crate::common::stderr(&o);
    assert_eq!(crate::common::code(&o), 2, "{err}");
    assert!(
        err.contains("moved.json") && err.contains("explained[0].tiles"),
        "{err}"
    );
    assert!(!d.path().join("moved.wav").exists());
    let roi = ["--roi", "32,32,64,64"];
    let (none, _) = crate::calibrate::listen_speech(d.path(), &speech, "none.json", &roi);
    let (after, text) = crate::calibrate::listen_speech(d.path(), &speech, "report.json", &roi);
    assert!(text.contains("explained term"), "{text}");
    let snr = [none, after];
    eprintln!(
        "camera shake, chirp to speech: held-out SNR {:.2} -> {:.2} dB ({:+.2})",
        snr[0],
        snr[1],
        snr[1] - snr[0]
    );
    assert!(snr[1] - snr[0] >= 0.5, "{snr:?}");
}
