//! Stage kinds, grouped by role, and the registry that maps a TOML `kind`
//! to its parameters and constructor.

pub mod sinks;
pub mod sources;
pub mod transform;

use crate::KindSpec;

/// Every stage kind the engine knows, in the order `vibroscope kinds` lists them.
pub static REGISTRY: &[KindSpec] = &[
    sources::file::KIND,
    sources::synthetic::KIND,
    sources::pattern::KIND,
    sources::v4l2::KIND,
    sources::nokhwa::KIND,
    #[cfg(feature = "net")]
    sources::zenoh_sub::KIND,
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
    sinks::speaker::KIND,
    sinks::csv::KIND,
    sinks::json::KIND,
    sinks::peaks::KIND,
    sinks::modes::KIND,
    sinks::spectrum_png::KIND,
    sinks::y4m::KIND,
    sinks::tap::KIND,
    sinks::null::KIND,
    #[cfg(feature = "net")]
    sinks::zenoh_pub::KIND,
];

/// Looks a kind up by name.
pub fn kind(name: &str) -> Option<&'static KindSpec> {
    REGISTRY.iter().find(|k| k.name == name)
}
