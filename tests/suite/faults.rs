//! Bad input never panics: truncated and malformed files, a zero frame
//! rate, a missing file, an interrupted run. Each gives a message naming the
//! file or value and a non-zero exit, and a WAV sink downstream still holds a
//! valid file with what was processed.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;

const SMALL: &[&str] = &[
    "--set",
    "cam.width=64",
    "--set",
    "cam.height=48",
    "--set",
    "cam.frames=50",
];

/// A directory with `scene.y4m` ([`SMALL`]) less its last `bytes` bytes.
fn cut_scene(bytes: u64) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SMALL);
    let p = dir.path().join("scene.y4m");
    let len = std::fs::metadata(&p).unwrap().len();
    let f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
    f.set_len(len - bytes).unwrap();
    dir
}

/// The error a cut `scene.y4m` gives: exit 1, the file and its fault named.
fn says_truncated(o: &std::process::Output) -> String {
    let err = stderr(o);
    assert_eq!(code(o), 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains("scene.y4m") && err.contains("truncated"),
        "{err}"
    );
    err
}

#[test]
fn truncated_y4m_keeps_a_valid_wav_of_what_was_processed() {
    // The last frame cut in half.
    let dir = cut_scene(64 * 48 / 2);
    let o = run_in(
        dir.path(),
        &[
            "run",
            "motion",
            "--replay",
            "scene.y4m",
            "--set",
            "out.path=t.wav",
            "--quiet",
        ],
    );
    let err = says_truncated(&o);
    assert!(err.contains("stage `src`"), "{err}");
    let (_, samples) = read_wav(&dir.path().join("t.wav"));
    assert_eq!(
        samples.len(),
        49,
        "every whole frame before the cut is in the WAV"
    );
}

/// `listen` on a recording cut short: the error names the file, and the
/// WAV of what was read is finished as a whole run's is (16-bit PCM at
/// the output rate, its peak at -1 dBFS), not left as the stream wrote it
/// (32-bit float at the recovery's scale), and the run says it kept it.
#[test]
fn truncated_y4m_gives_listen_a_finished_wav_of_what_was_read() {
    let dir = cut_scene(64 * 48 * 5);
    let o = run_in(dir.path(), &["listen", "scene.y4m", "-o", "t.wav"]);
    let err = says_truncated(&o);
    assert!(
        err.contains("t.wav: kept the sound of what was read before the error"),
        "{err}"
    );
    let spec = hound::WavReader::open(dir.path().join("t.wav"))
        .unwrap()
        .spec();
    assert_eq!(
        (spec.sample_format, spec.bits_per_sample, spec.sample_rate),
        (hound::SampleFormat::Int, 16, 48000),
        "{err}"
    );
    let (_, s) = read_wav(&dir.path().join("t.wav"));
    let peak = s.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(!s.is_empty() && (peak - 0.891).abs() < 0.01, "peak {peak}");
}

#[test]
fn malformed_header_zero_rate_and_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &[u8], &str)] = &[
        (
            "bad.y4m",
            b"YUV4MPEG2 W64 Hxx F30:1 Cmono\nFRAME\n",
            "bad.y4m",
        ),
        (
            "zero.y4m",
            b"YUV4MPEG2 W4 H4 F0:1 Cmono\nFRAME\n0123456789abcdef",
            "F0:1",
        ),
        ("junk.y4m", b"\x00\x01garbage", "junk.y4m"),
    ];
    for (name, bytes, needle) in cases {
        std::fs::write(dir.path().join(name), bytes).unwrap();
        let o = run_in(dir.path(), &["run", "motion", "--replay", name, "--quiet"]);
        let err = stderr(&o);
        assert_ne!(code(&o), 0, "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(
            err.contains(needle),
            "{name}: message lacks `{needle}`: {err}"
        );
        let o = run_in(dir.path(), &["probe", name]);
        assert_ne!(code(&o), 0);
        assert!(!stderr(&o).contains("panicked"));
    }
    let o = run_in(
        dir.path(),
        &["run", "motion", "--replay", "nope.y4m", "--quiet"],
    );
    assert_eq!(code(&o), 1);
    assert!(stderr(&o).contains("nope.y4m"), "{}", stderr(&o));
}

#[test]
fn zero_or_negative_fps_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SMALL);
    for bad in ["0", "-5", "nan"] {
        let o = run_in(
            dir.path(),
            &[
                "run",
                "motion",
                "--replay",
                "scene.y4m",
                "--fps",
                bad,
                "--quiet",
            ],
        );
        assert_eq!(code(&o), 2, "--fps {bad}: {}", stderr(&o));
        assert!(stderr(&o).contains("fps"), "{}", stderr(&o));
    }
}

#[test]
fn ctrl_c_finalises_the_wav() {
    let dir = tempfile::tempdir().unwrap();
    let o = interrupt_live_demo(dir.path(), "INT");
    assert_eq!(code(&o), 130, "{}", stderr(&o));
    let (rate, s) = read_wav(&dir.path().join("demo.wav"));
    assert_eq!(rate, 500);
    assert!(s.len() > 100, "only {} samples", s.len());
}

#[test]
fn probe_real_recordings() {
    let dir = tempfile::tempdir().unwrap();
    if let Some(cine) = shared_data("small.cine") {
        let o = run_in(
            dir.path(),
            &["probe", cine.to_str().unwrap(), "--json", "probe.json"],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let json = std::fs::read_to_string(dir.path().join("probe.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(
            (
                v["frames"].as_u64(),
                v["width"].as_u64(),
                v["height"].as_u64(),
                v["bits"].as_u64()
            ),
            (Some(235), Some(256), Some(32), Some(16)),
            "{v}"
        );
    }
    if let Some(cih) = shared_data("showcase.cih") {
        let o = run_in(dir.path(), &["probe", cih.to_str().unwrap()]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let out = stdout(&o);
        for n in [
            "frames:      75",
            "640x40",
            "frame rate:  150 Hz",
            "bit depth:   8 bits",
        ] {
            assert!(out.contains(n), "lacks `{n}`: {out}");
        }
    }
}

#[test]
fn real_recordings_replay_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    for (file, frames) in [("small.cine", 235), ("showcase.mraw", 75)] {
        let Some(p) = shared_data(file) else { continue };
        let o = run_in(
            dir.path(),
            &[
                "run",
                "intensity",
                "--replay",
                p.to_str().unwrap(),
                "--set",
                "out.path=i.csv",
                "--stats",
                "--quiet",
            ],
        );
        assert_eq!(code(&o), 0, "{file}: {}", stderr(&o));
        let rows = std::fs::read_to_string(dir.path().join("i.csv"))
            .unwrap()
            .lines()
            .count();
        assert_eq!(rows, frames + 1, "{file}");
    }
}

#[test]
fn ffmpeg_source_with_fps_override() {
    let Some(p) = guitar_with_ffmpeg() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "run",
            "intensity",
            "--replay",
            p.to_str().unwrap(),
            "--fps",
            "600",
            "--set",
            "out.path=g.csv",
            "--quiet",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.path().join("g.csv")).unwrap();
    assert_eq!(text.lines().count(), 301);
    let last: f64 = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        (last - 299.0 / 600.0).abs() < 1e-9,
        "times follow --fps 600: {last}"
    );
}
