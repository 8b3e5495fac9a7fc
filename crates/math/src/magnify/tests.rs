use super::*;
use crate::rng::Xoshiro256 as Rng;

fn texture(w: usize, h: usize, seed: u64) -> Vec<f32> {
    texture_shifted(w, h, seed, 0.0)
}

/// A periodic texture (plane waves with whole cycles across the frame,
/// below 0.12 cycles/px) translated right by `d` pixels, exactly.
fn texture_shifted(w: usize, h: usize, seed: u64, d: f32) -> Vec<f32> {
    let mut r = Rng::new(seed);
    let kmax = (0.12 * w.min(h) as f64).floor().max(1.0);
    let mut waves = Vec::new();
    while waves.len() < 12 {
        let kx = ((r.next_f64() * 2.0 - 1.0) * kmax).round();
        let ky = ((r.next_f64() * 2.0 - 1.0) * kmax).round();
        if kx == 0.0 && ky == 0.0 {
            continue;
        }
        waves.push((
            kx as f32 / w as f32,
            ky as f32 / h as f32,
            r.next_f64() as f32 * std::f32::consts::TAU,
        ));
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = 100.0
                + waves
                    .iter()
                    .map(|&(fx, fy, p)| {
                        8.0 * (std::f32::consts::TAU * (fx * (x as f32 - d) + fy * y as f32) + p)
                            .sin()
                    })
                    .sum::<f32>();
        }
    }
    out
}

#[test]
fn bandpass_has_unit_centre_and_half_power_edges() {
    for order in 1..=4 {
        for &(lo, hi, fs) in &[
            (75.0, 90.0, 600.0),
            (20.0, 40.0, 2200.0),
            (1.0, 200.0, 600.0),
        ] {
            let d = temporal::design(order, lo, hi, fs);
            assert_eq!(d.sections.len(), order);
            let c = d.response_at(d.centre_hz, fs);
            assert!(
                (c.re - 1.0).abs() < 1e-3 && c.im.abs() < 1e-3,
                "{order} {lo}-{hi}: {c}"
            );
            for f in [lo, hi] {
                let g = d.response_at(f, fs).norm();
                assert!(
                    (g - 0.5f64.sqrt()).abs() < 2e-3,
                    "{order} {lo}-{hi} at {f}: {g}"
                );
            }
            assert!(d.response_at(fs * 0.4999, fs).norm() < 1e-2);
            assert!(d.response_at(1e-3, fs).norm() < 1e-2);
        }
    }
}

#[test]
fn pixel_filter_matches_its_response() {
    let fs = 600.0;
    let d = temporal::design(2, 75.0, 90.0, fs);
    let mut f = PixelFilter::new(&d, 2);
    let f0 = 95.0;
    let n = 6000;
    let mut y = Vec::new();
    for t in 0..n {
        let v = (2.0 * std::f64::consts::PI * f0 * t as f64 / fs).sin() as f32;
        let mut x = [v, 2.0 * v];
        f.step(&mut x);
        y.push((v, x[0], x[1]));
    }
    let tail = &y[n / 2..];
    let rms = |k: usize| {
        (tail
            .iter()
            .map(|t| [t.0, t.1, t.2][k].powi(2) as f64)
            .sum::<f64>()
            / tail.len() as f64)
            .sqrt()
    };
    let g = rms(1) / rms(0);
    assert!((g - d.response_at(f0, fs).norm()).abs() < 1e-3, "{g}");
    assert!((rms(2) / rms(1) - 2.0).abs() < 1e-4);
}

/// Fed a signal's changes, [`BandpassDesign::on_increments`] gives what
/// the band-pass gives fed the signal: a drifting noise whose running sum
/// grows (orders 1 to 3, to f32 rounding of the larger sums).
#[test]
fn the_filter_of_the_changes_is_the_filter_of_the_sums() {
    for order in 1..=3 {
        let d = temporal::design(order, 30.0, 60.0, 500.0);
        let (mut sums, mut changes) = (
            PixelFilter::new(&d, 1),
            PixelFilter::new(&d.on_increments(), 1),
        );
        let mut r = Rng::new(order as u64);
        let (mut total, mut worst, mut peak) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..5000 {
            let step = r.next_f64() - 0.45;
            total += step;
            let (mut a, mut b) = ([total as f32], [step as f32]);
            sums.step(&mut a);
            changes.step(&mut b);
            worst = worst.max(f64::from(a[0] - b[0]).abs());
            peak = peak.max(f64::from(a[0]).abs());
        }
        assert!(
            worst < 1e-3 * peak,
            "order {order}: {worst} against a peak of {peak}"
        );
    }
}

