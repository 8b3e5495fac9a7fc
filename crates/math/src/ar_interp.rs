//! Filling gaps in a uniformly sampled signal: autoregressive
//! interpolation (Janssen, Veldhuis & Vries, "Adaptive interpolation of
//! discrete-time signals that can be modeled as autoregressive processes",
//! IEEE Trans. ASSP 34(2), 1986) and, for comparison, a straight line.
//!
//! A rolling-shutter camera (thesis ch. 4.5) samples one row per line delay
//! and is blind during the frame delay, so its signal has one gap per frame.
//! The AR method models the signal as x_t = Σ_i a_i x_{t-i} + e_t and picks
//! the missing samples that minimise the total squared prediction error
//! Σ_t e_t² over every residual that touches them; with the model fixed this
//! is a linear least-squares problem whose normal matrix is the banded
//! Toeplitz matrix of the autocorrelation of b = (1, -a_1, ..., -a_p).
//! Janssen et al. alternate model estimation and interpolation; the first
//! model here comes from the known samples only (autocorrelation summed over
//! the two known segments, so nothing is correlated across the gap), later
//! ones from the whole window with the gap filled.
//!
//! All working memory lives in [`ArInterpolator`]; once it has seen the
//! largest window, filling allocates nothing.

/// Reusable state for AR gap filling.
#[derive(Debug, Default)]
pub struct ArInterpolator {
    order: usize,
    iterations: usize,
    r: Vec<f64>,
    a: Vec<f64>,
    prev: Vec<f64>,
    b: Vec<f64>,
    rb: Vec<f64>,
    band: Vec<f64>,
    rhs: Vec<f64>,
    c: Vec<f64>,
    work: Vec<f64>,
    decimate: usize,
    lp: Vec<f64>,
    coarse: Vec<f64>,
}

impl ArInterpolator {
    /// `order` AR coefficients, `iterations` >= 1 rounds of
    /// estimate-then-interpolate.
    pub fn new(order: usize, iterations: usize) -> Self {
        Self {
            order: order.max(1),
            iterations: iterations.max(1),
            decimate: 1,
            ..Self::default()
        }
    }

    pub fn order(&self) -> usize {
        self.order
    }

    /// Fills `x[left..left + missing]` from the known samples around it (the
    /// rest of `x`). The order is reduced to what the context supports; with
    /// fewer than two known samples on a side the gap is filled linearly.
    /// With [`ArInterpolator::with_decimation`], long gaps are bridged at a
    /// lower rate (see there).
    pub fn fill(&mut self, x: &mut [f64], left: usize, missing: usize) {
        let d = self.decimate;
        if d > 1 && missing >= 2 * d && left + missing <= x.len() {
            self.fill_decimated(x, left, missing);
        } else {
            self.fill_direct(x, left, missing);
        }
    }

    /// Also bridge gaps at 1/`decimate` of the rate: a row-rate signal is
    /// hugely oversampled for sound (1/d ≈ 60 kHz, exposure limits it to
    /// 1/E ≈ 2 kHz), and an AR model at the full rate would need hundreds of
    /// coefficients to remember one pitch period across a 5 ms gap. The
    /// known samples are low-passed (windowed sinc at 0.45 of the low rate's
    /// Nyquist, evaluated only where its support avoids the gap), the gap is
    /// AR-interpolated on that coarse grid, and the result is brought back
    /// to the full rate by cubic interpolation. Content above the low rate's
    /// Nyquist is not restored inside gaps (it is removed downstream anyway).
    pub fn with_decimation(mut self, decimate: usize) -> Self {
        self.decimate = decimate.max(1);
        let d = self.decimate;
        if d > 1 {
            let hw = 3 * d;
            let fc = 0.45 / d as f64;
            let mut h: Vec<f64> = (0..=2 * hw)
                .map(|k| {
                    let j = k as f64 - hw as f64;
                    let sinc = if j == 0.0 {
                        2.0 * fc
                    } else {
                        (2.0 * std::f64::consts::PI * fc * j).sin() / (std::f64::consts::PI * j)
                    };
                    let w = k as f64 / (2 * hw) as f64;
                    let win = 0.42 - 0.5 * (2.0 * std::f64::consts::PI * w).cos()
                        + 0.08 * (4.0 * std::f64::consts::PI * w).cos();
                    sinc * win
                })
                .collect();
            let sum: f64 = h.iter().sum();
            h.iter_mut().for_each(|v| *v /= sum);
            self.lp = h;
        }
        self
    }

