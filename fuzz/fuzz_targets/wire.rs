//! The network decoder (`crates/core/src/wire.rs`, issue 21): bytes a
//! peer sends on an edge. Decoding must never panic nor allocate more than
//! the bytes present; an item that decodes must encode back to the same
//! bytes (the encoding is canonical: one layout per item, floats kept bit
//! for bit), frames excepted (they decode to an owned copy, not a `Frame`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibroscope_engine::wire::{self, WireItem, WireRef};

fuzz_target!(|data: &[u8]| {
    let Ok(item) = wire::decode(data) else {
        return;
    };
    let r = match &item {
        WireItem::Audio(a) => WireRef::Audio(a),
        WireItem::Samples(s) => WireRef::Samples(s),
        WireItem::Spectrum(s) => WireRef::Spectrum(s),
        WireItem::Peaks(p) => WireRef::Peaks(p),
        WireItem::Frame(f) => {
            let px = match &f.pixels {
                wire::WirePixels::U8(p) => p.len(),
                wire::WirePixels::U16(p) => p.len(),
            };
            assert_eq!(
                px,
                f.format.width as usize * f.format.height as usize,
                "a decoded frame holds width x height pixels"
            );
            return;
        }
    };
    let mut out = Vec::new();
    wire::encode_into(r, &mut out).expect("a decoded item encodes");
    assert_eq!(out, data, "decode then encode gives the bytes back");
});
