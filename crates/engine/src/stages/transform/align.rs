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

use crate::*;
use serde::Deserialize;
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::iir::Sos;

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum Weights {
    Equal,
    Mrc,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    reference_band: Option<usize>,
    weights: Weights,
    max_lag: usize,
    window: usize,
    warmup: Option<usize>,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::new("reference_band", ParamType::Int, Def::Optional)
        .ints(0, 1 << 16)
        .doc("band the others are aligned to; default: the most coherent one"),
    ParamSpec::new(
        "weights",
        ParamType::Choice(&["equal", "mrc"]),
        Def::Str("equal"),
    )
    .doc("sum the aligned bands equally, or by maximum-ratio combining"),
    ParamSpec::new("max_lag", ParamType::Int, Def::Int(8))
        .ints(0, 4096)
        .unit("samples")
        .doc("largest lag searched"),
    ParamSpec::new("window", ParamType::Int, Def::Int(2048))
        .ints(1, 1 << 22)
        .unit("samples")
        .doc("samples used to estimate the lags"),
    ParamSpec::new("warmup", ParamType::Int, Def::Optional)
        .ints(1, 1 << 22)
        .unit("samples")
        .doc(
            "a provisional estimate starts the output after this many (live use); default: window",
        ),
];

pub const KIND: KindSpec = KindSpec {
    name: "align",
    summary: "aligns per-band signals to a reference band by cross-correlation lag and sums them (Eq. 3.5-3.6)",
    inputs: &[InPort::one(&[PortType::Samples])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: PARAMS,
    plan: |p| {
        let v: P = p.resolve(PARAMS)?;
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

    #[test]
    fn missing_reference_band_is_an_error() {
        let mut a = align_with(vec![0.0; 20], 2);
        a.p.reference_band = Some(5);
        assert!(a.estimate(100.0).is_err());
    }
}
