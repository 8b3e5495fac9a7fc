//! Streaming single-channel noise reduction for recovered audio.
//!
//! The visual microphone leaves broadband noise on the recovered motion signal, and the
//! thesis (ch. 4.2.1) cleans it with one of two classic denoisers; both are implemented
//! here as causal, fixed-latency stream processors:
//!
//! * [`SpectralSubtraction`], magnitude spectral subtraction (Boll 1979) with Berouti's
//!   over-subtraction factor `alpha` and spectral floor `beta` — the choice when accuracy
//!   of the waveform matters,
//! * [`SpeechEnhance`], the Bayesian MMSE log-spectral-amplitude estimator (Ephraim &
//!   Malah 1985) with the decision-directed a-priori SNR — the perceptually motivated
//!   choice when intelligibility matters (the family of Loizou 2005).
//!
//! # Signal path
//!
//! Both share one short-time Fourier transform with weighted overlap-add. A frame is the
//! power of two nearest (in the logarithmic sense) to [`DenoiseConfig::frame_ms`] at the
//! stream rate, e.g. 256 samples at 8 kHz and 64 samples at 2200 Hz for the default
//! 32 ms, and the hop is a half or a quarter of it ([`DenoiseConfig::overlap`]). The
//! analysis window is the periodic Hann window (75 % overlap) or its square root (50 %
//! overlap); the synthesis window is the analysis window divided by the overlapped sum
//! of squared analysis windows, so that analysis followed by synthesis with unit gains
//! reconstructs the input exactly (to rounding). Gains are real, so the noisy phase is
//! kept.
//!
//! # Noise tracking
//!
//! The noise power spectrum is tracked while streaming, without looking ahead, by
//! minimum statistics with optimal smoothing (Martin 2001): a per-bin recursively
//! smoothed periodogram whose smoothing constant drops where the signal rises above the
//! noise estimate, its minimum over a sliding window of [`DenoiseConfig::noise_window_s`]
//! (default 1.5 s, kept as 8 sub-windows), a bias correction computed from the running
//! variance of the smoothed periodogram, and Martin's fast rise when the noise floor
//! steps up. Martin's constants, stated for 16 ms hops, are converted to time constants
//! so that the tracker behaves the same at any rate and overlap. The first 0.1 s of
//! full frames only average the periodogram (a short bootstrap that assumes the stream
//! starts with noise, like the noise-only lead of batch implementations); minimum
//! tracking takes over after that, so a signal present from the first sample is
//! suppressed as noise until its first pause. A recording can do better: `prime`
//! (on each denoiser) warms the tracker on the stream's first seconds, which are then
//! fed again from the start, so the noise floor at the start is a true minimum. The
//! frames that still overlap the implicit zeros before the stream start (the first
//! `frame - hop` samples) pass with unit gain. A noise floor that falls is followed within a fraction of a second, one that rises
//! within about one window length plus one sub-window.
//!
//! Minimum statistics treats anything stationary over the window as noise: a steady tone
//! that lasts longer than the window is suppressed like hum. Speech, and any signal that
//! leaves every frequency band quiet for a moment within each window, passes.
//!
//! # Streaming and latency
//!
//! [`SpectralSubtraction::process`] / [`SpeechEnhance::process`] accept blocks of any
//! size; the output is identical bit for bit however the input is split. Output sample
//! `k` is the estimate of input sample `k`, released exactly `latency_samples()` (one
//! frame) samples later: after `T` input samples in total, exactly
//! `T.saturating_sub(latency_samples())` output samples have been appended. `finish`
//! zero-pads the tail, appends the remaining samples (so the total output length equals
//! the total input length) and returns the processor to its freshly constructed state,
//! ready for a new stream. Once constructed, neither call allocates except to grow the
//! caller's `out` vector.
//!
//! # Robustness
//!
//! Construction validates the configuration and returns a [`DenoiseError`]; processing
//! never panics. Non-finite input samples are treated as zeros, and output samples are
//! clamped to the finite `f32` range.

use std::collections::VecDeque;
use std::f64::consts::PI;
use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

/// Smallest accepted frame, in samples (the requested `frame_ms * rate` must reach it).
pub const MIN_FRAME_SAMPLES: usize = 8;
/// Largest frame, in samples; longer requests are rejected to bound memory.
pub const MAX_FRAME_SAMPLES: usize = 1 << 20;
/// Longest accepted noise-tracking window, in seconds.
pub const MAX_NOISE_WINDOW_S: f64 = 600.0;
/// Default over-subtraction factor of [`SpectralSubtraction`].
pub const DEFAULT_ALPHA: f64 = 2.0;
/// Default spectral floor of [`SpectralSubtraction`].
pub const DEFAULT_BETA: f64 = 0.02;

/// Errors from constructing a denoiser.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DenoiseError {
    /// The sample rate is zero, negative or not finite.
    #[error("sample rate must be finite and positive, got {0} Hz")]
    InvalidRate(f64),
    /// The frame duration is zero, negative or not finite.
    #[error("frame duration must be finite and positive, got {0} ms")]
    InvalidFrameMs(f64),
    /// The overlap is neither 0.5 nor 0.75.
    #[error("overlap must be 0.5 or 0.75, got {0}")]
    InvalidOverlap(f64),
    /// `frame_ms * rate` is shorter than [`MIN_FRAME_SAMPLES`].
    #[error("frame of {length} samples is shorter than the minimum of {MIN_FRAME_SAMPLES}")]
    FrameTooShort {
        /// Requested frame length in samples, `frame_ms * rate / 1000`.
        length: f64,
    },
    /// The frame rounds to more than [`MAX_FRAME_SAMPLES`].
    #[error("frame of {length} samples is longer than the maximum of {MAX_FRAME_SAMPLES}")]
    FrameTooLong {
        /// Requested frame length in samples, `frame_ms * rate / 1000`.
        length: f64,
    },
    /// Some other parameter is out of its range.
    #[error("parameter {name} = {value} is invalid: {expected}")]
    InvalidParameter {
        /// Name of the parameter.
        name: &'static str,
        /// Value given.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
}

/// Configuration shared by [`SpectralSubtraction`] and [`SpeechEnhance`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenoiseConfig {
    /// Target frame duration in milliseconds; the frame is the power of two nearest to
    /// it at the stream rate. Default 32 ms.
    pub frame_ms: f64,
    /// Frame overlap, 0.5 (square-root Hann windows) or 0.75 (Hann windows). Default 0.75.
    pub overlap: f64,
    /// Length of the minimum-statistics window of the noise tracker in seconds, in
    /// `(0, 600]`. Default 1.5 s.
    pub noise_window_s: f64,
    /// [`SpeechEnhance`] and [`Wiener`] only: weight of the previous frame in the
    /// decision-directed a-priori SNR, in `[0, 1)`. Default 0.98 ([`DenoiseConfig::wiener`]:
    /// [`WIENER_DD_ALPHA`]).
    pub dd_alpha: f64,
    /// [`SpeechEnhance`] and [`Wiener`] only: lower bound of the a-priori SNR in dB (finite, at most
    /// 0). Default -25 dB.
    pub xi_min_db: f64,
}

/// The decision-directed weight [`SpeechEnhance`] uses by default ([`DenoiseConfig`]'s
/// default): Ephraim & Malah's 0.98.
pub const LSA_DD_ALPHA: f64 = 0.98;

/// The decision-directed weight [`Wiener`] uses by default. The LSA gain's 0.98
/// (Ephraim & Malah's choice, for little musical noise) smooths the a-priori SNR over
/// about 50 frames; the Wiener gain is judged by squared error, which a faster prior
/// lowers: on four rendered speech scenes whose recovered SNR ranged from -15 to +8 dB,
/// 0.9 raised the denoised SNR by 0.5 to 1.6 dB over 0.98, and none of 0.95, 0.85, 0.8
/// or 0.7 was better on all four (docs/engine.md, "Denoisers").
pub const WIENER_DD_ALPHA: f64 = 0.9;

impl DenoiseConfig {
    /// The default configuration with [`WIENER_DD_ALPHA`]: what [`Wiener::with_defaults`]
    /// and the `wiener` stage kind use.
    pub fn wiener() -> Self {
        Self {
            dd_alpha: WIENER_DD_ALPHA,
            ..Self::default()
        }
    }
}

impl Default for DenoiseConfig {
    fn default() -> Self {
        Self {
            frame_ms: 32.0,
            overlap: 0.75,
            noise_window_s: 1.5,
            dd_alpha: LSA_DD_ALPHA,
            xi_min_db: -25.0,
        }
    }
}

fn invalid(name: &'static str, value: f64, expected: &'static str) -> DenoiseError {
    DenoiseError::InvalidParameter {
        name,
        value,
        expected,
    }
}

// ---------------------------------------------------------------------------------------
// Exponential integral
// ---------------------------------------------------------------------------------------

