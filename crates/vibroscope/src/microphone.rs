//! The visual-microphone graph on a recording: the shipped
//! `visual-microphone` pipeline (pyramid local phase, band alignment,
//! high-pass, optional denoising) replayed on a video, writing a WAV. Used
//! by `listen` and `calibrate`.

use crate::engine::config::PipelineDecl;
use crate::error::Result;
use crate::pipeline::{self, by, path_value, Denoise, PipelineOptions, Region};
use std::path::Path;

/// Sets the high-pass of a visual-microphone pipeline to the causal IIR:
/// calibrations are fitted, and applied, on the causal recovery (their
/// models and their tests were made with it).
pub fn causal_highpass(decl: &mut PipelineDecl) -> Result<()> {
    pipeline::set(
        decl,
        "highpass",
        "mode",
        toml::Value::String("causal".into()),
        by("calibration (fitted on the causal high-pass)"),
    )
}

/// The visual-microphone pipeline replayed on `video`, writing `output`.
pub fn listen_pipeline(
    video: &Path,
    output: &Path,
    fps: Option<f64>,
    region: &Region,
    denoise: Denoise,
) -> Result<PipelineDecl> {
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: "visual-microphone".into(),
        set: Vec::new(),
        replay: Some(video.to_path_buf()),
        fps,
    })?;
    pipeline::set(&mut decl, "out", "path", path_value(output), by("-o"))?;
    region.apply(&mut decl, "phase")?;
    if let Some(kind) = denoise.kind() {
        let hp = pipeline::position(&decl, "highpass")?;
        let st = pipeline::new_stage("denoise", kind, &["highpass"], by("--denoise"));
        decl.stages.insert(hp + 1, st);
        pipeline::rewire(&mut decl, "out", "denoise")?;
    }
    Ok(decl)
}
