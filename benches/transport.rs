//! Network edge against in-process edge (issue 21): items per second and
//! latency p50/p99 for spectra (2049 bins, what `spectrum` emits for a
//! 4096-sample window) and audio blocks (1024 samples) between two processes
//! on one host over zenoh (TCP loopback, the `zenoh_pub`/`zenoh_sub` path:
//! wire encoding, sequence attachment, a blocking subscriber queue), and
//! through the engine's in-process SPSC edge between two threads, measured
//! in the same run.
//!
//! Two loads: *saturated* (the sender as fast as it can: throughput, and
//! latency including queueing) and *paced* at 1000 items/s (latency of one
//! item on an idle link). Latency is wall clock from just before encoding
//! (or sending) to just after decoding (or receiving). The in-process edge
//! moves a shared pointer, not bytes: its MB/s is the same items' wire size
//! for comparison. A third figure: the peak sets a second one `vibroscope
//! monitor` takes in.
//!
//!     cargo bench --bench transport

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use vibroscope_engine::edge::{edge, Recv};
use vibroscope_engine::wire::{self, WireItem, WireRef};
use vibroscope_engine::{AudioBlock, Item, Policy, Spectrum, Taper};
use vibroscope_net::session::{self as net, zenoh, Endpoints};
use zenoh::handlers::FifoChannel;
use zenoh::sample::SampleKind;
use zenoh::Wait;

const ROLE: &str = "VIBROSCOPE_TRANSPORT_ROLE";
const KEY: &str = "vibroscope/bench/transport";

fn now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i64
}

fn item(kind: &str, t_ns: i64) -> Item {
    match kind {
        "spectrum" => Item::Spectrum(Spectrum {
            t_ns,
            f0_hz: 0.0,
            resolution_hz: 0.5,
            rate_hz: 2048.0,
            window: 4096,
            taper: Taper::Hann,
            segments: 1,
            power: (0..2049).map(|i| i as f32).collect::<Vec<_>>().into(),
        }),
        _ => Item::Audio(AudioBlock {
            t0_ns: t_ns,
            rate_hz: 2200.0,
            samples: (0..1024)
                .map(|i| i as f32 * 1e-3)
                .collect::<Vec<_>>()
                .into(),
        }),
    }
}

fn wire_ref(it: &Item) -> WireRef<'_> {
    match it {
        Item::Spectrum(s) => WireRef::Spectrum(s),
        Item::Audio(a) => WireRef::Audio(a),
        _ => unreachable!(),
    }
}

/// The publishing process: `n` items, `rate` per second (0 = flat out).
fn publisher(endpoint: &str, kind: &str, n: usize, rate: f64) {
    let s = net::open_session_plain(&Endpoints {
        connect: vec![endpoint.to_string()],
        listen: vec![],
    })
    .unwrap();
    let p = s
        .declare_publisher(KEY)
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .wait()
        .unwrap();
    while !p.matching_status().wait().unwrap().matching() {
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut buf = Vec::new();
    let start = Instant::now();
    let mut it = item(kind, 0);
    for i in 0..n {
        if rate > 0.0 {
            let due = start + Duration::from_secs_f64(i as f64 / rate);
            if let Some(d) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(d);
            }
        }
        match &mut it {
            Item::Spectrum(s) => s.t_ns = now_ns(),
            Item::Audio(a) => a.t0_ns = now_ns(),
            _ => {}
        }
        wire::encode_into(wire_ref(&it), &mut buf).unwrap();
        p.put(buf.as_slice())
            .attachment(&net::seq_attachment(i as u64)[..])
            .wait()
            .unwrap();
    }
    p.delete()
        .attachment(&net::seq_attachment(n as u64)[..])
        .wait()
        .unwrap();
    // Let the end marker leave before the session closes.
    std::thread::sleep(Duration::from_millis(200));
    let _ = s.close().wait();
}

