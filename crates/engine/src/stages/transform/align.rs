//! `align`: one global motion signal from per-band signals (thesis
//! Eq. 3.5-3.6): each band is shifted by the lag that best matches a
//! reference band, then all are summed.
//!
//! Streaming: the lags are estimated once, on the first `window` samples
//! (high-passed copies, so drift does not decide the lag; ch. 4 footnote
//! 1), then held. Output waits only for the largest negative lag, plus the
//! block being assembled. Before the window is in, output is held; live
//! pipelines set `warmup` to a few blocks so that a provisional estimate on
//! the first `warmup` samples starts the sound at once, and the estimate on
//! the full window replaces it when that is in. Unlike Eq. 3.5, the lag maximises |correlation|
//! and the band is multiplied by the correlation's sign, so a band that
//! sees the motion inverted (diagonal motion, the thesis' y = -x corner
//! case) adds constructively instead of being shifted half a period.
//!
//! Weights: by default Eq. 3.6 sums the aligned bands as they are
//! (`weights = "equal"`), a fixed linear estimator that follows the SNR law
//! of Eq. 4.3. With `weights = "mrc"` each band is weighted by its
//! estimated signal gain over its noise variance (maximal-ratio combining):
//! measured +3.2 dB over the plain sum on a synthetic scene, but the
//! weights adapt to the data, so the law holds only approximately
//! (+4.4 dB instead of +6 for twice the motion). With
//! a_l = g_l s + n_l and independent band noise, the cross-covariances of
//! the aligned bands are g_l g_m var(s), so a one-factor fit gives g_l and
//! var(n_l). Bands that carry only noise (texture too weak at that scale,
//! motion orthogonal to that orientation) then get no weight. The
//! reference band, when not given, is the band most correlated with all the
//! others.
//!
//! With `weights = "principal"` no lag is searched and no reference band is
//! chosen: the output is the projection of all channels (at lag 0) on the
//! leading eigenvector of their high-passed covariance over the window.
//! For channels that carry one signal with different gains under white
//! noise of equal variance and no correlation (what `tile_motion` emits),
//! that is the maximum-likelihood combination: each channel is weighted by
//! its gain, so channels that see no motion get none. Its sign makes the
//! weights' sum positive. With `components = K > 1`, up to K leading
//! components are summed where they stand out from the noise (independent
//! sources: two strings of a guitar; see [`principal_weights`]). Power
//! iteration, from fixed starts: replays are bit-identical.

use crate::*;
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::iir::Sos;

/// How `align` combines the channels.
#[derive(serde::Deserialize, serde::Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Weights {
    Equal,
    Mrc,
    Principal,
}

params! {
    /// `align`'s parameters.
    pub struct AlignParams for "align" {
        reference_band: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(0, 1 << 16)
            .doc("band the others are aligned to; default: the most coherent one"),
        weights: Weights = ParamSpec::of(
            ParamType::Choice(&["equal", "mrc", "principal"]),
            Def::Str("equal"),
        )
        .doc("sum the aligned bands equally, by maximum-ratio combining, or project all channels (no lags) on their first principal component (for channels of equal white noise: `tile_motion`)"),
        max_lag: usize = ParamSpec::of(ParamType::Int, Def::Int(8))
            .ints(0, 4096)
            .unit("samples")
            .doc("largest lag searched"),
        window: usize = ParamSpec::of(ParamType::Int, Def::Int(2048))
            .ints(1, 1 << 22)
            .unit("samples")
            .doc("samples used to estimate the lags"),
        components: usize = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(1, MAX_COMPONENTS as i64)
            .doc("principal: leading components that may be summed (each beyond the first only where it stands out from the noise): 1 hears the strongest source, more also hear independent ones (a second string; a flickering light's residue can stand out too)"),
        warmup: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, 1 << 22)
            .unit("samples")
            .doc(
                "a provisional estimate starts the output after this many (live use); default: window",
            ),
    }
}

type P = AlignParams;

pub const KIND: KindSpec = KindSpec {
    name: "align",
    summary: "aligns per-band signals to a reference band by cross-correlation lag and sums them (Eq. 3.5-3.6)",
    inputs: &[InPort::one(&[PortType::Samples])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if let Some(w) = v.warmup {
            if w == 0 || w > v.window {
                return Err(p.error(
                    "warmup",
                    format!("must be 1..=window ({}) samples, got {w}", v.window),
                ));
            }
        }
        Ok(Box::new(AlignPlan(v)))
    },
};

