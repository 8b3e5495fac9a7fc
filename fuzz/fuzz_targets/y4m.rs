//! Y4M: the stream reader (standard input's path) and the file reader
//! (which also counts frames by seeking), then every frame.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use vibroscope_io::Y4mReader;

fuzz_target!(|data: &[u8]| {
    if let Ok(mut r) = Y4mReader::from_reader(std::io::Cursor::new(data), "<fuzz>") {
        common::read_frames(&mut r, data.len(), 64);
    }
    let p = common::file("in.y4m", data);
    if let Ok(mut r) = vibroscope_io::open(&p, vibroscope_io::Format::Y4m) {
        common::read_frames(r.as_mut(), data.len(), 64);
    }
});
