//! A modal image of a recording at one frequency (thesis ch. 3.5, Eq.
//! 3.18-3.19): the engine's `modes` sink fed by a file source, over a
//! region or mask, with either pyramid.
//!
//! Units: a normalised modal image is motion (its modulus the amplitude
//! of the mode's sinusoid, px). The recipe reads the complex image back
//! and reports its peak; with a scale (`--scale`, `--known-length`) the
//! `.npy` is rewritten in µm (peak below 1 mm) or mm and the peak says
//! which. An unnormalised image is weighted by the squared local
//! amplitude, not motion: it takes no scale.

use crate::engine::config::{set_param, PipelineDecl};
use crate::engine::RunReport;
use crate::error::{Error, Result};
use crate::pipeline::{self, by, int, path_value, Region, RunSettings};
use crate::units::{px_to, Quantity, Scale, ScaleArg, Unit};
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
    pub pyramid_scale: Option<usize>,
    /// Pixels to millimetres on the object; none: the `.npy` in px.
    pub scale: Option<ScaleArg>,
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
    /// The pixel of the largest amplitude and its amplitude, in `unit`
    /// (the `.npy`'s unit); none for an all-zero image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak: Option<ModePeak>,
    pub unit: Unit,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
}

/// Where a modal image is largest.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ModePeak {
    pub x: usize,
    pub y: usize,
    /// Amplitude of the mode's sinusoid there (0-peak), in the report's unit.
    pub amplitude: f64,
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
    if let Some(s) = o.pyramid_scale {
        set_param(&mut st, "scale", int(s), by("--pyramid-scale"));
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
    if o.unnormalized && o.scale.is_some() {
        return Err(Error::usage(
            "--scale",
            "an --unnormalized image is weighted by the squared local amplitude, not motion: it has no length unit (drop --unnormalized or the scale)",
        ));
    }
    let scale = crate::spectrum::resolve_scale(&o.video, o.fps, o.scale.as_ref())?;
    // The complex image is always written, to read its peak: to the
    // user's --npy, else to a temporary sibling of the PNG.
    let npy = match &o.npy {
        Some(n) => n.clone(),
        None => crate::io::atomic::temp_sibling(&o.output.with_extension("npy")),
    };
    let mut with_npy = o.clone();
    with_npy.npy = Some(npy.clone());
    let decl = modes_pipeline(&with_npy)?;
    let run = pipeline::run(&decl, o.run);
    let read = run.and_then(|run| {
        Ok((
            run,
            std::fs::read(&npy).map_err(|e| {
                Error::input(&npy, format!("cannot read the modal image back: {e}"))
            })?,
        ))
    });
    if o.npy.is_none() {
        let _ = std::fs::remove_file(&npy);
    }
    let (run, bytes) = read?;
    let (w, _h, mut data) = crate::math::modal::read_npy_complex64(&bytes)
        .map_err(|e| Error::input(&npy, format!("cannot read the modal image back: {e}")))?;
    let peak = data
        .iter()
        .enumerate()
        .map(|(i, c)| (i, c.norm()))
        .filter(|(_, a)| a.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|(_, a)| *a > 0.0);
    let largest = peak.map_or(0.0, |(_, a)| f64::from(a));
    let unit = if o.unnormalized {
        Unit::default()
    } else {
        Scale::unit(scale.as_ref(), Quantity::Displacement, largest)
    };
    let k = px_to(unit, scale.as_ref());
    if let (Some(n), true) = (&o.npy, k != 1.0) {
        for c in data.iter_mut() {
            *c *= k as f32;
        }
        let (w, h) = (w, data.len() / w.max(1));
        crate::io::atomic::write_atomic(n, &crate::math::modal::npy_complex64(&data, w, h))?;
    }
    Ok((
        ModalImagesReport {
            freq_hz: o.at_hz,
            png: o.output.clone(),
            npy: o.npy.clone(),
            peak: peak.map(|(i, a)| ModePeak {
                x: i % w.max(1),
                y: i / w.max(1),
                amplitude: f64::from(a) * k,
            }),
            unit,
            scale,
        },
        run,
    ))
}
