//! Interactive dynamic video in the page (issue 17, thesis ch. 6): the
//! image-space modal basis of a region, measured by
//! [`vibroscope::idv::extract_basis`] and sent in a form the page renders
//! from (the page simulates and warps; nothing is rendered here).
//!
//! The answer of `POST /api/idv/basis`:
//!
//! ```json
//! {"width": W, "height": H, "fps": F, "box": [x, y, w, h],
//!  "rest": "<base64: W*H bytes, the rest frame, 8-bit grey, row-major>",
//!  "layout": "f32le xr,xi,yr,yi per pixel of box, row-major",
//!  "modes": [{"freq_hz", "damping_ratio", "damping_method",
//!             "shape": "<base64: 16 bytes per pixel of box>"}, ...],
//!  "notes": [...], "payload_bytes": N, "roi", "mask_pixels", "cached", "elapsed_ms"}
//! ```
//!
//! The shapes are sent over the region's box only (the region is the
//! object: outside it the displacement is zero, as the library's mask
//! makes it outside a mask); the whole frame when no region is selected.

use super::{ApiError, Selection};
use axum::http::StatusCode;
use serde_json::{json, Value};
use std::path::Path;
use vibroscope::idv::{extract_basis, BasisOptions, ModeChoice, DEFAULT_MAX_MODES};

/// The largest basis answer sent, bytes of base64 (a 512x512 frame with 8
/// modes is 45 MB; a 1080p frame with 8 modes would be 350 MB).
pub const MAX_PAYLOAD: u64 = 64 << 20;

/// Bases larger than this are sent but not kept in the answer cache.
pub const MAX_CACHED_PAYLOAD: u64 = 16 << 20;

/// At most this many modes may be asked for.
pub const MAX_MODES: usize = 16;

/// The modes asked for: `auto` (the default) or `F1,F2,LO-HI` (Hz), and
/// at most how many with `auto`.
#[derive(Clone, Debug)]
pub struct Choice {
    pub modes: ModeChoice,
    pub max_modes: usize,
    /// The request's text, for the cache key.
    pub text: String,
}

impl Choice {
    /// Checks the request's `modes` and `max_modes` (422 naming the field).
    pub fn parse(modes: Option<&str>, max_modes: Option<usize>) -> Result<Choice, ApiError> {
        let text = modes.unwrap_or("auto").trim().to_owned();
        let parsed: ModeChoice = text.parse().map_err(|e: vibroscope::UsageError| {
            ApiError::unprocessable(format!("modes: {}", e.message))
        })?;
        let max_modes = max_modes.unwrap_or(DEFAULT_MAX_MODES);
        if !(1..=MAX_MODES).contains(&max_modes) {
            return Err(ApiError::unprocessable(format!(
                "max_modes {max_modes}: must be 1 to {MAX_MODES}"
            )));
        }
        if let ModeChoice::Listed(l) = &parsed {
            if l.len() > MAX_MODES {
                return Err(ApiError::unprocessable(format!(
                    "modes: {} listed, at most {MAX_MODES}",
                    l.len()
                )));
            }
        }
        Ok(Choice {
            modes: parsed,
            max_modes,
            text,
        })
    }

    /// The most modes the answer can hold.
    fn most(&self) -> usize {
        match &self.modes {
            ModeChoice::Auto => self.max_modes,
            ModeChoice::Listed(l) => l.len(),
        }
    }

    /// The answer's size in bytes of base64 for a box of `pixels` and
    /// `modes` modes (16 bytes per pixel and mode, 1 per pixel of the rest
    /// frame of `frame` pixels).
    fn payload(pixels: u64, modes: u64, frame: u64) -> u64 {
        (pixels * 16 * modes + frame).div_ceil(3) * 4
    }

