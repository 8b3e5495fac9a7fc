//! Time-domain damping: covariance-driven stochastic subspace identification
//! (SSI-cov; Peeters & De Roeck 1999), for modes too lightly damped for the
//! spectrum's bins to resolve.
//!
//! The output correlations R(k) of a linear system driven by white noise
//! (or ringing down after a strike) are sums of decaying exponentials whose
//! poles are the system's: R(k) = C Aᵏ G. Stacked into the block Toeplitz
//! matrix T[a][b] = R(i + a - b) (a, b = 0..i), T = O Γ factors into the
//! observability matrix O = [C; CA; ...; CA^{i-1}] and a controllability
//! matrix, so an SVD truncated to order n gives O = U_n S_n^{1/2}, and A
//! solves O[1..i] = O[0..i-1] A in least squares. Each eigenvalue λ of A is
//! a discrete pole; s = fs ln λ is the continuous one, with natural
//! frequency |s| / 2π and damping ratio ξ = -Re s / |s|.
//!
//! The model order is not known, so poles are computed for every even order
//! up to `max_order` (a **stabilisation diagram**): a pole is *stable* when
//! the next lower order has one within `err_f` in frequency and `err_xi` in
//! damping. Noise poles wander with the order, physical ones stay. A peak's
//! estimate is the median over the stable poles near its frequency; its
//! uncertainty combines the spread over orders with the spread over
//! `segments` independent parts of the record (divided by √segments).
//!
//! Correlations are the full sums R(k) = Σ_t y(t+k) y(t) / N (computed by
//! FFT). For a stationary random response this biases the decay rate by
//! 1/T (relative 1/(σT), far below the statistical floor √(2/(σT)) of any
//! estimate from T seconds); for a free decay after a strike (an energy
//! signal) it is exact, where the unbiased 1/(N-k) form would bias σ by -1/T.

use crate::numeric::median;
use nalgebra::{DMatrix, Schur, SVD};
use realfft::RealFftPlanner;

/// Choices of the identification.
#[derive(Clone, Debug)]
pub struct SsiOptions {
    /// Highest model order (even); orders 2, 4, ..., `max_order` are tried.
    pub max_order: usize,
    /// Block rows i; `None`: about four periods of the target frequency,
    /// at least `max_order + 10` and at most [`MAX_BLOCK_ROWS`].
    pub block_rows: Option<usize>,
    /// Poles damped more than this are not physical modes.
    pub max_damping: f64,
    /// Stability: relative frequency change to the next lower order.
    pub err_f: f64,
    /// Stability: relative damping change to the next lower order.
    pub err_xi: f64,
    /// Independent parts of the record for the statistical uncertainty.
    pub segments: usize,
}

/// Iteration bound of the SVD and Schur decompositions.
const MAX_ITER: usize = 10_000;

/// Upper bound on the automatic block rows (the SVD is i × i).
pub const MAX_BLOCK_ROWS: usize = 400;

impl Default for SsiOptions {
    fn default() -> Self {
        Self {
            max_order: 40,
            block_rows: None,
            max_damping: 0.2,
            err_f: 0.01,
            err_xi: 0.05,
            segments: 4,
        }
    }
}

/// One pole of one model order.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Pole {
    pub order: usize,
    /// Undamped natural frequency |s| / 2π (Hz).
    pub frequency_hz: f64,
    pub damping_ratio: f64,
    /// Stable against the next lower order.
    pub stable: bool,
}

/// A mode identified near a target frequency.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SsiMode {
    pub frequency_hz: f64,
    pub damping_ratio: f64,
    /// The spreads over orders and segments combined; NaN (JSON null)
    /// when neither exists (one stable order and fewer than two segments):
    /// the estimate's uncertainty is then unknown, not zero.
    pub damping_ratio_std: f64,
    /// Spread (robust standard deviation) over the stable orders (0 for
    /// one order).
    pub order_std: f64,
    /// Standard deviation over the record's segments, over √segments
    /// (`None` when the record is too short for two segments of 8 block
    /// rows, or fewer than two found the mode: the uncertainty is then only
    /// the spread over orders, which understates it).
    pub segment_std: Option<f64>,
    /// How many stable orders agreed, and the block rows used.
    pub stable_orders: usize,
    pub block_rows: usize,
}

