//! Interactive dynamic video, the offline part (thesis ch. 6, issue 17):
//! an image-space modal basis measured from a video, saved and loaded as
//! a directory (see `docs/idv.md`), simulated under scripted pokes and
//! rendered by warping the rest frame.
//!
//! - [`extract_basis`]: modes from the significant peaks of the video's
//!   motion spectrum (`spectrum`'s graph, its SSI-cov damping) or from
//!   the user's frequencies or ranges; per mode one pass of modal images
//!   (Eq. 3.18-3.19) for x and y motion at its frequency, all modes and
//!   both axes in a single read of the video; each shape rotated so its
//!   dominant axis is real (6.4.2).
//! - [`save_basis`] / [`load_basis`]: `basis.json` (format name, version,
//!   size, modes) + `rest.pgm` + one complex64 `.npy` per mode and axis.
//! - [`Simulation`]: one exact oscillator per mode (6.4.3) driven by
//!   impulses (6.4.4, Eq. 6.6) at the pokes' times, so the state at any
//!   time does not depend on the output frame rate.
//! - [`idv`]: the command: basis, pokes, frames out (.y4m, or through
//!   ffmpeg any container).

use crate::error::{Error, Result, UsageError};
use crate::io::{self, Depth, FrameDest};
use crate::math::idv::{manipulate, modal_force, Oscillator, Renderer, Shape};
use crate::math::idv::{Complex32, Complex64};
use crate::math::modal::{npy_complex64, read_npy_complex64, ModalConfig, ModalImager, Motion};
use crate::pipeline::{Region, Roi, RunSettings};
use crate::spectrum::{run_spectrum, SpectrumOptions};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The basis directory's format name and version ([`load_basis`] checks both).
pub const BASIS_FORMAT: &str = "vibroscope-idv-basis";
pub const BASIS_VERSION: u32 = 1;
/// The manifest's file name inside a basis directory.
pub const MANIFEST: &str = "basis.json";
/// Modes kept by `--modes auto` at most.
pub const DEFAULT_MAX_MODES: usize = 8;

/// Which modes make the basis.
#[derive(Clone, Debug, PartialEq)]
pub enum ModeChoice {
    /// The significant peaks of the motion spectrum.
    Auto,
    /// A frequency each (Hz), or a range `[lo, hi]` whose most prominent
    /// peak is taken.
    Listed(Vec<[f64; 2]>),
}

impl std::str::FromStr for ModeChoice {
    type Err = UsageError;
    /// `auto` or `F1,F2,LO-HI,...` (Hz).
    fn from_str(s: &str) -> std::result::Result<ModeChoice, UsageError> {
        if s.trim().eq_ignore_ascii_case("auto") {
            return Ok(ModeChoice::Auto);
        }
        let bad = |m: String| UsageError::new("--modes", m);
        let num = |t: &str| -> std::result::Result<f64, UsageError> {
            match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
                _ => Err(bad(format!(
                    "`{t}` is not a frequency in Hz > 0 (give auto, or F1,F2,.. or LO-HI ranges)"
                ))),
            }
        };
        let mut v = Vec::new();
        for part in s.split(',') {
            match part.split_once('-') {
                Some((lo, hi)) => {
                    let (lo, hi) = (num(lo)?, num(hi)?);
                    if lo >= hi {
                        return Err(bad(format!("range `{part}` is empty (LO must be < HI)")));
                    }
                    v.push([lo, hi]);
                }
                None => {
                    let f = num(part)?;
                    v.push([f, f]);
                }
            }
        }
        Ok(ModeChoice::Listed(v))
    }
}

/// How the basis is measured.
#[derive(Clone, Debug)]
pub struct BasisOptions {
    pub video: PathBuf,
    pub fps: Option<f64>,
    /// The object: mask (and rectangle for the spectrum) and pyramid.
    pub region: Region,
    pub modes: ModeChoice,
    /// At most this many modes with `Auto`.
    pub max_modes: usize,
    /// Pyramid scale of the shapes (0 = finest).
    pub scale: usize,
    /// σ_b of the shapes' blur, input pixels.
    pub sigma_px: f64,
    pub run: RunSettings,
    /// Called with (frames read, frames expected) while reading the video.
    pub progress: Option<fn(u64, Option<u64>)>,
}

impl BasisOptions {
    pub fn new(video: impl Into<PathBuf>) -> BasisOptions {
        BasisOptions {
            video: video.into(),
            fps: None,
            region: Region::default(),
            modes: ModeChoice::Auto,
            max_modes: DEFAULT_MAX_MODES,
            scale: 1,
            sigma_px: crate::stages::sinks::modes::DEFAULT_SIGMA_PX,
            run: RunSettings::default(),
            progress: None,
        }
    }
}

/// One mode of a basis.
#[derive(Clone, Debug)]
pub struct Mode {
    /// Damped frequency, Hz.
    pub freq_hz: f64,
    /// Damping ratio ξ.
    pub damping: f64,
    /// Where ξ came from (`lorentzian`, `ssi_cov`, `assumed`).
    pub damping_method: String,
    /// x and y displacement per pixel, px per unit modal coordinate.
    pub shape: Shape,
}

/// An image-space modal basis: the rest frame and the modes.
#[derive(Clone, Debug)]
pub struct Basis {
    pub width: usize,
    pub height: usize,
    /// The rest frame (the video's first frame, 8-bit grey).
    pub rest: Vec<u8>,
    /// The rest frame in colour, when the video has colour (and ffmpeg
    /// decodes it): Y, Cb and Cr planes at full resolution (4:4:4),
    /// rendered warped together instead of [`Basis::rest`].
    pub colour: Option<RestColour>,
    /// The capture rate of the video it came from.
    pub fps: f64,
    pub modes: Vec<Mode>,
    /// What was assumed or dropped while measuring it.
    pub notes: Vec<String>,
}

