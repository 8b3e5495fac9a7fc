//! Signal processing shared by stages and commands.

pub mod denoise;
pub mod fastmath;
pub mod iir;
pub mod kernels;
pub mod metrics;
pub mod pyramid;
pub mod riesz;
pub mod truth;