struct Figures {
    per_s: f64,
    p50_us: f64,
    p99_us: f64,
    bytes: usize,
}

fn summarise(mut lat: Vec<i64>, elapsed: Duration, bytes: usize) -> Figures {
    lat.sort_unstable();
    let q = |p: f64| lat[((p * lat.len() as f64) as usize).min(lat.len() - 1)] as f64 * 1e-3;
    Figures {
        per_s: lat.len() as f64 / elapsed.as_secs_f64(),
        p50_us: q(0.5),
        p99_us: q(0.99),
        bytes,
    }
}

/// Receives in this process from a publisher process.
fn over_zenoh(kind: &str, n: usize, rate: f64) -> Figures {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let ep = format!("tcp/127.0.0.1:{port}");
    let s = net::open_session_plain(&Endpoints {
        connect: vec![],
        listen: vec![ep.clone()],
    })
    .unwrap();
    let sub = s
        .declare_subscriber(KEY)
        .with(FifoChannel::new(64))
        .wait()
        .unwrap();
    let mut child = Command::new(std::env::current_exe().unwrap())
        .env(ROLE, format!("{ep} {kind} {n} {rate}"))
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut lat = Vec::with_capacity(n);
    let mut first = None;
    let mut bytes = 0;
    loop {
        let sample = sub.recv().unwrap();
        if sample.kind() == SampleKind::Delete {
            break;
        }
        let b = sample.payload().to_bytes();
        bytes = b.len();
        let t = match wire::decode(&b).unwrap() {
            WireItem::Spectrum(s) => s.t_ns,
            WireItem::Audio(a) => a.t0_ns,
            _ => unreachable!(),
        };
        let now = now_ns();
        first.get_or_insert_with(Instant::now);
        lat.push(now - t);
    }
    let elapsed = first.unwrap().elapsed();
    assert_eq!(lat.len(), n, "items lost");
    child.wait().unwrap();
    let _ = s.close().wait();
    summarise(lat, elapsed, bytes)
}

/// The engine's in-process edge, producer and consumer threads.
fn in_process(kind: &str, n: usize, rate: f64) -> Figures {
    let (mut tx, mut rx, _) = edge(64, Policy::Block);
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    let kind2 = kind.to_string();
    let producer = std::thread::spawn(move || {
        let start = Instant::now();
        let base = item(&kind2, 0);
        for i in 0..n {
            if rate > 0.0 {
                let due = start + Duration::from_secs_f64(i as f64 / rate);
                if let Some(d) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(d);
                }
            }
            let mut it = base.clone();
            match &mut it {
                Item::Spectrum(s) => s.t_ns = now_ns(),
                Item::Audio(a) => a.t0_ns = now_ns(),
                _ => {}
            }
            tx.send(it, &stop2);
        }
    });
    let mut lat = Vec::with_capacity(n);
    let mut first = None;
    while let Recv::Item(it) = rx.recv(&stop) {
        let now = now_ns();
        first.get_or_insert_with(Instant::now);
        lat.push(now - it.t_ns());
    }
    producer.join().unwrap();
    summarise(lat, first.unwrap().elapsed(), 0)
}

