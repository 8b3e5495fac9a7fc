//! `passthrough`: forwards every item unchanged (handles, not copies).
//! `delay_us` makes it deliberately slow, for backpressure tests and demos.

use crate::*;
use std::time::Duration;

params! {
    /// `passthrough`'s parameters.
    pub struct PassthroughParams for "passthrough" {
        delay_us: u64 = ParamSpec::of(ParamType::Int, Def::Int(0))
            .ints(0, 60_000_000)
            .unit("µs")
            .doc("sleep this long per item (simulates a slow stage)"),
    }
}

type P = PassthroughParams;

pub const KIND: KindSpec = KindSpec {
    name: "passthrough",
    summary: "forwards items unchanged; `delay_us` makes it slow on purpose",
    inputs: &[InPort::one(&[
        PortType::Frames,
        PortType::Samples,
        PortType::Audio,
        PortType::Spectrum,
        PortType::Pyramid,
    ])],
    outputs: &[OutPort {
        name: "out",
        ty: OutType::SameAsInput,
    }],
    params: P::PARAMS,
    plan: |p| {
        let p: P = p.resolve_typed()?;
        Ok(Box::new(Pass {
            delay: Duration::from_micros(p.delay_us),
        }))
    },
};

struct Pass {
    delay: Duration,
}

impl Plan for Pass {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}

impl Stage for Pass {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        if !self.delay.is_zero() {
            std::thread::sleep(self.delay);
        }
        // A downstream that went away is not this stage's error.
        let _ = out.emit(item);
        Ok(())
    }
}
