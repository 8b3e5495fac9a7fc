//! Signal processing shared by stages and commands.

pub mod iir;
pub mod metrics;
pub mod pyramid;
pub mod riesz;
pub mod truth;