/// The exponential integral `E1(x) = ∫_x^∞ e^-t / t dt` for real `x > 0`.
///
/// Power series `-γ - ln x - Σ_{k≥1} (-x)^k / (k k!)` for `x <= 1`, the continued fraction
/// `e^-x / (x + 1 - 1² / (x + 3 - 2² / (x + 5 - ...)))` evaluated by the modified Lentz
/// method for `x > 1`; relative accuracy about 1e-15. Returns `+inf` at 0, `NaN` for
/// negative or `NaN` input and 0 where `e^-x` underflows.
pub fn expint_e1(x: f64) -> f64 {
    const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;
    const MAX_TERMS: usize = 500;
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::INFINITY;
    }
    if x <= 1.0 {
        // Σ_{k≥1} (-1)^(k+1) x^k / (k k!), subtracted from -γ - ln x.
        let mut term = 1.0; // (-1)^(k+1) x^k / k!
        let mut sum = 0.0;
        for k in 1..MAX_TERMS {
            let kf = k as f64;
            term *= if k == 1 { x } else { -x / kf };
            let add = term / kf;
            sum += add;
            if add.abs() <= f64::EPSILON * sum.abs() {
                break;
            }
        }
        return -EULER_GAMMA - x.ln() + sum;
    }
    if x > 745.0 {
        return 0.0;
    }
    // Modified Lentz for b0 + a1/(b1 + a2/(b2 + ...)) with b_i = x + 2i + 1, a_i = -i².
    const TINY: f64 = 1e-300;
    let mut b = x + 1.0;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..MAX_TERMS {
        let a = -((i * i) as f64);
        b += 2.0;
        d = a * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + a / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = c * d;
        h *= delta;
        if (delta - 1.0).abs() <= f64::EPSILON {
            break;
        }
    }
    h * (-x).exp()
}

// ---------------------------------------------------------------------------------------
// Noise tracker: minimum statistics with optimal smoothing (Martin 2001)
// ---------------------------------------------------------------------------------------

/// Smallest noise power the tracker reports; keeps SNR ratios finite on digital silence.
const NOISE_FLOOR: f64 = 1e-300;
/// Number of sub-windows of the minimum search (Martin's `U`).
const SUBWINDOWS: usize = 8;
/// Martin's `a_v`, scale of the global bias correction `B_c`.
const AV: f64 = 2.12;
/// Bootstrap duration: the first full frames only average the periodogram.
const BOOTSTRAP_S: f64 = 0.1;
/// Martin's constants as time constants (his values at a 16 ms hop in brackets).
const TAU_ALPHA_MAX_S: f64 = 0.392; // alpha_max (0.96)
const TAU_ALPHA_MIN_S: f64 = 0.0133; // alpha_min (0.3)
const TAU_BETA_MAX_S: f64 = 0.0717; // beta_max (0.8)
const TAU_ALPHA_C_S: f64 = 0.0449; // smoothing of the correction alpha_c (0.7)
/// Fast-rise thresholds on the mean inverse equivalent degrees of freedom, and the
/// allowed noise slope in dB/s for each (8, 4, 2, 1.2 per 192 ms sub-window in Martin).
const SLOPE_QINV: [f64; 3] = [0.03, 0.05, 0.06];
const SLOPE_DB_PER_S: [f64; 4] = [47.0, 31.4, 15.7, 4.1];
/// Martin's table of `M(D)` for the bias of the minimum of `D` smoothed periodograms.
const M_TABLE: [(f64, f64); 14] = [
    (1.0, 0.0),
    (2.0, 0.26),
    (5.0, 0.48),
    (8.0, 0.58),
    (10.0, 0.61),
    (15.0, 0.668),
    (20.0, 0.705),
    (30.0, 0.762),
    (40.0, 0.8),
    (60.0, 0.841),
    (80.0, 0.865),
    (120.0, 0.89),
    (140.0, 0.9),
    (160.0, 0.91),
];

/// `M(D)` by linear interpolation in Martin's table, constant beyond its ends.
fn m_of_d(d: f64) -> f64 {
    let mut prev = M_TABLE[0];
    if d.is_nan() || d <= prev.0 {
        return prev.1;
    }
    for &(dk, mk) in &M_TABLE[1..] {
        if d <= dk {
            return prev.1 + (mk - prev.1) * (d - prev.0) / (dk - prev.0);
        }
        prev = (dk, mk);
    }
    prev.1
}

/// Bias factor `1 + (D - 1) 2 / Q~` of the minimum of `D` values with inverse equivalent
/// degrees of freedom `qinv`, `Q~ = (Q - 2 M(D)) / (1 - M(D))` (Martin 2001, eq. 17).
fn min_bias(d: f64, m: f64, qinv: f64) -> f64 {
    1.0 + 2.0 * (d - 1.0) * (1.0 - m) * qinv / (1.0 - 2.0 * m * qinv)
}

#[derive(Debug, Clone)]
struct NoiseTracker {
    bins: usize,
    alpha_max: f64,
    alpha_min: f64,
    beta_max: f64,
    alpha_c_smooth: f64,
    /// Frames per sub-window (Martin's `V`).
    v: usize,
    /// Window and sub-window lengths counted in half-frame hops, the spacing at which
    /// Martin's 50 %-overlap bias table applies.
    d_eff: f64,
    v_eff: f64,
    m_d: f64,
    m_v: f64,
    boot_frames: u64,
    /// Fast-rise factor per sub-window for each band of [`SLOPE_QINV`].
    slope: [f64; 4],
    // State.
    frames: u64,
    alpha_c: f64,
    subwc: usize,
    ibuf: usize,
    p: Vec<f64>,
    p_mean: Vec<f64>,
    p_sq: Vec<f64>,
    qinv: Vec<f64>,
    sigma2: Vec<f64>,
    act_min: Vec<f64>,
    act_min_sub: Vec<f64>,
    pmin_u: Vec<f64>,
    lmin_flag: Vec<bool>,
    /// `SUBWINDOWS` rows of `bins` minima.
    actbuf: Vec<f64>,
}

impl NoiseTracker {
    fn new(bins: usize, frame: usize, hop: usize, rate_hz: f64, window_s: f64) -> Self {
        let hop_s = hop as f64 / rate_hz;
        let per_hop = |tau: f64| (-hop_s / tau).exp();
        let v_float = (window_s / (SUBWINDOWS as f64 * hop_s)).round();
        // `as` saturates; the window is at most 600 s, so this is far from any limit.
        let v = (v_float as usize).max(1);
        let half = frame as f64 / 2.0;
        let v_eff = (v as f64 * hop as f64 / half).max(1.0);
        let d_eff = (SUBWINDOWS as f64 * v as f64 * hop as f64 / half).max(1.0);
        let sub_s = v as f64 * hop_s;
        let mut slope = [1.0; 4];
        for (s, db) in slope.iter_mut().zip(SLOPE_DB_PER_S) {
            *s = 10f64.powf(db * sub_s / 10.0);
        }
        let boot_frames = ((BOOTSTRAP_S / hop_s).round() as u64).max(1);
        Self {
            bins,
            alpha_max: per_hop(TAU_ALPHA_MAX_S),
            alpha_min: per_hop(TAU_ALPHA_MIN_S),
            beta_max: per_hop(TAU_BETA_MAX_S),
            alpha_c_smooth: per_hop(TAU_ALPHA_C_S),
            v,
            d_eff,
            v_eff,
            m_d: m_of_d(d_eff),
            m_v: m_of_d(v_eff),
            boot_frames,
            slope,
            frames: 0,
            alpha_c: 1.0,
            subwc: 1,
            ibuf: 0,
            p: vec![0.0; bins],
            p_mean: vec![0.0; bins],
            p_sq: vec![0.0; bins],
            qinv: vec![0.0; bins],
            sigma2: vec![NOISE_FLOOR; bins],
            act_min: vec![f64::INFINITY; bins],
            act_min_sub: vec![f64::INFINITY; bins],
            pmin_u: vec![f64::INFINITY; bins],
            lmin_flag: vec![false; bins],
            actbuf: vec![f64::INFINITY; SUBWINDOWS * bins],
        }
    }

    fn reset(&mut self) {
        self.frames = 0;
        self.alpha_c = 1.0;
        self.subwc = 1;
        self.ibuf = 0;
        self.p.fill(0.0);
        self.p_mean.fill(0.0);
        self.p_sq.fill(0.0);
        self.qinv.fill(0.0);
        self.sigma2.fill(NOISE_FLOOR);
        self.act_min.fill(f64::INFINITY);
        self.act_min_sub.fill(f64::INFINITY);
        self.pmin_u.fill(f64::INFINITY);
        self.lmin_flag.fill(false);
        self.actbuf.fill(f64::INFINITY);
    }

    /// Current noise power per bin.
    fn noise(&self) -> &[f64] {
        &self.sigma2
    }

