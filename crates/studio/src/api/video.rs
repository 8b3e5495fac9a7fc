//! The recording's own endpoints: its facts (`/api/info`) and its frames as 8-bit grey
//! PNG (`/api/frame`), read forward from the last frame served, with the PNG encoder the
//! live frame shares.

use axum::extract::{Query, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{json, Value};
use std::path::Path;
use std::sync::Arc;
use vibroscope::files::FrameDest;

use super::{fps_of, ApiError, ApiResult, App};
use crate::guard;

#[derive(Deserialize)]
pub(super) struct VideoQuery {
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

pub(super) async fn info(
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

pub(super) async fn frame(
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

pub(super) fn encode_png(
    px: &[u8],
    w: u32,
    h: u32,
    ty: image::ExtendedColorType,
) -> ApiResult<Vec<u8>> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(px, w, h, ty)
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, format!("PNG: {e}")))?;
    Ok(png)
}
