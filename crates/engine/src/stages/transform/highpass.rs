//! `highpass`: streaming Butterworth high-pass on an audio stream (removes
//! drift and slow camera motion before listening; thesis ch. 4).
//!
//! `cutoff_hz` defaults to fs/40 clamped to 20-100 Hz (and never above
//! fs/4, for slow cameras), decided from the first block's rate.

use crate::*;
use serde::Deserialize;
use std::sync::Arc;
use vibroscope_math::iir::Sos;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    order: usize,
    cutoff_hz: Option<f64>,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::new("order", ParamType::Int, Def::Int(4))
        .ints(1, 16)
        .doc("Butterworth order (second-order sections for even orders)"),
    ParamSpec::new("cutoff_hz", ParamType::Float, Def::Optional)
        .above(0.0)
        .unit("Hz")
        .doc("-3 dB corner; default fs/40 clamped to 20-100 Hz (and <= fs/4)"),
];

pub const KIND: KindSpec = KindSpec {
    name: "highpass",
    summary:
        "streaming Butterworth high-pass (order, cutoff_hz; default fs/40 clamped to 20-100 Hz)",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: PARAMS,
    plan: |p| {
        let v: P = p.resolve(PARAMS)?;
        Ok(Box::new(HighpassPlan(v)))
    },
};

pub use vibroscope_math::iir::default_highpass_cutoff_hz as default_cutoff_hz;

struct HighpassPlan(P);

impl Plan for HighpassPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Highpass {
            order: self.0.order,
            cutoff: self.0.cutoff_hz,
            filter: None,
            rate: 0.0,
            buf: Vec::new(),
        })))
    }
}

struct Highpass {
    order: usize,
    cutoff: Option<f64>,
    filter: Option<Sos>,
    rate: f64,
    buf: Vec<f32>,
}

impl Stage for Highpass {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if self.filter.is_none() || a.rate_hz != self.rate {
            let fc = self.cutoff.unwrap_or_else(|| default_cutoff_hz(a.rate_hz));
            let f = Sos::butterworth_highpass(self.order, fc, a.rate_hz)
                .map_err(|e| StageError::dsp(format!("highpass: {e}")))?;
            tracing::info!(
                cutoff_hz = fc,
                order = self.order,
                rate_hz = a.rate_hz,
                "highpass designed"
            );
            self.filter = Some(f);
            self.rate = a.rate_hz;
        }
        let Some(f) = self.filter.as_mut() else {
            return Ok(());
        };
        self.buf.clear();
        self.buf
            .extend(a.samples.iter().map(|&x| f.step(x as f64) as f32));
        let _ = out.emit(Item::Audio(AudioBlock {
            t0_ns: a.t0_ns,
            rate_hz: a.rate_hz,
            samples: Arc::from(&self.buf[..]),
        }));
        Ok(())
    }
}
