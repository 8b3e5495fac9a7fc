//! Bounded work per client (issue 54, item 4), alone in its test binary so
//! that its memory and latency figures are the studio's own: 50 analyses
//! asked at once each get an answer or a 429 while `/api/session` keeps
//! answering within a second and memory stays bounded; an analysis whose
//! client went away stops long before it would have ended.
//!
//!     cargo test --release -p vibroscope-studio --test load -- --nocapture

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::*;
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};
use vibroscope_studio::{limits, Studio, StudioOptions};

/// The tests of this binary one at a time: each measures the server alone.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The bound on the test process's resident memory while 50 analyses are
/// asked at once (the studio's queues admit ten: two running).
const RSS_BOUND_MB: f64 = 1024.0;

/// A `w` x `h` mono Y4M of `frames` frames at 1000 Hz: a noise texture
/// shifted by one pixel every other frame (something to measure).
fn moving_noise(p: &Path, w: usize, h: usize, frames: usize) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(p).unwrap());
    writeln!(f, "YUV4MPEG2 W{w} H{h} F1000:1 Ip A1:1 Cmono").unwrap();
    let (tw, mut state) = (w + 2, 0x2545_f491_u32);
    let tex: Vec<u8> = (0..tw * h)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 24) as u8
        })
        .collect();
    let mut frame = vec![0u8; w * h];
    for i in 0..frames {
        let dx = (i / 2) % 2;
        for y in 0..h {
            frame[y * w..(y + 1) * w].copy_from_slice(&tex[y * tw + dx..y * tw + dx + w]);
        }
        f.write_all(b"FRAME\n").unwrap();
        f.write_all(&frame).unwrap();
    }
    f.flush().unwrap();
}

/// The process's resident memory now, MB (Linux).
fn rss_mb() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

fn session(s: &Studio) -> serde_json::Value {
    let (st, b) = get(s, "/api/session");
    assert_eq!(st, 200, "{b}");
    serde_json::from_str(&b).unwrap()
}

#[test]
fn fifty_analyses_at_once_each_get_an_answer_or_429() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let d = tempfile::tempdir().unwrap();
    moving_noise(&d.path().join("v.y4m"), 128, 128, 2000);
    let s = Arc::new(
        Studio::start(&StudioOptions {
            root: Some(d.path().to_path_buf()),
            ..StudioOptions::default()
        })
        .unwrap(),
    );
    let rss_before = rss_mb();
    let stop = Arc::new(AtomicBool::new(false));
    // `/api/session` every 50 ms throughout: its slowest answer, and the
    // largest resident memory seen.
    let poller = {
        let (s, stop) = (s.clone(), stop.clone());
        std::thread::spawn(move || {
            let (mut slowest, mut rss, mut polls, mut most_waiting) = (0.0f64, 0.0f64, 0, 0);
            while !stop.load(Ordering::SeqCst) {
                let t0 = Instant::now();
                let v = session(&s);
                slowest = slowest.max(t0.elapsed().as_secs_f64());
                most_waiting = most_waiting.max(v["analyses"]["waiting"].as_u64().unwrap());
                rss = rss.max(rss_mb());
                polls += 1;
                std::thread::sleep(Duration::from_millis(50));
            }
            (slowest, rss, polls, most_waiting)
        })
    };
    let n = 50;
    let start = Arc::new(Barrier::new(n));
    let t0 = Instant::now();
    let clients: Vec<_> = (0..n)
        .map(|i| {
            let (s, start) = (s.clone(), start.clone());
            std::thread::spawn(move || {
                // Each its own region: no answer comes from the cache.
                let (x, y) = (i % 10 * 8, i / 10 * 8);
                let body = format!("{{\"video\":\"v.y4m\",\"roi\":[{x},{y},48,48]}}");
                start.wait();
                let (st, b) = post(&s, "/api/motion", &body);
                (st, b, t0.elapsed().as_secs_f64())
            })
        })
        .collect();
    let answers: Vec<(u16, String, f64)> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    stop.store(true, Ordering::SeqCst);
    let (slowest, rss, polls, most_waiting) = poller.join().unwrap();
    let ok = answers.iter().filter(|a| a.0 == 200).count();
    let busy = answers.iter().filter(|a| a.0 == 429).count();
    let last = answers.iter().map(|a| a.2).fold(0.0, f64::max);
    println!(
        "50 analyses at once: {ok} answered, {busy} refused with 429, all within {last:.2} s; \
         /api/session polled {polls} times, slowest {:.0} ms; at most {most_waiting} waiting; \
         resident memory {rss_before:.0} MB before, at most {rss:.0} MB (bound {RSS_BOUND_MB} MB)",
        slowest * 1e3
    );
    for (st, b, _) in &answers {
        assert!(*st == 200 || *st == 429, "{st}: {b}");
        if *st == 429 {
            assert!(error_of(b).contains("too many analyses"), "{b}");
        }
    }
    let admitted = limits::ANALYSES_RUNNING + limits::ANALYSES_WAITING;
    assert!(
        ok >= admitted,
        "{ok} answered: the first {admitted} are admitted"
    );
    assert!(busy > 0, "50 at once: some must be refused");
    assert!(most_waiting <= limits::ANALYSES_WAITING as u64);
    assert!(polls >= 3, "the poller ran throughout");
    assert!(slowest < 1.0, "/api/session took {slowest:.2} s");
    assert!(rss < RSS_BOUND_MB, "{rss:.0} MB");
    // Once they are done, nothing runs or waits.
    let v = session(&s);
    assert_eq!(
        v["analyses"],
        serde_json::json!({"running": 0, "waiting": 0})
    );
}

