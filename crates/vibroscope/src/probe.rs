//! Describe a video file: format, size, bit depth, frames, frame rate,
//! timestamps.

use crate::error::Result;
use crate::io;
use crate::pipeline;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What `probe` found: serialises to the JSON `probe --json` writes.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeReport {
    pub file: PathBuf,
    pub format: &'static str,
    pub width: u32,
    pub height: u32,
    pub bits: u8,
    pub frames: Option<u64>,
    /// The rate used: the given one, else the file's.
    pub fps: Option<f64>,
    pub fps_stated: Option<f64>,
    pub timestamps: bool,
    pub exposure_s: Option<f64>,
    pub notes: Vec<String>,
    /// The rate was given (not read from the file).
    #[serde(skip)]
    pub fps_given: bool,
}

/// Probes `file`; `fps` replaces the file's stated rate.
pub fn probe(file: &Path, fps: Option<f64>) -> Result<ProbeReport> {
    pipeline::check_fps(fps)?;
    let reader = io::open(file, io::Format::Auto)?;
    let info = reader.info();
    Ok(ProbeReport {
        file: file.to_path_buf(),
        format: info.format_name,
        width: info.width,
        height: info.height,
        bits: info.bits,
        frames: info.frame_count,
        fps: fps.or(info.fps),
        fps_stated: info.fps,
        timestamps: info.has_timestamps,
        exposure_s: info.exposure_s,
        notes: info.notes.clone(),
        fps_given: fps.is_some(),
    })
}
