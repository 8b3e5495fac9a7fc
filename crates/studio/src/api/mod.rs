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
//! | `GET /api/live/ws` | a WebSocket carrying each new update as it comes (at most 50 a second; stale ones are replaced, never queued) |
//!
//! A `mask` is a PNG the frame's size painted on the page (a `data:` URL),
//! read by the same loader as `--mask`.
//!
//! Errors come back as `{"error": MESSAGE}` with a 4xx (the request) or
//! 5xx (the computation) status; nothing a request holds panics the server.

pub mod idv;

pub use crate::error::ApiError;
use crate::guard::{self, Hosts};
use crate::limits::{self, Queue};
use crate::live::Live;

/// What the Monitor panel shows: a monitor's events over zenoh.
#[cfg(feature = "net")]
pub type MonitorFeed = vibroscope::monitor::feed::Feed;
/// Without the `net` feature there is no monitor to show.
#[cfg(not(feature = "net"))]
pub enum MonitorFeed {}
use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{DefaultBodyLimit, Query, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use serde::Deserialize;
use serde_json::{json, Value};
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use vibroscope::files::{FrameDest, VideoReader};
use vibroscope::modes::ModesOptions;
use vibroscope::modes::{align_phase, read_npy_complex64};
use vibroscope::pipeline::{Region, Roi};
use vibroscope::spectrum::{DisplacementTap, SpectrumOptions};

const INDEX_HTML: &str = include_str!("../../assets/index.html");
const APP_JS: &str = include_str!("../../assets/app.js");
const STYLE_CSS: &str = include_str!("../../assets/style.css");

/// At most this many computed answers are kept (then the cache starts over).
const CACHE_ENTRIES: usize = 64;

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

/// The cookie that carries the token for the page's own requests, once
/// the page's URL has set it (its script, stylesheet and API calls go
/// without `?token=`): this name, then `_PORT` ([`App::with_access`]).
const TOKEN_COOKIE: &str = "vibroscope_token";

/// Every request, WebSocket upgrades included, before any route:
/// - no encoded separators in the path (400);
/// - a `Host` that names this studio ([`Hosts::accepts`]), else 403: a
///   page whose name was rebound to this machine's address is refused;
/// - no other site's page ([`guard::cross_origin`]: `Origin`,
///   `Sec-Fetch-Site`), else 403, another port of this machine included;
/// - the token when one is set (query `token=`, header
///   `x-vibroscope-token`, or the cookie set when the page was opened
///   with it), else 403. The page's URL with `?token=` answers with the
///   cookie (`HttpOnly`, `SameSite=Strict`) and a redirect to the page
///   without the token, so it stays out of the address bar and history.
///
/// Every refusal is logged ([`App::log`]). Answers carry the security
/// headers, are bounded in size and never hold the root's absolute path
/// ([`limits::bounded`]).
async fn gate(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    let set_cookie = match access(&app, &req) {
        Access::Answer(resp) => return resp,
        Access::Pass { set_cookie } => set_cookie,
    };
    let resp = next.run(req).await;
    let mut resp = limits::bounded(resp, &app.root_forms).await;
    security_headers(&mut resp);
    if let Some(c) = set_cookie {
        resp.headers_mut().insert(header::SET_COOKIE, c);
    }
    resp
}

/// What [`gate`] decides before the request goes on.
enum Access {
    /// Refused, or redirected: this is the answer.
    Answer(Response),
    /// Let in, setting the token's cookie when it came in the query.
    Pass { set_cookie: Option<HeaderValue> },
}

fn header_text(req: &Request, name: &str) -> Option<String> {
    req.headers().get(name).map(|v| {
        v.to_str()
            .map_or_else(|_| "(not text)".to_owned(), str::to_owned)
    })
}

fn access(app: &App, req: &Request) -> Access {
    if guard::has_encoded_separator(req.uri().path()) {
        return Access::Answer(
            ApiError::bad("encoded slashes, backslashes or NULs are not allowed in a path")
                .into_response(),
        );
    }
    let Some(host) =
        header_text(req, "host").or_else(|| req.uri().authority().map(|a| a.to_string()))
    else {
        return Access::Answer(app.refuse(req, StatusCode::BAD_REQUEST, "no Host header".into()));
    };
    if !app.hosts.accepts(&host) {
        let message = format!(
            "Host: {host} does not name this studio (it answers localhost and its own address; start it with --allow-host NAME for another name)"
        );
        return Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, message));
    }
    let origin = header_text(req, "origin");
    let site = header_text(req, "sec-fetch-site");
    if let Some(why) = guard::cross_origin(origin.as_deref(), site.as_deref(), &host) {
        let message = format!("cross-origin request refused: {why}");
        return Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, message));
    }
    let Some(expected) = &app.token else {
        return Access::Pass { set_cookie: None };
    };
    let from_query = req.uri().query().and_then(|q| {
        q.split('&')
            .find_map(|kv| kv.strip_prefix("token=").map(str::to_owned))
    });
    let from_cookie = || {
        req.headers()
            .get_all(header::COOKIE)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(';'))
            .find_map(|kv| {
                kv.trim()
                    .strip_prefix(app.cookie.as_str())
                    .and_then(|r| r.strip_prefix('='))
                    .map(str::to_owned)
            })
    };
    let in_query = from_query.is_some();
    let given = from_query
        .or_else(|| header_text(req, "x-vibroscope-token"))
        .or_else(from_cookie);
    match given {
        None => {
            let message =
                "this studio needs its token: open the URL it printed (it ends in ?token=...)"
                    .to_owned();
            Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, message))
        }
        Some(t) if !guard::same_token(&t, expected) => {
            Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, "wrong token".into()))
        }
        Some(_) if in_query => {
            let set_cookie = HeaderValue::from_str(&format!(
                "{}={expected}; HttpOnly; SameSite=Strict; Path=/",
                app.cookie
            ))
            .ok();
            if req.method() != axum::http::Method::GET || req.uri().path() != "/" {
                return Access::Pass { set_cookie };
            }
            // The page's URL: the cookie, and the page again without the token.
            let rest: Vec<&str> = req
                .uri()
                .query()
                .unwrap_or("")
                .split('&')
                .filter(|kv| !kv.is_empty() && !kv.starts_with("token="))
                .collect();
            let to = if rest.is_empty() {
                "/".to_owned()
            } else {
                format!("/?{}", rest.join("&"))
            };
            let mut resp = StatusCode::SEE_OTHER.into_response();
            if let Ok(to) = HeaderValue::from_str(&to) {
                resp.headers_mut().insert(header::LOCATION, to);
            }
            if let Some(c) = set_cookie {
                resp.headers_mut().insert(header::SET_COOKIE, c);
            }
            security_headers(&mut resp);
            Access::Answer(resp)
        }
        Some(_) => Access::Pass { set_cookie: None },
    }
}

