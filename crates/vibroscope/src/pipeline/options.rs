//! The option types the recipes share (a region, a band filter,
//! denoising, the pyramid), what each sets on a pipeline, and the checks
//! and wording of rates.

use super::*;
use crate::engine;
use crate::engine::config::{ConfigError, Origin, PipelineDecl, StageDecl};
use crate::engine::spec::{Key, KindParams, StageId};
use crate::error::{Error, Result, UsageError};
use crate::io;
use crate::stages;
use crate::stages::params::{
    BandParams, ModesParams, PhaseParams, SpectralSubtractionParams, SpeechEnhanceParams,
    TileMotionParams, WienerParams,
};
use crate::stages::transform::roi::RoiParam;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
/// A rectangle of the frame, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Roi {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl FromStr for Roi {
    type Err = UsageError;
    /// `X,Y,W,H`: four whole numbers >= 0.
    fn from_str(r: &str) -> Result<Roi, UsageError> {
        let v: std::result::Result<Vec<u32>, _> =
            r.split(',').map(|v| v.trim().parse::<u32>()).collect();
        match v.as_deref() {
            Ok([x, y, w, h]) => Ok(Roi {
                x: *x,
                y: *y,
                w: *w,
                h: *h,
            }),
            _ => Err(UsageError::new(
                "--roi",
                format!("expected X,Y,W,H (four whole numbers >= 0), got `{r}`"),
            )),
        }
    }
}

impl fmt::Display for Roi {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{},{}", self.x, self.y, self.w, self.h)
    }
}

impl Roi {
    /// As a stage's `roi` parameter.
    pub fn param(&self) -> RoiParam {
        RoiParam([self.x, self.y, self.w, self.h])
    }
}

/// A Butterworth band filter asked for on the command line: `--band LO,HI`
/// (band-pass) or `--notch F[,WIDTH]` (band-stop from F - WIDTH/2 to
/// F + WIDTH/2; WIDTH defaults to F/10).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BandFilter {
    Pass { lo_hz: f64, hi_hz: f64 },
    Notch { f_hz: f64, width_hz: f64 },
}

fn numbers(flag: &str, text: &str, what: &str) -> Result<Vec<f64>, UsageError> {
    text.split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<std::result::Result<Vec<f64>, _>>()
        .ok()
        .filter(|v| v.iter().all(|x| x.is_finite()))
        .ok_or_else(|| {
            UsageError::new(flag, format!("expected {what} (numbers, Hz), got `{text}`"))
        })
}

impl BandFilter {
    /// `--band LO,HI`: 0 < LO < HI.
    pub fn band(text: &str) -> Result<BandFilter, UsageError> {
        match numbers("--band", text, "LO,HI")?.as_slice() {
            [lo, hi] if *lo > 0.0 && lo < hi => Ok(BandFilter::Pass {
                lo_hz: *lo,
                hi_hz: *hi,
            }),
            [lo, hi] => Err(UsageError::new(
                "--band",
                format!("LO,HI = `{text}`: need 0 < LO < HI (got LO {lo} Hz, HI {hi} Hz)"),
            )),
            _ => Err(UsageError::new(
                "--band",
                format!("expected LO,HI (two numbers, Hz), got `{text}`"),
            )),
        }
    }

    /// `--notch F[,WIDTH]`: F > 0, WIDTH > 0, F - WIDTH/2 > 0.
    pub fn notch(text: &str) -> Result<BandFilter, UsageError> {
        let v = numbers("--notch", text, "F[,WIDTH]")?;
        let (f, w) = match v.as_slice() {
            [f] => (*f, *f / 10.0),
            [f, w] => (*f, *w),
            _ => {
                return Err(UsageError::new(
                    "--notch",
                    format!("expected F[,WIDTH] (one or two numbers, Hz), got `{text}`"),
                ))
            }
        };
        if f <= 0.0 {
            return Err(UsageError::new(
                "--notch",
                format!("`{text}`: the frequency must be above 0 Hz, got {f}"),
            ));
        }
        if w <= 0.0 {
            return Err(UsageError::new(
                "--notch",
                format!("`{text}`: the width must be above 0 Hz, got {w}"),
            ));
        }
        if f - w / 2.0 <= 0.0 {
            return Err(UsageError::new(
                "--notch",
                format!(
                    "`{text}`: the band {} to {} Hz reaches 0 Hz; use a narrower width or --band",
                    f - w / 2.0,
                    f + w / 2.0
                ),
            ));
        }
        Ok(BandFilter::Notch {
            f_hz: f,
            width_hz: w,
        })
    }