    /// Feeds one frame's periodogram `y` (`bins` values, finite and non-negative).
    fn update(&mut self, y: &[f64]) {
        if y.len() != self.bins {
            return;
        }
        if self.frames == 0 {
            for (k, &yk) in y.iter().enumerate() {
                self.p[k] = yk;
                self.p_mean[k] = yk;
                self.p_sq[k] = yk * yk;
                self.sigma2[k] = yk.max(NOISE_FLOOR);
            }
            self.frames = 1;
            return;
        }
        self.frames += 1;
        let boot = self.frames <= self.boot_frames;
        let cap = 1.0 - 1.0 / self.frames as f64;

        // Global correction of the smoothing constant (Martin eq. 10).
        let sum_p: f64 = self.p.iter().sum();
        let sum_y: f64 = y.iter().sum();
        let ratio = if sum_y > 0.0 {
            sum_p / sum_y
        } else if sum_p > 0.0 {
            f64::INFINITY
        } else {
            1.0
        };
        let tilde = 1.0 / (1.0 + (ratio - 1.0) * (ratio - 1.0));
        let tilde = if tilde.is_finite() { tilde } else { 0.0 };
        self.alpha_c =
            self.alpha_c_smooth * self.alpha_c + (1.0 - self.alpha_c_smooth) * tilde.max(0.7);

        // Optimal smoothing, moments and equivalent degrees of freedom.
        let mut qsum = 0.0;
        for (k, &yk) in y.iter().enumerate() {
            let s2 = self.sigma2[k];
            let dev = self.p[k] / s2 - 1.0;
            let mut a = self.alpha_max * self.alpha_c / (1.0 + dev * dev);
            if !a.is_finite() {
                a = 0.0;
            }
            a = a.max(self.alpha_min);
            let mut b = (a * a).min(self.beta_max);
            if boot {
                a = a.min(cap);
                b = b.min(cap);
            }
            let p = a * self.p[k] + (1.0 - a) * yk;
            self.p[k] = p;
            self.p_mean[k] = b * self.p_mean[k] + (1.0 - b) * p;
            self.p_sq[k] = b * self.p_sq[k] + (1.0 - b) * p * p;
            let var = (self.p_sq[k] - self.p_mean[k] * self.p_mean[k]).max(0.0);
            let q = var / (2.0 * (s2 * s2).max(f64::MIN_POSITIVE));
            let q = if q.is_nan() { 0.5 } else { q.min(0.5) };
            self.qinv[k] = q;
            qsum += q;
        }
        if boot {
            for (s2, &p) in self.sigma2.iter_mut().zip(&self.p) {
                *s2 = p.max(NOISE_FLOOR);
            }
            return;
        }

        // Minimum search over sub-windows with bias correction.
        let qbar = qsum / self.bins as f64;
        let bc = 1.0 + AV * qbar.sqrt();
        let slope = match SLOPE_QINV.iter().position(|&t| qbar < t) {
            Some(i) => self.slope[i],
            None => self.slope[3],
        };
        let end = self.subwc >= self.v;
        let row = self.ibuf * self.bins;
        for k in 0..self.bins {
            let q = self.qinv[k];
            let p = self.p[k];
            let mut kmod = false;
            let candidate = p * min_bias(self.d_eff, self.m_d, q) * bc;
            if candidate < self.act_min[k] {
                self.act_min[k] = candidate;
                self.act_min_sub[k] = p * min_bias(self.v_eff, self.m_v, q) * bc;
                kmod = true;
            }
            let new_noise = if end {
                if kmod {
                    self.lmin_flag[k] = false;
                }
                self.actbuf[row + k] = self.act_min[k];
                let mut pmin = f64::INFINITY;
                for u in 0..SUBWINDOWS {
                    pmin = pmin.min(self.actbuf[u * self.bins + k]);
                }
                let sub = self.act_min_sub[k];
                if self.lmin_flag[k] && sub < slope * pmin && sub > pmin {
                    pmin = sub;
                    for u in 0..SUBWINDOWS {
                        self.actbuf[u * self.bins + k] = sub;
                    }
                }
                self.lmin_flag[k] = false;
                self.act_min[k] = f64::INFINITY;
                self.act_min_sub[k] = f64::INFINITY;
                self.pmin_u[k] = pmin;
                Some(pmin)
            } else if self.subwc > 1 {
                if kmod {
                    self.lmin_flag[k] = true;
                }
                let s = self.act_min_sub[k].min(self.pmin_u[k]);
                self.pmin_u[k] = s;
                Some(s)
            } else {
                None
            };
            if let Some(s) = new_noise {
                if s.is_finite() {
                    self.sigma2[k] = s.max(NOISE_FLOOR);
                }
            }
        }
        if end {
            self.subwc = 1;
            self.ibuf = (self.ibuf + 1) % SUBWINDOWS;
        } else {
            self.subwc += 1;
        }
    }
}

// ---------------------------------------------------------------------------------------
// Gain rules
// ---------------------------------------------------------------------------------------

/// A per-bin real gain computed from the noisy power and the noise estimate.
trait GainRule {
    /// Writes the gain of every bin into `gain` from the noisy periodogram `power` and
    /// the noise power `noise` (same units, all slices `bins` long).
    fn gains(&mut self, power: &[f64], noise: &[f64], gain: &mut [f64]);
    /// Forgets all history.
    fn reset(&mut self);
}

/// Boll's magnitude subtraction with Berouti's over-subtraction and floor:
/// `G = max(1 - alpha |N| / |Y|, beta)`, i.e. `|S| = max(|Y| - alpha |N|, beta |Y|)`,
/// with `|N| = sqrt(pi / 4 * noise power)` the mean noise magnitude.
#[derive(Debug, Clone)]
struct Subtraction {
    alpha: f64,
    beta: f64,
}

/// `(E|N|)² / E|N|²` for complex Gaussian noise: `pi / 4`.
const MEAN_MAGNITUDE_PER_RMS: f64 = PI / 4.0;

impl GainRule for Subtraction {
    fn gains(&mut self, power: &[f64], noise: &[f64], gain: &mut [f64]) {
        for ((g, &y), &n) in gain.iter_mut().zip(power).zip(noise) {
            // Boll's noise bias is the mean noise magnitude, sqrt(pi / 4) times the RMS
            // magnitude for complex Gaussian noise.
            let ratio = (MEAN_MAGNITUDE_PER_RMS * n / y).sqrt();
            let sub = 1.0 - self.alpha * ratio;
            // NaN (silent bin and silent noise) and -inf both fall to the floor.
            *g = if sub > self.beta {
                sub.min(1.0)
            } else {
                self.beta
            };
        }
    }

    fn reset(&mut self) {}
}

/// Ephraim-Malah log-spectral-amplitude gain with the decision-directed a-priori SNR.
#[derive(Debug, Clone)]
struct LogMmse {
    /// The Wiener gain `xi / (1 + xi)` (MMSE of the complex STFT coefficient)
    /// in place of the LSA gain.
    wiener: bool,
    dd_alpha: f64,
    xi_min: f64,
    /// Squared amplitude estimate of the previous frame, per bin.
    prev: Vec<f64>,
    first: bool,
}

/// Caps on the a-posteriori and a-priori SNR; only keep the arithmetic finite.
const GAMMA_MAX: f64 = 1e12;
const XI_MAX: f64 = 1e12;

/// The LSA gain `xi / (1 + xi) * exp(E1(v) / 2)`, `v = xi / (1 + xi) * gamma`, capped
/// at 1 (the cap only acts where the observed power is far below the noise estimate).
fn lsa_gain(xi: f64, gamma: f64) -> f64 {
    let a = xi / (1.0 + xi);
    let v = a * gamma;
    if v.is_nan() || v <= 0.0 {
        return 1.0;
    }
    let g = a * (0.5 * expint_e1(v)).exp();
    if g.is_nan() {
        1.0
    } else {
        g.min(1.0)
    }
}

impl GainRule for LogMmse {
    fn gains(&mut self, power: &[f64], noise: &[f64], gain: &mut [f64]) {
        for (((g, &y), &n), prev) in gain
            .iter_mut()
            .zip(power)
            .zip(noise)
            .zip(self.prev.iter_mut())
        {
            let gamma = (y / n).min(GAMMA_MAX);
            let gamma = if gamma.is_nan() { 0.0 } else { gamma };
            let prior = if self.first { 1.0 } else { *prev / n };
            let ml = (gamma - 1.0).max(0.0);
            let xi = self.dd_alpha * prior + (1.0 - self.dd_alpha) * ml;
            let xi = if xi.is_nan() {
                self.xi_min
            } else {
                xi.clamp(self.xi_min, XI_MAX)
            };
            let gk = if self.wiener {
                xi / (1.0 + xi)
            } else {
                lsa_gain(xi, gamma)
            };
            *g = gk;
            *prev = gk * gk * y;
        }
        self.first = false;
    }

    fn reset(&mut self) {
        self.prev.fill(0.0);
        self.first = true;
    }
}

// ---------------------------------------------------------------------------------------
// Streaming STFT engine
// ---------------------------------------------------------------------------------------

/// Validated frame geometry: `(frame, hop)`.
fn geometry(rate_hz: f64, cfg: &DenoiseConfig) -> Result<(usize, usize), DenoiseError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(DenoiseError::InvalidRate(rate_hz));
    }
    if !(cfg.frame_ms.is_finite() && cfg.frame_ms > 0.0) {
        return Err(DenoiseError::InvalidFrameMs(cfg.frame_ms));
    }
    let divisor = if (cfg.overlap - 0.5).abs() < 1e-9 {
        2
    } else if (cfg.overlap - 0.75).abs() < 1e-9 {
        4
    } else {
        return Err(DenoiseError::InvalidOverlap(cfg.overlap));
    };
    if !(cfg.noise_window_s.is_finite()
        && cfg.noise_window_s > 0.0
        && cfg.noise_window_s <= MAX_NOISE_WINDOW_S)
    {
        return Err(invalid(
            "noise_window_s",
            cfg.noise_window_s,
            "finite, > 0 and <= 600 s",
        ));
    }
    let length = cfg.frame_ms * 1e-3 * rate_hz;
    if length.is_nan() || length < MIN_FRAME_SAMPLES as f64 {
        return Err(DenoiseError::FrameTooShort { length });
    }
    let exponent = length.log2().round();
    if exponent.is_nan() || exponent > f64::from(MAX_FRAME_SAMPLES.trailing_zeros()) {
        return Err(DenoiseError::FrameTooLong { length });
    }
    // 3 <= exponent <= 20 here.
    let frame = 1usize << (exponent as u32);
    Ok((frame, frame / divisor))
}

