//! Per-pixel hot loops of the phase stage (Eq. 3.2-3.4), written over
//! fixed-size lane arrays so the compiler turns them into SIMD, and built
//! three times: a generic version, an AVX2 and an AVX-512 version, chosen
//! at run time (the RustFFT pattern). All compute the same operations in
//! the same order per lane, so they agree to the last bit on a given
//! input; the sums are exact functions of the data, whatever the thread
//! count or the vector width.
//!
//! The fused multiply-adds are written out (`mul_add`), never formed by
//! the compiler: exact on every path, one instruction where the CPU has
//! FMA (every x86-64 CPU with AVX2, every aarch64), a library call on an
//! x86-64 CPU without it (before 2013), which is slower there but gives the
//! same bits.
//!
//! Each kernel computes 4L pixels at a time (several vectors per value):
//! its chains of dependent operations (the arctangent's polynomial) are
//! then independent of each other and overlap. The
//! per-pixel values are added into L lanes L at a time, in pixel order,
//! so the width does not change the sums' rounding. The last pixels of a
//! span (fewer than L) go through the same lanes padded with zeros (a
//! tile's row at a coarse level is shorter than L: one pixel at a time,
//! such spans took most of a tiled analysis).

use super::Complex32;
use std::f32::consts::{FRAC_PI_2, PI};

const L: usize = 8;

/// The lanes' arctangent polynomial: atan(t) ≈ t·P(t²) on [0, 1], P of
/// degree 5 with P(0) = 1 (so a small phase change keeps its scale
/// exactly), its other coefficients the minimax fit of the error
/// (a linear program on 4001 points of [0, 1]; `docs/performance.md`,
/// session 79). In f32 it is within 2.5e-6 rad of atan everywhere and
/// within 1.1e-7 of it relatively below t = 0.01: far under the phase's
/// noise in any band, and 3 operations a lane fewer than the 9 terms of
/// [`crate::fastmath::atan2`] (2e-8), which [`quat_phase_delta`] keeps.
const ATAN: [f32; 6] = [
    1.0,
    -0.332_961_92,
    0.195_154_19,
    -0.119_748,
    0.055_732_65,
    -0.012_781_097,
];

/// `atan2(y, x)` for `y >= 0`, from `t = min(y, |x|) / max(y, |x|)` and
/// its flags (bit 0: `y > |x|`, bit 1: `x < 0`), on `N` lanes.
#[inline(always)]
fn atan_n<const N: usize>(t: &[f32; N], flags: &[u8; N]) -> [f32; N] {
    let mut r = [0.0f32; N];
    for l in 0..N {
        // Horner's scheme: with 6 terms its chain of 5 dependent
        // multiply-adds overlaps with the lanes' other work as well as
        // Estrin's 4 (measured), in 2 operations fewer.
        let x = t[l] * t[l];
        let mut p = ATAN[5];
        for &c in ATAN[..5].iter().rev() {
            p = p.mul_add(x, c);
        }
        let mut v = t[l] * p;
        v = if flags[l] & 1 != 0 { FRAC_PI_2 - v } else { v };
        r[l] = if flags[l] & 2 != 0 { PI - v } else { v };
    }
    r
}

/// The arctangent's argument reduction: for `atan2(y, x)` with `ay = |y|`,
/// `(num, den, flags)` with `num <= den`, `den` never 0 (0 / 1 gives
/// `atan2(0, 0) = 0`), and the flags [`atan_n`] takes.
#[inline(always)]
fn octant(ay: f32, x: f32) -> (f32, f32, u8) {
    let ax = x.abs();
    let swap = ay > ax;
    let num = if swap { ax } else { ay };
    let den = if swap { ay } else { ax };
    // 0 / 0 as 0 / MIN_POSITIVE (one operation, not a compare and a
    // select; a subnormal `den` reads as MIN_POSITIVE).
    let den = den.max(f32::MIN_POSITIVE);
    (num, den, u8::from(swap) | (u8::from(x < 0.0) << 1))
}

