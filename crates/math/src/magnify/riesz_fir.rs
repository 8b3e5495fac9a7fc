//! The Riesz pair of a band-pass level by a 7x7 filter: `R1` is the level
//! convolved with `h(m, n)`, odd along x and even along y, `R2` with its
//! transpose, mirrored borders:
//!
//! `R1(x, y) = Σ_{m=1..3} Σ_{n=-3..3} c[m][|n|] · (I(x-m, y+n) - I(x+m, y+n))`
//!
//! Its response `2 Σ c[m][n]·sin(mωx)·(2 cos nωy, or 1 for n = 0)`
//! approximates the Riesz transform's `ωx/|ω|` (`super::riesz_fft`'s
//! multiplier) by weighted least squares over the frequencies a Laplacian
//! level holds: the weight is the mean power spectrum of levels 0 to 2 of
//! textures with `1/f^β` amplitude spectra (β 0.8 to 1.2), none of them
//! the simulator's (`scripts/riesz_taps.py`, which prints these taps and
//! the error below).
//!
//! Why not the 3-tap pair `(I[x-1] - I[x+1])/2` of Wadhwa et al. (2014)?
//! Its response `sin ωx` is near `ωx/|ω|` only around a quarter of the
//! sampling rate; a Laplacian level reaches from about π/4 to π. Against
//! the exact pair on held-out textures (the script), the 3-tap pair's
//! error is -7.9 to -11.2 dB of the pair's energy, this filter's -13.6
//! at level 0 (whose content reaches the Nyquist frequency, where every
//! odd filter vanishes) and -18.6 to -19.7 dB at levels 1 to 3; the
//! amplitude-weighted phase change of a 0.05 px shift reads 0.945 of the
//! exact pair's at level 0 and 0.999-1.003 at levels 1 and 2 (the 3-tap
//! pair: 0.90 and 1.02).
//!
//! Why not the exact pair by FFT (`super::riesz_fft`, which the
//! magnifier used before)? At 640x480 it took a third of a frame's time
//! (4.0 of 12.1 ms on one core); this filter takes 0.6-0.7 ms, in a
//! single pass over rows, from cache. The magnifier's figures moved by
//! little (README: x7.10 for x10 where the FFT gave x7.15).

use super::laplacian::reflect;
use crate::join::{simd_fn, Simd};

/// Half-width of the filter (7x7).
const K: usize = 3;

/// `TAPS[m - 1][n]`: the weight of `I(x∓m, y±n)` in `R1` (and of
/// `I(x±n, y∓m)` in `R2`), from `scripts/riesz_taps.py`.
const TAPS: [[f32; K + 1]; K] = [
    [0.432_106_7, 0.078_048_93, 0.008_675_525, 0.007_075_212],
    [-0.096_715_58, 0.019_200_32, 0.012_912_47, 0.005_207_171],
    [0.087_998_51, 0.016_770_69, 0.009_614_102, 0.006_969_305],
];

/// Scratch rows of one half of a pass: `K` rows of `T_m` and `K + 1` of
/// `U_n`, each `w + 2K` long (the row with `K` mirrored pixels each side).
#[derive(Clone, Debug, Default)]
struct Rows {
    t: Vec<f32>,
    u: Vec<f32>,
}

impl Rows {
    fn new(w: usize) -> Self {
        let pw = w + 2 * K;
        Self {
            t: vec![0.0; K * pw],
            u: vec![0.0; (K + 1) * pw],
        }
    }
}

/// The filter's buffers for one level size.
#[derive(Clone, Debug)]
pub(crate) struct RieszFir {
    w: usize,
    h: usize,
    rows: [Rows; 2],
}

