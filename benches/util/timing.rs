//! Timing helpers shared by the benchmarks that time whole commands.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

pub const EXE: &str = env!("CARGO_BIN_EXE_vibroscope");

/// Runs `vibroscope ARGS` in `dir`; its wall time (s), process start included.
pub fn timed(dir: &Path, args: &[&str]) -> f64 {
    let t = Instant::now();
    let o = Command::new(EXE)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("spawn vibroscope");
    let secs = t.elapsed().as_secs_f64();
    assert!(
        o.status.success(),
        "vibroscope {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    secs
}

/// The least of `n` timings.
pub fn best_of(n: usize, mut f: impl FnMut() -> f64) -> f64 {
    (0..n).map(|_| f()).fold(f64::INFINITY, f64::min)
}
