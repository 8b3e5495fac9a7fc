//! `null`: consumes and discards items (benchmarks, tests).

use crate::*;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {}

pub const KIND: KindSpec = KindSpec {
    name: "null",
    summary: "discards everything it receives (benchmarks)",
    accepts: &[
        PortType::Frames,
        PortType::Samples,
        PortType::Audio,
        PortType::Spectrum,
        PortType::Pyramid,
    ],
    max_inputs: 16,
    output: Output::None,
    plan: |p| {
        let _: P = p.parse()?;
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