impl RieszFir {
    /// Buffers for `w x h` levels.
    pub(crate) fn new(w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            rows: [Rows::new(w), Rows::new(w)],
        }
    }

    /// The pair `(r1, r2)` of `band` (row-major `w x h`, all three).
    /// Allocates nothing. The rows in two halves through `j`: the same
    /// bits however `j` runs them, and on every vector width (no fused
    /// multiply-add; the sums in one order).
    /// (The magnifier runs every level's halves in one hand-over:
    /// [`Self::halves`].)
    #[cfg(test)]
    pub(crate) fn pair(
        &mut self,
        band: &[f32],
        r1: &mut [f32],
        r2: &mut [f32],
        j: crate::join::Par<'_>,
    ) {
        use super::laplacian::mid_row;
        use crate::join::both;
        let (w, h) = (self.w, self.h);
        let hm = mid_row(h, w);
        let (a0, a1) = r1.split_at_mut(hm * w);
        let (c0, c1) = r2.split_at_mut(hm * w);
        let [s0, s1] = &mut self.rows;
        let v = j.simd;
        both(
            j,
            hm < h,
            || pair_rows(v, band, w, h, 0, a0, c0, s0),
            || pair_rows(v, band, w, h, hm, a1, c1, s1),
        );
    }
}

impl RieszFir {
    /// The two halves' scratch, for a pass that hands every level's
    /// halves over at once (the magnifier's): each computes any rows
    /// with [`PairHalf::rows`].
    pub(crate) fn halves(&mut self) -> [PairHalf<'_>; 2] {
        let (w, h) = (self.w, self.h);
        let [a, b] = &mut self.rows;
        [PairHalf { w, h, rows: a }, PairHalf { w, h, rows: b }]
    }
}

/// One half's scratch of a [`RieszFir`] ([`RieszFir::halves`]).
pub(crate) struct PairHalf<'a> {
    w: usize,
    h: usize,
    rows: &'a mut Rows,
}

impl PairHalf<'_> {
    /// Rows `y0..y0 + r1.len() / w` of the pair of `band` (the whole
    /// level): the bits [`RieszFir::pair`] gives them.
    #[inline(always)]
    pub(crate) fn rows(
        &mut self,
        v: Simd,
        band: &[f32],
        y0: usize,
        r1: &mut [f32],
        r2: &mut [f32],
    ) {
        pair_rows(v, band, self.w, self.h, y0, r1, r2, self.rows);
    }
}

/// Rows `y0..y0 + r1.len() / w` of the pair.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn pair_rows(
    v: Simd,
    band: &[f32],
    w: usize,
    h: usize,
    y0: usize,
    r1: &mut [f32],
    r2: &mut [f32],
    s: &mut Rows,
) {
    if w == 0 {
        return;
    }
    let rows = r1.len() / w;
    let row = |y: isize| {
        let y = reflect(y, h);
        &band[y * w..(y + 1) * w]
    };
    for ry in 0..rows {
        let y = (y0 + ry) as isize;
        let above = [row(y - 1), row(y - 2), row(y - 3)];
        let below = [row(y + 1), row(y + 2), row(y + 3)];
        let out = ry * w..(ry + 1) * w;
        pair_row(
            v,
            row(y),
            above,
            below,
            &mut s.t,
            &mut s.u,
            &mut r1[out.clone()],
            &mut r2[out],
        );
    }
}

/// Writes `src` (`w` long) into `dst` (`w + 2K`) with `K` mirrored pixels
/// each side.
#[inline(always)]
fn pad_ends(dst: &mut [f32], w: usize) {
    for k in 0..K {
        let left = reflect(-((K - k) as isize), w);
        let right = reflect((w + k) as isize, w);
        dst[k] = dst[K + left];
        dst[K + w + k] = dst[K + right];
    }
}

