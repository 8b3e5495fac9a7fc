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
use crate::live::{Live, Retune};

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

/// The magnified view of a live pipeline with a `magnify` stage.
fn magnify_of(live: &Live) -> ApiResult<&crate::live::MagnifyView> {
    live.magnify.as_ref().ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            format!(
                "the live pipeline {} has no magnify stage (try --pipeline live-magnify)",
                live.name
            ),
        )
    })
}

/// The latest magnified frame as an 8-bit grey PNG (its frame number in
/// `X-Frame`).
pub(super) async fn live_magnified(State(app): State<Arc<App>>) -> ApiResult<Response> {
    let live = live_of(&app)?;
    let (frame, png) = blocking(move || {
        let m = magnify_of(&live)?;
        match m.latest() {
            None => Err(ApiError::new(
                StatusCode::NOT_FOUND,
                "no magnified frame yet: the magnify stage has not delivered one",
            )),
            Some((_, f)) => Ok((
                f.seq,
                encode_png(&f.gray, f.width, f.height, image::ExtendedColorType::L8)?,
            )),
        }
    })
    .await?;
    let mut r = (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static("image/png")),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-store")),
        ],
        png,
    )
        .into_response();
    r.headers_mut().insert("x-frame", HeaderValue::from(frame));
    Ok(r)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MagnifyRequest {
    lo_hz: f64,
    hi_hz: f64,
    factor: f64,
}

/// Changes the magnified view's band and factor: the `magnify` stage
/// starts its magnifier over at its next frame with them. Answers the
/// frame they took effect at, 422 with the stage's reason when refused,
/// 202 when no frame came within 3 s (the stage takes them at its next).
pub(super) async fn live_magnify(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<Response> {
    let live = live_of(&app)?;
    let r: MagnifyRequest = body(&b)?;
    let res = blocking(move || {
        let m = magnify_of(&live)?;
        Ok(m.retune(
            r.lo_hz,
            r.hi_hz,
            r.factor,
            std::time::Duration::from_secs(3),
        ))
    })
    .await?;
    let v = json!({ "lo_hz": r.lo_hz, "hi_hz": r.hi_hz, "factor": r.factor });
    match res {
        Retune::Applied(frame) => {
            let mut v = v;
            v["since_frame"] = json!(frame);
            Ok(axum::Json(v).into_response())
        }
        Retune::Refused(m) => Err(ApiError::unprocessable(format!(
            "the magnify stage kept its band and factor: {m}"
        ))),
        Retune::Pending => {
            let mut v = v;
            v["pending"] = json!(true);
            Ok((StatusCode::ACCEPTED, axum::Json(v)).into_response())
        }
    }
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

/// Bytes before the pixels of a magnified frame sent on the WebSocket:
/// `VMAG`, width and height (u32), the frame's number (u64) and capture
/// time (i64 ns), little-endian.
pub const MAGNIFIED_HEADER: usize = 28;

/// A magnified frame as one binary WebSocket message (see
/// [`MAGNIFIED_HEADER`]), 8-bit grey pixels row by row after the header.
fn magnified_message(f: &vibroscope::live::TapFrame) -> Vec<u8> {
    let mut b = Vec::with_capacity(MAGNIFIED_HEADER + f.gray.len());
    b.extend_from_slice(b"VMAG");
    b.extend_from_slice(&f.width.to_le_bytes());
    b.extend_from_slice(&f.height.to_le_bytes());
    b.extend_from_slice(&f.seq.to_le_bytes());
    b.extend_from_slice(&f.t_ns.to_le_bytes());
    b.extend_from_slice(&f.gray);
    b
}

/// Sends an update whenever a tap has something new, checking every 20 ms
/// (every 5 ms with a magnified view, each new magnified frame as a binary
/// message): while a send waits on a slow page, newer items replace older
/// ones in the taps, so the page gets the latest, never a backlog.
async fn live_socket(
    mut socket: WebSocket,
    live: Arc<Live>,
    mut closing: tokio::sync::watch::Receiver<bool>,
) {
    let every = if live.magnify.is_some() { 5 } else { 20 };
    let mut tick = tokio::time::interval(std::time::Duration::from_millis(every));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last = None;
    let mut last_magnified = 0;
    loop {
        tokio::select! {
            _ = tick.tick() => {
                if let Some(m) = &live.magnify {
                    if m.seq() != last_magnified {
                        let l = live.clone();
                        // Copied out and framed off the async threads.
                        let Ok(frame) = tokio::task::spawn_blocking(move || {
                            let (seq, f) = l.magnify.as_ref()?.latest()?;
                            Some((seq, magnified_message(&f)))
                        }).await else {
                            break;
                        };
                        if let Some((seq, message)) = frame {
                            last_magnified = seq;
                            if socket.send(Message::Binary(message.into())).await.is_err() {
                                break;
                            }
                        }
                    }
                }
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