    fn fill_decimated(&mut self, x: &mut [f64], left: usize, missing: usize) {
        let d = self.decimate;
        let hw = self.lp.len() / 2;
        let n = x.len();
        // Coarse grid g_k = g0 + k d, aligned so that one point falls on the
        // gap's first sample; a point is known when its filter support
        // avoids the gap and the window's ends.
        let g0 = left % d;
        let count = (n - g0).div_ceil(d);
        let is_known =
            |g: usize| g >= hw && g + hw < n && (g + hw < left || g >= left + missing + hw);
        let mut coarse = std::mem::take(&mut self.coarse);
        coarse.clear();
        let (mut first_unknown, mut last_unknown) = (None, None);
        let mut first_known = None;
        for k in 0..count {
            let g = g0 + k * d;
            if is_known(g) {
                first_known.get_or_insert(k);
                let src = &x[g - hw..=g + hw];
                coarse.push(src.iter().zip(&self.lp).map(|(a, b)| a * b).sum::<f64>());
            } else {
                if g + hw >= left && g < left + missing + hw {
                    first_unknown.get_or_insert(k);
                    last_unknown = Some(k);
                }
                coarse.push(0.0);
            }
        }
        let (Some(k0), Some(k1), Some(kf)) = (first_unknown, last_unknown, first_known) else {
            self.coarse = coarse;
            self.fill_direct(x, left, missing);
            return;
        };
        // Only the contiguous stretch of known points on each side is used.
        let mut lo = k0;
        while lo > kf && is_known(g0 + (lo - 1) * d) {
            lo -= 1;
        }
        let mut hi = k1 + 1;
        while hi < count && is_known(g0 + hi * d) {
            hi += 1;
        }
        let seg = &mut coarse[lo..hi];
        self.fill_direct(seg, k0 - lo, k1 + 1 - k0);
        // Back to the full rate inside the gap: Catmull-Rom on the coarse grid.
        let at = |k: isize| coarse[(k.max(lo as isize) as usize).min(hi - 1)];
        for (s, out) in x.iter_mut().enumerate().skip(left).take(missing) {
            let u = (s - g0) as f64 / d as f64;
            let i = u.floor() as isize;
            let t = u - i as f64;
            let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
            *out = p1
                + 0.5
                    * t
                    * (p2 - p0
                        + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3
                            + t * (3.0 * (p1 - p2) + p3 - p0)));
        }
        self.coarse = coarse;
    }

    fn fill_direct(&mut self, x: &mut [f64], left: usize, missing: usize) {
        let n = x.len();
        if missing == 0 || left + missing > n {
            return;
        }
        let right = n - left - missing;
        let p = self.order.min(left).min(right);
        if p < 2 {
            linear_fill(x, left, missing);
            return;
        }
        // Work on a zero-mean copy (the AR model has no constant term);
        // only the gap is written back, so known samples stay bit-exact.
        let known = (left + right) as f64;
        let mean =
            (x[..left].iter().sum::<f64>() + x[left + missing..].iter().sum::<f64>()) / known;
        let mut work = std::mem::take(&mut self.work);
        work.clear();
        work.extend(x.iter().map(|v| v - mean));
        // Start from the straight line: harmless for round one (its model
        // ignores the gap), and a finite value for every later read.
        linear_fill(&mut work, left, missing);
        for round in 0..self.iterations {
            self.r.clear();
            self.r.resize(p + 1, 0.0);
            if round == 0 {
                autocorr_add(&work[..left], &mut self.r);
                autocorr_add(&work[left + missing..], &mut self.r);
            } else {
                autocorr_add(&work, &mut self.r);
            }
            if !levinson(&self.r, &mut self.a, &mut self.prev) {
                linear_fill(&mut work, left, missing);
                break;
            }
            self.b.clear();
            self.b.push(1.0);
            self.b.extend(self.a.iter().map(|v| -v));
            self.solve(&mut work, left, missing, p);
        }
        for (o, w) in x[left..left + missing]
            .iter_mut()
            .zip(&work[left..left + missing])
        {
            *o = w + mean;
        }
        self.work = work;
    }

    /// The least-squares interpolant for the model in `self.b` (order `p`).
    fn solve(&mut self, x: &mut [f64], left: usize, m: usize, p: usize) {
        let b = &self.b;
        // Autocorrelation of b: the normal matrix is R_b(|j - k|), band p.
        self.rb.clear();
        self.rb
            .extend((0..=p).map(|l| (0..=p - l).map(|i| b[i] * b[i + l]).sum::<f64>()));
        // c_t: the part of residual e_t from known samples, t in [left, left + m + p).
        let is_known = |k: usize| k < left || k >= left + m;
        self.c.clear();
        self.c.extend((left..left + m + p).map(|t| {
            (0..=p)
                .filter(|&i| i <= t && is_known(t - i))
                .map(|i| b[i] * x[t - i])
                .sum::<f64>()
        }));
        // rhs_j = -Σ_{t=j}^{j+p} b_{t-j} c_t (j relative to the gap).
        self.rhs.clear();
        self.rhs
            .extend((0..m).map(|j| -(0..=p).map(|i| b[i] * self.c[j + i]).sum::<f64>()));
        banded_cholesky_solve(&self.rb, m, p, &mut self.band, &mut self.rhs);
        x[left..left + m].copy_from_slice(&self.rhs);
    }
}

