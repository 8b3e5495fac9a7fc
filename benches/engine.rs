//! Engine throughput: 256x256 8-bit frames from a pattern source through
//! three pass-through stages to a null sink (`chain3`), against the same
//! source straight into the null sink (`direct`), measured in the same run.
//! Target (issue 2): chain3 >= 20,000 frames/s on a 2-core machine.
//!
//!     cargo bench --bench engine

#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use vibroscope_engine::config::parse;
use vibroscope_engine::graph::validate;
use vibroscope_engine::stages::KINDS;
use vibroscope_engine::{run, Control, RunOptions};

const FRAMES: u64 = 20_000;

fn pipeline(stages: usize, size: u32) -> String {
    let mut t = format!("[[stage]]\nid = \"s0\"\nkind = \"pattern\"\nwidth = {size}\nheight = {size}\nframes = {FRAMES}\n\n");
    for i in 1..=stages {
        t += &format!(
            "[[stage]]\nid = \"s{i}\"\nkind = \"passthrough\"\ninput = \"s{}\"\n\n",
            i - 1
        );
    }
    t += &format!("[[stage]]\nid = \"sink\"\nkind = \"null\"\ninput = \"s{stages}\"\n");
    t
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("engine_256x256_u8");
    g.sample_size(10);
    g.throughput(Throughput::Elements(FRAMES));
    for (name, stages) in [("direct", 0usize), ("chain3", 3)] {
        let decl = parse("bench", &pipeline(stages, 256)).expect("pipeline parses");
        g.bench_with_input(BenchmarkId::new(name, FRAMES), &decl, |b, decl| {
            b.iter(|| {
                let graph = validate(decl, KINDS).expect("valid");
                let r = run(graph, Control::new(), &RunOptions::default()).expect("runs");
                assert!(r.errors.is_empty());
                assert_eq!(r.stages.last().map(|s| s.items_in), Some(FRAMES));
            })
        });
    }
    g.finish();
}

// No plots: criterion's plotters backend needs system fonts, which a
// headless machine may lack (it panicked there); the figures are printed.
criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = bench
}
criterion_main!(benches);
