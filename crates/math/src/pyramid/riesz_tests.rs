use super::super::tests::{alloc_count, noise, texture, Texture};
use super::*;
use proptest::prelude::*;

// ----- slow reference: direct 5x5 convolution in f64 -----

struct RefLevel {
    w: usize,
    h: usize,
    band: Vec<f64>,
    r1: Vec<f64>,
    r2: Vec<f64>,
    amp: Vec<f64>,
    phases: Vec<Vec<f64>>,
}

fn ref_mirror(mut i: i64, n: usize) -> usize {
    let n = n as i64;
    if n == 1 {
        return 0;
    }
    loop {
        if i < 0 {
            i = -i;
        } else if i >= n {
            i = 2 * (n - 1) - i;
        } else {
            return i as usize;
        }
    }
}

fn ref_conv(g: &[f64], w: usize, h: usize) -> Vec<f64> {
    let k = [1.0, 4.0, 6.0, 4.0, 1.0].map(|v: f64| v / 16.0);
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (j, kj) in k.iter().enumerate() {
                for (i, ki) in k.iter().enumerate() {
                    let yy = ref_mirror(y as i64 + j as i64 - 2, h);
                    let xx = ref_mirror(x as i64 + i as i64 - 2, w);
                    acc += kj * ki * g[yy * w + xx];
                }
            }
            out[y * w + x] = acc;
        }
    }
    out
}

fn reference(img: &[f32], w: usize, h: usize, scales: usize, k: usize) -> Vec<RefLevel> {
    let mut g: Vec<f64> = img.iter().map(|&v| f64::from(v)).collect();
    let (mut w, mut h) = (w, h);
    let mut levels = Vec::new();
    for _ in 0..scales {
        let s = ref_conv(&g, w, h);
        let t = ref_conv(&s, w, h);
        let band: Vec<f64> = s.iter().zip(&t).map(|(a, b)| a - b).collect();
        let at = |x: i64, y: i64| {
            band[y.clamp(0, h as i64 - 1) as usize * w + x.clamp(0, w as i64 - 1) as usize]
        };
        let mut r1 = vec![0.0; w * h];
        let mut r2 = vec![0.0; w * h];
        let mut amp = vec![0.0; w * h];
        let mut phases = vec![vec![0.0; w * h]; k];
        for y in 0..h {
            for x in 0..w {
                let (xi, yi) = (x as i64, y as i64);
                let i = y * w + x;
                r1[i] = 0.5 * (at(xi - 1, yi) - at(xi + 1, yi));
                r2[i] = 0.5 * (at(xi, yi - 1) - at(xi, yi + 1));
                let r = r1[i].hypot(r2[i]);
                amp[i] = band[i].hypot(r);
                let phi = r.atan2(band[i]);
                let theta = r2[i].atan2(r1[i]);
                for (kk, p) in phases.iter_mut().enumerate() {
                    let tk = std::f64::consts::PI * kk as f64 / k as f64;
                    p[i] = if r > 0.0 {
                        phi * (theta - tk).cos()
                    } else {
                        0.0
                    };
                }
            }
        }
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        let mut next = vec![0.0; nw * nh];
        for y in 0..nh {
            for x in 0..nw {
                next[y * nw + x] = t[2 * y * w + 2 * x];
            }
        }
        levels.push(RefLevel {
            w,
            h,
            band,
            r1,
            r2,
            amp,
            phases,
        });
        g = next;
        w = nw;
        h = nh;
    }
    levels
}

fn check_close(name: &str, fast: &[f32], slow: &[f64]) {
    assert_eq!(fast.len(), slow.len(), "{name}");
    let mag = slow.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let err = fast
        .iter()
        .zip(slow)
        .map(|(a, b)| (f64::from(*a) - b).abs())
        .fold(0.0, f64::max);
    assert!(
        err <= 1e-4 * mag + 1e-7,
        "{name}: err {err:e} vs max {mag:e}"
    );
}