struct AlignPlan(P);

impl Plan for AlignPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Align {
            p: self.0,
            channels: 0,
            hist: Vec::new(),
            hist_start: 0,
            total: 0,
            blocks: VecDeque::new(),
            shifts: None,
            train: Vec::new(),
            trained: false,
            buf: Vec::new(),
        })))
    }
}

/// Lag and signed weight per band.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Shift {
    lag: isize,
    sign: f32,
}

fn dot(a: &[f64], b: &[f64], lag: isize) -> f64 {
    // Σ_t a(t) b(t - lag)
    let mut acc = 0.0;
    for (t, &x) in a.iter().enumerate() {
        let j = t as isize - lag;
        if j >= 0 && (j as usize) < b.len() {
            acc += x * b[j as usize];
        }
    }
    acc
}

/// The band whose zero-lag correlations with all the others are largest.
fn most_coherent(bands: &[Vec<f64>]) -> usize {
    let energy: Vec<f64> = bands.iter().map(|b| dot(b, b, 0).max(1e-300)).collect();
    let score = |i: usize| -> f64 {
        (0..bands.len())
            .filter(|&j| j != i)
            .map(|j| dot(&bands[i], &bands[j], 0).abs() / (energy[i] * energy[j]).sqrt())
            .sum()
    };
    (0..bands.len())
        .max_by(|&a, &b| score(a).total_cmp(&score(b)))
        .unwrap_or(0)
}

/// One-factor fit of a covariance matrix C ≈ h hᵀ + diag(d) estimated from
/// `samples` samples: returns (h, d), h ≥ 0 entry-wise for a consistently
/// signed matrix. Iterated principal factor: h is the leading eigenvector of
/// C - diag(d) scaled by its eigenvalue's root, d = diag(C) - h².
///
/// A band whose SNR is high has d close to 0, below what N samples can
/// resolve (an off-diagonal covariance is only known to about C_ll/√N), and
/// the fit then gives it all the weight (a Heywood case). d is therefore
/// floored at 3 C_ll/√N: bands that are all clearly better than that floor
/// are combined as equals, which is what their estimates can support.
fn one_factor(c: &[Vec<f64>], samples: usize) -> (Vec<f64>, Vec<f64>) {
    let floor = 3.0 / (samples.max(1) as f64).sqrt();
    let n = c.len();
    let mut d: Vec<f64> = (0..n).map(|i| 0.5 * c[i][i]).collect();
    let mut h = vec![0.0; n];
    for _ in 0..50 {
        let m = |i: usize, j: usize| if i == j { c[i][i] - d[i] } else { c[i][j] };
        let mut v = vec![1.0 / (n as f64).sqrt(); n];
        let mut lambda = 0.0;
        for _ in 0..100 {
            let w: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| m(i, j) * v[j]).sum())
                .collect();
            let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm <= 0.0 || !norm.is_finite() {
                break;
            }
            lambda = v.iter().zip(&w).map(|(a, b)| a * b).sum();
            v = w.iter().map(|x| x / norm).collect();
        }
        let s = lambda.max(0.0).sqrt();
        let sign = if v.iter().sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        h = v.iter().map(|x| sign * s * x).collect();
        // Keep a noise floor so no band gets an unbounded weight.
        d = (0..n)
            .map(|i| (c[i][i] - h[i] * h[i]).max(floor * c[i][i]).max(1e-300))
            .collect();
    }
    (h, d)
}

/// Most components `principal` may sum (`components`).
const MAX_COMPONENTS: usize = 4;
/// Power iterations per component, at most.
const MAX_ITERATIONS: usize = 300;

