//! Hostile input and conditions (issue 20): each case once found a panic,
//! an abort, lost data or a misleading exit. Every test asserts the exit
//! code and the message, that nothing panicked, that the inputs are
//! unchanged (checksums before and after) and that outputs are valid or
//! absent. Inputs are small and made here.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
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
            // Caught at validation (the resonance's steady-state gain),
            // which does not filter the signal.
            "amplitude_px = 100.0\nresonances = [{ freq_hz = 440.0, q = 10.0, gain_db = 40.0 }]\n",
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
        // The header's sizes match the file: RIFF = len - 8, data to the end.
        assert_whole_wav(&p, &format!("SIG{sig}"));
        no_partial(dir.path(), &format!("SIG{sig}"));
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

/// Mounts a 64 KiB tmpfs at `dir/full` (a disk that fills up), or None
/// with a printed reason where the test may not mount (not root).
fn small_tmpfs(dir: &Path) -> Option<std::path::PathBuf> {
    let mnt = dir.join("full");
    std::fs::create_dir(&mnt).unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(&mnt)
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipping: cannot mount a tmpfs here (needs root)");
        return None;
    }
    Some(mnt)
}

/// A full disk (a 64 KiB tmpfs the test mounts, when it may): the run
/// fails naming the file (exit 1), the WAV's header matches the whole
/// samples on disk, and no temporary file is left.
#[test]
fn disk_full_finalises_what_fits() {
    let dir = tempfile::tempdir().unwrap();
    let Some(mnt) = small_tmpfs(dir.path()) else {
        return;
    };
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
    let copy = dir.path().join("copy.wav");
    std::fs::write(&copy, wav.unwrap()).unwrap();
    let n = assert_whole_wav(&copy, "full disk");
    assert!(n > 2500, "only {n} samples");
}

