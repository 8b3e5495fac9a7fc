//! `gradient_motion`: global sub-pixel motion of a region along a direction,
//! one sample per frame, by linearised least squares against a reference
//! frame (the first one):
//!
//! I_t(x) = R(x - d) ≈ R(x) - d g(x), with g the directional derivative of
//! R, so d = Σ g (R - I_t) / Σ g².
//!
//! This is the intensity-gradient estimator, the simplest honest visual
//! microphone; the phase-based pipeline of thesis ch. 3 is more robust to
//! noise and large motion. Bit-identical for any `threads` (see
//! [`super::reduce`]).

use super::audio_out::AudioBatcher;
use super::reduce::{check_roi, RowReducer, BLOCK, ROI, THREADS};
use super::roi::{Roi, RoiParam};
use crate::*;

params! {
    /// `gradient_motion`'s parameters.
    pub struct GradientMotionParams for "gradient_motion" {
        roi: Option<RoiParam> = ROI,
        direction_deg: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.0))
            .unit("deg")
            .doc("direction of motion to measure (0 = +x, 90 = +y)"),
        threads: usize = THREADS,
        block: usize = BLOCK,
    }
}

type P = GradientMotionParams;

pub const KIND: KindSpec = KindSpec {
    name: "gradient_motion",
    summary: "sub-pixel motion of a region along a direction (least squares on image gradients), as audio",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        check_roi(p, v.roi.as_ref())?;
        Ok(Box::new(MotionPlan(v)))
    },
};

struct MotionPlan(P);

impl Plan for MotionPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let th = self.0.direction_deg.to_radians();
        Ok(Node::Stage(Box::new(Motion {
            roi: self.0.roi,
            dir: (th.cos() as f32, th.sin() as f32),
            sums: RowReducer::new(self.0.threads)?,
            reference: Vec::new(),
            grad: Vec::new(),
            norm: 0.0,
            region: None,
            out: AudioBatcher::new(self.0.block),
        })))
    }
}

struct Motion {
    roi: Option<RoiParam>,
    dir: (f32, f32),
    sums: RowReducer,
    /// Reference intensities and directional gradient over the region.
    reference: Vec<f32>,
    grad: Vec<f32>,
    norm: f64,
    region: Option<Roi>,
    out: AudioBatcher,
}

/// Pixel `i` of a frame as f32.
pub(super) fn px(p: PixelsRef<'_>, i: usize) -> f32 {
    match p {
        PixelsRef::U8(d) => d[i] as f32,
        PixelsRef::U16(d) => d[i] as f32,
    }
}

impl Motion {
    /// Takes the first frame as reference: allocates once per stream.
    fn set_reference(&mut self, f: &Frame) -> Result<Roi, StageError> {
        let (w, h) = (f.width(), f.height());
        let full = Roi::resolve(self.roi.as_ref(), w, h)?;
        // Central differences need a neighbour on each side.
        let (x0, y0) = (full.x.max(1), full.y.max(1));
        let r = Roi {
            x: x0,
            y: y0,
            w: (full.x + full.w)
                .min(w.saturating_sub(1))
                .saturating_sub(x0),
            h: (full.y + full.h)
                .min(h.saturating_sub(1))
                .saturating_sub(y0),
        };
        if r.w == 0 || r.h == 0 {
            return Err(StageError::config(
                "roi",
                format!("the region is too small in a {w}x{h} frame"),
            ));
        }
        let p = f.pixels();
        self.reference = Vec::with_capacity(r.w * r.h);
        self.grad = Vec::with_capacity(r.w * r.h);
        for y in r.y..r.y + r.h {
            for x in r.x..r.x + r.w {
                let i = y * w + x;
                let gx = 0.5 * (px(p, i + 1) - px(p, i - 1));
                let gy = 0.5 * (px(p, i + w) - px(p, i - w));
                self.reference.push(px(p, i));
                self.grad.push(self.dir.0 * gx + self.dir.1 * gy);
            }
        }
        self.norm = self.grad.iter().map(|&g| (g as f64) * (g as f64)).sum();
        if self.norm <= 0.0 {
            return Err(StageError::dsp(
                "the region has no texture along the chosen direction (zero gradient)",
            ));
        }
        self.region = Some(r);
        Ok(r)
    }
}

impl Stage for Motion {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        let r = match self.region {
            Some(r) => r,
            None => self.set_reference(&f)?,
        };
        let (w, p) = (f.width(), f.pixels());
        let (reference, grad) = (&self.reference, &self.grad);
        let total = self.sums.sum(r.h, |y0, y1| {
            let mut acc = 0.0f64;
            for yy in y0..y1 {
                let row = (r.y + yy) * w + r.x;
                let k = yy * r.w;
                let mut racc = 0.0f32;
                for xx in 0..r.w {
                    racc += grad[k + xx] * (reference[k + xx] - px(p, row + xx));
                }
                acc += racc as f64;
            }
            acc
        });
        self.out.push(
            f.meta().t_ns,
            f.format().fps,
            (total / self.norm) as f32,
            out,
        );
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.out.flush(out);
        Ok(())
    }
}