/// The colour rest frame: 8-bit Y, Cb, Cr planes, each `width x height`.
#[derive(Clone, Debug, PartialEq)]
pub struct RestColour {
    pub planes: [Vec<u8>; 3],
    /// Full-range (0-255) luma, or video range (16-235).
    pub full_range: bool,
}

/// The first frame of `video` in colour (4:4:4) from ffmpeg, when the
/// video has colour, ffmpeg runs, and the frame is `w x h`; otherwise
/// none, with a note saying why when colour was lost.
fn rest_colour(
    video: &Path,
    info: &io::VideoInfo,
    (w, h): (usize, usize),
    notes: &mut Vec<String>,
) -> Option<RestColour> {
    let crate::magnify::Colour::Yes { video_range } = crate::magnify::has_colour(video, info)
    else {
        return None;
    };
    let out = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-nostdin", "-i"])
        .arg(io::ffmpeg_input(video))
        .args([
            "-frames:v",
            "1",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "yuv444p",
            "-",
        ])
        .output();
    let n = w * h;
    match out {
        Ok(o) if o.status.success() && o.stdout.len() == 3 * n => {
            notes.push("colour kept: the first frame's Y, Cb and Cr move together".into());
            let b = o.stdout;
            Some(RestColour {
                planes: [b[..n].to_vec(), b[n..2 * n].to_vec(), b[2 * n..].to_vec()],
                full_range: !video_range,
            })
        }
        _ => {
            notes.push(
                "colour is not kept: ffmpeg could not decode the first frame in colour; \
                 the frames are grey"
                    .into(),
            );
            None
        }
    }
}

/// A one-frame 4:4:4 Y4M of `c` (how a basis stores its colour rest frame).
fn y4m_444_header((w, h): (usize, usize), rate: f64, full_range: bool) -> String {
    let (num, den) = if rate.fract() == 0.0 && rate <= u32::MAX as f64 {
        (rate as u64, 1)
    } else {
        ((rate * 1000.0).round() as u64, 1000)
    };
    let range = if full_range { "FULL" } else { "LIMITED" };
    format!("YUV4MPEG2 W{w} H{h} F{num}:{den} Ip A1:1 C444 XCOLORRANGE={range}\n")
}

/// Reads a colour rest frame written by [`save_basis`]: a 4:4:4 Y4M of
/// one `w x h` frame.
fn read_rest_colour(path: &Path, (w, h): (usize, usize)) -> Result<RestColour> {
    let bad = |m: String| Error::input(path, m);
    let bytes = std::fs::read(path).map_err(|e| bad(e.to_string()))?;
    let nl = bytes
        .iter()
        .position(|&b| b == b'\n')
        .ok_or_else(|| bad("no Y4M header".into()))?;
    let head = String::from_utf8_lossy(&bytes[..nl]).to_string();
    let fields: Vec<&str> = head.split(' ').collect();
    let want = [format!("W{w}"), format!("H{h}")];
    if fields.first() != Some(&"YUV4MPEG2")
        || !want.iter().all(|f| fields.contains(&f.as_str()))
        || !fields.contains(&"C444")
    {
        return Err(bad(format!(
            "is not a {w}x{h} 4:4:4 Y4M frame (header `{head}`)"
        )));
    }
    let full_range = fields.contains(&"XCOLORRANGE=FULL");
    let body = &bytes[nl + 1..];
    let n = w * h;
    let fnl = body.iter().position(|&b| b == b'\n').unwrap_or(body.len());
    if !body.starts_with(b"FRAME") || body.len() != fnl + 1 + 3 * n {
        return Err(bad(format!(
            "does not hold exactly one {w}x{h} 4:4:4 frame"
        )));
    }
    let p = &body[fnl + 1..];
    Ok(RestColour {
        planes: [p[..n].to_vec(), p[n..2 * n].to_vec(), p[2 * n..].to_vec()],
        full_range,
    })
}

/// A peak of the spectrum: frequency, damping, method.
struct Picked {
    freq_hz: f64,
    damping: f64,
    method: String,
}

/// A quadrant at least this many pixels on each side is searched for
/// modes of its own (see [`pick_modes`]).
const MIN_QUADRANT_PX: u32 = 16;

/// A quadrant with fewer pixels of the mask than this is not searched.
const MIN_QUADRANT_MASK_PX: usize = 64;

