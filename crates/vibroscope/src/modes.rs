//! A modal image of a recording at one frequency (thesis ch. 3.5, Eq.
//! 3.18-3.19): the engine's `modes` sink fed by a file source, over a
//! region or mask, with either pyramid.
//!
//! Units: a normalised modal image is motion (its modulus the amplitude
//! of the mode's sinusoid, px). The recipe reads the complex image back
//! and reports its peak; with a scale (`--scale`, `--known-length`) the
//! `.npy` is rewritten in µm (peak below 1 mm) or mm and the peak says
//! which. An unnormalised image is motion weighted by the texture's
//! information about it (A² g², relative to its largest), not motion: it
//! takes no scale.

use crate::engine::config::PipelineDecl;
use crate::engine::RunReport;
use crate::error::{Error, Result};
pub use crate::math::modal::{align_phase, read_npy_complex64};
use crate::pipeline::{self, by, put, Region, RunSettings};
use crate::stages::params::{FileParams, ModesParams};
use crate::units::{px_to, Quantity, Scale, ScaleArg, Unit};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Which motion the image shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motion {
    X,
    Y,
    #[default]
    Sum,
}

impl Motion {
    /// The `modes` stage's value.
    pub fn param(self) -> crate::math::modal::Motion {
        match self {
            Motion::X => crate::math::modal::Motion::X,
            Motion::Y => crate::math::modal::Motion::Y,
            Motion::Sum => crate::math::modal::Motion::Sum,
        }
    }
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
    /// Also a video of the mode shape moving (`.y4m`, or `.mp4` and what
    /// else ffmpeg writes): the first frame warped by the image along
    /// `motion` (x or y) through its cycle, the image's 99.5th percentile
    /// of amplitude scaled to `animate_px` (default [`DEFAULT_ANIMATE_PX`]).
    pub animate: Option<PathBuf>,
    pub animate_px: Option<f64>,
    /// Further frequencies imaged in the same pass ([`modes_all`]); each
    /// image's files are then named after its frequency
    /// ([`per_frequency`]).
    pub also_at_hz: Vec<f64>,
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
    #[serde(skip_serializing_if = "Option::is_none")]
    pub animation: Option<PathBuf>,
    /// The pixel of the largest amplitude and its amplitude, in `unit`
    /// (the `.npy`'s unit); none for an all-zero image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak: Option<ModePeak>,
    pub unit: Unit,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// The image's mode-shape checks (MPC, MPD): near 1 and 0 for a real
    /// standing mode; none for an all-zero image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<crate::math::modal::ShapeChecks>,
}

/// Where a modal image is largest.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ModePeak {
    pub x: usize,
    pub y: usize,
    /// Amplitude of the mode's sinusoid there (0-peak), in the report's unit.
    pub amplitude: f64,
}

/// Every frequency imaged: `at_hz`, then `also_at_hz`.
pub fn frequencies(o: &ModesOptions) -> Vec<f64> {
    std::iter::once(o.at_hz)
        .chain(o.also_at_hz.iter().copied())
        .collect()
}

/// Where frequency `f`'s file goes: `path` itself when one frequency is
/// imaged, else `STEM-{f}hz.EXT` beside it (`m.png` -> `m-80.8hz.png`).
pub fn per_frequency(path: &Path, f: f64, many: bool) -> PathBuf {
    if !many {
        return path.to_path_buf();
    }
    let stem = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(e) => format!("{stem}-{f}hz.{}", e.to_string_lossy()),
        None => format!("{stem}-{f}hz"),
    };
    path.with_file_name(name)
}

/// The graph `file -> modes` with the options set (each names its flag in
/// errors): one `modes` stage per frequency (`modes`, `modes2`, ...), all
/// fed by one decoding of the recording.
pub fn modes_pipeline(o: &ModesOptions) -> Result<PipelineDecl> {
    let freqs = frequencies(o);
    let many = freqs.len() > 1;
    let npys: Vec<Option<PathBuf>> = freqs
        .iter()
        .map(|&f| o.npy.as_deref().map(|n| per_frequency(n, f, many)))
        .collect();
    pipeline_with(o, &npys)
}