struct Engine<R> {
    frame: usize,
    hop: usize,
    /// Partial frames at the stream start (they overlap the implicit leading zeros).
    warm_frames: u64,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
    win_a: Vec<f64>,
    win_s: Vec<f64>,
    /// 1 / Σ w_a², turning |Y|² into units of the input variance.
    power_scale: f64,
    /// Last `frame` input samples; new samples go after the first `frame - hop`.
    inbuf: Vec<f64>,
    fill: usize,
    time: Vec<f64>,
    spec: Vec<Complex<f64>>,
    power: Vec<f64>,
    gain: Vec<f64>,
    scratch_fwd: Vec<Complex<f64>>,
    scratch_inv: Vec<Complex<f64>>,
    ola: Vec<f64>,
    ready: VecDeque<f32>,
    /// Leading finished samples that belong to the implicit zero padding.
    pad_skip: usize,
    frames: u64,
    total_in: u64,
    total_out: u64,
    flushing: bool,
    tracker: NoiseTracker,
    rule: R,
}

impl<R: GainRule> Engine<R> {
    /// Builds the engine; `make_rule` receives the number of frequency bins.
    fn new(
        rate_hz: f64,
        cfg: &DenoiseConfig,
        make_rule: impl FnOnce(usize) -> R,
    ) -> Result<Self, DenoiseError> {
        let (frame, hop) = geometry(rate_hz, cfg)?;
        let bins = frame / 2 + 1;
        let mut planner = RealFftPlanner::<f64>::new();
        let forward = planner.plan_fft_forward(frame);
        let inverse = planner.plan_fft_inverse(frame);
        let sqrt_window = hop * 2 == frame;
        let win_a: Vec<f64> = (0..frame)
            .map(|i| {
                let hann = 0.5 * (1.0 - (2.0 * PI * i as f64 / frame as f64).cos());
                if sqrt_window {
                    hann.sqrt()
                } else {
                    hann
                }
            })
            .collect();
        // Overlapped sum of squared analysis windows; constant (1 or 1.5) up to rounding.
        let overlapped: Vec<f64> = (0..hop)
            .map(|i| (i..frame).step_by(hop).map(|j| win_a[j] * win_a[j]).sum())
            .collect();
        let win_s: Vec<f64> = win_a
            .iter()
            .enumerate()
            .map(|(i, w)| w / overlapped[i % hop])
            .collect();
        let energy: f64 = win_a.iter().map(|w| w * w).sum();
        let scratch_fwd = forward.make_scratch_vec();
        let scratch_inv = inverse.make_scratch_vec();
        Ok(Self {
            frame,
            hop,
            warm_frames: (frame / hop - 1) as u64,
            spec: forward.make_output_vec(),
            forward,
            inverse,
            win_a,
            win_s,
            power_scale: 1.0 / energy,
            inbuf: vec![0.0; frame],
            fill: 0,
            time: vec![0.0; frame],
            power: vec![0.0; bins],
            gain: vec![1.0; bins],
            scratch_fwd,
            scratch_inv,
            ola: vec![0.0; frame],
            ready: VecDeque::with_capacity(2 * frame + hop),
            pad_skip: frame - hop,
            frames: 0,
            total_in: 0,
            total_out: 0,
            flushing: false,
            tracker: NoiseTracker::new(bins, frame, hop, rate_hz, cfg.noise_window_s),
            rule: make_rule(bins),
        })
    }

    fn latency(&self) -> usize {
        self.frame
    }

    fn reset(&mut self) {
        self.reset_stream();
        self.tracker.reset();
    }

    /// Resets everything but the noise tracker.
    fn reset_stream(&mut self) {
        self.inbuf.fill(0.0);
        self.fill = 0;
        self.ola.fill(0.0);
        self.ready.clear();
        self.pad_skip = self.frame - self.hop;
        self.frames = 0;
        self.total_in = 0;
        self.total_out = 0;
        self.flushing = false;
        self.rule.reset();
    }

    /// Feeds `lead` to the noise tracker alone (analysis frames, no output), then
    /// starts the stream afresh with the tracker kept. See `prime` of the denoisers.
    fn prime(&mut self, lead: &[f32]) {
        self.reset_stream();
        let head = self.frame - self.hop;
        for chunk in lead.chunks_exact(self.hop) {
            for (dst, &x) in self.inbuf[head..].iter_mut().zip(chunk) {
                *dst = if x.is_finite() { f64::from(x) } else { 0.0 };
            }
            self.analyse();
            if self.frames >= self.warm_frames {
                self.tracker.update(&self.power);
            }
            self.inbuf.copy_within(self.hop.., 0);
            self.frames += 1;
        }
        self.reset_stream();
    }

    /// The windowed frame's power spectrum into `power` (its spectrum in `spec`).
    fn analyse(&mut self) {
        for ((t, &x), &w) in self.time.iter_mut().zip(&self.inbuf).zip(&self.win_a) {
            *t = x * w;
        }
        if self
            .forward
            .process_with_scratch(&mut self.time, &mut self.spec, &mut self.scratch_fwd)
            .is_err()
        {
            self.spec.fill(Complex::new(0.0, 0.0));
        }
        for (p, s) in self.power.iter_mut().zip(&self.spec) {
            *p = s.norm_sqr() * self.power_scale;
        }
    }

    fn process(&mut self, input: &[f32], out: &mut Vec<f32>) {
        let head = self.frame - self.hop;
        let mut rest = input;
        while !rest.is_empty() {
            let take = (self.hop - self.fill).min(rest.len());
            let (chunk, tail) = rest.split_at(take);
            let start = head + self.fill;
            for (dst, &x) in self.inbuf[start..start + take].iter_mut().zip(chunk) {
                *dst = if x.is_finite() { f64::from(x) } else { 0.0 };
            }
            self.fill += take;
            self.total_in += take as u64;
            rest = tail;
            if self.fill == self.hop {
                self.process_frame();
                self.release(out);
            }
        }
        self.release(out);
    }

    fn finish(&mut self, out: &mut Vec<f32>) {
        self.flushing = true;
        let head = self.frame - self.hop;
        while self.total_out + (self.ready.len() as u64) < self.total_in {
            self.inbuf[head + self.fill..].fill(0.0);
            self.fill = self.hop;
            self.process_frame();
            // Release what the fixed latency allows so the queue stays within capacity.
            self.release(out);
        }
        while self.total_out < self.total_in {
            match self.ready.pop_front() {
                Some(v) => {
                    out.push(v);
                    self.total_out += 1;
                }
                None => break,
            }
        }
        self.reset();
    }

    /// Appends finished samples up to `total_in - latency`.
    fn release(&mut self, out: &mut Vec<f32>) {
        let allowed = self.total_in.saturating_sub(self.frame as u64);
        while self.total_out < allowed {
            match self.ready.pop_front() {
                Some(v) => {
                    out.push(v);
                    self.total_out += 1;
                }
                None => break,
            }
        }
    }

    fn process_frame(&mut self) {
        self.analyse();
        if self.frames >= self.warm_frames {
            if !self.flushing {
                self.tracker.update(&self.power);
            }
            self.rule
                .gains(&self.power, self.tracker.noise(), &mut self.gain);
        } else {
            self.gain.fill(1.0);
        }
        for (s, &g) in self.spec.iter_mut().zip(&self.gain) {
            *s *= g;
        }
        // A real signal's DC and Nyquist bins are real.
        if let Some(first) = self.spec.first_mut() {
            first.im = 0.0;
        }
        if let Some(last) = self.spec.last_mut() {
            last.im = 0.0;
        }
        if self
            .inverse
            .process_with_scratch(&mut self.spec, &mut self.time, &mut self.scratch_inv)
            .is_err()
        {
            self.time.fill(0.0);
        }
        let scale = 1.0 / self.frame as f64;
        for ((o, &t), &w) in self.ola.iter_mut().zip(&self.time).zip(&self.win_s) {
            *o += t * w * scale;
        }
        for &v in &self.ola[..self.hop] {
            if self.pad_skip > 0 {
                self.pad_skip -= 1;
            } else {
                let clamped = v.clamp(-f64::from(f32::MAX), f64::from(f32::MAX));
                // NaN cannot arise from finite input; map it to silence regardless.
                self.ready.push_back(if clamped.is_nan() {
                    0.0
                } else {
                    clamped as f32
                });
            }
        }
        self.ola.copy_within(self.hop.., 0);
        let n = self.frame;
        self.ola[n - self.hop..].fill(0.0);
        self.inbuf.copy_within(self.hop.., 0);
        self.fill = 0;
        self.frames += 1;
    }
}

// ---------------------------------------------------------------------------------------
// Public denoisers
// ---------------------------------------------------------------------------------------

