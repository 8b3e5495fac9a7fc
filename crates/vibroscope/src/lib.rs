//! vibroscope: a streaming engine that turns a camera into a vibration
//! sensor (Abe Davis, *Visual Vibration Analysis*, MIT 2016).
//!
//! This crate holds the typed recipes over the layers below it, one module
//! per recipe: a function taking an options struct and returning a report
//! that serialises to the JSON the command line writes. No command-line
//! parsing here (the `vibroscope` binary does that and prints).
//!
//! - [`listen`], [`spectrum`] (+ [`damping`]), [`modes`], [`calibrate`],
//!   [`rod`], [`compare`], [`simulate`], [`record`], [`probe`], [`score`],
//!   [`demo`], [`rs_calibrate`], [`pitch`];
//! - [`units`]: pixels to µm/mm (a scale, or a known length), displacement,
//!   velocity or acceleration, the unit that travels with the results;
//! - [`pipeline`]: load, edit (replay, frame rate, typed stage edits) and
//!   run a pipeline;
//! - [`error`]: the one error type and the exit-status table;
//! - [`json`]: the JSON documents written and read back.
//!
//! The layers, re-exported:
//!
//! - [`math`]: pyramids, filters, spectra, peaks, SSI, modal sums, metrics,
//!   calibration math (no threads, no I/O).
//! - [`io`]: video file formats (Y4M, Phantom cine, Photron mraw, ffmpeg),
//!   WAV and PNG plots.
//! - [`sim`]: the forward model of object and camera (ground truth).
//! - [`engine`]: frames, typed items, edges, configuration, the runner,
//!   the stage kinds ([`stages`]) and the shipped [`pipelines`].

pub use vibroscope_engine as engine;
pub use vibroscope_engine::{pipelines, stages};
pub use vibroscope_io as io;
pub use vibroscope_math as math;
pub use vibroscope_sim as sim;

pub mod error;
pub mod json;
pub mod pipeline;

pub mod bound;
pub mod calibrate;
pub mod compare;
pub mod corrections;
pub mod damping;
pub mod demo;
pub mod devices;
pub mod idv;
pub mod learn;
pub mod listen;
pub mod magnify;
pub mod microphone;
pub mod modes;
#[cfg(feature = "net")]
pub mod monitor;
pub mod motion;
pub mod peaks;
pub mod pitch;
pub mod probe;
pub mod record;
pub mod rod;
pub mod rs_calibrate;
pub mod score;
pub mod simulate;
pub mod spectrum;
pub mod units;

pub use error::{Error, ErrorKind, Result, UsageError};
