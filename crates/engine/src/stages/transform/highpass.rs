//! `highpass`: Butterworth high-pass on an audio stream (removes drift and
//! slow camera motion before listening; thesis ch. 4), zero-phase on
//! replay and causal live (see [`super::butterworth`] for the modes).
//!
//! `cutoff_hz` defaults to fs/40 clamped to 20-100 Hz (and never above
//! fs/4, for slow cameras), decided from the first block's rate.

use super::butterworth::{Design, FilterPlan, Mode, MODE};
use crate::*;
use serde::Deserialize;
use vibroscope_math::iir::Shape;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    order: usize,
    cutoff_hz: Option<f64>,
    mode: Mode,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::new("order", ParamType::Int, Def::Int(4))
        .ints(1, 16)
        .doc("Butterworth order (second-order sections for even orders)"),
    ParamSpec::new("cutoff_hz", ParamType::Float, Def::Optional)
        .above(0.0)
        .unit("Hz")
        .doc("-3 dB corner (-6 dB zero-phase); default fs/40 clamped to 20-100 Hz (and <= fs/4)"),
    MODE,
];

pub const KIND: KindSpec = KindSpec {
    name: "highpass",
    summary: "Butterworth high-pass (order, cutoff_hz; default fs/40 clamped to 20-100 Hz); zero-phase on replay, causal live (mode)",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: PARAMS,
    plan: |p| {
        let v: P = p.resolve(PARAMS)?;
        Ok(Box::new(FilterPlan {
            kind: "highpass",
            order: v.order,
            design: match v.cutoff_hz {
                Some(cutoff_hz) => Design::Fixed(Shape::Highpass { cutoff_hz }),
                None => Design::DefaultHighpass,
            },
            mode: v.mode,
        }))
    },
};

pub use vibroscope_math::iir::default_highpass_cutoff_hz as default_cutoff_hz;