/// Straight line across `x[left..left + missing]` between its neighbours
/// (a constant when only one side exists).
pub fn linear_fill(x: &mut [f64], left: usize, missing: usize) {
    let n = x.len();
    if missing == 0 || left + missing > n {
        return;
    }
    let a = if left > 0 { Some(x[left - 1]) } else { None };
    let b = x.get(left + missing).copied();
    let (a, b) = match (a, b) {
        (Some(a), Some(b)) => (a, b),
        (Some(a), None) => (a, a),
        (None, Some(b)) => (b, b),
        (None, None) => (0.0, 0.0),
    };
    let step = (b - a) / (missing + 1) as f64;
    for (i, v) in x[left..left + missing].iter_mut().enumerate() {
        *v = a + step * (i + 1) as f64;
    }
}

/// `r[k] += Σ_t x_t x_{t+k}` for k < r.len() (biased, not normalised: a sum
/// of such sequences is still positive definite, so Levinson stays stable).
fn autocorr_add(x: &[f64], r: &mut [f64]) {
    for (k, rk) in r.iter_mut().enumerate() {
        if k < x.len() {
            *rk += x[..x.len() - k]
                .iter()
                .zip(&x[k..])
                .map(|(a, b)| a * b)
                .sum::<f64>();
        }
    }
}

/// Levinson-Durbin: prediction coefficients `a` (x_t ≈ Σ a_i x_{t-i}) of
/// order r.len() - 1. A tiny white-noise floor (1e-9 of r0) keeps the
/// recursion well conditioned on pure tones. False when r0 is not positive.
fn levinson(r: &[f64], a: &mut Vec<f64>, prev: &mut Vec<f64>) -> bool {
    let p = r.len() - 1;
    a.clear();
    if !(r[0].is_finite() && r[0] > 0.0) {
        return false;
    }
    let mut err = r[0] * (1.0 + 1e-9);
    for i in 1..=p {
        let acc = r[i]
            - a.iter()
                .enumerate()
                .map(|(j, aj)| aj * r[i - 1 - j])
                .sum::<f64>();
        let k = acc / err;
        prev.clear();
        prev.extend_from_slice(a);
        for j in 0..a.len() {
            a[j] -= k * prev[prev.len() - 1 - j];
        }
        a.push(k);
        err *= 1.0 - k * k;
        if !(err.is_finite() && err > 0.0) {
            return false;
        }
    }
    true
}

