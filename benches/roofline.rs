//! The roofline of the magnifier's and the phase method's kernels (issue 52): this machine's
//! measured peaks (an FMA loop and a STREAM-like triad, on every core at
//! once and on one), then each step of `Magnifier::process` (Riesz and
//! CSP, 256x256 unless VIBROSCOPE_ROOFLINE_SIZE=WxH) timed in-process on
//! one core, with its floating-point operations and bytes per input pixel
//! (counted in `docs/performance.md`), the bound those give on one core,
//! and how far each step stands from it; the phase method's kernels; then the
//! commands end to end beside a numpy reference (scripts/numpy_reference.py)
//! and the bound on every core. `docs/performance.md` keeps the
//! figures of the last run and how each count was made.
//!
//!     cargo bench --bench roofline
//!     cargo bench --bench roofline -- --kernels   (in-process figures only)

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::{Duration, Instant};
use vibroscope_engine::spin::SpinJoin;
use vibroscope_math::magnify::{Magnifier, MagnifyParams, PyramidKind, STEPS};

#[path = "util/timing.rs"]
mod timing;

/// Operations and bytes per input pixel of each step in `STEPS`, for each
/// pyramid (4 scales; the CSP with 8 orientations), and the memory level
/// whose bandwidth bounds it (2: L2, 3: L3): derived in
/// docs/performance.md ("How the counts are made"). A step without counts
/// is fused into the one before it (level 1) or absent (level 0).
const RIESZ_COUNTS: [(f64, f64, u8); 7] = [
    (18.3, 37.2, 3),   // pyramid build
    (77.0, 15.9, 2),   // Riesz pair (7x7 filter): the level's rows from L2
    (171.3, 164.7, 3), // phase difference, sum, amplitude + temporal band-pass + the blur's rows (fused)
    (0.0, 0.0, 1),     // (fused into the step before)
    (108.8, 53.1, 3),  // the blur's columns (three channels) + phase shift (fused)
    (0.0, 0.0, 1),     // (fused into the step before)
    (9.3, 20.0, 3),    // pyramid collapse
];
const CSP_COUNTS: [(f64, f64, u8); 7] = [
    (800.0, 680.0, 2), // pyramid build (FFT, masks, band inverse FFTs)
    (0.0, 0.0, 0),     // (no Riesz pair)
    // One sweep of each band's rows (`csp_band`): phase step, band-pass,
    // blur, shift; from L3 only the state (previous phase, band-pass).
    (1484.0, 424.0, 3), // phase difference, amplitude + band-pass + blur + shift (fused)
    (0.0, 0.0, 1),      // (fused into the step before)
    (0.0, 0.0, 1),      // (fused into the step before)
    (0.0, 0.0, 1),      // (fused into the step before)
    (800.0, 680.0, 2),  // pyramid collapse (band FFTs, masks, inverse FFT)
];

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (w, h) = std::env::var("VIBROSCOPE_ROOFLINE_SIZE")
        .ok()
        .and_then(|s| {
            let (a, b) = s.split_once('x')?;
            Some((a.parse().ok()?, b.parse().ok()?))
        })
        .unwrap_or((256usize, 256usize));
    println!("roofline: {cores} cores, {w}x{h} frames");

    let (fma1, fma_all, lanes) = fma_peak(cores);
    println!(
        "  FMA peak ({lanes}-lane f32 fused multiply-add, 2 flops each): {fma1:.1} GFLOP/s on one core, {fma_all:.1} on {cores}"
    );
    // The triads: in L2, in L3 (three arrays making a quarter of it, so
    // that other cores' share of it does not push them out), and in
    // memory (three arrays each as large as L3, at least 16 MiB). The last
    // cache's size is read from the system; 32 MiB where it is not
    // reported.
    let l3 = cache_bytes(3).unwrap_or(32 << 20);
    // [L2, L3, memory], one core.
    let bw = [
        ("L2", 1usize << 16),
        ("L3", l3 / 48),
        ("memory", (l3 / 4).max(1 << 22)),
    ]
    .map(|(name, floats)| {
        let (one, all) = triad(floats, cores);
        println!(
            "  triad a = b + s*c in {name} (3 x {} KiB): {one:.1} GB/s on one core, {all:.1} on {cores} (12 bytes per element)",
            floats * 4 / 1024
        );
        one
    });
    let roofs = Roofs { fma1, bw, l3 };
    // A magnifier's state (about 20 arrays of a level's size) outgrows L2
    // at 256x256; the FFTs' buffers of one level fit L2. Whether the rest
    // is in L3 or in memory is read from the arrays' size (`Roofs::bound`).

    let frames = texture_frames(w, h, 64);
    // One-core whole-frame bounds (Mpix/s) for the end-to-end section.
    let mut magnify_bounds = Vec::new();
    for (kind, counts, label) in [
        (PyramidKind::Riesz, RIESZ_COUNTS, "riesz"),
        (PyramidKind::Csp, CSP_COUNTS, "csp (8 orientations)"),
    ] {
        let mut p = MagnifyParams::new(500.0, 35.0, 45.0, 10.0);
        p.pyramid = kind;
        let before = heap_bytes();
        let mut m = Magnifier::new(w, h, p).expect("magnifier");
        let mut out = vec![0.0f32; w * h];
        // Warm-up (the filters' start), then the profiled frames.
        for f in frames.iter().take(16) {
            m.process(f, &mut out).expect("process");
        }
        let arrays = heap_bytes().saturating_sub(before);
        m.set_profiling(true);
        let n = if kind == PyramidKind::Riesz { 400 } else { 100 };
        let t = Instant::now();
        for i in 0..n {
            m.process(&frames[i % frames.len()], &mut out)
                .expect("process");
        }
        let wall = t.elapsed().as_secs_f64();
        let prof = m.profile().expect("profile").clone();
        let px = (w * h) as f64;
        println!(
            "\n  magnify {label}, one core, {} vectors: {:.1} Mpix/s ({:.3} ms a frame); its arrays {:.1} MiB",
            m.simd(),
            n as f64 * px / wall / 1e6,
            wall / n as f64 * 1e3,
            arrays as f64 / (1 << 20) as f64
        );
        println!(
            "    {:<58} {:>8} {:>10} {:>8} {:>8} {:>4} {:>10} {:>7}",
            "step", "ms/frame", "Mpix/s", "flop/px", "B/px", "mem", "bound", "of bound"
        );
        let mut bound_total = 0.0;
        for (k, name) in STEPS.iter().enumerate() {
            let (flops, bytes, level) = counts[k];
            if flops == 0.0 && bytes == 0.0 {
                continue;
            }
            // The steps fused with this one (no count of their own) take
            // their time too.
            let fused: Vec<usize> = (k + 1..counts.len())
                .take_while(|&i| counts[i].2 == 1)
                .collect();
            let secs = prof.seconds[k] + fused.iter().map(|&i| prof.seconds[i]).sum::<f64>();
            let name = std::iter::once(name.to_string())
                .chain(fused.iter().map(|&i| STEPS[i].to_string()))
                .collect::<Vec<_>>()
                .join(" + ");
            let s = secs / prof.frames as f64;
            let rate = px / s / 1e6;
            // Mpix/s the step could reach at the one-core peaks.
            let (mem, bound) = roofs.bound(flops, bytes, level, arrays);
            bound_total += px / (bound * 1e6);
            println!(
                "    {name:<58} {:>8.3} {:>10.1} {:>8.1} {:>8.1} {:>4} {:>10.1} {:>7.2}",
                s * 1e3,
                rate,
                flops,
                bytes,
                mem,
                bound,
                rate / bound
            );
        }
        magnify_bounds.push(px / bound_total / 1e6);
        println!(
            "    whole frame: bound {:.1} Mpix/s on one core, measured {:.1} ({:.1}x the bound's time)",
            px / bound_total / 1e6,
            n as f64 * px / wall / 1e6,
            wall / n as f64 / bound_total
        );
        if kind == PyramidKind::Riesz && cores > 1 {
            // The same magnifier with its passes split over two threads
            // (as the `magnify` stage runs it, through its spinning helper), against one in this run.
            let j = SpinJoin::new("roofline-half", Duration::from_micros(500)).expect("helper");
            m.set_profiling(true);
            let t = Instant::now();
            for i in 0..n {
                m.process_with(&frames[i % frames.len()], &mut out, &j)
                    .expect("process");
            }
            let two = t.elapsed().as_secs_f64();
            println!(
                "    two threads (passes split in halves): {:.1} Mpix/s, {:.2}x one core",
                n as f64 * px / two / 1e6,
                wall / two
            );
            // Each step's speed-up: where the split loses (joins, halves
            // of unequal cost, levels too small to split).
            let two_prof = m.profile().expect("profile").clone();
            let steps: Vec<String> = STEPS
                .iter()
                .enumerate()
                // (A step fused into the one before it has no time of its own.)
                .filter(|&(k, _)| prof.seconds[k] > 0.01 * wall)
                .map(|(k, name)| {
                    let (one, two) = (
                        prof.seconds[k] / prof.frames as f64,
                        two_prof.seconds[k] / two_prof.frames as f64,
                    );
                    format!("{name} {:.3} ms ({:.2}x)", two * 1e3, one / two)
                })
                .collect();
            println!("    two threads, each step: {}", steps.join("; "));
            // Two frames in flight (as the `magnify` stage runs the Riesz
            // magnifier on two threads): two hand-overs a frame.
            let t = Instant::now();
            let mut deliver = |m: &[f32]| out.copy_from_slice(m);
            for i in 0..n {
                let frame = &frames[i % frames.len()];
                let mut load = |dst: &mut [f32]| dst.copy_from_slice(frame);
                m.process_pipelined(&mut load, &mut deliver, &j)
                    .expect("process");
            }
            m.flush(&mut deliver, &j).expect("flush");
            let piped = t.elapsed().as_secs_f64();
            println!(
                "    two frames in flight (two hand-overs a frame, as `magnify` runs it): {:.1} Mpix/s, {:.2}x one core",
                n as f64 * px / piped / 1e6,
                wall / piped,
            );
        }
    }
    let listen_bounds = listen_kernels(&frames, w, h, &roofs);
    if std::env::args().any(|a| a == "--kernels") {
        // In-process figures only (`cargo bench --bench roofline --
        // --kernels`): to compare two builds of a kernel quickly.
        return;
    }
    end_to_end(
        (w, h),
        cores,
        [
            magnify_bounds[0],
            magnify_bounds[1],
            listen_bounds[0],
            listen_bounds[1],
            listen_bounds[2],
            listen_bounds[3],
        ],
    );
}

