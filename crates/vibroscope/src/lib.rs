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
//! - [`files`]: the file helpers the studio and the binary share with the
//!   recipes (atomic writes, temporary paths, video and WAV reading);
//! - [`live`]: what a live view of a running pipeline needs (taps,
//!   observers, the stream's item types).
//!
//! The layers below (math, io, sim, engine) are this crate's own business:
//! the studio and the binary reach them only through the recipes and the
//! items named here (issue 49; `tests/layers.rs` checks it).

use vibroscope_engine as engine;
use vibroscope_engine::pipelines;
use vibroscope_io as io;
use vibroscope_math as math;
use vibroscope_sim as sim;

pub mod error;
pub mod files;
pub mod json;
pub mod live;
pub mod pipeline;
mod stages;

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