    /// Its flag, as typed, for messages.
    pub fn flag(&self) -> String {
        match *self {
            BandFilter::Pass { lo_hz, hi_hz } => {
                format!("--band {},{}", short(lo_hz), short(hi_hz))
            }
            BandFilter::Notch { f_hz, width_hz } => {
                format!("--notch {},{}", short(f_hz), short(width_hz))
            }
        }
    }

    /// Stage kind and edges (Hz).
    pub fn stage(&self) -> (&'static str, f64, f64) {
        match *self {
            BandFilter::Pass { lo_hz, hi_hz } => ("bandpass", lo_hz, hi_hz),
            BandFilter::Notch { f_hz, width_hz } => {
                ("bandstop", f_hz - width_hz / 2.0, f_hz + width_hz / 2.0)
            }
        }
    }

    /// A usage error when the upper edge is not below the Nyquist frequency
    /// of a signal at `rate_hz`.
    pub fn check_rate(&self, rate_hz: f64) -> Result<(), UsageError> {
        let (_, _, hi) = self.stage();
        let nyq = rate_hz / 2.0;
        if hi >= nyq {
            let (flag, value) = self
                .flag()
                .split_once(' ')
                .map_or((String::new(), String::new()), |(a, b)| {
                    (a.to_string(), b.to_string())
                });
            return Err(UsageError::new(
                flag,
                format!(
                    "{value}: the band reaches {} Hz, not below the Nyquist frequency {} Hz of a signal sampled at {} Hz",
                    short(hi),
                    short(nyq),
                    short(rate_hz)
                ),
            ));
        }
        Ok(())
    }

    /// Inserts this filter's stage, `id`, just before the stage `before`.
    pub fn insert(&self, decl: &mut PipelineDecl, id: &str, before: &str) -> Result<()> {
        let (kind, lo, hi) = self.stage();
        let origin = by(&self.flag());
        let mut st = StageDecl::new_kind_of::<BandParams>(id, kind, &[], origin.clone())
            .ok_or_else(|| Error::input(&decl.file, format!("no band filter kind `{kind}`")))?;
        put(&mut st, BandParams::lo_hz, lo, origin.clone())?;
        put(&mut st, BandParams::hi_hz, hi, origin)?;
        insert_before(decl, before, st)
    }
}

/// The pyramid of the local-phase stage: complex steerable (quality) or
/// Riesz (speed).
pub use crate::math::pyramid::PyramidKind as Pyramid;

/// A pipeline checked against the registry of stage kinds (ports, types,
/// parameters), before anything runs: its stages in order with their
/// inputs, or the error naming the stage and field.
pub fn validate(decl: &PipelineDecl) -> std::result::Result<engine::graph::Graph, ConfigError> {
    engine::graph::validate(decl, stages::registry())
}

/// Denoising after the high-pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Denoise {
    #[default]
    None,
    /// Spectral subtraction.
    Subtract,
    /// Speech enhancement.
    Enhance,
    /// MMSE (Wiener) estimation: the least squared error.
    Wiener,
}

impl Denoise {
    /// Its stage `id` reading from `inputs`, if any.
    pub fn stage(self, id: &str, inputs: &[&str], origin: Origin) -> Option<StageDecl> {
        match self {
            Denoise::None => None,
            Denoise::Subtract => Some(new_stage::<SpectralSubtractionParams>(id, inputs, origin)),
            Denoise::Enhance => Some(new_stage::<SpeechEnhanceParams>(id, inputs, origin)),
            Denoise::Wiener => Some(new_stage::<WienerParams>(id, inputs, origin)),
        }
    }
}

