//! Analysis of measured signals and spectra: resonances and damping.

pub mod peaks;
pub mod rod;
pub mod ssi;