#[test]
fn fast_path_matches_direct_reference() {
    for &(w, h, s, k, seed) in &[
        (16, 16, 3, 2, 1u64),
        (32, 24, 4, 4, 2),
        (15, 9, 3, 2, 3),
        (7, 3, 3, 3, 4),
        (1, 1, 2, 2, 5),
        (2, 5, 3, 1, 6),
    ] {
        let img = noise(w * h, seed);
        let r = reference(&img, w, h, s, k);
        let mut p = RieszPyramid::new(w, h, s, k).unwrap();
        let mut c = p.alloc_coeffs();
        p.analyze(&img, &mut c).unwrap();
        let mut worst_phase = 0.0f64;
        for (l, (fast, slow)) in c.levels().iter().zip(&r).enumerate() {
            assert_eq!((fast.width(), fast.height()), (slow.w, slow.h));
            let tag = format!("{w}x{h} level {l}");
            check_close(&format!("{tag} band"), fast.band(), &slow.band);
            check_close(&format!("{tag} r1"), fast.r1(), &slow.r1);
            check_close(&format!("{tag} r2"), fast.r2(), &slow.r2);
            check_close(&format!("{tag} amplitude"), fast.amplitude(), &slow.amp);
            let amax = slow.amp.iter().fold(0.0f64, |a, b| a.max(*b));
            for kk in 0..k {
                let pf = fast.phase(kk).unwrap();
                for (i, &pv) in pf.iter().enumerate() {
                    // Where |R| ~ 0 the orientation is undefined and the
                    // projected phase legitimately jumps; skip those.
                    if slow.r1[i].hypot(slow.r2[i]) < 1e-2 * amax {
                        continue;
                    }
                    let e = (f64::from(pv) - slow.phases[kk][i]).abs();
                    worst_phase = worst_phase.max(e);
                }
            }
        }
        assert!(
            worst_phase <= 1e-4 * std::f64::consts::PI,
            "{w}x{h}: phase err {worst_phase:e}"
        );
    }
}

#[test]
fn atan2_approximation_is_accurate() {
    let mut worst = 0.0f32;
    for i in 0..=2000 {
        for j in -1000..=1000 {
            let (y, x) = (i as f32 / 1000.0, j as f32 / 1000.0);
            let e = (atan2_upper(y, x) - y.atan2(x)).abs();
            worst = worst.max(e);
        }
    }
    assert!(worst < 1e-6, "{worst}");
    assert_eq!(atan2_upper(0.0, 0.0), 0.0);
}

