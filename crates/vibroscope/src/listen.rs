//! Recover sound from a video: the shipped visual-microphone pipeline
//! (pyramid local phase, band alignment, high-pass, optional denoising)
//! replayed on a recording, written to a WAV at the camera's frame rate;
//! or, for rolling-shutter cameras, one sample per row.

use crate::corrections;
use crate::engine::config::PipelineDecl;
use crate::engine::RunReport;
use crate::error::{Error, Result};
use crate::microphone::listen_pipeline;
pub use crate::pipeline::Denoise;
use crate::pipeline::{self, by, path_value, PipelineOptions, Region, RunSettings};
use serde::Serialize;
use std::path::PathBuf;
use toml::Value;

/// Filling of a rolling-shutter camera's frame-delay gaps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Fill {
    #[default]
    Ar,
    Linear,
}

/// Rolling-shutter timing (thesis ch. 4.5): one sample per image row.
#[derive(Clone, Debug, Default)]
pub struct RollingShutter {
    /// Time between consecutive rows, µs (required).
    pub line_delay_us: Option<f64>,
    /// Blind time between a frame's last row and the next frame's first, µs.
    pub frame_delay_us: Option<f64>,
    /// Exposure per row, µs.
    pub exposure_us: Option<f64>,
    /// Invert the exposure boxcar (needs `exposure_us`).
    pub compensate_exposure: bool,
    pub fill: Fill,
    /// Output rate in Hz (needs `exposure_us`).
    pub rate: Option<f64>,
}

/// What `listen` is asked.
#[derive(Clone, Debug, Default)]
pub struct ListenOptions {
    pub video: PathBuf,
    /// The WAV written.
    pub output: PathBuf,
    /// Capture frame rate (Hz) when the file states the wrong one.
    pub fps: Option<f64>,
    pub region: Region,
    pub denoise: Denoise,
    /// Also play on this speaker (`default`, part of a name, or `null`).
    pub speaker: Option<String>,
    /// A stored calibration (REPORT.json of `calibrate`) to apply.
    pub calibration: Option<PathBuf>,
    /// One sample per row instead of per frame.
    pub rolling_shutter: Option<RollingShutter>,
    pub run: RunSettings,
}

/// What `listen` did.
#[derive(Debug, Serialize)]
pub struct ListenReport {
    pub output: PathBuf,
    /// The corrections applied from `--calibration`, by name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<String>,
    /// Samples written and their rate (Hz).
    pub samples: u64,
    pub sample_rate_hz: u32,
    /// Notes worth telling the user (e.g. a missing exposure).
    pub notes: Vec<String>,
    #[serde(skip)]
    pub run: Option<RunReport>,
}

/// Runs `listen`.
pub fn listen(o: &ListenOptions) -> Result<ListenReport> {
    let mut inputs = vec![o.video.as_path()];
    inputs.extend(o.calibration.as_deref());
    inputs.extend(o.region.mask.as_deref());
    crate::error::check_outputs(&inputs, &[&o.output])?;
    let corrections = match &o.calibration {
        Some(path) => {
            if o.rolling_shutter.is_some() || o.speaker.is_some() {
                let flag = if o.speaker.is_some() {
                    "--speaker"
                } else {
                    "--rolling-shutter"
                };
                return Err(Error::usage(
                    "--calibration",
                    format!(
                        "not available with {flag} (the correction is applied to the finished WAV)"
                    ),
                ));
            }
            Some(corrections::load_calibration(path)?)
        }
        None => None,
    };
    let mut notes = Vec::new();
    let mut decl = match &o.rolling_shutter {
        Some(rs) => {
            if o.region.mask.is_some() {
                return Err(Error::usage(
                    "--mask",
                    "not available with --rolling-shutter yet (use --roi)",
                ));
            }
            if o.denoise != Denoise::None {
                return Err(Error::usage(
                    "--denoise",
                    "not available with --rolling-shutter yet",
                ));
            }
            rs_pipeline(o, rs, &mut notes)?
        }
        None => listen_pipeline(&o.video, &o.output, o.fps, &o.region, o.denoise)?,
    };
    if let Some(dev) = &o.speaker {
        add_speaker(&mut decl, dev)?;
    }
    let run = pipeline::run(&decl, o.run)?;
    let calibration = match &corrections {
        Some(c) => {
            corrections::apply_to_wav(&o.output, c, o.denoise)?;
            Some(corrections::describe(c))
        }
        None => None,
    };
    let (samples, sample_rate_hz) = match hound::WavReader::open(&o.output) {
        Ok(r) => (u64::from(r.duration()), r.spec().sample_rate),
        Err(_) => (0, 0),
    };
    Ok(ListenReport {
        output: o.output.clone(),
        samples,
        sample_rate_hz,
        calibration,
        notes,
        run: Some(run),
    })
}