/// The region cut into 2 x 2 (see [`pick_modes`]): the rectangle of the
/// mask's pixels when there is a mask (already limited to the roi), else
/// the roi, else the frame; nothing when a quarter would be smaller than
/// [`MIN_QUADRANT_PX`] on a side, and no quarter holding fewer than
/// [`MIN_QUADRANT_MASK_PX`] of the mask's pixels.
fn quadrants(region: &Region, mask: Option<&[bool]>, width: usize, height: usize) -> Vec<Roi> {
    let frame = Roi {
        x: 0,
        y: 0,
        w: width as u32,
        h: height as u32,
    };
    let r = match mask {
        Some(m) => {
            let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
            for (i, _) in m.iter().enumerate().filter(|(_, &v)| v) {
                let (x, y) = (i % width, i / width);
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
            if x0 >= x1 {
                return Vec::new();
            }
            Roi {
                x: x0 as u32,
                y: y0 as u32,
                w: (x1 - x0) as u32,
                h: (y1 - y0) as u32,
            }
        }
        None => region.roi.unwrap_or(frame),
    };
    let (w0, h0) = (r.w / 2, r.h / 2);
    if w0 < MIN_QUADRANT_PX || h0 < MIN_QUADRANT_PX {
        return Vec::new();
    }
    let (w1, h1) = (r.w - w0, r.h - h0);
    let all = [
        (r.x, r.y, w0, h0),
        (r.x + w0, r.y, w1, h0),
        (r.x, r.y + h0, w0, h1),
        (r.x + w0, r.y + h0, w1, h1),
    ];
    all.into_iter()
        .map(|(x, y, w, h)| Roi { x, y, w, h })
        .filter(|q| {
            mask.is_none_or(|m| {
                let (x0, y0) = (q.x as usize, q.y as usize);
                let (x1, y1) = (x0 + q.w as usize, y0 + q.h as usize);
                (y0..y1)
                    .map(|y| {
                        m[y * width + x0..y * width + x1]
                            .iter()
                            .filter(|&&v| v)
                            .count()
                    })
                    .sum::<usize>()
                    >= MIN_QUADRANT_MASK_PX
            })
        })
        .collect()
}

/// The modes to measure, from the spectrum's peaks. With `Auto` the
/// peaks of the region's spectrum and of its four quadrants' are pooled:
/// the spectrum graph averages each band's motion over its region before
/// the power is taken, so a mode whose parts move in opposite phase (a
/// twist, a mode with a node across the region) cancels in the whole
/// region's spectrum; a quadrant sees it. (Eq. 3.17 sums the power of
/// every local signal for the same reason; quadrants are its coarsest
/// form.) The listed choice uses the whole region's spectrum only.
fn pick_modes(
    o: &BasisOptions,
    size: (usize, usize),
    mask: Option<&[bool]>,
    notes: &mut Vec<String>,
) -> Result<Vec<Picked>> {
    let mut so = SpectrumOptions::new(&o.video, PathBuf::new());
    so.fps = o.fps;
    so.region = o.region.clone();
    so.run = o.run;
    so.peaks = match &o.modes {
        ModeChoice::Auto => o.max_modes,
        ModeChoice::Listed(_) => 32,
    };
    let (report, _) = run_spectrum(&so, true)?;
    let mut reports = vec![report];
    if o.modes == ModeChoice::Auto {
        for q in quadrants(&o.region, mask, size.0, size.1) {
            so.region.roi = Some(q);
            // A quadrant is a second look; one the spectrum cannot take
            // (too little texture in it, say) is left out, and said.
            match run_spectrum(&so, true) {
                Ok((r, _)) => reports.push(r),
                Err(e) => notes.push(format!("quadrant {q} not searched for modes: {e}")),
            }
        }
    }
    let report = &reports[0];
    let mut peaks: Vec<&crate::peaks::Peak> = reports
        .iter()
        .flat_map(|r| r.peaks.iter())
        .filter(|p| p.frequency_hz.is_finite() && p.frequency_hz > 0.0)
        .collect();
    // A broadband-driven mode can show as a split peak: of peaks closer
    // than 4% (or 3 bins), only the most prominent is a mode (modes must
    // be well spaced, 6.3).
    peaks.sort_by(|a, b| b.prominence_db.total_cmp(&a.prominence_db));
    let mut kept: Vec<&crate::peaks::Peak> = Vec::new();
    for p in peaks {
        let near = |q: &&crate::peaks::Peak| {
            (q.frequency_hz - p.frequency_hz).abs()
                <= (3.0 * report.resolution_hz).max(0.04 * p.frequency_hz)
        };
        if !kept.iter().any(near) {
            kept.push(p);
        }
    }
    let peaks = kept;
    let damping = |p: &crate::peaks::Peak| -> (f64, String) {
        if p.damping_ratio.is_finite() && p.damping_ratio > 0.0 && p.damping_ratio < 1.0 {
            (p.damping_ratio, p.damping_method.clone())
        } else {
            (0.02, "assumed".into())
        }
    };
    let mut out = Vec::new();
    match &o.modes {
        ModeChoice::Auto => {
            if peaks.is_empty() {
                return Err(Error::Analysis(format!(
                    "{}: no significant peak in the motion spectrum: nothing vibrates \
                     enough to make a basis (give --modes F1,F2,.. if you know the frequencies)",
                    o.video.display()
                )));
            }
            for p in peaks.iter().take(o.max_modes) {
                let (d, m) = damping(p);
                out.push(Picked {
                    freq_hz: p.frequency_hz,
                    damping: d,
                    method: m,
                });
            }
        }
        ModeChoice::Listed(list) => {
            let df = report.resolution_hz;
            for &[lo, hi] in list {
                let (a, b) = if lo == hi {
                    let tol = (2.0 * df).max(0.02 * lo);
                    (lo - tol, lo + tol)
                } else {
                    (lo, hi)
                };
                let best = peaks
                    .iter()
                    .filter(|p| p.frequency_hz >= a && p.frequency_hz <= b)
                    .max_by(|x, y| x.prominence_db.total_cmp(&y.prominence_db));
                match best {
                    Some(p) => {
                        let (d, m) = damping(p);
                        out.push(Picked {
                            freq_hz: if lo == hi { lo } else { p.frequency_hz },
                            damping: d,
                            method: m,
                        });
                    }
                    None if lo == hi => {
                        notes.push(format!(
                            "no spectral peak near {lo} Hz: its damping is assumed 0.02"
                        ));
                        out.push(Picked {
                            freq_hz: lo,
                            damping: 0.02,
                            method: "assumed".into(),
                        });
                    }
                    None => {
                        return Err(Error::Analysis(format!(
                        "{}: no significant peak in the motion spectrum between {lo} and {hi} Hz",
                        o.video.display()
                    )))
                    }
                }
            }
        }
    }
    out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    Ok(out)
}

/// The mask of `region` as booleans, checked against the frame size.
fn read_mask(region: &Region, width: usize, height: usize) -> Result<Option<Vec<bool>>> {
    let Some(path) = &region.mask else {
        return Ok(None);
    };
    let img = io::image::read_gray16(path).map_err(|e| Error::File(e.into()))?;
    if img.width() as usize != width || img.height() as usize != height {
        return Err(Error::usage(
            "--mask",
            format!(
                "{} is {}x{}, the video's frames are {width}x{height}",
                path.display(),
                img.width(),
                img.height()
            ),
        ));
    }
    let mut m: Vec<bool> = img.pixels().map(|p| p.0[0] > 0).collect();
    if let Some(r) = &region.roi {
        for (i, v) in m.iter_mut().enumerate() {
            let (x, y) = ((i % width) as u32, (i / width) as u32);
            *v &= x >= r.x && x < r.x + r.w && y >= r.y && y < r.y + r.h;
        }
    }
    Ok(Some(m))
}

/// Measures a basis from a video (see the module documentation).
pub fn extract_basis(o: &BasisOptions) -> Result<Basis> {
    let mut notes = Vec::new();
    let (mut reader, fps) = crate::magnify::open_video(&o.video, o.fps)?;
    let info = reader.info().clone();
    let (w, h) = (info.width as usize, info.height as usize);
    let mask = read_mask(&o.region, w, h)?;
    let picked = pick_modes(o, (w, h), mask.as_deref(), &mut notes)?;
    let mut imagers = Vec::with_capacity(picked.len() * 2);
    for p in &picked {
        for motion in [Motion::X, Motion::Y] {
            let cfg = ModalConfig {
                freq_hz: p.freq_hz,
                scale: o.scale,
                sigma_px: o.sigma_px,
                motion,
                normalize: true,
                pyramid: o.region.pyramid,
            };
            let mut im = ModalImager::new(w, h, cfg).map_err(crate::math::MathError::from)?;
            if let Some(m) = &mask {
                im.set_mask(m)
                    .map_err(|e| Error::usage("--mask", format!("{}", e)))?;
            }
            imagers.push(im);
        }
    }
    let n = w * h;
    let (mut buf8, mut buf16) = (vec![0u8; n], vec![0u16; n]);
    let mut frame = vec![0f32; n];
    let mut rest = Vec::new();
    let mut k: u64 = 0;
    let scale16 = 255.0 / ((1u32 << info.bits.clamp(1, 16)) - 1) as f32;
    loop {
        let got = match info.depth {
            Depth::U8 => reader.read_frame(FrameDest::U8(&mut buf8))?,
            Depth::U16 => reader.read_frame(FrameDest::U16(&mut buf16))?,
        };
        let Some(fr) = got else { break };
        match info.depth {
            Depth::U8 => frame
                .iter_mut()
                .zip(&buf8)
                .for_each(|(f, &v)| *f = v as f32),
            Depth::U16 => frame
                .iter_mut()
                .zip(&buf16)
                .for_each(|(f, &v)| *f = v as f32 * scale16),
        }
        if k == 0 {
            rest = frame
                .iter()
                .map(|&v| v.round().clamp(0.0, 255.0) as u8)
                .collect();
        }
        let t_ns = match (o.fps, fr.timestamp_ns) {
            (None, Some(t)) => t,
            _ => (k as f64 / fps * 1e9).round() as i64,
        };
        // One pyramid analysis a frame: the first imager's, which the
        // others (every mode, both axes) follow, each with the bits it
        // would get on its own.
        if let Some((lead, rest)) = imagers.split_first_mut() {
            lead.push(&frame, t_ns)
                .map_err(crate::math::MathError::from)?;
            for im in rest {
                im.push_following(lead, &frame, t_ns)
                    .map_err(crate::math::MathError::from)?;
            }
        }
        k += 1;
        if let Some(cb) = o.progress {
            cb(k, info.frame_count);
        }
    }
    let colour = rest_colour(&o.video, &info, (w, h), &mut notes);
    let mut modes = Vec::with_capacity(picked.len());
    for (p, pair) in picked.iter().zip(imagers.chunks_exact_mut(2)) {
        let x = pair[0].finish().map_err(crate::math::MathError::from)?;
        let y = pair[1].finish().map_err(crate::math::MathError::from)?;
        let mut shape = Shape {
            x: x.data,
            y: y.data,
        };
        shape.align();
        modes.push(Mode {
            freq_hz: p.freq_hz,
            damping: p.damping,
            damping_method: p.method.clone(),
            shape,
        });
    }
    Ok(Basis {
        width: w,
        height: h,
        rest,
        colour,
        fps,
        modes,
        notes,
    })
}

/// One mode in `basis.json`.
#[derive(Serialize, Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct ModeEntry {
    freq_hz: f64,
    damping_ratio: f64,
    damping_method: String,
    x: String,
    y: String,
}