/// The stream methods both denoisers share, forwarded to their `engine`.
macro_rules! engine_methods {
    () => {
        /// Feeds any number of samples; appends every finished output sample to `out`.
        pub fn process(&mut self, input: &[f32], out: &mut Vec<f32>) {
            self.engine.process(input, out);
        }

        /// Flushes the tail (zero-padded) at end of stream, so that the total output length
        /// equals the total input length, then resets for a new stream.
        pub fn finish(&mut self, out: &mut Vec<f32>) {
            self.engine.finish(out);
        }

        /// Replay only: warms the noise tracker on the stream's first samples `lead`
        /// (which are then fed again, from the start, through `process`) and resets
        /// the stream, keeping the tracker. The noise floor at the start is then the
        /// minimum over the lead rather than the cold start's short average (module
        /// documentation, "Noise tracking"), which counts a signal present from the
        /// first sample as noise. A live stream cannot look ahead and starts cold.
        /// Allocates nothing; a lead shorter than a hop does nothing but the reset.
        pub fn prime(&mut self, lead: &[f32]) {
            self.engine.prime(lead);
        }

        /// Fixed latency in samples: one frame.
        pub fn latency_samples(&self) -> usize {
            self.engine.latency()
        }

        /// Frame length in samples.
        pub fn frame_len(&self) -> usize {
            self.engine.frame
        }

        /// Hop between frames in samples.
        pub fn hop_len(&self) -> usize {
            self.engine.hop
        }
    };
}

/// Streaming magnitude spectral subtraction (Boll 1979) with over-subtraction and a
/// spectral floor (Berouti et al. 1979): per bin `|S| = max(|Y| - alpha |N|, beta |Y|)`,
/// where `|N|` is Boll's mean noise magnitude, `sqrt(pi / 4)` times the square root of
/// the tracked noise power (exact for Gaussian noise); the noisy phase is kept. The floor
/// is relative to the noisy magnitude, so the gain stays in `[beta, 1]`.
///
/// Over-subtraction trades speech fidelity for less residual noise: with the default
/// `alpha = 2` every bin loses about 1.8 noise magnitudes, which attenuates speech
/// components well above the noise too. Where waveform accuracy matters more than
/// residual noise, `alpha = 1` (Boll's original rule) scores a higher segmental SNR.
///
/// See the [module documentation](self) for framing, noise tracking and latency.
pub struct SpectralSubtraction {
    engine: Engine<Subtraction>,
}

impl SpectralSubtraction {
    /// A spectral subtractor for a stream at `rate_hz` with over-subtraction factor
    /// `alpha` (finite, >= 0; [`DEFAULT_ALPHA`]) and spectral floor `beta` (in `[0, 1]`;
    /// [`DEFAULT_BETA`]). `alpha = 0` or `beta = 1` pass the input through unchanged.
    ///
    /// Errors when the rate, the frame, the overlap, the noise window, `alpha` or `beta`
    /// is out of range.
    pub fn new(
        rate_hz: f64,
        cfg: &DenoiseConfig,
        alpha: f64,
        beta: f64,
    ) -> Result<Self, DenoiseError> {
        if !(alpha.is_finite() && alpha >= 0.0) {
            return Err(invalid("alpha", alpha, "finite and >= 0"));
        }
        if !((0.0..=1.0).contains(&beta)) {
            return Err(invalid("beta", beta, "in [0, 1]"));
        }
        let engine = Engine::new(rate_hz, cfg, |_| Subtraction { alpha, beta })?;
        Ok(Self { engine })
    }

    /// [`SpectralSubtraction::new`] with the default configuration, alpha and beta.
    pub fn with_defaults(rate_hz: f64) -> Result<Self, DenoiseError> {
        Self::new(
            rate_hz,
            &DenoiseConfig::default(),
            DEFAULT_ALPHA,
            DEFAULT_BETA,
        )
    }

    engine_methods!();

    /// Tracked noise power per frequency bin `k = 0..=frame_len()/2` (bin `k` is at
    /// `k * rate / frame_len()` Hz), in units of the input variance: white noise of
    /// variance `s²` reads `s²` in every bin once tracked.
    pub fn noise_psd(&self) -> &[f64] {
        self.engine.tracker.noise()
    }
}

/// Streaming speech enhancement by the MMSE log-spectral-amplitude estimator (Ephraim &
/// Malah 1985): per bin gain `xi / (1 + xi) * exp(E1(v) / 2)` with
/// `v = gamma xi / (1 + xi)`, a-posteriori SNR `gamma = |Y|² / noise` and the
/// decision-directed a-priori SNR
/// `xi = dd_alpha |S_prev|² / noise + (1 - dd_alpha) max(gamma - 1, 0)`, floored at
/// `xi_min_db`; the gain is capped at 1 and the noisy phase is kept. See the
/// [module documentation](self) for framing, noise tracking and latency.
pub struct SpeechEnhance {
    engine: Engine<LogMmse>,
}

impl SpeechEnhance {
    /// An enhancer for a stream at `rate_hz`; uses `cfg.dd_alpha` and `cfg.xi_min_db`.
    ///
    /// Errors when the rate, the frame, the overlap, the noise window, `dd_alpha` (must
    /// be in `[0, 1)`) or `xi_min_db` (finite, <= 0) is out of range.
    pub fn new(rate_hz: f64, cfg: &DenoiseConfig) -> Result<Self, DenoiseError> {
        if !(cfg.dd_alpha >= 0.0 && cfg.dd_alpha < 1.0) {
            return Err(invalid("dd_alpha", cfg.dd_alpha, "in [0, 1)"));
        }
        if !(cfg.xi_min_db.is_finite() && cfg.xi_min_db <= 0.0) {
            return Err(invalid("xi_min_db", cfg.xi_min_db, "finite and <= 0 dB"));
        }
        let engine = Engine::new(rate_hz, cfg, |bins| LogMmse {
            wiener: false,
            dd_alpha: cfg.dd_alpha,
            xi_min: 10f64.powf(cfg.xi_min_db / 10.0),
            prev: vec![0.0; bins],
            first: true,
        })?;
        Ok(Self { engine })
    }

    /// [`SpeechEnhance::new`] with the default configuration.
    pub fn with_defaults(rate_hz: f64) -> Result<Self, DenoiseError> {
        Self::new(rate_hz, &DenoiseConfig::default())
    }

    engine_methods!();

    /// Tracked noise power per frequency bin; see [`SpectralSubtraction::noise_psd`].
    pub fn noise_psd(&self) -> &[f64] {
        self.engine.tracker.noise()
    }
}

/// Streaming MMSE (Wiener) estimation of the STFT coefficients: per bin gain
/// `xi / (1 + xi)`, the linear MMSE estimate of the complex coefficient under
/// Gaussian speech and noise, which minimises the waveform's squared error
/// (the SNR) where [`SpeechEnhance`]'s log-amplitude gain minimises a
/// perceptual error. `xi` is the same decision-directed a-priori SNR
/// (`dd_alpha`, floored at `xi_min_db`), the noise power the same
/// minimum-statistics tracker (Martin 2001) as the other denoisers; see the
/// [module documentation](self) for framing, noise tracking and latency.
pub struct Wiener {
    engine: Engine<LogMmse>,
}

impl Wiener {
    /// A Wiener denoiser for a stream at `rate_hz`; uses `cfg.dd_alpha` and
    /// `cfg.xi_min_db`. Errors as [`SpeechEnhance::new`].
    pub fn new(rate_hz: f64, cfg: &DenoiseConfig) -> Result<Self, DenoiseError> {
        let mut e = SpeechEnhance::new(rate_hz, cfg)?;
        e.engine.rule.wiener = true;
        Ok(Self { engine: e.engine })
    }

    /// [`Wiener::new`] with [`DenoiseConfig::wiener`].
    pub fn with_defaults(rate_hz: f64) -> Result<Self, DenoiseError> {
        Self::new(rate_hz, &DenoiseConfig::wiener())
    }

    engine_methods!();

