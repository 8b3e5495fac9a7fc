//! The studio's HTTP API: JSON in and out (frames and modal images as
//! PNG), every answer computed by the recipes of the `vibroscope` crate.
//!
//! | request | answer |
//! |---|---|
//! | `GET /api/session` | the video opened at start, the root's name (never its path), whether a token is needed, the analyses running and waiting |
//! | `GET /api/info?video=P[&fps=F]` | [`vibroscope::probe`]'s report |
//! | `GET /api/frame?video=P&i=N` | frame N as an 8-bit grey PNG |
//! | `POST /api/motion {video, roi?, mask?, fps?, scale_mm_per_px?}` | the region's waveform (px, and in µm/mm with a scale), spectrum (dB) and peaks (amplitudes likewise) |
//! | `POST /api/mode {video, freq_hz, roi?, fps?, scale_mm_per_px?}` | the modal image: PNG (hue = phase, brightness = amplitude) and the amplitude/phase numbers |
//! | `POST /api/listen {video, roi?, mask?, fps?}` | the region's recovered sound (the `listen` recipe, 16-bit WAV at 8 kHz) and its spectrogram |
//! | `POST /api/damping {video, lo_hz, hi_hz, roi?, mask?, fps?}` | the damping view over a range of the region's spectrum: the Lorentzian fitted there (damping, uncertainty, the model's curve) and SSI-cov's stabilisation diagram (poles over model orders, stable ones marked) |
//! | `POST /api/idv/basis {video, roi?, mask?, fps?, modes?, max_modes?}` | the region's image-space modal basis (interactive dynamic video, thesis ch. 6) for the page to simulate and render: see [`idv`] |
//! | `GET /api/live` | the live pipeline's latest update (spectrum in dB, peaks, level, frame number, stage counters) |
//! | `GET /api/live/frame` | its latest frame as an 8-bit grey PNG |
//! | `POST /api/live/mode {freq_hz}` | the modal image at that frequency from the live pipeline's last 4 s of frames (as `/api/mode` answers, with the frames, span and rate used) |
//! | `GET /api/live/ws` | a WebSocket carrying each new update as it comes (at most 50 a second; stale ones are replaced, never queued), and with a `magnify` stage each new magnified frame as a binary message (`VMAG`, width, height, frame number, capture time, then 8-bit grey pixels) |
//! | `GET /api/live/magnified` | the latest frame of the live pipeline's `magnify` stage as an 8-bit grey PNG (frame number in `X-Frame`) |
//! | `POST /api/live/magnify {lo_hz, hi_hz, factor}` | changes that stage's band and factor while it runs: the frame they took effect at, or 422 with why the stage kept its own |
//!
//! A `mask` is a PNG the frame's size painted on the page (a `data:` URL),
//! read by the same loader as `--mask`.
//!
//! Errors come back as `{"error": MESSAGE}` with a 4xx (the request) or
//! 5xx (the computation) status; nothing a request holds panics the server.

pub mod idv;

mod access;
mod base64;
mod cache;
mod live_routes;
mod modal;
mod region;
mod selection;
mod sound;
mod units;
mod video;

pub use self::base64::{base64, base64_decode};
use access::{gate, TOKEN_COOKIE};
use live_routes::{
    live_frame, live_magnified, live_magnify, live_mode, live_update, live_ws, monitor_update,
};
use modal::mode;
use region::{damping, idv_basis, motion};
pub(crate) use selection::Selection;
use sound::listen;
use video::{frame, info};

pub use crate::error::ApiError;
use crate::guard::Hosts;
use crate::limits::{self, Queue};
use crate::live::Live;

/// What the Monitor panel shows: a monitor's events over zenoh.
#[cfg(feature = "net")]
pub type MonitorFeed = vibroscope::monitor::feed::Feed;
/// Without the `net` feature there is no monitor to show.
#[cfg(not(feature = "net"))]
pub enum MonitorFeed {}
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use serde_json::{json, Value};
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use vibroscope::files::VideoReader;

const INDEX_HTML: &str = include_str!("../../assets/index.html");
const APP_JS: &str = include_str!("../../assets/app.js");
const STYLE_CSS: &str = include_str!("../../assets/style.css");

