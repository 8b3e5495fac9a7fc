//! The two image pyramids of phase-based motion: the complex steerable
//! pyramid ([`csp`], FFT-based) and the Riesz pyramid ([`riesz`],
//! FFT-free), their per-pixel phase kernels ([`kernels`]), and what they
//! share here: the band shape ([`BandInfo`]), the [`PhaseBands`] interface
//! a phase stage reads either through, the argument checks and
//! [`PyramidError`]. Dependencies point one way: this module, then
//! `kernels`, then `csp` and `riesz`.

pub use rustfft::num_complex::Complex32;

pub mod csp;
pub mod kernels;
pub mod riesz;

pub use csp::{ComplexSteerablePyramid, CspBand, PyramidCoeffs};
pub use riesz::{RieszCoeffs, RieszLevel, RieszPyramid};

/// Which pyramid measures local phase: the complex steerable pyramid
/// (quality, FFT-based) or the Riesz pyramid (speed, FFT-free).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PyramidKind {
    #[default]
    Csp,
    Riesz,
}

impl PyramidKind {
    /// The name used in pipelines and flags: `csp` or `riesz`.
    pub fn name(self) -> &'static str {
        match self {
            PyramidKind::Csp => "csp",
            PyramidKind::Riesz => "riesz",
        }
    }
}

/// Default number of octave scales.
pub const DEFAULT_SCALES: usize = 4;
/// Default number of orientations.
pub const DEFAULT_ORIENTATIONS: usize = 2;
/// Largest accepted number of scales (deeper scales degrade to 1x1 grids).
pub const MAX_SCALES: usize = 16;
/// Largest accepted number of orientations.
pub const MAX_ORIENTATIONS: usize = 16;
/// Largest accepted frame, in pixels.
pub const MAX_PIXELS: usize = 1 << 28;

/// Errors of the pyramids in this module and in `riesz`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PyramidError {
    #[error(
        "frame size {width}x{height} is invalid (each side >= 1, at most {MAX_PIXELS} pixels)"
    )]
    InvalidSize { width: usize, height: usize },
    #[error("scales must be in 1..={MAX_SCALES}, got {0}")]
    InvalidScales(usize),
    #[error("orientations must be in 1..={MAX_ORIENTATIONS}, got {0}")]
    InvalidOrientations(usize),
    #[error("buffer has {got} samples, expected {expected}")]
    LengthMismatch { expected: usize, got: usize },
    #[error("coefficients were allocated for a different pyramid")]
    LayoutMismatch,
    #[error("band index {index} out of range ({count} bands)")]
    BandOutOfRange { index: usize, count: usize },
    #[error("FFT failed: {0}")]
    Fft(String),
}

/// The shape a pyramid was built for; its coefficients carry it, so that a
/// pyramid refuses another's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LayoutKey {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) scales: usize,
    pub(crate) orientations: usize,
    /// The steerable pyramid's compact bands
    /// ([`ComplexSteerablePyramid::new_compact`]); false for the Riesz pyramid.
    pub(crate) compact: bool,
}

/// `with_defaults` and the size getters, the same in both pyramids (each
/// has a `key: LayoutKey` and a `new(width, height, scales, orientations)`).
macro_rules! layout_accessors {
    () => {
        /// Same as `new(width, height, DEFAULT_SCALES, DEFAULT_ORIENTATIONS)`.
        pub fn with_defaults(width: usize, height: usize) -> Result<Self, PyramidError> {
            Self::new(width, height, DEFAULT_SCALES, DEFAULT_ORIENTATIONS)
        }

        pub fn width(&self) -> usize {
            self.key.width
        }
        pub fn height(&self) -> usize {
            self.key.height
        }
        pub fn scales(&self) -> usize {
            self.key.scales
        }
        pub fn orientations(&self) -> usize {
            self.key.orientations
        }
    };
}
pub(crate) use layout_accessors;

/// Checks the common constructor arguments of both pyramids.
pub(crate) fn check_params(
    width: usize,
    height: usize,
    scales: usize,
    orientations: usize,
) -> Result<(), PyramidError> {
    let pixels = width.checked_mul(height);
    if width == 0 || height == 0 || pixels.is_none_or(|p| p > MAX_PIXELS) {
        return Err(PyramidError::InvalidSize { width, height });
    }
    if scales == 0 || scales > MAX_SCALES {
        return Err(PyramidError::InvalidScales(scales));
    }
    if orientations == 0 || orientations > MAX_ORIENTATIONS {
        return Err(PyramidError::InvalidOrientations(orientations));
    }
    Ok(())
}

/// A frame's pixels as a pyramid reads them: `f32`, or bytes (read as
/// bytes, widened exactly where they are used: the same bits).
#[derive(Clone, Copy)]
pub(crate) enum Pixels<'a> {
    F32(&'a [f32]),
    U8(&'a [u8]),
}

impl Pixels<'_> {
    pub(crate) fn len(&self) -> usize {
        match self {
            Pixels::F32(x) => x.len(),
            Pixels::U8(x) => x.len(),
        }
    }
}

pub(crate) fn check_len(expected: usize, got: usize) -> Result<(), PyramidError> {
    if expected == got {
        Ok(())
    } else {
        Err(PyramidError::LengthMismatch { expected, got })
    }
}

