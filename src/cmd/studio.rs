//! `vibroscope studio`.

use std::net::IpAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope_studio::{Studio, StudioOptions};

/// Open a recording in the browser: frame, regions, waveform, spectrum,
/// peaks and modal images (a local web application).
///
/// Starts a web server inside this process and prints its URL; open it in
/// a browser. Draw a rectangle (or paint a mask) on the frame to see that region's motion
/// waveform, its global power spectrum (Eq. 3.17) and the peak list
/// (frequency, damping ± uncertainty, prominence); click the spectrum, or a
/// listed peak to snap to it, to see the modal image at that frequency over
/// the frame (hue = phase, brightness = amplitude, thesis ch. 3.5.5) and
/// animate its mode shape. Drag over a spike in the spectrum instead to fit
/// its damping: a Lorentzian over the range dragged, with SSI-cov's
/// stabilisation diagram for it (thesis 5.4.2). A scale typed in the header
/// (mm per pixel) gives the motion in µm or mm. "Listen" plays the region's
/// recovered sound in the browser. Each view exports PNG and CSV/JSON (and
/// the sound as WAV).
///
/// With --pipeline (a shipped live pipeline such as live-spectrum, or a
/// pipeline file with a sliding `spectrum` stage) the studio runs it and
/// shows it live: the latest frame, the sliding spectrum and spectrogram,
/// the peaks, a level meter and every stage's counters (drops, queue
/// depth), updated over a WebSocket as they come. The page never slows the
/// pipeline: the studio keeps only the latest of each and drops what the
/// page has not taken. A pipeline with a `magnify` stage (live-magnify)
/// gets a magnified view: every frame the stage makes, at the rate the
/// page takes them, with fields that change its band and factor while it
/// runs (the magnifier starts over at the next frame), the frames shown
/// per second and the frames dropped on the way. --replay plays a
/// recording as the pipeline's camera, at the recording's own pace.
///
/// By default the server listens on 127.0.0.1 only, on a free port, and
/// the printed URL carries a random token (128 bits from the operating
/// system) that every request must present: opening the URL puts it in a
/// cookie (HttpOnly, SameSite=Strict) and takes it out of the address bar.
/// Requests whose Host header is not localhost, the address listened on or
/// a name given with --allow-host are refused (a web page whose name was
/// rebound to 127.0.0.1 cannot reach the studio), and so are requests made
/// by another site's page, another port of this machine included (Origin,
/// Sec-Fetch-Site). To use the studio from another machine, keep it on
/// 127.0.0.1 and forward its port over SSH (ssh -L 8080:127.0.0.1:8080
/// HOST, then open the printed URL with your local port); --bind ADDRESS
/// listens on another address instead, on the network as plain HTTP. At
/// most two analyses run at once and eight wait (more get 429), and one
/// request's analysis reads at most --max-work pixel-frames. Only files
/// under --root (by default the video's directory) can be opened, and no
/// answer names the root's absolute path. Stop with Ctrl-C (with a
/// live pipeline, the first Ctrl-C stops it, its outputs are finalised and
/// the studio exits; a second exits at once).
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope studio beam.y4m\n  \
    vibroscope studio ../shared/data/guitar.mp4 --fps 600 --port 8080\n  \
    vibroscope studio --pipeline live-spectrum --set src.duration_s=60\n  \
    vibroscope studio --pipeline live-magnify --replay rec.y4m --set mag.pyramid=riesz --set out.path=magnified.y4m\n  \
    vibroscope studio --root recordings --port 8080     # on a remote HOST; then, locally:\n  \
    ssh -N -L 8080:127.0.0.1:8080 HOST                    # and open the printed URL\n  \
    vibroscope studio --monitor tcp/127.0.0.1:7447     # a monitor's sources and alarms")]