/// The region of the object: a rectangle and/or a mask image, and the pyramid.
#[derive(Clone, Debug, Default)]
pub struct Region {
    pub roi: Option<Roi>,
    /// An image the size of the frame (PGM or PNG; pixels > 0 count).
    pub mask: Option<PathBuf>,
    pub pyramid: Pyramid,
}

/// A kind that reads a region of the frame (`roi`, `mask`).
pub trait RegionKind: KindParams {
    const ROI: Key<Self, Option<RoiParam>>;
    const MASK: Key<Self, Option<PathBuf>>;
}

/// A region kind that also builds a pyramid (`pyramid`).
pub trait PyramidRegionKind: RegionKind {
    const PYRAMID: Key<Self, Pyramid>;
}

macro_rules! region_kinds {
    ($($k:ty $(, $pyramid:ident)?);*) => {$(
        impl RegionKind for $k {
            const ROI: Key<Self, Option<RoiParam>> = <$k>::roi;
            const MASK: Key<Self, Option<PathBuf>> = <$k>::mask;
        }
        $(impl PyramidRegionKind for $k {
            const PYRAMID: Key<Self, Pyramid> = <$k>::$pyramid;
        })?
    )*};
}
region_kinds!(PhaseParams, pyramid; ModesParams, pyramid; TileMotionParams);

impl Region {
    /// Sets `roi`, `mask` and `pyramid` on the stage `id`.
    pub fn apply<K: PyramidRegionKind>(
        &self,
        decl: &mut PipelineDecl,
        id: StageId<K>,
    ) -> Result<()> {
        set(decl, id, K::PYRAMID, self.pyramid, by("--pyramid"))?;
        self.apply_region(decl, id)
    }

    /// Sets `roi` and `mask` (not the pyramid) on the stage `id`.
    pub fn apply_region<K: RegionKind>(
        &self,
        decl: &mut PipelineDecl,
        id: StageId<K>,
    ) -> Result<()> {
        if let Some(r) = &self.roi {
            set(decl, id, K::ROI, Some(r.param()), by(&format!("--roi {r}")))?;
        }
        if let Some(m) = &self.mask {
            let origin = by(&format!("--mask {}", m.display()));
            set(decl, id, K::MASK, Some(m.clone()), origin)?;
        }
        Ok(())
    }

    /// Sets `roi` and `mask` on `st`.
    pub fn put_region<K: RegionKind>(&self, st: &mut StageDecl) -> Result<()> {
        if let Some(r) = &self.roi {
            put(st, K::ROI, Some(r.param()), by(&format!("--roi {r}")))?;
        }
        if let Some(m) = &self.mask {
            put(
                st,
                K::MASK,
                Some(m.clone()),
                by(&format!("--mask {}", m.display())),
            )?;
        }
        Ok(())
    }
}

/// Checks a frame rate option.
pub fn check_fps(fps: Option<f64>) -> Result<()> {
    if let Some(f) = fps {
        stages::sources::check_fps(f).map_err(|m| Error::usage("--fps", m))?;
    }
    Ok(())
}

/// A warning when the frame rate will come from a container (the ffmpeg
/// path: MP4, AVI, MKV, ...) and looks like a playback rate (23.976-60 fps):
/// high-speed clips are usually stored that way, and every frequency would
/// come out scaled down. `None` with `fps` given, or for other formats.
pub fn playback_rate_warning(video: &Path, fps: Option<f64>) -> Option<String> {
    if fps.is_some() || !matches!(io::format_by_extension(video), io::Format::Ffmpeg) {
        return None;
    }
    let stated = io::open(video, io::Format::Ffmpeg).ok()?.info().fps?;
    (23.9..=60.01).contains(&stated).then(|| {
        format!(
            "warning: {} states {} fps, a playback rate: if it was filmed at a \
             higher rate, pass the capture rate with --fps (every frequency scales with it)",
            video.display(),
            short(stated)
        )
    })
}

/// A rate or frequency for messages: at most 3 decimals, no trailing zeros.
pub fn short(v: f64) -> String {
    let s = format!("{v:.3}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}