fn dot0(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// The `k` leading eigenpairs (λ, unit v) of Σ_t x(t) x(t)ᵀ / n
/// (`channels[c][t]`), largest first: power iteration from fixed starts,
/// each kept orthogonal to those found before. Fewer when the channels
/// have nothing left.
fn leading_components(channels: &[Vec<f64>], k: usize) -> Vec<(f64, Vec<f64>)> {
    let c = channels.len();
    let n = channels.first().map_or(0, |x| x.len()).max(1);
    let mut found: Vec<(f64, Vec<f64>)> = Vec::new();
    let mut y = vec![0.0; n];
    let orthogonalise = |v: &mut Vec<f64>, found: &[(f64, Vec<f64>)]| {
        for (_, u) in found {
            let along = dot0(v, u);
            v.iter_mut().zip(u).for_each(|(v, u)| *v -= along * u);
        }
    };
    for j in 0..k.min(c) {
        // A start no eigenvector is likely to be orthogonal to.
        let mut v: Vec<f64> = (0..c)
            .map(|i| 1.0 + 0.5 * (i as f64 * 0.618 + j as f64 * 1.7).sin())
            .collect();
        orthogonalise(&mut v, &found);
        let norm = dot0(&v, &v).sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            break;
        }
        v.iter_mut().for_each(|x| *x /= norm);
        let mut lambda = None;
        // Converges geometrically at the ratio of the next eigenvalue to
        // this one: fast for a source above the noise. For noise alone the
        // ratio is near 1 and no direction is better than another, so the
        // iteration stops at a bound instead of at a tolerance.
        for _ in 0..MAX_ITERATIONS {
            y.iter_mut().for_each(|y| *y = 0.0);
            for (x, &vi) in channels.iter().zip(&v) {
                for (y, &x) in y.iter_mut().zip(x) {
                    *y += vi * x;
                }
            }
            let mut w: Vec<f64> = channels.iter().map(|x| dot0(x, &y) / n as f64).collect();
            orthogonalise(&mut w, &found);
            let norm = dot0(&w, &w).sqrt();
            if !(norm > 0.0 && norm.is_finite()) {
                break;
            }
            let change: f64 = w.iter().zip(&v).map(|(w, v)| (w / norm - v).abs()).sum();
            v = w.iter().map(|w| w / norm).collect();
            lambda = Some(norm);
            if change < 1e-9 * (c as f64).sqrt() {
                break;
            }
        }
        match lambda {
            Some(l) if v.iter().all(|x| x.is_finite()) => found.push((l, v)),
            _ => break,
        }
    }
    found
}

/// The `principal` weights: the sum of at most `most` leading components,
/// each signed so that its entries sum to a positive number. The first
/// always counts; a further one only when it stands out (eigenvalue over a quarter of the
/// first's and over twice the Marchenko-Pastur edge of the noise, the
/// largest eigenvalue white noise alone would give `n` samples of `c`
/// channels), so independent sources (two strings) are all heard and a
/// single one gets no noise added. Returns the weights and the eigenvalues
/// of the components summed (all ones and none when the channels are all
/// zero).
fn principal_weights(channels: &[Vec<f64>], most: usize) -> (Vec<f64>, Vec<f64>) {
    let c = channels.len();
    let n = channels.first().map_or(0, |x| x.len()).max(1);
    let comps = leading_components(channels, most.clamp(1, MAX_COMPONENTS));
    let Some(top) = comps.first().map(|c| c.0) else {
        return (vec![1.0; c], Vec::new());
    };
    let trace: f64 = channels.iter().map(|x| dot0(x, x)).sum::<f64>() / n as f64;
    // Each channel's noise variance: what the components leave, per
    // dimension they leave (an overestimate when more sources are there).
    let found: f64 = comps.iter().map(|c| c.0).sum();
    let noise = (trace - found).max(0.0) / c.saturating_sub(comps.len()).max(1) as f64;
    let edge = noise * (1.0 + (c as f64 / n as f64).sqrt()).powi(2);
    let mut w = vec![0.0; c];
    let mut used = Vec::new();
    for (k, (lambda, v)) in comps.iter().enumerate() {
        if k >= most || (k > 0 && !(*lambda > 0.25 * top && *lambda > 2.0 * edge)) {
            break;
        }
        let v = sparse(v, *lambda, noise, n, edge);
        let sign = if v.iter().sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        w.iter_mut().zip(&v).for_each(|(w, v)| *w += sign * v);
        used.push(*lambda);
    }
    (w, used)
}

