//! The live endpoints: the live pipeline's latest update, frame and WebSocket, the modal
//! image from its recent frames, and a monitor's events.

use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{json, Value};
use std::sync::Arc;
use std::time::Instant;

use super::modal::{check_frequency, modal_image};
use super::video::encode_png;
use super::{blocking, body, ApiError, ApiResult, App};
use crate::live::Live;

/// The monitor's sources and latest events (`--monitor`).
pub(super) async fn monitor_update(State(app): State<Arc<App>>) -> ApiResult<axum::Json<Value>> {
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

pub(super) async fn live_update(State(app): State<Arc<App>>) -> ApiResult<axum::Json<Value>> {
    let live = live_of(&app)?;
    blocking(move || Ok(axum::Json(live.update()))).await
}

pub(super) async fn live_frame(State(app): State<Arc<App>>) -> ApiResult<Response> {
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
pub(super) async fn live_mode(
    State(app): State<Arc<App>>,
    b: Bytes,
) -> ApiResult<axum::Json<Value>> {
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

pub(super) async fn live_ws(
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