    /// Tracked noise power per frequency bin; see [`SpectralSubtraction::noise_psd`].
    pub fn noise_psd(&self) -> &[f64] {
        self.engine.tracker.noise()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::metrics::{best_lag_gain, segmental_snr_db, snr_db, stoi};

    // ----- deterministic test signals --------------------------------------------------

    /// SplitMix64 generator with Box-Muller Gaussian samples.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        /// Uniform in (0, 1].
        fn uniform(&mut self) -> f64 {
            ((self.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
        }

        fn gauss(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
        }
    }

    fn white(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng(seed);
        (0..n).map(|_| sigma * rng.gauss()).collect()
    }

    /// On/off gate at `phase` in [0, 1) of a period of `period_s`: on for the first
    /// `duty` of the period, with 25 ms raised-cosine ramps inside the on part.
    fn gate(phase: f64, duty: f64, period_s: f64) -> f64 {
        gate_with_ramp(phase, duty, period_s, 0.025)
    }

    /// [`gate`] with ramps of `ramp_s` seconds.
    fn gate_with_ramp(phase: f64, duty: f64, period_s: f64, ramp_s: f64) -> f64 {
        let ramp = (ramp_s / period_s).min(duty / 2.0);
        if phase < ramp {
            0.5 - 0.5 * (PI * phase / ramp).cos()
        } else if phase < duty - ramp {
            1.0
        } else if phase < duty {
            0.5 + 0.5 * (PI * (phase - duty + ramp) / ramp).cos()
        } else {
            0.0
        }
    }

    /// Speech-like test signal at `fs`, RMS 0.1: a harmonic series on a pitch gliding
    /// between 120 and 220 Hz, shaped by three drifting formant resonances over a
    /// -6 dB/octave source tilt above 400 Hz, and gated on and off at a syllabic rate of
    /// 4 ± 0.6 Hz (on for 75 % of each syllable, 25 ms ramps). Harmonics fade out
    /// towards 0.45 fs.
    fn speech_like(fs: f64, seconds: f64) -> Vec<f64> {
        let n = (seconds * fs) as usize;
        let mut out = Vec::with_capacity(n);
        let (mut pitch_phase, mut syllable_phase) = (0.0f64, 0.0f64);
        let top = 0.45 * fs;
        for i in 0..n {
            let t = i as f64 / fs;
            let f0 = 170.0 + 50.0 * (2.0 * PI * 0.35 * t).sin();
            pitch_phase = (pitch_phase + f0 / fs).fract();
            let rate = 4.0 + 0.6 * (2.0 * PI * 0.23 * t).sin();
            syllable_phase = (syllable_phase + rate / fs).fract();
            let g = gate(syllable_phase, 0.75, 1.0 / rate);
            let formants = [
                (600.0 + 150.0 * (2.0 * PI * 1.1 * t).sin(), 90.0, 1.0),
                (
                    1500.0 + 300.0 * (2.0 * PI * 0.7 * t + 1.0).sin(),
                    130.0,
                    0.5,
                ),
                (2500.0, 180.0, 0.25),
            ];
            let mut s = 0.0;
            for h in 1.. {
                let f = h as f64 * f0;
                if f >= top {
                    break;
                }
                let mut env = 0.03;
                for &(fc, bw, gain) in &formants {
                    let d = (f - fc) / bw;
                    env += gain / (1.0 + d * d);
                }
                env *= ((top - f) / (0.05 * fs)).clamp(0.0, 1.0);
                env /= (1.0 + (f / 400.0).powi(2)).sqrt();
                s += env * (2.0 * PI * h as f64 * pitch_phase).sin();
            }
            out.push(g * s);
        }
        let rms = rms(&out);
        out.iter().map(|v| 0.1 * v / rms).collect()
    }

    /// Clean multi-tone: five tones spread over the band at least four frequency bins
    /// apart, each switched on and off independently (periods 0.45 to 1.05 s, on 60 %,
    /// 20 ms ramps), after 0.3 s of silence. The gaps and the silent lead matter: minimum
    /// statistics would take a tone that never pauses, or one sounding from the first
    /// sample, for noise (see the module documentation).
    fn gated_multitone(fs: f64, seconds: f64) -> Vec<f64> {
        let n = (seconds * fs) as usize;
        let freqs = [0.08, 0.22, 0.38, 0.55, 0.75].map(|r| r * fs / 2.0);
        let periods = [0.45, 0.6, 0.75, 0.9, 1.05];
        (0..n)
            .map(|i| {
                let t = i as f64 / fs - 0.3;
                if t < 0.0 {
                    return 0.0;
                }
                freqs
                    .iter()
                    .zip(periods)
                    .enumerate()
                    .map(|(j, (&f, p))| {
                        let phase = (t / p + 0.13 * j as f64).fract();
                        let g = gate_ramped(phase, 0.6, p);
                        0.1 * g * (2.0 * PI * f * t + j as f64).sin()
                    })
                    .sum()
            })
            .collect()
    }

    /// Like [`gate`] but with 20 ms ramps.
    fn gate_ramped(phase: f64, duty: f64, period_s: f64) -> f64 {
        gate_with_ramp(phase, duty, period_s, 0.02)
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt()
    }

    /// `clean` plus white Gaussian noise at the given global SNR.
    fn add_noise(clean: &[f64], snr_db: f64, seed: u64) -> Vec<f64> {
        let sigma = rms(clean) / 10f64.powf(snr_db / 20.0);
        let noise = white(clean.len(), sigma, seed);
        clean.iter().zip(&noise).map(|(s, n)| s + n).collect()
    }

    fn to_f32(x: &[f64]) -> Vec<f32> {
        x.iter().map(|&v| v as f32).collect()
    }

    fn to_f64(x: &[f32]) -> Vec<f64> {
        x.iter().map(|&v| f64::from(v)).collect()
    }

    // ----- running either denoiser -----------------------------------------------------

    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Method {
        Subtraction,
        Lsa,
    }

    const METHODS: [Method; 2] = [Method::Subtraction, Method::Lsa];

    enum Denoiser {
        Ss(SpectralSubtraction),
        Lsa(SpeechEnhance),
    }

    impl Denoiser {
        fn new(method: Method, fs: f64, cfg: &DenoiseConfig) -> Self {
            match method {
                Method::Subtraction => Denoiser::Ss(
                    SpectralSubtraction::new(fs, cfg, DEFAULT_ALPHA, DEFAULT_BETA).unwrap(),
                ),
                Method::Lsa => Denoiser::Lsa(SpeechEnhance::new(fs, cfg).unwrap()),
            }
        }

        fn process(&mut self, x: &[f32], out: &mut Vec<f32>) {
            match self {
                Denoiser::Ss(d) => d.process(x, out),
                Denoiser::Lsa(d) => d.process(x, out),
            }
        }

        fn finish(&mut self, out: &mut Vec<f32>) {
            match self {
                Denoiser::Ss(d) => d.finish(out),
                Denoiser::Lsa(d) => d.finish(out),
            }
        }

        fn latency(&self) -> usize {
            match self {
                Denoiser::Ss(d) => d.latency_samples(),
                Denoiser::Lsa(d) => d.latency_samples(),
            }
        }

        fn frame_len(&self) -> usize {
            match self {
                Denoiser::Ss(d) => d.frame_len(),
                Denoiser::Lsa(d) => d.frame_len(),
            }
        }

        fn noise_psd(&self) -> &[f64] {
            match self {
                Denoiser::Ss(d) => d.noise_psd(),
                Denoiser::Lsa(d) => d.noise_psd(),
            }
        }
    }

    /// Runs a whole signal through `d` in blocks of `block` samples and finishes.
    fn run_on(d: &mut Denoiser, x: &[f32], block: usize) -> Vec<f32> {
        let mut out = Vec::new();
        for chunk in x.chunks(block.max(1)) {
            d.process(chunk, &mut out);
        }
        d.finish(&mut out);
        out
    }

    fn run(method: Method, fs: f64, x: &[f64]) -> Vec<f64> {
        let mut d = Denoiser::new(method, fs, &DenoiseConfig::default());
        to_f64(&run_on(&mut d, &to_f32(x), usize::MAX))
    }

    /// Writes `x` as a 32-bit float WAV into `$VIBROSCOPE_DENOISE_WAV_DIR`, if set.
    fn maybe_write_wav(name: &str, fs: f64, x: &[f64]) {
        let Ok(dir) = std::env::var("VIBROSCOPE_DENOISE_WAV_DIR") else {
            return;
        };
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: fs as u32,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let path = std::path::Path::new(&dir).join(format!("{name}.wav"));
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for &v in x {
            w.write_sample(v as f32).unwrap();
        }
        w.finalize().unwrap();
    }

    // ----- exponential integral --------------------------------------------------------

    #[test]
    fn expint_matches_known_values() {
        let known = [
            (0.1, 1.822_923_958_419_39),
            (1.0, 0.219_383_934_395_520),
            (5.0, 0.001_148_295_591_275),
            (0.5, 0.559_773_594_776_160_8),
            (2.0, 0.048_900_510_708_061_12),
            (10.0, 4.156_968_929_685_324e-6),
            (1e-10, 22.448_635_265_138_92),
        ];
        for (x, want) in known {
            let got = expint_e1(x);
            let rel = ((got - want) / want).abs();
            assert!(rel < 1e-12, "E1({x}) = {got}, want {want}, rel err {rel:e}");
        }
        // Continuous where the series hands over to the continued fraction.
        let (below, above) = (expint_e1(1.0 - 1e-12), expint_e1(1.0 + 1e-12));
        assert!((below - above).abs() < 1e-11);
        // Large x: E1(x) ~ e^-x / x (1 - 1/x + 2/x²).
        let x = 50.0f64;
        let asym = (-x).exp() / x * (1.0 - 1.0 / x + 2.0 / (x * x) - 6.0 / x.powi(3));
        assert!(((expint_e1(x) - asym) / asym).abs() < 1e-5);
        assert_eq!(expint_e1(0.0), f64::INFINITY);
        assert_eq!(expint_e1(800.0), 0.0);
        assert!(expint_e1(-1.0).is_nan());
        assert!(expint_e1(f64::NAN).is_nan());
        assert_eq!(expint_e1(f64::INFINITY), 0.0);
    }

    #[test]
    fn lsa_gain_behaves() {
        // High SNR: gain close to the Wiener gain xi / (1 + xi) -> 1.
        assert!((lsa_gain(1e4, 1e4) - 1.0).abs() < 1e-3);
        // Low a-priori SNR and an average observation: strong suppression.
        assert!(lsa_gain(10f64.powf(-2.5), 1.0) < 0.1);
        // Monotone in the a-priori SNR.
        let mut last = 0.0;
        for i in 0..60 {
            let xi = 10f64.powf(-3.0 + 0.1 * i as f64);
            let g = lsa_gain(xi, 2.0);
            assert!(g >= last && g <= 1.0, "xi {xi}: {g} after {last}");
            last = g;
        }
        assert_eq!(lsa_gain(1.0, 0.0), 1.0);
    }

    // ----- framing, reconstruction, alignment ------------------------------------------

    #[test]
    fn frame_geometry_follows_rate_and_overlap() {
        let ss = SpectralSubtraction::with_defaults(8000.0).unwrap();
        assert_eq!(
            (ss.frame_len(), ss.hop_len(), ss.latency_samples()),
            (256, 64, 256)
        );
        let se = SpeechEnhance::with_defaults(2200.0).unwrap();
        assert_eq!(
            (se.frame_len(), se.hop_len(), se.latency_samples()),
            (64, 16, 64)
        );
        let cfg = DenoiseConfig {
            overlap: 0.5,
            ..DenoiseConfig::default()
        };
        let ss = SpectralSubtraction::new(44100.0, &cfg, 2.0, 0.02).unwrap();
        assert_eq!((ss.frame_len(), ss.hop_len()), (1024, 512));
        assert_eq!(ss.noise_psd().len(), 513);
    }

    /// With unit gains (alpha = 0) the STFT/overlap-add chain reconstructs the input
    /// exactly and aligned, at any length, for both window/overlap pairs.
    #[test]
    fn unit_gain_reconstructs_input_exactly() {
        for fs in [8000.0, 2200.0] {
            for overlap in [0.5, 0.75] {
                let cfg = DenoiseConfig {
                    overlap,
                    ..DenoiseConfig::default()
                };
                for len in [0usize, 1, 17, 63, 64, 65, 255, 256, 257, 1000, 12_345] {
                    let x = to_f32(&white(len, 0.3, len as u64 + 1));
                    for block in [1usize, 37, 4096] {
                        let mut d = SpectralSubtraction::new(fs, &cfg, 0.0, 0.02).unwrap();
                        let mut out = Vec::new();
                        for chunk in x.chunks(block) {
                            d.process(chunk, &mut out);
                        }
                        d.finish(&mut out);
                        assert_eq!(out.len(), x.len());
                        for (k, (a, b)) in x.iter().zip(&out).enumerate() {
                            assert!(
                                (a - b).abs() <= 1e-6,
                                "fs {fs} overlap {overlap} len {len} k {k}: {a} vs {b}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Zero noise: a clean (gated) multi-tone comes out with SNR > 25 dB, the same
    /// length, and aligned (cross-correlation peak at lag 0).
    #[test]
    fn clean_signal_passes_nearly_unchanged() {
        for fs in [8000.0, 2200.0] {
            let clean = gated_multitone(fs, 5.0);
            for method in METHODS {
                let out = run(method, fs, &clean);
                assert_eq!(out.len(), clean.len());
                let snr = snr_db(&clean, &out);
                let frame = Denoiser::new(method, fs, &DenoiseConfig::default()).frame_len();
                let (lag, gain) = best_lag_gain(&clean, &out, 2 * frame);
                println!("clean multitone fs {fs} {method:?}: SNR {snr:.1} dB, lag {lag}, gain {gain:.4}");
                assert!(snr > 25.0, "{method:?} at {fs} Hz: SNR {snr:.1} dB");
                assert_eq!(lag, 0, "{method:?} at {fs} Hz");
                assert!((gain - 1.0).abs() < 0.05);
            }
        }
    }

    // ----- denoising ---------------------------------------------------------------------

    /// Speech-like signal plus white noise at 0 and 5 dB, at 8 kHz and 2200 Hz: the
    /// segmental SNR improves. The MMSE-LSA estimator gains at least 3 dB everywhere.
    /// Spectral subtraction with the default over-subtraction alpha = 2 gains at least
    /// 3 dB at 8 kHz / 0 dB; elsewhere its speech attenuation (alpha = 2 removes about
    /// 1.8 noise magnitudes from every bin) limits it to the smaller asserted bounds
    /// (measured: +2.9 dB at 8 kHz / 5 dB and 2200 Hz / 0 dB, +1.5 dB at 2200 Hz / 5 dB,
    /// stable to ±0.2 dB over noise seeds). Run with `--nocapture` for the table, and set
    /// `VIBROSCOPE_DENOISE_WAV_DIR` to listen to the signals.
    #[test]
    fn speech_like_noise_is_reduced() {
        let mut report = String::new();
        for fs in [8000.0, 2200.0] {
            let clean = speech_like(fs, 6.0);
            for snr in [0.0, 5.0] {
                let noisy = add_noise(&clean, snr, 7);
                let seg_in = segmental_snr_db(&clean, &noisy, fs);
                let stoi_in = stoi(&clean, &noisy, fs);
                maybe_write_wav(&format!("speech_{fs}_{snr}_clean"), fs, &clean);
                maybe_write_wav(&format!("speech_{fs}_{snr}_noisy"), fs, &noisy);
                for method in METHODS {
                    let out = run(method, fs, &noisy);
                    maybe_write_wav(&format!("speech_{fs}_{snr}_{method:?}"), fs, &out);
                    assert_eq!(out.len(), noisy.len());
                    let seg_out = segmental_snr_db(&clean, &out, fs);
                    let stoi_out = stoi(&clean, &out, fs);
                    let gain = seg_out - seg_in;
                    let line = format!(
                        "fs {fs:>6} Hz, SNR {snr} dB, {method:?}: segSNR {seg_in:.2} -> \
                         {seg_out:.2} dB ({gain:+.2}), STOI {stoi_in:.3} -> {stoi_out:.3}, \
                         SNR {:.2} -> {:.2} dB\n",
                        snr_db(&clean, &noisy),
                        snr_db(&clean, &out)
                    );
                    report += &line;
                    let needed = match (method, fs > 3000.0, snr > 0.0) {
                        (Method::Lsa, _, _) => 3.0,
                        (Method::Subtraction, true, false) => 3.0,
                        (Method::Subtraction, true, true) => 2.5,
                        (Method::Subtraction, false, false) => 2.5,
                        (Method::Subtraction, false, true) => 1.0,
                    };
                    assert!(gain >= needed, "{line} needs +{needed} dB");
                    assert!(stoi_out.is_finite());
                }
            }
        }
        println!("{report}");
    }

    /// The Wiener mode raises the waveform SNR itself (not only segmental SNR)
    /// by at least 1 dB on the speech-like signal at 0 and 5 dB input SNR,
    /// at 8 kHz and at a camera's 2200 Hz.
    #[test]
    fn wiener_raises_snr() {
        for fs in [8000.0, 2200.0] {
            let clean = speech_like(fs, 6.0);
            for snr in [0.0, 5.0] {
                let noisy = add_noise(&clean, snr, 7);
                let mut d = Wiener::with_defaults(fs).unwrap();
                let mut out = Vec::new();
                d.process(&to_f32(&noisy), &mut out);
                d.finish(&mut out);
                let out: Vec<f64> = out.iter().map(|&v| v as f64).collect();
                let (a, b) = (snr_db(&clean, &noisy), snr_db(&clean, &out));
                println!("fs {fs} Hz, SNR {a:.2} -> {b:.2} dB (Wiener)");
                assert!(b >= a + 1.0, "fs {fs} Hz: SNR {a:.2} -> {b:.2} dB");
            }
        }
    }

    /// A signal sounding from the first sample: cold, the tracker's start takes it for
    /// noise and the first half second loses SNR; primed on the stream's first 1.5 s
    /// (replay), it does not. Both give one output sample per input sample, and the
    /// primed stream is as block-size independent as the cold one.
    #[test]
    fn priming_spares_a_signal_present_from_the_first_sample() {
        let fs = 2200.0;
        let clean = speech_like(fs, 4.0);
        let noisy = add_noise(&clean, 5.0, 11);
        let x = to_f32(&noisy);
        let lead = &x[..(1.5 * fs) as usize];
        let head = (0.5 * fs) as usize;
        let run = |prime: bool, block: usize| {
            let mut d = Wiener::with_defaults(fs).unwrap();
            if prime {
                d.prime(lead);
            }
            let mut out = Vec::new();
            for c in x.chunks(block) {
                d.process(c, &mut out);
            }
            d.finish(&mut out);
            out.iter().map(|&v| v as f64).collect::<Vec<_>>()
        };
        let (cold, primed) = (run(false, 64), run(true, 64));
        assert_eq!(cold.len(), x.len());
        assert_eq!(primed.len(), x.len());
        assert_eq!(primed, run(true, 7), "block size changed the primed output");
        let (a, b, c) = (
            snr_db(&clean[..head], &noisy[..head]),
            snr_db(&clean[..head], &cold[..head]),
            snr_db(&clean[..head], &primed[..head]),
        );
        println!("first 0.5 s: SNR {a:.2} dB in, {b:.2} cold, {c:.2} primed");
        assert!(
            c >= b + 1.0 && c >= a + 1.0,
            "first 0.5 s: {a:.2} in, {b:.2} cold, {c:.2} primed"
        );
        // A lead shorter than a hop only resets.
        let mut d = Wiener::with_defaults(fs).unwrap();
        d.prime(&x[..3]);
        let mut out = Vec::new();
        d.process(&x, &mut out);
        d.finish(&mut out);
        assert_eq!(out.iter().map(|&v| v as f64).collect::<Vec<_>>(), cold);
    }

    // ----- streaming ---------------------------------------------------------------------

    /// Feeding blocks of 1, 37 or 4096 samples gives the same output bit for bit, and
    /// after every call exactly `total_in - latency` samples have been released.
    #[test]
    fn block_size_does_not_change_output() {
        for fs in [8000.0, 2200.0] {
            let noisy = to_f32(&add_noise(&speech_like(fs, 2.5), 3.0, 11));
            for method in METHODS {
                let mut outputs = Vec::new();
                for block in [1usize, 37, 4096] {
                    let mut d = Denoiser::new(method, fs, &DenoiseConfig::default());
                    let latency = d.latency();
                    let mut out = Vec::new();
                    let mut fed = 0usize;
                    for chunk in noisy.chunks(block) {
                        d.process(chunk, &mut out);
                        fed += chunk.len();
                        assert_eq!(out.len(), fed.saturating_sub(latency));
                    }
                    d.finish(&mut out);
                    assert_eq!(out.len(), noisy.len());
                    outputs.push(out);
                }
                for other in &outputs[1..] {
                    assert!(
                        outputs[0]
                            .iter()
                            .zip(other)
                            .all(|(a, b)| a.to_bits() == b.to_bits()),
                        "{method:?} at {fs} Hz differs between block sizes"
                    );
                }
            }
        }
    }

    /// `finish` resets: a second stream through the same object matches a fresh one.
    #[test]
    fn finish_resets_for_a_new_stream() {
        let fs = 8000.0;
        let x = to_f32(&add_noise(&speech_like(fs, 1.0), 0.0, 5));
        for method in METHODS {
            let mut d = Denoiser::new(method, fs, &DenoiseConfig::default());
            let first = run_on(&mut d, &x, 100);
            let second = run_on(&mut d, &x, 333);
            assert_eq!(first.len(), x.len());
            assert!(first
                .iter()
                .zip(&second)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    // ----- noise tracking ----------------------------------------------------------------

    /// Mean tracked noise power over the inner bins, in dB relative to `truth`.
    fn tracked_db(d: &Denoiser, truth: f64) -> f64 {
        let psd = d.noise_psd();
        let inner = &psd[1..psd.len() - 1];
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        10.0 * (mean / truth).log10()
    }

    /// White noise whose level steps up by 10 dB after 5 s: the tracked floor is within
    /// 3 dB of the old level before the step, still near it right after the step (no
    /// look-ahead), and within 3 dB of the new level 2 s after it. A 10 dB step down is
    /// followed within 0.5 s.
    #[test]
    fn noise_tracker_follows_level_steps() {
        for fs in [8000.0, 2200.0] {
            for overlap in [0.5, 0.75] {
                let cfg = DenoiseConfig {
                    overlap,
                    ..DenoiseConfig::default()
                };
                for method in METHODS {
                    let sigma2: f64 = 1e-4;
                    let step = (5.0 * fs) as usize;
                    let mut x = white(2 * step, sigma2.sqrt(), 3);
                    for v in &mut x[step..] {
                        *v *= 10f64.sqrt();
                    }
                    let x = to_f32(&x);
                    let mut d = Denoiser::new(method, fs, &cfg);
                    let mut out = Vec::new();
                    let at = |t: f64| (t * fs) as usize;

                    // Calibration on stationary noise, averaged over 2..5 s.
                    d.process(&x[..at(2.0)], &mut out);
                    let mut sum = 0.0;
                    let mut count = 0.0;
                    for w in (at(2.0)..step).collect::<Vec<_>>().chunks(at(0.25)) {
                        d.process(&x[w[0]..=w[w.len() - 1]], &mut out);
                        sum += tracked_db(&d, sigma2);
                        count += 1.0;
                    }
                    let before = sum / count;
                    d.process(&x[step..step + at(0.2)], &mut out);
                    let just_after = tracked_db(&d, 10.0 * sigma2);
                    d.process(&x[step + at(0.2)..step + at(2.0)], &mut out);
                    let after = tracked_db(&d, 10.0 * sigma2);
                    println!(
                        "fs {fs} overlap {overlap} {method:?}: before {before:+.2} dB, \
                         0.2 s after step {just_after:+.2} dB, 2 s after {after:+.2} dB"
                    );
                    assert!(before.abs() < 1.5, "stationary calibration {before:.2} dB");
                    assert!(just_after < -6.0, "reacted within 0.2 s: {just_after:.2}");
                    assert!(after.abs() < 3.0, "2 s after the step: {after:.2} dB");

                    // Step back down by 10 dB.
                    let down: Vec<f32> = white(at(0.5), sigma2.sqrt(), 9)
                        .iter()
                        .map(|&v| v as f32)
                        .collect();
                    d.process(&down, &mut out);
                    let after_down = tracked_db(&d, sigma2);
                    assert!(
                        after_down.abs() < 3.0,
                        "0.5 s after step down: {after_down:.2}"
                    );
                }
            }
        }
    }

    // ----- configuration errors and hostile input ------------------------------------------

    #[test]
    fn bad_configuration_is_rejected() {
        let ok = DenoiseConfig::default();
        for rate in [0.0, -8000.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                SpectralSubtraction::new(rate, &ok, 2.0, 0.02),
                Err(DenoiseError::InvalidRate(_))
            ));
            assert!(matches!(
                SpeechEnhance::new(rate, &ok),
                Err(DenoiseError::InvalidRate(_))
            ));
        }
        for overlap in [0.0, 0.6, 0.9, 1.0, f64::NAN] {
            let cfg = DenoiseConfig { overlap, ..ok };
            assert!(matches!(
                SpectralSubtraction::new(8000.0, &cfg, 2.0, 0.02),
                Err(DenoiseError::InvalidOverlap(_))
            ));
            assert!(matches!(
                SpeechEnhance::new(8000.0, &cfg),
                Err(DenoiseError::InvalidOverlap(_))
            ));
        }
        // 32 ms at 200 Hz is 6.4 samples; tiny rates likewise.
        for rate in [200.0, 1.0, 1e-300, f64::MIN_POSITIVE] {
            assert!(matches!(
                SpeechEnhance::new(rate, &ok),
                Err(DenoiseError::FrameTooShort { .. })
            ));
        }
        let short = DenoiseConfig {
            frame_ms: 0.5,
            ..ok
        };
        assert!(matches!(
            SpectralSubtraction::new(8000.0, &short, 2.0, 0.02),
            Err(DenoiseError::FrameTooShort { .. })
        ));
        // Exactly 8 samples is accepted.
        let eight = DenoiseConfig {
            frame_ms: 1.0,
            ..ok
        };
        let d = SpectralSubtraction::new(8000.0, &eight, 2.0, 0.02).unwrap();
        assert_eq!(d.frame_len(), 8);
        for rate in [1e12, 1e300, f64::MAX] {
            assert!(matches!(
                SpeechEnhance::new(rate, &ok),
                Err(DenoiseError::FrameTooLong { .. })
            ));
        }
        for frame_ms in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let cfg = DenoiseConfig { frame_ms, ..ok };
            assert!(matches!(
                SpeechEnhance::new(8000.0, &cfg),
                Err(DenoiseError::InvalidFrameMs(_))
            ));
        }
        for noise_window_s in [0.0, -1.0, f64::NAN, 1e9] {
            let cfg = DenoiseConfig {
                noise_window_s,
                ..ok
            };
            assert!(matches!(
                SpeechEnhance::new(8000.0, &cfg),
                Err(DenoiseError::InvalidParameter {
                    name: "noise_window_s",
                    ..
                })
            ));
        }
        for (alpha, beta) in [
            (-1.0, 0.02),
            (f64::NAN, 0.02),
            (2.0, -0.1),
            (2.0, 1.5),
            (2.0, f64::NAN),
        ] {
            assert!(matches!(
                SpectralSubtraction::new(8000.0, &ok, alpha, beta),
                Err(DenoiseError::InvalidParameter { .. })
            ));
        }
        for dd_alpha in [-0.1, 1.0, f64::NAN] {
            let cfg = DenoiseConfig { dd_alpha, ..ok };
            assert!(SpeechEnhance::new(8000.0, &cfg).is_err());
        }
        for xi_min_db in [1.0, f64::NAN, f64::NEG_INFINITY] {
            let cfg = DenoiseConfig { xi_min_db, ..ok };
            assert!(SpeechEnhance::new(8000.0, &cfg).is_err());
        }
        // Errors render.
        let msg = SpeechEnhance::new(0.0, &ok).err().unwrap().to_string();
        assert!(msg.contains("sample rate"));
    }

    #[test]
    fn hostile_input_never_panics() {
        let cfgs = [
            DenoiseConfig::default(),
            DenoiseConfig {
                overlap: 0.5,
                frame_ms: 4.0,
                noise_window_s: 1e-3,
                ..DenoiseConfig::default()
            },
        ];
        let specials = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            -f32::MAX,
            f32::MIN_POSITIVE,
            1e-45,
            0.0,
        ];
        let mut rng = Rng(99);
        let mixed: Vec<f32> = (0..5000)
            .map(|_| {
                let u = rng.next_u64();
                if u.is_multiple_of(7) {
                    specials[(u >> 8) as usize % specials.len()]
                } else {
                    rng.gauss() as f32
                }
            })
            .collect();
        let inputs: Vec<Vec<f32>> = vec![
            vec![],
            vec![0.5],
            vec![0.0; 3000],
            vec![f32::NAN; 3000],
            vec![f32::MAX; 3000],
            vec![1e-45; 3000],
            (0..3000)
                .map(|i| if i % 2 == 0 { f32::MAX } else { -f32::MAX })
                .collect(),
            mixed,
        ];
        for cfg in &cfgs {
            for method in METHODS {
                for fs in [8000.0, 2200.0, 192_000.0] {
                    let mut d = Denoiser::new(method, fs, cfg);
                    for x in &inputs {
                        let out = run_on(&mut d, x, 211);
                        assert_eq!(out.len(), x.len());
                        assert!(out.iter().all(|v| v.is_finite()), "{method:?} {fs}");
                        if x.iter().all(|&v| v == 0.0 || !v.is_finite()) {
                            assert!(out.iter().all(|&v| v == 0.0));
                        }
                    }
                }
            }
        }
    }
}
