//! vibroscope: a streaming engine that turns a camera into a vibration
//! sensor (Abe Davis, *Visual Vibration Analysis*, MIT 2016).
//!
//! This crate holds the typed recipes (listen, spectrum, modes, calibrate,
//! rod, compare, simulate, record) over the layers below it, which it
//! re-exports:
//!
//! - [`math`]: pyramids, filters, spectra, peaks, SSI, modal sums, metrics,
//!   calibration math (no threads, no I/O).
//! - [`io`]: video file formats (Y4M, Phantom cine, Photron mraw, ffmpeg)
//!   and PNG plots.
//! - [`sim`]: the forward model of object and camera (ground truth).
//! - [`engine`]: frames, typed items, edges, configuration, the runner,
//!   the stage kinds ([`stages`]) and the shipped [`pipelines`].

pub use vibroscope_engine as engine;
pub use vibroscope_engine::{pipelines, stages};
pub use vibroscope_io as io;
pub use vibroscope_math as math;
pub use vibroscope_sim as sim;

pub mod cli;
pub mod vibrometry;
