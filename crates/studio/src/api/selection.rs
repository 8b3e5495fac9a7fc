//! A region of the recording as the recipes take it: the rectangle and the painted mask
//! checked against the frame and against the work a request may ask for.

use axum::http::StatusCode;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use vibroscope::pipeline::{Region, Roi};

use super::base64::base64_decode;
use super::{ApiError, ApiResult};
use crate::limits;

/// The video's size and rate, and `roi` checked against the frame and
/// against the work a request may ask for (`max_pixel_frames`: region x
/// frames).
pub(super) fn check_roi(
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

    pub(super) fn mask_path(&self) -> Option<PathBuf> {
        self.mask.as_ref().map(|(t, _)| t.path().to_path_buf())
    }

    /// Facts of the selection for its answer.
    pub(super) fn describe(&self, v: &mut Value) {
        v["roi"] = json!(self.roi);
        v["mask_pixels"] = json!(self.mask.as_ref().map(|(_, n)| n));
    }
}

/// At least this many mask pixels inside the region.
const MIN_MASK_PIXELS: u64 = 16;

/// `roi` and a painted `mask` checked against the recording `path`.
pub(super) fn select(
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