pub struct Args {
    /// The recording opened first (.y4m, .cine, .mraw/.cih, or anything
    /// ffmpeg reads); others under --root can be opened from the page.
    video: Option<PathBuf>,
    /// Serve files only from under this directory (default: the video's
    /// directory, else the current one).
    #[arg(long, value_name = "DIR")]
    root: Option<PathBuf>,
    /// Listen on this address instead of 127.0.0.1 (plain HTTP: prefer an
    /// SSH tunnel to a studio on 127.0.0.1).
    #[arg(long, value_name = "ADDRESS")]
    bind: Option<IpAddr>,
    /// Serve without a token (loopback addresses only): every program and
    /// every user of this machine can then use the studio. Not advised.
    #[arg(long)]
    no_token: bool,
    /// Also answer requests for this host name (the Host header), beside
    /// localhost and the address listened on; repeatable.
    #[arg(long = "allow-host", value_name = "NAME")]
    allow_host: Vec<String>,
    /// The largest analysis one request may ask for, in G pixel-frames
    /// (region width x height x frames; 2^30 each).
    #[arg(
        long,
        value_name = "GPIX",
        default_value_t = 4.0,
        allow_negative_numbers = true
    )]
    max_work: f64,
    /// Port to listen on (0: any free one).
    #[arg(long, default_value_t = 0)]
    port: u16,
    /// Capture rate in Hz, when the file states the wrong one.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Run this live pipeline and show it (a shipped name, see `vibroscope
    /// pipelines`, or a file): its frames and counters, the sliding
    /// spectrum when it has a `spectrum` stage, the magnified view when it
    /// has a `magnify` stage.
    #[arg(long, value_name = "PIPELINE")]
    pipeline: Option<String>,
    /// Play this recording as --pipeline's source (replacing its camera),
    /// at the recording's own pace: a live source, so a stage that falls
    /// behind drops frames and counts them.
    #[arg(long, value_name = "FILE", requires = "pipeline")]
    replay: Option<PathBuf>,
    /// Change a parameter of --pipeline: STAGE.KEY=VALUE (VALUE is TOML);
    /// repeatable.
    #[arg(long = "set", value_name = "STAGE.KEY=VALUE")]
    set: Vec<String>,
    /// Show a `vibroscope monitor`'s sources and alarms: the zenoh endpoint
    /// it listens on (tcp/HOST:PORT; comma-separated for several).
    #[arg(long, value_name = "ENDPOINT")]
    monitor: Option<String>,
    /// The key the monitor publishes its events on (its --events-key).
    #[arg(long, value_name = "KEY", default_value = "vibroscope/@monitor/events")]
    monitor_key: String,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if !(a.max_work.is_finite() && a.max_work > 0.0) {
        return Err(vibroscope::UsageError::new(
            "studio",
            format!(
                "--max-work {}: must be a positive number of G pixel-frames",
                a.max_work
            ),
        )
        .into());
    }
    let o = StudioOptions {
        video: a.video,
        root: a.root,
        bind: a.bind,
        no_token: a.no_token,
        allow_hosts: a.allow_host,
        max_work: Some((a.max_work * (1u64 << 30) as f64).max(1.0) as u64),
        port: a.port,
        fps: a.fps,
        max_body: None,
        pipeline: a.pipeline,
        set: a.set,
        replay: a.replay,
        monitor: a.monitor.map(|m| (m, a.monitor_key)),
    };
    let o_pipeline = o.pipeline.clone();
    let studio = Studio::start(&o).map_err(|e| -> anyhow::Error {
        if e.is_usage() {
            vibroscope::UsageError::new("studio", e.to_string()).into()
        } else {
            anyhow::anyhow!("{e}")
        }
    })?;
    super::outln!("vibroscope studio: open {}", studio.url);
    eprintln!(
        "serving files under {} (Ctrl-C stops)",
        studio.root.display()
    );
    if let Some(p) = &o_pipeline {
        eprintln!("running the live pipeline {p}: its view is on the page");
    }
    if studio.token.is_none() {
        eprintln!(
            "warning: --no-token: any program or user of this machine can use this studio and read the files under its root"
        );
    } else if !studio.addr.ip().is_loopback() {
        eprintln!(
            "listening beyond this machine, as plain HTTP: every request needs the token in the URL"
        );
    }
    if studio.serve() {
        // Ctrl-C stopped the live pipeline; its sinks finalised.
        return Err(vibroscope::pipeline::interrupted().into());
    }
    Ok(ExitCode::SUCCESS)
}
