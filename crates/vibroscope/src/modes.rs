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
    /// Also a figure to read: the image enlarged and laid over the
    /// recording's first frame, with a title, a phase wheel and an
    /// amplitude key ([`crate::io::plot::modal_figure`]).
    pub figure: Option<PathBuf>,
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
    #[serde(skip_serializing_if = "Option::is_none")]
    pub figure: Option<PathBuf>,
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
    outputs.extend(o.figure.as_deref());
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
    let (h, w, mut data) = crate::math::modal::read_npy_complex64(&bytes)
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
    if let Some(f) = &o.figure {
        let label = if o.unnormalized {
            "A²-weighted motion (no unit)".to_string()
        } else {
            format!("amplitude ({unit})")
        };
        write_figure(f, o, &data, w, k, &label)?;
    }
    if let (Some(n), true) = (&o.npy, k != 1.0) {
        for c in data.iter_mut() {
            *c *= k as f32;
        }
        crate::io::atomic::write_atomic(n, &crate::math::modal::npy_complex64(&data, w, h))?;
    }
    Ok((
        ModalImagesReport {
            freq_hz: o.at_hz,
            png: o.output.clone(),
            npy: o.npy.clone(),
            figure: o.figure.clone(),
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

/// Writes `modes --figure`: the image (`data`, `w` wide, in px; `k` to the
/// key's unit) over the recording's first frame, titled and keyed.
fn write_figure(
    path: &std::path::Path,
    o: &ModesOptions,
    data: &[crate::math::modal::Complex32],
    w: usize,
    k: f64,
    label: &str,
) -> Result<()> {
    use crate::io::plot::{modal_figure, AmplitudeKey, Rgb};
    use crate::math::modal::{overlay_rgb, render_rgb_data, Visual};
    let h = data.len() / w.max(1);
    let exponent = o.exponent.unwrap_or(1.0);
    let rgb = render_rgb_data(data, Visual { exponent });
    let frame = first_frame_gray(&o.video)?;
    let pixels = match frame {
        Some((fw, fh, gray)) if (fw, fh) == (w, h) => overlay_rgb(&rgb, &gray),
        _ => rgb,
    };
    let (lo, hi) = data
        .iter()
        .map(|c| f64::from(c.norm()))
        .filter(|a| a.is_finite())
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), a| {
            (lo.min(a), hi.max(a))
        });
    let lo = if lo.is_finite() { lo } else { 0.0 };
    let motion = match o.motion {
        Motion::X => "x",
        Motion::Y => "y",
        Motion::Sum => "x + y",
    };
    let mut name = o
        .video
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    if name.chars().count() > 40 {
        name = name.chars().take(39).chain(['…']).collect();
    }
    let caption = format!(
        "{name}: mode at {} Hz, {motion} motion ({} pyramid)",
        o.at_hz,
        o.region.pyramid.name()
    );
    let img = Rgb {
        width: w as u32,
        height: h as u32,
        pixels,
    };
    let key = AmplitudeKey {
        lo: lo * k,
        hi: hi * k,
        exponent,
        label,
    };
    let fig = modal_figure(&img, &caption, &key).map_err(crate::io::Error::from)?;
    let png = fig.png().map_err(crate::io::Error::from)?;
    crate::io::atomic::write_atomic(path, &png)?;
    Ok(())
}

/// The recording's first frame as 8-bit gray, stretched to its own range;
/// none for a recording with no frame.
fn first_frame_gray(video: &std::path::Path) -> Result<Option<(usize, usize, Vec<u8>)>> {
    use crate::io::{self, Depth, FrameDest};
    let mut reader = io::open(video, io::Format::Auto).map_err(|e| match e {
        io::VideoError::Io { .. } => Error::from(e),
        other => Error::input(video, other.to_string()),
    })?;
    let info = reader.info().clone();
    let (w, h) = (info.width as usize, info.height as usize);
    let values: Vec<f32> = match info.depth {
        Depth::U8 => {
            let mut b = vec![0u8; w * h];
            if reader.read_frame(FrameDest::U8(&mut b))?.is_none() {
                return Ok(None);
            }
            b.iter().map(|&v| f32::from(v)).collect()
        }
        Depth::U16 => {
            let mut b = vec![0u16; w * h];
            if reader.read_frame(FrameDest::U16(&mut b))?.is_none() {
                return Ok(None);
            }
            b.iter().map(|&v| f32::from(v)).collect()
        }
    };
    let lo = values.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let range = (hi - lo).max(1.0);
    let gray = values
        .iter()
        .map(|v| ((v - lo) / range * 255.0).round() as u8)
        .collect();
    Ok(Some((w, h, gray)))
}
