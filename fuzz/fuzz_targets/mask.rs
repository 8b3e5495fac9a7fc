//! Masks and pictures (PGM P2/P5, PNG) as the mask loader reads them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;
use vibroscope_engine::stages::transform::roi::Mask;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Mask::decode(data, Path::new("<fuzz>")) {
        let b = m.bounds();
        assert!(m.at(b.x, b.y) || b.w > 0);
    }
});
