//! Per-pixel hot loops of the phase stage (Eq. 3.2-3.4), written over
//! 8-lane arrays so the compiler turns them into SIMD, and built three
//! times: a generic version, an AVX2 and an AVX-512 version, chosen at run
//! time (the RustFFT pattern). All compute the same operations in the same order per lane
//! (no fused multiply-add is formed without permission), so they agree to
//! the last bit on a given input; the sums are exact functions of the data,
//! whatever the thread count.

use super::Complex32;
use std::f32::consts::{FRAC_PI_2, PI};

const L: usize = 8;

/// The coefficients of [`crate::fastmath::atan2`], lane by lane.
const ATAN: [f32; 9] = crate::fastmath::ATAN_COEFFS;

/// atan2 on 8 lanes, branch-free; same result as
/// [`crate::fastmath::atan2`] lane by lane.
#[inline(always)]
fn atan2_8(y: &[f32; L], x: &[f32; L]) -> [f32; L] {
    let mut r = [0.0f32; L];
    for l in 0..L {
        let (ax, ay) = (x[l].abs(), y[l].abs());
        let swap = ay > ax;
        let num = if swap { ax } else { ay };
        let den = if swap { ay } else { ax };
        // den = 0 only when num = 0 too: 0 / 1 gives atan2(0, 0) = 0.
        let t = num / if den == 0.0 { 1.0 } else { den };
        let t2 = t * t;
        let mut p = ATAN[8];
        for c in ATAN[..8].iter().rev() {
            p = p * t2 + c;
        }
        let mut v = t * p;
        v = if swap { FRAC_PI_2 - v } else { v };
        v = if x[l] < 0.0 { PI - v } else { v };
        r[l] = if y[l] < 0.0 { -v } else { v };
    }
    r
}

/// Σ w · arg(c · conj(c0)) over one row span of a complex band.
#[inline(always)]
fn csp_row_generic(cur: &[Complex32], reference: &[Complex32], w: &[f32]) -> f32 {
    let n = cur.len().min(reference.len()).min(w.len());
    let (cur, reference, w) = (&cur[..n], &reference[..n], &w[..n]);
    let mut acc = [0.0f32; L];
    let chunks = n / L;
    for ch in 0..chunks {
        let s = ch * L;
        let (c, r, wt) = (&cur[s..s + L], &reference[s..s + L], &w[s..s + L]);
        let mut re = [0.0f32; L];
        let mut im = [0.0f32; L];
        for l in 0..L {
            re[l] = c[l].re * r[l].re + c[l].im * r[l].im;
            im[l] = c[l].im * r[l].re - c[l].re * r[l].im;
        }
        let a = atan2_8(&im, &re);
        for l in 0..L {
            acc[l] += wt[l] * a[l];
        }
    }
    let mut tail = 0.0f32;
    for i in chunks * L..n {
        let (c, r) = (cur[i], reference[i]);
        let re = c.re * r.re + c.im * r.im;
        let im = c.im * r.re - c.re * r.im;
        tail += w[i] * crate::fastmath::atan2(im, re);
    }
    // Lanes added in a fixed order.
    acc.iter().sum::<f32>() + tail
}

/// Most orientations a fused Riesz call handles.
pub const MAX_ORIENT: usize = 8;

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
    let chunks = n / L;
    for ch in 0..chunks {
        let s = ch * L;
        let (a, b, c) = (&cur[0][s..s + L], &cur[1][s..s + L], &cur[2][s..s + L]);
        let (d, e, f) = (&prev[0][s..s + L], &prev[1][s..s + L], &prev[2][s..s + L]);
        let mut re = [0.0f32; L];
        let mut vn = [0.0f32; L];
        let mut vi = [0.0f32; L];
        let mut vj = [0.0f32; L];
        let mut inv_ij = [0.0f32; L];
        for l in 0..L {
            re[l] = a[l] * d[l] + b[l] * e[l] + c[l] * f[l];
            vi[l] = b[l] * d[l] - a[l] * e[l];
            vj[l] = c[l] * d[l] - a[l] * f[l];
            let vk = c[l] * e[l] - b[l] * f[l];
            let inplane = vi[l] * vi[l] + vj[l] * vj[l];
            vn[l] = (inplane + vk * vk).sqrt();
            // No branch: where the in-plane norm is 0, vi = vj = 0 and the
            // projection below is exactly 0, so any finite factor gives 0
            // (|Δφ| ≤ π keeps π / MIN_POSITIVE finite).
            inv_ij[l] = 1.0 / inplane.sqrt().max(f32::MIN_POSITIVE);
        }
        let dphi = atan2_8(&vn, &re);
        let mut scale = [0.0f32; L];
        for l in 0..L {
            scale[l] = dphi[l] * inv_ij[l];
        }
        for ((&(ck, sk), wk), acc) in dirs[..k].iter().zip(&w[..k]).zip(lanes.iter_mut()) {
            // Fixed-size views let the compiler keep all 8 lanes in one
            // register (a dynamic index into `lanes` defeats it).
            let Ok(wk) = <&[f32; L]>::try_from(&wk[s..s + L]) else {
                continue;
            };
            let mut a = *acc;
            for l in 0..L {
                a[l] += wk[l] * (scale[l] * (vi[l] * ck + vj[l] * sk));
            }
            *acc = a;
        }
    }
    for (o, (&(ck, sk), wk)) in dirs[..k].iter().zip(&w[..k]).enumerate() {
        let mut tail = 0.0f32;
        for i in chunks * L..n {
            tail += wk[i]
                * quat_phase_delta(
                    [cur[0][i], cur[1][i], cur[2][i]],
                    [prev[0][i], prev[1][i], prev[2][i]],
                    ck,
                    sk,
                );
        }
        acc[o] += lanes[o].iter().sum::<f32>() + tail;
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

    #[test]
    fn lanes_match_the_scalar_atan2_bitwise() {
        let mut s = 7u64;
        for _ in 0..2000 {
            let mut y = [0.0f32; L];
            let mut x = [0.0f32; L];
            for l in 0..L {
                y[l] = rng(&mut s) * 10f32.powi((l as i32 % 5) - 2);
                x[l] = rng(&mut s);
            }
            y[0] = 0.0;
            x[1] = 0.0;
            x[2] = -0.0;
            let a = atan2_8(&y, &x);
            for l in 0..L {
                assert_eq!(
                    a[l].to_bits(),
                    atan2(y[l], x[l]).to_bits(),
                    "{} {}",
                    y[l],
                    x[l]
                );
            }
        }
        let z = atan2_8(&[0.0; L], &[0.0; L]);
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