/// The phase method's kernels (`listen --method phase`, the `phase`
/// stage): each pyramid's analysis of a frame, then the A²-weighted phase
/// change sums of every band against a reference (Eq. 3.2-3.4), 4 scales
/// and 2 orientations, one core. Counts per input pixel as in
/// docs/performance.md ("The phase method's kernels").
///
/// Returns each pyramid's one-core bound for a frame (analysis and sums in
/// turn), Mpix/s: Riesz, then steerable; then the tile method's sums';
/// then the steerable pyramid's on half grids.
fn listen_kernels(frames: &[Vec<f32>], w: usize, h: usize, roofs: &Roofs) -> [f64; 4] {
    use vibroscope_math::pyramid::{ComplexSteerablePyramid, PhaseBands};
    use vibroscope_math::riesz::RieszPyramid;
    let (scales, k) = (4, 2);
    let px = (w * h) as f64;
    // (name, flops, bytes, memory level) per input pixel.
    // (Since session 79 the sums' arctangent is a 6-term polynomial, 19
    // flops where the 9-term one took 25: 74.4 flops, not 82.0; the
    // steerable sums 71.9, not 88; on half grids 35.9, not 44.)
    let riesz_counts = [(43.8, 38.5, 2u8), (74.4, 42.5, 3u8)];
    // (Since session 73 orientation 0's half plane, zero in its mask,
    // is neither gathered nor transformed along y, and the band's norm
    // rides in the gather: 223 flops and 153 bytes, not 250 and 190.)
    let csp_counts = [(223.0, 153.0, 2u8), (71.9, 53.0, 3u8)];
    // The same on half grids (`listen --half-grids`): 1.33 band pixels a
    // pixel, not 2.66 (no half plane left out there: the norm's pass
    // alone, 105 bytes before).
    let half_counts = [(138.0, 94.0, 2u8), (35.9, 26.6, 3u8)];
    println!("\n  listen --method phase kernels, one core, {scales} scales, {k} orientations:");
    println!(
        "    {:<58} {:>8} {:>10} {:>8} {:>8} {:>4} {:>10} {:>7}",
        "kernel", "ms/frame", "Mpix/s", "flop/px", "B/px", "mem", "bound", "of bound"
    );
    let bounds = std::cell::RefCell::new(Vec::new());
    // What the kernels keep beyond L2: a frame's coefficients and the
    // reference's, 4 scales over 1.33 of the frame, at the larger of the
    // two pyramids' bytes a band pixel (the steerable one's complex bands,
    // 8 bytes an orientation; the Riesz triples, 12).
    let arrays = (px * 1.33 * 2.0 * (k as f64 * 8.0).max(12.0)) as usize;
    let row = |name: &str, secs: f64, (flops, bytes, level): (f64, f64, u8)| {
        let rate = px / secs / 1e6;
        let (mem, bound) = roofs.bound(flops, bytes, level, arrays);
        bounds.borrow_mut().push(bound);
        println!(
            "    {name:<58} {:>8.3} {:>10.1} {:>8.1} {:>8.1} {:>4} {:>10.1} {:>7.2}",
            secs * 1e3,
            rate,
            flops,
            bytes,
            mem,
            bound,
            rate / bound
        );
    };
    // Best of 5 batches of 64 frames, per frame.
    fn best(f: &mut dyn FnMut(usize)) -> f64 {
        (0..5)
            .map(|_| {
                let t = Instant::now();
                for i in 0..64 {
                    f(i);
                }
                t.elapsed().as_secs_f64() / 64.0
            })
            .fold(f64::INFINITY, f64::min)
    }
    fn sums<C: PhaseBands>(c: &C, r: &C, weights: &[Vec<f32>], scales: usize, k: usize) -> f64 {
        let mut out = [0.0f64; 8];
        let mut total = 0.0;
        for s in 0..scales {
            let info = c.band_info(s * k).expect("band");
            let shared = (0..k).all(|o| {
                let i = c.band_info(s * k + o).expect("band");
                (i.width, i.height) == (info.width, info.height)
            });
            if shared {
                let wts: Vec<&[f32]> = weights[s * k..(s + 1) * k].iter().map(|v| &v[..]).collect();
                c.scale_phase_delta_sums(r, s, &wts, 0..info.height, 0..info.width, &mut out[..k])
                    .expect("sums");
                total += out[..k].iter().sum::<f64>();
            } else {
                // A compact steerable pyramid's bands (as the `phase`
                // stage sums them): each over its own grid.
                for o in 0..k {
                    let i = c.band_info(s * k + o).expect("band");
                    total += c
                        .weighted_phase_delta_sum(
                            r,
                            s * k + o,
                            &weights[s * k + o],
                            0..i.height,
                            0..i.width,
                        )
                        .expect("sums");
                }
            }
        }
        total
    }
    // A pyramid's analysis and its sums, each timed per frame and printed
    // with its counts: `analyze` fills coefficients; the first frame's are
    // the reference, its A² the weights.
    type Counts = (f64, f64, u8);
    type Kernel<'a> = (&'a str, Counts);
    fn time<C: PhaseBands>(
        frames: &[Vec<f32>],
        (mut c, mut r): (C, C),
        mut analyze: impl FnMut(&[f32], &mut C),
        (scales, k): (usize, usize),
        [an, sum]: [Kernel<'_>; 2],
        row: &dyn Fn(&str, f64, Counts),
    ) -> f64 {
        analyze(&frames[0], &mut r);
        let wts: Vec<Vec<f32>> = (0..r.num_bands())
            .map(|i| {
                let mut v = vec![0.0f32; r.band_info(i).expect("band").len()];
                r.amplitude_into(i, &mut v).expect("amplitude");
                v.iter_mut().for_each(|a| *a = *a * *a);
                v
            })
            .collect();
        row(
            an.0,
            best(&mut |i| analyze(&frames[i % frames.len()], &mut c)),
            an.1,
        );
        let mut sink = 0.0;
        row(
            sum.0,
            best(&mut |_| sink += sums(&c, &r, &wts, scales, k)),
            sum.1,
        );
        sink
    }

    let mut rp = RieszPyramid::new(w, h, scales, k).expect("riesz");
    rp.set_triples_only(true);
    let sink = time(
        frames,
        (rp.alloc_coeffs(), rp.alloc_coeffs()),
        |f, c| rp.analyze(f, c).expect("analyze"),
        (scales, k),
        [
            (
                "Riesz pyramid: band and Riesz pair (the triples)",
                riesz_counts[0],
            ),
            (
                "Riesz phase sums (quaternion, atan2, 2 orientations)",
                riesz_counts[1],
            ),
        ],
        &row,
    );
    let steerable = |half: bool, [an, sum]: [Kernel<'_>; 2]| {
        let mut cp = if half {
            ComplexSteerablePyramid::new_compact(w, h, scales, k)
        } else {
            ComplexSteerablePyramid::new(w, h, scales, k)
        }
        .expect("csp");
        cp.set_residuals(false);
        time(
            frames,
            (cp.alloc_coeffs(), cp.alloc_coeffs()),
            |f, c| cp.analyze(f, c).expect("analyze"),
            (scales, k),
            [an, sum],
            &row,
        )
    };
    let sink = sink
        + steerable(
            false,
            [
                (
                    "steerable pyramid: FFT, masks, 8 inverse band FFTs",
                    csp_counts[0],
                ),
                (
                    "steerable phase sums (complex product, atan2)",
                    csp_counts[1],
                ),
            ],
        );
    let sink = sink + tile_sums(frames, w, h, best, &row);
    let sink = sink
        + steerable(
            true,
            [
                (
                    "steerable pyramid on half grids (listen --half-grids)",
                    half_counts[0],
                ),
                ("steerable phase sums on half grids", half_counts[1]),
            ],
        );
    // The Riesz triples from the frame's bytes, as `listen` makes them
    // since session 83 (`analyze_levels_u8`: the first level's blur in
    // 16-bit integers, the same bits; the frame read as 1 byte a pixel,
    // not 4): the bound below pairs this row with the sums.
    let bytes: Vec<Vec<u8>> = frames
        .iter()
        .map(|f| {
            f.iter()
                .map(|v| v.round().clamp(0.0, 255.0) as u8)
                .collect()
        })
        .collect();
    let mut c = rp.alloc_coeffs();
    row(
        "Riesz pyramid from the frame's bytes (as `listen` runs it)",
        best(&mut |i| {
            rp.analyze_levels_u8(&bytes[i % bytes.len()], &mut c, &mut |_, _| {})
                .expect("analyze")
        }),
        (riesz_counts[0].0, riesz_counts[0].1 - 3.0, 2u8),
    );
    println!("    (checksum {sink:.3e})");
    // A frame's time at the bound is the analysis's plus the sums'.
    let b = bounds.into_inner();
    let pair = |i: usize| 1.0 / (1.0 / b[i] + 1.0 / b[i + 1]);
    [1.0 / (1.0 / b[7] + 1.0 / b[1]), pair(2), b[4], pair(5)]
}