/// R(k) = Σ_t y(t+k) y(t) / N for k = 0..=max_lag, mean removed, by FFT.
pub fn autocorrelation(y: &[f64], max_lag: usize) -> Vec<f64> {
    let n = y.len();
    if n == 0 {
        return vec![0.0; max_lag + 1];
    }
    let mean = y.iter().sum::<f64>() / n as f64;
    let m = (n + max_lag + 1).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(m);
    let inv = planner.plan_fft_inverse(m);
    let mut buf = vec![0.0; m];
    for (b, v) in buf.iter_mut().zip(y) {
        *b = v - mean;
    }
    let mut spec = fwd.make_output_vec();
    if fwd.process(&mut buf, &mut spec).is_err() {
        return vec![0.0; max_lag + 1];
    }
    for c in spec.iter_mut() {
        *c = realfft::num_complex::Complex::new(c.norm_sqr(), 0.0);
    }
    if inv.process(&mut spec, &mut buf).is_err() {
        return vec![0.0; max_lag + 1];
    }
    let scale = 1.0 / (m as f64 * n as f64);
    (0..=max_lag)
        .map(|k| buf.get(k).map_or(0.0, |v| v * scale))
        .collect()
}

/// Poles for orders 2, 4, ..., `max_order` from correlations `r` (at least
/// 2i lags) with `i` block rows, each marked stable or not.
pub fn stabilisation(r: &[f64], fs: f64, i: usize, opts: &SsiOptions) -> Vec<Pole> {
    if i < 3 || r.len() < 2 * i || !(fs.is_finite() && fs > 0.0) {
        return Vec::new();
    }
    let t = DMatrix::from_fn(i, i, |a, b| r[i + a - b]);
    if !t.iter().all(|v| v.is_finite()) {
        return Vec::new();
    }
    // Bounded iterations: nalgebra's plain `svd` and Schur loop until
    // convergence, which degenerate input may never reach.
    let Some(svd) = SVD::try_new(t, true, false, f64::EPSILON, MAX_ITER) else {
        return Vec::new();
    };
    let Some(u) = svd.u else {
        return Vec::new();
    };
    let top = svd.singular_values.max();
    if !(top > 0.0 && top.is_finite()) {
        return Vec::new();
    }
    // nalgebra does not promise sorted singular values: order them.
    let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
    idx.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
    let max_order = opts.max_order.min(i - 1) & !1;
    let mut all: Vec<Pole> = Vec::new();
    let mut prev: Vec<Pole> = Vec::new();
    for n in (2..=max_order).step_by(2) {
        let o = DMatrix::from_fn(i, n, |row, c| {
            u[(row, idx[c])] * svd.singular_values[idx[c]].max(0.0).sqrt()
        });
        let up = o.rows(0, i - 1).clone_owned();
        let down = o.rows(1, i - 1).clone_owned();
        let Some(a) = SVD::try_new(up, true, true, f64::EPSILON, MAX_ITER)
            .and_then(|s| s.solve(&down, 1e-12 * top).ok())
        else {
            continue;
        };
        let Some(schur) = Schur::try_new(a, f64::EPSILON, MAX_ITER) else {
            continue;
        };
        let mut cur = Vec::new();
        for lam in schur.complex_eigenvalues().iter() {
            if lam.im <= 0.0 || !lam.re.is_finite() {
                continue;
            }
            let s = lam.ln() * fs;
            let wn = s.norm();
            let xi = -s.re / wn;
            if !(wn > 0.0 && xi > 0.0 && xi < opts.max_damping) {
                continue;
            }
            let f = wn / (2.0 * std::f64::consts::PI);
            let stable = prev.iter().any(|p| {
                (p.frequency_hz - f).abs() < opts.err_f * f
                    && (p.damping_ratio - xi).abs() < opts.err_xi * xi
            });
            cur.push(Pole {
                order: n,
                frequency_hz: f,
                damping_ratio: xi,
                stable,
            });
        }
        all.extend_from_slice(&cur);
        prev = cur;
    }
    all
}

/// Block rows for a target frequency: about four periods.
pub fn block_rows_for(fs: f64, target_hz: f64, opts: &SsiOptions) -> usize {
    if let Some(i) = opts.block_rows {
        return i;
    }
    let periods = (4.0 * fs / target_hz.max(1e-9)).ceil();
    let lo = opts.max_order + 10;
    (periods.min(MAX_BLOCK_ROWS as f64) as usize).max(lo)
}

/// Median of stable poles within `tol_hz` of `target_hz`, one per order (the
/// closest), as (frequency, damping, robust spread of damping, count).
fn near(poles: &[Pole], target_hz: f64, tol_hz: f64) -> Option<(f64, f64, f64, usize)> {
    let mut best: Vec<Pole> = Vec::new();
    for p in poles
        .iter()
        .filter(|p| p.stable && (p.frequency_hz - target_hz).abs() <= tol_hz)
    {
        match best.iter_mut().find(|b| b.order == p.order) {
            Some(b) => {
                if (p.frequency_hz - target_hz).abs() < (b.frequency_hz - target_hz).abs() {
                    *b = *p;
                }
            }
            None => best.push(*p),
        }
    }
    if best.is_empty() {
        return None;
    }
    let f = median(&mut best.iter().map(|p| p.frequency_hz).collect::<Vec<_>>());
    let xs: Vec<f64> = best.iter().map(|p| p.damping_ratio).collect();
    let xi = median(&mut xs.clone());
    let mad = median(&mut xs.iter().map(|x| (x - xi).abs()).collect::<Vec<_>>());
    Some((f, xi, 1.4826 * mad, best.len()))
}