/// `N` pixels from `s` of [`csp_row_generic`], added into the L lanes of
/// `acc` L at a time, in pixel order.
#[inline(always)]
fn csp_px<const N: usize>(
    cur: &[Complex32],
    reference: &[Complex32],
    w: &[f32],
    s: usize,
    acc: &mut [f32; L],
) {
    let (c, r) = (&cur[s..s + N], &reference[s..s + N]);
    let mut t = [0.0f32; N];
    let mut flags = [0u8; N];
    let mut sign = [false; N];
    for l in 0..N {
        let re = c[l].re.mul_add(r[l].re, c[l].im * r[l].im);
        let im = c[l].im.mul_add(r[l].re, -(c[l].re * r[l].im));
        let (num, den, fl) = octant(im.abs(), re);
        t[l] = num / den;
        flags[l] = fl;
        sign[l] = im < 0.0;
    }
    let a = atan_n(&t, &flags);
    // Each value weighed and added into its lane in one multiply-add, L
    // at a time, in pixel order.
    let mut p = [0.0f32; N];
    for l in 0..N {
        p[l] = if sign[l] { -a[l] } else { a[l] };
    }
    let wn = &w[s..s + N];
    for (pg, wg) in p.chunks_exact(L).zip(wn.chunks_exact(L)) {
        for l in 0..L {
            acc[l] = wg[l].mul_add(pg[l], acc[l]);
        }
    }
}

/// Σ w · arg(c · conj(c0)) over one row span of a complex band.
#[inline(always)]
fn csp_row_generic(cur: &[Complex32], reference: &[Complex32], w: &[f32]) -> f32 {
    let n = cur.len().min(reference.len()).min(w.len());
    let (cur, reference, w) = (&cur[..n], &reference[..n], &w[..n]);
    let mut acc = [0.0f32; L];
    // 4L pixels at a time where there are that many (as in
    // `riesz_span`: the same additions in the same order). Written out,
    // not through a closure: a closure is not compiled with the calling
    // function's target features, so its mul_add became a library call
    // (12x slower).
    let chunks = n / L;
    let mut ch = 0;
    while ch < chunks {
        if ch + 4 <= chunks {
            csp_px::<{ 4 * L }>(cur, reference, w, ch * L, &mut acc);
            ch += 4;
        } else {
            csp_px::<L>(cur, reference, w, ch * L, &mut acc);
            ch += 1;
        }
    }
    // The last pixels (fewer than L) through the same lanes, padded with
    // zeros, which add exactly 0 (as in `riesz_span`).
    let s = chunks * L;
    if s < n {
        let mut c = [Complex32::default(); L];
        let mut r = [Complex32::default(); L];
        let mut wp = [0.0f32; L];
        c[..n - s].copy_from_slice(&cur[s..n]);
        r[..n - s].copy_from_slice(&reference[s..n]);
        wp[..n - s].copy_from_slice(&w[s..n]);
        csp_px::<L>(&c, &r, &wp, 0, &mut acc);
    }
    // Lanes added in a fixed order.
    acc.iter().sum::<f32>()
}

/// Most orientations a fused Riesz call handles.
pub const MAX_ORIENT: usize = 8;

/// `N` pixels from `s` of [`riesz_row_generic`], `K` orientations, added
/// into the L lanes of `lanes` in groups of L, in pixel order.
#[inline(always)]
fn riesz_px<const N: usize, const K: usize>(
    cur: [&[f32]; 3],
    prev: [&[f32]; 3],
    s: usize,
    dirs: &[(f32, f32); K],
    w: &[&[f32]; K],
    lanes: &mut [[f32; L]; K],
) {
    let part = |v: &[f32]| -> [f32; N] {
        let mut o = [0.0f32; N];
        o.copy_from_slice(&v[s..s + N]);
        o
    };
    let (a, b, c) = (part(cur[0]), part(cur[1]), part(cur[2]));
    let (d, e, f) = (part(prev[0]), part(prev[1]), part(prev[2]));
    let mut t = [0.0f32; N];
    let mut scale = [0.0f32; N];
    let mut vi = [0.0f32; N];
    let mut vj = [0.0f32; N];
    let mut flags = [0u8; N];
    for l in 0..N {
        let re = c[l].mul_add(f[l], b[l].mul_add(e[l], a[l] * d[l]));
        vi[l] = (-a[l]).mul_add(e[l], b[l] * d[l]);
        vj[l] = (-a[l]).mul_add(f[l], c[l] * d[l]);
        let vk = (-b[l]).mul_add(f[l], c[l] * e[l]);
        let inplane = vj[l].mul_add(vj[l], vi[l] * vi[l]);
        let vn = vk.mul_add(vk, inplane).sqrt();
        // No branch: where the in-plane norm is 0, vi = vj = 0 and the
        // projection below is exactly 0, so any finite factor gives 0.
        let ij = inplane.sqrt().max(f32::MIN_POSITIVE);
        // atan2(vn, re) as atan(num / den) with num <= den, and 1 / ij:
        // one division gives both (division and square root are the
        // kernel's slowest operations).
        let (num, den, fl) = octant(vn, re);
        let r = 1.0 / (den * ij).max(f32::MIN_POSITIVE);
        t[l] = num * (ij * r);
        scale[l] = den * r;
        flags[l] = fl;
    }
    let dphi = atan_n(&t, &flags);
    for l in 0..N {
        scale[l] *= dphi[l];
    }
    for ((&(ck, sk), wk), acc) in dirs.iter().zip(w).zip(lanes.iter_mut()) {
        let wk = part(wk);
        let mut p = [0.0f32; N];
        for l in 0..N {
            p[l] = wk[l] * (scale[l] * vj[l].mul_add(sk, vi[l] * ck));
        }
        for g in p.chunks_exact(L) {
            for l in 0..L {
                acc[l] += g[l];
            }
        }
    }
}

