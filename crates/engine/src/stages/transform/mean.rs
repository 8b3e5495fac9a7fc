//! `mean`: mean intensity of a region per frame, as an audio-rate signal
//! (one sample per frame, at the frame's capture time). Bit-identical for
//! any `threads` (see [`super::reduce`]).

use super::audio_out::AudioBatcher;
use super::reduce::{check_roi, RowReducer, BLOCK, ROI, THREADS};
use super::roi::{Roi, RoiParam};
use crate::*;

params! {
    /// `mean`'s parameters.
    pub struct MeanParams for "mean" {
        roi: Option<RoiParam> = ROI,
        threads: usize = THREADS,
        block: usize = BLOCK,
    }
}

type P = MeanParams;

pub const KIND: KindSpec = KindSpec {
    name: "mean",
    summary: "mean intensity of a region per frame, as audio (deterministic for any `threads`)",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        check_roi(p, v.roi.as_ref())?;
        Ok(Box::new(MeanPlan(v)))
    },
};

struct MeanPlan(P);

impl Plan for MeanPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Mean {
            roi: self.0.roi,
            sums: RowReducer::new(self.0.threads)?,
            out: AudioBatcher::new(self.0.block),
        })))
    }
}

struct Mean {
    roi: Option<RoiParam>,
    sums: RowReducer,
    out: AudioBatcher,
}

fn row_sum(p: PixelsRef<'_>, start: usize, len: usize) -> f64 {
    match p {
        PixelsRef::U8(d) => d[start..start + len].iter().map(|&v| v as u64).sum::<u64>() as f64,
        PixelsRef::U16(d) => d[start..start + len].iter().map(|&v| v as u64).sum::<u64>() as f64,
    }
}

impl Stage for Mean {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        let r = Roi::resolve(self.roi.as_ref(), f.width(), f.height())?;
        let (w, px) = (f.width(), f.pixels());
        let total = self.sums.sum(r.h, |y0, y1| {
            (y0..y1)
                .map(|yy| row_sum(px, (r.y + yy) * w + r.x, r.w))
                .sum()
        });
        let mean = total / (r.w * r.h) as f64;
        self.out
            .push(f.meta().t_ns, f.format().fps, mean as f32, out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.out.flush(out);
        Ok(())
    }
}
