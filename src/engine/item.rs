//! Typed payloads that travel on edges.

use super::frame::Frame;
use std::fmt;
use std::sync::Arc;

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
}

impl fmt::Display for PortType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PortType::Frames => "frames",
            PortType::Samples => "samples",
            PortType::Audio => "audio",
            PortType::Spectrum => "spectrum",
        })
    }
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

/// A power spectrum: `power[k]` at `f0_hz + k * resolution_hz`.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// Time of the centre of the analysed window.
    pub t_ns: i64,
    pub f0_hz: f64,
    pub resolution_hz: f64,
    pub power: Arc<[f32]>,
}

/// What an edge carries.
#[derive(Clone, Debug)]
pub enum Item {
    Frame(Frame),
    Samples(SampleBlock),
    Audio(AudioBlock),
    Spectrum(Spectrum),
}

impl Item {
    pub fn port_type(&self) -> PortType {
        match self {
            Item::Frame(_) => PortType::Frames,
            Item::Samples(_) => PortType::Samples,
            Item::Audio(_) => PortType::Audio,
            Item::Spectrum(_) => PortType::Spectrum,
        }
    }

    /// Capture time the item refers to.
    pub fn t_ns(&self) -> i64 {
        match self {
            Item::Frame(f) => f.meta().t_ns,
            Item::Samples(s) => s.t0_ns,
            Item::Audio(a) => a.t0_ns,
            Item::Spectrum(s) => s.t_ns,
        }
    }
}
