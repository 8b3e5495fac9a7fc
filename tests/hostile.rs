//! Hostile input and conditions (issue 20): each case once found a panic,
//! an abort, lost data or a misleading exit. Every test asserts the exit
//! code and the message, that nothing panicked, that the inputs are
//! unchanged (checksums before and after) and that outputs are valid or
//! absent. Inputs are small and made here.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::*;
use std::path::Path;
use std::process::Stdio;

/// A cheap checksum of a file's bytes (FNV-1a), to prove it unchanged.
fn checksum(p: &Path) -> u64 {
    std::fs::read(p)
        .unwrap()
        .iter()
        .fold(0xcbf29ce484222325u64, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x100000001b3)
        })
}

fn no_panic(o: &std::process::Output) {
    let err = stderr(o);
    assert!(!err.contains("panicked"), "{err}");
    assert!(!err.contains("RUST_BACKTRACE"), "{err}");
}

const SMALL: &[&str] = &[
    "--set",
    "cam.width=64",
    "--set",
    "cam.height=48",
    "--set",
    "cam.frames=40",
];

/// Runs the binary with a stdout whose reader is gone before it writes.
fn with_closed_stdout(dir: &Path, args: &[&str]) -> std::process::Output {
    let mut child = bin()
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child.wait_with_output().unwrap()
}

/// Closed stdout ends quietly with exit 0 (what `| head` users expect);
/// a full one (`> /dev/full`) says so and exits 1; never a panic.
#[test]
fn closed_or_full_stdout() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "s.y4m", SMALL);
    let sum = checksum(&dir.path().join("s.y4m"));
    for args in [
        &["pipelines"][..],
        &["kinds"][..],
        &["kinds", "phase"][..],
        &["probe", "s.y4m"][..],
    ] {
        let o = with_closed_stdout(dir.path(), args);
        no_panic(&o);
        assert_eq!(code(&o), 0, "{args:?}: {}", stderr(&o));
        if Path::new("/dev/full").exists() {
            let full = std::fs::OpenOptions::new()
                .write(true)
                .open("/dev/full")
                .unwrap();
            let o = bin()
                .current_dir(dir.path())
                .args(args)
                .stdout(full)
                .output()
                .unwrap();
            no_panic(&o);
            assert_eq!(code(&o), 1, "{args:?}: {}", stderr(&o));
            assert!(
                stderr(&o).contains("cannot write to stdout"),
                "{}",
                stderr(&o)
            );
        }
    }
    // The JSON file is still written when stdout is closed.
    let o = with_closed_stdout(dir.path(), &["probe", "s.y4m", "--json", "p.json"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("p.json")).unwrap()).unwrap();
    assert_eq!(v["frames"].as_u64(), Some(40), "{v}");
    assert_eq!(checksum(&dir.path().join("s.y4m")), sum);
}