#[test]
fn laplacian_collapses_to_the_frame() {
    for &(w, h) in &[(64, 48), (37, 21), (5, 3), (1, 7)] {
        let img = texture(w, h, 3);
        let mut lap = Laplacian::new(w, h, 3);
        lap.analyze(&img);
        let mut out = vec![0.0; w * h];
        lap.collapse(&mut out);
        let err = img
            .iter()
            .zip(&out)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(err < 1e-3, "{w}x{h}: {err}");
        // The band-pass levels hold the texture, not a copy of the frame.
        assert!(lap.bands[0].iter().map(|v| v.abs()).sum::<f32>() > 0.0);
    }
}

/// A texture translated by `d(t)` along x: a factor of 1 returns it, any
/// factor returns a still frame unchanged.
#[test]
fn factor_one_and_still_frames_pass_unchanged() {
    let (w, h) = (48, 40);
    for kind in [PyramidKind::Csp, PyramidKind::Riesz] {
        for factor in [1.0, 0.0, 20.0] {
            let mut p = MagnifyParams::new(100.0, 5.0, 15.0, factor);
            p.pyramid = kind;
            p.scales = 3;
            let mut m = Magnifier::new(w, h, p).unwrap();
            let img = texture(w, h, 9);
            let mut out = vec![0.0; w * h];
            for t in 0..20 {
                let frame: Vec<f32> = if factor == 1.0 {
                    let d = 0.3 * (t as f32 * 0.6).sin();
                    shifted(&img, w, h, d)
                } else {
                    img.clone()
                };
                m.process(&frame, &mut out).unwrap();
                let err = frame
                    .iter()
                    .zip(&out)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f32::max);
                assert!(err < 0.05, "{kind:?} factor {factor} frame {t}: {err}");
            }
        }
    }
}

/// Linear interpolation of `img` shifted right by `d` pixels (edges clamped).
fn shifted(img: &[f32], w: usize, h: usize, d: f32) -> Vec<f32> {
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let sx = (x as f32 - d).clamp(0.0, (w - 1) as f32);
            let x0 = sx.floor() as usize;
            let x1 = (x0 + 1).min(w - 1);
            let f = sx - x0 as f32;
            out[y * w + x] = img[y * w + x0] * (1.0 - f) + img[y * w + x1] * f;
        }
    }
    out
}

#[test]
fn bad_parameters_name_their_field() {
    let ok = MagnifyParams::new(600.0, 75.0, 90.0, 10.0);
    assert!(ok.check().is_ok());
    let cases: Vec<(MagnifyParams, &str)> = vec![
        (MagnifyParams { hi_hz: 300.0, ..ok }, "band"),
        (MagnifyParams { lo_hz: 95.0, ..ok }, "band"),
        (MagnifyParams { lo_hz: 0.0, ..ok }, "band"),
        (
            MagnifyParams {
                hi_hz: f64::NAN,
                ..ok
            },
            "band",
        ),
        (MagnifyParams { factor: -1.0, ..ok }, "factor"),
        (
            MagnifyParams {
                factor: f32::NAN,
                ..ok
            },
            "factor",
        ),
        (MagnifyParams { order: 0, ..ok }, "order"),
        (
            MagnifyParams {
                max_phase: 0.0,
                ..ok
            },
            "max_phase",
        ),
        (MagnifyParams { fps: 0.0, ..ok }, "fps"),
    ];
    for (p, field) in cases {
        match p.check() {
            Err(MagnifyError::Param { field: f, .. }) => assert_eq!(f, field, "{p:?}"),
            other => panic!("{p:?}: {other:?}"),
        }
        assert!(Magnifier::new(16, 16, p).is_err());
    }
}

/// Least-squares global x shift of `a` relative to `base` (gradient method)
/// over the interior.
fn shift_of(a: &[f32], base: &[f32], w: usize, h: usize) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for y in 8..h - 8 {
        for x in 8..w - 8 {
            let gx = 0.5 * (base[y * w + x + 1] - base[y * w + x - 1]) as f64;
            let dt = (a[y * w + x] - base[y * w + x]) as f64;
            num += -gx * dt;
            den += gx * gx;
        }
    }
    num / den
}

