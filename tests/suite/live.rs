//! The live path without a camera: a missing device is named and nothing
//! invalid is left behind; a live session with a deliberately slow stage
//! drops frames (counted) with bounded queues and latency, while a recording of the same
//! session replays through the same graph without losing a frame, and two
//! replays are byte-identical. (The live path on a real V4L2 driver, with a
//! mid-stream unplug, is tests/vm/run.sh.)

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;

/// (in, out, dropped, queue max, queue capacity) of a `--stats` row.
fn row(table: &str, id: &str) -> (u64, u64, u64, u64, u64) {
    let r = table
        .lines()
        .find(|l| l.split_whitespace().next() == Some(id))
        .unwrap_or_else(|| panic!("no `{id}` row in:\n{table}"));
    let c: Vec<&str> = r.split_whitespace().collect();
    let (qmax, qcap) = c[5].split_once('/').unwrap_or(("0", "0"));
    (
        c[2].parse().unwrap(),
        c[3].parse().unwrap(),
        c[4].parse().unwrap(),
        qmax.parse().unwrap(),
        qcap.parse().unwrap(),
    )
}

/// p99 of the `latency capture -> SINK:` line of `--stats`, in ms.
fn latency_p99_ms(table: &str, sink: &str) -> f64 {
    let key = format!("latency capture -> {sink}:");
    let line = table
        .lines()
        .find(|l| l.starts_with(&key))
        .unwrap_or_else(|| panic!("no `{key}` in:\n{table}"));
    let at = line.find("p99 ").unwrap() + 4;
    line[at..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn missing_device_is_named_and_leaves_no_invalid_file() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "run",
            "live-microphone",
            "--set",
            "cam.device=\"/dev/video99\"",
            "--set",
            "out.path=m.wav",
            "--quiet",
        ],
    );
    let err = stderr(&o);
    assert_eq!(code(&o), 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains("/dev/video99") && err.contains("stage `cam`"),
        "{err}"
    );
    // The device fails before anything runs: no WAV, or a valid one.
    let wav = dir.path().join("m.wav");
    if wav.exists() {
        read_wav(&wav);
    }
    let o = run_in(
        dir.path(),
        &[
            "record",
            "--device",
            "/dev/video99",
            "-o",
            "r.y4m",
            "--seconds",
            "1",
        ],
    );
    let err = stderr(&o);
    assert_eq!(code(&o), 1, "{err}");
    assert!(err.contains("/dev/video99"), "{err}");
    assert!(!dir.path().join("r.y4m").exists());
    // Bad arguments are usage errors naming the field.
    let o = run_in(dir.path(), &["record", "-o", "r.y4m", "--seconds", "-1"]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("duration_s"), "{}", stderr(&o));
    let o = run_in(dir.path(), &["record", "-o", "r.y4m", "--format", "rgb"]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("format"), "{}", stderr(&o));
}

#[test]
fn devices_says_no_camera_found_without_one() {
    let nodes = vibroscope_devices::v4l2::video_nodes();
    if !nodes.is_empty() {
        eprintln!("skipping: this machine has video nodes ({nodes:?})");
        return;
    }
    let o = run_in(std::path::Path::new("."), &["devices"]);
    assert_eq!(code(&o), 1);
    assert!(stderr(&o).contains("no camera found"), "{}", stderr(&o));
}