/// Stable poles that agree on one mode (issue 51): their mean and spread.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PoleCluster {
    pub frequency_hz: f64,
    pub frequency_std_hz: f64,
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
    /// Model orders with a pole in it (one pole counted per order).
    pub orders: usize,
}

/// The stable poles of `poles` clustered into modes: sorted by frequency,
/// a pole joins the cluster before it when within `rel_tol` of its mean
/// frequency (and ties at one pole per order, the nearest kept); clusters
/// with poles at fewer than `min_orders` orders are spurious and left out.
/// Strongest evidence (most orders) first.
pub fn cluster_poles(poles: &[Pole], rel_tol: f64, min_orders: usize) -> Vec<PoleCluster> {
    let mut stable: Vec<&Pole> = poles
        .iter()
        .filter(|p| p.stable && p.frequency_hz.is_finite() && p.damping_ratio.is_finite())
        .collect();
    stable.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
    let mut groups: Vec<Vec<&Pole>> = Vec::new();
    for p in stable {
        let joins = groups.last().is_some_and(|g| {
            let mean = g.iter().map(|q| q.frequency_hz).sum::<f64>() / g.len() as f64;
            (p.frequency_hz - mean).abs() <= rel_tol * mean
        });
        if joins {
            let g = groups.last_mut().expect("a last group");
            let mean = g.iter().map(|q| q.frequency_hz).sum::<f64>() / g.len() as f64;
            match g.iter_mut().find(|q| q.order == p.order) {
                Some(q) => {
                    if (p.frequency_hz - mean).abs() < (q.frequency_hz - mean).abs() {
                        *q = p;
                    }
                }
                None => g.push(p),
            }
        } else {
            groups.push(vec![p]);
        }
    }
    let stats = |v: Vec<f64>| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let var = if v.len() > 1 {
            v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            f64::NAN
        };
        (m, var.sqrt())
    };
    let mut out: Vec<PoleCluster> = groups
        .into_iter()
        .filter(|g| g.len() >= min_orders.max(1))
        .map(|g| {
            let (f, fs) = stats(g.iter().map(|p| p.frequency_hz).collect());
            let (z, zs) = stats(g.iter().map(|p| p.damping_ratio).collect());
            PoleCluster {
                frequency_hz: f,
                frequency_std_hz: fs,
                damping_ratio: z,
                damping_ratio_std: zs,
                orders: g.len(),
            }
        })
        .collect();
    out.sort_by(|a, b| {
        b.orders
            .cmp(&a.orders)
            .then(a.frequency_hz.total_cmp(&b.frequency_hz))
    });
    out
}

/// The damping's uncertainty from the spread over `orders` stable orders
/// and over segments: NaN when there is neither (one order, under two
/// segments), since one estimate says nothing of its own error.
fn combined_std(order_std: f64, orders: usize, segment_std: Option<f64>) -> f64 {
    if orders < 2 && segment_std.is_none() {
        f64::NAN
    } else {
        order_std.hypot(segment_std.unwrap_or(0.0))
    }
}

