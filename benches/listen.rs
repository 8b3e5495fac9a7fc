//! The visual microphone's speed, latency and memory (issue 3):
//!
//! 1. Throughput of `vibroscope listen` on a 2200 fps 256x256 8-bit Y4M
//!    (1 s, rendered here by the engine), for the Riesz and the 4-scale CSP
//!    pyramids, best of 3 runs, in Mpix/s, against a baseline measured in
//!    the same run: the same file replayed through the same file source
//!    into a null sink (decoding only). Real time for that camera is
//!    2200 x 65,536 = 144 Mpix/s. Targets: Riesz >= 150, CSP >= 60.
//!    A peer implementation can be timed on the same file: set
//!    `VIBROSCOPE_PEER_CMD` to a shell command with `{video}` and `{out}`
//!    placeholders (it is run once, and its Mpix/s and our ratio printed).
//! 2. Live latency: the same file played in real time (file source with
//!    `realtime = true`, a live source) through phase -> align -> high-pass
//!    -> WAV + speaker (virtual `null` device); capture-to-sink p50/p99 and
//!    frames dropped, from `--stats`. Target: p99 < 50 ms when keeping up.
//! 3. Memory: peak RSS of `listen` reading 10 s and 60 s of 64x64 input
//!    from a pipe (so the page cache does not count).
//!
//! Set `VIBROSCOPE_BENCH_BEFORE` to another build of the binary (say, the
//! previous commit's) to time it on the same file in the same run,
//! interleaved with this one, and print the ratio.
//!
//!     cargo bench --bench listen

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

#[path = "util/timing.rs"]
#[allow(dead_code)] // `timed` and `best_of` serve the other benchmarks
mod timing;
use timing::{run_exe, EXE};

const PIX: f64 = 256.0 * 256.0;
const FRAMES: f64 = 2200.0;

fn vibroscope(dir: &Path, args: &[&str]) -> (f64, String) {
    run_exe(EXE, dir, args)
}

fn best_of(n: usize, mut f: impl FnMut() -> f64) -> f64 {
    (0..n).map(|_| f()).fold(f64::INFINITY, f64::min)
}

fn field(stats: &str, prefix: &str, key: &str) -> Option<f64> {
    let line = stats.lines().find(|l| l.starts_with(prefix))?;
    line.split(key)
        .nth(1)?
        .split_whitespace()
        .next()?
        .trim_end_matches(',')
        .parse()
        .ok()
}

fn dropped(stats: &str, stage: &str) -> Option<u64> {
    let line = stats
        .lines()
        .find(|l| l.split_whitespace().next() == Some(stage))?;
    line.split_whitespace().nth(4)?.parse().ok()
}

