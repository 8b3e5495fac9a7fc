//! WAV: the reader every command shares (`score`, `calibrate`, scene
//! signals), and the header repair used after a full disk.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use std::path::Path;
use vibroscope_io::wav::{self, WavError};

fuzz_target!(|data: &[u8]| {
    let before = wav::read_mono_from(std::io::Cursor::new(data), Path::new("<fuzz>"));
    let p = common::file("in.wav", data);
    let _ = wav::info(&p);
    // A WAV whose samples read (all, or until the file was cut short, as
    // after a full disk) reads once its header is repaired. (Without a
    // sample read, a header hound accepts may still hold a format it
    // cannot read, e.g. 24 bits in 6-byte blocks.)
    let readable = match &before {
        Ok((_, v)) => !v.is_empty(),
        Err(WavError::Samples {
            source: hound::Error::IoError(e),
            ..
        }) => e.kind() == std::io::ErrorKind::UnexpectedEof,
        Err(_) => false,
    };
    if wav::repair_header(&p).is_ok() && readable {
        if let Err(e) = wav::read_mono(&p) {
            panic!("repair_header left an unreadable WAV: {e}");
        }
    }
});
