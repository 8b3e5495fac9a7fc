//! The noise tracker every denoiser shares: minimum statistics with optimal smoothing
//! (Martin 2001), following the noise power spectrum while streaming, without look-ahead.

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
pub(super) struct NoiseTracker {
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
    pub(super) fn new(bins: usize, frame: usize, hop: usize, rate_hz: f64, window_s: f64) -> Self {
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

    pub(super) fn reset(&mut self) {
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
    pub(super) fn noise(&self) -> &[f64] {
        &self.sigma2
    }

    /// Feeds one frame's periodogram `y` (`bins` values, finite and non-negative).
    pub(super) fn update(&mut self, y: &[f64]) {
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