/// `basis.json`.
#[derive(Serialize, Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct Manifest {
    format: String,
    version: u32,
    width: usize,
    height: usize,
    fps: f64,
    rest: String,
    /// The colour rest frame, a one-frame 4:4:4 Y4M (absent: grey).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rest_colour: Option<String>,
    modes: Vec<ModeEntry>,
}

/// Writes `basis` into the directory `dir` (created if missing): every
/// file atomically, the manifest last. Returns the files written.
pub fn save_basis(basis: &Basis, dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|source| {
        Error::from(io::atomic::WriteError {
            path: dir.to_path_buf(),
            source,
        })
    })?;
    let mut written = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<()> {
        let p = dir.join(name);
        io::atomic::write_atomic(&p, bytes)?;
        written.push(p);
        Ok(())
    };
    let mut pgm = format!("P5\n{} {}\n255\n", basis.width, basis.height).into_bytes();
    pgm.extend_from_slice(&basis.rest);
    put("rest.pgm", &pgm)?;
    let rest_colour = match &basis.colour {
        Some(c) => {
            let size = (basis.width, basis.height);
            let mut y4m = y4m_444_header(size, basis.fps, c.full_range).into_bytes();
            y4m.extend_from_slice(b"FRAME\n");
            c.planes.iter().for_each(|p| y4m.extend_from_slice(p));
            put("rest.y4m", &y4m)?;
            Some("rest.y4m".to_string())
        }
        None => None,
    };
    let mut entries = Vec::new();
    for (k, m) in basis.modes.iter().enumerate() {
        let (xn, yn) = (format!("mode{k}_x.npy"), format!("mode{k}_y.npy"));
        put(&xn, &npy_complex64(&m.shape.x, basis.width, basis.height))?;
        put(&yn, &npy_complex64(&m.shape.y, basis.width, basis.height))?;
        entries.push(ModeEntry {
            freq_hz: m.freq_hz,
            damping_ratio: m.damping,
            damping_method: m.damping_method.clone(),
            x: xn,
            y: yn,
        });
    }
    let manifest = Manifest {
        format: BASIS_FORMAT.into(),
        version: BASIS_VERSION,
        width: basis.width,
        height: basis.height,
        fps: basis.fps,
        rest: "rest.pgm".into(),
        rest_colour,
        modes: entries,
    };
    let p = dir.join(MANIFEST);
    crate::json::write(&p, &manifest)?;
    written.push(p);
    Ok(written)
}

