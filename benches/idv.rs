//! Interactive dynamic video rendering (issue 17): frames per second for a
//! 512x512 frame with 8 modes, against a plain copy of the frame measured
//! in the same run (the floor of any renderer): `simulate` (advance 8
//! exact oscillators by one frame), `displacement` (Eq. 6.10, D = Σ
//! Re{φ'q}, one thread), `frame` (simulation + displacement + forward
//! warp with the depth rule, one thread), `frame, 2 threads` (the same
//! with `vibroscope::idv::FrameRenderer` on two threads: what `idv`
//! renders with on this two-core machine), and `colour frame, 2 threads`
//! (three planes warped together).
//!
//!     cargo bench --bench idv

#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use vibroscope_math::idv::{Complex32, Complex64, Oscillator, Renderer, Shape};

const W: usize = 512;
const H: usize = 512;
const MODES: usize = 8;

fn setup() -> (Vec<u8>, Vec<Shape>, Vec<Oscillator>) {
    let n = W * H;
    let rest: Vec<u8> = (0..n).map(|i| ((i * 7919) % 251) as u8).collect();
    let shapes = (0..MODES)
        .map(|k| {
            let f = |i: usize, a: f32| {
                let (x, y) = ((i % W) as f32 / W as f32, (i / W) as f32 / H as f32);
                let v = a * ((k + 1) as f32 * std::f32::consts::PI * x).sin() * y;
                Complex32::new(v, 0.1 * v)
            };
            Shape {
                x: (0..n).map(|i| f(i, 0.5)).collect(),
                y: (0..n).map(|i| f(i, 2.0)).collect(),
            }
        })
        .collect();
    let osc = (0..MODES)
        .map(|k| {
            let mut o = Oscillator::new(2.0 + 3.0 * k as f64, 0.02);
            o.kick(10.0);
            o
        })
        .collect();
    (rest, shapes, osc)
}

fn bench(c: &mut Criterion) {
    let (rest, shapes, mut osc) = setup();
    let mut out = vec![0u8; W * H];
    let mut r = Renderer::new(W, H);
    let mut q = vec![Complex64::new(0.0, 0.0); MODES];
    let mut g = c.benchmark_group("idv_512x512_8_modes");
    g.throughput(Throughput::Elements(1));
    g.bench_function("copy (baseline)", |b| {
        b.iter(|| out.copy_from_slice(std::hint::black_box(&rest)))
    });
    g.bench_function("simulate", |b| {
        b.iter(|| {
            for (o, q) in osc.iter_mut().zip(&mut q) {
                o.step(1.0 / 60.0, 0.0);
                *q = o.q();
            }
        })
    });
    g.bench_function("displacement", |b| b.iter(|| r.displacement(&shapes, &q)));
    g.bench_function("frame", |b| {
        b.iter(|| {
            for (o, q) in osc.iter_mut().zip(&mut q) {
                o.step(1.0 / 60.0, 0.0);
                *q = o.q();
            }
            r.displacement(&shapes, &q);
            r.warp(&rest, &mut out);
        })
    });
    let mut fr = vibroscope::idv::FrameRenderer::new(W, H, 2);
    assert_eq!(fr.threads(), 2);
    g.bench_function("frame, 2 threads", |b| {
        b.iter(|| {
            for (o, q) in osc.iter_mut().zip(&mut q) {
                o.step(1.0 / 60.0, 0.0);
                *q = o.q();
            }
            fr.displace(&shapes, &q);
            fr.sample(&rest, &mut out);
        })
    });
    let mut planes = [out.clone(), out.clone(), out.clone()];
    g.bench_function("colour frame, 2 threads", |b| {
        b.iter(|| {
            for (o, q) in osc.iter_mut().zip(&mut q) {
                o.step(1.0 / 60.0, 0.0);
                *q = o.q();
            }
            fr.displace(&shapes, &q);
            for p in &mut planes {
                fr.sample(&rest, p);
            }
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().without_plots().sample_size(20);
    targets = bench
}
criterion_main!(benches);
