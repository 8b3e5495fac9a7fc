//! vibroscope studio (issue 16): a local web application over the typed
//! recipes. The binary's `vibroscope studio` starts it; the page and its
//! script are built into the binary (plain JavaScript drawing on canvas:
//! no npm, no network at run time).
//!
//! - [`Studio::start`] binds (127.0.0.1 by default, port 0 = any free one),
//!   serves on a thread of its own and returns the URL to print;
//! - [`guard`]: files only under the root given at start; a token in every
//!   request (loopback included, unless `--no-token`), a `Host` that names
//!   the studio and no other site's `Origin` (DNS rebinding, other pages);
//! - [`limits`]: bounded work per client (analyses at once, their size,
//!   the answers' size; the work of a client that went away stopped), and
//!   no absolute path of the root in any answer;
//! - [`api`]: the JSON API (video info, frames as PNG, a region's motion,
//!   spectrum and peaks, the modal image at a frequency), each answer
//!   computed by the recipes of the `vibroscope` crate and cached per video;
//! - [`error`]: the error answers (`{"error": MESSAGE}` with a status);
//! - [`api::idv`]: the modal basis of a region for interactive dynamic video in
//!   the page (thesis ch. 6: drag the object, see it respond).

pub mod api;
pub mod error;
pub mod guard;
pub mod limits;
pub mod live;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What `vibroscope studio` is asked.
#[derive(Clone, Debug, Default)]
pub struct StudioOptions {
    /// The recording opened first (must be under `root`).
    pub video: Option<PathBuf>,
    /// Files are served only from under this directory (default: the
    /// video's directory, else the current directory).
    pub root: Option<PathBuf>,
    /// Address to bind (default 127.0.0.1).
    pub bind: Option<IpAddr>,
    /// Serve without a token (loopback addresses only): any program or
    /// page of this machine that can reach the port can then use it.
    pub no_token: bool,
    /// More names accepted in the `Host` header (beside `localhost` and
    /// the address listened on): a name this machine is reached by.
    pub allow_hosts: Vec<String>,
    /// The largest analysis a request may ask for, pixel-frames (region
    /// width x height x frames; default [`limits::MAX_PIXEL_FRAMES`]).
    pub max_work: Option<u64>,
    /// Port (0: one the operating system gives).
    pub port: u16,
    /// The capture rate, when the file states the wrong one.
    pub fps: Option<f64>,
    /// Largest request body accepted, bytes (default [`MAX_BODY`]).
    pub max_body: Option<usize>,
    /// A live pipeline to run and show (a shipped name or a file): its
    /// latest frame, sliding spectrum, level and stage counters.
    pub pipeline: Option<String>,
    /// `STAGE.KEY=VALUE` changes to that pipeline.
    pub set: Vec<String>,
    /// Replaces that pipeline's source with this recording, played at its
    /// own pace (a live source).
    pub replay: Option<PathBuf>,
    /// A `vibroscope monitor` to show: its zenoh endpoints (comma-separated)
    /// and the key it publishes its events on.
    pub monitor: Option<(String, String)>,
}

/// Subscribes to a monitor's events (`--monitor`).
#[cfg(feature = "net")]
fn start_monitor_feed(endpoints: &str, key: &str) -> Result<Arc<api::MonitorFeed>, StartError> {
    use vibroscope::live::net;
    let connect = net::parse_endpoints(endpoints)
        .map_err(|m| StartError::Usage(format!("--monitor: {m}")))?;
    let feed = vibroscope::monitor::feed::Feed::start(
        net::Endpoints {
            connect,
            listen: Vec::new(),
        },
        key,
    )
    .map_err(|m| StartError::Usage(format!("--monitor: {m}")))?;
    Ok(Arc::new(feed))
}

#[cfg(not(feature = "net"))]
fn start_monitor_feed(_: &str, _: &str) -> Result<Arc<api::MonitorFeed>, StartError> {
    Err(StartError::Usage(
        "--monitor: this build has no network support (the `net` feature)".into(),
    ))
}

/// The default bound on request bodies (the API's requests are a few
/// hundred bytes of JSON).
pub const MAX_BODY: usize = 64 * 1024;

/// Why the studio did not start.
#[derive(Debug)]
pub enum StartError {
    /// A bad option (exit 2).
    Usage(String),
    /// The address could not be bound, or the runtime not built (exit 1).
    Runtime(String),
}

impl std::error::Error for StartError {}

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StartError::Usage(m) | StartError::Runtime(m) => f.write_str(m),
        }
    }
}

impl StartError {
    /// True for a usage error (bad path or option): exit status 2.
    pub fn is_usage(&self) -> bool {
        matches!(self, StartError::Usage(_))
    }
}

/// The server's threads yield to the pipeline's: each runs at nice +10
/// (Linux keeps a nice value per thread), so on a machine the live
/// pipeline keeps busy, answering the page takes time from idle cores
/// only, never from the frame path.
fn lower_priority() {
    // SAFETY: setpriority on the calling thread (who = 0) only reads its
    // arguments; a failure leaves the priority as it was.
    #[cfg(target_os = "linux")]
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}

/// A running studio.
pub struct Studio {
    /// The URL to open (with `?token=…` when one is needed).
    pub url: String,
    pub addr: SocketAddr,
    /// The token every request needs (none with `--no-token`).
    pub token: Option<String>,
    /// The directory files are served from (canonical).
    pub root: PathBuf,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
    app: Arc<api::App>,
}

impl Studio {
    /// The latest requests refused (Host, Origin, token), oldest first, as
    /// printed on standard error.
    pub fn log(&self) -> Vec<String> {
        self.app.log()
    }