fn rss_of_stream(dir: &Path, seconds: u32) -> f64 {
    let mut producer = Command::new(EXE)
        .current_dir(dir)
        .args([
            "run",
            "render",
            "--quiet",
            "--set",
            "cam.width=64",
            "--set",
            "cam.height=64",
            "--set",
            &format!("cam.duration_s={seconds}"),
            "--set",
            &format!(
                "cam.signal={{type=\"chirp\",f0_hz=100.0,f1_hz=1000.0,duration_s={seconds}.0}}"
            ),
            "--set",
            "out.path=\"-\"",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn producer");
    let o = Command::new(EXE)
        .current_dir(dir)
        .args(["listen", "-", "-o", "stream.wav", "--stats"])
        .stdin(producer.stdout.take().expect("pipe"))
        .output()
        .expect("spawn listen");
    let _ = producer.wait();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    err.split("peak RSS ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .expect("--stats prints peak RSS")
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("vibroscope-listen-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    eprintln!("rendering 1 s of 2200 fps 256x256 video ...");
    vibroscope(
        &dir,
        &[
            "run",
            "render",
            "--quiet",
            "--set",
            "cam.width=256",
            "--set",
            "cam.height=256",
            "--set",
            "cam.duration_s=1",
            "--set",
            "cam.signal={type=\"chirp\",f0_hz=100.0,f1_hz=1000.0,duration_s=1.0}",
            "--set",
            "out.path=\"scene.y4m\"",
        ],
    );
    let mpix = |secs: f64| FRAMES * PIX / 1e6 / secs;
    let base = best_of(3, || {
        vibroscope(
            &dir,
            &["run", "passthrough", "--replay", "scene.y4m", "--quiet"],
        )
        .0
    });
    println!(
        "baseline: decode only (file source -> null): {:.0} Mpix/s",
        mpix(base)
    );
    let before = std::env::var("VIBROSCOPE_BENCH_BEFORE").ok();
    let mut ours = Vec::new();
    for (pyr, target) in [("riesz", 150.0), ("csp", 60.0)] {
        let args = ["listen", "scene.y4m", "-o", "out.wav", "--pyramid", pyr];
        let (mut secs, mut secs_before) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..3 {
            secs = secs.min(vibroscope(&dir, &args).0);
            if let Some(b) = &before {
                secs_before = secs_before.min(run_exe(b, &dir, &args).0);
            }
        }
        if before.is_some() {
            println!(
                "listen --pyramid {pyr:5} with VIBROSCOPE_BENCH_BEFORE: {:6.1} Mpix/s; this build / before: {:.3}",
                mpix(secs_before),
                mpix(secs) / mpix(secs_before)
            );
        }
        let m = mpix(secs);
        ours.push((pyr, m));
        println!(
            "listen --pyramid {pyr:5}: {m:6.1} Mpix/s ({:.2}x real time for 2200 fps 256x256; target {target} Mpix/s: {}); {:.2} of the decode baseline",
            m / 144.2,
            if m >= target { "met" } else { "NOT met" },
            m / mpix(base)
        );
    }
    match std::env::var("VIBROSCOPE_PEER_CMD") {
        Ok(cmd) => {
            let video = dir.join("scene.y4m");
            let out = dir.join("peer.wav");
            let cmd = cmd
                .replace("{video}", &video.display().to_string())
                .replace("{out}", &out.display().to_string());
            let t = Instant::now();
            let st = Command::new("sh").args(["-c", &cmd]).status();
            let secs = t.elapsed().as_secs_f64();
            match st {
                Ok(s) if s.success() => {
                    println!("peer `{cmd}`: {:.1} Mpix/s", mpix(secs));
                    for (pyr, m) in &ours {
                        println!("  ratio ours ({pyr}) / peer: {:.1}", m / mpix(secs));
                    }
                }
                other => println!("peer `{cmd}` failed: {other:?}"),
            }
        }
        Err(_) => println!(
            "peer: not run (set VIBROSCOPE_PEER_CMD='... {{video}} {{out}}' to time one on the same file)"
        ),
    }
    for pyr in ["riesz", "csp"] {
        let toml = format!(
            "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"scene.y4m\"\nrealtime = true\n\n\
             [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\npyramid = \"{pyr}\"\nblock = 16\n\n\
             [[stage]]\nid = \"align\"\nkind = \"align\"\ninput = \"phase\"\nwarmup = 64\n\n\
             [[stage]]\nid = \"highpass\"\nkind = \"highpass\"\ninput = \"align\"\n\n\
             [[stage]]\nid = \"out\"\nkind = \"wav\"\ninput = \"highpass\"\npath = \"live.wav\"\n\n\
             [[stage]]\nid = \"speaker\"\nkind = \"speaker\"\ninput = \"highpass\"\ndevice = \"null\"\n"
        );
        let p = dir.join(format!("live-{pyr}.toml"));
        std::fs::write(&p, toml).expect("write pipeline");
        let args = ["run", p.to_str().unwrap(), "--stats", "--quiet"];
        let pre = "latency capture -> speaker:";
        let runs = std::iter::once(("", EXE)).chain(before.as_deref().map(|b| (" (before)", b)));
        for (label, exe) in runs {
            let (_, stats) = run_exe(exe, &dir, &args);
            println!(
                "live {pyr:5}{label} (2200 fps 256x256 in real time): capture -> speaker p50 {:.1} ms, p99 {:.1} ms (target p99 < 50 ms); frames dropped {}",
                field(&stats, pre, "p50 ").unwrap_or(f64::NAN),
                field(&stats, pre, "p99 ").unwrap_or(f64::NAN),
                dropped(&stats, "phase").map_or("?".into(), |d| d.to_string()),
            );
        }
    }
    let (r10, r60) = (rss_of_stream(&dir, 10), rss_of_stream(&dir, 60));
    println!(
        "peak RSS of listen on 10 s / 60 s of 2200 fps 64x64 from a pipe: {r10:.1} / {r60:.1} MiB"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
