//! The frame path allocates nothing per frame: a counting global allocator
//! sees the same number of allocations for 1,000 and for 10,000 frames
//! through source -> 3 pass-through stages -> null sink (everything is
//! allocated when the graph is built: pool, rings, threads).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use vibroscope_engine::config::parse;
use vibroscope_engine::graph::validate;
use vibroscope_engine::stages::KINDS;
use vibroscope_engine::{run, Control, RunOptions};

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

/// The counter is global: tests in this file take turns.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn allocations(frames: u64) -> u64 {
    let text = format!(
        "[[stage]]\nid = \"s\"\nkind = \"pattern\"\nwidth = 64\nheight = 64\nframes = {frames}\n\n\
         [[stage]]\nid = \"a\"\nkind = \"passthrough\"\ninput = \"s\"\n\n\
         [[stage]]\nid = \"b\"\nkind = \"passthrough\"\ninput = \"a\"\n\n\
         [[stage]]\nid = \"c\"\nkind = \"passthrough\"\ninput = \"b\"\n\n\
         [[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"c\"\n"
    );
    let decl = parse("alloc.toml", &text).unwrap();
    let graph = validate(&decl, KINDS).unwrap();
    let before = ALLOCS.load(Ordering::SeqCst);
    let report = run(graph, Control::new(), &RunOptions::default()).unwrap();
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(report.errors.is_empty());
    assert_eq!(report.stages.last().unwrap().items_in, frames);
    after - before
}

#[test]
fn no_allocation_per_frame() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
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

fn pyramid_allocations(frames: u64, pyramid: &str) -> u64 {
    let text = format!(
        "[[stage]]\nid = \"s\"\nkind = \"pattern\"\nwidth = 64\nheight = 64\nframes = {frames}\nfps = 1000.0\n\n\
         [[stage]]\nid = \"p\"\nkind = \"pyramid\"\ninput = \"s\"\npyramid = \"{pyramid}\"\nthreads = 2\n\n\
         [[stage]]\nid = \"ph\"\nkind = \"phase\"\ninput = \"p\"\nblock = 4096\nreference_interval_s = 0\n\n\
         [[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"ph\"\n"
    );
    graph_allocations(&text)
}

/// `phase` on frames with two workers streams them to its helper thread
/// (renewing its reference every 500 frames, with a handover of 32).
fn streamed_phase_allocations(frames: u64, pyramid: &str) -> u64 {
    let text = format!(
        "[[stage]]\nid = \"s\"\nkind = \"pattern\"\nwidth = 64\nheight = 64\nframes = {frames}\nfps = 1000.0\n\n\
         [[stage]]\nid = \"ph\"\nkind = \"phase\"\ninput = \"s\"\npyramid = \"{pyramid}\"\nthreads = 2\nblock = 4096\nreference_interval_s = 0.5\n\n\
         [[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"ph\"\n"
    );
    graph_allocations(&text)
}

fn graph_allocations(text: &str) -> u64 {
    let decl = parse("alloc.toml", text).unwrap();
    let graph = validate(&decl, KINDS).unwrap();
    let before = ALLOCS.load(Ordering::SeqCst);
    let report = run(graph, Control::new(), &RunOptions::default()).unwrap();
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(report.errors.is_empty(), "{:?}", report.errors);
    after - before
}

/// The `pyramid` stage recycles its coefficient buffers once `phase` lets
/// go of them, and `phase` renews its reference (every 500 frames here)
/// from a spare, so nothing is allocated per frame. What remains grows
/// with the stream but far slower than the frames: the sample blocks (one
/// per 4,096 frames) and rayon's job queue, which allocates a block of
/// slots every 63 batches of frames (about one allocation per 126 frames
/// per stage with two workers). Checked: 20,000 more frames add fewer than
/// one allocation per 20 frames.
#[test]
fn pyramid_and_phase_allocate_nothing_per_frame() {
    fewer_than_one_allocation_per_20_frames(pyramid_allocations);
}

/// Both pyramids through `allocations(frames, pyramid)`: 20,000 more
/// frames (30,000 against 10,000, after a warm-up) add fewer than one
/// allocation per 20 frames.
fn fewer_than_one_allocation_per_20_frames(allocations: fn(u64, &str) -> u64) {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for pyramid in ["csp", "riesz"] {
        allocations(100, pyramid);
        let small = allocations(10_000, pyramid);
        let large = allocations(30_000, pyramid);
        let per_frame = (large as f64 - small as f64) / 20_000.0;
        eprintln!(
            "{pyramid}: allocations: {small} for 10,000 frames, {large} for 30,000 ({per_frame:.4} per extra frame)"
        );
        assert!(
            per_frame < 0.05,
            "{pyramid}: {small} allocations for 10,000 frames, {large} for 30,000"
        );
    }
}

/// The same for `phase` reading frames with two workers, which streams
/// them to a helper thread one by one (no batches), its references shared
/// with each frame in flight: nothing per frame either.
#[test]
fn streamed_phase_allocates_nothing_per_frame() {
    fewer_than_one_allocation_per_20_frames(streamed_phase_allocations);
}
