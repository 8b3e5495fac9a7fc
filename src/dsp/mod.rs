//! Signal processing shared by stages and commands.

pub mod metrics;
pub mod truth;
