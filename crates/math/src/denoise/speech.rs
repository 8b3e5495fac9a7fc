//! Speech enhancement by the MMSE log-spectral-amplitude estimator (Ephraim & Malah 1985):
//! the exponential integral its gain needs, the decision-directed gain rule (which also
//! gives [`super::Wiener`] its gain) and the [`SpeechEnhance`] denoiser.

use super::engine::{engine_methods, Engine, GainRule};
use super::{invalid, DenoiseConfig, DenoiseError};

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

/// Ephraim-Malah log-spectral-amplitude gain with the decision-directed a-priori SNR.
#[derive(Debug, Clone)]
pub(super) struct LogMmse {
    /// The Wiener gain `xi / (1 + xi)` (MMSE of the complex STFT coefficient)
    /// in place of the LSA gain.
    pub(super) wiener: bool,
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

/// Streaming speech enhancement by the MMSE log-spectral-amplitude estimator (Ephraim &
/// Malah 1985): per bin gain `xi / (1 + xi) * exp(E1(v) / 2)` with
/// `v = gamma xi / (1 + xi)`, a-posteriori SNR `gamma = |Y|² / noise` and the
/// decision-directed a-priori SNR
/// `xi = dd_alpha |S_prev|² / noise + (1 - dd_alpha) max(gamma - 1, 0)`, floored at
/// `xi_min_db`; the gain is capped at 1 and the noisy phase is kept. See the
/// [module documentation](super) for framing, noise tracking and latency.
pub struct SpeechEnhance {
    pub(super) engine: Engine<LogMmse>,
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

    /// Tracked noise power per frequency bin; see [`SpectralSubtraction::noise_psd`](super::SpectralSubtraction::noise_psd).
    pub fn noise_psd(&self) -> &[f64] {
        self.engine.tracker.noise()
    }
}

#[cfg(test)]
mod tests {
    use super::{expint_e1, lsa_gain};

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
}