/// Reads a basis written by [`save_basis`], checking the format name and
/// version, every array's shape against the manifest's size, and each
/// mode's frequency and damping.
pub fn load_basis(dir: &Path) -> Result<Basis> {
    let mpath = dir.join(MANIFEST);
    let bad = |path: &Path, m: String| Error::input(path, m);
    let text = std::fs::read_to_string(&mpath).map_err(|e| bad(&mpath, e.to_string()))?;
    let m: Manifest = serde_json::from_str(&text)
        .map_err(|e| bad(&mpath, format!("not a basis manifest: {e}")))?;
    if m.format != BASIS_FORMAT {
        return Err(bad(
            &mpath,
            format!("format is `{}`, expected `{BASIS_FORMAT}`", m.format),
        ));
    }
    if m.version != BASIS_VERSION {
        return Err(bad(
            &mpath,
            format!(
                "basis version {} is not supported (this vibroscope reads version {BASIS_VERSION}); \
                 measure the basis again with --save-basis",
                m.version
            ),
        ));
    }
    if m.width == 0 || m.height == 0 || m.width.saturating_mul(m.height) > 1 << 28 {
        return Err(bad(
            &mpath,
            format!("frame size {}x{} is not usable", m.width, m.height),
        ));
    }
    if m.modes.is_empty() {
        return Err(bad(&mpath, "lists no mode".into()));
    }
    if !(m.fps.is_finite() && m.fps > 0.0) {
        return Err(bad(&mpath, format!("fps {} must be > 0", m.fps)));
    }
    // Only plain file names inside the directory.
    let inside = |name: &str| -> Result<PathBuf> {
        if name.is_empty() || name.contains('/') || name.contains('\\') || name.starts_with('.') {
            return Err(bad(
                &mpath,
                format!("`{name}` is not a file name in the basis directory"),
            ));
        }
        Ok(dir.join(name))
    };
    let rp = inside(&m.rest)?;
    let rest = io::image::read_gray16(&rp).map_err(|e| Error::File(e.into()))?;
    if rest.width() as usize != m.width || rest.height() as usize != m.height {
        return Err(bad(
            &rp,
            format!(
                "is {}x{}, the manifest says {}x{}",
                rest.width(),
                rest.height(),
                m.width,
                m.height
            ),
        ));
    }
    let max = rest.pixels().map(|p| p.0[0]).max().unwrap_or(0);
    let div = if max > 255 { 257.0 } else { 1.0 };
    let rest: Vec<u8> = rest
        .pixels()
        .map(|p| (p.0[0] as f64 / div).round() as u8)
        .collect();
    let read = |name: &str| -> Result<Vec<Complex32>> {
        let p = inside(name)?;
        let bytes = std::fs::read(&p).map_err(|e| bad(&p, e.to_string()))?;
        let (h, w, v) = read_npy_complex64(&bytes).map_err(|e| bad(&p, e.to_string()))?;
        if (w, h) != (m.width, m.height) {
            return Err(bad(
                &p,
                format!(
                    "shape ({h}, {w}) does not match the manifest's frame ({}, {})",
                    m.height, m.width
                ),
            ));
        }
        if v.iter().any(|c| !(c.re.is_finite() && c.im.is_finite())) {
            return Err(bad(&p, "holds values that are not finite".into()));
        }
        Ok(v)
    };
    let mut modes = Vec::with_capacity(m.modes.len());
    for (k, e) in m.modes.iter().enumerate() {
        if !(e.freq_hz.is_finite() && e.freq_hz > 0.0) {
            return Err(bad(
                &mpath,
                format!("modes[{k}].freq_hz must be > 0, got {}", e.freq_hz),
            ));
        }
        if !(e.damping_ratio.is_finite() && e.damping_ratio >= 0.0 && e.damping_ratio < 1.0) {
            return Err(bad(
                &mpath,
                format!(
                    "modes[{k}].damping_ratio must be in [0, 1), got {}",
                    e.damping_ratio
                ),
            ));
        }
        modes.push(Mode {
            freq_hz: e.freq_hz,
            damping: e.damping_ratio,
            damping_method: e.damping_method.clone(),
            shape: Shape {
                x: read(&e.x)?,
                y: read(&e.y)?,
            },
        });
    }
    let colour = match &m.rest_colour {
        Some(name) => Some(read_rest_colour(&inside(name)?, (m.width, m.height))?),
        None => None,
    };
    Ok(Basis {
        width: m.width,
        height: m.height,
        rest,
        colour,
        fps: m.fps,
        modes,
        notes: Vec::new(),
    })
}

