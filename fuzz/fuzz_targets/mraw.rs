//! Photron .cih (text) or .cihx (XML) header with its .mraw pixels.
//! Input layout: byte 0 bit 0 picks .cihx; bytes 1-2 (little-endian) are
//! the header's length (modulo what is left); the header, then the pixels.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 3 {
        return;
    }
    let xml = data[0] & 1 == 1;
    let rest = &data[3..];
    let n = usize::from(u16::from_le_bytes([data[1], data[2]])) % (rest.len() + 1);
    let (header, pixels) = rest.split_at(n);
    let dir = common::scratch_dir();
    // Only one header per run: the reader finds the sibling by name.
    let _ = std::fs::remove_file(dir.join("in.cih"));
    let _ = std::fs::remove_file(dir.join("in.cihx"));
    let h = common::file(if xml { "in.cihx" } else { "in.cih" }, header);
    common::file("in.mraw", pixels);
    if let Ok(mut r) = vibroscope_io::open(&h, vibroscope_io::Format::Mraw) {
        common::read_frames(r.as_mut(), pixels.len(), 64);
    }
});