/// Sends `sig` to a running child once `ready` says its work has begun
/// (polled every 20 ms, for at most 60 s), then waits for it.
fn interrupt_when(
    mut child: std::process::Child,
    sig: &str,
    ready: impl Fn() -> bool,
) -> std::process::Output {
    let t0 = std::time::Instant::now();
    while !ready() {
        assert!(
            t0.elapsed().as_secs() < 60,
            "the command never started its work"
        );
        if let Ok(Some(st)) = child.try_wait() {
            panic!("the command ended ({st}) before SIG{sig} was sent");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let st = std::process::Command::new("kill")
        .args([&format!("-{sig}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    child.wait_with_output().unwrap()
}

/// A WAV whose header agrees with the file: RIFF size = length - 8, the
/// `data` chunk runs to the end, and it reads back. Returns its samples.
fn assert_whole_wav(p: &Path, what: &str) -> usize {
    let bytes = std::fs::read(p).unwrap_or_else(|e| panic!("{what}: {}: {e}", p.display()));
    let riff = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
    assert_eq!(riff, bytes.len() - 8, "{what}: RIFF size");
    let at = bytes.windows(4).position(|w| w == b"data").unwrap();
    let data = u32::from_le_bytes(bytes[at + 4..at + 8].try_into().unwrap()) as usize;
    assert_eq!(data, bytes.len() - at - 8, "{what}: data size");
    read_wav(p).1.len()
}

/// A Y4M file of whole frames: every frame reads back and the reader saw
/// no frame cut short. Returns the frames.
fn assert_whole_y4m(p: &Path, what: &str) -> u64 {
    use vibroscope_io::{FrameDest, VideoReader};
    let mut r = vibroscope_io::Y4mReader::open(p)
        .unwrap_or_else(|e| panic!("{what}: {}: {e}", p.display()));
    let info = r.info().clone();
    assert!(
        !info.notes.iter().any(|n| n.contains("ends inside")),
        "{what}: {:?}",
        info.notes
    );
    let mut buf = vec![0u16; info.width as usize * info.height as usize];
    let mut b8 = vec![0u8; buf.len()];
    let mut n = 0;
    loop {
        let dst = match info.depth {
            vibroscope_io::Depth::U8 => FrameDest::U8(&mut b8),
            vibroscope_io::Depth::U16 => FrameDest::U16(&mut buf),
        };
        match r.read_frame(dst) {
            Ok(Some(_)) => n += 1,
            Ok(None) => break,
            Err(e) => panic!("{what}: {e}"),
        }
    }
    assert_eq!(Some(n), info.frame_count, "{what}");
    n
}

fn no_partial(d: &Path, what: &str) {
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert!(left.is_empty(), "{what}: {left:?}");
}

const SIGNALS: [(&str, i32); 3] = [("INT", 130), ("TERM", 143), ("HUP", 129)];

/// SIGINT, SIGTERM and SIGHUP while the studio runs a live pipeline: the
/// pipeline stops, its WAV is finalised whole, the studio exits 128 + the
/// signal, and no temporary file is left.
#[test]
fn signals_during_studio_live() {
    for (sig, expected) in SIGNALS {
        let dir = tempfile::tempdir().unwrap();
        let child = bin()
            .current_dir(dir.path())
            .args(["studio", "--pipeline", "demo"])
            .args(LIVE_DEMO)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let t0 = std::time::Instant::now();
        let o = interrupt_when(child, sig, || t0.elapsed().as_millis() > 2000);
        no_panic(&o);
        assert_eq!(code(&o), expected, "SIG{sig}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("finalising outputs"),
            "SIG{sig}: {}",
            stderr(&o)
        );
        let n = assert_whole_wav(&dir.path().join("demo.wav"), &format!("SIG{sig}"));
        assert!(n > 500, "SIG{sig}: only {n} samples");
        no_partial(dir.path(), &format!("SIG{sig}"));
    }
}

/// SIGINT, SIGTERM and SIGHUP while `listen` works (its video arrives on
/// standard input, endlessly): the WAV of what was heard is whole, the exit
/// code is 128 + the signal, no temporary file is left.
#[test]
fn signals_during_listen() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(
        d,
        "s.y4m",
        &["--set", "cam.width=48", "--set", "cam.height=32"],
    );
    let video = std::fs::read(d.join("s.y4m")).unwrap();
    let header = video.iter().position(|&b| b == b'\n').unwrap() + 1;
    for (sig, expected) in SIGNALS {
        let what = format!("listen, SIG{sig}");
        let mut child = bin()
            .current_dir(d)
            .args(["listen", "-", "--fps", "2200", "-o", "l.wav"])
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        let fed = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let feeder = {
            let (video, fed) = (video.clone(), fed.clone());
            std::thread::spawn(move || {
                use std::io::Write;
                if stdin.write_all(&video).is_err() {
                    return;
                }
                // The same frames again and again until listen stops reading.
                while stdin.write_all(&video[header..]).is_ok() {
                    fed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
            })
        };
        let o = interrupt_when(child, sig, || {
            fed.load(std::sync::atomic::Ordering::Relaxed) >= 2
        });
        feeder.join().unwrap();
        no_panic(&o);
        assert_eq!(code(&o), expected, "{what}: {}", stderr(&o));
        let n = assert_whole_wav(&d.join("l.wav"), &what);
        assert!(n > 1000, "{what}: {n} samples");
        no_partial(d, &what);
        std::fs::remove_file(d.join("l.wav")).unwrap();
    }
}

/// The same during `simulate` and `run` writing Y4M: whole frames only.
#[test]
fn signals_during_simulate_and_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("scene.toml"),
        "width = 64\nheight = 48\nfps = 2200.0\nduration_s = 600.0\n\
         signal = { type = \"tone\", freq_hz = 440.0 }\n",
    )
    .unwrap();
    let scene = checksum(&d.join("scene.toml"));
    for (sig, expected) in SIGNALS {
        for args in [
            &["simulate", "scene.toml", "-o", "v.y4m"][..],
            &[
                "run",
                "render",
                "--quiet",
                "--set",
                "cam.duration_s=600",
                // The scene file's frame size (the kind's default is
                // 256x256): 100 kB on disk is then about 32 frames, so the
                // count asserted below is reached before the signal.
                "--set",
                "cam.width=64",
                "--set",
                "cam.height=48",
                "--set",
                "out.path=v.y4m",
            ][..],
        ] {
            let what = format!("{}, SIG{sig}", args[0]);
            let child = bin()
                .current_dir(d)
                .args(args)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            // Started: some frames are on disk (under the final or a temporary name).
            let o = interrupt_when(child, sig, || {
                std::fs::read_dir(d).unwrap().any(|e| {
                    let e = e.unwrap();
                    e.file_name().to_string_lossy().contains("v.y4m")
                        && e.metadata().unwrap().len() > 100_000
                })
            });
            no_panic(&o);
            assert_eq!(code(&o), expected, "{what}: {}", stderr(&o));
            let n = assert_whole_y4m(&d.join("v.y4m"), &what);
            assert!(n > 10, "{what}: {n} frames");
            no_partial(d, &what);
            std::fs::remove_file(d.join("v.y4m")).unwrap();
        }
    }
    assert_eq!(checksum(&d.join("scene.toml")), scene);
}

/// The same during `calibrate` (interrupted in its recovery): the exit
/// code is 128 + the signal; the report and the corrected WAV are either
/// absent or whole; the inputs are unchanged.
#[test]
fn signals_during_calibrate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(
        d,
        "c.y4m",
        &[
            "--set",
            "cam.width=64",
            "--set",
            "cam.height=48",
            "--set",
            "cam.duration_s=4",
        ],
    );
    // A 5 s chirp at 8 kHz, longer than the 4 s video.
    let rate = 8000u32;
    let chirp: Vec<f32> = (0..5 * rate)
        .map(|i| {
            let t = i as f64 / rate as f64;
            (std::f64::consts::TAU * (100.0 * t + 50.0 * t * t)).sin() as f32
        })
        .collect();
    write_wav_f32(&d.join("ref.wav"), rate, &chirp);
    let sums = (checksum(&d.join("c.y4m")), checksum(&d.join("ref.wav")));
    for (sig, expected) in SIGNALS {
        let what = format!("calibrate, SIG{sig}");
        let child = bin()
            .current_dir(d)
            .args([
                "calibrate",
                "c.y4m",
                "--reference",
                "ref.wav",
                "--json",
                "r.json",
                "-o",
                "k.wav",
            ])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let t0 = std::time::Instant::now();
        let o = interrupt_when(child, sig, || t0.elapsed().as_millis() > 700);
        no_panic(&o);
        assert_eq!(code(&o), expected, "{what}: {}", stderr(&o));
        if d.join("k.wav").exists() {
            assert_whole_wav(&d.join("k.wav"), &what);
            std::fs::remove_file(d.join("k.wav")).unwrap();
        }
        if d.join("r.json").exists() {
            let t = std::fs::read_to_string(d.join("r.json")).unwrap();
            serde_json::from_str::<serde_json::Value>(&t)
                .unwrap_or_else(|e| panic!("{what}: r.json: {e}"));
            std::fs::remove_file(d.join("r.json")).unwrap();
        }
        no_partial(d, &what);
    }
    assert_eq!(
        (checksum(&d.join("c.y4m")), checksum(&d.join("ref.wav"))),
        sums
    );
}

/// A pipeline writing one video, its motion as WAV and as CSV (fan-out).
fn three_sinks(width: u32, duration_s: f64, amplitude_px: f64) -> String {
    format!(
        "[pipeline]\nname = \"three\"\n\
         [[stage]]\nid = \"cam\"\nkind = \"synthetic\"\nwidth = {width}\nheight = 32\nfps = 2200.0\n\
         duration_s = {duration_s}\namplitude_px = {amplitude_px}\nsignal = {{ type = \"tone\", freq_hz = 440.0 }}\n\
         [[stage]]\nid = \"motion\"\nkind = \"gradient_motion\"\ninput = \"cam\"\n\
         [[stage]]\nid = \"wav\"\nkind = \"wav\"\ninput = \"motion\"\npath = \"same.wav\"\n\
         [[stage]]\nid = \"csv\"\nkind = \"csv\"\ninput = \"motion\"\npath = \"same.csv\"\n\
         [[stage]]\nid = \"y4m\"\nkind = \"y4m\"\ninput = \"cam\"\npath = \"same.y4m\"\n"
    )
}

/// Two runs writing the same WAV, CSV and Y4M paths at once: both succeed
/// and each file is whole and is one run's file, byte for byte (the
/// streaming sinks write a unique temporary sibling and rename it), never
/// a splice of both; no temporary file is left.
#[test]
fn two_concurrent_writers_of_one_path_cannot_splice() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Each run alone, in its own directory: what a whole file of it is.
    let runs = [three_sinks(32, 1.0, 0.05), three_sinks(48, 1.0, 0.2)];
    let mut alone = Vec::new();
    for (i, p) in runs.iter().enumerate() {
        let sub = d.join(format!("alone{i}"));
        std::fs::create_dir(&sub).unwrap();
        std::fs::write(sub.join("p.toml"), p).unwrap();
        let o = run_in(&sub, &["run", "p.toml", "--quiet"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let files: Vec<Vec<u8>> = ["same.wav", "same.csv", "same.y4m"]
            .iter()
            .map(|f| std::fs::read(sub.join(f)).unwrap())
            .collect();
        alone.push(files);
    }
    for (i, p) in runs.iter().enumerate() {
        std::fs::write(d.join(format!("p{i}.toml")), p).unwrap();
    }
    for round in 0..3 {
        let children: Vec<_> = (0..2)
            .map(|i| {
                bin()
                    .current_dir(d)
                    .args(["run", &format!("p{i}.toml"), "--quiet"])
                    .stderr(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for c in children {
            let o = c.wait_with_output().unwrap();
            no_panic(&o);
            assert_eq!(code(&o), 0, "round {round}: {}", stderr(&o));
        }
        for (k, f) in ["same.wav", "same.csv", "same.y4m"].iter().enumerate() {
            let got = std::fs::read(d.join(f)).unwrap();
            assert!(
                got == alone[0][k] || got == alone[1][k],
                "round {round}: {f} ({} bytes) is neither run's file ({} or {} bytes)",
                got.len(),
                alone[0][k].len(),
                alone[1][k].len()
            );
        }
        assert_whole_wav(&d.join("same.wav"), "wav");
        assert_whole_y4m(&d.join("same.y4m"), "y4m");
        no_partial(d, &format!("round {round}"));
    }
}

/// A full disk (a 64 KiB tmpfs the test mounts, when it may) under the
/// streaming Y4M and CSV sinks: exit 1 naming the file, the Y4M holds
/// whole frames only, the CSV whole rows only, no temporary file is left.
#[test]
fn disk_full_keeps_whole_frames_and_rows() {
    let dir = tempfile::tempdir().unwrap();
    let Some(mnt) = small_tmpfs(dir.path()) else {
        return;
    };
    // Only one of the two sinks per run, so that it is the one that fills the disk.
    let mut results = Vec::new();
    for (sink, extra) in [
        ("y4m", "[[stage]]\nid = \"y4m\"\nkind = \"y4m\"\ninput = \"cam\"\npath = \"same.y4m\"\n"),
        ("csv", "[[stage]]\nid = \"motion\"\nkind = \"gradient_motion\"\ninput = \"cam\"\n[[stage]]\nid = \"csv\"\nkind = \"csv\"\ninput = \"motion\"\npath = \"same.csv\"\n"),
    ] {
        let p = format!(
            "[pipeline]\nname = \"full\"\n[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\n\
             width = 33\nheight = 17\nfps = 2200.0\nduration_s = 20.0\n\
             signal = {{ type = \"tone\", freq_hz = 440.0 }}\n{extra}"
        );
        std::fs::write(dir.path().join(format!("{sink}.toml")), p).unwrap();
        let toml = dir.path().join(format!("{sink}.toml"));
        let o = run_in(&mnt, &["run", toml.to_str().unwrap(), "--quiet"]);
        let names: Vec<String> = std::fs::read_dir(&mnt)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        let file = mnt.join(format!("same.{sink}"));
        let copy = dir.path().join(format!("copy.{sink}"));
        let _ = std::fs::copy(&file, &copy);
        let _ = std::fs::remove_file(&file);
        results.push((sink, o, names, copy));
    }
    let _ = std::process::Command::new("umount").arg(&mnt).status();
    for (sink, o, names, copy) in results {
        no_panic(&o);
        assert_eq!(code(&o), 1, "{sink}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("same.{sink}")),
            "{}",
            stderr(&o)
        );
        assert!(stderr(&o).contains("No space left"), "{}", stderr(&o));
        assert!(!names.iter().any(|n| n.ends_with(".partial")), "{names:?}");
        match sink {
            "y4m" => {
                let n = assert_whole_y4m(&copy, "full disk");
                assert!(n > 10, "only {n} frames");
            }
            _ => {
                let t = std::fs::read_to_string(&copy).unwrap();
                assert!(t.ends_with('\n'), "the CSV ends inside a row");
                let rows: Vec<&str> = t.lines().collect();
                assert_eq!(rows[0], "t_s,value");
                assert!(rows.len() > 100, "only {} rows", rows.len());
                for r in &rows[1..] {
                    let (a, b) = r.split_once(',').unwrap();
                    a.parse::<f64>().unwrap();
                    b.parse::<f64>().unwrap();
                }
            }
        }
    }
}

/// A calibration report whose clock error is out of range (-1e6 ppm once
/// gave a 0-sample WAV): `listen --calibration` refuses it before any work
/// (exit 2, the field and value named), writes nothing, changes nothing.
#[test]
fn a_calibration_report_out_of_range_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(d, "s.y4m", SMALL);
    std::fs::write(
        d.join("r.json"),
        r#"{"effects": [{"name": "time_base", "parameters": {"clock_error_ppm": -1e6}}]}"#,
    )
    .unwrap();
    let sums = (checksum(&d.join("s.y4m")), checksum(&d.join("r.json")));
    let o = run_in(
        d,
        &["listen", "s.y4m", "--calibration", "r.json", "-o", "l.wav"],
    );
    no_panic(&o);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("r.json") && err.contains("clock_error_ppm") && err.contains("-1000000"),
        "{err}"
    );
    assert!(!d.join("l.wav").exists());
    no_partial(d, "listen --calibration");
    assert_eq!(
        (checksum(&d.join("s.y4m")), checksum(&d.join("r.json"))),
        sums
    );
}

/// Frame rates below 1 Hz, from a flag (`--fps 1e-300`), a Y4M header
/// (`F1:4294967295`) or a `.cih` save step (99999999999), once panicked in
/// the resampler or aborted allocating terabytes after the work had begun:
/// each is refused before any frame is processed, naming the rate, and
/// nothing is written. The flag is a usage error (exit 2); a file's rate is
/// found when the pipeline starts its source (exit 1, as a file that
/// states no rate).
#[test]
fn frame_rates_below_one_hertz_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(d, "s.y4m", SMALL);
    let video = std::fs::read(d.join("s.y4m")).unwrap();
    let nl = video.iter().position(|&b| b == b'\n').unwrap();
    let header = String::from_utf8(video[..nl].to_vec()).unwrap();
    let slow: String = header
        .split(' ')
        .map(|t| {
            if t.starts_with('F') {
                "F1:4294967295"
            } else {
                t
            }
        })
        .collect::<Vec<_>>()
        .join(" ");
    let mut f = slow.into_bytes();
    f.extend_from_slice(&video[nl..]);
    std::fs::write(d.join("slow.y4m"), &f).unwrap();
    std::fs::write(
        d.join("m.cih"),
        "Record Rate(fps) : 20000\nTotal Frame : 2\nSave Step : 99999999999\n\
         Image Width : 4\nImage Height : 2\nColor Type : Mono\nColor Bit : 8\nFile Format : MRaw\n",
    )
    .unwrap();
    std::fs::write(d.join("m.mraw"), [7u8; 16]).unwrap();
    let sums = [
        checksum(&d.join("s.y4m")),
        checksum(&d.join("slow.y4m")),
        checksum(&d.join("m.cih")),
    ];
    for (args, needle, exit) in [
        (
            &["listen", "s.y4m", "--fps", "1e-300", "-o", "l.wav"][..],
            "fps",
            2,
        ),
        (
            &["listen", "slow.y4m", "-o", "l.wav"][..],
            "slow.y4m: frame rate must be at least 1 Hz",
            1,
        ),
        (
            &["listen", "m.cih", "-o", "l.wav"][..],
            "frame rate must be at least 1 Hz",
            1,
        ),
    ] {
        let o = run_in(d, args);
        no_panic(&o);
        assert!(!stderr(&o).contains("memory allocation"), "{}", stderr(&o));
        assert_eq!(code(&o), exit, "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
        assert!(!d.join("l.wav").exists(), "{args:?}");
        no_partial(d, &format!("{args:?}"));
    }
    assert_eq!(
        [
            checksum(&d.join("s.y4m")),
            checksum(&d.join("slow.y4m")),
            checksum(&d.join("m.cih")),
        ],
        sums
    );
}

/// A whole-recording spectrum keeps channels x frames: with a `phase`
/// stage's `tiles = 32` (8192 channels) it grows by 32 KiB a frame, and
/// past 64 MiB it is refused under a 100 MiB limit (exit 1, the message
/// says what to change), not killed for memory; no peaks file is left.
#[test]
fn a_whole_spectrum_of_too_many_channels_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("p.toml"),
        "[[stage]]\nid = \"src\"\nkind = \"synthetic\"\nwidth = 64\nheight = 64\nfps = 1000.0\n\
         frames = 4000\nnoise_std = 1.0\n\
         [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\npyramid = \"riesz\"\ntiles = 32\n\
         [[stage]]\nid = \"spectrum\"\nkind = \"spectrum\"\ninput = \"phase\"\nmode = \"whole\"\n\
         [[stage]]\nid = \"out\"\nkind = \"peaks\"\ninput = \"spectrum\"\npath = \"s.json\"\n",
    )
    .unwrap();
    let o = bin()
        .current_dir(d)
        .env("VIBROSCOPE_MAX_MEMORY", "100M")
        .args(["run", "p.toml", "-q"])
        .output()
        .unwrap();
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    for want in [
        "whole-recording spectrum of 8192 channels",
        "would need up to",
        "tiles",
    ] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    assert!(!d.join("s.json").exists());
}

/// A frame size whose pyramids would not fit in the memory the process
/// may take is refused when the first frame arrives, before the
/// pyramids are allocated: the message gives the bound and what to
/// change, the exit is 1 (a resource, not a setting), and no output is
/// written. `VIBROSCOPE_MAX_MEMORY` sets the limit; a value that is not a
/// size is named.
#[test]
fn frames_too_large_for_the_memory_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (1024usize, 1024usize);
    let mut y4m = format!("YUV4MPEG2 W{w} H{h} F100:1 Ip A1:1 Cmono\n").into_bytes();
    for i in 0..2u8 {
        y4m.extend_from_slice(b"FRAME\n");
        y4m.extend((0..w * h).map(|p| (p as u8).wrapping_mul(31).wrapping_add(i)));
    }
    std::fs::write(d.join("big.y4m"), &y4m).unwrap();
    let sum = checksum(&d.join("big.y4m"));
    let listen = |limit: &str| {
        bin()
            .current_dir(d)
            .env("VIBROSCOPE_MAX_MEMORY", limit)
            .args(["listen", "big.y4m", "-o", "big.wav", "--method", "phase"])
            .output()
            .unwrap()
    };
    // The bound for 1024² (steerable pyramid, 2 orientations) is at least
    // 160 bytes a pixel, 168 MB: above a 64 MiB limit whatever the cores.
    let o = listen("64M");
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    for want in [
        "1024x1024 frames",
        "would need up to",
        "VIBROSCOPE_MAX_MEMORY",
        "threads",
    ] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    assert!(!d.join("big.wav").exists());
    let o = listen("12X");
    no_panic(&o);
    assert_ne!(code(&o), 0);
    assert!(
        stderr(&o).contains("VIBROSCOPE_MAX_MEMORY=\"12X\" is not a size"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("big.wav").exists());
    // The default method (per-tile gradients, 37 bytes a pixel) under a
    // 16 MiB limit.
    let o = bin()
        .current_dir(d)
        .env("VIBROSCOPE_MAX_MEMORY", "16M")
        .args(["listen", "big.y4m", "-o", "big.wav"])
        .output()
        .unwrap();
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    for want in ["1024x1024 frames in `tile_motion`", "would need up to"] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    assert!(!d.join("big.wav").exists());
    // The noise bound of the same frames: 32 bytes a pixel and 64 MiB.
    let o = bin()
        .current_dir(d)
        .env("VIBROSCOPE_MAX_MEMORY", "64M")
        .args(["bound", "big.y4m", "--json", "b.json"])
        .output()
        .unwrap();
    no_panic(&o);
    assert_ne!(code(&o), 0, "{}", stderr(&o));
    for want in ["big.y4m", "1024x1024 frames", "would need up to"] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    assert!(!d.join("b.json").exists());
    // A modal image of the same frames: 120+ bytes a pixel, over 64 MiB.
    let o = bin()
        .current_dir(d)
        .env("VIBROSCOPE_MAX_MEMORY", "64M")
        .args(["modes", "big.y4m", "--at", "10", "-o", "m.png"])
        .output()
        .unwrap();
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    for want in ["modal image of 1024x1024 pixels", "would need up to", "roi"] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    assert!(!d.join("m.png").exists());
    // Magnification of the same frames: 584 bytes a pixel by default (8
    // orientations).
    let o = bin()
        .current_dir(d)
        .env("VIBROSCOPE_MAX_MEMORY", "300M")
        .args([
            "magnify", "big.y4m", "--band", "5,15", "--factor", "10", "-o", "mg.y4m",
        ])
        .output()
        .unwrap();
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    for want in ["magnifying 1024x1024 pixels", "would need up to", "roi"] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    assert!(!d.join("mg.y4m").exists());
    // A `pyramid` stage: its workers' pyramids and the coefficient sets
    // its consumers can hold.
    std::fs::write(
        d.join("pyr.toml"),
        "[pipeline]\nname = \"pyr\"\n\
         [[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"big.y4m\"\n\
         [[stage]]\nid = \"pyr\"\nkind = \"pyramid\"\ninput = \"src\"\n\
         [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"pyr\"\n\
         [[stage]]\nid = \"out\"\nkind = \"null\"\ninput = \"phase\"\n",
    )
    .unwrap();
    let o = bin()
        .current_dir(d)
        .env("VIBROSCOPE_MAX_MEMORY", "64M")
        .args(["run", "pyr.toml"])
        .output()
        .unwrap();
    no_panic(&o);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    for want in [
        "stage `pyr`",
        "coefficient sets in flight",
        "would need up to",
        "capacity",
    ] {
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    // Raised, the same video runs.
    let o = listen("0");
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(d.join("big.wav").exists());
    assert_eq!(checksum(&d.join("big.y4m")), sum);
}

/// A reference WAV that is finite but huge (3e38, float) is refused with
/// its peak named, before anything is computed: it once gave a corrected
/// WAV mostly inf and NaN. No output is written.
#[test]
fn calibrate_refuses_a_huge_reference() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_y4m(d, "v.y4m", &["--set", "cam.duration_s=0.2"]);
    let rate = 8000u32;
    let tone: Vec<f32> = (0..rate).map(|i| 3e38 * (i as f32 * 0.3).sin()).collect();
    write_wav_f32(&d.join("ref.wav"), rate, &tone);
    let sums = (checksum(&d.join("v.y4m")), checksum(&d.join("ref.wav")));
    let o = run_in(
        d,
        &[
            "calibrate",
            "v.y4m",
            "--reference",
            "ref.wav",
            "--json",
            "r.json",
            "-o",
            "c.wav",
        ],
    );
    no_panic(&o);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("ref.wav: peaks at 3.000e38"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("r.json").exists() && !d.join("c.wav").exists());
    assert_eq!(
        sums,
        (checksum(&d.join("v.y4m")), checksum(&d.join("ref.wav")))
    );
}