/// What a scripted [`Poke`] does to the object at its time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PokeKind {
    /// A force impulse (Eq. 6.6, `--poke`): adds to the motion there is.
    #[default]
    Impulse,
    /// Direct manipulation (Eq. 6.7-6.8, `--pull`): the point is held
    /// displaced by (`dx`, `dy`) and let go; the motion before is replaced.
    Pull,
    /// Direct manipulation (Eq. 6.9, `--throw`): the point is at rest and
    /// moving along (`dx`, `dy`), swinging about as far; the motion before
    /// is replaced.
    Throw,
}

impl PokeKind {
    /// The command-line flag that gives it.
    pub fn flag(self) -> &'static str {
        match self {
            PokeKind::Impulse => "--poke",
            PokeKind::Pull => "--pull",
            PokeKind::Throw => "--throw",
        }
    }
}

/// A scripted poke: at time `t_s` at pixel (`x`, `y`) in the direction
/// (`dx`, `dy`) px, of relative `strength`: an impulse, or a pull or
/// throw of the point (see [`PokeKind`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Poke {
    pub t_s: f64,
    pub x: f64,
    pub y: f64,
    pub dx: f64,
    pub dy: f64,
    pub strength: f64,
    pub kind: PokeKind,
}

impl std::str::FromStr for Poke {
    type Err = UsageError;
    /// `T,X,Y,DX,DY[,STRENGTH]`: an impulse.
    fn from_str(s: &str) -> std::result::Result<Poke, UsageError> {
        Poke::parse(s, PokeKind::Impulse)
    }
}

impl Poke {
    /// `T,X,Y,DX,DY[,STRENGTH]` as a poke of `kind` (errors name its flag).
    pub fn parse(s: &str, kind: PokeKind) -> std::result::Result<Poke, UsageError> {
        let v: Vec<&str> = s.split(',').collect();
        let bad = |m: String| UsageError::new(kind.flag(), format!("`{s}`: {m}"));
        if !(5..=6).contains(&v.len()) {
            return Err(bad(
                "expected T,X,Y,DX,DY[,STRENGTH] (seconds, pixel, direction in px, strength)"
                    .into(),
            ));
        }
        let mut n = [0.0; 6];
        n[5] = 1.0;
        for (i, t) in v.iter().enumerate() {
            n[i] = t
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("`{t}` is not a number")))?;
        }
        if n[0] < 0.0 {
            return Err(bad(format!("time {} s is before the start", n[0])));
        }
        if n[3] == 0.0 && n[4] == 0.0 {
            return Err(bad("the direction DX,DY is zero".into()));
        }
        Ok(Poke {
            t_s: n[0],
            x: n[1],
            y: n[2],
            dx: n[3],
            dy: n[4],
            strength: n[5],
            kind,
        })
    }
}

impl Poke {
    /// The pixel index of the poked point; a usage error when it is
    /// outside a `width x height` frame.
    pub fn pixel(&self, width: usize, height: usize) -> std::result::Result<usize, UsageError> {
        let (x, y) = (self.x.round(), self.y.round());
        if x < 0.0 || y < 0.0 || x >= width as f64 || y >= height as f64 {
            return Err(UsageError::new(
                self.kind.flag(),
                format!(
                    "point ({}, {}) at t = {} s is outside the {width}x{height} frame",
                    self.x, self.y, self.t_s
                ),
            ));
        }
        Ok(y as usize * width + x as usize)
    }
}

/// What happens to the modes at a poke's time.
enum Event {
    /// Each mode's velocity jumps by this impulse.
    Kick(Vec<f64>),
    /// Each mode's state is set to this complex coordinate.
    Set(Vec<Complex64>),
}

/// The modal coordinates over time: one exact oscillator per mode, kicked
/// by impulses (Eq. 6.6) or set by direct manipulation (Eq. 6.7-6.9) at
/// the pokes' times.
pub struct Simulation {
    osc: Vec<Oscillator>,
    /// (time, what happens), sorted by time (stable: pokes at one time
    /// act in the order given).
    events: Vec<(f64, Event)>,
    next: usize,
    t: f64,
    q: Vec<Complex64>,
}

impl Simulation {
    /// `damping_scale` multiplies every mode's ξ.
    ///
    /// - An impulse's (`--poke`) on mode i is α Re(dᵀφ'_i(p)) (see
    ///   [`modal_force`]), with α chosen so that a poke of strength 1
    ///   moves the poked point by about |d| px along d: α = strength |d| /
    ///   Σ_i (d̂ᵀφ'_i(p))² / ω_i.
    /// - A pull or throw sets mode i to [`manipulate`]`(φ'_i, p, d, α)`
    ///   with α = strength / Σ_i |d̂ᵀφ'_i(p)|², so that a pull of strength
    ///   1 displaces p by exactly |d| px along d (and a throw swings it
    ///   about as far).
    pub fn new(
        basis: &Basis,
        pokes: &[Poke],
        damping_scale: f64,
    ) -> std::result::Result<Simulation, UsageError> {
        let osc: Vec<Oscillator> = basis
            .modes
            .iter()
            .map(|m| Oscillator::new(m.freq_hz, m.damping * damping_scale))
            .collect();
        let mut events = Vec::with_capacity(pokes.len());
        for pk in pokes {
            let p = pk.pixel(basis.width, basis.height)?;
            let len = pk.dx.hypot(pk.dy);
            let dir = [pk.dx / len, pk.dy / len];
            let reach: f64 = basis
                .modes
                .iter()
                .zip(&osc)
                .map(|(m, o)| match pk.kind {
                    PokeKind::Impulse => modal_force(&m.shape, p, dir, 1.0).powi(2) / o.omega,
                    _ => m.shape.along(p, dir).norm_sqr(),
                })
                .sum();
            if reach.is_nan() || reach <= 0.0 {
                return Err(UsageError::new(
                    pk.kind.flag(),
                    format!(
                        "point ({}, {}) at t = {} s moves with no mode along ({}, {}): every \
                         mode's shape is zero there (outside the mask, or at a node of them all); \
                         poke the object",
                        pk.x, pk.y, pk.t_s, pk.dx, pk.dy
                    ),
                ));
            }
            let event = match pk.kind {
                PokeKind::Impulse => {
                    let alpha = pk.strength * len / reach;
                    Event::Kick(
                        basis
                            .modes
                            .iter()
                            .map(|m| modal_force(&m.shape, p, dir, alpha))
                            .collect(),
                    )
                }
                PokeKind::Pull | PokeKind::Throw => {
                    let alpha = pk.strength / reach;
                    let d = [pk.dx, pk.dy];
                    let throw = pk.kind == PokeKind::Throw;
                    Event::Set(
                        basis
                            .modes
                            .iter()
                            .map(|m| manipulate(&m.shape, p, d, alpha, throw))
                            .collect(),
                    )
                }
            };
            events.push((pk.t_s, event));
        }
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let n = osc.len();
        Ok(Simulation {
            osc,
            events,
            next: 0,
            t: 0.0,
            q: vec![Complex64::new(0.0, 0.0); n],
        })
    }

