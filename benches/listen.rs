//! The visual microphone's speed, latency and memory (issue 3):
//!
//! 1. Throughput of `vibroscope listen` on a 2200 fps 256x256 8-bit Y4M
//!    (1 s, rendered here by the engine), for the default method (per-tile
//!    gradients) and the phase method with the Riesz and the 4-scale CSP
//!    pyramids, best of 3 runs, in Mpix/s, against a baseline measured in
//!    the same run: the same file replayed through the same file source
//!    into a null sink (decoding only). Real time for that camera is
//!    2200 x 65,536 = 144 Mpix/s. Targets: gradient >= 150, Riesz >= 150,
//!    CSP >= 60.
//!    A peer implementation can be timed on the same file: set
//!    `VIBROSCOPE_PEER_CMD` to a shell command with `{video}` and `{out}`
//!    placeholders (it is run once, and its Mpix/s and our ratio printed).
//! 2. Live latency: the same file played in real time (file source with
//!    `realtime = true`, a live source) through phase -> align -> high-pass
//!    -> WAV + speaker (virtual `null` device); capture-to-sink p50/p99 and
//!    frames dropped, from `--stats`. Target: p99 < 50 ms when keeping up.
//!    Then the same pipeline run by `vibroscope studio --pipeline` with a
//!    watcher doing what the studio's page does (a WebSocket reading every
//!    update, the latest frame fetched 10 times a second): the latency and
//!    drops must not change (issue 16).
//! 3. Memory: peak RSS of `listen` reading 10 s and 60 s of 64x64 input
//!    from a pipe (so the page cache does not count).
//!
//! Set `VIBROSCOPE_BENCH_BEFORE` to another build of the binary (say, the
//! previous commit's) to time it on the same file in the same run,
//! interleaved with this one, and print the ratio.
//!
//!     cargo bench --bench listen
//!     VIBROSCOPE_BENCH_LIVE_ONLY=1 cargo bench --bench listen   # part 2 only

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

/// One HTTP GET on a fresh connection: the status and the body.
fn http_get(port: u16, token: &str, target: &str) -> std::io::Result<(u16, Vec<u8>)> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port))?;
    s.set_read_timeout(Some(std::time::Duration::from_secs(10)))?;
    write!(
        s,
        "GET {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nx-vibroscope-token: {token}\r\nConnection: close\r\n\r\n"
    )?;
    let mut out = Vec::new();
    s.read_to_end(&mut out)?;
    let split = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or(out.len());
    let head = String::from_utf8_lossy(&out[..split]).into_owned();
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    Ok((status, out.get(split + 4..).unwrap_or_default().to_vec()))
}