/// Prints a kernel's row: its name, seconds a frame, and (flops, bytes,
/// memory level) a pixel.
type KernelRow<'a> = &'a dyn Fn(&str, f64, (f64, f64, u8));

/// The tile method's kernel (`listen`'s default, the `tile_motion`
/// stage's `measure`): per pixel of the region, `gx·(ref − frame)` and
/// `gy·(ref − frame)` added into column sums (5 flops; the reference and
/// its two gradients read, 12 bytes, and the 8-bit frame, 1: 13 bytes,
/// in L2 at 256x256), then each 16x16 tile's columns (2 adds a column a
/// tile, 0.13 a pixel). One core, on 8-bit frames.
fn tile_sums(
    frames: &[Vec<f32>],
    w: usize,
    h: usize,
    best: fn(&mut dyn FnMut(usize)) -> f64,
    row: KernelRow<'_>,
) -> f64 {
    let k = vibroscope_math::tile_sums::TileSums::new();
    let to_u8 = |f: &[f32]| -> Vec<u8> {
        f.iter()
            .map(|v| v.round().clamp(0.0, 255.0) as u8)
            .collect()
    };
    let eight: Vec<Vec<u8>> = frames.iter().map(|f| to_u8(f)).collect();
    let img: Vec<f32> = eight[0].iter().map(|&v| v as f32).collect();
    // Central differences (0 on the border).
    let grad = |dx: usize| -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let inside = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                if inside {
                    0.5 * (img[i + dx] - img[i - dx])
                } else {
                    0.0
                }
            })
            .collect()
    };
    let (gx, gy) = (grad(1), grad(w));
    let (mut sx, mut sy) = (vec![0.0f32; w], vec![0.0f32; w]);
    let mut sums = vec![0.0f64; 2 * (w / 16) * (h / 16)];
    let mut sink = 0.0;
    let mut frame = |i: usize| {
        let f = &eight[i % eight.len()];
        for (ty, y0) in (0..h).step_by(16).enumerate() {
            sx.iter_mut().for_each(|v| *v = 0.0);
            sy.iter_mut().for_each(|v| *v = 0.0);
            for y in y0..(y0 + 16).min(h) {
                let r = y * w..(y + 1) * w;
                k.add_row_u8(
                    &img[r.clone()],
                    &gx[r.clone()],
                    &gy[r.clone()],
                    &f[r],
                    &mut sx,
                    &mut sy,
                );
            }
            for tx in 0..w / 16 {
                let c = tx * 16..(tx + 1) * 16;
                let t = ty * (w / 16) + tx;
                if let Some(o) = sums.get_mut(2 * t..2 * t + 2) {
                    o[0] = sx[c.clone()].iter().map(|&v| v as f64).sum();
                    o[1] = sy[c].iter().map(|&v| v as f64).sum();
                }
            }
        }
        sink += sums.iter().sum::<f64>();
    };
    row(
        "tile sums (gradient least squares, 16x16 tiles, 8-bit)",
        best(&mut frame),
        (5.1, 13.0, 2u8),
    );
    sink
}