/// The page may run only its own script and style, load images and sound
/// from itself or from `data:`/`blob:` URLs it made, and talk only to the
/// studio; no other site may frame it.
const CSP: &str = "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; media-src 'self' data: blob:; connect-src 'self' data: blob:; base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

fn security_headers(resp: &mut Response) {
    let h = resp.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
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
        "live": app.live.as_ref().map(|l| json!({ "pipeline": l.name, "has_spectrum": l.has_spectrum })),
        "monitor": app.monitor.is_some(),
    }))
}

/// The monitor's sources and latest events (`--monitor`).
async fn monitor_update(State(app): State<Arc<App>>) -> ApiResult<axum::Json<Value>> {
    match &app.monitor {
        #[cfg(feature = "net")]
        Some(m) => Ok(axum::Json(m.snapshot())),
        #[cfg(not(feature = "net"))]
        Some(m) => match **m {},
        None => Err(ApiError::new(
            StatusCode::NOT_FOUND,
            "no monitor: start the studio with --monitor tcp/HOST:PORT (the endpoint `vibroscope monitor` listens on)",
        )),
    }
}

fn live_of(app: &App) -> ApiResult<Arc<Live>> {
    app.live.clone().ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "no live pipeline: start the studio with --pipeline (for example --pipeline live-spectrum)",
        )
    })
}

async fn live_update(State(app): State<Arc<App>>) -> ApiResult<axum::Json<Value>> {
    let live = live_of(&app)?;
    blocking(move || Ok(axum::Json(live.update()))).await
}