/// Runs `pipeline` under `vibroscope studio --pipeline` with a watcher
/// doing what the page does; returns the run's `--stats` table.
fn under_studio(dir: &Path, pipeline: &Path) -> Result<String, String> {
    use std::io::{BufRead, Read, Write};
    let mut child = Command::new(EXE)
        .current_dir(dir)
        .args([
            "studio",
            "--pipeline",
            pipeline.to_str().unwrap(),
            "--root",
            ".",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| e.to_string())?;
    let mut line = String::new();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    out.read_line(&mut line).map_err(|e| e.to_string())?;
    // http://127.0.0.1:PORT/?token=TOKEN
    let (port, token) = line
        .trim()
        .rsplit_once(':')
        .and_then(|(_, rest)| rest.split_once("/?token="))
        .and_then(|(p, t)| Some((p.parse::<u16>().ok()?, t.to_owned())))
        .ok_or_else(|| format!("no URL printed: {line:?}"))?;
    let token2 = token.clone();
    // The page's socket: every update read and dropped.
    let ws = std::thread::spawn(move || -> usize {
        let Ok(mut s) = std::net::TcpStream::connect(("127.0.0.1", port)) else {
            return 0;
        };
        let _ = write!(
            s,
            "GET /api/live/ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nx-vibroscope-token: {token2}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n"
        );
        let mut n = 0;
        let mut buf = vec![0u8; 1 << 16];
        while let Ok(k) = s.read(&mut buf) {
            if k == 0 {
                break;
            }
            n += k;
        }
        n
    });
    let t0 = Instant::now();
    let mut tick = 0u64;
    let result = loop {
        std::thread::sleep(std::time::Duration::from_millis(100));
        let _ = http_get(port, &token, "/api/live/frame");
        // The end of the run, looked for twice a second.
        tick += 1;
        if !tick.is_multiple_of(5) {
            continue;
        }
        let Ok((200, body)) = http_get(port, &token, "/api/live") else {
            continue;
        };
        let u: serde_json::Value = serde_json::from_slice(&body).map_err(|e| e.to_string())?;
        match u["state"].as_str() {
            Some("finished") => break Ok(u["report"].as_str().unwrap_or("").to_owned()),
            Some("failed") => break Err(u["message"].to_string()),
            _ if t0.elapsed().as_secs() > 120 => break Err("no end after 120 s".into()),
            _ => {}
        }
    };
    let _ = child.kill();
    let _ = child.wait();
    let bytes = ws.join().unwrap_or(0);
    if bytes == 0 {
        return Err("the WebSocket carried nothing".into());
    }
    result
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
    // VIBROSCOPE_BENCH_LIVE_ONLY=1: only part 2 (the live latency).
    let live_only = std::env::var_os("VIBROSCOPE_BENCH_LIVE_ONLY").is_some();
    let before = std::env::var("VIBROSCOPE_BENCH_BEFORE").ok();
    if !live_only {
        throughput(&dir, before.as_deref());
    }
    live_latency(&dir, before.as_deref(), live_only);
}

/// Part 1: `listen` throughput against the decode baseline (and a peer).
fn throughput(dir: &Path, before: Option<&str>) {
    let mpix = |secs: f64| FRAMES * PIX / 1e6 / secs;
    let base = best_of(3, || {
        vibroscope(
            dir,
            &["run", "passthrough", "--replay", "scene.y4m", "--quiet"],
        )
        .0
    });
    println!(
        "baseline: decode only (file source -> null): {:.0} Mpix/s",
        mpix(base)
    );
    let mut ours = Vec::new();
    for (label, extra, target) in [
        ("gradient", &["--method", "gradient"][..], 150.0),
        (
            "phase riesz",
            &["--method", "phase", "--pyramid", "riesz"][..],
            150.0,
        ),
        (
            "phase csp",
            &["--method", "phase", "--pyramid", "csp"][..],
            60.0,
        ),
    ] {
        let mut args = vec!["listen", "scene.y4m", "-o", "out.wav"];
        args.extend_from_slice(extra);
        let (mut secs, mut secs_before) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..3 {
            secs = secs.min(vibroscope(dir, &args).0);
            if let Some(b) = before {
                secs_before = secs_before.min(run_exe(b, dir, &args).0);
            }
        }
        if before.is_some() {
            println!(
                "listen --method {label:11} with VIBROSCOPE_BENCH_BEFORE: {:6.1} Mpix/s; this build / before: {:.3}",
                mpix(secs_before),
                mpix(secs) / mpix(secs_before)
            );
        }
        let m = mpix(secs);
        ours.push((label, m));
        println!(
            "listen --method {label:11}: {m:6.1} Mpix/s ({:.2}x real time for 2200 fps 256x256; target {target} Mpix/s: {}); {:.2} of the decode baseline",
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
                    for (label, m) in &ours {
                        println!("  ratio ours ({label}) / peer: {:.1}", m / mpix(secs));
                    }
                }
                other => println!("peer `{cmd}` failed: {other:?}"),
            }
        }
        Err(_) => println!(
            "peer: not run (set VIBROSCOPE_PEER_CMD='... {{video}} {{out}}' to time one on the same file)"
        ),
    }
}

