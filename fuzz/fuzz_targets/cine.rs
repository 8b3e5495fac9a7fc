//! Phantom .cine: header, setup, image offsets, time block, then frames.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let p = common::file("in.cine", data);
    if let Ok(mut r) = vibroscope_io::open(&p, vibroscope_io::Format::Cine) {
        common::read_frames(r.as_mut(), data.len(), 64);
    }
});