    /// Refuses, before any work, a basis whose answer would exceed
    /// [`MAX_PAYLOAD`] (422 naming the region and the modes).
    pub(crate) fn check_size(&self, sel: &Selection) -> Result<(), ApiError> {
        let [_, _, w, h] = sel.whole.map(u64::from);
        let frame = u64::from(sel.probe.width) * u64::from(sel.probe.height);
        let n = Choice::payload(w * h, self.most() as u64, frame);
        if n > MAX_PAYLOAD {
            return Err(ApiError::unprocessable(format!(
                "roi/modes: a basis of {} modes over {w}x{h} pixels would be {} MB, over the \
                 {} MB the page is sent: select a smaller region or ask for fewer modes",
                self.most(),
                n >> 20,
                MAX_PAYLOAD >> 20
            )));
        }
        Ok(())
    }
}

/// The basis of the selection (see the module documentation). A recording
/// with no significant peak, or none in a listed range, is the request's
/// problem (422), as are bad values; other failures are 500s. `name` is
/// the request's name of the recording, said in messages instead of the
/// server's path.
pub(crate) fn basis_answer(
    name: &str,
    path: &Path,
    fps: Option<f64>,
    sel: &Selection,
    choice: &Choice,
) -> Result<Value, ApiError> {
    let mut o = BasisOptions::new(path);
    o.fps = fps;
    o.region = sel.region();
    o.modes = choice.modes.clone();
    o.max_modes = choice.max_modes;
    let basis = extract_basis(&o).map_err(|e| match e {
        vibroscope::Error::Analysis(m) => ApiError::unprocessable(
            m.replace(&path.display().to_string(), name)
                .replace("--modes", "modes"),
        ),
        e => ApiError::from(e),
    })?;
    let (w, h) = (basis.width, basis.height);
    let [bx, by, bw, bh] = sel.whole.map(|v| v as usize);
    if bx + bw > w || by + bh > h || basis.rest.len() != w * h {
        return Err(ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the basis is {w}x{h}, not the frame the region was checked against"),
        ));
    }
    let mut modes = Vec::with_capacity(basis.modes.len());
    let mut bytes = Vec::with_capacity(bw * bh * 16);
    for m in &basis.modes {
        bytes.clear();
        for y in by..by + bh {
            for i in y * w + bx..y * w + bx + bw {
                let (sx, sy) = (m.shape.x[i], m.shape.y[i]);
                for v in [sx.re, sx.im, sy.re, sy.im] {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        modes.push(json!({
            "freq_hz": m.freq_hz,
            "damping_ratio": m.damping,
            "damping_method": m.damping_method,
            "shape": super::base64(&bytes),
        }));
    }
    let payload = Choice::payload((bw * bh) as u64, modes.len() as u64, (w * h) as u64);
    Ok(json!({
        "width": w,
        "height": h,
        "fps": basis.fps,
        "box": sel.whole,
        "rest": super::base64(&basis.rest),
        "layout": "f32le xr,xi,yr,yi per pixel of box, row-major",
        "modes": modes,
        "notes": basis.notes,
        "modes_asked": choice.text,
        "payload_bytes": payload,
    }))
}

#[cfg(test)]
mod tests {
    use super::Choice;

    #[test]
    fn the_payload_of_512_by_512_with_8_modes_is_under_the_bound() {
        let n = Choice::payload(512 * 512, 8, 512 * 512);
        assert!(n > 40 << 20 && n < super::MAX_PAYLOAD, "{n}");
        assert!(Choice::payload(1920 * 1080, 8, 1920 * 1080) > super::MAX_PAYLOAD);
    }

    #[test]
    fn modes_are_checked() {
        assert!(Choice::parse(None, None).is_ok());
        assert!(Choice::parse(Some("7.3,45.8,100-130"), None).is_ok());
        let e = Choice::parse(Some("7.3,abc"), None)
            .err()
            .map(|e| e.message);
        assert!(
            e.as_deref().is_some_and(|m| m.starts_with("modes:")),
            "{e:?}"
        );
        assert!(Choice::parse(Some("auto"), Some(0)).is_err());
        assert!(Choice::parse(Some("auto"), Some(17)).is_err());
    }
}
