//! Typed payloads that travel on edges.

use super::frame::Frame;
use std::fmt;
use std::sync::Arc;
use vibroscope_math::pyramid::{BandInfo, PhaseBands, PyramidCoeffs, PyramidError};
use vibroscope_math::riesz::RieszCoeffs;

/// The type of an edge, checked by the validator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PortType {
    /// Gray video frames.
    Frames,
    /// Blocks of per-band or per-row motion samples (possibly several channels).
    Samples,
    /// Mono audio-rate signal blocks.
    Audio,
    /// Power spectra.
    Spectrum,
    /// One frame's pyramid coefficients (local amplitude and phase per band).
    Pyramid,
    /// The resonances picked from one spectrum ([`PeakSet`]).
    Peaks,
}

impl PortType {
    /// The type its [`fmt::Display`] name names (`"spectrum"`, ...).
    pub fn from_name(name: &str) -> Option<PortType> {
        [
            PortType::Frames,
            PortType::Samples,
            PortType::Audio,
            PortType::Spectrum,
            PortType::Pyramid,
            PortType::Peaks,
        ]
        .into_iter()
        .find(|t| t.to_string() == name)
    }
}

impl fmt::Display for PortType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PortType::Frames => "frames",
            PortType::Samples => "samples",
            PortType::Audio => "audio",
            PortType::Spectrum => "spectrum",
            PortType::Pyramid => "pyramid",
            PortType::Peaks => "peaks",
        })
    }
}

/// One resonance picked from a spectrum: what `monitor` tracks and what
/// crosses a network edge (the analysis's full [`vibroscope_math::peaks::Peak`]
/// also carries its fit details).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Resonance {
    pub frequency_hz: f64,
    pub frequency_std_hz: f64,
    /// Power at the peak, dB of the spectrum's unit (amplitude²).
    pub power_db: f64,
    pub prominence_db: f64,
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
}

impl From<&vibroscope_math::peaks::Peak> for Resonance {
    fn from(p: &vibroscope_math::peaks::Peak) -> Self {
        Resonance {
            frequency_hz: p.frequency_hz,
            frequency_std_hz: p.frequency_std_hz,
            power_db: p.power_db,
            prominence_db: p.prominence_db,
            damping_ratio: p.damping_ratio,
            damping_ratio_std: p.damping_ratio_std,
        }
    }
}

/// The resonances found in one spectrum, strongest first, at the
/// spectrum's time.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PeakSet {
    /// Time of the spectrum's window centre, ns on the source clock.
    pub t_ns: i64,
    pub peaks: Vec<Resonance>,
}

/// A block of a uniformly sampled mono signal.
#[derive(Clone, Debug, PartialEq)]
pub struct AudioBlock {
    /// Time of the first sample, ns on the source clock.
    pub t0_ns: i64,
    /// Sample rate in Hz.
    pub rate_hz: f64,
    pub samples: Arc<[f32]>,
}

impl AudioBlock {
    /// Time of sample `i` in seconds.
    pub fn time_s(&self, i: usize) -> f64 {
        self.t0_ns as f64 * 1e-9 + i as f64 / self.rate_hz
    }
}

/// A block of multi-channel samples (per band or per row), interleaved by
/// frame: `data[i * channels + c]`. Rows of a rolling-shutter frame carry
/// their own times in `times_ns`; otherwise time follows `t0_ns` and `rate_hz`.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleBlock {
    pub t0_ns: i64,
    pub rate_hz: f64,
    pub channels: usize,
    pub data: Arc<[f32]>,
    pub times_ns: Option<Arc<[i64]>>,
}

/// The taper a spectrum's segments were multiplied by: it decides how one
/// spectral line looks, so it travels with the spectrum (see
/// `stages::transform::spectrum` for its coefficients and power kernel).
#[derive(serde::Deserialize, serde::Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Taper {
    Hann,
    Hamming,
    Blackman,
    Rect,
}

impl Taper {
    pub fn name(self) -> &'static str {
        match self {
            Taper::Hann => "hann",
            Taper::Hamming => "hamming",
            Taper::Blackman => "blackman",
            Taper::Rect => "rect",
        }
    }
}

