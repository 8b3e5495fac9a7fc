//! Analysis of measured signals and spectra: resonances and damping.

pub mod modal;
pub mod peaks;
pub mod plot;
pub mod rod;
pub mod ssi;