/// SSI-cov around one resonance: the mode nearest `target_hz` (within
/// `tol_hz`) among the stable poles of the whole record, with its
/// uncertainty. `None` when no stable pole is near.
pub fn identify(
    y: &[f64],
    fs: f64,
    target_hz: f64,
    tol_hz: f64,
    opts: &SsiOptions,
) -> Option<SsiMode> {
    let i = block_rows_for(fs, target_hz, opts);
    if y.len() < 8 * i {
        return None;
    }
    let r = autocorrelation(y, 2 * i);
    let (f, xi, order_std, count) = near(&stabilisation(&r, fs, i, opts), target_hz, tol_hz)?;
    // Statistical spread: the same identification on independent parts.
    // As many segments as allowed that are still 8 block rows long.
    let m = opts.segments.min(y.len() / (8 * i));
    let seg_len = y.len() / m.max(1);
    let mut seg = Vec::new();
    if m >= 2 {
        for s in 0..m {
            let r = autocorrelation(&y[s * seg_len..(s + 1) * seg_len], 2 * i);
            if let Some((_, x, _, _)) = near(&stabilisation(&r, fs, i, opts), f, tol_hz) {
                seg.push(x);
            }
        }
    }
    let segment_std = (seg.len() >= 2).then(|| {
        let mean = seg.iter().sum::<f64>() / seg.len() as f64;
        let var = seg.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (seg.len() - 1) as f64;
        (var / m as f64).sqrt()
    });
    Some(SsiMode {
        frequency_hz: f,
        damping_ratio: xi,
        damping_ratio_std: combined_std(order_std, count, segment_std),
        order_std,
        segment_std,
        stable_orders: count,
        block_rows: i,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One stable order and no segments: the uncertainty is unknown, not
    /// the 0 the single order's spread would give.
    #[test]
    fn one_estimate_has_no_uncertainty_to_give() {
        assert!(combined_std(0.0, 1, None).is_nan());
        assert_eq!(combined_std(0.0, 1, Some(0.002)), 0.002);
        assert_eq!(combined_std(0.003, 4, None), 0.003);
        assert!((combined_std(0.003, 4, Some(0.004)) - 0.005).abs() < 1e-15);
    }

    /// A noiseless ring-down of two modes: poles recovered to 1e-6.
    #[test]
    fn free_decay_poles_are_exact() {
        let fs = 300.0;
        let modes = [(58.3, 0.002), (128.0, 0.005)];
        let y: Vec<f64> = (0..3000)
            .map(|n| {
                let t = n as f64 / fs;
                modes
                    .iter()
                    .map(|&(f, xi)| {
                        let w = 2.0 * std::f64::consts::PI * f;
                        (-xi * w * t).exp() * (w * (1.0f64 - xi * xi).sqrt() * t).sin()
                    })
                    .sum::<f64>()
            })
            .collect();
        for (f, xi) in modes {
            let m = identify(&y, fs, f, 1.0, &SsiOptions::default()).expect("mode found");
            assert!((m.frequency_hz - f).abs() < 1e-4 * f, "{m:?}");
            assert!((m.damping_ratio - xi).abs() < 1e-3 * xi, "{m:?}");
        }
    }

    #[test]
    fn autocorrelation_matches_direct_sum() {
        let y: Vec<f64> = (0..257).map(|k| ((k * 37 % 101) as f64).sin()).collect();
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        let r = autocorrelation(&y, 10);
        for (k, rk) in r.iter().enumerate() {
            let d: f64 = (0..y.len() - k)
                .map(|t| (y[t + k] - mean) * (y[t] - mean))
                .sum::<f64>()
                / y.len() as f64;
            assert!((rk - d).abs() < 1e-9, "lag {k}: {rk} vs {d}");
        }
    }

    #[test]
    fn degenerate_input_finds_nothing() {
        let o = SsiOptions::default();
        assert!(identify(&[], 300.0, 50.0, 1.0, &o).is_none());
        assert!(identify(&[0.0; 10000], 300.0, 50.0, 1.0, &o).is_none());
        assert!(identify(&[f64::NAN; 10000], 300.0, 50.0, 1.0, &o).is_none());
    }

    /// Two modes' stable poles over many orders cluster into two modes with
    /// their means; a pole seen at one order only is left out.
    #[test]
    fn stable_poles_cluster_into_modes() {
        let fs = 300.0;
        let y: Vec<f64> = (0..3000)
            .map(|n| {
                let t = n as f64 / fs;
                [(58.3, 0.002), (128.0, 0.005)]
                    .iter()
                    .map(|&(f, xi): &(f64, f64)| {
                        let w = 2.0 * std::f64::consts::PI * f;
                        (-xi * w * t).exp() * (w * (1.0 - xi * xi).sqrt() * t).sin()
                    })
                    .sum::<f64>()
            })
            .collect();
        let o = SsiOptions::default();
        let i = block_rows_for(fs, 58.3, &o);
        let mut poles = stabilisation(&autocorrelation(&y, 2 * i), fs, i, &o);
        poles.push(Pole {
            order: 4,
            frequency_hz: 90.0,
            damping_ratio: 0.01,
            stable: true,
        });
        let c = cluster_poles(&poles, 0.01, 3);
        assert!(
            c.iter()
                .any(|c| (c.frequency_hz - 58.3).abs() < 0.01 && c.orders >= 3),
            "{c:?}"
        );
        assert!(
            c.iter().any(|c| (c.frequency_hz - 128.0).abs() < 0.01),
            "{c:?}"
        );
        assert!(
            c.iter().all(|c| (c.frequency_hz - 90.0).abs() > 1.0),
            "{c:?}"
        );
        assert!(cluster_poles(&[], 0.01, 3).is_empty());
    }
}
