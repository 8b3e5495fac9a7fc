//! Batching per-frame samples into audio blocks.

use crate::engine::{AudioBlock, Emitter, Item};
use std::sync::Arc;

/// Collects one sample per frame and emits an [`AudioBlock`] every `block`
/// samples (one allocation per block, not per frame). A block carries the
/// capture time of its first sample; a new block starts early if the rate
/// changes or the next frame's time is not where the rate puts it (a gap).
pub struct AudioBatcher {
    block: usize,
    buf: Vec<f32>,
    t0_ns: i64,
    rate: f64,
}

impl AudioBatcher {
    pub fn new(block: usize) -> Self {
        Self {
            block: block.max(1),
            buf: Vec::with_capacity(block.max(1)),
            t0_ns: 0,
            rate: 0.0,
        }
    }

    pub fn push(&mut self, t_ns: i64, rate: f64, v: f32, out: &mut Emitter) {
        if !self.buf.is_empty() {
            let expect = self.t0_ns as f64 + self.buf.len() as f64 * 1e9 / self.rate;
            let period = 1e9 / self.rate;
            if rate != self.rate || (t_ns as f64 - expect).abs() > 0.5 * period {
                self.flush(out);
            }
        }
        if self.buf.is_empty() {
            self.t0_ns = t_ns;
            self.rate = rate;
        }
        self.buf.push(v);
        if self.buf.len() >= self.block {
            self.flush(out);
        }
    }

    pub fn flush(&mut self, out: &mut Emitter) {
        if self.buf.is_empty() {
            return;
        }
        let samples: Arc<[f32]> = Arc::from(&self.buf[..]);
        self.buf.clear();
        let _ = out.emit(Item::Audio(AudioBlock {
            t0_ns: self.t0_ns,
            rate_hz: self.rate,
            samples,
        }));
    }
}
