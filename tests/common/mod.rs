//! Shared helpers for the integration tests.
#![allow(dead_code)]
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vibroscope"))
}

/// Runs the binary in `dir` with `args`.
pub fn run_in(dir: &Path, args: &[&str]) -> Output {
    bin()
        .current_dir(dir)
        .args(args)
        .output()
        .expect("spawn vibroscope")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn code(o: &Output) -> i32 {
    o.status.code().unwrap_or(-1)
}

/// The package's directory, read when the test runs (cargo sets
/// `CARGO_MANIFEST_DIR` and runs tests there), not compiled in with `env!`:
/// a build at another path (a fresh clone elsewhere) stays reusable.
pub fn manifest_dir() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR").map_or_else(
        || std::env::current_dir().unwrap_or_default(),
        std::path::PathBuf::from,
    )
}

/// `../shared/data` next to the checkout, or None (with a printed reason).
pub fn shared_data(file: &str) -> Option<PathBuf> {
    let p = manifest_dir().join("../shared/data").join(file);
    if p.exists() {
        Some(p)
    } else {
        eprintln!(
            "skipping: {} not found (real recordings live in ../shared/data)",
            p.display()
        );
        None
    }
}

/// Reads a mono f32 WAV; panics with the path on failure (tests only).
pub fn read_wav(p: &Path) -> (u32, Vec<f32>) {
    let mut r = hound::WavReader::open(p)
        .unwrap_or_else(|e| panic!("{}: not a valid WAV: {e}", p.display()));
    let spec = r.spec();
    // 16-bit PCM (listen's default) scaled to [-1, 1); float as stored.
    let s = match spec.sample_format {
        hound::SampleFormat::Float => r.samples::<f32>().collect::<Result<Vec<_>, _>>(),
        hound::SampleFormat::Int => {
            let scale = 1.0 / (1u64 << (spec.bits_per_sample - 1)) as f32;
            r.samples::<i32>()
                .map(|v| v.map(|v| v as f32 * scale))
                .collect::<Result<Vec<_>, _>>()
        }
    }
    .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    (spec.sample_rate, s)
}

/// Writes a mono 32-bit float WAV.
pub fn write_wav_f32(p: &Path, rate: u32, s: &[f32]) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(p, spec).unwrap();
    for &v in s {
        w.write_sample(v).unwrap();
    }
    w.finalize().unwrap();
}

/// The shipped `demo` pipeline's camera made live: 64x64 at 500 fps in
/// real time, for 60 s.
pub const LIVE_DEMO: [&str; 10] = [
    "--set",
    "cam.realtime=true",
    "--set",
    "cam.duration_s=60",
    "--set",
    "cam.width=64",
    "--set",
    "cam.height=64",
    "--set",
    "cam.fps=500",
];

/// Runs the shipped `demo` pipeline live (a 64x64, 500 fps realtime
/// synthetic camera, 60 s) in `dir`, sends `kill -SIG` after 1.5 s (past
/// the WAV header's first periodic rewrite) and waits for it.
pub fn interrupt_live_demo(dir: &Path, sig: &str) -> Output {
    let child = bin()
        .current_dir(dir)
        .args(["run", "demo"])
        .args(LIVE_DEMO)
        .arg("--quiet")
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let st = Command::new("kill")
        .args([&format!("-{sig}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    child.wait_with_output().unwrap()
}

/// Renders the synthetic scene to `path` as Y4M through the engine itself.
pub fn render_y4m(dir: &Path, path: &str, extra: &[&str]) {
    let mut args = vec!["run", "render", "--quiet", "--set"];
    let out = format!("out.path={path}");
    args.push(&out);
    args.extend_from_slice(extra);
    let o = run_in(dir, &args);
    assert_eq!(code(&o), 0, "render failed: {}", stderr(&o));
}

/// The guitar clip, when it and ffmpeg are both present (else None, with a reason).
pub fn guitar_with_ffmpeg() -> Option<PathBuf> {
    let p = shared_data("guitar.mp4")?;
    if Command::new("ffmpeg").arg("-version").output().is_err() {
        eprintln!("skipping: ffmpeg is not installed");
        return None;
    }
    Some(p)
}

/// Ground truth: the displacement (px) the forward model gave the object in
/// the first `n` frames of synthetic stage `stage_id` of `decl`.
pub fn true_motion(decl: &vibroscope_engine::PipelineDecl, stage_id: &str, n: usize) -> Vec<f64> {
    use vibroscope_engine::stages::sources::synthetic::SyntheticParams;
    let st = decl
        .stages
        .iter()
        .find(|s| s.id == stage_id)
        .expect("synthetic stage");
    let p: SyntheticParams = vibroscope_engine::Params {
        file: &decl.file,
        stage: st,
    }
    .parse()
    .expect("valid synthetic parameters");
    let scene = p.scene().expect("scene");
    (0..n)
        .map(|k| scene.displacement_px(k as f64 / p.fps))
        .collect()
}

/// Power spectrum (Hann window, zero-padded to `n`) and bin spacing.
pub fn power_spectrum(x: &[f32], rate: f64, n: usize) -> (Vec<f64>, f64) {
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / x.len() as f64;
    let mut buf: Vec<rustfft::num_complex::Complex<f64>> = (0..n)
        .map(|i| {
            if i < x.len() {
                let w = 0.5
                    - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (x.len() - 1) as f64).cos();
                rustfft::num_complex::Complex::new((x[i] as f64 - mean) * w, 0.0)
            } else {
                rustfft::num_complex::Complex::new(0.0, 0.0)
            }
        })
        .collect();
    rustfft::FftPlanner::new()
        .plan_fft_forward(n)
        .process(&mut buf);
    (
        buf[..n / 2].iter().map(|c| c.norm_sqr()).collect(),
        rate / n as f64,
    )
}

/// Writes an 8-bit gray PGM.
pub fn write_pgm(path: &Path, w: usize, h: usize, px: impl Fn(usize, usize) -> u8) {
    let mut b = format!("P5\n{w} {h}\n255\n").into_bytes();
    for y in 0..h {
        for x in 0..w {
            b.push(px(x, y));
        }
    }
    std::fs::write(path, b).unwrap();
}

/// A smooth `n` x `n` picture (PGM): stripes at two angles and a ramp, a
/// texture whose gradients are known and unlike the simulator's random one.
pub fn smooth_picture(path: &Path, n: usize) {
    let last = (n - 1) as f64;
    write_pgm(path, n, n, |x, y| {
        let (x, y) = (x as f64, y as f64);
        let v = 128.0
            + 50.0 * (0.45 * x + 0.2 * y).sin()
            + 30.0 * (0.1 * x - 0.5 * y).cos()
            + 20.0 * (y / last - 0.5);
        v.round() as u8
    });
}
