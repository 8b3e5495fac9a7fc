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
