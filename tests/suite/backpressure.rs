//! Backpressure with a deliberately slow stage.
//!
//! Under `block` every frame arrives, in order, none duplicated, whatever the
//! ring capacities and rates (proptest). Under `drop_oldest` after a
//! live-paced source, memory stays bounded (fixed pool, queues never above
//! capacity), the newest frames win, and drops are counted and reported.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::*;
use std::sync::Mutex;
use vibroscope_engine::config::parse;
use vibroscope_engine::graph::validate;
use vibroscope_engine::stages::KINDS;
use vibroscope_engine::*;

/// Sequence numbers seen by the `collect` sink (tests run it one at a time).
static SEEN: Mutex<Vec<u64>> = Mutex::new(Vec::new());
static LOCK: Mutex<()> = Mutex::new(());

struct Collect;
impl Plan for Collect {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}
impl Stage for Collect {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        if let Item::Frame(f) = item {
            SEEN.lock().unwrap().push(f.meta().seq);
        }
        Ok(())
    }
}

fn registry() -> &'static [KindSpec] {
    static R: std::sync::OnceLock<Vec<KindSpec>> = std::sync::OnceLock::new();
    R.get_or_init(|| {
        let mut v: Vec<KindSpec> = KINDS.to_vec();
        v.push(KindSpec {
            name: "collect",
            summary: "test sink",
            inputs: &[InPort {
                name: "in",
                accepts: &[PortType::Frames],
                max_edges: 1,
            }],
            outputs: &[],
            params: &[],
            plan: |p| {
                #[derive(serde::Deserialize)]
                #[serde(deny_unknown_fields)]
                struct P {}
                let _: P = p.parse()?;
                Ok(Box::new(Collect))
            },
        });
        v
    })
}

fn run_text(text: &str) -> (RunReport, Vec<u64>) {
    SEEN.lock().unwrap().clear();
    let decl = parse("test.toml", text).unwrap();
    let graph = validate(&decl, registry()).unwrap();
    let report = run(graph, Control::new(), &RunOptions::default()).unwrap();
    assert!(report.errors.is_empty(), "{:?}", report.errors);
    (report, std::mem::take(&mut *SEEN.lock().unwrap()))
}

fn pipeline(
    frames: u64,
    fps: f64,
    realtime: bool,
    cap_in: usize,
    cap_slow: usize,
    delay_us: u64,
    policy: &str,
) -> String {
    format!(
        "[[stage]]\nid = \"src\"\nkind = \"pattern\"\nwidth = 32\nheight = 8\nframes = {frames}\nfps = {fps}\nrealtime = {realtime}\n\n\
         [[stage]]\nid = \"slow\"\nkind = \"passthrough\"\ninput = {{ from = \"src\", capacity = {cap_in}, policy = \"{policy}\" }}\ndelay_us = {delay_us}\n\n\
         [[stage]]\nid = \"fast\"\nkind = \"passthrough\"\ninput = \"slow\"\ncapacity = {cap_slow}\n\n\
         [[stage]]\nid = \"sink\"\nkind = \"collect\"\ninput = \"fast\"\ncapacity = 1\n"
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    #[test]
    fn block_delivers_every_frame_in_order(cap_in in 1usize..6, cap_slow in 1usize..6, delay_us in 0u64..300, fps in 2000.0f64..20000.0, frames in 1u64..120) {
        let _g = LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let (report, seen) = run_text(&pipeline(frames, fps, true, cap_in, cap_slow, delay_us, "block"));
        prop_assert_eq!(seen, (0..frames).collect::<Vec<_>>());
        prop_assert!(report.stages.iter().all(|s| s.dropped == 0));
        for s in &report.stages {
            prop_assert!(s.max_queue <= s.queue_capacity, "{} queued {} > {}", s.id, s.max_queue, s.queue_capacity);
        }
    }
}

#[test]
fn drop_oldest_bounds_memory_keeps_newest_and_counts_drops() {
    let _g = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // A 2000 fps live camera into a stage that needs 2 ms per frame.
    let frames = 400;
    let (report, seen) = run_text(&pipeline(frames, 2000.0, true, 4, 2, 2000, "drop_oldest"));
    let slow = report.stages.iter().find(|s| s.id == "slow").unwrap();
    let src = report.stages.iter().find(|s| s.id == "src").unwrap();
    assert_eq!(src.items_out, frames);
    assert!(
        slow.dropped > 0,
        "a slow stage behind a live source must drop"
    );
    assert_eq!(
        slow.items_in + slow.dropped,
        frames,
        "every frame is either processed or counted as dropped"
    );
    assert_eq!(seen.len() as u64, slow.items_in);
    assert!(
        seen.windows(2).all(|w| w[0] < w[1]),
        "order kept, nothing duplicated"
    );
    assert_eq!(*seen.last().unwrap(), frames - 1, "the newest frame wins");
    for s in &report.stages {
        assert!(s.max_queue <= s.queue_capacity);
    }
    assert!(report.table().contains("dropped"));
    let row = report
        .table()
        .lines()
        .find(|l| l.starts_with("slow"))
        .unwrap()
        .to_string();
    assert!(row.contains(&slow.dropped.to_string()), "{row}");
}

#[test]
fn live_default_policy_is_drop_oldest_and_file_default_is_block() {
    let text = "[[stage]]\nid = \"src\"\nkind = \"pattern\"\nrealtime = true\n\n[[stage]]\nid = \"a\"\nkind = \"passthrough\"\ninput = \"src\"\n\n[[stage]]\nid = \"b\"\nkind = \"null\"\ninput = \"a\"\n";
    let g = validate(&parse("t", text).unwrap(), registry()).unwrap();
    assert_eq!(g.nodes[1].inputs[0].policy, Policy::DropOldest);
    assert_eq!(g.nodes[2].inputs[0].policy, Policy::Block);
    let g = validate(
        &parse("t", &text.replace("realtime = true", "realtime = false")).unwrap(),
        registry(),
    )
    .unwrap();
    assert_eq!(g.nodes[1].inputs[0].policy, Policy::Block);
}

#[test]
fn fan_out_delivers_to_every_consumer_without_copies() {
    let _g = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let text = "[[stage]]\nid = \"src\"\nkind = \"pattern\"\nframes = 300\n\n[[stage]]\nid = \"a\"\nkind = \"collect\"\ninput = \"src\"\n\n[[stage]]\nid = \"b\"\nkind = \"collect\"\ninput = \"src\"\n";
    let (_, seen) = run_text(text);
    assert_eq!(seen.len(), 600);
    let mut sorted = seen.clone();
    sorted.sort_unstable();
    let expect: Vec<u64> = (0..300).flat_map(|i| [i, i]).collect();
    assert_eq!(sorted, expect);
}
