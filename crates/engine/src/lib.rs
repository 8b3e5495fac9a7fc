//! The stage kinds that need only computation and files (sources from
//! files and renderers, every transform, the sinks that write files or
//! hand items to the caller), and the shipped pipelines, over the engine's
//! core (`vibroscope-core`: frames, items, edges, configuration, typed
//! parameters, the runner), which this crate re-exports whole so a kind
//! reads `crate::config`, `crate::Frame`...
//!
//! The kinds on live devices (`vibroscope-devices`: v4l2, nokhwa, speaker)
//! and on the network (`vibroscope-net`: zenoh) are crates of their own, so
//! this one builds without their drivers; the recipes assemble the
//! registry of all three.

pub use vibroscope_core::*;

#[cfg(test)]
pub(crate) mod test_support;

pub mod pipelines;
pub mod stages;
