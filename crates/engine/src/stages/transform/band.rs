//! `bandpass` and `bandstop`: Butterworth band filters on an audio stream
//! (keep one resonance, or remove a hum or a camera's flicker), zero-phase
//! on replay and causal live (see [`super::butterworth`] for the modes).
//! Chain several for several bands: each is one stage.
//!
//! `order` is the prototype's: the filter has 2 `order` poles, and each
//! edge falls at 6 `order` dB per octave (twice that zero-phase).

use super::butterworth::{Design, FilterPlan, Mode, MODE};
use crate::*;
use vibroscope_math::iir::Shape;

params! {
    /// `bandpass`'s and `bandstop`'s parameters.
    pub struct BandParams for "bandpass", "bandstop" {
        order: usize = ParamSpec::of(ParamType::Int, Def::Int(2))
            .ints(1, 8)
            .doc("prototype order: 2*order poles, 6*order dB per octave at each edge"),
        lo_hz: f64 = ParamSpec::of(ParamType::Float, Def::Required)
            .above(0.0)
            .unit("Hz")
            .doc("lower -3 dB edge (-6 dB zero-phase)"),
        hi_hz: f64 = ParamSpec::of(ParamType::Float, Def::Required)
            .above(0.0)
            .unit("Hz")
            .doc("upper -3 dB edge (-6 dB zero-phase); above lo_hz, below half the rate"),
        mode: Mode = MODE,
    }
}

type P = BandParams;

fn plan(p: &Params<'_>, kind: &'static str, stop: bool) -> Result<Box<dyn Plan>, ConfigError> {
    let v: P = p.resolve_typed()?;
    if v.hi_hz <= v.lo_hz {
        return Err(p.error(
            "hi_hz",
            format!("must be above lo_hz ({} Hz), got {} Hz", v.lo_hz, v.hi_hz),
        ));
    }
    let (lo_hz, hi_hz) = (v.lo_hz, v.hi_hz);
    Ok(Box::new(FilterPlan {
        kind,
        order: v.order,
        design: Design::Fixed(if stop {
            Shape::Bandstop { lo_hz, hi_hz }
        } else {
            Shape::Bandpass { lo_hz, hi_hz }
        }),
        mode: v.mode,
    }))
}

pub const BANDPASS_KIND: KindSpec = KindSpec {
    name: "bandpass",
    summary: "Butterworth band-pass lo_hz..hi_hz (order); zero-phase on replay, causal live (mode)",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| plan(p, "bandpass", false),
};

pub const BANDSTOP_KIND: KindSpec = KindSpec {
    name: "bandstop",
    summary: "Butterworth band-stop (notch) lo_hz..hi_hz (order); zero-phase on replay, causal live (mode)",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| plan(p, "bandstop", true),
};
