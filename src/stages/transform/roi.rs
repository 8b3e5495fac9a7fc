//! Regions of interest shared by the analysis stages.

use crate::engine::StageError;
use serde::Deserialize;

/// `[x, y, w, h]` in pixels, as written in TOML.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
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
            return Err(StageError::msg(format!(
                "roi [{x}, {y}, {w}, {h}] does not fit in a {width}x{height} frame"
            )));
        }
        Ok(Roi { x, y, w, h })
    }
}