/// End to end: the commands issue 52's bars are set on, each timed on a
/// rendered scene (500 fps, 400 frames, tones at 40 and 150 Hz; process
/// start, decoding and writing included; best of 3), beside the numpy
/// reference (`scripts/numpy_reference.py`, the same method in numpy,
/// timed on the first 100 frames of the same file, 50 for the steerable
/// magnifier) with how well its output agrees with ours, and beside the
/// bound of the command's kernels on every core (`bounds`: one core's
/// whole-frame bounds of the sections above, times the cores).
fn end_to_end((w, h): (usize, usize), cores: usize, bounds: [f64; 6]) {
    let dir = std::env::temp_dir().join(format!("vibroscope-roofline-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    timing::render_tones_scene(&dir, (w, h), 400);
    let python = numpy_python();
    let px = (w * h) as f64;
    println!(
        "\n  end to end, {w}x{h}, 400 frames at 500 fps, {cores} cores, best of 3 (process start, decoding and writing included):"
    );
    if let Err(why) = &python {
        println!("    numpy reference: not run ({why})");
    }
    println!(
        "    {:<48} {:>9} {:>9} {:>7} {:>9} {:>9} {:>9}",
        "command", "Mpix/s", "numpy", "agrees", "bound", "of bound", "x numpy"
    );
    // The phase methods: (command, pyramid, the reference's frames, the
    // one-core bound); then the default `listen` (the tiles), its
    // reference the same script's tile method.
    let phase = [
        ("magnify", "riesz", 100, bounds[0]),
        ("magnify", "csp", 50, bounds[1]),
        ("listen", "riesz", 100, bounds[2]),
        ("listen", "csp", 100, bounds[3]),
    ];
    let mut cases: Vec<Case> = phase
        .iter()
        .map(|&(task, pyramid, frames, bound)| {
            let (label, args) = if task == "magnify" {
                let out = format!("m_{pyramid}.y4m");
                let args = timing::magnify_args(pyramid, &out).map(String::from);
                (format!("magnify --pyramid {pyramid}"), args.to_vec())
            } else {
                let out = format!("l_{pyramid}.wav");
                let args = ["listen", "scene.y4m", "--method", "phase", "--pyramid"]
                    .into_iter()
                    .chain([pyramid, "--rate", "native", "-o", &out])
                    .map(String::from);
                (
                    format!("listen --method phase --pyramid {pyramid}"),
                    args.collect(),
                )
            };
            (label, args, Some((task, pyramid, frames)), Some(bound))
        })
        .collect();
    // The steerable pyramid on half grids (its reference: the same
    // script's steerable pyramid, full grids).
    cases.push((
        "listen --method phase --pyramid csp --half-grids".to_string(),
        [
            "listen",
            "scene.y4m",
            "--method",
            "phase",
            "--pyramid",
            "csp",
            "--half-grids",
            "--rate",
            "native",
            "-o",
            "l_csp_half.wav",
        ]
        .map(String::from)
        .to_vec(),
        Some(("listen", "csp", 100)),
        Some(bounds[5]),
    ));
    cases.push((
        "listen (tiles, gradient; the default)".to_string(),
        [
            "listen",
            "scene.y4m",
            "--rate",
            "native",
            "-o",
            "l_tiles.wav",
        ]
        .map(String::from)
        .to_vec(),
        Some(("listen", "tiles", 100)),
        Some(bounds[4]),
    ));
    for (label, args, numpy, bound) in cases {
        // Our output, to compare the reference's with: the last argument.
        let out = args.last().map_or("", String::as_str);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let secs = timing::best_of(3, || timing::timed(&dir, &args));
        let ours = 400.0 * px / secs / 1e6;
        let reference = match (&python, numpy) {
            (Ok(py), Some((task, pyramid, frames))) => {
                numpy_reference(py, &dir, (task, pyramid, frames), out)
            }
            _ => None,
        };
        let cell =
            |v: Option<f64>, prec: usize| v.map_or("-".to_string(), |v| format!("{v:.prec$}"));
        let all = bound.map(|b| b * cores as f64);
        println!(
            "    {label:<48} {ours:>9.1} {:>9} {:>7} {:>9} {:>9} {:>9}",
            cell(reference.map(|r| r.0), 2),
            cell(reference.map(|r| r.1), 4),
            cell(all, 1),
            cell(all.map(|b| ours / b), 2),
            cell(reference.map(|r| ours / r.0), 0),
        );
    }
    println!(
        "    (numpy: Mpix/s of scripts/numpy_reference.py, Python's start and imports left out; agrees: the correlation of its output with ours, the motion each magnifier adds or the two sound tracks; bound: the kernels' one-core bound above times {cores}; for the tile method, its sums' alone)"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// An end-to-end case: label, our command (its output last), the numpy
/// reference's task, pyramid and frames, the bound on one core.
type Case = (
    String,
    Vec<String>,
    Option<(&'static str, &'static str, usize)>,
    Option<f64>,
);

/// A Python 3 that imports numpy and scipy (`VIBROSCOPE_PYTHON`, else
/// `python3`, else Debian's `/usr/bin/python3`), or why there is none.
fn numpy_python() -> Result<String, String> {
    let mut tried = Vec::new();
    let candidates = std::env::var("VIBROSCOPE_PYTHON")
        .into_iter()
        .chain(["python3".to_string(), "/usr/bin/python3".to_string()]);
    for py in candidates {
        let ok = std::process::Command::new(&py)
            .args(["-c", "import numpy, scipy.signal, scipy.ndimage"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Ok(py);
        }
        tried.push(py);
    }
    Err(format!(
        "no Python with numpy and scipy among {}: Debian's python3-scipy, or set VIBROSCOPE_PYTHON",
        tried.join(", ")
    ))
}

/// Runs the numpy reference on `scene.y4m` in `dir` and compares it with
/// our output `ours`: (its Mpix/s, the correlation), or None (with the
/// reason printed) when it fails.
fn numpy_reference(
    python: &str,
    dir: &std::path::Path,
    (task, pyramid, frames): (&str, &str, usize),
    ours: &str,
) -> Option<(f64, f64)> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/numpy_reference.py");
    let out = if task == "listen" { "np.wav" } else { "np.y4m" };
    let frames = frames.to_string();
    let o = std::process::Command::new(python)
        .current_dir(dir)
        .args([
            script,
            task,
            "scene.y4m",
            out,
            "--pyramid",
            pyramid,
            "--band",
            "35,45",
            "--factor",
            "10",
            "--frames",
            &frames,
            "--compare",
            ours,
        ])
        .output()
        .ok()?;
    if !o.status.success() {
        println!(
            "    numpy reference {task} {pyramid} failed: {}",
            String::from_utf8_lossy(&o.stderr).trim()
        );
        return None;
    }
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).ok()?;
    let n = v["frames"].as_f64()? * v["pixels"].as_f64()?;
    Some((n / v["seconds"].as_f64()? / 1e6, v["correlation"].as_f64()?))
}

/// A textured frame moving by a sub-pixel sine (x and y), `n` frames.
fn texture_frames(w: usize, h: usize, n: usize) -> Vec<Vec<f32>> {
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let waves: Vec<(f64, f64, f64)> = (0..24)
        .map(|_| {
            let f = 0.02 + 0.3 * next();
            let a = std::f64::consts::TAU * next();
            (f * a.cos(), f * a.sin(), std::f64::consts::TAU * next())
        })
        .collect();
    (0..n)
        .map(|t| {
            let d = 0.3 * (std::f64::consts::TAU * 40.0 * t as f64 / 500.0).sin();
            let mut f = vec![0.0f32; w * h];
            for (i, v) in f.iter_mut().enumerate() {
                let (x, y) = ((i % w) as f64 - d, (i / w) as f64 - 0.5 * d);
                let s: f64 = waves
                    .iter()
                    .map(|&(kx, ky, ph)| (std::f64::consts::TAU * (kx * x + ky * y) + ph).cos())
                    .sum();
                *v = (128.0 + 20.0 * s) as f32;
            }
            f
        })
        .collect()
}

/// GFLOP/s of a register-only FMA loop on one core and on `cores` at once,
/// with the lane count used.
fn fma_peak(cores: usize) -> (f64, f64, usize) {
    let iters = 40_000_000u64;
    let lanes = fma_lanes();
    let run = || {
        let t = Instant::now();
        let v = fma_loop(iters);
        std::hint::black_box(v);
        // 12 accumulators, `lanes` each, 2 flops per FMA.
        (iters * 12 * lanes as u64 * 2) as f64 / t.elapsed().as_secs_f64() / 1e9
    };
    let one = (0..3).map(|_| run()).fold(0.0, f64::max);
    let all = (0..3)
        .map(|_| {
            std::thread::scope(|s| {
                let hs: Vec<_> = (0..cores).map(|_| s.spawn(run)).collect();
                hs.into_iter().map(|h| h.join().unwrap()).sum::<f64>()
            })
        })
        .fold(0.0, f64::max);
    (one, all, lanes)
}

fn fma_lanes() -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx512f") {
            return 16;
        }
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            return 8;
        }
    }
    1
}

