//! Signal processing shared by stages and commands.

pub mod ar_interp;
pub mod denoise;
pub mod exposure;
pub mod fastmath;
pub mod iir;
pub mod kernels;
pub mod metrics;
pub mod pyramid;
pub mod riesz;
pub mod row_phase;
pub mod rs_calibrate;
pub mod truth;