/// The server's state.
pub struct App {
    root: PathBuf,
    video: Option<String>,
    fps: Option<f64>,
    token: Option<String>,
    cache: Mutex<HashMap<String, Arc<Value>>>,
    /// The last frame reader, for scrubbing forward without reopening.
    reader: Mutex<Option<OpenReader>>,
    /// The live pipeline, when started with one.
    live: Option<Arc<Live>>,
    /// A monitor's events (`--monitor`).
    monitor: Option<Arc<MonitorFeed>>,
    /// Raised when the studio stops: open WebSockets close.
    closing: tokio::sync::watch::Sender<bool>,
    /// The `Host` names answered.
    hosts: Hosts,
    /// The cookie carrying the token (named after the port: cookies are
    /// shared by every port of a host, so two studios keep one each).
    cookie: String,
    /// Analyses and reads under way and waiting.
    analyses: Queue,
    reads: Queue,
    /// The largest analysis a request may ask for (pixel-frames).
    max_pixel_frames: u64,
    /// The root's absolute path as it could appear in an answer: taken out.
    root_forms: Vec<String>,
    /// The latest refusals (also printed on standard error).
    log: Mutex<VecDeque<String>>,
}

/// How many refusals [`App::log`] keeps.
const LOG_LINES: usize = 200;

/// A reader left open: its file and the index of the next frame it gives.
type OpenReader = (PathBuf, u64, Box<dyn VideoReader>);

impl App {
    pub fn new(
        root: PathBuf,
        video: Option<String>,
        fps: Option<f64>,
        token: Option<String>,
    ) -> App {
        let root_forms = limits::path_forms(&root);
        App {
            root,
            video,
            fps,
            token,
            cache: Mutex::new(HashMap::new()),
            reader: Mutex::new(None),
            live: None,
            monitor: None,
            closing: tokio::sync::watch::Sender::new(false),
            hosts: Hosts {
                bound: std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
                allowed: Vec::new(),
            },
            cookie: TOKEN_COOKIE.to_owned(),
            analyses: Queue::new(
                "analyses",
                limits::ANALYSES_RUNNING,
                limits::ANALYSES_WAITING,
            ),
            reads: Queue::new("frame reads", limits::READS_RUNNING, limits::READS_WAITING),
            max_pixel_frames: limits::MAX_PIXEL_FRAMES,
            root_forms,
            log: Mutex::new(VecDeque::new()),
        }
    }

    /// Answers the `Host` names of `hosts`; the token's cookie is named
    /// after `port`.
    pub fn with_access(mut self, hosts: Hosts, port: u16) -> App {
        self.hosts = hosts;
        self.cookie = format!("{TOKEN_COOKIE}_{port}");
        self
    }

    /// Bounds an analysis to `max_pixel_frames` (region x frames).
    pub fn with_max_work(mut self, max_pixel_frames: u64) -> App {
        self.max_pixel_frames = max_pixel_frames;
        self
    }

    /// Also takes `dir` (the root as given, before symlinks were resolved)
    /// out of every answer.
    pub fn hiding(mut self, dir: &Path) -> App {
        for f in limits::path_forms(dir) {
            if !self.root_forms.contains(&f) {
                self.root_forms.push(f);
            }
        }
        // Longest first: a form inside another is taken out after it.
        self.root_forms.sort_by_key(|f| std::cmp::Reverse(f.len()));
        self
    }

    /// The latest refusals, oldest first.
    pub fn log(&self) -> Vec<String> {
        self.log
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .cloned()
            .collect()
    }

    /// A request refused: logged (standard error and [`App::log`]) and
    /// answered with `status` and `message`. The log names the method,
    /// the path (never the query: it may hold the token) and the reason.
    fn refuse(&self, req: &Request, status: StatusCode, message: String) -> Response {
        let line = format!(
            "studio: refused {} {} ({}): {message}",
            req.method(),
            req.uri().path(),
            status.as_u16()
        );
        eprintln!("{line}");
        let mut log = self.log.lock().unwrap_or_else(|p| p.into_inner());
        if log.len() >= LOG_LINES {
            log.pop_front();
        }
        log.push_back(line);
        drop(log);
        ApiError::new(status, message).into_response()
    }

    /// Serves `live`'s updates too.
    pub fn with_monitor(mut self, monitor: Option<Arc<MonitorFeed>>) -> App {
        self.monitor = monitor;
        self
    }

    pub fn with_live(mut self, live: Option<Arc<Live>>) -> App {
        self.live = live;
        self
    }

    /// The live pipeline was stopped by a signal (see [`Live::interrupted`]).
    pub fn live_interrupted(&self) -> bool {
        self.live.as_ref().is_some_and(|l| l.interrupted())
    }