/// A texture moving with a tone at the band's centre: factor 1 keeps the
/// motion, 0 takes most of it away, 10 multiplies it several times (a
/// smoke test of signs and direction; this texture reaches 0.17
/// cycles/px, into the CSP's unmagnified high-pass residual, and the
/// gains are measured on the simulator in `tests/suite/magnify.rs`).
#[test]
fn in_band_tone_is_scaled_by_the_factor() {
    let (w, h) = (64, 64);
    let img = texture(w, h, 5);
    let fps = 100.0;
    for kind in [PyramidKind::Csp, PyramidKind::Riesz] {
        let mut ratios = Vec::new();
        for factor in [0.0f32, 1.0, 10.0] {
            let mut p = MagnifyParams::new(fps, 8.0, 12.0, factor);
            p.pyramid = kind;
            p.scales = 5;
            let f0 = temporal::design(p.order, 8.0, 12.0, fps).centre_hz;
            let mut m = Magnifier::new(w, h, p).unwrap();
            let mut out = vec![0.0; w * h];
            let (mut sin_in, mut sin_out) = (0.0, 0.0);
            let amp = 0.05;
            for t in 0..400 {
                let s = (2.0 * std::f64::consts::PI * f0 * t as f64 / fps).sin();
                let frame = texture_shifted(w, h, 5, (amp * s) as f32);
                m.process(&frame, &mut out).unwrap();
                if t >= 200 {
                    sin_in += s * s * amp;
                    sin_out += s * shift_of(&out, &img, w, h);
                }
            }
            let ratio = sin_out / sin_in;
            eprintln!("{kind:?} factor {factor}: motion ratio {ratio:.3}");
            ratios.push(ratio);
        }
        assert!((ratios[1] - 1.0).abs() < 0.05, "{kind:?}: {ratios:?}");
        assert!(ratios[0] < 0.6, "{kind:?}: {ratios:?}");
        assert!(ratios[2] > 4.0, "{kind:?}: {ratios:?}");
    }
}

/// The row-vectorised blur equals the plain clamped convolution, for rows
/// shorter than, equal to and longer than the kernel.
#[test]
fn blur_matches_the_clamped_convolution() {
    let kernel = WeightedBlur::new(1.5).kernel;
    let r = (kernel.len() / 2) as isize;
    for (w, h) in [(1, 1), (3, 2), (9, 4), (10, 7), (33, 5)] {
        let src: Vec<f32> = (0..w * h)
            .map(|i| ((i * 7919) % 101) as f32 / 10.0)
            .collect();
        let mut want = vec![0.0f32; w * h];
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut acc = 0.0f64;
                for (ky, cy) in kernel.iter().enumerate() {
                    for (kx, cx) in kernel.iter().enumerate() {
                        let yi = (y + ky as isize - r).clamp(0, h as isize - 1) as usize;
                        let xi = (x + kx as isize - r).clamp(0, w as isize - 1) as usize;
                        acc += f64::from(cy * cx) * f64::from(src[yi * w + xi]);
                    }
                }
                want[y as usize * w + x as usize] = acc as f32;
            }
        }
        let (mut buf, mut tmp) = (src.clone(), vec![0.0f32; w * h]);
        blur(
            &kernel,
            &mut buf,
            &mut tmp,
            w,
            h,
            crate::join::Simd::detect(),
        );
        for (i, (a, b)) in buf.iter().zip(&want).enumerate() {
            assert!((a - b).abs() < 1e-4, "{w}x{h} at {i}: {a} vs {b}");
        }
    }
}

/// The blur's horizontal pass for a kernel of fixed length (blocks that
/// overlap at a row's end, the ends read from a padded copy) gives the
/// same bits as the general pass (the clamped sums, pixel by pixel at the
/// edges), at every width from 1 to past three blocks and at four fixed
/// lengths.
#[test]
fn fixed_length_blur_rows_equal_the_general_ones() {
    for sigma in [0.5f32, 1.0, 1.5, 2.5] {
        let kernel = WeightedBlur::new(sigma).kernel;
        assert!(kernel.len() <= MAX_FIXED_TAPS, "sigma {sigma}");
        for w in (1..=100).chain([127, 255, 256]) {
            let h = 9;
            let src: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919) % 101) as f32 / 10.0 - 3.0)
                .collect();
            let simd = crate::join::Simd::detect();
            let (mut fixed, mut any) = (vec![0.0f32; w * h], vec![0.0f32; w * h]);
            blur_rows(simd, &kernel, &src, &mut fixed, w);
            blur_rows_any(&kernel, src.chunks_exact(w).zip(any.chunks_exact_mut(w)));
            assert_eq!(fixed, any, "rows, {} taps, width {w}", kernel.len());
        }
    }
}

