//! Shared by the fuzz targets: temporary files for the readers that work on
//! paths (they seek, or find a sibling file), and reading every frame.

#![allow(dead_code)]

use std::path::PathBuf;
use vibroscope_io::{Depth, FrameDest, VideoReader};

/// A per-process directory under `$VIBROSCOPE_FUZZ_DIR` (which `run.sh`
/// makes and removes), else in RAM when there is one (`/dev/shm`).
pub fn scratch_dir() -> PathBuf {
    let base = if let Some(d) = std::env::var_os("VIBROSCOPE_FUZZ_DIR") {
        PathBuf::from(d)
    } else if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let d = base.join(format!("vibroscope-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("scratch directory");
    d
}

/// Writes `bytes` to `name` in the scratch directory and returns its path.
pub fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let p = scratch_dir().join(name);
    std::fs::write(&p, bytes).expect("scratch file");
    p
}

/// Reads frames until the end, an error, or `max` frames. The frame buffer
/// is allocated only when the input could hold a frame of that size (a
/// 1-bit-per-pixel packing at most 8 pixels a byte): a header alone
/// claiming 2^26 pixels must not make the harness allocate 128 MB.
pub fn read_frames(r: &mut dyn VideoReader, input_len: usize, max: usize) {
    let info = r.info().clone();
    let n = info.width as usize * info.height as usize;
    if n == 0 || n > input_len.saturating_mul(8) {
        return;
    }
    match info.depth {
        Depth::U8 => frames::<u8>(r, n, max, |b| FrameDest::U8(b)),
        Depth::U16 => frames::<u16>(r, n, max, |b| FrameDest::U16(b)),
    }
}

fn frames<T: Copy + Default>(
    r: &mut dyn VideoReader,
    n: usize,
    max: usize,
    dest: for<'a> fn(&'a mut [T]) -> FrameDest<'a>,
) {
    let mut buf = vec![T::default(); n];
    for _ in 0..max {
        if !matches!(r.read_frame(dest(&mut buf)), Ok(Some(_))) {
            break;
        }
    }
}