/// An output that is an input is refused before any work, whatever its
/// spelling (`./x`, a hard link), in every command and in a pipeline.
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(d, "same.y4m", SMALL);
    std::fs::hard_link(d.join("same.y4m"), d.join("link.y4m")).unwrap();
    std::fs::write(
        d.join("s.toml"),
        "width = 64\nheight = 48\nfps = 2200.0\nduration_s = 0.01\n",
    )
    .unwrap();
    write_wav_f32(&d.join("ref.wav"), 8000, &[0.1; 800]);
    let files = ["same.y4m", "s.toml", "ref.wav"];
    let sums: Vec<u64> = files.iter().map(|f| checksum(&d.join(f))).collect();
    let cases: &[&[&str]] = &[
        &["listen", "same.y4m", "--fps", "2200", "-o", "same.y4m"],
        &["listen", "same.y4m", "--fps", "2200", "-o", "./same.y4m"],
        &["listen", "same.y4m", "--fps", "2200", "-o", "link.y4m"],
        &["simulate", "s.toml", "-o", "s.toml"],
        &["probe", "same.y4m", "--json", "same.y4m"],
        &["score", "ref.wav", "ref.wav", "--json", "ref.wav"],
        &[
            "calibrate",
            "same.y4m",
            "--fps",
            "2200",
            "--reference",
            "ref.wav",
            "--json",
            "ref.wav",
        ],
        &["spectrum", "same.y4m", "--fps", "2200", "-o", "same.y4m"],
        &[
            "run",
            "motion",
            "--replay",
            "same.y4m",
            "--set",
            "out.path=same.y4m",
            "--quiet",
        ],
    ];
    for args in cases {
        let o = run_in(d, args);
        no_panic(&o);
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("is the same file as the input"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    for (f, s) in files.iter().zip(&sums) {
        assert_eq!(checksum(&d.join(f)), *s, "{f} changed");
    }
    // A missing output directory is refused before the work.
    let o = run_in(
        d,
        &["listen", "same.y4m", "--fps", "2200", "-o", "no/x.wav"],
    );
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
}

/// Scene fields out of bounds are refused at validation, before anything
/// is allocated, naming the user's file, line and field.
#[test]
fn scene_bounds_and_errors_at_the_right_place() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 4x4 picture for the texture.
    let mut pgm = b"P5\n4 4\n255\n".to_vec();
    pgm.extend((0..16u8).map(|i| i * 10));
    std::fs::write(d.join("t.pgm"), &pgm).unwrap();
    let head = "width = 64\nheight = 48\nfps = 2200.0\nduration_s = 0.01\n";
    let cases: &[(&str, &[&str])] = &[
        (
            "interference = [{ freq_hz = 137.0, amplitude_px = 9.2e18 }]\n",
            &["s.toml:5", "field `interference`", "amplitude_px", "1000"],
        ),
        (
            "interference = [{ freq_hz = 137.0, amplitude_px = 65536.0 }]\n",
            &["s.toml:5", "field `interference`"],
        ),
        (
            "amplitude_px = 0.001\ninterference = [{ freq_hz = 137.0, amplitude_px = 999.0 }, { freq_hz = 50.0, amplitude_px = 999.0 }]\n",
            &["s.toml:5", "field `amplitude_px`", "excursion"],
        ),
        (
            "texture = \"t.pgm\"\nobject = [0, 0, 8000, 8000]\n",
            &["s.toml:6", "field `object`", "extends past the 64x48 frame"],
        ),
        ("duration_s =\n", &["s.toml:5", "field `duration_s`", "value is missing"]),
        (
            "seed = 18446744073709551616\n",
            &["s.toml:5", "field `seed`", "too large"],
        ),
    ];
    for (extra, needles) in cases {
        std::fs::write(d.join("s.toml"), format!("{head}{extra}")).unwrap();
        let sum = checksum(&d.join("s.toml"));
        let o = run_in(d, &["simulate", "s.toml", "-o", "out.y4m"]);
        no_panic(&o);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{extra}: {err}");
        for n in *needles {
            assert!(err.contains(n), "`{n}` not in: {err}");
        }
        assert!(!err.contains("render.toml"), "{err}");
        assert!(!d.join("out.y4m").exists(), "{extra}");
        assert_eq!(checksum(&d.join("s.toml")), sum);
    }
    // A pipeline file ending in `key =` names the line and the field.
    std::fs::write(
        d.join("p.toml"),
        "[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\nduration_s =",
    )
    .unwrap();
    let o = run_in(d, &["run", "p.toml"]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("p.toml:4: field `duration_s`: the value is missing"),
        "{}",
        stderr(&o)
    );
}

/// `score` checks rates and lengths from the headers before resampling,
/// and a degenerate reference is an error that says what is wrong.
#[test]
fn score_bounds_and_degenerate_references() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tone: Vec<f32> = (0..16000).map(|i| (i as f32 * 0.07).sin()).collect();
    write_wav_f32(&d.join("t.wav"), 16000, &tone);
    write_wav_f32(&d.join("huge_rate.wav"), 1_000_000_000, &tone[..1000]);
    write_wav_f32(&d.join("empty.wav"), 16000, &[]);
    write_wav_f32(&d.join("one.wav"), 16000, &[0.5]);
    write_wav_f32(&d.join("nan.wav"), 16000, &[f32::NAN; 100]);
    write_wav_f32(&d.join("inf.wav"), 16000, &[f32::INFINITY; 100]);
    write_wav_f32(&d.join("silent.wav"), 16000, &[0.0; 16000]);
    // A header claiming 2^23 + 1 samples (the file holds 4): refused from
    // the header, before reading or allocating.
    let mut long = std::fs::read(d.join("one.wav")).unwrap();
    let n = (1u32 << 23) + 1;
    let data = long.len() - 4;
    long[data..].copy_from_slice(&[0, 0, 0, 63]);
    let at = long.windows(4).position(|w| w == b"data").unwrap();
    long[at + 4..at + 8].copy_from_slice(&(4 * n).to_le_bytes());
    std::fs::write(d.join("long.wav"), &long).unwrap();
    let sum = checksum(&d.join("t.wav"));
    let cases: &[(&[&str], &str)] = &[
        (&["huge_rate.wav", "t.wav"], "outside 1..=768000 Hz"),
        (&["t.wav", "huge_rate.wav"], "outside 1..=768000 Hz"),
        (&["empty.wav", "t.wav"], "holds 0 samples"),
        (&["one.wav", "t.wav"], "holds 1 samples"),
        (&["nan.wav", "t.wav"], "NaN"),
        (&["inf.wav", "t.wav"], "inf"),
        (&["silent.wav", "t.wav"], "silent"),
        (&["t.wav", "empty.wav"], "holds 0 samples"),
        (&["long.wav", "t.wav"], "longer than score accepts"),
        (&["t.wav", "long.wav"], "longer than score accepts"),
    ];
    for (args, needle) in cases {
        let mut a = vec!["score"];
        a.extend_from_slice(args);
        let o = run_in(d, &a);
        no_panic(&o);
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(args[0]) || stderr(&o).contains(args[1]));
    }
    // A metric that cannot be computed says why.
    let o = run_in(d, &["score", "t.wav", "one.wav"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["stoi"].is_null(), "{v}");
    let notes = v["notes"].as_array().expect("notes");
    assert!(
        notes
            .iter()
            .any(|n| n.as_str().unwrap().starts_with("stoi: cannot be computed")),
        "{v}"
    );
    assert_eq!(checksum(&d.join("t.wav")), sum);
}

