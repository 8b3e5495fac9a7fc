pub mod file;
pub mod pattern;
pub mod synthetic;

use crate::{FrameFormat, FrameMeta, FrameMut, Item};
use std::time::{Duration, Instant};

/// Paces a source like a live camera: frame `seq` is delivered at
/// `epoch + seq / fps` on the wall clock, whatever downstream is doing. The
/// epoch is the run clock ([`crate::Control::epoch`]), so the
/// nominal capture time `seq / fps` is also the frame's time on that clock
/// and sinks can measure how old what reaches them is.
pub struct Pacer {
    fps: f64,
}

impl Pacer {
    pub fn new(fps: f64) -> Self {
        Self { fps }
    }

    /// Sleeps until frame `seq` is due on the run clock.
    pub fn wait(&mut self, seq: u64, epoch: Instant) {
        self.wait_after(seq, epoch, 0.0);
    }

    /// Sleeps until `extra_s` after frame `seq` starts: a rolling-shutter
    /// frame can only be delivered once its last row has been read out.
    pub fn wait_after(&mut self, seq: u64, epoch: Instant, extra_s: f64) {
        let due = epoch + Duration::from_secs_f64(seq as f64 / self.fps + extra_s.max(0.0));
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
    }
}

/// Stamps a frame rendered at the nominal rate and hands it downstream.
pub fn nominal_frame(mut f: FrameMut, seq: u64, fps: f64) -> Item {
    *f.meta_mut() = FrameMeta {
        seq,
        t_ns: nominal_time_ns(seq, fps),
    };
    Item::Frame(f.freeze())
}

/// Capture time of frame `seq` at a nominal rate (used only when the file
/// or device gives no timestamp of its own).
pub fn nominal_time_ns(seq: u64, fps: f64) -> i64 {
    (seq as f64 * 1e9 / fps).round() as i64
}

/// The largest frame rate accepted, Hz.
pub const MAX_FPS: f64 = 1e7;

/// The smallest frame rate accepted, Hz: one frame a second. Below it
/// nothing audible or modal is left, and resampling to an audio rate needs
/// buffers of the ratio's size (`--fps 1e-300`, a Y4M `F1:4294967295` or a
/// `.cih` save step of 99999999999 once panicked or aborted there).
pub const MIN_FPS: f64 = 1.0;

/// A frame rate parameter (`fps`) with the range [`check_fps`] applies.
pub const fn fps_param(default: crate::Def, doc: &'static str) -> crate::ParamSpec {
    crate::ParamSpec::new("fps", crate::ParamType::Float, default)
        .floats(MIN_FPS, MAX_FPS)
        .unit("Hz")
        .doc(doc)
}

/// `width` or `height` of a rendered frame.
pub const fn side_param(name: &'static str, default: i64, doc: &'static str) -> crate::ParamSpec {
    crate::ParamSpec::new(name, crate::ParamType::Int, crate::Def::Int(default))
        .ints(1, 16384)
        .unit("px")
        .doc(doc)
}

/// `bits` of a rendered frame.
pub const BITS: crate::ParamSpec =
    crate::ParamSpec::new("bits", crate::ParamType::Int, crate::Def::Int(8))
        .ints(1, 16)
        .doc("bit depth of the pixels (above 8: 16-bit samples)");

/// Checks a frame rate given by a user or a file.
pub fn check_fps(fps: f64) -> Result<f64, String> {
    if (MIN_FPS..=MAX_FPS).contains(&fps) {
        Ok(fps)
    } else {
        Err(format!(
            "frame rate must be at least {MIN_FPS} Hz and at most 1e7 Hz, got {fps}"
        ))
    }
}

pub fn describe(f: &FrameFormat) -> String {
    format!("{}x{} {}-bit at {} fps", f.width, f.height, f.bits, f.fps)
}
