//! The peak search over spectra that the `resonances` transform and the
//! `peaks` and `spectrum_png` sinks share: the parameters of the band and
//! of the search (declared once, with their ranges and docs), the band's
//! check, and the options of [`vibroscope_math::peaks`]'s search built from
//! the facts a spectrum carries.

use super::spectrum::TaperExt;
use crate::*;
use vibroscope_math::peaks::PeakOptions;

/// `min_hz` and `max_hz`, shared with `spectrum_png`.
pub const MIN_HZ: ParamSpec = ParamSpec::new("min_hz", ParamType::Float, Def::Optional)
    .at_least(0.0)
    .unit("Hz")
    .doc("lower edge of the band searched; default: the first bin");
pub const MAX_HZ: ParamSpec = ParamSpec::new("max_hz", ParamType::Float, Def::Optional)
    .at_least(0.0)
    .unit("Hz")
    .doc("upper edge of the band searched (> min_hz); default: Nyquist");

/// `min_prominence_db`, shared with `resonances`.
pub const MIN_PROMINENCE: ParamSpec =
    ParamSpec::new("min_prominence_db", ParamType::Float, Def::Float(6.0))
        .at_least(0.0)
        .unit("dB")
        .doc("a peak must stand this far above its surroundings");
/// `false_alarm`, shared with `resonances`.
pub const FALSE_ALARM: ParamSpec = ParamSpec::new("false_alarm", ParamType::Float, Def::Float(vibroscope_math::peaks::DEFAULT_FALSE_ALARM))
    .floats(1e-12, 1.0)
    .doc("report only peaks that noise alone would put this high anywhere in the band with at most this probability (the spectrum's K averages and its local floor); 1 = every prominent peak, each with its probability");

/// Checks that the band (`min_hz`, `max_hz`), which `peaks` and
/// `spectrum_png` share, is not empty.
pub fn check_band(
    p: &Params<'_>,
    min_hz: Option<f64>,
    max_hz: Option<f64>,
) -> Result<(), ConfigError> {
    if let (Some(a), Some(b)) = (min_hz, max_hz) {
        if a >= b {
            return Err(p.error("max_hz", format!("must exceed min_hz ({a}), got {b}")));
        }
    }
    Ok(())
}

/// The peak search `peaks` and `resonances` share, for `averaged`
/// spectra averaged whose facts (taper, window, Welch segments) `facts`
/// carries.
pub fn search_options(
    max_peaks: usize,
    min_prominence_db: f64,
    min_hz: Option<f64>,
    max_hz: Option<f64>,
    false_alarm: f64,
    facts: &Spectrum,
    averaged: usize,
) -> PeakOptions {
    PeakOptions {
        max_peaks,
        min_prominence_db,
        min_hz,
        max_hz,
        // The fit sees each line through the taper's spectral window.
        window_kernel: facts.taper.power_kernel(facts.window, 4),
        // Welch segments times the spectra averaged.
        segments: facts.segments.max(1).saturating_mul(averaged),
        max_false_alarm: (false_alarm < 1.0).then_some(false_alarm),
    }
}