/// An estimated eigenvector's entries that its sampling noise explains
/// are set to zero: those of channels the source does not move, whose
/// weights would only add noise. With a spike `ℓ = λ / noise - 1` seen in
/// `n` samples, each entry of the estimate off the true direction has a
/// standard deviation of about √((1 + ℓ) / n) / ℓ (first-order
/// perturbation); entries under 3 of those are dropped. Only for a
/// component clear of the largest eigenvalue noise alone gives (its
/// Marchenko-Pastur edge, and 10% for that eigenvalue's own fluctuation),
/// and never all of its entries. Measured on issue 14's speech scene at 0.03 px and 2 DN:
/// +0.16 dB (0.15 → 0.31 dB, the bound 0.84 dB); at 0.1 px nothing lost.
fn sparse(v: &[f64], lambda: f64, noise: f64, n: usize, edge: f64) -> Vec<f64> {
    let ell = if noise > 0.0 {
        lambda / noise - 1.0
    } else {
        0.0
    };
    if !(lambda > 1.1 * edge && ell > 0.0 && ell.is_finite()) {
        return v.to_vec();
    }
    let tau = 3.0 * ((1.0 + ell) / n as f64).sqrt() / ell;
    let kept: Vec<f64> = v
        .iter()
        .map(|&x| if x.abs() > tau { x } else { 0.0 })
        .collect();
    if kept.iter().any(|&x| x != 0.0) {
        kept
    } else {
        v.to_vec()
    }
}

struct Align {
    p: P,
    channels: usize,
    /// Interleaved samples from absolute index `hist_start` on.
    hist: Vec<f32>,
    hist_start: usize,
    /// Samples received so far.
    total: usize,
    /// Input blocks not yet emitted: (t0_ns, rate, first sample, length).
    blocks: VecDeque<(i64, f64, usize, usize)>,
    shifts: Option<Vec<Shift>>,
    /// The first `window` samples, interleaved, kept for the estimate.
    train: Vec<f32>,
    /// The estimate on the full window is done.
    trained: bool,
    buf: Vec<f32>,
}

impl Align {
    fn get(&self, n: isize, ch: usize) -> f32 {
        if n < self.hist_start as isize || n >= self.total as isize {
            return 0.0;
        }
        self.hist[(n as usize - self.hist_start) * self.channels + ch]
    }

    /// Eq. 3.5 on the training samples received so far.
    fn estimate(&mut self, rate: f64) -> Result<(), StageError> {
        let (c, n) = (self.channels, self.train.len() / self.channels.max(1));
        if let Some(r) = self.p.reference_band {
            if r >= c {
                return Err(StageError::config(
                    "reference_band",
                    format!("band {r} does not exist ({c} bands)"),
                ));
            }
        }
        let cutoff = super::highpass::default_cutoff_hz(rate);
        let principal = self.p.weights == Weights::Principal;
        let filtered: Vec<Vec<f64>> = (0..c)
            .map(|ch| {
                let mut hp = Sos::butterworth_highpass(2, cutoff, rate).ok();
                (0..n)
                    .map(|i| {
                        let x = self.train[i * c + ch] as f64;
                        hp.as_mut().map_or(x, |h| h.step(x))
                    })
                    .collect()
            })
            .collect();
        if principal {
            let (w, used) = principal_weights(&filtered, self.p.components);
            tracing::info!(
                channels = c,
                window = n,
                eigenvalues = ?used,
                "principal weights: the sum of {} leading component(s)",
                used.len()
            );
            self.shifts = Some(
                w.iter()
                    .map(|&w| Shift {
                        lag: 0,
                        sign: w as f32,
                    })
                    .collect(),
            );
            return Ok(());
        }
        let r = self
            .p
            .reference_band
            .unwrap_or_else(|| most_coherent(&filtered));
        let max_lag = self.p.max_lag as isize;
        let reference = &filtered[r];
        let mut shifts: Vec<Shift> = filtered
            .iter()
            .enumerate()
            .map(|(ch, sig)| {
                if ch == r {
                    return Shift { lag: 0, sign: 1.0 };
                }
                let mut best = (0isize, 0.0f64);
                for lag in -max_lag..=max_lag {
                    let acc = dot(reference, sig, lag);
                    if acc.abs() > best.1.abs() {
                        best = (lag, acc);
                    }
                }
                Shift {
                    lag: best.0,
                    sign: if best.1 < 0.0 { -1.0 } else { 1.0 },
                }
            })
            .collect();
        if self.p.weights == Weights::Mrc && c > 1 {
            // Covariances of the aligned bands, then maximal-ratio weights.
            let aligned: Vec<Vec<f64>> = filtered
                .iter()
                .zip(&shifts)
                .map(|(sig, sh)| {
                    (0..n)
                        .map(|t| {
                            let j = t as isize - sh.lag;
                            if j >= 0 && (j as usize) < n {
                                sh.sign as f64 * sig[j as usize]
                            } else {
                                0.0
                            }
                        })
                        .collect()
                })
                .collect();
            let cov: Vec<Vec<f64>> = (0..c)
                .map(|i| {
                    (0..c)
                        .map(|j| dot(&aligned[i], &aligned[j], 0) / n as f64)
                        .collect()
                })
                .collect();
            let (h, d) = one_factor(&cov, n);
            let w: Vec<f64> = h.iter().zip(&d).map(|(h, d)| h / d).collect();
            let wmax = w.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            for (sh, w) in shifts.iter_mut().zip(&w) {
                sh.sign *= if wmax > 0.0 { (w / wmax) as f32 } else { 1.0 };
            }
        }
        tracing::info!(
            ?shifts,
            reference = r,
            window = n,
            "band alignment (lag, signed weight)"
        );
        self.shifts = Some(shifts);
        Ok(())
    }

