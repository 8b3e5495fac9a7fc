//! The modal image at a frequency: the mode endpoint, and the image (PNG, amplitude and
//! phase) it and the live view answer with.

use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use serde::Deserialize;
use serde_json::{json, Value};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use vibroscope::modes::ModesOptions;
use vibroscope::modes::{align_phase, read_npy_complex64};
use vibroscope::pipeline::{Region, Roi};

use super::base64::base64;
use super::cache::{answer, cached, file_key, remember};
use super::selection::check_roi;
use super::units::{mode_units, scale_of};
use super::{body, fps_of, ApiError, ApiResult, App};
use crate::guard;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModeRequest {
    video: String,
    freq_hz: f64,
    roi: Option<[u32; 4]>,
    fps: Option<f64>,
    scale_mm_per_px: Option<f64>,
}

pub(super) async fn mode(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
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

/// Refuses a modal image's frequency at or below 0 Hz (or not a number).
pub(super) fn check_frequency(freq_hz: f64) -> ApiResult<()> {
    if freq_hz.is_finite() && freq_hz > 0.0 {
        return Ok(());
    }
    Err(ApiError::unprocessable(format!(
        "frequency {freq_hz} Hz: must be above 0"
    )))
}

/// The modes recipe's PNG and complex image (phase aligned as the PNG's
/// hue is), as base64 PNG and amplitude/phase arrays.
pub(super) fn modal_image(
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
