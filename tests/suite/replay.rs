//! Replay: synthetic scenes rendered to Y4M (the engine's own render
//! pipeline) and replayed through the same file path a user's recording
//! takes; outputs are bit-identical run to run and for any thread count.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use vibroscope_math::truth::snr_db_fit;

const SCENE: &[&str] = &[
    "--set",
    "cam.width=96",
    "--set",
    "cam.height=64",
    "--set",
    "cam.fps=2200",
    "--set",
    "cam.duration_s=0.2",
    "--set",
    "cam.amplitude_px=0.1",
    "--set",
    "cam.signal={ type = \"tone\", freq_hz = 300.0 }",
];

#[test]
fn replay_recovers_the_rendered_motion() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    let o = run_in(
        dir.path(),
        &[
            "run",
            "motion",
            "--replay",
            "scene.y4m",
            "--set",
            "out.path=m.wav",
            "--quiet",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let (rate, est) = read_wav(&dir.path().join("m.wav"));
    assert_eq!(rate, 2200, "the WAV rate is the camera's frame rate");
    assert_eq!(est.len(), 440);
    // Ground truth from the same forward model and the same parameters.
    let mut decl = vibroscope::pipeline::load("render").unwrap();
    for pair in SCENE.chunks(2) {
        vibroscope_engine::config::apply_set(&mut decl, pair[1]).unwrap();
    }
    let truth = true_motion(&decl, "cam", est.len());
    let est: Vec<f64> = est.iter().map(|&v| v as f64).collect();
    let snr = snr_db_fit(&truth, &est);
    eprintln!("replayed motion SNR {snr:.1} dB");
    assert!(snr > 15.0, "SNR {snr:.1} dB");
}

#[test]
fn replay_is_bit_identical_across_runs_and_thread_counts() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    let mut outputs = Vec::new();
    for (i, threads) in ["1", "1", "2", "4"].iter().enumerate() {
        let wav = format!("out{i}.wav");
        let o = run_in(
            dir.path(),
            &[
                "run",
                "motion",
                "--replay",
                "scene.y4m",
                "--set",
                &format!("out.path={wav}"),
                "--set",
                &format!("motion.threads={threads}"),
                "--quiet",
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        outputs.push(std::fs::read(dir.path().join(&wav)).unwrap());
        let csv = format!("out{i}.csv");
        let o = run_in(
            dir.path(),
            &[
                "run",
                "intensity",
                "--replay",
                "scene.y4m",
                "--set",
                &format!("out.path={csv}"),
                "--set",
                &format!("mean.threads={threads}"),
                "--quiet",
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        outputs.push(std::fs::read(dir.path().join(&csv)).unwrap());
    }
    for k in 2..outputs.len() {
        assert!(
            outputs[k] == outputs[k % 2],
            "output {k} differs from run {}",
            k % 2
        );
    }
}

#[test]
fn replay_uses_timestamps_written_by_the_recorder() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    let o = run_in(dir.path(), &["probe", "scene.y4m"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("timestamps:  present"), "{out}");
    assert!(out.contains("frames:      440"), "{out}");
    assert!(out.contains("96x64"), "{out}");
    // The CSV's time column follows the recorded timestamps (t = n / 2200).
    let o = run_in(
        dir.path(),
        &[
            "run",
            "intensity",
            "--replay",
            "scene.y4m",
            "--set",
            "out.path=t.csv",
            "--quiet",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.path().join("t.csv")).unwrap();
    let row = text.lines().nth(11).unwrap();
    let t: f64 = row.split(',').next().unwrap().parse().unwrap();
    assert!((t - 10.0 / 2200.0).abs() < 1e-9, "{row}");
}

#[test]
fn replay_from_stdin() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    let f = std::fs::File::open(dir.path().join("scene.y4m")).unwrap();
    let o = bin()
        .current_dir(dir.path())
        .args([
            "run",
            "motion",
            "--replay",
            "-",
            "--set",
            "out.path=s.wav",
            "--quiet",
        ])
        .stdin(f)
        .output()
        .unwrap();
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert_eq!(read_wav(&dir.path().join("s.wav")).1.len(), 440);
}

#[test]
fn live_pipeline_replays_unchanged_and_never_drops() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    // Written for a live camera: drop-oldest capture edge, a slow stage.
    let live = "[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\nrealtime = true\nwidth = 96\nheight = 64\n\n\
                [[stage]]\nid = \"slow\"\nkind = \"passthrough\"\ninput = \"cam\"\ncapacity = 2\npolicy = \"drop_oldest\"\ndelay_us = 200\n\n\
                [[stage]]\nid = \"motion\"\nkind = \"gradient_motion\"\ninput = \"slow\"\n\n\
                [[stage]]\nid = \"out\"\nkind = \"wav\"\ninput = \"motion\"\npath = \"live.wav\"\n";
    std::fs::write(dir.path().join("live.toml"), live).unwrap();
    let o = run_in(
        dir.path(),
        &[
            "run",
            "live.toml",
            "--replay",
            "scene.y4m",
            "--stats",
            "--quiet",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let table = stderr(&o);
    let slow = table
        .lines()
        .find(|l| l.starts_with("slow"))
        .unwrap_or_else(|| panic!("{table}"));
    let cols: Vec<&str> = slow.split_whitespace().collect();
    assert_eq!(cols[2], "440", "every frame reaches the slow stage: {slow}");
    assert_eq!(cols[4], "0", "a replay drops nothing: {slow}");
    assert_eq!(read_wav(&dir.path().join("live.wav")).1.len(), 440);
}

/// The visual microphone itself (issue 3): the phase stage spreads frames
/// over workers, each computing a whole frame, so its output does not
/// depend on the thread count; checked for both pyramids with 1, 2 and 3
/// workers (3 leaves a short last batch), with the reference renewed every
/// 31 ms so that renewals and their handovers fall inside batches.
#[test]
fn phase_stage_is_bit_identical_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    for pyramid in ["csp", "riesz"] {
        let mut outputs = Vec::new();
        for threads in ["1", "2", "3", "2"] {
            let wav = format!("{pyramid}-{threads}.wav");
            let o = run_in(
                dir.path(),
                &[
                    "run",
                    "visual-microphone",
                    "--replay",
                    "scene.y4m",
                    "--set",
                    &format!("out.path={wav}"),
                    "--set",
                    &format!("phase.pyramid=\"{pyramid}\""),
                    "--set",
                    &format!("phase.threads={threads}"),
                    // Renewals (with their handovers) across batches.
                    "--set",
                    "phase.reference_interval_s=0.031",
                    "--set",
                    "phase.reference_overlap=7",
                    "--quiet",
                ],
            );
            assert_eq!(code(&o), 0, "{}", stderr(&o));
            let bytes = std::fs::read(dir.path().join(&wav)).unwrap();
            assert!(bytes.len() > 1000, "{wav} is too short");
            outputs.push((threads, bytes));
        }
        for (t, b) in &outputs[1..] {
            assert!(
                *b == outputs[0].1,
                "{pyramid}: threads = {t} differs from threads = 1"
            );
        }
    }
}

/// `--stats` counts the work `phase` does on its helper thread. With two
/// workers on frames it streams them to the helper, which on a live source
/// (frames a period apart) computes nearly all of them, while the stage's
/// own thread only hands them over: its time alone read 5 µs a frame on
/// 256x256 where a frame takes about 190. So the stage's time per frame
/// live must be at least half of its time per frame on a replay of the same
/// file (both workers busy there); with the helper counted it was 1.6
/// times, without it 0.07.
#[test]
fn phase_stats_count_its_helper_on_a_live_source() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SCENE.to_vec();
    scene.extend(["--set", "cam.width=256", "--set", "cam.height=256"]);
    render_y4m(dir.path(), "scene.y4m", &scene);
    let us_per_frame = |realtime: bool| -> f64 {
        let toml = format!(
            "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"scene.y4m\"\nrealtime = {realtime}\n\n\
             [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\npyramid = \"riesz\"\nthreads = 2\n\n\
             [[stage]]\nid = \"out\"\nkind = \"null\"\ninput = \"phase\"\n"
        );
        std::fs::write(dir.path().join("p.toml"), toml).unwrap();
        let o = run_in(dir.path(), &["run", "p.toml", "--stats", "--quiet"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let table = stderr(&o);
        let row = table
            .lines()
            .find(|l| l.starts_with("phase "))
            .unwrap_or_else(|| panic!("no phase row: {table}"));
        let cols: Vec<&str> = row.split_whitespace().collect();
        // Every frame reaches the stage or is counted as dropped (a live
        // source drops the oldest when the stage falls behind, as it may
        // under load).
        let count = |i: usize| cols[i].parse::<u64>().unwrap_or_else(|_| panic!("{row}"));
        assert_eq!(count(2) + count(4), 440, "{row}");
        if !realtime {
            assert_eq!(count(4), 0, "a replay drops nothing: {row}");
        }
        cols[6].parse().unwrap_or_else(|_| panic!("{row}"))
    };
    let replay = us_per_frame(false);
    let live = us_per_frame(true);
    eprintln!("phase: {replay:.1} us a frame on a replay, {live:.1} live");
    assert!(
        live >= 0.5 * replay,
        "phase's time a frame live ({live:.1} us) leaves out its helper (replay: {replay:.1} us)"
    );
}

/// Frame times survive a gap (frames lost before the file was written): the
/// phase stage's sample blocks start afresh at the gap, so every sample
/// carries its frame's capture time, not one extrapolated from the rate.
#[test]
fn phase_samples_keep_their_frame_times_across_a_gap() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (32usize, 32usize);
    let mut y4m = format!("YUV4MPEG2 W{w} H{h} F1000:1 Ip A1:1 Cmono\n").into_bytes();
    let mut times = Vec::new();
    let mut state = 12345u32;
    let texture: Vec<u8> = (0..w * h)
        .map(|_| {
            state = state.wrapping_mul(1664525).wrapping_add(1013904223);
            (state >> 24) as u8
        })
        .collect();
    for k in 0..200u64 {
        // 1 ms apart, with 37 frames missing after frame 99.
        let t = if k < 100 { k } else { k + 37 } * 1_000_000;
        times.push(t);
        y4m.extend_from_slice(format!("FRAME Xts={t}\n").as_bytes());
        y4m.extend_from_slice(&texture);
    }
    std::fs::write(dir.path().join("gap.y4m"), y4m).unwrap();
    let toml = "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"gap.y4m\"\n\n\
                [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\nscales = 2\nblock = 64\n\n\
                [[stage]]\nid = \"out\"\nkind = \"csv\"\ninput = \"phase\"\npath = \"t.csv\"\n";
    std::fs::write(dir.path().join("gap.toml"), toml).unwrap();
    let o = run_in(dir.path(), &["run", "gap.toml", "--quiet"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let csv = std::fs::read_to_string(dir.path().join("t.csv")).unwrap();
    let got: Vec<f64> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(got.len(), times.len());
    for (k, (g, t)) in got.iter().zip(&times).enumerate() {
        assert!(
            (g - *t as f64 * 1e-9).abs() < 1e-7,
            "sample {k}: {g} s, frame at {t} ns"
        );
    }
}

/// The pyramid as a stage of its own (issue 3, item 1): `pyramid -> phase`
/// reads the coefficients `phase` would have computed itself, so the two
/// graphs write the same bytes, for both pyramids, for any thread count,
/// with reference renewals inside the run.
#[test]
fn pyramid_stage_then_phase_equals_phase() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(dir.path(), "scene.y4m", SCENE);
    let split = "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"scene.y4m\"\n\n\
                 [[stage]]\nid = \"pyr\"\nkind = \"pyramid\"\ninput = \"src\"\n\n\
                 [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"pyr\"\nreference_interval_s = 0.031\nreference_overlap = 7\n\n\
                 [[stage]]\nid = \"out\"\nkind = \"csv\"\ninput = \"phase\"\npath = \"split.csv\"\n";
    let fused = "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"scene.y4m\"\n\n\
                 [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\nreference_interval_s = 0.031\nreference_overlap = 7\n\n\
                 [[stage]]\nid = \"out\"\nkind = \"csv\"\ninput = \"phase\"\npath = \"fused.csv\"\n";
    std::fs::write(dir.path().join("split.toml"), split).unwrap();
    std::fs::write(dir.path().join("fused.toml"), fused).unwrap();
    for pyramid in ["csp", "riesz"] {
        let kind = format!("=\"{pyramid}\"");
        let o = run_in(
            dir.path(),
            &[
                "run",
                "fused.toml",
                "--quiet",
                "--set",
                &format!("phase.pyramid{kind}"),
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let want = std::fs::read(dir.path().join("fused.csv")).unwrap();
        assert!(want.len() > 10_000, "{pyramid}: fused output too short");
        for (pt, ft) in [("1", "1"), ("3", "2"), ("2", "3")] {
            let o = run_in(
                dir.path(),
                &[
                    "run",
                    "split.toml",
                    "--quiet",
                    "--set",
                    &format!("pyr.pyramid{kind}"),
                    "--set",
                    &format!("pyr.threads={pt}"),
                    "--set",
                    &format!("phase.threads={ft}"),
                ],
            );
            assert_eq!(code(&o), 0, "{}", stderr(&o));
            let got = std::fs::read(dir.path().join("split.csv")).unwrap();
            assert!(
                got == want,
                "{pyramid}: pyramid -> phase (threads {pt}/{ft}) differs from phase"
            );
        }
    }
}

/// A pyramid edge into a stage that takes frames is refused at validation,
/// naming the stage and both types.
#[test]
fn a_pyramid_edge_into_a_frame_stage_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let text = "[[stage]]\nid = \"src\"\nkind = \"pattern\"\n\n\
                [[stage]]\nid = \"pyr\"\nkind = \"pyramid\"\ninput = \"src\"\n\n\
                [[stage]]\nid = \"m\"\nkind = \"mean\"\ninput = \"pyr\"\n";
    std::fs::write(dir.path().join("bad.toml"), text).unwrap();
    let o = run_in(dir.path(), &["run", "bad.toml"]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("stage `m`") && e.contains("gives pyramid") && e.contains("takes frames"),
        "{e}"
    );
}