/// The whole-chunk part of [`riesz_row_generic`] for `K` orientations
/// (a constant, so that the sums' lanes stay in registers): each
/// orientation's L lanes.
#[inline(always)]
fn riesz_span<const K: usize>(
    cur: [&[f32]; 3],
    prev: [&[f32]; 3],
    w: &[&[f32]; K],
    dirs: &[(f32, f32); K],
    n: usize,
) -> [[f32; L]; K] {
    // Pixels are computed 4L at a time (several vectors per value, whose
    // chains of dependent operations overlap: the kernel is bound by
    // their latency) and added into the L lanes of the sums L at a time,
    // in pixel order: the same additions in the same order whatever the
    // vector width, so every path gives the same bits.
    let mut lanes = [[0.0f32; L]; K];
    let chunks = n / L;
    let mut ch = 0;
    while ch < chunks {
        let s = ch * L;
        if ch + 4 <= chunks {
            riesz_px::<{ 4 * L }, K>(cur, prev, s, dirs, w, &mut lanes);
            ch += 4;
        } else {
            riesz_px::<L, K>(cur, prev, s, dirs, w, &mut lanes);
            ch += 1;
        }
    }
    // The last pixels (fewer than L) through the same lanes, padded with
    // zeros: a zero pixel adds exactly 0 (its weight is 0 and its change
    // finite). A span shorter than L (a tile's row at a coarse level) is
    // all tail: its pixels one at a time took 85% of a tiled analysis.
    let s = chunks * L;
    if s < n {
        // Plain loops: a closure (or `map`) is not compiled for the
        // caller's vectors, and its copies were called lane by lane.
        let r = n - s;
        let (mut c, mut p) = ([[0.0f32; L]; 3], [[0.0f32; L]; 3]);
        for j in 0..3 {
            c[j][..r].copy_from_slice(&cur[j][s..n]);
            p[j][..r].copy_from_slice(&prev[j][s..n]);
        }
        let mut wp = [[0.0f32; L]; K];
        for (o, v) in wp.iter_mut().zip(w) {
            o[..r].copy_from_slice(&v[s..n]);
        }
        let mut ws: [&[f32]; K] = [&[]; K];
        for (o, v) in ws.iter_mut().zip(&wp) {
            *o = v;
        }
        riesz_px::<L, K>(
            [&c[0], &c[1], &c[2]],
            [&p[0], &p[1], &p[2]],
            0,
            dirs,
            &ws,
            &mut lanes,
        );
    }
    lanes
}