/// Two parts of the steerable-pyramid magnifier (half the orientations
/// each, one with the residuals) sum to the whole magnifier's frames.
#[test]
fn parts_sum_to_the_whole() {
    let (w, h) = (48, 40);
    let fps = 100.0;
    let mut p = MagnifyParams::new(fps, 8.0, 12.0, 10.0);
    p.scales = 3;
    let mut whole = Magnifier::new(w, h, p).unwrap();
    let k = p.orientations;
    let mut a = Magnifier::new_part(w, h, p, 0..k / 2, true).unwrap();
    let mut b = Magnifier::new_part(w, h, p, k / 2..k, false).unwrap();
    let (mut o, mut oa, mut ob) = (vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]);
    let mut worst = 0.0f32;
    for t in 0..60 {
        let s = (2.0 * std::f64::consts::PI * 10.0 * t as f64 / fps).sin();
        let frame = texture_shifted(w, h, 3, (0.05 * s) as f32);
        whole.process(&frame, &mut o).unwrap();
        a.process(&frame, &mut oa).unwrap();
        b.process(&frame, &mut ob).unwrap();
        for ((v, x), y) in o.iter().zip(&oa).zip(&ob) {
            worst = worst.max((v - (x + y)).abs());
        }
    }
    // The texture spans about 0..255: float rounding only.
    assert!(worst < 1e-3, "parts differ from the whole by {worst}");
    // Bad parts are refused.
    assert!(Magnifier::new_part(w, h, p, 3..3, true).is_err());
    assert!(Magnifier::new_part(w, h, p, 0..k + 1, true).is_err());
    let mut r = p;
    r.pyramid = PyramidKind::Riesz;
    assert!(Magnifier::new_part(w, h, r, 0..1, true).is_err());
}

/// A [`Join`] that runs its halves on two threads at once (as the
/// engine's rayon pool does), second half first on this one.
pub(super) struct TwoThreads;

impl Join for TwoThreads {
    fn join(&self, a: &mut (dyn FnMut() + Send), b: &mut (dyn FnMut() + Send)) {
        std::thread::scope(|s| {
            s.spawn(a);
            b();
        });
    }
}

/// The Riesz magnifier's passes split in halves (at once on two threads)
/// and its loops at every vector width give the bits of one thread with
/// SSE2: each half writes its own pixels, and the vector paths use the
/// same IEEE operations in the same order.
#[test]
fn riesz_halves_and_vector_widths_give_the_same_bits() {
    // Frames over SPLIT_MIN, whose every level is split at half its
    // height: 144x112 (neither side a multiple of the filter's block),
    // and 260x40 with 7 scales (levels of odd heights, the last one row
    // high: its first half is empty).
    for (w, h, scales) in [(144, 112, 4), (260, 40, 7)] {
        let base = texture(w, h, 7);
        // With the amplitude-weighted smoothing (fused into the phase pass and
        // the shift) and without.
        for sigma in [DEFAULT_SIGMA, 0.0] {
            let mut p = MagnifyParams::new(100.0, 8.0, 12.0, 20.0);
            p.pyramid = PyramidKind::Riesz;
            p.scales = scales;
            p.sigma = sigma;
            let mut serial = Magnifier::new(w, h, p).unwrap();
            serial.simd = Simd::Sse2;
            let mut split = Magnifier::new(w, h, p).unwrap();
            let (mut a, mut b) = (vec![0.0; w * h], vec![0.0; w * h]);
            for t in 0..24 {
                let d = 0.3 * (std::f32::consts::TAU * 10.0 * t as f32 / 100.0).sin();
                let frame = shifted(&base, w, h, d);
                serial.process(&frame, &mut a).unwrap();
                split.process_with(&frame, &mut b, &TwoThreads).unwrap();
                assert!(
                a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{w}x{h}, σ {sigma}, frame {t}: {} (two threads) differs from sse2 (one thread)",
                split.simd()
            );
            }
        }
    }
}

