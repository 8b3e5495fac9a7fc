//! The visual-microphone graph on a recording: a shipped pipeline
//! replayed on a video, writing a WAV: `tile-microphone` (per-tile gradient
//! motion, first principal component, high-pass; `listen`'s default) or
//! `visual-microphone` (the thesis: pyramid local phase, band alignment,
//! high-pass; what `calibrate` fits on), with optional denoising. Used by
//! `listen` and `calibrate`.

use crate::engine::config::PipelineDecl;
use crate::engine::pipelines::stage::{tile_microphone, visual_microphone};
use crate::error::Result;
use crate::pipeline::{self, by, Denoise, PipelineOptions, Region};
use crate::stages::params::{HighpassParams, WavParams};
use crate::stages::transform::butterworth::Mode;
use std::path::Path;

/// Sets the high-pass of a visual-microphone pipeline to the causal IIR:
/// calibrations are fitted, and applied, on the causal recovery (their
/// models and their tests were made with it).
pub fn causal_highpass(decl: &mut PipelineDecl) -> Result<()> {
    // The same stage in both microphone pipelines.
    debug_assert_eq!(visual_microphone::HIGHPASS.id, tile_microphone::HIGHPASS.id);
    pipeline::set(
        decl,
        visual_microphone::HIGHPASS,
        HighpassParams::mode,
        Mode::Causal,
        by("calibration (fitted on the causal high-pass)"),
    )
}

/// How a visual microphone measures motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Method {
    /// Per-tile gradient least squares, whitened, projected on the first
    /// principal component (`tile-microphone`): at the Cramér-Rao bound on
    /// textured sub-pixel motion, the still background weighed out.
    #[default]
    Gradient,
    /// Pyramid local phase, A²-weighted, aligned across bands and summed
    /// (`visual-microphone`, thesis ch. 3): robust to larger motions.
    Phase,
}

impl Method {
    /// The shipped pipeline.
    fn pipeline(self) -> &'static str {
        match self {
            Method::Gradient => tile_microphone::PIPELINE,
            Method::Phase => visual_microphone::PIPELINE,
        }
    }

    /// The unit of the samples the pipeline writes.
    pub fn unit(self) -> &'static str {
        match self {
            Method::Gradient => {
                "the tiles' whitened motion on their first principal component (relative units)"
            }
            Method::Phase => "radians of local phase, A²-weighted over the bands",
        }
    }
}

/// The visual-microphone pipeline of `method` replayed on `video`, writing
/// `output`.
pub fn listen_pipeline(
    video: &Path,
    output: &Path,
    fps: Option<f64>,
    (region, method): (&Region, Method),
    denoise: Denoise,
) -> Result<PipelineDecl> {
    let name = method.pipeline();
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: name.into(),
        set: Vec::new(),
        replay: Some(video.to_path_buf()),
        fps,
    })?;
    let out = match method {
        Method::Phase => visual_microphone::OUT,
        Method::Gradient => tile_microphone::OUT,
    };
    pipeline::set(
        &mut decl,
        out,
        WavParams::path,
        output.to_path_buf(),
        by("-o"),
    )?;
    match method {
        Method::Phase => region.apply(&mut decl, visual_microphone::PHASE)?,
        Method::Gradient => region.apply_region(&mut decl, tile_microphone::MOTION)?,
    }
    if let Some(st) = denoise.stage("denoise", &["highpass"], by("--denoise")) {
        let hp = pipeline::position(&decl, "highpass")?;
        decl.stages.insert(hp + 1, st);
        pipeline::rewire(&mut decl, "out", "denoise")?;
    }
    Ok(decl)
}