    /// Advances to `t_s` (not before the current time) and returns the
    /// complex modal coordinates there.
    pub fn advance_to(&mut self, t_s: f64) -> &[Complex64] {
        while self.next < self.events.len() && self.events[self.next].0 <= t_s {
            let (tk, event) = &self.events[self.next];
            let h = tk - self.t;
            for (k, o) in self.osc.iter_mut().enumerate() {
                o.step(h, 0.0);
                match event {
                    Event::Kick(j) => o.kick(j[k]),
                    Event::Set(q) => o.set_q(q[k]),
                }
            }
            self.t = self.t.max(*tk);
            self.next += 1;
        }
        let h = t_s - self.t;
        for (o, q) in self.osc.iter_mut().zip(&mut self.q) {
            o.step(h, 0.0);
            *q = o.q();
        }
        self.t = self.t.max(t_s);
        &self.q
    }
}

/// [`crate::magnify::write_gray_video`] in colour: a 4:4:4 Y4M (or any
/// container through ffmpeg) whose frame `k` is drawn into the Y, Cb and
/// Cr planes by `draw(k, planes)`, in the range of the rest frame `c`.
fn write_colour_video(
    output: &Path,
    ffmpeg: bool,
    (w, h): (usize, usize),
    rate: f64,
    frames: u64,
    c: &RestColour,
    mut draw: impl FnMut(u64, &mut [Vec<u8>; 3]) -> Result<()>,
) -> Result<()> {
    use std::io::Write;
    crate::magnify::write_via_y4m(output, ffmpeg, |file, werr| {
        let mut wr = std::io::BufWriter::new(file);
        wr.write_all(y4m_444_header((w, h), rate, c.full_range).as_bytes())
            .map_err(werr)?;
        let mut planes = [vec![0u8; w * h], vec![0u8; w * h], vec![0u8; w * h]];
        for k in 0..frames {
            draw(k, &mut planes)?;
            wr.write_all(b"FRAME\n").map_err(werr)?;
            for p in &planes {
                wr.write_all(p).map_err(werr)?;
            }
        }
        wr.into_inner()
            .map_err(|e| werr(e.into_error()))?
            .sync_all()
            .map_err(werr)
    })
}

/// The renderer of [`crate::math::idv::Renderer`] on every core: Eq.
/// 6.10 and the sampling of each plane split into parts (pixels, rows)
/// run on a pool made once; the depth rule's scatter, which writes
/// anywhere, stays on one thread. Allocates nothing per frame.
pub struct FrameRenderer {
    pub r: Renderer,
    pool: Option<rayon::ThreadPool>,
    parts: usize,
}

impl FrameRenderer {
    /// `threads`: 0 = one per core.
    pub fn new(width: usize, height: usize, threads: usize) -> FrameRenderer {
        let threads = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        }
        .clamp(1, 64);
        let pool = if threads > 1 {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|i| format!("idv-render-{i}"))
                .build()
                .ok()
        } else {
            None
        };
        let parts = if pool.is_some() { threads } else { 1 };
        FrameRenderer {
            r: Renderer::new(width, height),
            pool,
            parts,
        }
    }

    /// The threads it renders on.
    pub fn threads(&self) -> usize {
        self.parts
    }

    /// Eq. 6.10 for the modal coordinates `q`, then the depth rule.
    pub fn displace(&mut self, shapes: &[Shape], q: &[Complex64]) {
        let Some(pool) = &self.pool else {
            self.r.displacement(shapes, q);
            self.r.resolve();
            return;
        };
        use rayon::prelude::*;
        let n = self.r.dx.len();
        let chunk = n.div_ceil(self.parts).max(1);
        let (dx, dy) = (&mut self.r.dx, &mut self.r.dy);
        pool.install(|| {
            dx.par_chunks_mut(chunk)
                .zip(dy.par_chunks_mut(chunk))
                .enumerate()
                .for_each(|(k, (a, b))| {
                    crate::math::idv::displacement_part(shapes, q, k * chunk, a, b)
                })
        });
        self.r.resolve();
    }

    /// One plane of the rest frame sampled where [`FrameRenderer::displace`] said.
    pub fn sample(&self, rest: &[u8], out: &mut [u8]) {
        let Some(pool) = &self.pool else {
            return self.r.sample(rest, out);
        };
        use rayon::prelude::*;
        let (w, h) = (self.r.width(), self.r.height());
        let rows = h.div_ceil(self.parts).max(1);
        let r = &self.r;
        pool.install(|| {
            out.par_chunks_mut(rows * w)
                .enumerate()
                .for_each(|(k, part)| r.sample_rows(rest, k * rows, part))
        });
    }
}

