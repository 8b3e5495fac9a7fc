//! Regions of interest shared by the analysis stages.

use crate::{ConfigError, Def, ParamSpec, ParamType, Params, StageError};
use serde::Deserialize;
use std::path::PathBuf;

/// At planning: checks `roi` and reads `mask` once, so that a bad one is a
/// configuration error naming the field.
pub fn plan_region(
    p: &Params<'_>,
    roi: Option<&RoiParam>,
    mask: Option<&PathBuf>,
) -> Result<Option<(PathBuf, Mask)>, ConfigError> {
    if let Some(r) = roi {
        r.check().map_err(|m| p.error("roi", m))?;
    }
    match mask {
        Some(m) => Ok(Some((
            m.clone(),
            Mask::load(m).map_err(|e| p.error("mask", e))?,
        ))),
        None => Ok(None),
    }
}

/// `mask`, shared by the stages that take a region.
pub const MASK: ParamSpec = ParamSpec::new("mask", ParamType::Path, Def::Optional)
    .doc("region as an image the frame's size (PGM/PNG, > 0 inside); with roi, both");

/// `[x, y, w, h]` in pixels, as written in TOML.
#[derive(Deserialize, serde::Serialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct RoiParam(pub [u32; 4]);

impl RoiParam {
    /// Checks what can be checked before the frame size is known.
    pub fn check(&self) -> Result<(), String> {
        let [_, _, w, h] = self.0;
        if w == 0 || h == 0 {
            return Err(format!("width and height must be > 0, got {:?}", self.0));
        }
        Ok(())
    }
}

/// A region clipped to a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Roi {
    pub x: usize,
    pub y: usize,
    pub w: usize,
    pub h: usize,
}

impl Roi {
    pub fn resolve(p: Option<&RoiParam>, width: usize, height: usize) -> Result<Roi, StageError> {
        let Some(RoiParam([x, y, w, h])) = p else {
            return Ok(Roi {
                x: 0,
                y: 0,
                w: width,
                h: height,
            });
        };
        let (x, y, w, h) = (*x as usize, *y as usize, *w as usize, *h as usize);
        if x + w > width || y + h > height || w == 0 || h == 0 {
            return Err(StageError::config(
                "roi",
                format!("[{x}, {y}, {w}, {h}] does not fit in a {width}x{height} frame"),
            ));
        }
        Ok(Roi { x, y, w, h })
    }
}

/// A region given as an image: pixels > 0 are inside. Read from a PGM
/// (P2 or P5, 8 or 16 bit) or PNG file the size of the frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    pub width: usize,
    pub height: usize,
    inside: Vec<bool>,
}

impl Mask {
    /// Reads `path` (the error names it and what is wrong).
    pub fn load(path: &std::path::Path) -> Result<Mask, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::decode(&bytes, path)
    }

    /// [`Mask::load`] of a picture's bytes; `path` names them in errors.
    pub fn decode(bytes: &[u8], path: &std::path::Path) -> Result<Mask, String> {
        let img = vibroscope_io::image::decode_gray16(bytes, path).map_err(|e| e.to_string())?;
        let (w, h) = img.dimensions();
        let inside: Vec<bool> = img.pixels().map(|p| p.0[0] > 0).collect();
        if !inside.iter().any(|&v| v) {
            return Err(format!(
                "{}: the mask is empty (no pixel > 0)",
                path.display()
            ));
        }
        Ok(Mask {
            width: w as usize,
            height: h as usize,
            inside,
        })
    }

    /// Whether input pixel (x, y) is inside (false outside the image).
    pub fn at(&self, x: usize, y: usize) -> bool {
        x < self.width && y < self.height && self.inside[y * self.width + x]
    }

    /// The bounding box of the inside pixels, as a region.
    pub fn bounds(&self) -> Roi {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..self.height {
            for x in 0..self.width {
                if self.inside[y * self.width + x] {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
                }
            }
        }
        Roi {
            x: x0,
            y: y0,
            w: x1 + 1 - x0,
            h: y1 + 1 - y0,
        }
    }

    /// Checks the mask against the frame size.
    pub fn check_size(
        &self,
        path: &std::path::Path,
        width: usize,
        height: usize,
    ) -> Result<(), StageError> {
        if (self.width, self.height) != (width, height) {
            return Err(StageError::config(
                "mask",
                format!(
                    "{} is {}x{}, but the frames are {width}x{height}",
                    path.display(),
                    self.width,
                    self.height
                ),
            ));
        }
        Ok(())
    }
}

/// The region of a `w x h` frame a stage analyses: `roi` (the whole frame
/// without one) narrowed to the mask's bounding box, and the mask checked
/// against the frame size. The errors name `roi` or `mask`.
pub fn resolve_region(
    roi: Option<&RoiParam>,
    mask: Option<(std::path::PathBuf, Mask)>,
    width: usize,
    height: usize,
) -> Result<(Roi, Option<Mask>), StageError> {
    let roi = Roi::resolve(roi, width, height)?;
    let Some((path, m)) = mask else {
        return Ok((roi, None));
    };
    m.check_size(&path, width, height)?;
    let roi = roi.intersect(&m.bounds()).ok_or_else(|| {
        StageError::config(
            "mask",
            format!("{} does not overlap the roi", path.display()),
        )
    })?;
    Ok((roi, Some(m)))
}

impl Roi {
    /// The overlap of two regions, if any.
    pub fn intersect(&self, o: &Roi) -> Option<Roi> {
        let (x0, y0) = (self.x.max(o.x), self.y.max(o.y));
        let (x1, y1) = (
            (self.x + self.w).min(o.x + o.w),
            (self.y + self.h).min(o.y + o.h),
        );
        (x1 > x0 && y1 > y0).then_some(Roi {
            x: x0,
            y: y0,
            w: x1 - x0,
            h: y1 - y0,
        })
    }
}
