//! The Riesz pair of a band-pass level by FFT: `R1 + i·R2` is the inverse
//! transform of the level's spectrum times `(ωy - i·ωx)/|ω|`, the exact
//! Riesz transform (Felsberg and Sommer's monogenic signal), with periodic
//! borders.
//!
//! The magnifier's own pair is now the 7x7 filter of `super::riesz_fir`;
//! this exact one is kept as the reference its tests measure it against.
//!
//! Why not the 3-tap pair `(I[x-1] - I[x+1])/2` of Wadhwa et al. (2014)?
//! Its response is `sin ωx` where the Riesz transform's is `ωx/|ω|`: near
//! 1 only around a quarter of the sampling rate. The paper designs its own
//! narrow pyramid bands to live there; a Laplacian level reaches from
//! about π/4 to π, where `sin ω` falls to zero, so the pair is short and
//! the quaternionic phase reads low. Measured on the simulator's texture
//! (`cargo test --release --test suite magnify::`): a factor of 10 gave x6.8 and a
//! factor of 0 left the motion only 7 dB down with the 3-tap pair; the
//! exact pair's figures are in the README.

use super::laplacian::mid_row;
use crate::join::{both, Par};
use crate::pyramid::Complex32;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// The FFTs, the multiplier and the buffers of one level size.
pub(crate) struct RieszFft {
    w: usize,
    h: usize,
    row_fwd: Arc<dyn Fft<f32>>,
    row_inv: Arc<dyn Fft<f32>>,
    col_fwd: Arc<dyn Fft<f32>>,
    col_inv: Arc<dyn Fft<f32>>,
    /// Row-major `w x h`.
    buf: Vec<Complex32>,
    /// Column-major (`x * h + y`), for the column transforms.
    tr: Vec<Complex32>,
    /// `(ωy - i·ωx)/|ω| / (w·h)` in the column-major layout.
    mult: Vec<Complex32>,
    /// One scratch buffer for each half of a split pass.
    scratch: [Vec<Complex32>; 2],
}

/// Angular frequency of bin `k` of `n` in `(-π, π]`; 0 at the Nyquist bin
/// of an even `n` (where `ω` and `-ω` share a bin, the odd multiplier must
/// vanish for a real result).
fn omega(k: usize, n: usize) -> (f32, f32) {
    let signed = if 2 * k > n {
        k as f32 - n as f32
    } else {
        k as f32
    };
    let w = 2.0 * std::f32::consts::PI * signed / n as f32;
    let odd = if 2 * k == n { 0.0 } else { w };
    (w, odd)
}

impl RieszFft {
    /// Plans and buffers for `w x h` levels.
    pub(crate) fn new(w: usize, h: usize) -> Self {
        let mut planner = FftPlanner::<f32>::new();
        let row_fwd = planner.plan_fft_forward(w);
        let row_inv = planner.plan_fft_inverse(w);
        let col_fwd = planner.plan_fft_forward(h);
        let col_inv = planner.plan_fft_inverse(h);
        let scratch_len = [&row_fwd, &row_inv, &col_fwd, &col_inv]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        let norm = 1.0 / (w * h) as f32;
        let mut mult = vec![Complex32::new(0.0, 0.0); w * h];
        for kx in 0..w {
            let (wx, ox) = omega(kx, w);
            for ky in 0..h {
                let (wy, oy) = omega(ky, h);
                let r = wx.hypot(wy);
                if r > 0.0 {
                    mult[kx * h + ky] = Complex32::new(oy / r, -ox / r) * norm;
                }
            }
        }
        let zero = Complex32::new(0.0, 0.0);
        Self {
            w,
            h,
            row_fwd,
            row_inv,
            col_fwd,
            col_inv,
            buf: vec![zero; w * h],
            tr: vec![zero; w * h],
            mult,
            scratch: [vec![zero; scratch_len], vec![zero; scratch_len]],
        }
    }

