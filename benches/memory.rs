//! Memory stays flat with stream length: peak RSS of the process that
//! replays 1,000 and 100,000 frames of 256x256 8-bit Y4M (from a pipe, so
//! the file system cache does not count), through source -> 3 pass-through
//! stages -> null sink. Also prints replay throughput in Mpix/s against a
//! same-run baseline (`cat` of the same stream into /dev/null).
//! Target (issue 2): RSS(100,000) - RSS(1,000) <= 64 MiB.
//!
//!     cargo bench --bench memory

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Instant;

const EXE: &str = env!("CARGO_BIN_EXE_vibroscope");

fn replay(frames: u64, dir: &std::path::Path) -> (f64, f64) {
    let gen = dir.join("gen.toml");
    let mut f = std::fs::File::create(&gen).expect("temp file");
    write!(
        f,
        "[[stage]]\nid = \"src\"\nkind = \"pattern\"\nwidth = 256\nheight = 256\nframes = {frames}\n\n[[stage]]\nid = \"out\"\nkind = \"y4m\"\ninput = \"src\"\npath = \"-\"\n"
    )
    .expect("write");
    let mut producer = Command::new(EXE)
        .args(["run", gen.to_str().unwrap_or_default(), "--quiet"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn producer");
    let t = Instant::now();
    let consumer = Command::new(EXE)
        .args(["run", "passthrough", "--replay", "-", "--stats", "--quiet"])
        .stdin(producer.stdout.take().expect("pipe"))
        .output()
        .expect("spawn consumer");
    let secs = t.elapsed().as_secs_f64();
    let _ = producer.wait();
    let err = String::from_utf8_lossy(&consumer.stderr);
    assert!(consumer.status.success(), "{err}");
    let rss = err
        .split("peak RSS ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse::<f64>().ok())
        .expect("--stats prints peak RSS");
    (rss, frames as f64 * 65536.0 / 1e6 / secs)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("vibroscope-membench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let (rss_small, _) = replay(1_000, &dir);
    let (rss_large, mpix) = replay(100_000, &dir);
    // Baseline: the same pipe drained by `cat`.
    let gen = dir.join("gen.toml");
    let mut producer = Command::new(EXE)
        .args(["run", gen.to_str().unwrap_or_default(), "--quiet"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn");
    let t = Instant::now();
    let st = Command::new("cat")
        .stdin(producer.stdout.take().expect("pipe"))
        .stdout(Stdio::null())
        .status()
        .expect("cat");
    let base = 100_000.0 * 65536.0 / 1e6 / t.elapsed().as_secs_f64();
    let _ = producer.wait();
    assert!(st.success());
    let _ = std::fs::remove_dir_all(&dir);
    println!("peak RSS replaying   1,000 frames: {rss_small:.1} MiB");
    println!("peak RSS replaying 100,000 frames: {rss_large:.1} MiB");
    println!(
        "difference: {:.1} MiB (target <= 64 MiB)",
        rss_large - rss_small
    );
    println!("replay throughput (100,000 frames, pipe -> 3 pass-through -> null): {mpix:.0} Mpix/s = {:.0} frames/s", mpix * 1e6 / 65536.0);
    println!(
        "baseline (same pipe into cat): {base:.0} Mpix/s; ratio {:.2}",
        mpix / base
    );
}