/// How many peak sets a second one `vibroscope monitor` takes in (tracking
/// and the SQLite history included): 10 sources of 5 peaks each, sent as
/// fast as the monitor's blocking queue lets them through.
fn monitor_rate(n: usize) -> f64 {
    use std::io::BufRead;
    let dir = std::env::temp_dir().join(format!("vbs-bench-monitor-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let ep = format!("tcp/127.0.0.1:{port}");
    let mut mon = Command::new(env!("CARGO_BIN_EXE_vibroscope"))
        .args(["monitor", "--db"])
        .arg(dir.join("h.sqlite"))
        .args(["--listen", &ep, "--events-key", "", "--stale-s", "60"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(mon.stdout.take().unwrap()).lines();
    let s = net::open_session_plain(&Endpoints {
        connect: vec![ep],
        listen: vec![],
    })
    .unwrap();
    let pubs: Vec<_> = (0..10)
        .map(|k| {
            s.declare_publisher(format!("vibroscope/bench/cam{k}/peaks"))
                .congestion_control(zenoh::qos::CongestionControl::Block)
                .wait()
                .unwrap()
        })
        .collect();
    for p in &pubs {
        while !p.matching_status().wait().unwrap().matching() {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let mut buf = Vec::new();
    let t0 = Instant::now();
    for i in 0..n {
        let set = vibroscope_engine::PeakSet {
            t_ns: (i / 10) as i64 * 500_000_000,
            peaks: (0..5)
                .map(|j| vibroscope_engine::Resonance {
                    frequency_hz: 20.0 * (j + 1) as f64 + 0.01 * ((i * 7 + j) % 13) as f64,
                    frequency_std_hz: 0.05,
                    power_db: -40.0,
                    prominence_db: 20.0,
                    damping_ratio: 0.01,
                    damping_ratio_std: 0.001,
                })
                .collect(),
        };
        wire::encode_into(WireRef::Peaks(&set), &mut buf).unwrap();
        pubs[i % 10]
            .put(buf.as_slice())
            .attachment(&net::seq_attachment((i / 10) as u64)[..])
            .wait()
            .unwrap();
    }
    for p in &pubs {
        p.delete()
            .attachment(&net::seq_attachment((n / 10) as u64)[..])
            .wait()
            .unwrap();
    }
    let mut ended = 0;
    while ended < 10 {
        let l = lines.next().unwrap().unwrap();
        if l.contains("\"event\":\"ended\"") {
            ended += 1;
        }
    }
    let rate = n as f64 / t0.elapsed().as_secs_f64();
    unsafe { libc::kill(mon.id() as i32, libc::SIGTERM) };
    let _ = mon.wait();
    let _ = s.close().wait();
    let _ = std::fs::remove_dir_all(&dir);
    rate
}

fn main() {
    if let Ok(role) = std::env::var(ROLE) {
        let a: Vec<&str> = role.split(' ').collect();
        publisher(a[0], a[1], a[2].parse().unwrap(), a[3].parse().unwrap());
        return;
    }
    // `cargo bench` passes --bench; `cargo test --benches` runs it short.
    let quick = !std::env::args().any(|a| a == "--bench");
    let (flat, paced) = if quick { (2_000, 200) } else { (50_000, 3_000) };
    println!(
        "transport: two processes over zenoh (TCP loopback) against the in-process edge, same run"
    );
    println!(
        "{:<9} {:<18} {:>7} {:>12} {:>10} {:>10} {:>10} {:>12}",
        "item", "load", "bytes", "items/s", "MB/s", "p50 µs", "p99 µs", "vs in-proc"
    );
    let sets = if quick { 2_000 } else { 40_000 };
    println!(
        "one monitor (10 sources, 5 peaks a set, SQLite history): {:.0} peak sets/s",
        monitor_rate(sets)
    );
    for kind in ["spectrum", "audio"] {
        for (load, n, rate) in [("saturated", flat, 0.0), ("1000/s", paced, 1000.0)] {
            let local = in_process(kind, n, rate);
            let z = over_zenoh(kind, n, rate);
            for (name, f) in [("zenoh", &z), ("in-proc", &local)] {
                println!(
                    "{:<9} {:<18} {:>7} {:>12.0} {:>10.1} {:>10.1} {:>10.1} {:>12}",
                    format!("{kind}"),
                    format!("{load} {name}"),
                    z.bytes,
                    f.per_s,
                    f.per_s * z.bytes as f64 / 1e6,
                    f.p50_us,
                    f.p99_us,
                    if name == "zenoh" {
                        format!("{:.3}x", z.per_s / local.per_s)
                    } else {
                        "1x".into()
                    }
                );
            }
        }
    }
}