/// One row span of a Riesz level, every orientation at once: for each
/// pixel the quaternion phase change from `prev` to `cur` (angle Δφ about
/// the in-plane axis (vi, vj), see [`quat_phase_delta`]) is
/// computed once, then projected on each orientation `(ck, sk)` and
/// weighted by that orientation's `w[k]`. Adds Σ into `acc[k]`.
#[inline(always)]
fn riesz_row_generic(
    cur: [&[f32]; 3],
    prev: [&[f32]; 3],
    w: &[&[f32]],
    dirs: &[(f32, f32)],
    acc: &mut [f32],
) {
    let k = dirs.len().min(w.len()).min(acc.len()).min(MAX_ORIENT);
    let n = cur
        .iter()
        .chain(prev.iter())
        .map(|s| s.len())
        .chain(w[..k].iter().map(|s| s.len()))
        .min()
        .unwrap_or(0);
    let mut lanes = [[0.0f32; L]; MAX_ORIENT];
    macro_rules! span {
        ($k:literal) => {{
            let mut d = [(0.0f32, 0.0f32); $k];
            let mut ws: [&[f32]; $k] = [&[]; $k];
            d.copy_from_slice(&dirs[..$k]);
            ws.copy_from_slice(&w[..$k]);
            let got = riesz_span::<$k>(cur, prev, &ws, &d, n);
            lanes[..$k].copy_from_slice(&got);
        }};
    }
    match k {
        0 => {}
        1 => span!(1),
        2 => span!(2),
        3 => span!(3),
        4 => span!(4),
        // 5 to 8: the last orientation repeated up to 8, its extra lanes
        // dropped.
        _ => {
            let mut d = [dirs[k - 1]; MAX_ORIENT];
            let mut ws: [&[f32]; MAX_ORIENT] = [w[k - 1]; MAX_ORIENT];
            d[..k].copy_from_slice(&dirs[..k]);
            ws[..k].copy_from_slice(&w[..k]);
            lanes = riesz_span::<MAX_ORIENT>(cur, prev, &ws, &d, n);
        }
    }
    for (a, l) in acc[..k].iter_mut().zip(&lanes) {
        *a += l.iter().sum::<f32>();
    }
}

crate::join::simd_fn! {
    fn csp_row_simd(cur: &[Complex32], reference: &[Complex32], w: &[f32]) -> f32 {
        csp_row_generic(cur, reference, w)
    }
}

crate::join::simd_fn! {
    fn riesz_row_simd(
        cur: [&[f32]; 3],
        prev: [&[f32]; 3],
        w: &[&[f32]],
        dirs: &[(f32, f32)],
        acc: &mut [f32],
    ) {
        riesz_row_generic(cur, prev, w, dirs, acc)
    }
}

/// Σ w · arg(c · conj(c0)) over a row span (lengths: the shortest slice).
pub fn csp_row(cur: &[Complex32], reference: &[Complex32], w: &[f32]) -> f32 {
    csp_row_simd(crate::join::Simd::detect(), cur, reference, w)
}

/// Adds each orientation's weighted Riesz phase change over a row span to
/// `acc[k]` (see [`riesz_row_generic`]); at most [`MAX_ORIENT`] orientations.
pub fn riesz_row(
    cur: [&[f32]; 3],
    prev: [&[f32]; 3],
    w: &[&[f32]],
    dirs: &[(f32, f32)],
    acc: &mut [f32],
) {
    riesz_row_simd(crate::join::Simd::detect(), cur, prev, w, dirs, acc)
}

