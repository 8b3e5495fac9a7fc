//! `null`: consumes and discards items (benchmarks, tests).

use crate::*;

params! {
    /// `null`'s parameters (none).
    pub struct NullParams for "null" {}
}

const ANY: &[PortType] = &[
    PortType::Frames,
    PortType::Samples,
    PortType::Audio,
    PortType::Spectrum,
    PortType::Pyramid,
];

pub const KIND: KindSpec = KindSpec {
    name: "null",
    summary: "discards everything it receives (benchmarks)",
    inputs: &[InPort {
        name: "in",
        accepts: ANY,
        max_edges: 16,
    }],
    outputs: NO_OUTPUTS,
    params: NullParams::PARAMS,
    plan: |p| {
        let _: NullParams = p.resolve_typed()?;
        Ok(Box::new(Null))
    },
};

struct Null;

impl Plan for Null {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}

impl Stage for Null {
    fn process(&mut self, _: usize, _item: Item, _: &mut Emitter) -> Result<(), StageError> {
        Ok(())
    }
}
