//! The speaker sink (issue 3, item 6) and capture-to-sink latency in live
//! runs. Latency figures are printed by `cargo bench --bench live`; tests
//! here check behaviour, never wall-clock values.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;

fn scene(dir: &Path) -> &'static str {
    render_y4m(
        dir,
        "scene.y4m",
        &[
            "--set",
            "cam.width=64",
            "--set",
            "cam.height=64",
            "--set",
            "cam.duration_s=0.5",
        ],
    );
    "scene.y4m"
}

/// An ALSA configuration whose default PCM is ALSA's `null` plugin: the
/// real cpal/ALSA path, on a machine without a sound card.
fn alsa_null(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("asound.conf");
    std::fs::write(&p, "pcm.!default { type null }\n").unwrap();
    p
}

/// `listen --speaker` plays through cpal (ALSA's null PCM here) while the
/// WAV sink gets the same blocks: the WAV is bit-identical to a run
/// without the speaker.
#[test]
fn listen_plays_through_cpal_and_writes_the_same_wav() {
    let d = tempfile::tempdir().unwrap();
    let v = scene(d.path());
    let o = run_in(d.path(), &["listen", v, "-o", "plain.wav"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let conf = alsa_null(d.path());
    let o = bin()
        .current_dir(d.path())
        .env("ALSA_CONFIG_PATH", &conf)
        .args(["listen", v, "-o", "both.wav", "--speaker", "--stats"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(code(&o), 0, "{err}");
    assert!(err.contains("speaker"), "{err}");
    let a = std::fs::read(d.path().join("plain.wav")).unwrap();
    let b = std::fs::read(d.path().join("both.wav")).unwrap();
    assert!(a.len() > 44);
    assert_eq!(a, b, "the speaker changed what the WAV sink received");
}

/// A replay through the virtual `null` device plays at the device's pace:
/// everything reaches the WAV, and the run lasts at least as long as the
/// sound (the device drains 48 kHz of wall clock; a lower bound on
/// elapsed time, not a speed target).
#[test]
fn replay_through_the_null_speaker_is_paced_and_complete() {
    let d = tempfile::tempdir().unwrap();
    let v = scene(d.path());
    let t = std::time::Instant::now();
    let o = run_in(
        d.path(),
        &[
            "listen",
            v,
            "-o",
            "s.wav",
            "--speaker",
            "null",
            "--stats",
            "--rate",
            "native",
        ],
    );
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let (rate, s) = read_wav(&d.path().join("s.wav"));
    assert_eq!(rate, 2200);
    assert_eq!(s.len(), 1100);
    assert!(secs >= 0.45, "0.5 s of sound played in {secs:.2} s");
}

/// Unknown devices and bad parameters are named, with a non-zero exit.
#[test]
fn speaker_errors_name_the_device_and_field() {
    let d = tempfile::tempdir().unwrap();
    let v = scene(d.path());
    let o = run_in(
        d.path(),
        &["listen", v, "-o", "s.wav", "--speaker", "no-such-card-xyz"],
    );
    assert_ne!(code(&o), 0);
    let err = stderr(&o);
    assert!(err.contains("no-such-card-xyz"), "{err}");
    let o = run_in(
        d.path(),
        &[
            "run",
            "live-demo",
            "--set",
            "speaker.latency_ms=0",
            "--set",
            "speaker.device=null",
        ],
    );
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("latency_ms") && err.contains("speaker"),
        "{err}"
    );
}

/// A live run reports capture-to-sink latency for each sink; a replay
/// does not (file timestamps are not on the run clock).
#[test]
fn live_runs_report_latency_replays_do_not() {
    let d = tempfile::tempdir().unwrap();
    let o = run_in(
        d.path(),
        &[
            "run",
            "live-demo",
            "--stats",
            "--set",
            "cam.duration_s=0.5",
            "--set",
            "cam.width=64",
            "--set",
            "cam.height=64",
            "--set",
            "speaker.device=null",
        ],
    );
    let err = stderr(&o);
    assert_eq!(code(&o), 0, "{err}");
    for sink in ["out", "speaker"] {
        let line = err
            .lines()
            .find(|l| l.starts_with(&format!("latency capture -> {sink}:")))
            .unwrap_or_else(|| panic!("no latency line for {sink}: {err}"));
        let p50: f64 = line
            .split("p50 ")
            .nth(1)
            .and_then(|s| s.split_whitespace().next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("unparsable: {line}"));
        assert!(p50 >= 0.0, "{line}");
    }
    let (rate, s) = read_wav(&d.path().join("live.wav"));
    assert_eq!(rate, 2200);
    assert!(!s.is_empty());
    let v = scene(d.path());
    let o = run_in(d.path(), &["listen", v, "-o", "r.wav", "--stats"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(!stderr(&o).contains("latency capture"), "{}", stderr(&o));
}
