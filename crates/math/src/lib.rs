//! The mathematics of visual vibration analysis: no threads, no I/O.
//!
//! - Motion from video: the complex steerable and Riesz pyramids and their
//!   per-pixel phase kernels ([`pyramid`]; [`riesz`] and [`kernels`] are
//!   also at the crate root, where other crates have used them);
//!   rolling-shutter rows ([`row_phase`], [`rs_calibrate`]), exposure
//!   ([`exposure`]), gap filling ([`ar_interp`]), the tile method's sums
//!   ([`tile_sums`]).
//! - Signals: IIR filters ([`iir`]), denoising ([`denoise`]), quality
//!   metrics ([`metrics`]), ground-truth comparison ([`truth`]), pitch
//!   ([`pitch`], YIN).
//! - Resonances: spectral peaks and damping ([`peaks`]), modal images
//!   ([`modal`]) and their simulation as interactive dynamic video
//!   ([`idv`]), stochastic subspace identification ([`ssi`]), rods
//!   ([`rod`]), calibration against a known sound ([`calibrate`]).
//! - The noise floor: the Cramér-Rao bound on sub-pixel motion from the
//!   video itself ([`bound`]).
//! - [`rng`]: the deterministic PRNG shared with the simulator; [`numeric`]:
//!   small shared helpers (gcd, median, Bessel I0).
//! - [`MathError`]: every module's typed error as one enum.

pub mod amplitude;
pub mod ar_interp;
pub mod bound;
pub mod calibrate;
pub mod denoise;
pub mod detmath;
pub mod error;
pub mod exposure;
pub mod fastmath;
pub mod idv;
pub mod iir;
pub mod join;
pub mod magnify;
pub mod metrics;
pub mod modal;
pub mod numeric;
pub mod peaks;
pub mod pitch;
pub mod pyramid;
pub mod rng;
pub mod rod;
pub mod row_phase;
pub mod rs_calibrate;
pub mod sinefit;
pub mod ssi;
pub mod stft;
pub mod tile_sums;
pub mod truth;

pub use error::MathError;
pub use pyramid::{kernels, riesz};
