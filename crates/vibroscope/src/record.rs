//! Record a camera to Y4M (gray) with each frame's capture time in its
//! header: a `v4l2` source `cam` into a `y4m` sink `rec`.

use crate::engine::config::{ConfigError, PipelineDecl};
use crate::engine::RunReport;
use crate::error::Result;
use crate::pipeline::{self, RunSettings};
use crate::stages::params::{V4l2Params, Y4mParams};
use crate::{engine::Origin, io};
use serde::de::IntoDeserializer;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use vibroscope_devices::v4l2::PixelFormat;

/// What `record` is asked.
#[derive(Clone, Debug)]
pub struct RecordOptions {
    /// The camera's device node.
    pub device: PathBuf,
    /// Output Y4M (`-` for standard output).
    pub output: PathBuf,
    /// Stop after this many seconds (default: until interrupted).
    pub seconds: Option<f64>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub fps: Option<f64>,
    /// Pixel format: grey, yuyv, mjpeg or auto.
    pub format: String,
    pub run: RunSettings,
}

/// What `record` did.
#[derive(Debug, Serialize)]
pub struct RecordReport {
    pub output: PathBuf,
    pub frames: u64,
    /// Frames lost: at the device (sequence gaps) and in the recorder's
    /// queue (the disk fell behind).
    pub dropped_device: u64,
    pub dropped_queue: u64,
    /// Size and rate read back from the file (`None` for standard output).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recorded: Option<(u32, u32, Option<f64>)>,
    /// Why the file could not be read back, if it could not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub read_back_error: Option<String>,
    /// Stopped by Ctrl-C (the file is valid).
    pub interrupted: bool,
    /// Stage failures (the file holds what was recorded before).
    pub errors: Vec<String>,
    #[serde(skip)]
    pub run: Option<RunReport>,
}

/// The pipeline `record` runs: a `v4l2` source `cam` into a `y4m` sink `rec`.
pub fn record_pipeline(o: &RecordOptions) -> Result<PipelineDecl> {
    let origin = Origin::Builtin("vibroscope record".into());
    let mut decl = pipeline::empty("record", "camera -> Y4M (vibroscope record)");
    decl.file = "record".into();
    let mut cam = pipeline::new_stage::<V4l2Params>("cam", &[], origin.clone());
    let format = pixel_format(&decl.file, &cam, &o.format, &origin)?;
    pipeline::put(
        &mut cam,
        V4l2Params::device,
        o.device.clone(),
        origin.clone(),
    )?;
    pipeline::put(&mut cam, V4l2Params::format, format, origin.clone())?;
    for (k, v) in [(V4l2Params::width, o.width), (V4l2Params::height, o.height)] {
        if v.is_some() {
            pipeline::put(&mut cam, k, v, origin.clone())?;
        }
    }
    if let Some(f) = o.fps {
        pipeline::put(&mut cam, V4l2Params::fps, Some(f), origin.clone())?;
    }
    if let Some(d) = o.seconds {
        pipeline::put(&mut cam, V4l2Params::duration_s, Some(d), origin.clone())?;
    }
    decl.stages.push(cam);
    let mut rec = pipeline::new_stage::<Y4mParams>("rec", &["cam"], origin.clone());
    pipeline::put(&mut rec, Y4mParams::path, o.output.clone(), origin)?;
    decl.stages.push(rec);
    Ok(decl)
}

/// `--format` as the `v4l2` source's pixel format; a word it does not
/// know is the configuration error validation would give (the field, the
/// words it takes).
fn pixel_format(
    file: &str,
    cam: &crate::engine::config::StageDecl,
    word: &str,
    origin: &Origin,
) -> Result<PixelFormat> {
    let key = V4l2Params::format;
    let parsed: std::result::Result<PixelFormat, serde::de::value::Error> =
        PixelFormat::deserialize(word.into_deserializer());
    parsed.map_err(|_| {
        let message = match key.spec().ty {
            crate::engine::spec::ParamType::Choice(words) => format!(
                "must be {}, got `{word}`",
                crate::engine::spec::or_list(words)
            ),
            _ => format!("unknown pixel format `{word}`"),
        };
        ConfigError {
            file: file.to_string(),
            origin: Some(origin.clone()),
            stage: Some(cam.id.as_str().into()),
            field: Some(key.name.into()),
            message,
        }
        .into()
    })
}

/// Runs `record` (an interrupted recording is a result, not an error).
pub fn record(o: &RecordOptions) -> Result<RecordReport> {
    let decl = record_pipeline(o)?;
    // A recording that failed part way is still a valid file: report it,
    // with the stage errors.
    let (run, errors) = match pipeline::run_with(&decl, o.run, true) {
        Ok(run) => (run, Vec::new()),
        Err(crate::error::Error::Stages { report }) => {
            let errors = report
                .errors
                .iter()
                .map(|e| crate::engine::error_chain(e))
                .collect();
            (*report, errors)
        }
        Err(e) => return Err(e),
    };
    let stage = |id: &str| run.stages.iter().find(|s| s.id == id);
    let (cam_dropped, rec_dropped, frames) = match (stage("cam"), stage("rec")) {
        (Some(c), Some(r)) => (c.dropped, r.dropped, r.items_in),
        _ => (0, 0, 0),
    };
    let (mut recorded, mut read_back_error) = (None, None);
    if o.output.as_os_str() != "-" && frames > 0 {
        match io::open(&o.output, io::Format::Y4m) {
            Ok(r) => {
                let i = r.info();
                recorded = Some((i.width, i.height, i.fps));
            }
            Err(e) => read_back_error = Some(e.to_string()),
        }
    }
    Ok(RecordReport {
        output: o.output.clone(),
        frames,
        dropped_device: cam_dropped,
        dropped_queue: rec_dropped,
        recorded,
        read_back_error,
        interrupted: run.interrupted,
        errors,
        run: Some(run),
    })
}
