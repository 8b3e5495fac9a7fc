//! A modal image of a recording at one frequency (thesis ch. 3.5, Eq.
//! 3.18-3.19): the engine's `modes` sink fed by a file source, over a
//! region or mask, with either pyramid.

use crate::engine::config::{set_param, PipelineDecl};
use crate::engine::RunReport;
use crate::error::Result;
use crate::pipeline::{self, by, int, path_value, Region, RunSettings};
use serde::Serialize;
use std::path::PathBuf;
use toml::Value;

/// Which motion the image shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motion {
    X,
    Y,
    #[default]
    Sum,
}

/// What `modes` is asked.
#[derive(Clone, Debug, Default)]
pub struct ModesOptions {
    pub video: PathBuf,
    /// The frequency of the image, Hz.
    pub at_hz: f64,
    /// Output PNG: phase as hue, amplitude as brightness.
    pub output: PathBuf,
    /// Also the complex image as .npy.
    pub npy: Option<PathBuf>,
    pub fps: Option<f64>,
    /// The object: a rectangle and/or a mask, and the pyramid.
    pub region: Region,
    /// σ_b of the Gaussian blur, input pixels.
    pub sigma: Option<f64>,
    pub motion: Motion,
    pub exponent: Option<f64>,
    /// Pyramid scale (0 = finest).
    pub scale: Option<usize>,
    /// Do not divide by the blurred weights.
    pub unnormalized: bool,
    pub run: RunSettings,
}

/// What `modes` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct ModalImagesReport {
    pub freq_hz: f64,
    pub png: PathBuf,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub npy: Option<PathBuf>,
}

/// The graph `file -> modes` with the options set (each names its flag in errors).
pub fn modes_pipeline(o: &ModesOptions) -> Result<PipelineDecl> {
    let mut decl = pipeline::empty("modes", "recording -> modal image (vibroscope modes)");
    let mut src = pipeline::new_stage("src", "file", &[], by("VIDEO"));
    set_param(&mut src, "path", path_value(&o.video), by("VIDEO"));
    decl.stages.push(src);
    if let Some(f) = o.fps {
        pipeline::apply_fps(&mut decl, f)?;
    }
    let mut st = pipeline::new_stage("modes", "modes", &["src"], by("vibroscope modes"));
    set_param(&mut st, "freq_hz", Value::Float(o.at_hz), by("--at"));
    set_param(&mut st, "path", path_value(&o.output), by("-o"));
    if let Some(n) = &o.npy {
        set_param(&mut st, "npy", path_value(n), by("--npy"));
    }
    if let Some(s) = o.sigma {
        set_param(&mut st, "sigma_px", Value::Float(s), by("--sigma"));
    }
    let m = match o.motion {
        Motion::X => "x",
        Motion::Y => "y",
        Motion::Sum => "sum",
    };
    set_param(&mut st, "motion", Value::String(m.into()), by("--motion"));
    if let Some(e) = o.exponent {
        set_param(&mut st, "exponent", Value::Float(e), by("--exponent"));
    }
    if let Some(s) = o.scale {
        set_param(&mut st, "scale", int(s), by("--scale"));
    }
    if o.unnormalized {
        set_param(
            &mut st,
            "normalize",
            Value::Boolean(false),
            by("--unnormalized"),
        );
    }
    decl.stages.push(st);
    o.region.apply(&mut decl, "modes")?;
    Ok(decl)
}

/// Runs `modes`.
pub fn modes(o: &ModesOptions) -> Result<(ModalImagesReport, RunReport)> {
    let mut outputs = vec![o.output.as_path()];
    outputs.extend(o.npy.as_deref());
    crate::error::check_outputs(&[&o.video], &outputs)?;
    let decl = modes_pipeline(o)?;
    let run = pipeline::run(&decl, o.run)?;
    Ok((
        ModalImagesReport {
            freq_hz: o.at_hz,
            png: o.output.clone(),
            npy: o.npy.clone(),
        },
        run,
    ))
}