/// Adds a `speaker` sink fed by whatever feeds the `out` sink (fan-out:
/// the WAV and the speaker get the same blocks).
fn add_speaker(decl: &mut PipelineDecl, device: &str) -> Result<()> {
    let out = pipeline::position(decl, "out")?;
    let origin = by(&format!("--speaker {device}"));
    let mut st = decl.stages[out].clone();
    st.id = "speaker".into();
    st.kind = "speaker".into();
    st.kind_origin = origin.clone();
    st.params.clear();
    crate::engine::config::set_param(&mut st, "device", Value::String(device.into()), origin);
    decl.stages.push(st);
    Ok(())
}

/// The shipped rolling-shutter pipeline replayed on the video with the
/// camera's timing.
fn rs_pipeline(
    o: &ListenOptions,
    a: &RollingShutter,
    notes: &mut Vec<String>,
) -> Result<PipelineDecl> {
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: "rolling-shutter".into(),
        set: Vec::new(),
        replay: Some(o.video.clone()),
        fps: o.fps,
    })?;
    let Some(d) = a.line_delay_us else {
        return Err(Error::usage(
            "--line-delay-us",
            "required with --rolling-shutter (estimate it with `vibroscope rs-calibrate`)",
        ));
    };
    let f = Value::Float;
    pipeline::set(
        &mut decl,
        "rows",
        "line_delay_us",
        f(d),
        by(&format!("--line-delay-us {d}")),
    )?;
    if let Some(g) = a.frame_delay_us {
        pipeline::set(
            &mut decl,
            "rows",
            "frame_delay_us",
            f(g),
            by(&format!("--frame-delay-us {g}")),
        )?;
    }
    // The shipped region is the simulator's object: a recording starts from the whole frame.
    pipeline::stage_mut(&mut decl, "rows")?
        .params
        .retain(|p| p.key != "roi");
    if let Some(r) = &o.region.roi {
        pipeline::set(
            &mut decl,
            "rows",
            "roi",
            r.value(),
            by(&format!("--roi {r}")),
        )?;
    }
    let method = match a.fill {
        Fill::Ar => "ar",
        Fill::Linear => "linear",
    };
    pipeline::set(
        &mut decl,
        "fill",
        "method",
        Value::String(method.into()),
        by("--fill"),
    )?;
    match a.exposure_us {
        Some(e) => {
            pipeline::set(
                &mut decl,
                "exposure",
                "exposure_us",
                f(e),
                by(&format!("--exposure-us {e}")),
            )?;
            if a.compensate_exposure {
                let v = Value::String("compensate".into());
                pipeline::set(
                    &mut decl,
                    "exposure",
                    "mode",
                    v,
                    by("--compensate-exposure"),
                )?;
            }
            if let Some(r) = a.rate {
                pipeline::set(
                    &mut decl,
                    "exposure",
                    "rate_hz",
                    f(r),
                    by(&format!("--rate {r}")),
                )?;
            }
        }
        None => {
            if a.compensate_exposure || a.rate.is_some() {
                let flag = if a.rate.is_some() {
                    "--rate"
                } else {
                    "--compensate-exposure"
                };
                return Err(Error::usage(flag, "needs --exposure-us"));
            }
            notes.push(
                "no --exposure-us: the output is not band-limited to the exposure's first null"
                    .into(),
            );
            decl.stages.retain(|s| s.id != "exposure");
            pipeline::rewire(&mut decl, "out", "fill")?;
        }
    }
    pipeline::set(&mut decl, "out", "path", path_value(&o.output), by("-o"))?;
    Ok(decl)
}
