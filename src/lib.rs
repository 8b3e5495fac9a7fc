//! vibroscope: a streaming engine that turns a camera into a vibration
//! sensor (Abe Davis, *Visual Vibration Analysis*, MIT 2016).
//!
//! - [`engine`]: frames and their pool, typed items, ring-buffer edges,
//!   pipeline configuration and validation, the threaded runner.
//! - [`stages`]: sources, transforms and sinks, and the kind registry.
//! - [`dsp`]: signal processing: quality metrics (SNR, segmental SNR,
//!   LLR, STOI) and ground-truth comparison.
//! - [`io`]: video file formats (Y4M, Phantom cine, Photron mraw, ffmpeg).
//! - [`sim`]: the forward model of object and camera (ground truth).
//! - [`pipelines`]: the pipeline files that ship with the binary.
//! - [`analysis`]: peaks, prominence and damping of motion spectra.
//! - [`vibrometry`]: time-domain damping, rods, regions (issue 5 commands).
//! - [`cli`]: the `vibroscope` command line.

pub mod analysis;
pub mod cli;
pub mod dsp;
pub mod engine;
pub mod io;
pub mod pipelines;
pub mod sim;
pub mod stages;
pub mod vibrometry;
