//! Batching per-frame samples into blocks: mono audio blocks, or blocks of
//! several channels (one per band) for the `samples` port.

use crate::{AudioBlock, Emitter, Item, SampleBlock};
use std::sync::Arc;

/// Collects one sample (or one row of `channels` samples) per frame and
/// emits a block every `block` frames (one allocation per block, not per
/// frame). A block carries the capture time of its first frame; a new block
/// starts early if the rate changes or the next frame's time is not where
/// the rate puts it (a gap: frames lost upstream, a clock jump), so every
/// sample keeps its own frame's time.
pub struct Batcher {
    block: usize,
    /// `None`: mono [`AudioBlock`]s; `Some(c)`: [`SampleBlock`]s of `c` channels.
    channels: Option<usize>,
    buf: Vec<f32>,
    frames: usize,
    t0_ns: i64,
    rate: f64,
}

impl Batcher {
    /// Mono audio blocks of `block` samples.
    pub fn audio(block: usize) -> Self {
        Self::new(block, None)
    }

    /// Sample blocks of `block` frames of `channels` values each.
    pub fn samples(block: usize, channels: usize) -> Self {
        Self::new(block, Some(channels.max(1)))
    }

    fn new(block: usize, channels: Option<usize>) -> Self {
        let block = block.max(1);
        Self {
            block,
            channels,
            buf: Vec::with_capacity(block * channels.unwrap_or(1)),
            frames: 0,
            t0_ns: 0,
            rate: 0.0,
        }
    }

    /// Adds one frame's values, captured at `t_ns`, at `rate` frames per second.
    pub fn push(
        &mut self,
        t_ns: i64,
        rate: f64,
        values: impl IntoIterator<Item = f32>,
        out: &mut Emitter,
    ) {
        if self.frames > 0 {
            let expect = self.t0_ns as f64 + self.frames as f64 * 1e9 / self.rate;
            let period = 1e9 / self.rate;
            if rate != self.rate || (t_ns as f64 - expect).abs() > 0.5 * period {
                self.flush(out);
            }
        }
        if self.frames == 0 {
            self.t0_ns = t_ns;
            self.rate = rate;
        }
        self.buf.extend(values);
        self.frames += 1;
        if self.frames >= self.block {
            self.flush(out);
        }
    }

    /// Emits what is collected, if anything.
    pub fn flush(&mut self, out: &mut Emitter) {
        if self.frames == 0 {
            return;
        }
        let data: Arc<[f32]> = Arc::from(&self.buf[..]);
        self.buf.clear();
        self.frames = 0;
        let item = match self.channels {
            None => Item::Audio(AudioBlock {
                t0_ns: self.t0_ns,
                rate_hz: self.rate,
                samples: data,
            }),
            Some(channels) => Item::Samples(SampleBlock {
                t0_ns: self.t0_ns,
                rate_hz: self.rate,
                channels,
                data,
                times_ns: None,
            }),
        };
        let _ = out.emit(item);
    }
}

/// Collects one sample per frame into mono [`AudioBlock`]s (see [`Batcher`]).
pub struct AudioBatcher(Batcher);

impl AudioBatcher {
    pub fn new(block: usize) -> Self {
        Self(Batcher::audio(block))
    }

    pub fn push(&mut self, t_ns: i64, rate: f64, v: f32, out: &mut Emitter) {
        self.0.push(t_ns, rate, [v], out);
    }

    pub fn flush(&mut self, out: &mut Emitter) {
        self.0.flush(out);
    }
}