/// [`modes_pipeline`] with each frequency's `.npy` given.
fn pipeline_with(o: &ModesOptions, npys: &[Option<PathBuf>]) -> Result<PipelineDecl> {
    let mut decl = pipeline::empty("modes", "recording -> modal image (vibroscope modes)");
    let mut src = pipeline::new_stage::<FileParams>("src", &[], by("VIDEO"));
    put(&mut src, FileParams::path, o.video.clone(), by("VIDEO"))?;
    decl.stages.push(src);
    if let Some(f) = o.fps {
        pipeline::apply_fps(&mut decl, f)?;
    }
    let freqs = frequencies(o);
    let many = freqs.len() > 1;
    for (k, (&f, npy)) in freqs.iter().zip(npys).enumerate() {
        let id = stage_id(k);
        let mut st = pipeline::new_stage::<ModesParams>(&id, &["src"], by("vibroscope modes"));
        put(&mut st, ModesParams::freq_hz, f, by("--at"))?;
        let png = per_frequency(&o.output, f, many);
        put(&mut st, ModesParams::path, png, by("-o"))?;
        if let Some(n) = npy {
            put(&mut st, ModesParams::npy, Some(n.clone()), by("--npy"))?;
        }
        if let Some(s) = o.sigma {
            put(&mut st, ModesParams::sigma_px, s, by("--sigma"))?;
        }
        put(
            &mut st,
            ModesParams::motion,
            o.motion.param(),
            by("--motion"),
        )?;
        if let Some(e) = o.exponent {
            put(&mut st, ModesParams::exponent, e, by("--exponent"))?;
        }
        if let Some(s) = o.pyramid_scale {
            let s = pipeline::count(s);
            put(&mut st, ModesParams::scale, s, by("--pyramid-scale"))?;
        }
        if o.unnormalized {
            put(&mut st, ModesParams::normalize, false, by("--unnormalized"))?;
        }
        // The region as `Region::apply` sets it: pyramid, roi, mask.
        put(
            &mut st,
            ModesParams::pyramid,
            o.region.pyramid,
            by("--pyramid"),
        )?;
        o.region.put_region::<ModesParams>(&mut st)?;
        decl.stages.push(st);
    }
    Ok(decl)
}

/// The `modes` stage of the `k`-th frequency.
fn stage_id(k: usize) -> String {
    if k == 0 {
        "modes".into()
    } else {
        format!("modes{}", k + 1)
    }
}

/// Runs `modes` at `at_hz` only (`also_at_hz` must be empty; see
/// [`modes_all`]).
pub fn modes(o: &ModesOptions) -> Result<(ModalImagesReport, RunReport)> {
    if !o.also_at_hz.is_empty() {
        return Err(Error::usage(
            "--at",
            "several frequencies give several images: use modes_all",
        ));
    }
    let (mut images, run) = modes_all(o)?;
    match images.pop() {
        Some(r) => Ok((r, run)),
        None => Err(Error::usage("--at", "no frequency")),
    }
}

