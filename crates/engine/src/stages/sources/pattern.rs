//! `pattern`: a static test pattern at a given size and rate. Costs next to
//! nothing per frame (each pool buffer is drawn once), so it measures the
//! engine itself; with `realtime = true` it is a live-paced camera.

use super::{check_fps, nominal_frame, Pacer};
use crate::*;
use serde::Deserialize;
use vibroscope_io::Depth;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    #[serde(default = "d_size")]
    width: u32,
    #[serde(default = "d_size")]
    height: u32,
    #[serde(default = "d_fps")]
    fps: f64,
    #[serde(default = "d_frames")]
    frames: u64,
    #[serde(default = "d_bits")]
    bits: u8,
    #[serde(default)]
    realtime: bool,
}
fn d_size() -> u32 {
    256
}
fn d_fps() -> f64 {
    1000.0
}
fn d_frames() -> u64 {
    1000
}
fn d_bits() -> u8 {
    8
}

pub const KIND: KindSpec = KindSpec {
    name: "pattern",
    summary: "static test pattern at a chosen size and rate (engine benchmarks; `realtime` = live camera)",
    accepts: &[],
    max_inputs: 0,
    output: Output::Fixed(PortType::Frames),
    plan: |p| {
        let v: P = p.parse()?;
        check_fps(v.fps).map_err(|m| p.error("fps", m))?;
        if v.width == 0 || v.height == 0 || v.width > 16384 || v.height > 16384 {
            return Err(p.error("width", format!("frame size must be 1..=16384 each, got {}x{}", v.width, v.height)));
        }
        if !(1..=16).contains(&v.bits) {
            return Err(p.error("bits", format!("must be 1..=16, got {}", v.bits)));
        }
        Ok(Box::new(PatternPlan(v)))
    },
};

struct PatternPlan(P);

impl Plan for PatternPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let p = self.0;
        let format = FrameFormat {
            width: p.width,
            height: p.height,
            depth: if p.bits > 8 { Depth::U16 } else { Depth::U8 },
            bits: p.bits,
            fps: p.fps,
            row_timing: None,
        };
        let pool = FramePool::new(format, ctx.pool_frames);
        Ok(Node::Source(Box::new(Pattern {
            drawn: vec![false; pool.capacity()],
            pool,
            seq: 0,
            total: p.frames,
            fps: p.fps,
            pacer: p.realtime.then(|| Pacer::new(p.fps)),
        })))
    }
    fn is_live(&self) -> bool {
        self.0.realtime
    }
}

struct Pattern {
    pool: FramePool,
    drawn: Vec<bool>,
    seq: u64,
    total: u64,
    fps: f64,
    pacer: Option<Pacer>,
}

fn draw(f: &mut FrameMut) {
    let (w, max) = (f.format().width as usize, f.format().max_value());
    let level = |i: usize| {
        let (x, y) = (i % w, i / w);
        let checker = ((x / 8 + y / 8) % 2) as f64;
        (0.25 + 0.5 * checker * 0.5 + 0.25 * (x as f64 / w as f64)) * max
    };
    match f.pixels_mut() {
        PixelsMut::U8(p) => p
            .iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v = level(i) as u8),
        PixelsMut::U16(p) => p
            .iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v = level(i) as u16),
    }
}

impl Source for Pattern {
    fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
        if self.seq >= self.total {
            return Ok(None);
        }
        if let Some(p) = &mut self.pacer {
            p.wait(self.seq, ctx.control.epoch());
        }
        let Some(mut f) = ctx.acquire(&self.pool) else {
            return Ok(None);
        };
        // The pattern is static: draw each pool buffer the first time only.
        let slot = f.slot();
        if let Some(d) = self.drawn.get_mut(slot) {
            if !*d {
                draw(&mut f);
                *d = true;
            }
        }
        let item = nominal_frame(f, self.seq, self.fps);
        self.seq += 1;
        Ok(Some(item))
    }
    fn total_hint(&self) -> Option<u64> {
        Some(self.total)
    }
    fn is_live(&self) -> bool {
        self.pacer.is_some()
    }
}