/// Two frames in flight (`process_pipelined`, on two threads) give each
/// frame's bits one call later, the last one from `flush`; after a flush
/// the next call starts a new pipeline on the same state, so a run that
/// flushes midway still matches. A frame too small to split (under
/// `SPLIT_MIN`) and one that splits, with smoothing and without.
#[test]
fn riesz_pipelined_frames_are_the_same_bits_one_call_later() {
    for (w, h, scales) in [(144, 112, 4), (60, 40, 3)] {
        let base = texture(w, h, 11);
        for sigma in [DEFAULT_SIGMA, 0.0] {
            let mut p = MagnifyParams::new(100.0, 8.0, 12.0, 20.0);
            p.pyramid = PyramidKind::Riesz;
            p.scales = scales;
            p.sigma = sigma;
            let mut whole = Magnifier::new(w, h, p).unwrap();
            let mut piped = Magnifier::new(w, h, p).unwrap();
            let mut want: Vec<Vec<f32>> = Vec::new();
            let mut got: Vec<Vec<f32>> = Vec::new();
            let mut o = vec![0.0; w * h];
            let frames = 20;
            for t in 0..frames {
                let d = 0.3 * (std::f32::consts::TAU * 10.0 * t as f32 / 100.0).sin();
                let frame = shifted(&base, w, h, d);
                whole.process(&frame, &mut o).unwrap();
                want.push(o.clone());
                let before = got.len();
                let mut load = |dst: &mut [f32]| dst.copy_from_slice(&frame);
                let mut deliver = |m: &[f32]| got.push(m.to_vec());
                let wrote = piped
                    .process_pipelined(&mut load, &mut deliver, &TwoThreads)
                    .unwrap();
                // Nothing comes out of the first call, nor of the first
                // after a flush.
                assert_eq!(wrote, t != 0 && t != 8, "frame {t}");
                assert_eq!(got.len(), before + usize::from(wrote), "frame {t}");
                // A flush midway: the held frame comes out, the next call
                // holds its own.
                if t == 7 {
                    let mut deliver = |m: &[f32]| got.push(m.to_vec());
                    assert!(piped.flush(&mut deliver, &TwoThreads).unwrap());
                    assert!(!piped.flush(&mut deliver, &TwoThreads).unwrap());
                }
            }
            let mut deliver = |m: &[f32]| got.push(m.to_vec());
            assert!(piped.flush(&mut deliver, &TwoThreads).unwrap());
            assert!(!piped.flush(&mut deliver, &TwoThreads).unwrap());
            assert_eq!(got.len(), frames, "{w}x{h}, σ {sigma}: frames out");
            for (t, (a, b)) in want.iter().zip(&got).enumerate() {
                assert!(
                    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{w}x{h}, σ {sigma}, frame {t}: pipelined differs from one frame at a time"
                );
            }
        }
    }
}

/// Where the Riesz magnifier cuts its levels into halves does not change
/// a bit: every row computes the same sums whichever half it is in (a
/// half that read or wrote its rows from the wrong place would differ
/// between cuts).
#[test]
fn riesz_halves_cut_anywhere_give_the_same_bits() {
    let (w, h) = (96, 70);
    let base = texture(w, h, 3);
    let cuts: [fn(usize) -> usize; 4] = [|h| h / 2, |_| 0, |h| h, |h| h / 3 + 1];
    for sigma in [DEFAULT_SIGMA, 0.0] {
        let mut p = MagnifyParams::new(100.0, 8.0, 12.0, 20.0);
        p.pyramid = PyramidKind::Riesz;
        p.scales = 5;
        p.sigma = sigma;
        let mut ms: Vec<Magnifier> = cuts
            .iter()
            .map(|&c| {
                let mut m = Magnifier::new(w, h, p).unwrap();
                let State::Riesz(s) = &mut m.state else {
                    unreachable!()
                };
                s.cut = c;
                m
            })
            .collect();
        let mut outs = vec![vec![0.0; w * h]; cuts.len()];
        for t in 0..12 {
            let d = 0.3 * (std::f32::consts::TAU * 10.0 * t as f32 / 100.0).sin();
            let frame = shifted(&base, w, h, d);
            for (m, o) in ms.iter_mut().zip(outs.iter_mut()) {
                m.process(&frame, o).unwrap();
            }
            for (k, o) in outs.iter().enumerate().skip(1) {
                assert!(
                    o.iter()
                        .zip(&outs[0])
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "σ {sigma}, frame {t}: cut {k} differs from the cut at half the rows"
                );
            }
        }
    }
}

