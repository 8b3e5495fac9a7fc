//! `bound`: how small a motion a recording can show at all. Per region, the
//! sensor noise and the texture measured from the video give the
//! Cramér-Rao floor of per-frame sub-pixel motion and so the best SNR any
//! estimator can reach for a given amplitude ([`crate::math::bound`]).

use crate::error::{Error, Result};
use crate::io::{self, Depth, FrameDest};
pub use crate::math::bound::REFERENCE_FRAMES;
use crate::math::bound::{BoundAccumulator, BoundError, RegionBound};
use crate::pipeline::Roi;
use serde::Serialize;
use std::path::PathBuf;

/// What `bound` is asked.
#[derive(Clone, Debug)]
pub struct BoundOptions {
    pub video: PathBuf,
    /// Capture rate (Hz) when the file states the wrong one (reported only).
    pub fps: Option<f64>,
    /// Regions (none: the whole frame).
    pub regions: Vec<Roi>,
    /// A motion amplitude (px) to give the best SNR for.
    pub amplitude_px: Option<f64>,
    /// Frames averaged into the reference.
    pub reference_frames: usize,
    /// At most this many frames (none: all).
    pub max_frames: Option<usize>,
}

impl BoundOptions {
    pub fn new(video: impl Into<PathBuf>) -> Self {
        BoundOptions {
            video: video.into(),
            fps: None,
            regions: Vec::new(),
            amplitude_px: None,
            reference_frames: REFERENCE_FRAMES,
            max_frames: None,
        }
    }
}

/// One region's bound and, with an amplitude, its best SNR.
#[derive(Clone, Debug, Serialize)]
pub struct RegionReport {
    #[serde(flatten)]
    pub bound: RegionBound,
    /// Best per-frame SNR (dB) of a tone of `amplitude_px` along x and y.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub snr_db: Option<[f64; 2]>,
}

/// What `bound` found.
#[derive(Clone, Debug, Serialize)]
pub struct BoundReport {
    pub video: PathBuf,
    pub width: usize,
    pub height: usize,
    pub frames: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    pub reference_frames: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub amplitude_px: Option<f64>,
    pub regions: Vec<RegionReport>,
    /// Warnings about what the bound can mean here.
    pub notes: Vec<String>,
    pub method: &'static str,
}

/// What [`BoundReport::method`] says.
pub const METHOD: &str = "Cramér-Rao bound of a rigid sub-pixel translation per frame: sigma^2 (Sum grad R grad R^T)^-1; R the mean of the first reference_frames frames (7-tap gradient, its noise's share removed); sigma the median over later frames of 1.4826 x the median |residual| after each frame's own least-squares motion";

/// Runs `bound`.
pub fn bound(o: &BoundOptions) -> Result<BoundReport> {
    if let Some(a) = o.amplitude_px {
        if !(a.is_finite() && a > 0.0) {
            return Err(Error::usage(
                "--amplitude-px",
                format!("must be a motion amplitude > 0 px, got {a}"),
            ));
        }
    }
    if o.reference_frames == 0 {
        return Err(Error::usage("--reference-frames", "must be at least 1"));
    }
    let mut reader = io::open(&o.video, io::Format::Auto).map_err(|e| match e {
        io::VideoError::Io { .. } => Error::from(e),
        other => Error::input(&o.video, other.to_string()),
    })?;
    let info = reader.info().clone();
    let (w, h) = (info.width as usize, info.height as usize);
    let rois: Vec<[usize; 4]> = o
        .regions
        .iter()
        .map(|r| [r.x as usize, r.y as usize, r.w as usize, r.h as usize])
        .collect();
    // The sums (f64), reference, gradients, residuals and the frame: at most
    // 32 bytes a pixel, checked before any of it is allocated.
    let need = ((w as u64) * (h as u64))
        .saturating_mul(32)
        .saturating_add(64 << 20);
    crate::engine::memory::check(
        need,
        &format!("the bound on {w}x{h} frames"),
        "measure a smaller video",
    )
    .map_err(|m| Error::input(&o.video, m))?;
    let mut acc = BoundAccumulator::new(w, h, &rois, o.reference_frames)
        .map_err(|e| Error::usage("--region", e.to_string()))?;
    let n = w * h;
    let (mut buf8, mut buf16) = (Vec::new(), Vec::new());
    match info.depth {
        Depth::U8 => buf8 = vec![0u8; n],
        Depth::U16 => buf16 = vec![0u16; n],
    }
    let mut frame = vec![0f32; n];
    let limit = o.max_frames.unwrap_or(usize::MAX);
    while acc.frames() < limit {
        let got = match info.depth {
            Depth::U8 => reader.read_frame(FrameDest::U8(&mut buf8))?,
            Depth::U16 => reader.read_frame(FrameDest::U16(&mut buf16))?,
        };
        if got.is_none() {
            break;
        }
        match info.depth {
            Depth::U8 => frame
                .iter_mut()
                .zip(&buf8)
                .for_each(|(f, &v)| *f = v as f32),
            Depth::U16 => frame
                .iter_mut()
                .zip(&buf16)
                .for_each(|(f, &v)| *f = v as f32),
        }
        acc.push(&frame)
            .map_err(|e| Error::input(&o.video, e.to_string()))?;
    }
    let regions = acc.finish().map_err(|e| match e {
        BoundError::TooShort { .. } | BoundError::Region { .. } | BoundError::FrameSize { .. } => {
            Error::input(&o.video, e.to_string())
        }
    })?;
    // Quantisation alone leaves 1/√12 DN of noise in a raw recording.
    let q = 1.0 / 12f64.sqrt();
    let notes = regions
        .iter()
        .enumerate()
        .filter(|(_, b)| b.noise_dn < q)
        .map(|(k, b)| {
            format!(
                "region {}: noise {:.3} DN is below one quantisation step's {q:.3} DN: the video was compressed or denoised (still blocks repeat exactly), so this noise, and the floor, are too low",
                k + 1,
                b.noise_dn
            )
        })
        .collect();
    let regions = regions
        .into_iter()
        .map(|b| RegionReport {
            snr_db: o.amplitude_px.map(|a| [b.snr_db(a, 0), b.snr_db(a, 1)]),
            bound: b,
        })
        .collect();
    Ok(BoundReport {
        video: o.video.clone(),
        width: w,
        height: h,
        frames: acc.frames(),
        fps: o.fps.or(info.fps),
        reference_frames: o.reference_frames,
        amplitude_px: o.amplitude_px,
        regions,
        notes,
        method: METHOD,
    })
}