/// Part 2: live latency, plain and under the studio.
fn live_latency(dir: &Path, before: Option<&str>, live_only: bool) {
    // A scene this machine keeps up with (2200 fps of 128x128, 3 s): there
    // the studio's own cost shows, not the saturation of both cores.
    vibroscope(
        dir,
        &[
            "run",
            "render",
            "--quiet",
            "--set",
            "cam.width=128",
            "--set",
            "cam.height=128",
            "--set",
            "cam.duration_s=3",
            "--set",
            "cam.signal={type=\"chirp\",f0_hz=100.0,f1_hz=1000.0,duration_s=3.0}",
            "--set",
            "out.path=\"small.y4m\"",
        ],
    );
    for (scene, size) in [("scene.y4m", "256x256"), ("small.y4m", "128x128")] {
        for pyr in ["riesz", "csp"] {
            live_pair(dir, before, scene, size, pyr);
        }
    }
    if !live_only {
        let (r10, r60) = (rss_of_stream(dir, 10), rss_of_stream(dir, 60));
        println!(
            "peak RSS of listen on 10 s / 60 s of 2200 fps 64x64 from a pipe: {r10:.1} / {r60:.1} MiB"
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// The live microphone on `scene` in real time, plain then under the
/// studio, 3 interleaved pairs.
fn live_pair(dir: &Path, before: Option<&str>, scene: &str, size: &str, pyr: &str) {
    {
        let toml = format!(
            "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"{scene}\"\nrealtime = true\n\n\
             [[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\npyramid = \"{pyr}\"\nblock = 16\n\n\
             [[stage]]\nid = \"align\"\nkind = \"align\"\ninput = \"phase\"\nwarmup = 64\n\n\
             [[stage]]\nid = \"highpass\"\nkind = \"highpass\"\ninput = \"align\"\n\n\
             [[stage]]\nid = \"out\"\nkind = \"wav\"\ninput = \"highpass\"\npath = \"live.wav\"\n\n\
             [[stage]]\nid = \"speaker\"\nkind = \"speaker\"\ninput = \"highpass\"\ndevice = \"null\"\n"
        );
        let p = dir.join(format!("live-{pyr}-{size}.toml"));
        std::fs::write(&p, toml).expect("write pipeline");
        let args = ["run", p.to_str().unwrap(), "--stats", "--quiet"];
        let pre = "latency capture -> speaker:";
        let runs = std::iter::once(("", EXE)).chain(before.map(|b| (" (before)", b)));
        for (label, exe) in runs.filter(|_| scene == "scene.y4m") {
            let (_, stats) = run_exe(exe, dir, &args);
            println!(
                "live {pyr:5}{label} (2200 fps 256x256 in real time): capture -> speaker p50 {:.1} ms, p99 {:.1} ms (target p99 < 50 ms); frames dropped {}",
                field(&stats, pre, "p50 ").unwrap_or(f64::NAN),
                field(&stats, pre, "p99 ").unwrap_or(f64::NAN),
                dropped(&stats, "phase").map_or("?".into(), |d| d.to_string()),
            );
        }
        // The same pipeline run by the studio, watched as the page does
        // (issue 16): a WebSocket taking every update, the latest frame
        // fetched 10 times a second. Interleaved with plain runs, 3 pairs
        // (a 1 s run's figures vary by several ms), medians printed.
        let figures = |stats: &str| {
            [
                field(stats, pre, "p50 ").unwrap_or(f64::NAN),
                field(stats, pre, "p99 ").unwrap_or(f64::NAN),
                dropped(stats, "phase").map_or(f64::NAN, |d| d as f64),
            ]
        };
        let (mut plain, mut watched) = (Vec::new(), Vec::new());
        for _ in 0..3 {
            plain.push(figures(&run_exe(EXE, dir, &args).1));
            match under_studio(dir, &p) {
                Ok(stats) => watched.push(figures(&stats)),
                Err(e) => {
                    println!("live {pyr:5} {size} with the studio attached: not measured ({e})");
                    break;
                }
            }
        }
        let median = |v: &[[f64; 3]], k: usize| {
            let mut x: Vec<f64> = v.iter().map(|f| f[k]).collect();
            x.sort_by(f64::total_cmp);
            x.get(x.len() / 2).copied().unwrap_or(f64::NAN)
        };
        for (label, v) in [("plain", &plain), ("with the studio attached", &watched)] {
            if v.is_empty() {
                continue;
            }
            println!(
                "live {pyr:5} {size} {label}, median of {}: capture -> speaker p50 {:.1} ms, p99 {:.1} ms; frames dropped {} (each run: {})",
                v.len(),
                median(v, 0),
                median(v, 1),
                median(v, 2),
                v.iter()
                    .map(|f| format!("{:.1}/{:.1} ms {} dropped", f[0], f[1], f[2]))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
}
