//! Timing helpers shared by the benchmarks that time whole commands.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

pub const EXE: &str = env!("CARGO_BIN_EXE_vibroscope");

/// Runs `vibroscope ARGS` in `dir`; its wall time (s), process start included.
pub fn timed(dir: &Path, args: &[&str]) -> f64 {
    run_exe(EXE, dir, args).0
}

/// Runs the binary `exe` (this build's, or another for a side-by-side run)
/// with `args` in `dir`: its wall time (s, process start included) and
/// what it printed on stderr; panics when it fails.
pub fn run_exe(exe: &str, dir: &Path, args: &[&str]) -> (f64, String) {
    let t = Instant::now();
    let o = Command::new(exe)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("spawn vibroscope");
    let secs = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "vibroscope {args:?} failed: {err}");
    (secs, err)
}

/// The least of `n` timings.
pub fn best_of(n: usize, mut f: impl FnMut() -> f64) -> f64 {
    (0..n).map(|_| f()).fold(f64::INFINITY, f64::min)
}

/// Renders `scene.y4m` in `dir`: the magnifier benches' scene, `w x h`,
/// `frames` frames at 500 fps of a texture moved by tones at 40 and 150 Hz
/// (`vibroscope run render`).
pub fn render_tones_scene(dir: &Path, (w, h): (usize, usize), frames: usize) {
    timed(
        dir,
        &[
            "run",
            "render",
            "--quiet",
            "--set",
            "cam.fps=500",
            "--set",
            &format!("cam.frames={frames}"),
            "--set",
            &format!("cam.width={w}"),
            "--set",
            &format!("cam.height={h}"),
            "--set",
            "cam.signal={type=\"tones\",freqs_hz=[40.0,150.0]}",
            "--set",
            "out.path=scene.y4m",
        ],
    );
}

/// `vibroscope magnify` on [`render_tones_scene`]'s scene as the magnifier
/// benches run it: the 35-45 Hz band (the 40 Hz tone) times 10.
pub fn magnify_args<'a>(pyramid: &'a str, out: &'a str) -> [&'a str; 10] {
    [
        "magnify",
        "scene.y4m",
        "--band",
        "35,45",
        "--factor",
        "10",
        "--pyramid",
        pyramid,
        "-o",
        out,
    ]
}