/// SIGINT, SIGTERM and SIGHUP during a run each finalise the WAV (its
/// header matches its data) and exit 128 + the signal.
#[test]
fn signals_finalise_outputs_with_the_documented_exit_code() {
    for (sig, expected) in [("INT", 130), ("TERM", 143), ("HUP", 129)] {
        let dir = tempfile::tempdir().unwrap();
        let o = interrupt_live_demo(dir.path(), sig);
        no_panic(&o);
        assert_eq!(code(&o), expected, "SIG{sig}: {}", stderr(&o));
        let p = dir.path().join("demo.wav");
        let (rate, s) = read_wav(&p);
        assert_eq!(rate, 500);
        assert!(s.len() > 500, "SIG{sig}: only {} samples", s.len());
        // The header's sizes match the file: RIFF = len - 8, data = 4 * n.
        let bytes = std::fs::read(&p).unwrap();
        let riff = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
        assert_eq!(riff, bytes.len() - 8, "SIG{sig}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".partial"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
}

/// A video with a header and no frames is an input error (exit 2), not a
/// success that wrote nothing; no output is left behind.
#[test]
fn a_video_with_no_frames_exits_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("zero.y4m"),
        "YUV4MPEG2 W64 H48 F2200:1 Ip A1:1 Cmono\n",
    )
    .unwrap();
    let sum = checksum(&d.join("zero.y4m"));
    for args in [
        &["listen", "zero.y4m", "-o", "zero.wav"][..],
        &["spectrum", "zero.y4m", "-o", "zero.json"][..],
        &[
            "run",
            "motion",
            "--replay",
            "zero.y4m",
            "--set",
            "out.path=zero.wav",
        ][..],
    ] {
        let o = run_in(d, args);
        no_panic(&o);
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("zero.y4m: holds no frames"),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("wrote "), "{}", stderr(&o));
        assert!(!d.join("zero.wav").exists() && !d.join("zero.json").exists());
    }
    assert_eq!(checksum(&d.join("zero.y4m")), sum);
}

/// A full disk (a 64 KiB tmpfs the test mounts, when it may): the run
/// fails naming the file (exit 1), the WAV's header matches the whole
/// samples on disk, and no temporary file is left.
#[test]
fn disk_full_finalises_what_fits() {
    let dir = tempfile::tempdir().unwrap();
    let mnt = dir.path().join("full");
    std::fs::create_dir(&mnt).unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(&mnt)
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipping: cannot mount a tmpfs here (needs root)");
        return;
    }
    let o = run_in(
        &mnt,
        &[
            "run",
            "demo",
            "--set",
            "cam.width=32",
            "--set",
            "cam.height=32",
            "--set",
            "cam.frames=40000",
            "--quiet",
        ],
    );
    let names: Vec<String> = std::fs::read_dir(&mnt)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    let wav = std::fs::read(mnt.join("demo.wav"));
    let _ = std::process::Command::new("umount").arg(&mnt).status();
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("demo.wav"), "{}", stderr(&o));
    assert!(stderr(&o).contains("No space left"), "{}", stderr(&o));
    assert!(!names.iter().any(|n| n.ends_with(".partial")), "{names:?}");
    let bytes = wav.unwrap();
    let riff = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
    assert_eq!(riff, bytes.len() - 8);
    let at = bytes.windows(4).position(|w| w == b"data").unwrap();
    let data = u32::from_le_bytes(bytes[at + 4..at + 8].try_into().unwrap()) as usize;
    assert_eq!(data, bytes.len() - at - 8);
    assert!(data > 10_000, "only {data} bytes of samples");
}
