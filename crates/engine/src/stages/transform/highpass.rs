//! `highpass`: Butterworth high-pass on an audio stream (removes drift and
//! slow camera motion before listening; thesis ch. 4), zero-phase on
//! replay and causal live (see [`super::butterworth`] for the modes).
//!
//! `cutoff_hz` defaults to fs/40 clamped to 20-100 Hz (and never above
//! fs/4, for slow cameras), decided from the first block's rate.

use super::butterworth::{Design, FilterPlan, Mode, MODE};
use crate::*;
use vibroscope_math::iir::Shape;

params! {
    /// `highpass`'s parameters.
    pub struct HighpassParams for "highpass" {
        order: usize = ParamSpec::of(ParamType::Int, Def::Int(4))
            .ints(1, 16)
            .doc("Butterworth order (second-order sections for even orders)"),
        cutoff_hz: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .above(0.0)
            .unit("Hz")
            .doc("-3 dB corner (-6 dB zero-phase); default fs/40 clamped to 20-100 Hz (and <= fs/4)"),
        mode: Mode = MODE,
    }
}

type P = HighpassParams;

pub const KIND: KindSpec = KindSpec {
    name: "highpass",
    summary: "Butterworth high-pass (order, cutoff_hz; default fs/40 clamped to 20-100 Hz); zero-phase on replay, causal live (mode)",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
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
