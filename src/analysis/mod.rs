//! Analysis of measured signals and spectra: resonances and damping, and
//! calibration against a known sound.

pub mod calibrate;
pub mod modal;
pub mod peaks;
pub mod plot;
pub mod rod;
pub mod ssi;