/// The steerable magnifier's phase step, taken apart into lanes of
/// [`CSP_LANES`] pixels, gives the bits of the pixel-by-pixel loop, at
/// every length about a whole number of lanes, on the first frame and
/// after it (magnitudes from 1e-30 to 1e3, phases on both sides of ±π, so
/// that tiny bands and wrapped changes are covered); its change is the
/// wrapped difference of the phases within 1e-6 rad (f64). The shift
/// gives the bits of the loop it replaced.
#[test]
fn csp_lanes_give_the_bits_of_the_pixel_loop() {
    use std::f32::consts::{PI, TAU};
    let mut r = Rng::new(11);
    let mut c = || {
        let m = 10f64.powf(-30.0 + 33.0 * r.next_f64());
        let t = std::f64::consts::TAU * r.next_f64();
        Complex32::new((m * t.cos()) as f32, (m * t.sin()) as f32)
    };
    for len in [0, 1, 15, 16, 17, 31, 32, 33, 100, 257] {
        for first in [true, false] {
            let data: Vec<Complex32> = (0..len).map(|_| c()).collect();
            let prev: Vec<f32> = (0..len).map(|i| (i as f32 * 0.37).sin() * 3.1).collect();
            // The loop, pixel by pixel.
            let mut p0 = prev.clone();
            let (mut ch0, mut am0) = (vec![0f32; len], vec![0f32; len]);
            for (((c, pv), ch), am) in data
                .iter()
                .zip(p0.iter_mut())
                .zip(ch0.iter_mut())
                .zip(am0.iter_mut())
            {
                let a = crate::fastmath::atan2(c.im, c.re);
                let mut d = a - *pv;
                if d > PI {
                    d -= TAU;
                } else if d < -PI {
                    d += TAU;
                }
                *ch = if first { 0.0 } else { d };
                *pv = a;
                *am = (c.re * c.re + c.im * c.im).sqrt();
            }
            let mut p1 = prev.clone();
            let (mut ch1, mut am1) = (vec![0f32; len], vec![0f32; len]);
            csp_phase_step(&data, &mut p1, &mut ch1, &mut am1, first);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let cbits = |v: &[Complex32]| {
                v.iter()
                    .map(|x| (x.re.to_bits(), x.im.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&p0), bits(&p1), "prev, len {len}");
            assert_eq!(bits(&ch0), bits(&ch1), "change, len {len}");
            assert_eq!(bits(&am0), bits(&am1), "amp, len {len}");
            for i in 0..len {
                let (c, pv) = (data[i], f64::from(prev[i]));
                let d = f64::from(c.im).atan2(f64::from(c.re)) - pv;
                let want = if first {
                    0.0
                } else {
                    (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                        - std::f64::consts::PI
                };
                let err = (f64::from(ch1[i]) - want).abs();
                // (±π are the same change.)
                let err = err.min((err - std::f64::consts::TAU).abs());
                assert!(err < 1e-6, "len {len}, pixel {i}: {} vs {want}", ch1[i]);
            }
            // The shift, as it was and as it is.
            let phase: Vec<f32> = (0..len).map(|i| (i as f32 - 50.0) * 0.05).collect();
            let (factor, limit) = (9.0, DEFAULT_MAX_PHASE);
            let mut s0 = data.clone();
            for (c, &ph) in s0.iter_mut().zip(phase.iter()) {
                let psi = shift(ph, factor, limit);
                let (sn, cs) = crate::fastmath::sin_cos(psi);
                *c *= Complex32::new(cs, sn);
            }
            let mut s1 = data.clone();
            let (mut sn, mut cs) = (vec![0f32; len], vec![0f32; len]);
            csp_shift(&mut s1, &phase, (&mut sn, &mut cs), factor, limit);
            assert_eq!(cbits(&s0), cbits(&s1), "shift, len {len}");
        }
    }
}

/// [`csp_band`]'s one sweep of a band's rows gives the bits of its steps
/// one after another over the whole band (the phase step, the band-pass,
/// the blur's two passes over the band, the weighted mean, the shift), as
/// the steerable magnifier ran them before: frames in turn, bands wider
/// and narrower than a blur block, fewer rows than the kernel's taps,
/// kernels of 1, 7 and 19 taps (19: past the fixed lengths).
#[test]
fn csp_band_sweep_gives_the_bits_of_the_passes() {
    let design = temporal::design(2, 35.0, 45.0, 500.0).on_increments();
    let mut r = Rng::new(5);
    for sigma in [0.0f32, 1.0, 3.0] {
        let kernel = WeightedBlur::new(sigma).kernel;
        for (w, h) in [(1, 1), (5, 3), (33, 4), (64, 20), (70, 9)] {
            let n = w * h;
            let mut rows = CspRows::new(80, kernel.len());
            let (mut filter_a, mut filter_b) = (
                PixelFilter::new(&design, n),
                PixelFilter::with_rows(&design, w, h),
            );
            let (mut prev_a, mut prev_b) = (vec![0f32; n], vec![0f32; n]);
            let base: Vec<Complex32> = (0..n)
                .map(|_| Complex32::new(r.next_f64() as f32 + 0.2, r.next_f64() as f32 - 0.5))
                .collect();
            for t in 0..6 {
                // The band turning a little more each frame.
                let turn = Complex32::from_polar(1.0, 0.3 * t as f32);
                let frame: Vec<Complex32> = base
                    .iter()
                    .enumerate()
                    .map(|(i, &b)| b * turn * (1.0 + 0.01 * (i % 7) as f32))
                    .collect();
                let (factor, limit) = (10.0, DEFAULT_MAX_PHASE);
                // The passes one after another.
                let mut a = frame.clone();
                let (mut phase, mut amp) = (vec![0f32; n], vec![0f32; n]);
                csp_phase_step(&a, &mut prev_a, &mut phase, &mut amp, t == 0);
                filter_a.step(&mut phase);
                if kernel.len() > 1 {
                    let (mut den, mut tmp) = (amp.clone(), vec![0f32; n]);
                    let simd = crate::join::Simd::detect();
                    blur(&kernel, &mut den, &mut tmp, w, h, simd);
                    let mut num: Vec<f32> = amp.iter().zip(&phase).map(|(a, v)| a * v).collect();
                    blur(&kernel, &mut num, &mut tmp, w, h, simd);
                    for ((v, nu), de) in phase.iter_mut().zip(&num).zip(&den) {
                        *v = if *de > 1e-12 { nu / de } else { 0.0 };
                    }
                }
                let (mut sn, mut cs) = (vec![0f32; n], vec![0f32; n]);
                csp_shift(&mut a, &phase, (&mut sn, &mut cs), factor, limit);
                // The sweep.
                let mut b = frame.clone();
                csp_band(
                    BandSweep {
                        data: &mut b,
                        prev: &mut prev_b,
                        filter: &mut filter_b,
                        w,
                        h,
                    },
                    &mut rows,
                    &kernel,
                    (factor, limit),
                    t == 0,
                );
                for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                    assert!(
                        x.re.to_bits() == y.re.to_bits() && x.im.to_bits() == y.im.to_bits(),
                        "σ {sigma}, {w}x{h}, frame {t}, pixel {i}: {x} vs {y}"
                    );
                }
                assert!(
                    t == 0 || a.iter().zip(&frame).any(|(x, f)| x != f),
                    "σ {sigma}, {w}x{h}, frame {t}: nothing was shifted"
                );
            }
        }
    }
}

/// The pyramid's levels are the binomial reduce and expand as their
/// definitions say, summed directly in 2-D here (mirrored borders; the
/// expansion `4·B * (G_(l+1) upsampled by zero insertion)`): even and odd
/// sizes, rows too short for the passes' interiors, and the split passes.
/// The fast passes sum separably, so the match is to f32 rounding.
#[test]
fn levels_are_the_binomial_reduce_and_expand() {
    use laplacian::reflect;
    let t = [1.0f64, 4.0, 6.0, 4.0, 1.0].map(|v| v / 16.0);
    let reduce = |g: &[f64], (w, h): (usize, usize)| -> Vec<f64> {
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        let mut out = vec![0.0; nw * nh];
        for y in 0..nh {
            for x in 0..nw {
                let mut acc = 0.0;
                for (a, ta) in t.iter().enumerate() {
                    for (b, tb) in t.iter().enumerate() {
                        let r = reflect(2 * y as isize + a as isize - 2, h);
                        let c = reflect(2 * x as isize + b as isize - 2, w);
                        acc += ta * tb * g[r * w + c];
                    }
                }
                out[y * nw + x] = acc;
            }
        }
        out
    };
    let expand = |g: &[f64], (nw, nh): (usize, usize), (w, h): (usize, usize)| -> Vec<f64> {
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for (a, ta) in t.iter().enumerate() {
                    let r = reflect(y as isize + a as isize - 2, h);
                    for (b, tb) in t.iter().enumerate() {
                        let c = reflect(x as isize + b as isize - 2, w);
                        if r.is_multiple_of(2) && c.is_multiple_of(2) {
                            let (r, c) = ((r / 2).min(nh - 1), (c / 2).min(nw - 1));
                            acc += 4.0 * ta * tb * g[r * nw + c];
                        }
                    }
                }
                out[y * w + x] = acc;
            }
        }
        out
    };
    for &(w, h) in &[
        (256, 40),
        (131, 67),
        (37, 21),
        (8, 9),
        (5, 3),
        (4, 6),
        (1, 7),
    ] {
        let img = texture(w, h, 11);
        let mut lap = Laplacian::new(w, h, 3);
        lap.analyze(&img);
        let mut g: Vec<f64> = img.iter().map(|&v| f64::from(v)).collect();
        for l in 0..3 {
            let (dims, next_dims) = (lap.dims[l], lap.dims[l + 1]);
            let next = reduce(&g, dims);
            let up = expand(&next, next_dims, dims);
            let peak = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (i, (gv, uv)) in g.iter().zip(&up).enumerate() {
                let got = f64::from(lap.bands[l][i]);
                assert!(
                    (got - (gv - uv)).abs() < 1e-5 * peak,
                    "{w}x{h}, level {l}, pixel {i}: {got} against {}",
                    gv - uv
                );
            }
            g = next;
        }
        for (i, gv) in g.iter().enumerate() {
            assert!(
                (f64::from(lap.bands[3][i]) - gv).abs() < 1e-4,
                "{w}x{h}, residual {i}"
            );
        }
    }
}