async fn live_frame(State(app): State<Arc<App>>) -> ApiResult<Response> {
    let live = live_of(&app)?;
    let png = blocking(move || match live.latest_frame() {
        None => Err(ApiError::new(
            StatusCode::NOT_FOUND,
            "no frame yet: the live pipeline has not delivered one",
        )),
        Some(f) => encode_png(&f.gray, f.width, f.height, image::ExtendedColorType::L8),
    })
    .await?;
    Ok((
        [
            (header::CONTENT_TYPE, HeaderValue::from_static("image/png")),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-store")),
        ],
        png,
    )
        .into_response())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LiveModeRequest {
    freq_hz: f64,
}

/// The modal image at a frequency from the live pipeline's last
/// [`crate::live::HISTORY_S`] seconds of frames (the `modes` recipe over
/// them, written to a scratch video).
async fn live_mode(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let live = live_of(&app)?;
    let r: LiveModeRequest = body(&b)?;
    check_frequency(r.freq_hz)?;
    let mut v = app.analyses.run(move || {
        let video = vibroscope::files::TempPath::new("studio-live.y4m");
        let (frames, span_s, fps) = live
            .history_video(video.path())
            .map_err(|(io, m)| {
                let status = if io {
                    StatusCode::INTERNAL_SERVER_ERROR
                } else {
                    StatusCode::CONFLICT
                };
                ApiError::new(status, m)
            })?;
        if r.freq_hz > fps / 2.0 {
            return Err(ApiError::unprocessable(format!(
                "frequency {} Hz is above the Nyquist frequency {} Hz (the live frames come at {fps:.1} Hz)",
                r.freq_hz,
                fps / 2.0
            )));
        }
        let mut v = modal_image(video.path(), Some(fps), None, r.freq_hz)?;
        v["frames"] = json!(frames);
        v["span_s"] = json!(span_s);
        v["fps"] = json!(fps);
        Ok(v)
    })
    .await?;
    v["elapsed_ms"] = json!(t0.elapsed().as_secs_f64() * 1e3);
    Ok(axum::Json(v))
}

async fn live_ws(
    State(app): State<Arc<App>>,
    ws: Result<WebSocketUpgrade, axum::extract::ws::rejection::WebSocketUpgradeRejection>,
) -> ApiResult<Response> {
    let live = live_of(&app)?;
    let ws = ws.map_err(|e| ApiError::bad(format!("WebSocket: {}", e.body_text())))?;
    let closing = app.closing.subscribe();
    Ok(ws
        .max_message_size(64 * 1024)
        .on_upgrade(move |socket| live_socket(socket, live, closing)))
}

/// Sends an update whenever a tap has something new, checking every 20 ms:
/// while a send waits on a slow page, newer items replace older ones in
/// the taps, so the page gets the latest, never a backlog.
async fn live_socket(
    mut socket: WebSocket,
    live: Arc<Live>,
    mut closing: tokio::sync::watch::Receiver<bool>,
) {
    let mut tick = tokio::time::interval(std::time::Duration::from_millis(20));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last = None;
    loop {
        tokio::select! {
            _ = tick.tick() => {
                let v = live.version();
                if last == Some(v) {
                    continue;
                }
                last = Some(v);
                let l = live.clone();
                let Ok(update) = tokio::task::spawn_blocking(move || l.update()).await else {
                    break;
                };
                live.sent.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if socket.send(Message::Text(update.to_string().into())).await.is_err() {
                    break;
                }
            }
            m = socket.recv() => match m {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
                Some(Ok(_)) => {}
            },
            _ = closing.changed() => {
                let _ = socket.send(Message::Close(None)).await;
                break;
            }
        }
    }
}

#[derive(Deserialize)]
struct VideoQuery {
    video: String,
    fps: Option<f64>,
    i: Option<u64>,
}

/// Query-string errors as JSON 400s (axum's own rejection is plain text).
fn query<T: serde::de::DeserializeOwned>(
    q: Result<Query<T>, axum::extract::rejection::QueryRejection>,
) -> ApiResult<T> {
    q.map(|Query(v)| v)
        .map_err(|e| ApiError::bad(format!("query: {}", e.body_text())))
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

async fn info(
    State(app): State<Arc<App>>,
    q: Result<Query<VideoQuery>, axum::extract::rejection::QueryRejection>,
) -> ApiResult<axum::Json<Value>> {
    let q = query(q)?;
    let path = guard::resolve(&app.root, &q.video)?;
    let fps = fps_of(&app, q.fps)?;
    let r = app
        .reads
        .run(move || Ok(vibroscope::probe::probe(&path, fps)?))
        .await?;
    let mut v = serde_json::to_value(&r).map_err(|e| ApiError::bad(e.to_string()))?;
    v["video"] = json!(q.video);
    // The file as the page named it, relative to the root.
    v["file"] = json!(q.video);
    Ok(axum::Json(v))
}

async fn frame(
    State(app): State<Arc<App>>,
    q: Result<Query<VideoQuery>, axum::extract::rejection::QueryRejection>,
) -> ApiResult<Response> {
    let q = query(q)?;
    let path = guard::resolve(&app.root, &q.video)?;
    let i = q.i.unwrap_or(0);
    let a = app.clone();
    let png = app.reads.run(move || read_frame_png(&a, &path, i)).await?;
    Ok((
        [(header::CONTENT_TYPE, HeaderValue::from_static("image/png"))],
        png,
    )
        .into_response())
}

/// Frame `i` of `path` as an 8-bit grey PNG (16-bit frames scaled by their
/// declared bit depth); reads forward from the last frame served.
fn read_frame_png(app: &App, path: &Path, i: u64) -> ApiResult<Vec<u8>> {
    let mut slot = app.reader.lock().unwrap_or_else(|p| p.into_inner());
    let reuse = matches!(&*slot, Some((p, next, _)) if p == path && *next <= i);
    if !reuse {
        let r = vibroscope::files::open_video(path, vibroscope::files::Format::Auto)
            .map_err(|e| ApiError::unprocessable(e.to_string()))?;
        *slot = Some((path.to_path_buf(), 0, r));
    }
    let Some((_, next, reader)) = slot.as_mut() else {
        return Err(ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "no reader",
        ));
    };
    let info = reader.info().clone();
    let n = info.width as usize * info.height as usize;
    let mut px8 = vec![0u8; n];
    let mut px16 = vec![0u16; n];
    loop {
        let got = match info.depth {
            vibroscope::files::Depth::U8 => reader.read_frame(FrameDest::U8(&mut px8)),
            vibroscope::files::Depth::U16 => reader.read_frame(FrameDest::U16(&mut px16)),
        };
        let got = got.map_err(|e| {
            *next = u64::MAX;
            ApiError::unprocessable(e.to_string())
        })?;
        if got.is_none() {
            let have = *next;
            *next = u64::MAX;
            return Err(ApiError::new(
                StatusCode::NOT_FOUND,
                format!("frame {i}: the video has {have} frames"),
            ));
        }
        *next += 1;
        if *next > i {
            break;
        }
    }
    if info.depth == vibroscope::files::Depth::U16 {
        vibroscope::files::gray8_from_u16(&px16, info.bits, &mut px8);
    }
    encode_png(&px8, info.width, info.height, image::ExtendedColorType::L8)
}

fn encode_png(px: &[u8], w: u32, h: u32, ty: image::ExtendedColorType) -> ApiResult<Vec<u8>> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(px, w, h, ty)
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, format!("PNG: {e}")))?;
    Ok(png)
}