    /// The pair `(r1, r2)` of `band` (row-major `w x h`, all three).
    /// Allocates nothing. Each pass (rows, the transposes, columns) in two
    /// halves through `j`: the same bits however `j` runs them.
    #[inline(always)]
    pub(crate) fn pair(&mut self, band: &[f32], r1: &mut [f32], r2: &mut [f32], j: Par<'_>) {
        let RieszFft {
            w,
            h,
            row_fwd,
            row_inv,
            col_fwd,
            col_inv,
            buf,
            tr,
            mult,
            scratch,
        } = self;
        let (w, h) = (*w, *h);
        let [s0, s1] = scratch;
        // Rows in halves (hm rows, then the rest), columns likewise.
        let hm = mid_row(h, w);
        let wm = if hm < h { w / 2 } else { w };
        {
            let (b0, b1) = buf.split_at_mut(hm * w);
            let fwd = |band: &[f32], b: &mut [Complex32], s: &mut [Complex32]| {
                for (b, &v) in b.iter_mut().zip(band) {
                    *b = Complex32::new(v, 0.0);
                }
                if !b.is_empty() {
                    row_fwd.process_with_scratch(b, s);
                }
            };
            both(
                j,
                hm < h,
                || fwd(&band[..hm * w], b0, s0),
                || fwd(&band[hm * w..], b1, s1),
            );
        }
        // Transposed so each column is contiguous: columns in halves.
        {
            let src = &*buf;
            let (t0, t1) = tr.split_at_mut(wm * h);
            let (m0, m1) = mult.split_at(wm * h);
            let cols = |t: &mut [Complex32], m: &[Complex32], x0: usize, s: &mut [Complex32]| {
                transpose(src, t, w, h, x0);
                if t.is_empty() {
                    return;
                }
                col_fwd.process_with_scratch(t, s);
                for (t, m) in t.iter_mut().zip(m) {
                    *t *= m;
                }
                col_inv.process_with_scratch(t, s);
            };
            both(j, wm < w, || cols(t0, m0, 0, s0), || cols(t1, m1, wm, s1));
        }
        {
            let src = &*tr;
            let (b0, b1) = buf.split_at_mut(hm * w);
            let (a0, a1) = r1.split_at_mut(hm * w);
            let (c0, c1) = r2.split_at_mut(hm * w);
            let inv = |b: &mut [Complex32],
                       y0: usize,
                       r1: &mut [f32],
                       r2: &mut [f32],
                       s: &mut [Complex32]| {
                transpose(src, b, h, w, y0);
                if !b.is_empty() {
                    row_inv.process_with_scratch(b, s);
                }
                for ((z, a), c) in b.iter().zip(r1.iter_mut()).zip(r2.iter_mut()) {
                    *a = z.re;
                    *c = z.im;
                }
            };
            both(
                j,
                hm < h,
                || inv(b0, 0, a0, c0, s0),
                || inv(b1, hm, a1, c1, s1),
            );
        }
    }
}

/// Columns `x0..x0 + dst.len() / h` of the transpose of a row-major
/// `w x h` `src`: `dst[(x - x0) * h + y] = src[y * w + x]`, in tiles.
#[inline(always)]
fn transpose(src: &[Complex32], dst: &mut [Complex32], w: usize, h: usize, x0: usize) {
    const T: usize = 16;
    let nx = dst.len() / h.max(1);
    for y0 in (0..h).step_by(T) {
        for xa in (x0..x0 + nx).step_by(T) {
            for x in xa..(xa + T).min(x0 + nx) {
                let col = &mut dst[(x - x0) * h..(x - x0 + 1) * h];
                for (y, d) in col.iter_mut().enumerate().take((y0 + T).min(h)).skip(y0) {
                    *d = src[y * w + x];
                }
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A plane wave `cos(k·x)` has the pair `(kx, ky)/|k| · sin(k·x)` (for
    /// frequencies that fit the frame a whole number of times).
    #[test]
    fn plane_waves_get_the_exact_pair() {
        for &(w, h) in &[(32usize, 24usize), (27, 15), (1, 8), (6, 1)] {
            let mut r = RieszFft::new(w, h);
            for &(cx, cy) in &[(3usize, 0usize), (0, 2), (5, 4), (1, 1)] {
                let (cx, cy) = (cx % w.max(1), cy % h.max(1));
                if cx == 0 && cy == 0 || 2 * cx == w || 2 * cy == h {
                    continue;
                }
                // The bin's frequency in (-π, π] (bin 5 of 6 is -2π/6).
                let signed = |c: usize, n: usize| {
                    let c = if 2 * c > n {
                        c as f64 - n as f64
                    } else {
                        c as f64
                    };
                    2.0 * std::f64::consts::PI * c / n as f64
                };
                let (kx, ky) = (signed(cx, w), signed(cy, h));
                let k = kx.hypot(ky);
                let band: Vec<f32> = (0..w * h)
                    .map(|i| ((kx * (i % w) as f64 + ky * (i / w) as f64).cos()) as f32)
                    .collect();
                let (mut r1, mut r2) = (vec![0.0; w * h], vec![0.0; w * h]);
                let par = Par {
                    j: &crate::join::Serial,
                    simd: crate::join::Simd::detect(),
                };
                r.pair(&band, &mut r1, &mut r2, par);
                for i in 0..w * h {
                    let s = (kx * (i % w) as f64 + ky * (i / w) as f64).sin();
                    let (e1, e2) = (kx / k * s, ky / k * s);
                    assert!(
                        (f64::from(r1[i]) - e1).abs() < 1e-4
                            && (f64::from(r2[i]) - e2).abs() < 1e-4,
                        "{w}x{h} ({cx},{cy}) at {i}: ({}, {}) vs ({e1}, {e2})",
                        r1[i],
                        r2[i]
                    );
                }
            }
        }
    }
}