/// A power spectrum: `power[k]` at `f0_hz + k * resolution_hz`, a one-sided
/// density in input units² per Hz. The facts of its analysis travel with it,
/// so that downstream stages read them here rather than restating them.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// Time of the centre of the analysed window.
    pub t_ns: i64,
    pub f0_hz: f64,
    pub resolution_hz: f64,
    /// Sample rate of the analysed signal, Hz.
    pub rate_hz: f64,
    /// Segment length in samples (the FFT size).
    pub window: usize,
    /// The taper applied to each segment.
    pub taper: Taper,
    /// Segments averaged into this spectrum (Welch).
    pub segments: usize,
    pub power: Arc<[f32]>,
}

/// The coefficients of one frame's pyramid (thesis Eq. 3.1), shared, not
/// copied, by the stages that read them.
#[derive(Clone, Debug)]
pub enum PyramidData {
    /// Complex steerable pyramid: one complex band per scale and orientation.
    Csp(Arc<PyramidCoeffs>),
    /// Riesz pyramid: one quadrature triple per scale, projected on each
    /// orientation.
    Riesz(Arc<RieszCoeffs>),
}

impl PyramidData {
    /// Number of (scale, orientation) bands, scale-major.
    pub fn num_bands(&self) -> usize {
        match self {
            PyramidData::Csp(c) => c.num_bands(),
            PyramidData::Riesz(c) => c.num_bands(),
        }
    }

    /// Shape of band `i`.
    pub fn band_info(&self, i: usize) -> Option<&BandInfo> {
        match self {
            PyramidData::Csp(c) => c.band_info(i),
            PyramidData::Riesz(c) => c.band_info(i),
        }
    }

    /// Local amplitude of band `i`, row-major.
    pub fn amplitude_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        match self {
            PyramidData::Csp(c) => c.amplitude_into(i, out),
            PyramidData::Riesz(c) => c.amplitude_into(i, out),
        }
    }

    /// Local phase of band `i`, radians, row-major.
    pub fn phase_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        match self {
            PyramidData::Csp(c) => c.phase_into(i, out),
            PyramidData::Riesz(c) => c.phase_into(i, out),
        }
    }

    /// (scales, orientations) of the layout.
    pub fn layout(&self) -> (usize, usize) {
        let n = self.num_bands();
        let k = (0..n)
            .filter(|&i| self.band_info(i).is_some_and(|b| b.scale == 0))
            .count()
            .max(1);
        (n / k, k)
    }
}

/// A frame's pyramid, with the frame's time and rate.
#[derive(Clone, Debug)]
pub struct PyramidFrame {
    /// Capture time of the frame, ns on the source clock.
    pub t_ns: i64,
    /// The source's sequence number of the frame.
    pub seq: u64,
    /// Nominal frame rate in Hz.
    pub fps: f64,
    /// Size of the frame the pyramid was built from.
    pub width: usize,
    pub height: usize,
    pub data: PyramidData,
}

/// What an edge carries.
#[derive(Clone, Debug)]
pub enum Item {
    Frame(Frame),
    Samples(SampleBlock),
    Audio(AudioBlock),
    Spectrum(Spectrum),
    Pyramid(PyramidFrame),
    Peaks(PeakSet),
}

impl Item {
    pub fn port_type(&self) -> PortType {
        match self {
            Item::Frame(_) => PortType::Frames,
            Item::Samples(_) => PortType::Samples,
            Item::Audio(_) => PortType::Audio,
            Item::Spectrum(_) => PortType::Spectrum,
            Item::Pyramid(_) => PortType::Pyramid,
            Item::Peaks(_) => PortType::Peaks,
        }
    }

    /// Capture time the item refers to.
    pub fn t_ns(&self) -> i64 {
        match self {
            Item::Frame(f) => f.meta().t_ns,
            Item::Samples(s) => s.t0_ns,
            Item::Audio(a) => a.t0_ns,
            Item::Spectrum(s) => s.t_ns,
            Item::Pyramid(p) => p.t_ns,
            Item::Peaks(p) => p.t_ns,
        }
    }
}