#[test]
fn slow_live_session_drops_counted_and_its_recording_replays_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    // A 1000 fps live camera; `slow` needs 3 ms a frame. The recorder hangs
    // off the camera on its own edge, large enough to keep every frame.
    let live = "[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\nrealtime = true\nwidth = 64\nheight = 48\nfps = 1000.0\nframes = 400\n\n\
                [[stage]]\nid = \"rec\"\nkind = \"y4m\"\ninput = { from = \"cam\", capacity = 1024 }\npath = \"session.y4m\"\n\n\
                [[stage]]\nid = \"slow\"\nkind = \"passthrough\"\ninput = { from = \"cam\", capacity = 4 }\ndelay_us = 3000\n\n\
                [[stage]]\nid = \"motion\"\nkind = \"gradient_motion\"\ninput = \"slow\"\n\n\
                [[stage]]\nid = \"out\"\nkind = \"wav\"\ninput = \"motion\"\npath = \"live.wav\"\n";
    std::fs::write(dir.path().join("live.toml"), live).unwrap();
    let o = run_in(dir.path(), &["run", "live.toml", "--stats", "--quiet"]);
    let table = stderr(&o);
    assert_eq!(code(&o), 0, "{table}");
    let (_, cam_out, ..) = row(&table, "cam");
    let (rec_in, _, rec_dropped, ..) = row(&table, "rec");
    let (slow_in, _, slow_dropped, qmax, qcap) = row(&table, "slow");
    assert_eq!(cam_out, 400);
    assert!(
        slow_dropped > 0,
        "a slow stage behind a live camera drops: {table}"
    );
    assert_eq!(
        slow_in + slow_dropped,
        cam_out,
        "processed or counted: {table}"
    );
    assert!(
        qmax <= qcap && qcap == 4,
        "the capture queue stays bounded: {table}"
    );
    assert_eq!((rec_in, rec_dropped), (400, 0), "{table}");
    let (_, live_wav) = read_wav(&dir.path().join("live.wav"));
    assert_eq!(live_wav.len() as u64, slow_in);
    // Latency stays bounded: the same camera behind a blocking edge falls
    // further behind with every frame; dropping the oldest holds it near
    // the queue's length times the stage's time.
    let dropping = latency_p99_ms(&table, "out");
    let blocking_toml = live.replace(
        "input = { from = \"cam\", capacity = 4 }",
        "input = { from = \"cam\", capacity = 4, policy = \"block\" }",
    );
    std::fs::write(dir.path().join("block.toml"), blocking_toml).unwrap();
    let o = run_in(
        dir.path(),
        &[
            "run",
            "block.toml",
            "--set",
            "out.path=block.wav",
            "--stats",
            "--quiet",
        ],
    );
    let t = stderr(&o);
    assert_eq!(code(&o), 0, "{t}");
    assert_eq!(row(&t, "slow").2, 0, "{t}");
    let blocking = latency_p99_ms(&t, "out");
    eprintln!("p99 capture -> out: {dropping:.1} ms dropping oldest, {blocking:.1} ms blocking");
    assert!(
        dropping * 5.0 < blocking,
        "drop-oldest p99 {dropping} ms vs blocking {blocking} ms"
    );

    // The recording of that session, replayed through the same graph:
    // every frame is processed, and twice gives the same bytes.
    let mut outs = Vec::new();
    for name in ["r1.wav", "r2.wav"] {
        let o = run_in(
            dir.path(),
            &[
                "run",
                "live.toml",
                "--replay",
                "session.y4m",
                "--set",
                "rec.path=copy.y4m",
                "--set",
                &format!("out.path={name}"),
                "--stats",
                "--quiet",
            ],
        );
        let table = stderr(&o);
        assert_eq!(code(&o), 0, "{table}");
        let (slow_in, _, slow_dropped, ..) = row(&table, "slow");
        assert_eq!((slow_in, slow_dropped), (400, 0), "{table}");
        let (_, s) = read_wav(&dir.path().join(name));
        assert_eq!(s.len(), 400);
        outs.push(std::fs::read(dir.path().join(name)).unwrap());
    }
    assert_eq!(outs[0], outs[1], "replays are byte-identical");
    // The replay's own recording keeps the original capture times.
    let a = std::fs::read(dir.path().join("session.y4m")).unwrap();
    let b = std::fs::read(dir.path().join("copy.y4m")).unwrap();
    assert_eq!(a, b, "re-recording a replay reproduces the file");
}
