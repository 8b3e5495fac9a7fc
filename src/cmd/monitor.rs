//! `vibroscope monitor`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use vibroscope::live::net;
use vibroscope::monitor::{track::TrackConfig, MonitorOptions};

/// Watch the resonances of many cameras: subscribe (zenoh) to the peak sets
/// that camera nodes publish (pipelines/camera-node.toml), follow each
/// resonance's frequency, damping and power over time, and raise an alarm
/// when one moves beyond --k standard deviations of its own history (the
/// thesis's 5.6 test, made continuous). Events are JSON lines on stdout:
/// start, baseline, track, alarm, lost, cleared, stale, resumed, ended,
/// refused, summary. The history lives in an SQLite file (--db): a monitor
/// restarted after a crash continues with it and loses at most the last
/// quarter second.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope monitor --db site.sqlite --listen tcp/0.0.0.0:7447\n  \
    vibroscope monitor --db site.sqlite --connect tcp/10.0.0.5:7447 --key 'vibroscope/bridge/**'\n\n\
Each camera node runs `vibroscope run camera-node --set pub.connect=tcp/MONITOR:7447` \
(or listens, and the monitor connects). A source that sends nothing for --stale-s \
seconds is reported stale, not alarmed. Stop with Ctrl-C or SIGTERM: the history \
is committed and a summary line is printed per track.")]
pub struct Args {
    /// The history file (SQLite; created when absent, opened exclusively).
    #[arg(long, value_name = "FILE")]
    db: PathBuf,
    /// Key expression of the peak sets to watch.
    #[arg(long, default_value = "vibroscope/**/peaks")]
    key: String,
    /// zenoh endpoints to listen on, comma-separated.
    #[arg(long, default_value = "", value_name = "ENDPOINTS")]
    listen: String,
    /// zenoh endpoints to connect to, comma-separated (retried until up).
    #[arg(long, default_value = "", value_name = "ENDPOINTS")]
    connect: String,
    /// Alarm threshold in standard deviations of the track's own history.
    #[arg(long, default_value_t = TrackConfig::default().k)]
    k: f64,
    /// Observations in a row that raise (or clear) an alarm.
    #[arg(long, default_value_t = TrackConfig::default().persist)]
    persist: usize,
    /// Peak sets pooled to find each source's resonances.
    #[arg(long, default_value_t = TrackConfig::default().baseline)]
    baseline: usize,
    /// Normal observations kept as each track's history.
    #[arg(long, default_value_t = TrackConfig::default().window)]
    window: usize,
    /// A track takes the nearest peak within this fraction of its frequency.
    #[arg(long, default_value_t = TrackConfig::default().gate_rel)]
    gate: f64,
    /// Seconds without a peak set before a source is reported stale.
    #[arg(long, value_name = "S", default_value_t = 5.0)]
    stale_s: f64,
    /// Stop after this many seconds (default: until interrupted).
    #[arg(long, value_name = "S")]
    for_s: Option<f64>,
    /// Also publish every event (JSON) on this key (empty: do not publish).
    #[arg(long, default_value = "vibroscope/@monitor/events")]
    events_key: String,
}

fn secs(flag: &str, v: f64) -> anyhow::Result<Duration> {
    if v.is_finite() && v > 0.0 && v < 1e9 {
        Ok(Duration::from_secs_f64(v))
    } else {
        anyhow::bail!("{flag}: must be a number of seconds > 0, got {v}")
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let endpoints = net::Endpoints {
        connect: net::parse_endpoints(&a.connect).map_err(|m| anyhow::anyhow!("--connect: {m}"))?,
        listen: net::parse_endpoints(&a.listen).map_err(|m| anyhow::anyhow!("--listen: {m}"))?,
    };
    let opts = MonitorOptions {
        key: a.key,
        endpoints,
        db: a.db,
        track: TrackConfig {
            k: a.k,
            persist: a.persist,
            baseline: a.baseline,
            window: a.window,
            gate_rel: a.gate,
            ..TrackConfig::default()
        },
        stale_after: secs("--stale-s", a.stale_s)?,
        run_for: a.for_s.map(|s| secs("--for-s", s)).transpose()?,
        events_key: (!a.events_key.is_empty()).then_some(a.events_key),
    };
    let mut out = std::io::stdout();
    let r = vibroscope::monitor::run(&opts, &mut out)?;
    eprintln!(
        "monitor: {} sources, {} peak sets, {} alarms, {} stale, {} refused; history {} ({} rows written)",
        r.sources,
        r.peak_sets,
        r.alarms,
        r.stale,
        r.refused,
        r.db.display(),
        r.rows_written
    );
    Ok(ExitCode::SUCCESS)
}