/// Shape of one band, shared by the CSP and the Riesz pyramid.
#[derive(Clone, Debug, PartialEq)]
pub struct BandInfo {
    /// Octave, 0 = finest.
    pub scale: usize,
    /// Orientation index, `0..orientations`.
    pub orientation: usize,
    /// Orientation angle in radians (`π·orientation/orientations`): the
    /// direction, in image coordinates (x right, y down), of the frequencies
    /// the band keeps; local phase grows along it, so motion along it shows
    /// up as phase change.
    pub angle: f32,
    /// Band width in band pixels.
    pub width: usize,
    /// Band height in band pixels.
    pub height: usize,
    /// Input pixels per band pixel along x (`W / width`).
    pub step_x: f32,
    /// Input pixels per band pixel along y (`H / height`).
    pub step_y: f32,
    /// Nominal radial centre frequency, cycles per input pixel.
    pub centre_frequency: f32,
}

impl BandInfo {
    /// Number of samples in the band.
    pub fn len(&self) -> usize {
        self.width * self.height
    }
    /// Whether the band is empty (never, for a valid pyramid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Per-band amplitude and phase, as both pyramids expose them, so that a
/// downstream phase stage (thesis Eq. 3.2-3.4) can use either.
pub trait PhaseBands {
    /// Number of (scale, orientation) bands, scale-major:
    /// `index = scale * orientations + orientation`.
    fn num_bands(&self) -> usize;
    /// Shape of band `i`.
    fn band_info(&self, i: usize) -> Option<&BandInfo>;
    /// Local amplitude (contrast) of band `i`, row-major.
    fn amplitude_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError>;
    /// Whether every orientation of a scale has the same amplitude (the
    /// Riesz pyramid's, one per level): a reader of several orientations
    /// can then read one amplitude image for all.
    fn amplitude_shared(&self) -> bool {
        false
    }
    /// Local phase of band `i`, radians in `[-π, π]`, row-major.
    fn phase_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError>;
    /// Local phase change of band `i` from `reference` to `self`, wrapped
    /// correctly (thesis Eq. 3.2): radians in `[-π, π]`, row-major.
    /// Image content moving by `d` input pixels along the band's angle
    /// changes the phase by about `-2π·f·d`, `f` the local frequency along
    /// that angle in cycles per input pixel.
    fn phase_delta_into(
        &self,
        reference: &Self,
        i: usize,
        out: &mut [f32],
    ) -> Result<(), PyramidError>;
    /// Σ weights[y·width + x] · Δφ(x, y) over `rows` × `cols` of band `i`,
    /// Δφ as in [`PhaseBands::phase_delta_into`], fused (no scratch buffer),
    /// for Eq. 3.3-3.4 on a region. Summed row by row in f32, rows in f64.
    fn weighted_phase_delta_sum(
        &self,
        reference: &Self,
        i: usize,
        weights: &[f32],
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) -> Result<f64, PyramidError>;
    /// The sums of [`PhaseBands::weighted_phase_delta_sum`] for every
    /// orientation of one scale at once: `out[k]` for band
    /// `scale * orientations + k`, weighted by `weights[k]`. The bands of a
    /// scale share their shape, so one region serves all; a pyramid whose
    /// orientations share work per pixel (Riesz) does it once. (A compact
    /// steerable pyramid's do not share it,
    /// [`ComplexSteerablePyramid::new_compact`]: sum its bands one by one,
    /// each over its own region; here they are refused.)
    fn scale_phase_delta_sums(
        &self,
        reference: &Self,
        scale: usize,
        weights: &[&[f32]],
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
        out: &mut [f64],
    ) -> Result<(), PyramidError>;
}

/// Shared coefficients (an edge payload) read like their owner.
impl<T: PhaseBands> PhaseBands for std::sync::Arc<T> {
    fn num_bands(&self) -> usize {
        (**self).num_bands()
    }
    fn band_info(&self, i: usize) -> Option<&BandInfo> {
        (**self).band_info(i)
    }
    fn amplitude_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        (**self).amplitude_into(i, out)
    }
    fn amplitude_shared(&self) -> bool {
        (**self).amplitude_shared()
    }
    fn phase_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        (**self).phase_into(i, out)
    }
    fn phase_delta_into(
        &self,
        reference: &Self,
        i: usize,
        out: &mut [f32],
    ) -> Result<(), PyramidError> {
        (**self).phase_delta_into(reference, i, out)
    }
    fn weighted_phase_delta_sum(
        &self,
        reference: &Self,
        i: usize,
        weights: &[f32],
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) -> Result<f64, PyramidError> {
        (**self).weighted_phase_delta_sum(reference, i, weights, rows, cols)
    }
    fn scale_phase_delta_sums(
        &self,
        reference: &Self,
        scale: usize,
        weights: &[&[f32]],
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
        out: &mut [f64],
    ) -> Result<(), PyramidError> {
        (**self).scale_phase_delta_sums(reference, scale, weights, rows, cols, out)
    }
}

/// Checks a region against a band's shape and a weight buffer.
pub(crate) fn check_region(
    info: &BandInfo,
    weights: &[f32],
    rows: &std::ops::Range<usize>,
    cols: &std::ops::Range<usize>,
) -> Result<(), PyramidError> {
    if rows.end > info.height
        || cols.end > info.width
        || rows.start > rows.end
        || cols.start > cols.end
    {
        return Err(PyramidError::LengthMismatch {
            expected: info.len(),
            got: rows.end.max(1) * info.width,
        });
    }
    check_len(info.len(), weights.len())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
pub(crate) mod tests;