    /// Emits every queued block whose samples (and lagged neighbours) are in.
    fn emit_ready(&mut self, out: &mut Emitter, at_end: bool) {
        // Taken out for the loop (self.get borrows self), put back below.
        let Some(shifts) = self.shifts.take() else {
            return;
        };
        let lookahead = shifts
            .iter()
            .map(|s| (-s.lag).max(0) as usize)
            .max()
            .unwrap_or(0);
        while let Some(&(t0, rate, start, len)) = self.blocks.front() {
            if !at_end && start + len + lookahead > self.total {
                break;
            }
            self.buf.clear();
            for i in 0..len {
                let n = (start + i) as isize;
                let s: f32 = shifts
                    .iter()
                    .enumerate()
                    .map(|(ch, sh)| sh.sign * self.get(n - sh.lag, ch))
                    .sum();
                self.buf.push(s);
            }
            self.blocks.pop_front();
            let _ = out.emit(Item::Audio(AudioBlock {
                t0_ns: t0,
                rate_hz: rate,
                samples: Arc::from(&self.buf[..]),
            }));
        }
        self.shifts = Some(shifts);
        // Keep only what lagged reads can still need.
        let keep_from = self
            .blocks
            .front()
            .map_or(self.total, |b| b.2)
            .saturating_sub(self.p.max_lag);
        if keep_from > self.hist_start {
            let drop = (keep_from - self.hist_start) * self.channels;
            self.hist.drain(..drop.min(self.hist.len()));
            self.hist_start = keep_from;
        }
    }
}

impl Stage for Align {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Samples(b) = item else {
            return Err(StageError::expected("per-band samples"));
        };
        if self.channels == 0 {
            self.channels = b.channels.max(1);
        } else if b.channels != self.channels {
            return Err(StageError::format("the number of bands changed mid-stream"));
        }
        let len = b.data.len() / self.channels;
        self.hist.extend_from_slice(&b.data[..len * self.channels]);
        self.blocks.push_back((b.t0_ns, b.rate_hz, self.total, len));
        let before = self.total;
        self.total += len;
        if !self.trained {
            let want = (self.p.window - before.min(self.p.window)).min(len);
            self.train
                .extend_from_slice(&b.data[..want * self.channels]);
            let warmup = self.p.warmup.unwrap_or(self.p.window);
            if self.total >= self.p.window {
                self.estimate(b.rate_hz)?;
                self.trained = true;
                self.train = Vec::new();
            } else if self.shifts.is_none() && self.total >= warmup {
                self.estimate(b.rate_hz)?;
            }
        }
        self.emit_ready(out, false);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        if !self.trained && self.total > 0 {
            let rate = self.blocks.front().map_or(1.0, |b| b.1);
            self.estimate(rate)?;
        }
        self.emit_ready(out, true);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn align_with(hist: Vec<f32>, channels: usize) -> Align {
        let total = hist.len() / channels;
        Align {
            p: P {
                reference_band: Some(0),
                weights: Weights::Equal,
                max_lag: 8,
                window: 4096,
                components: 1,
                warmup: None,
            },
            channels,
            train: hist.clone(),
            trained: false,
            hist,
            hist_start: 0,
            total,
            blocks: VecDeque::new(),
            shifts: None,
            buf: Vec::new(),
        }
    }