    /// Closes the WebSockets and stops the live pipeline.
    pub fn close(&self) {
        self.closing.send_replace(true);
        if let Some(l) = &self.live {
            l.stop();
        }
    }
}

type ApiResult<T> = Result<T, ApiError>;

/// The routes, behind the guard, with request bodies bounded to `max_body`.
pub fn router(app: Arc<App>, max_body: usize) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { asset(INDEX_HTML, "text/html; charset=utf-8") }),
        )
        .route(
            "/app.js",
            get(|| async { asset(APP_JS, "text/javascript; charset=utf-8") }),
        )
        .route(
            "/style.css",
            get(|| async { asset(STYLE_CSS, "text/css; charset=utf-8") }),
        )
        .route("/api/session", get(session))
        .route("/api/info", get(info))
        .route("/api/frame", get(frame))
        .route("/api/motion", post(motion))
        .route("/api/mode", post(mode))
        .route("/api/listen", post(listen))
        .route("/api/damping", post(damping))
        .route("/api/idv/basis", post(idv_basis))
        .route("/api/monitor", get(monitor_update))
        .route("/api/live", get(live_update))
        .route("/api/live/frame", get(live_frame))
        .route("/api/live/ws", get(live_ws))
        .route("/api/live/mode", post(live_mode))
        .route("/api/live/magnified", get(live_magnified))
        .route("/api/live/magnify", post(live_magnify))
        .fallback(|| async { ApiError::new(StatusCode::NOT_FOUND, "no such page") })
        .layer(DefaultBodyLimit::max(max_body))
        .layer(middleware::from_fn(json_errors))
        .layer(middleware::from_fn_with_state(app.clone(), gate))
        .with_state(app)
}

fn asset(body: &'static str, mime: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(mime)),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-store")),
        ],
        body,
    )
        .into_response()
}

/// Error answers that axum makes itself (405 for a wrong method, 413 for a
/// body over the bound, 400/415 for a body it cannot read) come as plain
/// text or empty; the page shows `{"error": ...}`, so they are rewritten
/// into that JSON with their status and text kept.
async fn json_errors(req: Request, next: Next) -> Response {
    let resp = next.run(req).await;
    let status = resp.status();
    let is_json = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return resp;
    }
    let text = axum::body::to_bytes(resp.into_body(), 64 * 1024)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_owned())
        .unwrap_or_default();
    let message = match (text.is_empty(), status) {
        (false, _) => text,
        (true, StatusCode::METHOD_NOT_ALLOWED) => {
            "method not allowed here (the API takes GET for info and frames, POST for motion and modes)".to_owned()
        }
        (true, s) => s.canonical_reason().unwrap_or("error").to_owned(),
    };
    ApiError::new(status, message).into_response()
}

async fn session(State(app): State<Arc<App>>) -> axum::Json<Value> {
    let (running, waiting) = app.analyses.load();
    // The root's own name, never its absolute path.
    let root = app
        .root
        .file_name()
        .map_or_else(|| ".".to_owned(), |n| n.to_string_lossy().into_owned());
    axum::Json(json!({
        "video": app.video,
        "fps": app.fps,
        "root": root,
        "analyses": { "running": running, "waiting": waiting },
        "token_required": app.token.is_some(),
        "live": app.live.as_ref().map(|l| json!({
            "pipeline": l.name,
            "has_spectrum": l.has_spectrum,
            "magnify": l.magnify.as_ref().map(|m| m.stage.clone()),
        })),
        "monitor": app.monitor.is_some(),
    }))
}

/// Runs a computation off the async threads; a panic in it becomes a 500.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    tokio::task::spawn_blocking(f).await.map_err(|e| {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("internal error in the computation: {e}"),
        )
    })?
}

fn fps_of(app: &App, given: Option<f64>) -> ApiResult<Option<f64>> {
    match given.or(app.fps) {
        Some(f) if !(f.is_finite() && f > 0.0) => Err(ApiError::unprocessable(format!(
            "fps {f}: must be a positive number"
        ))),
        f => Ok(f),
    }
}

/// A JSON body, or 400 naming what is wrong (bodies over the bound were
/// refused with 413 before this).
fn body<T: serde::de::DeserializeOwned>(b: &Bytes) -> ApiResult<T> {
    serde_json::from_slice(b).map_err(|e| ApiError::bad(format!("request body: {e}")))
}