/// An analysis asked and then abandoned (the connection closed): its run
/// is stopped, so the studio is idle again long before the analysis would
/// have ended (measured: the same request run to its end on a recording a
/// tenth as long, times ten).
#[test]
fn an_analysis_whose_client_went_away_stops() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let d = tempfile::tempdir().unwrap();
    let (w, h, long) = (256, 256, 6000);
    moving_noise(&d.path().join("short.y4m"), w, h, long / 10);
    moving_noise(&d.path().join("long.y4m"), w, h, long);
    let s = Studio::start(&StudioOptions {
        root: Some(d.path().to_path_buf()),
        ..StudioOptions::default()
    })
    .unwrap();
    let route = "/api/mode";
    let body = |v: &str| format!("{{\"video\":\"{v}\",\"freq_hz\":250}}");
    let t0 = Instant::now();
    let (st, b) = post(&s, route, &body("short.y4m"));
    assert_eq!(st, 200, "{b}");
    let whole = t0.elapsed().as_secs_f64() * 10.0;
    // The long one, abandoned once it runs.
    let mut c = std::net::TcpStream::connect(s.addr).unwrap();
    let b = body("long.y4m");
    write!(
        c,
        "POST {route} HTTP/1.1\r\nHost: 127.0.0.1\r\n{}Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{b}",
        auth(&s),
        b.len()
    )
    .unwrap();
    let t0 = Instant::now();
    while session(&s)["analyses"]["running"] != 1 {
        assert!(t0.elapsed() < Duration::from_secs(10), "it never ran");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    drop(c);
    let gone = Instant::now();
    while session(&s)["analyses"]["running"] != 0 {
        assert!(
            gone.elapsed().as_secs_f64() < whole / 3.0,
            "still running {:.1} s after its client went away (the whole analysis takes about {whole:.1} s)",
            gone.elapsed().as_secs_f64()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let stopped = gone.elapsed().as_secs_f64();
    println!(
        "an abandoned {w}x{h}x{long} {route}: stopped {:.2} s after its client went away; run whole it takes about {whole:.1} s",
        stopped
    );
}
