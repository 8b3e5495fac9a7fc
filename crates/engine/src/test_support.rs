//! Helpers the engine's unit tests share.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::edge::{edge, Policy};
use crate::*;
use std::sync::Arc;

/// Builds `plan` for a replay (`live = false`) or a live graph with one
/// audio input, feeds it `x` at `fs` in blocks of `block` samples (block
/// `k` stamped `t0_ns + k * block / fs`), finishes it and returns every
/// audio block it emitted.
pub(crate) fn run_audio_stage(
    plan: Box<dyn Plan>,
    live: bool,
    x: &[f32],
    fs: f64,
    block: usize,
    t0_ns: i64,
) -> Vec<AudioBlock> {
    let ctx = BuildCtx {
        id: "stage".into(),
        held_downstream: 0,
        pool_frames: 0,
        input_types: vec![PortType::Audio],
        live,
        observer: None,
        worker_busy_ns: Default::default(),
    };
    let Ok(Node::Stage(mut st)) = plan.build(&ctx) else {
        panic!("not a stage");
    };
    let (tx, mut rx, _) = edge(x.len() + 1, Policy::Block);
    let mut out = Emitter::new(vec![tx], Control::new(), Arc::default());
    for (k, c) in x.chunks(block).enumerate() {
        let a = AudioBlock {
            t0_ns: t0_ns + (k as f64 * block as f64 * 1e9 / fs).round() as i64,
            rate_hz: fs,
            samples: Arc::from(c),
        };
        st.process(0, Item::Audio(a), &mut out).unwrap();
    }
    st.finish(&mut out).unwrap();
    let mut blocks = Vec::new();
    while let Some(Item::Audio(a)) = rx.try_recv() {
        blocks.push(a);
    }
    blocks
}
