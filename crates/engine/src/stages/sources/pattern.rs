//! `pattern`: a static test pattern at a given size and rate. Costs next to
//! nothing per frame (each pool buffer is drawn once), so it measures the
//! engine itself; with `realtime = true` it is a live-paced camera.

use super::{nominal_frame, side_param, Pacer, BITS};
use crate::*;
use vibroscope_io::Depth;

params! {
    /// `pattern`'s parameters.
    pub struct PatternParams for "pattern" {
        width: u32 = side_param("width", 256, "frame width"),
        height: u32 = side_param("height", 256, "frame height"),
        fps: f64 = super::fps_param(Def::Float(1000.0), "frame rate"),
        frames: u64 = ParamSpec::of(ParamType::Int, Def::Int(1000))
            .ints(0, i64::MAX)
            .doc("frames produced"),
        bits: u8 = BITS,
        realtime: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("pace frames by the wall clock like a live camera"),
    }
}

type P = PatternParams;

pub const KIND: KindSpec = KindSpec {
    name: "pattern",
    summary: "static test pattern at a chosen size and rate (engine benchmarks; `realtime` = live camera)",
    inputs: NO_INPUTS,
    outputs: &[OutPort::out(PortType::Frames)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
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