    #[test]
    fn finds_lag_and_sign_of_each_band() {
        // Band 1 is band 0 delayed by 3 samples and inverted; band 2 leads by 2.
        let n = 2000;
        let s = |t: isize| {
            let t = t as f64 / 2200.0;
            ((2.0 * std::f64::consts::PI * 310.0 * t).sin()
                + 0.5 * (2.0 * std::f64::consts::PI * 730.0 * t).sin()) as f32
        };
        let mut hist = Vec::with_capacity(3 * n);
        for i in 0..n as isize {
            hist.extend_from_slice(&[s(i), -s(i - 3), s(i + 2)]);
        }
        let mut a = align_with(hist, 3);
        a.estimate(2200.0).unwrap();
        let sh = a.shifts.unwrap();
        assert_eq!(
            sh[1],
            Shift {
                lag: -3,
                sign: -1.0
            }
        );
        assert_eq!(sh[2], Shift { lag: 2, sign: 1.0 });
    }

    /// Gaussian samples from a fixed seed.
    fn gauss(seed: u64) -> impl FnMut() -> f64 {
        let mut rng = seed;
        move || {
            let mut u = || {
                rng = rng
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((rng >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
        }
    }

    /// Channels `gains[k][c] s_k + 0.3 n_c` for independent unit sources.
    fn mixed(gains: &[&[f64]], n: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut g = gauss(seed);
        let c = gains[0].len();
        let mut ch = vec![Vec::with_capacity(n); c];
        for _ in 0..n {
            let s: Vec<f64> = gains.iter().map(|_| 3.0 * g()).collect();
            for (i, ch) in ch.iter_mut().enumerate() {
                let sig: f64 = gains.iter().zip(&s).map(|(gk, s)| gk[i] * s).sum();
                ch.push(sig + 0.3 * g());
            }
        }
        ch
    }

    #[test]
    fn principal_weights_follow_each_channels_gain() {
        // Channels 0 and 1 carry one signal with gains 1 and -0.5, the
        // other three only noise, all with the same white noise.
        let gains = [1.0, -0.5, 0.0, 0.0, 0.0];
        let (v, used) = principal_weights(&mixed(&[&gains], 20000, 12345), 4);
        assert_eq!(used.len(), 1, "{used:?}");
        let norm = gains.iter().map(|g| g * g).sum::<f64>().sqrt();
        for (v, g) in v.iter().zip(gains) {
            assert!((v - g / norm).abs() < 0.02, "{v} vs {}", g / norm);
        }
        // Noise alone: one component (the first always counts), no more.
        let (_, used) = principal_weights(&mixed(&[&[0.0; 6]], 4000, 7), 4);
        assert_eq!(used.len(), 1, "{used:?}");
        // Two independent sources on channels 0-1 and 2-3: both are summed.
        let two = mixed(
            &[&[1.0, 0.8, 0.0, 0.0, 0.0], &[0.0, 0.0, 0.7, -0.7, 0.0]],
            20000,
            3,
        );
        let (v, used) = principal_weights(&two, 4);
        assert_eq!(used.len(), 2, "{used:?}");
        assert!(
            v[..4].iter().all(|w| w.abs() > 0.5) && v[4].abs() < 0.05,
            "{v:?}"
        );
        // One asked for: the stronger only.
        let (v, used) = principal_weights(&two, 1);
        assert_eq!(used.len(), 1, "{used:?}");
        assert!(v[2].abs() < 0.05 && v[3].abs() < 0.05, "{v:?}");
        // No signal at all: equal weights, no NaN.
        assert_eq!(
            principal_weights(&[vec![0.0; 8], vec![0.0; 8]], 4).0,
            [1.0, 1.0]
        );
    }

    #[test]
    fn weights_of_channels_the_source_does_not_move_are_dropped() {
        // Three channels see the source, sixty only noise.
        let mut gains = vec![0.0; 63];
        gains[..3].copy_from_slice(&[1.0, 0.7, -0.5]);
        let (w, _) = principal_weights(&mixed(&[&gains], 2000, 11), 1);
        assert!(w[..3].iter().all(|w| w.abs() > 0.3), "{:?}", &w[..3]);
        // Sampling noise passes 3 sigma for 0.3% of them.
        let kept = w[3..].iter().filter(|w| **w != 0.0).count();
        assert!(kept <= 3, "{kept} of 60 noise channels kept");
        // Noise alone is under the edge: nothing is dropped.
        let (w, _) = principal_weights(&mixed(&[&[0.0; 20]], 2000, 5), 1);
        assert!(w.iter().all(|w| *w != 0.0), "{w:?}");
    }

    #[test]
    fn missing_reference_band_is_an_error() {
        let mut a = align_with(vec![0.0; 20], 2);
        a.p.reference_band = Some(5);
        assert!(a.estimate(100.0).is_err());
    }
}
