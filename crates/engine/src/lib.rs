//! The stage kinds and their registry, and the shipped pipelines, over
//! the engine's core (`vibroscope-core`: frames, items, edges,
//! configuration, typed parameters, the runner), which this crate
//! re-exports whole so a kind reads `crate::config`, `crate::Frame`...

pub use vibroscope_core::*;

#[cfg(feature = "net")]
pub mod net;
#[cfg(test)]
pub(crate) mod test_support;

pub mod pipelines;
pub mod stages;