simd_fn! {
/// One row of the pair from the row, the `K` rows above and the `K` below
/// (mirrored already): per column, the vertical combinations
/// `T_m = Σ_n c[m][n]·(I(y+n) + I(y-n))` and `U_n = Σ_m c[m][n]·(I(y-m) -
/// I(y+m))` into `t`, `u` (padded by mirroring), then the horizontal
/// ones, `R1 = Σ_m T_m(x-m) - T_m(x+m)` and `R2 = U_0 + Σ_n U_n(x-n) +
/// U_n(x+n)`.
fn pair_row(
    mid: &[f32],
    above: [&[f32]; K],
    below: [&[f32]; K],
    t: &mut [f32],
    u: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
) {
    let w = mid.len();
    let pw = w + 2 * K;
    let [a1, a2, a3] = above.map(|r| &r[..w]);
    let [b1, b2, b3] = below.map(|r| &r[..w]);
    let (t, u) = (&mut t[..K * pw], &mut u[..(K + 1) * pw]);
    let (t1, rest) = t.split_at_mut(pw);
    let (t2, t3) = rest.split_at_mut(pw);
    let (u0, rest) = u.split_at_mut(pw);
    let (u1, rest) = rest.split_at_mut(pw);
    let (u2, u3) = rest.split_at_mut(pw);
    let c = TAPS;
    {
        let (t1, t2, t3) = (&mut t1[K..K + w], &mut t2[K..K + w], &mut t3[K..K + w]);
        let (u0, u1, u2, u3) = (
            &mut u0[K..K + w],
            &mut u1[K..K + w],
            &mut u2[K..K + w],
            &mut u3[K..K + w],
        );
        for x in 0..w {
            let s0 = mid[x];
            let (s1, s2, s3) = (a1[x] + b1[x], a2[x] + b2[x], a3[x] + b3[x]);
            let (d1, d2, d3) = (a1[x] - b1[x], a2[x] - b2[x], a3[x] - b3[x]);
            t1[x] = c[0][0] * s0 + c[0][1] * s1 + c[0][2] * s2 + c[0][3] * s3;
            t2[x] = c[1][0] * s0 + c[1][1] * s1 + c[1][2] * s2 + c[1][3] * s3;
            t3[x] = c[2][0] * s0 + c[2][1] * s1 + c[2][2] * s2 + c[2][3] * s3;
            u0[x] = c[0][0] * d1 + c[1][0] * d2 + c[2][0] * d3;
            u1[x] = c[0][1] * d1 + c[1][1] * d2 + c[2][1] * d3;
            u2[x] = c[0][2] * d1 + c[1][2] * d2 + c[2][2] * d3;
            u3[x] = c[0][3] * d1 + c[1][3] * d2 + c[2][3] * d3;
        }
    }
    for p in [&mut *t1, &mut *t2, &mut *t3, &mut *u0, &mut *u1, &mut *u2, &mut *u3] {
        pad_ends(p, w);
    }
    let (r1, r2) = (&mut r1[..w], &mut r2[..w]);
    let (t1, t2, t3) = (&t1[..pw], &t2[..pw], &t3[..pw]);
    let (u0, u1, u2, u3) = (&u0[..pw], &u1[..pw], &u2[..pw], &u3[..pw]);
    for x in 0..w {
        let k = x + K;
        r1[x] = (t1[k - 1] - t1[k + 1]) + (t2[k - 2] - t2[k + 2]) + (t3[k - 3] - t3[k + 3]);
        r2[x] = u0[k] + (u1[k - 1] + u1[k + 1]) + (u2[k - 2] + u2[k + 2]) + (u3[k - 3] + u3[k + 3]);
    }
}
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::join::{Par, Serial};

    /// A plane wave `cos(k·x)` has the pair `(kx, ky)/|k| · sin(k·x)`; the
    /// filter gives it to within its stated error inside the band it was
    /// designed for (|k| from π/4 to 3π/4 along and across the axes),
    /// away from the borders.
    #[test]
    fn plane_waves_in_the_band_get_nearly_the_exact_pair() {
        let (w, h) = (64usize, 48usize);
        let mut f = RieszFir::new(w, h);
        let par = Par {
            j: &Serial,
            simd: Simd::detect(),
        };
        let mut worst = f64::NEG_INFINITY;
        for &(kx, ky) in &[
            (0.8f64, 0.0f64),
            (0.0, 1.2),
            (1.0, 1.0),
            (-0.6, 1.4),
            (2.0, 0.5),
        ] {
            let k = kx.hypot(ky);
            let band: Vec<f32> = (0..w * h)
                .map(|i| ((kx * (i % w) as f64 + ky * (i / w) as f64).cos()) as f32)
                .collect();
            let (mut r1, mut r2) = (vec![0.0; w * h], vec![0.0; w * h]);
            f.pair(&band, &mut r1, &mut r2, par);
            let (mut err, mut energy) = (0.0, 0.0);
            for y in K..h - K {
                for x in K..w - K {
                    let i = y * w + x;
                    let s = (kx * x as f64 + ky * y as f64).sin();
                    let (e1, e2) = (kx / k * s, ky / k * s);
                    err += (f64::from(r1[i]) - e1).powi(2) + (f64::from(r2[i]) - e2).powi(2);
                    energy += e1 * e1 + e2 * e2;
                }
            }
            let db = 10.0 * (err / energy).log10();
            worst = worst.max(db);
            eprintln!("({kx}, {ky}): {db:.1} dB");
            assert!(db < -18.0, "({kx}, {ky}): error {db:.1} dB of the pair");
        }
        eprintln!("worst plane wave: {worst:.1} dB");
    }

    /// One thread at SSE2 and two halves at the machine's width give the
    /// same bits; tiny levels (1 and 2 pixels wide or high) work.
    #[test]
    fn halves_and_widths_give_the_same_bits_on_any_size() {
        for &(w, h) in &[(97usize, 131usize), (1, 5), (5, 1), (2, 2), (3, 7)] {
            let band: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919) % 251) as f32 / 25.0 - 5.0)
                .collect();
            let run = |simd, j: &dyn crate::join::Join| {
                let mut f = RieszFir::new(w, h);
                let (mut r1, mut r2) = (vec![0.0; w * h], vec![0.0; w * h]);
                f.pair(&band, &mut r1, &mut r2, Par { j, simd });
                (r1, r2)
            };
            let a = run(Simd::Sse2, &Serial);
            let b = run(Simd::detect(), &super::super::tests::TwoThreads);
            assert!(a.0.iter().chain(&a.1).all(|v| v.is_finite()));
            assert_eq!(a, b, "{w}x{h}");
        }
    }

    /// On the levels of a noise texture with a `1/f` amplitude spectrum
    /// (a seed the taps were not designed on), the pair is within the
    /// stated error of the exact pair by FFT (away from the borders, where
    /// the FFT's are periodic and these mirrored).
    #[test]
    fn texture_levels_get_nearly_the_exact_pair() {
        let n = 128usize;
        // 1/f noise: white noise's spectrum divided by |f| (a DFT each way
        // through the exact pair's own FFTs would do; a sum of random
        // plane waves with amplitudes 1/|k| is simpler).
        let mut r = crate::rng::Xoshiro256::new(4242);
        let mut img = vec![0.0f32; n * n];
        for _ in 0..400 {
            let (kx, ky) = (r.next_f64() * 2.0 - 1.0, r.next_f64() * 2.0 - 1.0);
            let (kx, ky) = (kx * std::f64::consts::PI, ky * std::f64::consts::PI);
            let k = kx.hypot(ky).max(0.05);
            let ph = r.next_f64() * std::f64::consts::TAU;
            for (i, v) in img.iter_mut().enumerate() {
                let (x, y) = ((i % n) as f64, (i / n) as f64);
                *v += ((kx * x + ky * y + ph).cos() / k) as f32;
            }
        }
        let mut lap = super::super::laplacian::Laplacian::new(n, n, 3);
        lap.analyze(&img);
        let par = Par {
            j: &Serial,
            simd: Simd::detect(),
        };
        for l in 0..3 {
            let (w, h) = lap.dims[l];
            let band = &lap.bands[l][..w * h];
            let (mut e1, mut e2) = (vec![0.0; w * h], vec![0.0; w * h]);
            super::super::riesz_fft::RieszFft::new(w, h).pair(band, &mut e1, &mut e2, par);
            let (mut f1, mut f2) = (vec![0.0; w * h], vec![0.0; w * h]);
            RieszFir::new(w, h).pair(band, &mut f1, &mut f2, par);
            let m = 8 >> l;
            let (mut err, mut energy) = (0.0f64, 0.0f64);
            for y in m..h - m {
                for x in m..w - m {
                    let i = y * w + x;
                    let d = |a: f32, b: f32| f64::from(a - b).powi(2);
                    err += d(f1[i], e1[i]) + d(f2[i], e2[i]);
                    energy += f64::from(e1[i] * e1[i] + e2[i] * e2[i]);
                }
            }
            let db = 10.0 * (err / energy).log10();
            eprintln!("level {l}: {db:.1} dB");
            assert!(db < -12.0, "level {l}: error {db:.1} dB of the pair");
        }
    }
}