/// A JSON body, or 400 naming what is wrong (bodies over the bound were
/// refused with 413 before this).
fn body<T: serde::de::DeserializeOwned>(b: &Bytes) -> ApiResult<T> {
    serde_json::from_slice(b).map_err(|e| ApiError::bad(format!("request body: {e}")))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionRequest {
    video: String,
    /// `[x, y, w, h]`; none: the whole frame.
    roi: Option<[u32; 4]>,
    fps: Option<f64>,
    /// Millimetres per pixel on the object: the motion is then also given
    /// in µm or mm (as `--scale`).
    scale_mm_per_px: Option<f64>,
    /// A mask painted on the frame: a PNG the frame's size (a `data:` URL
    /// or bare base64), pixels > 0 inside; with `roi`, both must hold.
    mask: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModeRequest {
    video: String,
    freq_hz: f64,
    roi: Option<[u32; 4]>,
    fps: Option<f64>,
    scale_mm_per_px: Option<f64>,
}

/// The request's scale, checked as `--scale` is.
fn scale_of(mm_per_px: Option<f64>) -> ApiResult<Option<vibroscope::units::Scale>> {
    mm_per_px
        .map(|v| {
            vibroscope::units::ScaleArg::MmPerPx(v)
                .resolve(u32::MAX, u32::MAX)
                .map_err(|e| ApiError::unprocessable(format!("scale_mm_per_px: {}", e.message)))
        })
        .transpose()
}

/// A unit for values up to `largest_px` pixels and the factor from pixels
/// to it (the library's choice: µm below 1 mm, else mm; px without a
/// scale).
fn unit_for(scale: Option<&vibroscope::units::Scale>, largest_px: f64) -> (String, f64) {
    use vibroscope::units::{px_to, Quantity, Scale};
    let unit = Scale::unit(scale, Quantity::Displacement, largest_px);
    (unit.to_string(), px_to(unit, scale))
}

/// Adds the motion in the scale's unit to a region's answer: the
/// waveform's `x`, `y` and `unit`, each peak's `amplitude` and the peaks'
/// `amplitude_unit` (the same numbers in px without a scale).
fn with_units(v: &mut Value, scale: Option<&vibroscope::units::Scale>) {
    let nums = |a: &Value| -> Vec<f64> {
        a.as_array()
            .map(|a| a.iter().filter_map(Value::as_f64).collect())
            .unwrap_or_default()
    };
    let largest = |a: &[f64]| a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (x, y) = (nums(&v["waveform"]["x_px"]), nums(&v["waveform"]["y_px"]));
    let (unit, k) = unit_for(scale, largest(&x).max(largest(&y)));
    let conv = |a: &[f64]| a.iter().map(|p| p * k).collect::<Vec<f64>>();
    v["waveform"]["x"] = json!(conv(&x));
    v["waveform"]["y"] = json!(conv(&y));
    v["waveform"]["unit"] = json!(unit);
    let amps: Vec<f64> = v["peaks"]
        .as_array()
        .map(|p| {
            p.iter()
                .filter_map(|p| p["amplitude_px"].as_f64())
                .collect()
        })
        .unwrap_or_default();
    let (unit, k) = unit_for(scale, largest(&amps));
    if let Some(peaks) = v["peaks"].as_array_mut() {
        for p in peaks {
            if let Some(a) = p["amplitude_px"].as_f64() {
                p["amplitude"] = json!(a * k);
            }
        }
    }
    v["amplitude_unit"] = json!(unit);
    v["scale_mm_per_px"] = json!(scale.map(|s| s.mm_per_px));
}

/// The video's size and rate, and `roi` checked against the frame and
/// against the work a request may ask for (`max_pixel_frames`: region x
/// frames).
fn check_roi(
    path: &Path,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    max_pixel_frames: u64,
) -> ApiResult<(vibroscope::probe::ProbeReport, [u32; 4])> {
    let p = vibroscope::probe::probe(path, fps)?;
    let r = roi.unwrap_or([0, 0, p.width, p.height]);
    let [x, y, w, h] = r.map(u64::from);
    if w < 8 || h < 8 || x + w > u64::from(p.width) || y + h > u64::from(p.height) {
        return Err(ApiError::unprocessable(format!(
            "region {x},{y},{w},{h} is not inside the {}x{} frame (or smaller than 8x8)",
            p.width, p.height
        )));
    }
    limits::check_work(w, h, p.frames, max_pixel_frames)?;
    Ok((p, r))
}

/// A cache key naming the file's identity (path, size, modification time).
fn file_key(path: &Path) -> String {
    let meta = std::fs::metadata(path).ok();
    let len = meta.as_ref().map_or(0, |m| m.len());
    let mtime = meta
        .and_then(|m| m.modified().ok())
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    format!("{}|{len}|{mtime}", path.display())
}

fn cached(app: &App, key: &str) -> Option<Arc<Value>> {
    app.cache
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .get(key)
        .cloned()
}

fn remember(app: &App, key: String, v: Value) -> Arc<Value> {
    let v = Arc::new(v);
    let mut c = app.cache.lock().unwrap_or_else(|p| p.into_inner());
    if c.len() >= CACHE_ENTRIES {
        c.clear();
    }
    c.insert(key, v.clone());
    v
}

/// A cached answer's field that stays on the server: the motion signal
/// the region's spectrum was computed from (the damping view's SSI).
const PRIVATE_MOTION: &str = "_motion";

/// A computed answer's mark: send it, do not keep it (too large).
pub(crate) const PRIVATE_NO_CACHE: &str = "_no_cache";

/// Answers from the cache, marking them so (`"cached": true`).
fn answer(v: &Value, cached: bool, ms: f64) -> axum::Json<Value> {
    let mut v = v.clone();
    if let Some(o) = v.as_object_mut() {
        o.remove(PRIVATE_MOTION);
    }
    v["cached"] = json!(cached);
    v["elapsed_ms"] = json!(ms);
    axum::Json(v)
}

async fn motion(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let r: MotionRequest = body(&b)?;
    let scale = scale_of(r.scale_mm_per_px)?;
    let axum::Json(mut v) = region_answer(app, &b, "motion", region_motion).await?;
    with_units(&mut v, scale.as_ref());
    Ok(axum::Json(v))
}

/// A recipe over a region: (video, fps, region as requested, region or the
/// whole frame, the video's probe) to its JSON answer.
type RegionRecipe = fn(&Path, Option<f64>, &Selection) -> ApiResult<Value>;

/// A region as the recipes take it, checked against the recording.
pub(crate) struct Selection {
    pub(crate) probe: vibroscope::probe::ProbeReport,
    /// The rectangle analysed: as given, else the mask's bounding box, else
    /// none (the whole frame).
    roi: Option<[u32; 4]>,
    /// The rectangle the waveform is measured over (`roi` or the frame).
    pub(crate) whole: [u32; 4],
    /// The painted mask, written to a scratch PNG, and its pixels inside.
    mask: Option<(vibroscope::files::TempPath, u64)>,
}

impl Selection {
    pub(crate) fn region(&self) -> Region {
        Region {
            roi: self.roi.map(|[x, y, w, h]| Roi { x, y, w, h }),
            mask: self.mask_path(),
            ..Region::default()
        }
    }

    fn mask_path(&self) -> Option<PathBuf> {
        self.mask.as_ref().map(|(t, _)| t.path().to_path_buf())
    }

    /// Facts of the selection for its answer.
    fn describe(&self, v: &mut Value) {
        v["roi"] = json!(self.roi);
        v["mask_pixels"] = json!(self.mask.as_ref().map(|(_, n)| n));
    }
}

/// At least this many mask pixels inside the region.
const MIN_MASK_PIXELS: u64 = 16;

/// `roi` and a painted `mask` checked against the recording `path`.
fn select(
    path: &Path,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    mask: Option<&str>,
    max_pixel_frames: u64,
) -> ApiResult<Selection> {
    let (probe, whole) = check_roi(path, fps, roi, max_pixel_frames)?;
    let Some(mask) = mask else {
        return Ok(Selection {
            probe,
            roi,
            whole,
            mask: None,
        });
    };
    let b64 = mask.strip_prefix("data:image/png;base64,").unwrap_or(mask);
    let bytes = base64_decode(b64)
        .ok_or_else(|| ApiError::bad("mask: not base64 (send the PNG as a data: URL)"))?;
    let m = vibroscope::live::Mask::decode(&bytes, Path::new("mask"))
        .map_err(ApiError::unprocessable)?;
    if (m.width, m.height) != (probe.width as usize, probe.height as usize) {
        return Err(ApiError::unprocessable(format!(
            "mask: {}x{}, but the frames are {}x{}",
            m.width, m.height, probe.width, probe.height
        )));
    }
    let [x, y, w, h] = whole.map(|v| v as usize);
    let inside = (y..y + h)
        .flat_map(|yy| (x..x + w).map(move |xx| (xx, yy)))
        .filter(|&(xx, yy)| m.at(xx, yy))
        .count() as u64;
    if inside < MIN_MASK_PIXELS {
        return Err(ApiError::unprocessable(format!(
            "mask: {inside} painted pixels inside the region; paint at least {MIN_MASK_PIXELS}"
        )));
    }
    // Without a rectangle: the mask's bounding box, at least 8x8.
    let roi = roi.unwrap_or_else(|| {
        let b = m.bounds();
        let grow = |start: usize, len: usize, size: u32| -> (u32, u32) {
            let size = size as usize;
            let len2 = len.max(8).min(size);
            let start2 = start.saturating_sub((len2 - len) / 2).min(size - len2);
            (start2 as u32, len2 as u32)
        };
        let (bx, bw) = grow(b.x, b.w, probe.width);
        let (by, bh) = grow(b.y, b.h, probe.height);
        [bx, by, bw, bh]
    });
    let file = vibroscope::files::TempPath::new("studio-mask.png");
    std::fs::write(file.path(), &bytes).map_err(|e| {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the mask's scratch file: {e}"),
        )
    })?;
    Ok(Selection {
        probe,
        roi: Some(roi),
        whole: roi,
        mask: Some((file, inside)),
    })
}

/// A region's answer (`what`: its cache key's tag) for a [`MotionRequest`]:
/// from the cache, or `compute(path, fps, roi as given, roi or the whole
/// frame, probe)` once the region is checked against the frame.
async fn region_answer(
    app: Arc<App>,
    b: &Bytes,
    what: &'static str,
    compute: RegionRecipe,
) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: MotionRequest = body(b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let key = region_key(what, &path, r.roi, r.mask.as_deref(), fps);
    let queue = app.clone();
    let (v, was_cached) = queue
        .analyses
        .run(move || {
            region_cached(
                &app,
                key,
                &path,
                fps,
                (r.roi, r.mask.as_deref()),
                compute,
                |_| Ok(()),
            )
        })
        .await?;
    Ok(answer(&v, was_cached, t0.elapsed().as_secs_f64() * 1e3))
}

/// A region's answer kept under `key` (and whether it was), else computed
/// by `compute` over the selection (`roi`, `mask`) once `check` accepts
/// it, and kept. Blocking: call it through [`blocking`].
fn region_cached(
    app: &App,
    key: String,
    path: &Path,
    fps: Option<f64>,
    (roi, mask): (Option<[u32; 4]>, Option<&str>),
    compute: impl FnOnce(&Path, Option<f64>, &Selection) -> ApiResult<Value>,
    check: impl FnOnce(&Selection) -> ApiResult<()>,
) -> ApiResult<(Arc<Value>, bool)> {
    if let Some(v) = cached(app, &key) {
        return Ok((v, true));
    }
    let sel = select(path, fps, roi, mask, app.max_pixel_frames)?;
    check(&sel)?;
    let mut v = compute(path, fps, &sel)?;
    sel.describe(&mut v);
    if let Some(o) = v.as_object_mut() {
        if o.remove(PRIVATE_NO_CACHE).is_some() {
            return Ok((Arc::new(v), false));
        }
    }
    Ok((remember(app, key, v), false))
}

/// The cache key of a region's answer (`what`: its recipe's tag).
fn region_key(
    what: &str,
    path: &Path,
    roi: Option<[u32; 4]>,
    mask: Option<&str>,
    fps: Option<f64>,
) -> String {
    use std::hash::{Hash, Hasher};
    let mask = mask.map(|m| {
        let mut h = std::hash::DefaultHasher::new();
        m.hash(&mut h);
        (h.finish(), m.len())
    });
    format!("{what}|{}|{roi:?}|{mask:?}|{fps:?}", file_key(path))
}

/// The damping request's fields that name its range, in its errors.
const RANGE_FIELDS: &str = "lo_hz/hi_hz";

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DampingRequest {
    video: String,
    roi: Option<[u32; 4]>,
    mask: Option<String>,
    fps: Option<f64>,
    lo_hz: f64,
    hi_hz: f64,
}

/// The damping view (thesis 5.4.2) over a dragged range of a region's
/// spectrum: the region's answer (cached, or computed and kept), then the
/// Lorentzian over the range and SSI's poles for it
/// ([`vibroscope::damping::damping_over`]).
async fn damping(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: DampingRequest = body(&b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let key = region_key("motion", &path, r.roi, r.mask.as_deref(), fps);
    let queue = app.clone();
    let v = queue
        .analyses
        .run(move || {
            // A range the recording cannot have is refused before the work.
            let check = |sel: &Selection| match sel.probe.fps {
                Some(rate) => Ok(vibroscope::damping::check_range(
                    (r.lo_hz, r.hi_hz),
                    rate,
                    RANGE_FIELDS,
                )?),
                None => Ok(()),
            };
            let sel = (r.roi, r.mask.as_deref());
            let (m, _) = region_cached(&app, key, &path, fps, sel, region_motion, check)?;
            let internal = |what: &str| {
                ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("the region's {what} is missing"),
                )
            };
            let sp: vibroscope::peaks::SpectrumDb =
                serde_json::from_value(m["spectrum"].clone()).map_err(|_| internal("spectrum"))?;
            let motion: Vec<f64> = serde_json::from_value(m[PRIVATE_MOTION].clone())
                .map_err(|_| internal("motion"))?;
            let fs = m["sample_rate_hz"]
                .as_f64()
                .ok_or_else(|| internal("sample rate"))?;
            let d = vibroscope::damping::damping_over(
                &sp,
                fs,
                m["taper"].as_str(),
                &motion,
                (r.lo_hz, r.hi_hz),
                RANGE_FIELDS,
            )?;
            Ok(json!({ "roi": r.roi, "sample_rate_hz": fs, "damping": d }))
        })
        .await?;
    Ok(answer(&v, false, t0.elapsed().as_secs_f64() * 1e3))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BasisRequest {
    video: String,
    roi: Option<[u32; 4]>,
    mask: Option<String>,
    fps: Option<f64>,
    /// `auto` (default) or `F1,F2,LO-HI` (Hz), as `vibroscope idv --modes`.
    modes: Option<String>,
    /// At most this many modes with `auto` (default 8).
    max_modes: Option<usize>,
}

/// The region's image-space modal basis ([`idv`]): cached per
/// video, region, rate and modes like the other region answers; a basis
/// whose answer would be too large is refused before the work.
async fn idv_basis(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: BasisRequest = body(&b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let choice = idv::Choice::parse(r.modes.as_deref(), r.max_modes)?;
    let tag = format!("idv-basis|{}|{}", choice.text, choice.max_modes);
    let key = region_key(&tag, &path, r.roi, r.mask.as_deref(), fps);
    let queue = app.clone();
    let (v, was_cached) = queue
        .analyses
        .run(move || {
            let c2 = choice.clone();
            let name = r.video.clone();
            region_cached(
                &app,
                key,
                &path,
                fps,
                (r.roi, r.mask.as_deref()),
                move |p, f, sel| {
                    let mut v = idv::basis_answer(&name, p, f, sel, &c2)?;
                    if v["payload_bytes"].as_u64().unwrap_or(u64::MAX) > idv::MAX_CACHED_PAYLOAD {
                        v[PRIVATE_NO_CACHE] = json!(true);
                    }
                    Ok(v)
                },
                |sel| choice.check_size(sel),
            )
        })
        .await?;
    Ok(answer(&v, was_cached, t0.elapsed().as_secs_f64() * 1e3))
}

/// The spectrum recipe (its peaks with damping and uncertainty) and the
/// region's displacement, from one run over the recording.
fn region_motion(path: &Path, fps: Option<f64>, sel: &Selection) -> ApiResult<Value> {
    let mut o = SpectrumOptions::new(path, "studio-unused.json");
    o.fps = fps;
    o.peaks = 8;
    o.include_spectrum = true;
    o.region = sel.region();
    // The motion the spectrum came from, kept for the damping view's SSI.
    let wav = vibroscope::files::TempPath::new("studio-motion.wav");
    o.motion_wav = Some(wav.path().to_path_buf());
    let tap = DisplacementTap::new(vec![sel.whole]).with_mask(sel.mask_path());
    let (report, _run) = vibroscope::spectrum::run_spectrum_with(&o, true, Some(&tap))?;
    let (_, signal) = vibroscope::files::read_wav_mono(wav.path()).map_err(|e| {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the region's motion WAV: {e}"),
        )
    })?;
    let regions = tap.read()?;
    let m = regions.into_iter().next().unwrap_or_default();
    let freqs: Vec<f64> = report.peaks.iter().map(|p| p.frequency_hz).collect();
    let (amps, _) = vibroscope::motion::peak_amplitudes(
        &freqs,
        report.resolution_hz,
        &m,
        None,
        vibroscope::units::Quantity::Displacement,
    );
    let peaks: Vec<Value> = report
        .peaks
        .iter()
        .zip(amps)
        .map(|(p, a)| {
            json!({
                "frequency_hz": p.frequency_hz,
                "frequency_std_hz": p.frequency_std_hz,
                "damping_ratio": p.damping_ratio,
                "damping_ratio_std": p.damping_ratio_std,
                "damping_method": p.damping_method,
                "prominence_db": p.prominence_db,
                "false_alarm": p.false_alarm,
                "floor_db": p.floor_db,
                "power_db": p.power_db,
                "resolved": p.resolved,
                "amplitude_px": a,
            })
        })
        .collect();
    let mut v = json!({
        "sample_rate_hz": report.sample_rate_hz,
        "resolution_hz": report.resolution_hz,
        "spectrum": report.spectrum,
        "taper": report.taper,
        "peaks": peaks,
        // What the resonance test turned away, with why (issue 51).
        "others": report.others.iter().map(|p| json!({
            "frequency_hz": p.frequency_hz,
            "class": p.class,
            "class_reason": p.class_reason,
        })).collect::<Vec<Value>>(),
        "waveform": { "rate_hz": m.rate_hz, "t_s": m.t_s, "x_px": m.x, "y_px": m.y },
    });
    // Kept on the server, not sent (see `answer`).
    v[PRIVATE_MOTION] = json!(signal);
    Ok(v)
}

async fn mode(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: ModeRequest = body(&b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let scale = scale_of(r.scale_mm_per_px)?;
    check_frequency(r.freq_hz)?;
    let key = format!(
        "mode|{}|{:?}|{fps:?}|{}",
        file_key(&path),
        r.roi,
        r.freq_hz.to_bits()
    );
    if let Some(v) = cached(&app, &key) {
        let axum::Json(mut v) = answer(&v, true, t0.elapsed().as_secs_f64() * 1e3);
        mode_units(&mut v, scale.as_ref());
        return Ok(axum::Json(v));
    }
    let app2 = app.clone();
    let v = app
        .analyses
        .run(move || {
            let (p, roi) = check_roi(&path, fps, r.roi, app2.max_pixel_frames)?;
            let rate = p.fps.ok_or_else(|| {
                ApiError::unprocessable("the video states no frame rate: give fps")
            })?;
            if r.freq_hz > rate / 2.0 {
                return Err(ApiError::unprocessable(format!(
                    "frequency {} Hz is above the Nyquist frequency {} Hz (frame rate {rate} Hz)",
                    r.freq_hz,
                    rate / 2.0
                )));
            }
            let v = modal_image(&path, fps, r.roi.map(|_| roi), r.freq_hz)?;
            Ok(remember(&app2, key, v))
        })
        .await?;
    let axum::Json(mut v) = answer(&v, false, t0.elapsed().as_secs_f64() * 1e3);
    mode_units(&mut v, scale.as_ref());
    Ok(axum::Json(v))
}

/// A modal image's largest amplitude in the scale's unit (`max_amplitude`,
/// `amplitude_unit`).
fn mode_units(v: &mut Value, scale: Option<&vibroscope::units::Scale>) {
    let max = v["max_amplitude_px"].as_f64().unwrap_or(0.0);
    let (unit, k) = unit_for(scale, max);
    v["max_amplitude"] = json!(max * k);
    v["amplitude_unit"] = json!(unit);
}

/// The playback rate of a region's sound: a standard rate every browser
/// decodes, well above twice any frame rate a region's motion is sampled at
/// by the cameras we read (up to 4 kHz of motion).
const LISTEN_RATE_HZ: u32 = 8000;
/// The lowest frame rate the studio makes a sound from: below it the
/// sound's content, which ends at half the frame rate, is all under 10 Hz,
/// below hearing (the motion view shows slow vibration). A rate a request
/// can set also bounds the work: the sound lasts frames / fps.
const MIN_LISTEN_FPS: f64 = 20.0;
/// The longest sound the studio makes: its WAV, sent in the answer, is then
/// at most 9.6 MB (`vibroscope listen` has no such limit).
const MAX_LISTEN_S: f64 = 600.0;

async fn listen(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    region_answer(app, &b, "listen", region_sound).await
}

/// The `listen` recipe on a region (16-bit WAV at [`LISTEN_RATE_HZ`]), and
/// the sound's spectrogram up to half the frame rate (where the motion's
/// content ends) in dB.
fn region_sound(path: &Path, fps: Option<f64>, sel: &Selection) -> ApiResult<Value> {
    let frame_rate = sel.probe.fps;
    if let Some(rate) = frame_rate {
        if rate < MIN_LISTEN_FPS {
            return Err(ApiError::unprocessable(format!(
                "fps {rate}: a sound needs at least {MIN_LISTEN_FPS} frames per second (its content ends at half the frame rate, {} Hz here, below hearing); the motion view shows slow vibration",
                rate / 2.0
            )));
        }
        if let Some(frames) = sel.probe.frames {
            let seconds = frames as f64 / rate;
            if seconds > MAX_LISTEN_S {
                return Err(ApiError::unprocessable(format!(
                    "{frames} frames at fps {rate} make {seconds:.0} s of sound; the studio plays at most {MAX_LISTEN_S} s (use `vibroscope listen` for longer recordings)"
                )));
            }
        }
    }
    let wav = vibroscope::files::TempPath::new("studio-listen.wav");
    let o = vibroscope::listen::ListenOptions {
        video: path.to_path_buf(),
        output: wav.path().to_path_buf(),
        fps,
        region: sel.region(),
        method: None,
        sources: None,
        denoise: Default::default(),
        speaker: None,
        calibration: None,
        rolling_shutter: None,
        filters: Vec::new(),
        rate: vibroscope::listen::OutputRate::Hz(LISTEN_RATE_HZ),
        float: false,
        run: Default::default(),
    };
    let report = vibroscope::listen::listen(&o)?;
    let internal = |m: String| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, m);
    let bytes = std::fs::read(wav.path()).map_err(|e| internal(format!("the sound's WAV: {e}")))?;
    let (rate, x) = vibroscope::files::read_wav_mono(wav.path())
        .map_err(|e| internal(format!("the sound's WAV: {e}")))?;
    let rate = f64::from(rate);
    // Bins up to half the frame rate, about 64 of them; windows overlap 3/4.
    let top = frame_rate.map_or(rate / 2.0, |f| (f / 2.0).min(rate / 2.0));
    let nfft = ((rate / top * 64.0).ceil() as usize)
        .next_power_of_two()
        .clamp(64, 1 << 16);
    let hop = (nfft / 4).max(1);
    let bin_hz = rate / nfft as f64;
    let bins = ((top / bin_hz).floor() as usize + 1).min(nfft / 2 + 1);
    let columns: Vec<Vec<f32>> = vibroscope::spectrum::stft(&x, nfft, hop)
        .iter()
        .map(|col| {
            col[..bins]
                .iter()
                .map(|c| (10.0 * c.norm_sqr().max(1e-30).log10()) as f32)
                .collect()
        })
        .collect();
    Ok(json!({
        "sample_rate_hz": report.sample_rate_hz,
        "samples": report.samples,
        "duration_s": report.samples as f64 / rate,
        "encoding": report.encoding,
        "notes": report.notes,
        "wav": format!("data:audio/wav;base64,{}", base64(&bytes)),
        "spectrogram": {
            "nfft": nfft,
            "hop_s": hop as f64 / rate,
            "bin_hz": bin_hz,
            "top_hz": top,
            "db": columns,
        },
    }))
}

/// Refuses a modal image's frequency at or below 0 Hz (or not a number).
fn check_frequency(freq_hz: f64) -> ApiResult<()> {
    if freq_hz.is_finite() && freq_hz > 0.0 {
        return Ok(());
    }
    Err(ApiError::unprocessable(format!(
        "frequency {freq_hz} Hz: must be above 0"
    )))
}

/// The modes recipe's PNG and complex image (phase aligned as the PNG's
/// hue is), as base64 PNG and amplitude/phase arrays.
fn modal_image(
    path: &Path,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    freq_hz: f64,
) -> ApiResult<Value> {
    let png = vibroscope::files::TempPath::new("studio-mode.png");
    let npy = vibroscope::files::TempPath::new("studio-mode.npy");
    let o = ModesOptions {
        video: path.to_path_buf(),
        at_hz: freq_hz,
        output: png.path().to_path_buf(),
        npy: Some(npy.path().to_path_buf()),
        fps,
        region: Region {
            roi: roi.map(|[x, y, w, h]| Roi { x, y, w, h }),
            ..Region::default()
        },
        ..ModesOptions::default()
    };
    vibroscope::modes::modes(&o)?;
    let internal = |m: String| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, m);
    let png_bytes =
        std::fs::read(png.path()).map_err(|e| internal(format!("modal image PNG: {e}")))?;
    let npy_bytes =
        std::fs::read(npy.path()).map_err(|e| internal(format!("modal image npy: {e}")))?;
    let (h, w, data) =
        read_npy_complex64(&npy_bytes).map_err(|e| internal(format!("modal image npy: {e}")))?;
    let data = align_phase(&data);
    let amplitude: Vec<f32> = data.iter().map(|c| c.norm()).collect();
    let phase: Vec<f32> = data.iter().map(|c| c.arg()).collect();
    let max = amplitude.iter().copied().fold(0.0f32, f32::max);
    Ok(json!({
        "freq_hz": freq_hz,
        "roi": roi,
        "width": w,
        "height": h,
        "max_amplitude_px": max,
        "amplitude_px": amplitude,
        "phase_rad": phase,
        "png": format!("data:image/png;base64,{}", base64(&png_bytes)),
    }))
}

/// Standard base64 with padding.
pub fn base64(b: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(b.len().div_ceil(3) * 4);
    for c in b.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Standard base64 (padding optional, no whitespace) decoded; `None` for
/// anything else.
pub fn base64_decode(s: &str) -> Option<Vec<u8>> {
    let s = s.trim_end_matches('=').as_bytes();
    let val = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    if s.len() % 4 == 1 {
        return None;
    }
    let mut out = Vec::with_capacity(s.len() / 4 * 3 + 2);
    for c in s.chunks(4) {
        let mut n = 0u32;
        for (k, &ch) in c.iter().enumerate() {
            n |= val(ch)? << (18 - 6 * k);
        }
        let bytes = n.to_be_bytes();
        out.extend_from_slice(&bytes[1..c.len()]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::{base64, base64_decode};

    #[test]
    fn base64_decodes_what_it_encodes() {
        for n in 0..40u8 {
            let b: Vec<u8> = (0..n).map(|k| k.wrapping_mul(97).wrapping_add(n)).collect();
            assert_eq!(base64_decode(&base64(&b)).as_deref(), Some(&b[..]));
        }
        assert_eq!(base64_decode("Zm9vYg").as_deref(), Some(&b"foob"[..]));
        assert_eq!(base64_decode("Zm9v!mFy"), None);
        assert_eq!(base64_decode("Z"), None);
    }

    #[test]
    fn base64_matches_the_rfc_examples() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }
}