/// The dither written straight into 8- and 16-bit pixels gives the levels
/// of `dither_round` then a cast, for values inside the range, beyond both
/// ends, at the levels' midpoints and NaN; `values` stay as they were.
#[test]
fn dithered_pixels_are_the_rounded_values_cast() {
    let mut values: Vec<f32> = (0..3000)
        .map(|i| (i as f32 * 0.731).sin() * 400.0 + 100.0)
        .collect();
    values.extend([
        f32::NAN,
        -0.5,
        0.5,
        254.5,
        255.5,
        1e9,
        -1e9,
        65535.5,
        70000.0,
    ]);
    for (max, first) in [(255.0, 0usize), (255.0, 1234), (65535.0, 7), (1023.0, 0)] {
        let mut rounded = values.clone();
        dither_round(&mut rounded, 99, first, max);
        let keep = values.clone();
        if max <= 255.0 {
            let mut px = vec![0u8; values.len()];
            dither_round_u8(&values, 99, first, max, &mut px);
            for (i, (p, r)) in px.iter().zip(&rounded).enumerate() {
                assert_eq!(*p, *r as u8, "max {max}, value {} at {i}", values[i]);
            }
        }
        let mut px = vec![0u16; values.len()];
        dither_round_u16(&values, 99, first, max, &mut px);
        for (i, (p, r)) in px.iter().zip(&rounded).enumerate() {
            assert_eq!(*p, *r as u16, "max {max}, value {} at {i}", values[i]);
        }
        assert!(values
            .iter()
            .zip(&keep)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

/// Magnifying a frame allocates nothing once the magnifier is built and
/// has seen its first frames: both pyramids, whole and in the steerable
/// pyramid's parts, with and without the blur.
#[test]
fn magnifying_a_frame_allocates_nothing() {
    use crate::pyramid::tests::alloc_count;
    let (w, h) = (48, 40);
    let frames: Vec<Vec<f32>> = (0..6)
        .map(|t| {
            (0..w * h)
                .map(|i| ((i * 7 + t * 3) % 23) as f32 + ((i / w) as f32 * 0.3).sin())
                .collect()
        })
        .collect();
    for (pyramid, sigma, part) in [
        (PyramidKind::Csp, DEFAULT_SIGMA, 0..DEFAULT_ORIENTATIONS),
        (PyramidKind::Csp, 0.0, 0..DEFAULT_ORIENTATIONS),
        (PyramidKind::Csp, DEFAULT_SIGMA, 0..DEFAULT_ORIENTATIONS / 2),
        (PyramidKind::Riesz, DEFAULT_SIGMA, 0..DEFAULT_ORIENTATIONS),
    ] {
        let mut p = MagnifyParams::new(500.0, 35.0, 45.0, 10.0);
        p.pyramid = pyramid;
        p.sigma = sigma;
        p.scales = 3;
        let whole = part == (0..p.orientations);
        let mut m = Magnifier::new_part(w, h, p, part.clone(), whole).unwrap();
        let mut out = vec![0.0f32; w * h];
        for f in &frames[..2] {
            m.process(f, &mut out).unwrap();
        }
        let before = alloc_count::allocations();
        for f in &frames[2..] {
            m.process(f, &mut out).unwrap();
        }
        let n = alloc_count::allocations() - before;
        assert_eq!(
            n, 0,
            "{pyramid:?}, σ {sigma}, part {part:?}: {n} allocations"
        );
    }
}