/// What `idv` is asked.
#[derive(Clone, Debug)]
pub struct IdvOptions {
    /// Measure the basis from a video, or load it (`basis_dir`).
    pub basis: BasisOptions,
    pub basis_dir: Option<PathBuf>,
    pub save_basis: Option<PathBuf>,
    pub pokes: Vec<Poke>,
    /// Output frame rate (default: the video's).
    pub rate_hz: Option<f64>,
    /// Seconds rendered (default: the last poke + 1 s).
    pub duration_s: Option<f64>,
    pub damping_scale: f64,
    /// `.y4m`, or anything ffmpeg writes.
    pub output: PathBuf,
}

/// What `idv` did.
#[derive(Clone, Debug, Serialize)]
pub struct IdvReport {
    pub output: PathBuf,
    pub frames: u64,
    pub rate_hz: f64,
    pub width: usize,
    pub height: usize,
    /// (frequency Hz, damping ratio) per mode.
    pub modes: Vec<(f64, f64)>,
    pub basis_written: Vec<PathBuf>,
    pub notes: Vec<String>,
}

/// Runs `idv`: basis (measured or loaded), simulation, frames.
pub fn idv(o: &IdvOptions) -> Result<IdvReport> {
    if o.pokes.is_empty() {
        return Err(Error::usage(
            "--poke",
            "give at least one --poke, --pull or --throw T,X,Y,DX,DY[,STRENGTH]",
        ));
    }
    if !(o.damping_scale.is_finite() && o.damping_scale > 0.0) {
        return Err(Error::usage(
            "--damping-scale",
            format!("must be > 0, got {}", o.damping_scale),
        ));
    }
    let ffmpeg = crate::magnify::output_needs_ffmpeg(&o.output, crate::magnify::ffmpeg_present)?;
    let mut inputs: Vec<&Path> = Vec::new();
    if o.basis_dir.is_none() {
        inputs.push(&o.basis.video);
    }
    crate::error::check_outputs(&inputs, &[o.output.as_path()])?;
    let basis = match &o.basis_dir {
        Some(d) => load_basis(d)?,
        None => extract_basis(&o.basis)?,
    };
    // Every poke inside the frame before any work is written.
    for pk in &o.pokes {
        pk.pixel(basis.width, basis.height)?;
    }
    let basis_written = match &o.save_basis {
        Some(d) => save_basis(&basis, d)?,
        None => Vec::new(),
    };
    let rate = o.rate_hz.unwrap_or(basis.fps);
    if !(rate.is_finite() && rate > 0.0) {
        return Err(Error::usage(
            "--rate",
            format!("must be > 0 Hz, got {rate}"),
        ));
    }
    let last = o.pokes.iter().map(|p| p.t_s).fold(0.0, f64::max);
    let duration = o.duration_s.unwrap_or(last + 1.0);
    if !(duration.is_finite() && duration > 0.0 && duration * rate <= 1e7) {
        return Err(Error::usage(
            "--duration",
            format!("must be > 0 s and at most 10 million frames, got {duration} s at {rate} Hz"),
        ));
    }
    let frames = (duration * rate).round().max(1.0) as u64;
    let mut sim = Simulation::new(&basis, &o.pokes, o.damping_scale)?;
    let shapes: Vec<Shape> = basis.modes.iter().map(|m| m.shape.clone()).collect();
    let mut notes = basis.notes.clone();
    let mut r = FrameRenderer::new(basis.width, basis.height, 0);
    let size = (basis.width, basis.height);
    match &basis.colour {
        Some(c) => write_colour_video(&o.output, ffmpeg, size, rate, frames, c, |k, out| {
            r.displace(&shapes, sim.advance_to(k as f64 / rate));
            for (plane, o) in c.planes.iter().zip(out.iter_mut()) {
                r.sample(plane, o);
            }
            Ok(())
        })?,
        None => {
            crate::magnify::write_gray_video(&o.output, ffmpeg, size, rate, frames, |k, out| {
                r.displace(&shapes, sim.advance_to(k as f64 / rate));
                r.sample(&basis.rest, out);
                Ok(())
            })?
        }
    }
    if basis.modes.iter().any(|m| m.freq_hz > rate / 2.0) {
        notes.push(format!(
            "modes above {} Hz (half the output rate) alias in the rendered video; raise --rate",
            rate / 2.0
        ));
    }
    Ok(IdvReport {
        output: o.output.clone(),
        frames,
        rate_hz: rate,
        width: basis.width,
        height: basis.height,
        modes: basis.modes.iter().map(|m| (m.freq_hz, m.damping)).collect(),
        basis_written,
        notes,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn quadrants_cover_the_region_or_the_mask_and_skip_empty_ones() {
        let whole = quadrants(&Region::default(), None, 64, 40);
        assert_eq!(whole.len(), 4);
        let area: u32 = whole.iter().map(|q| q.w * q.h).sum();
        assert_eq!(area, 64 * 40);
        // Too small a region: no quadrant.
        let small = Region {
            roi: Some(Roi {
                x: 4,
                y: 4,
                w: 30,
                h: 40,
            }),
            ..Default::default()
        };
        assert!(quadrants(&small, None, 64, 40).is_empty());
        // A mask: its bounding box, and only the quarters it covers enough.
        let (w, h) = (100usize, 80usize);
        let mut m = vec![false; w * h];
        for y in 10..50 {
            for x in 20..60 {
                // An L: the top rows and the left columns of the box.
                m[y * w + x] = y < 14 || x < 24;
            }
        }
        let q = quadrants(&Region::default(), Some(&m), w, h);
        assert_eq!(q[0].to_string(), "20,10,20,20");
        // The bottom-right quarter holds none of the L.
        assert_eq!(q.len(), 3, "{q:?}");
        assert!(q.iter().all(|r| !(r.x == 40 && r.y == 30)));
        assert!(quadrants(&Region::default(), Some(&vec![false; w * h]), w, h).is_empty());
    }
}
