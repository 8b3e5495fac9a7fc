//! A rolling-shutter camera's line delay (and frame delay) from a video of
//! a known tone or a flickering light (thesis ch. 4.5: the slope of the
//! tone's phase down the rows).

use crate::error::{Error, Result};
use crate::io;
use crate::math::row_phase::RowPhase;
use crate::math::rs_calibrate::{estimate, remove_row_means};
use crate::pipeline::{self, Roi};
use serde::Serialize;
use std::path::PathBuf;

/// What each row measures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RowSignal {
    /// Horizontal motion of each row (a vibrating textured object).
    #[default]
    Motion,
    /// Mean brightness of each row (a flickering light).
    Intensity,
}

/// What `rs-calibrate` is asked.
#[derive(Clone, Debug)]
pub struct RsCalibrateOptions {
    pub video: PathBuf,
    /// The tone's (or flicker's) frequency, Hz.
    pub tone_hz: f64,
    pub fps: Option<f64>,
    pub signal: RowSignal,
    pub roi: Option<Roi>,
    /// Frames read at most.
    pub max_frames: usize,
}

/// What `rs-calibrate` found: serialises to the JSON `--json` writes.
#[derive(Clone, Debug, Serialize)]
pub struct RsCalibrationReport {
    pub line_delay_us: f64,
    pub frame_delay_us: f64,
    pub rows: usize,
    pub fps: f64,
    pub row_rate_hz: f64,
    pub missing_fraction: f64,
    /// Share of the per-row signal the tone explains.
    pub explained: f64,
    pub frames: usize,
}

/// Runs `rs-calibrate`.
pub fn rs_calibrate(a: &RsCalibrateOptions) -> Result<RsCalibrationReport> {
    if !(a.tone_hz.is_finite() && a.tone_hz > 0.0) {
        return Err(Error::usage(
            "--tone-hz",
            format!("must be > 0 Hz, got {}", a.tone_hz),
        ));
    }
    pipeline::check_fps(a.fps)?;
    let mut reader = io::open(&a.video, io::Format::Auto)?;
    let info = reader.info().clone();
    let fps = a.fps.or(info.fps).ok_or_else(|| {
        Error::usage(
            "--fps",
            format!(
                "{}: the file states no frame rate; pass --fps",
                a.video.display()
            ),
        )
    })?;
    let (w, h) = (info.width as usize, info.height as usize);
    let (x, y, rw, rh) = match &a.roi {
        Some(r) => {
            let (x, y, rw, rh) = (r.x as usize, r.y as usize, r.w as usize, r.h as usize);
            if rw == 0 || rh < 8 || x + rw > w || y + rh > h {
                return Err(Error::usage(
                    "--roi",
                    format!("`{r}` does not fit a {w}x{h} frame (at least 8 rows)"),
                ));
            }
            (x, y, rw, rh)
        }
        None => (0, 0, w, h),
    };
    let mut rp = match a.signal {
        RowSignal::Motion => Some(
            RowPhase::new(w, x, x + rw, rh, &[8.0, 16.0])
                .map_err(|m| Error::usage("--roi", m.to_string()))?,
        ),
        RowSignal::Intensity => None,
    };
    let mut buf8 = vec![0u8; w * h];
    let mut buf16 = vec![0u16; w * h];
    let mut line = vec![0.0f32; w];
    let mut frames: Vec<Vec<f64>> = Vec::new();
    for n in 0..a.max_frames {
        let dst = match info.depth {
            io::Depth::U8 => io::FrameDest::U8(&mut buf8),
            io::Depth::U16 => io::FrameDest::U16(&mut buf16),
        };
        if reader.read_frame(dst)?.is_none() {
            break;
        }
        let mut rows = Vec::with_capacity(rh);
        for i in 0..rh {
            let s = (y + i) * w;
            match info.depth {
                io::Depth::U8 => line
                    .iter_mut()
                    .zip(&buf8[s..s + w])
                    .for_each(|(o, &v)| *o = v as f32),
                io::Depth::U16 => line
                    .iter_mut()
                    .zip(&buf16[s..s + w])
                    .for_each(|(o, &v)| *o = v as f32),
            }
            let v = match rp.as_mut() {
                Some(rp) if n == 0 => {
                    rp.set_reference(i, &line);
                    0.0
                }
                Some(rp) => rp.displacement(i, &line),
                None => line[x..x + rw].iter().map(|&v| v as f64).sum::<f64>() / rw as f64,
            };
            rows.push(v);
        }
        // The motion reference frame reads zero everywhere: leave it out.
        if rp.is_none() || n > 0 {
            frames.push(rows);
        }
    }
    if frames.len() < 2 {
        return Err(Error::Analysis(format!(
            "{}: need at least 3 frames, got {}",
            a.video.display(),
            frames.len() + 1
        )));
    }
    remove_row_means(&mut frames);
    let period = 1.0 / fps;
    let est = estimate(&frames, a.tone_hz, period / h as f64).ok_or_else(|| {
        Error::Analysis(format!(
            "{}: cannot fit: the tone must make at least a quarter cycle during the readout of {rh} rows",
            a.video.display()
        ))
    })?;
    let d = est.line_delay_s;
    let gap = (period - h as f64 * d).max(0.0);
    Ok(RsCalibrationReport {
        line_delay_us: d * 1e6,
        frame_delay_us: gap * 1e6,
        rows: h,
        fps,
        row_rate_hz: 1.0 / d,
        missing_fraction: gap / period,
        explained: est.explained,
        frames: frames.len(),
    })
}
