//! The frame path allocates nothing per frame: a counting global allocator
//! sees the same number of allocations for 1,000 and for 10,000 frames
//! through source -> 3 pass-through stages -> null sink (everything is
//! allocated when the graph is built: pool, rings, threads).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use vibroscope::engine::config::parse;
use vibroscope::engine::graph::validate;
use vibroscope::engine::{run, Control, RunOptions};
use vibroscope::stages::REGISTRY;

struct Counting;
static ALLOCS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static A: Counting = Counting;

fn allocations(frames: u64) -> u64 {
    let text = format!(
        "[[stage]]\nid = \"s\"\nkind = \"pattern\"\nwidth = 64\nheight = 64\nframes = {frames}\n\n\
         [[stage]]\nid = \"a\"\nkind = \"passthrough\"\ninput = \"s\"\n\n\
         [[stage]]\nid = \"b\"\nkind = \"passthrough\"\ninput = \"a\"\n\n\
         [[stage]]\nid = \"c\"\nkind = \"passthrough\"\ninput = \"b\"\n\n\
         [[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"c\"\n"
    );
    let decl = parse("alloc.toml", &text).unwrap();
    let graph = validate(&decl, REGISTRY).unwrap();
    let before = ALLOCS.load(Ordering::SeqCst);
    let report = run(graph, Control::new(), &RunOptions::default()).unwrap();
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(report.errors.is_empty());
    assert_eq!(report.stages.last().unwrap().items_in, frames);
    after - before
}

#[test]
fn no_allocation_per_frame() {
    allocations(100); // warm up lazy statics
    let small = allocations(1_000);
    let large = allocations(10_000);
    eprintln!("allocations: {small} for 1,000 frames, {large} for 10,000");
    // Thread start-up may vary by a few; 9,000 more frames must not add any
    // per-frame allocation (that would be >= 9,000 more).
    assert!(
        large <= small + 50,
        "{small} allocations for 1,000 frames, {large} for 10,000"
    );
}