    /// Binds and starts serving on a thread of its own.
    pub fn start(o: &StudioOptions) -> Result<Studio, StartError> {
        let root_arg: PathBuf = match (&o.root, &o.video) {
            (Some(r), _) => r.clone(),
            (None, Some(v)) => v
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
            (None, None) => PathBuf::from("."),
        };
        let root = root_arg
            .canonicalize()
            .map_err(|e| StartError::Usage(format!("--root {}: {e}", root_arg.display())))?;
        if !root.is_dir() {
            return Err(StartError::Usage(format!(
                "--root {}: not a directory",
                root_arg.display()
            )));
        }
        let video = match &o.video {
            None => None,
            Some(v) => {
                let real = v
                    .canonicalize()
                    .map_err(|e| StartError::Usage(format!("{}: {e}", v.display())))?;
                let rel = real.strip_prefix(&root).map_err(|_| {
                    StartError::Usage(format!(
                        "{}: not under the root {} (pass --root)",
                        v.display(),
                        root.display()
                    ))
                })?;
                Some(rel.to_string_lossy().into_owned())
            }
        };
        if let Some(f) = o.fps {
            if !(f.is_finite() && f > 0.0) {
                return Err(StartError::Usage(format!(
                    "--fps {f}: must be a positive number of frames per second"
                )));
            }
        }
        if o.pipeline.is_none() && !o.set.is_empty() {
            return Err(StartError::Usage(
                "--set changes a --pipeline: give one".into(),
            ));
        }
        if o.pipeline.is_none() && o.replay.is_some() {
            return Err(StartError::Usage(
                "--replay replaces the source of a --pipeline: give one".into(),
            ));
        }
        let live_decl = match &o.pipeline {
            None => None,
            Some(p) => {
                Some(live::prepare(p, &o.set, o.replay.as_deref()).map_err(StartError::Usage)?)
            }
        };
        let monitor = match &o.monitor {
            None => None,
            Some((endpoints, key)) => Some(start_monitor_feed(endpoints, key)?),
        };
        let ip = o.bind.unwrap_or(IpAddr::V4(Ipv4Addr::LOCALHOST));
        let token = if o.no_token {
            if !ip.is_loopback() {
                return Err(StartError::Usage(format!(
                    "--no-token: only on a loopback address; listening on {ip} every request needs the token"
                )));
            }
            None
        } else {
            Some(guard::new_token().map_err(StartError::Runtime)?)
        };
        let mut allowed = Vec::new();
        for h in &o.allow_hosts {
            match guard::host_name(h) {
                Some(n) if !h.contains(':') || h.starts_with('[') => allowed.push(n),
                _ => {
                    return Err(StartError::Usage(format!(
                        "--allow-host {h:?}: give a host name (letters, digits, dots, dashes), without a port"
                    )))
                }
            }
        }
        if o.max_work == Some(0) {
            return Err(StartError::Usage(
                "--max-work 0: an analysis must be allowed some pixels".into(),
            ));
        }
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .on_thread_start(lower_priority)
            .enable_all()
            .build()
            .map_err(|e| StartError::Runtime(format!("cannot start the server's runtime: {e}")))?;
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(SocketAddr::new(ip, o.port)))
            .map_err(|e| StartError::Runtime(format!("cannot bind {ip}:{}: {e}", o.port)))?;
        let addr = listener
            .local_addr()
            .map_err(|e| StartError::Runtime(format!("bound address: {e}")))?;
        let live = match (live_decl, &o.pipeline) {
            (Some(d), Some(name)) => Some(live::Live::start(name, d).map_err(StartError::Runtime)?),
            _ => None,
        };
        let given_root = std::path::absolute(&root_arg).unwrap_or_else(|_| root_arg.clone());
        let app = Arc::new(
            api::App::new(root.clone(), video, o.fps, token.clone())
                .with_access(guard::Hosts { bound: ip, allowed }, addr.port())
                .with_max_work(o.max_work.unwrap_or(limits::MAX_PIXEL_FRAMES))
                .hiding(&given_root)
                .with_live(live)
                .with_monitor(monitor),
        );
        let router = api::router(app.clone(), o.max_body.unwrap_or(MAX_BODY));
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("studio".into())
            .spawn(move || {
                rt.block_on(async move {
                    let server = axum::serve(listener, router).with_graceful_shutdown(async {
                        let _ = rx.await;
                    });
                    if let Err(e) = server.await {
                        eprintln!("studio: server stopped: {e}");
                    }
                });
            })
            .map_err(|e| StartError::Runtime(format!("cannot start the server thread: {e}")))?;
        let host = match ip {
            IpAddr::V6(v6) => format!("[{v6}]"),
            IpAddr::V4(v4) => v4.to_string(),
        };
        let mut url = format!("http://{host}:{}/", addr.port());
        if let Some(t) = &token {
            url.push_str(&format!("?token={t}"));
        }
        Ok(Studio {
            url,
            addr,
            token,
            root,
            shutdown: Some(tx),
            thread: Some(thread),
            app,
        })
    }

    /// Serves until the process ends, or until a signal (Ctrl-C) stopped
    /// the live pipeline: then its outputs are finalised, the server stops
    /// and this returns true (the caller exits with the signal's status).
    pub fn serve(mut self) -> bool {
        loop {
            if self.app.live_interrupted() {
                return true;
            }
            if self.thread.as_ref().is_none_or(|t| t.is_finished()) {
                if let Some(t) = self.thread.take() {
                    let _ = t.join();
                }
                return false;
            }
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    }
}

impl Drop for Studio {
    /// Stops serving (open connections finish, WebSockets close, the live
    /// pipeline stops) and waits for the thread.
    fn drop(&mut self) {
        self.app.close();
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