#[test]
fn sizes_levels_and_errors() {
    let p = RieszPyramid::new(100, 75, 4, 2).unwrap();
    let c = p.alloc_coeffs();
    let dims: Vec<(usize, usize)> = c.levels().iter().map(|l| (l.width(), l.height())).collect();
    assert_eq!(dims, vec![(100, 75), (50, 38), (25, 19), (13, 10)]);
    assert_eq!(c.num_bands(), 8);
    let b = c.band_info(3).unwrap();
    assert_eq!((b.scale, b.orientation, b.width, b.height), (1, 1, 50, 38));
    assert!((b.angle - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
    assert!(RieszPyramid::new(0, 1, 1, 1).is_err());
    assert!(RieszPyramid::new(4, 4, 0, 1).is_err());
    assert!(RieszPyramid::new(4, 4, 1, 0).is_err());
    let mut p = RieszPyramid::new(8, 6, 2, 2).unwrap();
    let mut c = p.alloc_coeffs();
    assert!(matches!(
        p.analyze(&[0.0; 5], &mut c),
        Err(PyramidError::LengthMismatch { .. })
    ));
    let mut wrong = RieszPyramid::new(6, 8, 2, 2).unwrap().alloc_coeffs();
    assert_eq!(
        p.analyze(&[0.0; 48], &mut wrong).unwrap_err(),
        PyramidError::LayoutMismatch
    );
    p.analyze(&[0.5; 48], &mut c).unwrap();
    let mut out = vec![0.0; 48];
    assert!(c.phase_into(4, &mut out).is_err());
    assert!(c.amplitude_into(0, &mut out[..3]).is_err());
    assert!(c.phase_delta_into(&wrong, 0, &mut out).is_err());
    // A constant frame has no band-pass content.
    c.amplitude_into(0, &mut out).unwrap();
    assert!(out.iter().all(|v| v.abs() < 1e-6));
}

/// A 1D cosine along x: phase along orientation 0 is its spatial phase,
/// orientation 90° sees none, and the sign matches the CSP convention.
#[test]
fn cosine_phase_convention() {
    let (w, h) = (64, 8);
    let f = 0.18f32;
    let img: Vec<f32> = (0..w * h)
        .map(|i| (2.0 * PI * f * (i % w) as f32).cos())
        .collect();
    let mut p = RieszPyramid::new(w, h, 1, 2).unwrap();
    let mut c = p.alloc_coeffs();
    p.analyze(&img, &mut c).unwrap();
    let l = c.level(0).unwrap();
    let (p0, p1) = (l.phase(0).unwrap(), l.phase(1).unwrap());
    let row = 4 * w;
    for x in 8..w - 8 {
        let expect = 2.0 * PI * f * x as f32;
        let d = (p0[row + x] - expect).sin().abs();
        assert!(d < 0.06, "x={x}: {} vs {}", p0[row + x], expect);
        assert!(p1[row + x].abs() < 1e-3);
    }
}

struct RieszShift {
    level: usize,
    k: usize,
    fx: f64,
    d_est: f64,
    d_lin: f64,
}

fn mean_delta(cur: &RieszCoeffs, reference: &RieszCoeffs, i: usize, margin: usize) -> (f64, f64) {
    let info = cur.band_info(i).unwrap();
    let (w, h) = (info.width, info.height);
    let n = w * h;
    let (mut d, mut a0, mut a1) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    cur.phase_delta_into(reference, i, &mut d).unwrap();
    reference.amplitude_into(i, &mut a0).unwrap();
    cur.amplitude_into(i, &mut a1).unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    for y in margin..h.saturating_sub(margin) {
        for x in margin..w.saturating_sub(margin) {
            let j = y * w + x;
            let wt = f64::from(a0[j]) * f64::from(a1[j]);
            num += wt * f64::from(d[j]);
            den += wt;
        }
    }
    (num, den)
}

fn riesz_shift_rows(w: usize, h: usize, k: usize, d: f64, seed: u64) -> Vec<RieszShift> {
    let scales = 4;
    let margin = 9;
    let mut p = RieszPyramid::new(w, h, scales, k).unwrap();
    let mut run = |dx: f64| {
        let img = texture(w, h, seed, Texture::Natural, dx, 0.0);
        let mut c = p.alloc_coeffs();
        p.analyze(&img, &mut c).unwrap();
        c
    };
    let (c0, c1) = (run(0.0), run(d));
    let eps = 0.01;
    let (cp, cm) = (run(eps), run(-eps));
    let mut rows = Vec::new();
    for l in 0..scales {
        let level = c0.level(l).unwrap();
        let (lw, lh) = (level.width(), level.height());
        let q = |j: usize| [level.band()[j], level.r1()[j], level.r2()[j]];
        for kk in 0..k {
            let i = l * k + kk;
            let info = c0.band_info(i).unwrap();
            let (ck, sk) = (info.angle.cos(), info.angle.sin());
            // A²-weighted mean spatial x-derivative of the projected phase,
            // from wrap-safe neighbour differences, per input pixel.
            let (mut gn, mut gd) = (0.0, 0.0);
            for y in margin..lh.saturating_sub(margin) {
                for x in margin..lw.saturating_sub(margin) {
                    let j = y * lw + x;
                    let g = 0.5
                        * f64::from(
                            quat_phase_delta(q(j + 1), q(j), ck, sk)
                                + quat_phase_delta(q(j), q(j - 1), ck, sk),
                        );
                    let wt = f64::from(level.amplitude()[j]).powi(2);
                    gn += wt * g;
                    gd += wt;
                }
            }
            let grad = gn / gd / f64::from(info.step_x);
            let (num, den) = mean_delta(&c1, &c0, i, margin);
            let mean_dp = num / den;
            let (np, dp) = mean_delta(&cp, &cm, i, margin);
            let sens = np / dp / (2.0 * eps);
            rows.push(RieszShift {
                level: l,
                k: kk,
                fx: grad / (2.0 * std::f64::consts::PI),
                d_est: -mean_dp / grad,
                d_lin: mean_dp / sens,
            });
        }
    }
    rows
}

#[test]
fn local_phase_tracks_subpixel_translation() {
    for &k in &[2, 4] {
        for &d in &[0.05, 0.2, 0.5] {
            let rows = riesz_shift_rows(256, 256, k, d, 4321);
            let mut tested = 0;
            for r in &rows {
                let angle = PI * r.k as f32 / k as f32;
                let err = r.d_est / d - 1.0;
                println!(
                    "Riesz 256x256 K={k} d={d}: level {} ({:5.1} deg) mean x-freq of phase {:.4} c/px -> d_est {:.4} ({:+.2}%); from the response to a ±0.01 px shift instead: {:+.2}%",
                    r.level,
                    angle.to_degrees(),
                    r.fx,
                    r.d_est,
                    100.0 * err,
                    100.0 * (r.d_lin / d - 1.0)
                );
                if angle.cos() > 0.1 {
                    tested += 1;
                    assert!(
                        err.abs() < 0.05,
                        "K={k} d={d} level {} k {}: {:+.2}%",
                        r.level,
                        r.k,
                        100.0 * err
                    );
                    let lin = r.d_lin / d - 1.0;
                    assert!(
                        lin.abs() < 0.02,
                        "K={k} d={d} level {} k {}: linearity {:+.2}%",
                        r.level,
                        r.k,
                        100.0 * lin
                    );
                }
            }
            assert!(tested >= 4);
        }
    }
}

/// The weighted sums, per band and fused per scale, against the
/// per-pixel phase changes summed in f64 over a region.
#[test]
fn weighted_sums_match_the_per_pixel_phase_changes() {
    let (w, h) = (96, 64);
    let mut p = RieszPyramid::new(w, h, 3, 2).unwrap();
    let (mut c0, mut c1) = (p.alloc_coeffs(), p.alloc_coeffs());
    p.analyze(&texture(w, h, 5, Texture::Natural, 0.0, 0.0), &mut c0)
        .unwrap();
    p.analyze(&texture(w, h, 5, Texture::Natural, 0.3, 0.1), &mut c1)
        .unwrap();
    for scale in 0..3 {
        let mut want = [0.0f64; 2];
        let mut weights = Vec::new();
        for (o, wt) in want.iter_mut().enumerate() {
            let i = scale * 2 + o;
            let info = c1.band_info(i).unwrap().clone();
            let mut amp = vec![0.0f32; info.len()];
            c0.amplitude_into(i, &mut amp).unwrap();
            let wgt: Vec<f32> = amp.iter().map(|a| a * a).collect();
            let mut d = vec![0.0f32; info.len()];
            c1.phase_delta_into(&c0, i, &mut d).unwrap();
            let (rows, cols) = (1..info.height - 1, 2..info.width - 1);
            for y in rows.clone() {
                for x in cols.clone() {
                    *wt += (wgt[y * info.width + x] * d[y * info.width + x]) as f64;
                }
            }
            let one = c1
                .weighted_phase_delta_sum(&c0, i, &wgt, rows, cols)
                .unwrap();
            assert!(
                (one - *wt).abs() <= 1e-4 * (1.0 + wt.abs()),
                "band {i}: {one} vs {wt}"
            );
            weights.push((wgt, info));
        }
        let ws: Vec<&[f32]> = weights.iter().map(|(w, _)| &w[..]).collect();
        let info = &weights[0].1;
        let mut got = [0.0f64; 2];
        c1.scale_phase_delta_sums(
            &c0,
            scale,
            &ws,
            1..info.height - 1,
            2..info.width - 1,
            &mut got,
        )
        .unwrap();
        for o in 0..2 {
            assert!(
                (got[o] - want[o]).abs() <= 1e-4 * (1.0 + want[o].abs()),
                "scale {scale}"
            );
        }
    }
}

/// A frame of bytes analysed as bytes gives the bits of the same frame
/// widened to `f32`: every level's triple and derived values, on every
/// vector path this CPU has, for frames narrower than the blur's padding
/// (1 and 2 columns), with fewer rows than its taps, odd and even sizes,
/// and bytes at both ends of their range (where the 16-bit sums are
/// largest). Fails if the integer blur overflows or rounds otherwise.
#[test]
fn frames_of_bytes_give_the_bits_of_their_f32() {
    use crate::join::Simd;
    let mut seed = 7u64;
    let best = Simd::detect();
    for (w, h) in [
        (1, 1),
        (1, 9),
        (2, 5),
        (3, 3),
        (7, 4),
        (33, 17),
        (64, 64),
        (256, 8),
    ] {
        for fill in 0..3 {
            let bytes: Vec<u8> = (0..w * h)
                .map(|i| match fill {
                    0 => {
                        seed = seed
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        (seed >> 56) as u8
                    }
                    1 => 255,
                    _ => {
                        if (i / w + i % w) % 2 == 0 {
                            255
                        } else {
                            0
                        }
                    }
                })
                .collect();
            let floats: Vec<f32> = bytes.iter().map(|&b| f32::from(b)).collect();
            for simd in [Simd::Sse2, Simd::Avx2, Simd::Avx512] {
                if simd != Simd::Sse2
                    && (best == Simd::Sse2 || (simd == Simd::Avx512 && best != simd))
                {
                    continue;
                }
                for triples_only in [false, true] {
                    let mut p = RieszPyramid::new(w, h, 4, 2).unwrap();
                    p.simd = simd;
                    p.set_triples_only(triples_only);
                    let (mut a, mut b) = (p.alloc_coeffs(), p.alloc_coeffs());
                    let mut seen = Vec::new();
                    p.analyze_levels(&floats, &mut a, &mut |_, l| seen.push(l))
                        .unwrap();
                    p.analyze_levels_u8(&bytes, &mut b, &mut |_, l| seen.push(l))
                        .unwrap();
                    assert_eq!(seen.len(), 2 * a.levels().len(), "{w}x{h}");
                    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    for (l, (x, y)) in a.levels().iter().zip(b.levels()).enumerate() {
                        let what = format!("{w}x{h} fill {fill} {simd:?} level {l}");
                        assert_eq!(bits(x.band()), bits(y.band()), "{what}: band");
                        assert_eq!(bits(x.r1()), bits(y.r1()), "{what}: r1");
                        assert_eq!(bits(x.r2()), bits(y.r2()), "{what}: r2");
                        if !triples_only {
                            assert_eq!(
                                bits(x.amplitude()),
                                bits(y.amplitude()),
                                "{what}: amplitude"
                            );
                            for k in 0..2 {
                                assert_eq!(
                                    bits(x.phase(k).unwrap()),
                                    bits(y.phase(k).unwrap()),
                                    "{what}: phase {k}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }
    let mut p = RieszPyramid::new(8, 8, 2, 2).unwrap();
    let mut c = p.alloc_coeffs();
    assert!(p
        .analyze_levels_u8(&[0u8; 63], &mut c, &mut |_, _| {})
        .is_err());
}

#[test]
fn analyze_allocates_nothing() {
    let (w, h) = (100, 75);
    let img = texture(w, h, 5, Texture::Natural, 0.0, 0.0);
    let mut p = RieszPyramid::new(w, h, 4, 2).unwrap();
    let mut c = p.alloc_coeffs();
    let c_ref = p.alloc_coeffs();
    let mut out = vec![0.0f32; w * h];
    p.analyze(&img, &mut c).unwrap();
    let before = alloc_count::allocations();
    for _ in 0..5 {
        p.analyze(&img, &mut c).unwrap();
        c.phase_delta_into(&c_ref, 0, &mut out).unwrap();
        c.phase_into(1, &mut out).unwrap();
        c.amplitude_into(0, &mut out).unwrap();
    }
    assert_eq!(alloc_count::allocations() - before, 0);
}

#[test]
fn speed_report() {
    let (w, h) = (256, 256);
    let img = texture(w, h, 11, Texture::Natural, 0.0, 0.0);
    let mut p = RieszPyramid::new(w, h, 4, 2).unwrap();
    let mut c = p.alloc_coeffs();
    let iters = if cfg!(debug_assertions) { 2 } else { 200 };
    use crate::join::Simd;
    let best = p.simd;
    for simd in [Simd::Sse2, Simd::Avx2, Simd::Avx512] {
        if simd != Simd::Sse2 && (best == Simd::Sse2 || (simd == Simd::Avx512 && best != simd)) {
            continue;
        }
        p.simd = simd;
        p.analyze(&img, &mut c).unwrap();
        // Best of 9 batches: the machine is shared, the minimum is the cost.
        let ta = (0..9)
            .map(|_| {
                let t = std::time::Instant::now();
                for _ in 0..iters {
                    p.analyze(&img, &mut c).unwrap();
                }
                t.elapsed().as_secs_f64() / iters as f64
            })
            .fold(f64::INFINITY, f64::min);
        println!(
            "SPEED Riesz 256x256 (4 scales, 2 orientations, {} path): analyze {:.3} ms = {:.1} Mpix/s{}",
            simd.name(),
            ta * 1e3,
            (w * h) as f64 / 1e6 / ta,
            if cfg!(debug_assertions) { " (debug build)" } else { "" }
        );
    }
}

#[test]
fn vector_and_generic_paths_agree_bitwise() {
    use crate::join::Simd;
    let (w, h) = (77, 45);
    let img = texture(w, h, 3, Texture::Natural, 0.0, 0.0);
    let mut p = RieszPyramid::new(w, h, 4, 3).unwrap();
    let best = p.simd;
    let mut a = p.alloc_coeffs();
    let mut b = p.alloc_coeffs();
    p.simd = Simd::Sse2;
    p.analyze(&img, &mut a).unwrap();
    for simd in [Simd::Avx2, Simd::Avx512] {
        if best == Simd::Sse2 || (simd == Simd::Avx512 && best != simd) {
            continue;
        }
        p.simd = simd;
        p.analyze(&img, &mut b).unwrap();
        for (la, lb) in a.levels().iter().zip(b.levels()) {
            assert_eq!(la.band(), lb.band(), "{}", simd.name());
            assert_eq!(la.amplitude(), lb.amplitude(), "{}", simd.name());
            for k in 0..3 {
                assert_eq!(la.phase(k), lb.phase(k), "{}", simd.name());
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn any_size_is_finite(w in 1usize..40, h in 1usize..40, s in 1usize..8, k in 1usize..6, seed in 0u64..1000) {
        let img = noise(w * h, seed);
        let mut p = RieszPyramid::new(w, h, s, k).unwrap();
        let mut c = p.alloc_coeffs();
        p.analyze(&img, &mut c).unwrap();
        for l in c.levels() {
            prop_assert!(l.amplitude().iter().all(|v| v.is_finite()));
            for kk in 0..k {
                prop_assert!(l.phase(kk).unwrap().iter().all(|v| v.is_finite() && v.abs() <= PI + 1e-4));
            }
        }
    }
}

/// The mirror index without a division agrees with the periodic formula
/// (`x[-1] = x[1]`, period `2(n - 1)`) everywhere.
#[test]
fn reflect_matches_the_periodic_mirror() {
    for n in 1..12usize {
        for i in -40isize..40 {
            let want = if n == 1 {
                0
            } else {
                let p = 2 * (n as isize - 1);
                let m = i.rem_euclid(p);
                (if m >= n as isize { p - m } else { m }) as usize
            };
            assert_eq!(super::reflect(i, n), want, "i = {i}, n = {n}");
        }
    }
}

/// An analysis of the triples only gives the same triples, and the
/// amplitude and phases derived from them (through `PhaseBands`, or
/// `derive`) are the full analysis's, bit for bit.
#[test]
fn triples_only_derives_the_same_amplitude_and_phases() {
    let (w, h) = (61, 47);
    let img = texture(w, h, 9, Texture::Natural, 0.3, -0.2);
    let mut p = RieszPyramid::new(w, h, 4, 3).unwrap();
    let mut full = p.alloc_coeffs();
    p.analyze(&img, &mut full).unwrap();
    p.set_triples_only(true);
    let mut part = p.alloc_coeffs();
    p.analyze(&img, &mut part).unwrap();
    assert!(full.is_derived() && !part.is_derived());
    for i in 0..full.num_bands() {
        let n = full.band_info(i).unwrap().len();
        let (mut a, mut b) = (vec![0.0f32; n], vec![0.0f32; n]);
        full.amplitude_into(i, &mut a).unwrap();
        part.amplitude_into(i, &mut b).unwrap();
        assert!(a == b, "amplitude of band {i}");
        full.phase_into(i, &mut a).unwrap();
        part.phase_into(i, &mut b).unwrap();
        assert!(a == b, "phase of band {i}");
    }
    part.derive();
    for (la, lb) in full.levels().iter().zip(part.levels()) {
        assert!(la.band() == lb.band() && la.r1() == lb.r1() && la.r2() == lb.r2());
        assert!(la.amplitude() == lb.amplitude());
        for k in 0..3 {
            assert!(la.phase(k) == lb.phase(k));
        }
    }
}

/// The padded row blur (one loop over the row between mirrored pixels)
/// gives the bits of the separable blur with each tap's index reflected,
/// at every width, the narrow ones that take the per-pixel path included.
#[test]
fn padded_row_blur_matches_the_reflected_taps_bitwise() {
    let h = 7;
    for w in 1..=70 {
        let src = noise(w * h, w as u64);
        for y in 0..h {
            let mut padded = vec![f32::NAN; w + 4];
            let mut fast = vec![f32::NAN; w];
            blur_row(&src, (w, h), y, &mut padded, &mut fast);
            let mut vrow = vec![0.0; w];
            vblur_row(&src, w, h, y, &mut vrow);
            let at = |i: isize| vrow[reflect(i, w)];
            for (x, f) in fast.iter().enumerate() {
                let x = x as isize;
                let slow = B2 * (at(x - 2) + at(x + 2)) + B1 * (at(x - 1) + at(x + 1)) + B0 * at(x);
                assert_eq!(f.to_bits(), slow.to_bits(), "w {w}, row {y}, x {x}");
            }
        }
    }
}