fn fma_loop(iters: u64) -> f32 {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU reported AVX-512F.
            return unsafe { fma_avx512(iters) };
        }
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU reported AVX2 and FMA.
            return unsafe { fma_avx2(iters) };
        }
    }
    let mut acc = [1.0f32; 12];
    for _ in 0..iters {
        for a in acc.iter_mut() {
            *a = a.mul_add(0.999_999, 1e-7);
        }
    }
    acc.iter().sum()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn fma_avx512(iters: u64) -> f32 {
    use std::arch::x86_64::*;
    let (a, b) = (_mm512_set1_ps(0.999_999), _mm512_set1_ps(1e-7));
    let mut acc = [_mm512_set1_ps(1.0); 12];
    for _ in 0..iters {
        for v in acc.iter_mut() {
            *v = _mm512_fmadd_ps(*v, a, b);
        }
    }
    acc.iter().map(|v| _mm512_reduce_add_ps(*v)).sum()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn fma_avx2(iters: u64) -> f32 {
    use std::arch::x86_64::*;
    let (a, b) = (_mm256_set1_ps(0.999_999), _mm256_set1_ps(1e-7));
    let mut acc = [_mm256_set1_ps(1.0); 12];
    for _ in 0..iters {
        for v in acc.iter_mut() {
            *v = _mm256_fmadd_ps(*v, a, b);
        }
    }
    let mut lanes = [0.0f32; 8];
    let mut sum = 0.0;
    for v in acc {
        _mm256_storeu_ps(lanes.as_mut_ptr(), v);
        sum += lanes.iter().sum::<f32>();
    }
    sum
}

/// This machine's one-core peaks: FMA (GFLOP/s), the triads' bandwidths
/// in L2, L3 and memory (GB/s), and the last cache's size (bytes).
struct Roofs {
    fma1: f64,
    bw: [f64; 3],
    l3: usize,
}

impl Roofs {
    /// The memory a kernel's bytes come from and the Mpix/s its counts
    /// allow on one core: `level` 2 is L2; 3 is beyond L2, which is L3
    /// while the arrays the kernel works on (`arrays` bytes) take at most
    /// half of it (the rest is other cores' share: the triads fall off past
    /// that), and memory beyond.
    fn bound(&self, flops: f64, bytes: f64, level: u8, arrays: usize) -> (&'static str, f64) {
        let (name, bw) = match level {
            2 => ("L2", self.bw[0]),
            _ if arrays <= self.l3 / 2 => ("L3", self.bw[1]),
            _ => ("mem", self.bw[2]),
        };
        (name, (self.fma1 * 1e3 / flops).min(bw * 1e3 / bytes))
    }
}

/// Bytes of CPU 0's level-`level` data or unified cache, as the system
/// reports it (`None` where it does not).
fn cache_bytes(level: u32) -> Option<usize> {
    (0..8).find_map(|i| {
        let dir = format!("/sys/devices/system/cpu/cpu0/cache/index{i}");
        let read = |f: &str| std::fs::read_to_string(format!("{dir}/{f}")).ok();
        let lv: u32 = read("level")?.trim().parse().ok()?;
        if lv != level || read("type")?.trim() == "Instruction" {
            return None;
        }
        let size = read("size")?;
        let size = size.trim();
        let (digits, unit) = size.split_at(size.find(|c: char| !c.is_ascii_digit())?);
        let n: usize = digits.parse().ok()?;
        match unit {
            "K" => Some(n << 10),
            "M" => Some(n << 20),
            _ => None,
        }
    })
}

/// Bytes the heap holds now (glibc's `mallinfo2`: what is allocated, in
/// the arenas and mapped): the difference across a constructor is what
/// the object allocated, whatever pages the allocator reused. 0 where
/// there is no glibc.
fn heap_bytes() -> usize {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: glibc's `mallinfo2` (2.33 and later) takes nothing and
        // only reads the allocator's counters.
        let m = unsafe { libc::mallinfo2() };
        m.uordblks + m.hblkhd
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    0
}

/// GB/s of `a[i] = b[i] + s·c[i]` over arrays of `n` floats (12 bytes an
/// element), best of several sweeps: one core, and `cores` each on their
/// own arrays at once.
fn triad(n: usize, cores: usize) -> (f64, f64) {
    let sweeps = (1usize << 27) / n;
    let run = || {
        let (mut a, b, c) = (vec![0.0f32; n], vec![1.0f32; n], vec![2.0f32; n]);
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let t = Instant::now();
            for _ in 0..sweeps.max(1) {
                triad_sweep(&mut a, &b, &c);
                std::hint::black_box(&mut a);
            }
            best = best.min(t.elapsed().as_secs_f64());
        }
        (12 * n * sweeps.max(1)) as f64 / best / 1e9
    };
    let one = run();
    let all = std::thread::scope(|s| {
        let hs: Vec<_> = (0..cores).map(|_| s.spawn(run)).collect();
        hs.into_iter().map(|h| h.join().unwrap()).sum::<f64>()
    });
    (one, all)
}

fn triad_sweep(a: &mut [f32], b: &[f32], c: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU reported AVX-512F.
        unsafe { triad_avx512(a, b, c) };
        return;
    }
    triad_body(a, b, c);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn triad_avx512(a: &mut [f32], b: &[f32], c: &[f32]) {
    triad_body(a, b, c);
}

#[inline(always)]
fn triad_body(a: &mut [f32], b: &[f32], c: &[f32]) {
    for ((x, y), z) in a.iter_mut().zip(b).zip(c) {
        *x = y + 3.0 * z;
    }
}