/// Solves T y = rhs in place for the symmetric positive-definite banded
/// Toeplitz matrix T[j][k] = rb[|j - k|] (zero beyond the band `p`) of size
/// `m`: banded Cholesky, O(m p²). `band` is scratch.
fn banded_cholesky_solve(rb: &[f64], m: usize, p: usize, band: &mut Vec<f64>, rhs: &mut [f64]) {
    let w = p + 1;
    band.clear();
    band.resize(m * w, 0.0);
    // band[i * w + (i - j)] = L[i][j] for i - p <= j <= i.
    for i in 0..m {
        let j0 = i.saturating_sub(p);
        for j in j0..=i {
            let q0 = j0.max(j.saturating_sub(p));
            let mut s = rb[i - j];
            for q in q0..j {
                s -= band[i * w + (i - q)] * band[j * w + (j - q)];
            }
            if i == j {
                band[i * w] = s.max(1e-300).sqrt();
            } else {
                band[i * w + (i - j)] = s / band[j * w];
            }
        }
    }
    for i in 0..m {
        let mut s = rhs[i];
        for q in i.saturating_sub(p)..i {
            s -= band[i * w + (i - q)] * rhs[q];
        }
        rhs[i] = s / band[i * w];
    }
    for i in (0..m).rev() {
        let mut s = rhs[i];
        for q in i + 1..(i + w).min(m) {
            s -= band[q * w + (q - i)] * rhs[q];
        }
        rhs[i] = s / band[i * w];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Xoshiro256;

    fn tones(n: usize, noise: f64, seed: u64) -> Vec<f64> {
        let mut rng = Xoshiro256::new(seed);
        (0..n)
            .map(|t| {
                let t = t as f64;
                (0.07 * t).sin() + 0.5 * (0.19 * t + 1.0).sin() + noise * (rng.next_f64() - 0.5)
            })
            .collect()
    }

    fn err(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>()
    }

    #[test]
    fn ar_bridges_a_long_gap_in_two_tones() {
        let truth = tones(600, 0.01, 7);
        let (left, m) = (250, 60);
        let mut ar = truth.clone();
        ArInterpolator::new(24, 2).fill(&mut ar, left, m);
        let mut lin = truth.clone();
        linear_fill(&mut lin, left, m);
        let g = left..left + m;
        let (e_ar, e_lin) = (
            err(&ar[g.clone()], &truth[g.clone()]),
            err(&lin[g.clone()], &truth[g]),
        );
        assert!(e_ar * 100.0 < e_lin, "AR {e_ar:.3e} vs linear {e_lin:.3e}");
        // Known samples are untouched.
        assert_eq!(&ar[..left], &truth[..left]);
        assert_eq!(&ar[left + m..], &truth[left + m..]);
    }

    /// The banded solver against a dense least-squares solve of the
    /// prediction-error problem written out in full (the slow reference).
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn banded_solution_matches_dense_least_squares() {
        let x0 = tones(120, 0.3, 3);
        let (left, m, p) = (40, 25, 6);
        let mut ai = ArInterpolator::new(p, 1);
        let mut fast = x0.clone();
        ai.fill(&mut fast, left, m);
        // Rebuild the model the fast path used (round one: known samples, zero mean).
        let known: Vec<usize> = (0..x0.len())
            .filter(|&k| k < left || k >= left + m)
            .collect();
        let mean = known.iter().map(|&k| x0[k]).sum::<f64>() / known.len() as f64;
        let xc: Vec<f64> = x0.iter().map(|v| v - mean).collect();
        let mut r = vec![0.0; p + 1];
        autocorr_add(&xc[..left], &mut r);
        autocorr_add(&xc[left + m..], &mut r);
        let (mut a, mut prev) = (Vec::new(), Vec::new());
        assert!(levinson(&r, &mut a, &mut prev));
        let b: Vec<f64> = std::iter::once(1.0).chain(a.iter().map(|v| -v)).collect();
        // Dense normal equations over every full residual t in [p, n).
        let n = x0.len();
        let mut ata = vec![vec![0.0; m]; m];
        let mut atb = vec![0.0; m];
        for t in p..n {
            let mut row = vec![0.0; m];
            let mut k = 0.0;
            for (i, bi) in b.iter().enumerate() {
                let s = t - i;
                if (left..left + m).contains(&s) {
                    row[s - left] += bi;
                } else {
                    k += bi * xc[s];
                }
            }
            for j in 0..m {
                atb[j] -= row[j] * k;
                for l in 0..m {
                    ata[j][l] += row[j] * row[l];
                }
            }
        }
        // Gaussian elimination.
        for c in 0..m {
            let piv = ata[c][c];
            for rr in c + 1..m {
                let f = ata[rr][c] / piv;
                for l in c..m {
                    ata[rr][l] -= f * ata[c][l];
                }
                atb[rr] -= f * atb[c];
            }
        }
        let mut y = vec![0.0; m];
        for c in (0..m).rev() {
            let s: f64 = (c + 1..m).map(|l| ata[c][l] * y[l]).sum();
            y[c] = (atb[c] - s) / ata[c][c];
        }
        for j in 0..m {
            assert!((fast[left + j] - (y[j] + mean)).abs() < 1e-9, "sample {j}");
        }
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let mut ai = ArInterpolator::new(8, 2);
        let mut z = vec![0.0; 50];
        ai.fill(&mut z, 10, 20);
        assert!(z.iter().all(|v| *v == 0.0));
        let mut short = vec![1.0, 2.0, 0.0, 0.0, 5.0];
        ai.fill(&mut short, 2, 2);
        assert_eq!(short, vec![1.0, 2.0, 3.0, 4.0, 5.0]);
        let mut edge = vec![0.0, 0.0, 3.0];
        ai.fill(&mut edge, 0, 2);
        assert_eq!(edge, vec![3.0, 3.0, 3.0]);
        ai.fill(&mut edge, 2, 5);
    }
}