/// Runs `modes` at every frequency in one pass over the recording: one
/// report per frequency, in order; with `figure`, one figure, or for
/// several frequencies one sheet of figures, one under the other.
pub fn modes_all(o: &ModesOptions) -> Result<(Vec<ModalImagesReport>, RunReport)> {
    let freqs = frequencies(o);
    let many = freqs.len() > 1;
    if freqs.len() > MAX_FREQUENCIES {
        return Err(Error::usage(
            "--at",
            format!(
                "at most {MAX_FREQUENCIES} frequencies in one run (each images every frame), got {}",
                freqs.len()
            ),
        ));
    }
    for (k, f) in freqs.iter().enumerate() {
        if freqs[..k].contains(f) {
            return Err(Error::usage("--at", format!("{f} Hz is given twice")));
        }
    }
    let pngs: Vec<PathBuf> = freqs
        .iter()
        .map(|&f| per_frequency(&o.output, f, many))
        .collect();
    let user_npys: Vec<Option<PathBuf>> = freqs
        .iter()
        .map(|&f| o.npy.as_deref().map(|n| per_frequency(n, f, many)))
        .collect();
    let animations: Vec<Option<PathBuf>> = freqs
        .iter()
        .map(|&f| o.animate.as_deref().map(|a| per_frequency(a, f, many)))
        .collect();
    let mut outputs: Vec<&Path> = pngs.iter().map(PathBuf::as_path).collect();
    outputs.extend(user_npys.iter().flatten().map(PathBuf::as_path));
    outputs.extend(o.figure.as_deref());
    outputs.extend(animations.iter().flatten().map(PathBuf::as_path));
    crate::error::check_outputs(&[&o.video], &outputs)?;
    let ffmpeg = match &o.animate {
        Some(a) => {
            if o.motion == Motion::Sum {
                return Err(Error::usage(
                    "--animate",
                    "needs --motion x or y: the sum of both has no direction to move along",
                ));
            }
            let px = o.animate_px.unwrap_or(DEFAULT_ANIMATE_PX);
            if !(px.is_finite() && px > 0.0 && px <= 100.0) {
                return Err(Error::usage(
                    "--animate-px",
                    format!("must be in (0, 100] px, got {px}"),
                ));
            }
            crate::magnify::output_needs_ffmpeg(a, crate::magnify::ffmpeg_present)?
        }
        None => false,
    };
    if o.unnormalized && o.scale.is_some() {
        return Err(Error::usage(
            "--scale",
            "an --unnormalized image is motion weighted by the texture's information about it, not motion: it has no length unit (drop --unnormalized or the scale)",
        ));
    }
    let scale = crate::spectrum::resolve_scale(&o.video, o.fps, o.scale.as_ref())?;
    // The complex image is always written, to read its peak: to the
    // user's --npy, else to a temporary sibling of the PNG.
    let npys: Vec<PathBuf> = user_npys
        .iter()
        .zip(&pngs)
        .map(|(n, png)| match n {
            Some(n) => n.clone(),
            None => crate::io::atomic::temp_sibling(&png.with_extension("npy")),
        })
        .collect();
    let decl = pipeline_with(o, &npys.iter().cloned().map(Some).collect::<Vec<_>>())?;
    let run = pipeline::run(&decl, o.run);
    let read = run.and_then(|run| {
        let bytes = npys
            .iter()
            .map(|n| {
                std::fs::read(n)
                    .map_err(|e| Error::input(n, format!("cannot read the modal image back: {e}")))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((run, bytes))
    });
    if o.npy.is_none() {
        for n in &npys {
            let _ = std::fs::remove_file(n);
        }
    }
    let (run, bytes) = read?;
    let frame = match (&o.figure, &o.animate) {
        (None, None) => None,
        _ => first_frame_gray(&o.video)?,
    };
    let mut reports = Vec::with_capacity(freqs.len());
    let mut figures = Vec::new();
    for (k, &f) in freqs.iter().enumerate() {
        let (h, w, mut data) = crate::math::modal::read_npy_complex64(&bytes[k]).map_err(|e| {
            Error::input(&npys[k], format!("cannot read the modal image back: {e}"))
        })?;
        let peak = data
            .iter()
            .enumerate()
            .map(|(i, c)| (i, c.norm()))
            .filter(|(_, a)| a.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|(_, a)| *a > 0.0);
        let largest = peak.map_or(0.0, |(_, a)| f64::from(a));
        let shape = crate::math::modal::shape_checks(&data);
        let unit = if o.unnormalized {
            Unit::default()
        } else {
            Scale::unit(scale.as_ref(), Quantity::Displacement, largest)
        };
        let kk = px_to(unit, scale.as_ref());
        if o.figure.is_some() {
            let label = if o.unnormalized {
                "texture-weighted motion (no unit)".to_string()
            } else {
                format!("amplitude ({unit})")
            };
            figures.push(figure(o, f, &data, w, kk, &label, frame.as_ref())?);
        }
        if let Some(a) = &animations[k] {
            let rest = frame_under(o, frame.as_ref(), w, h).ok_or_else(|| {
                Error::input(
                    &o.video,
                    "cannot animate: its first frame could not be read at the image's size",
                )
            })?;
            let px = o.animate_px.unwrap_or(DEFAULT_ANIMATE_PX);
            animate(a, ffmpeg, &data, (w, h), &rest, o.motion, px)?;
        }
        if let (Some(n), true) = (&user_npys[k], kk != 1.0) {
            for c in data.iter_mut() {
                *c *= kk as f32;
            }
            crate::io::atomic::write_atomic(n, &crate::math::modal::npy_complex64(&data, w, h))?;
        }
        reports.push(ModalImagesReport {
            freq_hz: f,
            png: pngs[k].clone(),
            npy: user_npys[k].clone(),
            figure: o.figure.clone(),
            animation: animations[k].clone(),
            peak: peak.map(|(i, a)| ModePeak {
                x: i % w.max(1),
                y: i / w.max(1),
                amplitude: f64::from(a) * kk,
            }),
            unit,
            scale,
            shape,
        });
    }
    if let Some(path) = &o.figure {
        let sheet = crate::io::plot::stack(&figures).map_err(crate::io::Error::from)?;
        let png = sheet.png().map_err(crate::io::Error::from)?;
        crate::io::atomic::write_atomic(path, &png)?;
    }
    Ok((reports, run))
}

/// Most frequencies in one `modes` run.
pub const MAX_FREQUENCIES: usize = 8;

/// The `--figure` of one frequency: the image (`data`, `w` wide, in px;
/// `k` to the key's unit) over the recording's first frame (`frame`: its
/// size and gray values), titled and keyed.
fn figure(
    o: &ModesOptions,
    freq_hz: f64,
    data: &[crate::math::modal::Complex32],
    w: usize,
    k: f64,
    label: &str,
    frame: Option<&(usize, usize, Vec<u8>)>,
) -> Result<crate::io::plot::Rgb> {
    use crate::io::plot::{modal_figure, AmplitudeKey, Rgb};
    use crate::math::modal::{overlay_rgb, render_rgb_data, Visual};
    let h = data.len() / w.max(1);
    let exponent = o.exponent.unwrap_or(1.0);
    let rgb = render_rgb_data(data, Visual { exponent });
    let pixels = match frame_under(o, frame, w, h) {
        Some(gray) => overlay_rgb(&rgb, &gray),
        None => rgb,
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
    let region = match &o.region.roi {
        Some(r) => format!(", region {},{},{},{}", r.x, r.y, r.w, r.h),
        None => String::new(),
    };
    let caption = format!(
        "{name}: mode at {freq_hz} Hz, {motion} motion ({} pyramid){region}",
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
    Ok(modal_figure(&img, &caption, &key).map_err(crate::io::Error::from)?)
}

/// The part of the first frame (`frame`: size and gray values) a `w` x
/// `h` image covers: the whole frame, or the `--roi` cropped from it.
fn frame_under(
    o: &ModesOptions,
    frame: Option<&(usize, usize, Vec<u8>)>,
    w: usize,
    h: usize,
) -> Option<Vec<u8>> {
    let (fw, fh, gray) = frame?;
    if (*fw, *fh) == (w, h) {
        return Some(gray.clone());
    }
    let r = o.region.roi.as_ref()?;
    let (x, y) = (r.x as usize, r.y as usize);
    ((r.w as usize, r.h as usize) == (w, h) && x + w <= *fw && y + h <= *fh).then(|| {
        (y..y + h)
            .flat_map(|row| gray[row * fw + x..row * fw + x + w].iter().copied())
            .collect()
    })
}

/// Frames per cycle and cycles of a `--animate` video (played at 24 fps:
/// one cycle a second, four seconds).
const ANIMATION_FRAMES: usize = 24;
const ANIMATION_CYCLES: usize = 4;

/// The default largest displacement of a `--animate` video, px of the
/// video.
pub const DEFAULT_ANIMATE_PX: f64 = 2.0;

/// Writes `--animate`: the first frame (`rest`, `w` x `h`) warped by the
/// mode shape (`data`, along `motion`) through one cycle of phase, four
/// times: D(θ) = g Re{U e^{-iθ}} with g making the 99.5th percentile of
/// |U| `px` pixels, rendered as interactive dynamic video renders (thesis 6.4,
/// [`crate::math::idv::Renderer`]), enlarged by a whole factor like the
/// figure; `.y4m`, or through ffmpeg anything else.
fn animate(
    path: &Path,
    ffmpeg: bool,
    data: &[crate::math::modal::Complex32],
    (w, h): (usize, usize),
    rest: &[u8],
    motion: Motion,
    px: f64,
) -> Result<()> {
    use crate::math::idv::{Complex64, Renderer, Shape};
    use crate::math::modal::{align_phase, Complex32};
    // The scale's reference is the 99.5th percentile of |U|, not its
    // largest value: a few outliers (at the frame's border, say) would
    // otherwise set it and leave the object still.
    let mut amps: Vec<f32> = data
        .iter()
        .map(|c| c.norm())
        .filter(|a| a.is_finite())
        .collect();
    let peak = if amps.is_empty() {
        0.0
    } else {
        let k = ((amps.len() - 1) as f64 * 0.995).round() as usize;
        *amps.select_nth_unstable_by(k, f32::total_cmp).1
    };
    if !(peak > 0.0 && peak.is_finite()) {
        return Err(Error::usage(
            "--animate",
            "the image has no motion at that frequency to animate",
        ));
    }
    // Enlarged like the figure (never shrunk); even sides for ffmpeg's 4:2:0.
    let z = crate::io::plot::figure_zoom(w, h).floor().max(1.0) as usize;
    let (dw, dh) = ((w * z) & !1, (h * z) & !1);
    if dw == 0 || dh == 0 {
        return Err(Error::usage(
            "--animate",
            format!("a {w}x{h} image is too small to animate"),
        ));
    }
    let g = (px * z as f64 / f64::from(peak)) as f32;
    let aligned = align_phase(data);
    let zero = vec![Complex32::new(0.0, 0.0); dw * dh];
    let mut along = zero.clone();
    let mut big = vec![0u8; dw * dh];
    for y in 0..dh {
        for x in 0..dw {
            let i = (y / z) * w + x / z;
            along[y * dw + x] = aligned[i] * g;
            big[y * dw + x] = rest[i];
        }
    }
    let shape = match motion {
        Motion::X => Shape { x: along, y: zero },
        Motion::Y => Shape { x: zero, y: along },
        Motion::Sum => {
            return Err(Error::usage(
                "--animate",
                "needs --motion x or y: the sum of both has no direction to move along",
            ))
        }
    };
    let rate = ANIMATION_FRAMES as f64;
    let mut r = Renderer::new(dw, dh);
    let shapes = [shape];
    let frames = (ANIMATION_FRAMES * ANIMATION_CYCLES) as u64;
    crate::magnify::write_gray_video(path, ffmpeg, (dw, dh), rate, frames, |k, out| {
        let theta = std::f64::consts::TAU * k as f64 / ANIMATION_FRAMES as f64;
        r.displacement(&shapes, &[Complex64::from_polar(1.0, -theta)]);
        r.warp(&big, out);
        Ok(())
    })
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