/// Phase change from `q0 = (I, R1, R2)` to `q1`, projected on the
/// orientation `(cos θk, sin θk)`: the quaternion `q1·conj(q0)` has angle
/// `Δφ` about the axis `(vi, vj, vk)`; the in-plane part `(vi, vj)` gives the
/// orientation along which the phase moved.
#[inline]
pub fn quat_phase_delta(q1: [f32; 3], q0: [f32; 3], ck: f32, sk: f32) -> f32 {
    let [a, b, c] = q1;
    let [d, e, f] = q0;
    let re = a * d + b * e + c * f;
    let vi = b * d - a * e;
    let vj = c * d - a * f;
    let vk = c * e - b * f;
    let vn = (vi * vi + vj * vj + vk * vk).sqrt();
    let dphi = crate::fastmath::atan2(vn, re);
    let ij = (vi * vi + vj * vj).sqrt();
    if ij > 0.0 {
        dphi * (vi * ck + vj * sk) / ij
    } else {
        0.0
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::fastmath::atan2;

    fn rng(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    /// atan2 on 8 lanes from [`atan_n`], as the kernels reduce it.
    fn atan2_lanes(y: &[f32; L], x: &[f32; L]) -> [f32; L] {
        let mut t = [0.0f32; L];
        let mut flags = [0u8; L];
        for l in 0..L {
            let (num, den, fl) = octant(y[l].abs(), x[l]);
            t[l] = num / den;
            flags[l] = fl;
        }
        let a = atan_n(&t, &flags);
        let mut r = [0.0f32; L];
        for l in 0..L {
            r[l] = if y[l] < 0.0 { -a[l] } else { a[l] };
        }
        r
    }

    /// The lanes' arctangent (6 terms in Horner's scheme, fused
    /// multiply-adds) is within 3e-6 rad of f64's everywhere (the scalar
    /// one within 1e-6), and within 2e-7 of it relatively for small
    /// angles.
    #[test]
    fn lanes_atan2_is_within_3e6_of_f64() {
        let mut s = 7u64;

        for _ in 0..20000 {
            let mut y = [0.0f32; L];
            let mut x = [0.0f32; L];
            for l in 0..L {
                y[l] = rng(&mut s) * 10f32.powi((l as i32 % 5) - 2);
                x[l] = rng(&mut s);
            }
            y[0] = 0.0;
            x[1] = 0.0;
            x[2] = -0.0;
            let a = atan2_lanes(&y, &x);
            for l in 0..L {
                let want = (y[l] as f64).atan2(x[l] as f64);
                let err = (a[l] as f64 - want).abs();
                assert!(err < 3e-6, "{} {}: {} vs {want}", y[l], x[l], a[l]);
                assert!((a[l] - atan2(y[l], x[l])).abs() < 3e-6);
                if want.abs() < 0.01 {
                    assert!(
                        err <= 2e-7 * want.abs(),
                        "{} {}: {} vs {want}",
                        y[l],
                        x[l],
                        a[l]
                    );
                }
            }
        }
        let z = atan2_lanes(&[0.0; L], &[0.0; L]);
        assert!(z.iter().all(|&v| v == 0.0));
    }

    /// Against the obvious per-pixel loop, in f64, for odd lengths (tails).
    #[test]
    fn csp_row_matches_the_obvious_sum() {
        let mut s = 3u64;
        for n in [0usize, 1, 7, 8, 9, 63, 200] {
            let c: Vec<Complex32> = (0..n)
                .map(|_| Complex32::new(rng(&mut s), rng(&mut s)))
                .collect();
            let r: Vec<Complex32> = (0..n)
                .map(|_| Complex32::new(rng(&mut s), rng(&mut s)))
                .collect();
            let w: Vec<f32> = (0..n).map(|_| rng(&mut s).abs()).collect();
            let want: f64 = (0..n)
                .map(|i| {
                    let p = c[i] * r[i].conj();
                    w[i] as f64 * (p.im as f64).atan2(p.re as f64)
                })
                .sum();
            for got in [csp_row(&c, &r, &w), csp_row_generic(&c, &r, &w)] {
                assert!(
                    (got as f64 - want).abs() < 1e-4 * (1.0 + want.abs()),
                    "n {n}: {got} vs {want}"
                );
            }
            assert_eq!(
                csp_row(&c, &r, &w).to_bits(),
                csp_row_generic(&c, &r, &w).to_bits()
            );
        }
    }

    #[test]
    fn riesz_row_matches_per_orientation_quaternion_sums() {
        let mut s = 11u64;
        let dirs = [(1.0f32, 0.0f32), (0.0, 1.0), (0.6, 0.8)];
        for n in [0usize, 5, 8, 17, 130] {
            let v: Vec<Vec<f32>> = (0..6)
                .map(|_| (0..n).map(|_| rng(&mut s)).collect())
                .collect();
            let w: Vec<Vec<f32>> = (0..3)
                .map(|_| (0..n).map(|_| rng(&mut s).abs()).collect())
                .collect();
            let ws: Vec<&[f32]> = w.iter().map(|x| &x[..]).collect();
            let mut acc = [0.0f32; 3];
            riesz_row(
                [&v[0], &v[1], &v[2]],
                [&v[3], &v[4], &v[5]],
                &ws,
                &dirs,
                &mut acc,
            );
            let mut acc_g = [0.0f32; 3];
            riesz_row_generic(
                [&v[0], &v[1], &v[2]],
                [&v[3], &v[4], &v[5]],
                &ws,
                &dirs,
                &mut acc_g,
            );
            for k in 0..3 {
                let want: f64 = (0..n)
                    .map(|i| {
                        w[k][i] as f64
                            * quat_phase_delta(
                                [v[0][i], v[1][i], v[2][i]],
                                [v[3][i], v[4][i], v[5][i]],
                                dirs[k].0,
                                dirs[k].1,
                            ) as f64
                    })
                    .sum();
                assert!(
                    (acc[k] as f64 - want).abs() < 1e-4 * (1.0 + want.abs()),
                    "n {n} k {k}"
                );
                assert_eq!(acc[k].to_bits(), acc_g[k].to_bits());
            }
        }
    }
}
