//! This crate's stage kinds, grouped by role, and their list: what maps a
//! TOML `kind` to its parameters and constructor.

pub mod sinks;
pub mod sources;
mod spec_tests;
pub mod transform;

use crate::KindSpec;

/// Every kind's typed parameters ([`crate::params!`]), by struct name: a
/// recipe edits a stage through these (`MagnifyParams::factor`).
pub mod params {
    pub use super::sinks::csv::CsvParams;
    pub use super::sinks::json::JsonParams;
    pub use super::sinks::modes::ModesParams;
    pub use super::sinks::null::NullParams;
    pub use super::sinks::peaks::PeaksParams;
    pub use super::sinks::spectrum_png::SpectrumPngParams;
    pub use super::sinks::tap::TapParams;
    pub use super::sinks::wav::WavParams;
    pub use super::sinks::y4m::Y4mParams;
    pub use super::sources::file::FileParams;
    pub use super::sources::pattern::PatternParams;
    pub use super::sources::synthetic::SyntheticParams;
    pub use super::transform::align::AlignParams;
    pub use super::transform::band::BandParams;
    pub use super::transform::denoise::SpectralSubtractionParams;
    pub use super::transform::denoise::SpeechEnhanceParams;
    pub use super::transform::denoise::WienerParams;
    pub use super::transform::displacement::{DisplacementParams, Untextured};
    pub use super::transform::exposure::ExposureParams;
    pub use super::transform::gap_fill::GapFillParams;
    pub use super::transform::gradient_motion::GradientMotionParams;
    pub use super::transform::highpass::HighpassParams;
    pub use super::transform::magnify::MagnifyParams;
    pub use super::transform::mean::MeanParams;
    pub use super::transform::passthrough::PassthroughParams;
    pub use super::transform::phase::PhaseParams;
    pub use super::transform::pitch::PitchParams;
    pub use super::transform::pyramid::PyramidParams;
    pub use super::transform::resample::ResampleParams;
    pub use super::transform::resonances::ResonancesParams;
    pub use super::transform::rows::RowsParams;
    pub use super::transform::spectrum::SpectrumParams;
    pub use super::transform::tile_motion::TileMotionParams;
}

/// The kinds of this crate (computation and files), sources first, in the
/// order `vibroscope kinds` lists them. The kinds on live devices
/// (`vibroscope-devices`) and on the network (`vibroscope-net`) live in
/// crates of their own; the recipes' `stages` assembles the registry.
pub static KINDS: &[KindSpec] = &[
    sources::file::KIND,
    sources::synthetic::KIND,
    sources::pattern::KIND,
    transform::passthrough::KIND,
    transform::mean::KIND,
    transform::gradient_motion::KIND,
    transform::tile_motion::KIND,
    transform::displacement::KIND,
    transform::highpass::KIND,
    transform::magnify::KIND,
    transform::band::BANDPASS_KIND,
    transform::band::BANDSTOP_KIND,
    transform::pyramid::KIND,
    transform::phase::KIND,
    transform::align::KIND,
    transform::denoise::SUBTRACT_KIND,
    transform::denoise::ENHANCE_KIND,
    transform::denoise::WIENER_KIND,
    transform::rows::KIND,
    transform::gap_fill::KIND,
    transform::exposure::KIND,
    transform::spectrum::KIND,
    transform::resonances::KIND,
    transform::resample::KIND,
    transform::pitch::KIND,
    sinks::wav::KIND,
    sinks::csv::KIND,
    sinks::json::KIND,
    sinks::peaks::KIND,
    sinks::modes::KIND,
    sinks::spectrum_png::KIND,
    sinks::y4m::KIND,
    sinks::tap::KIND,
    sinks::null::KIND,
];

/// Looks one of this crate's kinds up by name.
pub fn kind(name: &str) -> Option<&'static KindSpec> {
    KINDS.iter().find(|k| k.name == name)
}
