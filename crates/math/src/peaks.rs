//! Resonances in a power spectrum: peak picking by prominence, and damping
//! per peak (thesis ch. 5.5), each estimate with its uncertainty and the
//! name of the method that produced it.
//!
//! - **Prominence** (as in topography and `scipy.signal.peak_prominences`):
//!   the height of a local maximum of the dB spectrum above the higher of the
//!   two lowest points that separate it from higher ground on either side.
//!   Noise ripples on a mode's flank have little prominence; modes have a lot.
//! - **Lorentzian least squares** (`"lorentzian_ls"`): near a mode of damping
//!   ratio ξ, a lightly damped oscillator driven by broadband noise has
//!   P(f) ≈ A / (1 + ((f - f0)/γ)²) + B with half width γ = ξ f0 (Hz). The fit
//!   is done on ln P, where a Welch average's scatter is the same at every
//!   bin (so plain least squares is the right weighting, and a constant
//!   bias of the log only scales A and B). The fit range, which the thesis
//!   asked a person to drag, is chosen automatically: ±`RANGE_HALF_WIDTHS`
//!   half widths around the peak, bounded by the valleys that separate it
//!   from its neighbours, re-centred on the fit until it settles.
//!   Uncertainty: the Gauss-Newton covariance s² (JᵀJ)⁻¹ with s² the
//!   residual variance, inflated by (1 + ρ)/(1 - ρ) for the lag-1 correlation
//!   ρ of the residuals (tapers correlate neighbouring bins).
//! - **Half-power bandwidth** (`"half_power"`): ξ = Δf / (2 f0), Δf the width
//!   at half the peak's height above the background, crossings interpolated
//!   between bins. Uncertainty: each crossing moves by s·γ for a relative
//!   power scatter s (the slope of a Lorentzian at half power is A / 2γ).
//!
//! A peak narrower than the bin spacing can resolve (fitted half width under
//! `MIN_RESOLVED_BINS` bins, or twice that of raw half-power width when the
//! fit fails) is marked unresolved: its damping is then only
//! an upper bound, and says so in its method.

/// Fit range, in fitted half widths either side of the peak.
pub const RANGE_HALF_WIDTHS: f64 = 4.0;
/// Below this half width (in bins) a peak is not resolved by the spectrum.
pub const MIN_RESOLVED_BINS: f64 = 1.5;

/// What to look for.
#[derive(Clone, Debug)]
pub struct PeakOptions {
    /// At most this many peaks (the most prominent).
    pub max_peaks: usize,
    /// Ignore peaks less prominent than this (dB).
    pub min_prominence_db: f64,
    /// Search band (Hz); `None` = from 3 bins above DC / up to Nyquist.
    pub min_hz: Option<f64>,
    pub max_hz: Option<f64>,
    /// The taper's power response |W|² at steps of [`KERNEL_STEP`] bins
    /// (odd length, centred); empty = fit the bare Lorentzian.
    pub window_kernel: Vec<f64>,
    /// Spectra averaged into `power` (Welch segments times spectra): a
    /// noise bin's power is then its mean times χ²₂ₖ/2K, which sets how
    /// far above its floor noise alone reaches ([`significance`]).
    pub segments: usize,
    /// Report only peaks whose false-alarm probability over the band
    /// searched is at most this (`None`: report every prominent peak, each
    /// with its probability).
    pub max_false_alarm: Option<f64>,
}

/// The default family-wise false-alarm probability a reported peak must
/// stay under: 1% that noise alone puts a peak this high anywhere in the
/// band searched.
pub const DEFAULT_FALSE_ALARM: f64 = 0.01;

impl Default for PeakOptions {
    fn default() -> Self {
        Self {
            max_peaks: 5,
            min_prominence_db: 6.0,
            min_hz: None,
            max_hz: None,
            window_kernel: Vec::new(),
            segments: 1,
            max_false_alarm: Some(DEFAULT_FALSE_ALARM),
        }
    }
}

/// The largest damping ratio a resonance may have (issue 51). A mode's
/// half-power band is 2ζ f wide: at ζ = 0.25 it spans half the mode's
/// frequency, and above ζ = 1/√2 a driven oscillator's displacement has no
/// peak at all. Structures measured by vibrometry ring far below it (ζ of
/// 0.001-0.1); a hump broader than this is coloured noise, a drift's knee
/// or several lines smeared together, not a mode to name. The bound
/// applies to a measured damping, not to the upper bound an unresolved
/// peak carries.
pub const MAX_MODE_DAMPING: f64 = 0.25;
/// A resonance's frequency uncertainty must be below this fraction of its
/// frequency (the line is resolved or bounded): a "peak" at 0.5 ± 18 Hz
/// is the spectrum's slope, not a line. A quarter lets a line two bins
/// from zero through (its bin quantisation, df/√12, is 14% of it): the
/// slowest sway a record's spectrum can show, which the drift test then
/// measures against the drift floor.
pub const MAX_RELATIVE_FREQUENCY_STD: f64 = 0.25;

/// The steepest floor taken for a drift (a random walk's is 2; see
/// `classify`).
pub const MAX_DRIFT_BETA: f64 = 2.5;

/// What a spectral peak is (issue 51's resonance test).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PeakClass {
    /// A line: resolved or bounded, damping plausible for a mode, above
    /// both its local floor and the spectrum's fitted drift floor.
    Resonance,
    /// The low-frequency continuation of a drift (1/f^β) spectrum: not
    /// above the drift floor fitted to the spectrum's low end.
    Drift,
    /// Too broad, or its frequency too uncertain, to be a mode.
    Broadband,
}

/// A spectrum's floor as a drift plus white noise: P(f) ≈ A f^-β + C.
/// The white level C is the median of the upper half of the spectrum; A
/// and β are fitted (least squares in log-log, bands sticking out above
/// the fit left out) to the medians of log-spaced bands of at least three
/// bins, over the run of lowest bands that stand at least twice above C.
/// No such run: A = 0 (no drift).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DriftFloor {
    pub a: f64,
    pub beta: f64,
    pub white: f64,
}

impl DriftFloor {
    /// The floor's mean power at `f` Hz.
    pub fn at(&self, f: f64) -> f64 {
        self.drift(f) + self.white
    }

    /// The drift's part at `f` Hz.
    pub fn drift(&self, f: f64) -> f64 {
        if self.a > 0.0 && f > 0.0 {
            self.a * f.powf(-self.beta)
        } else {
            0.0
        }
    }

    /// Fits the floor of `power` (`power[k]` at `f0 + k df`, `k_avg`
    /// spectra averaged).
    pub fn fit(power: &[f64], f0_hz: f64, df_hz: f64, k_avg: usize) -> DriftFloor {
        Self::fit_without(power, f0_hz, df_hz, k_avg, 0..0)
    }

    /// [`DriftFloor::fit`] with the bins of `skip` left out of its bands
    /// (a candidate's own lobe, which would otherwise hold the fit up at
    /// its own frequency).
    pub fn fit_without(
        power: &[f64],
        f0_hz: f64,
        df_hz: f64,
        k_avg: usize,
        skip: std::ops::Range<usize>,
    ) -> DriftFloor {
        let to_mean = 1.0 / chi2_ratio_median(k_avg.max(1));
        let first = (1..power.len()).find(|&i| f0_hz + i as f64 * df_hz > 0.0);
        let Some(first) = first else {
            return DriftFloor {
                a: 0.0,
                beta: 0.0,
                white: 0.0,
            };
        };
        let median = |v: &mut Vec<f64>| -> f64 {
            v.retain(|x| x.is_finite());
            if v.is_empty() {
                return 0.0;
            }
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let upper: Vec<f64> = power[(power.len() / 2).max(first)..].to_vec();
        let white = median(&mut upper.clone()) * to_mean;
        // Log-spaced bands: a quarter octave, at least three bins.
        let mut bands: Vec<(f64, f64)> = Vec::new();
        let mut i = first;
        while i + 3 <= power.len() {
            let w = ((i as f64) * 0.19).round().max(3.0) as usize;
            let j = (i + w).min(power.len());
            if i < skip.end && j > skip.start {
                // Overlaps the lobe left out: skipped, the run goes on.
                i = j;
                continue;
            }
            let mut v = power[i..j].to_vec();
            let m = median(&mut v) * to_mean;
            let f = f0_hz + 0.5 * (i + j - 1) as f64 * df_hz;
            if m.is_nan() || m <= 2.0 * white {
                break;
            }
            bands.push((f.ln(), (m - white).ln()));
            i = j;
        }
        if bands.len() < 2 {
            return DriftFloor {
                a: 0.0,
                beta: 0.0,
                white,
            };
        }
        let mut keep = vec![true; bands.len()];
        let mut fit = (0.0, 0.0);
        for _ in 0..3 {
            let pts: Vec<(f64, f64)> = bands
                .iter()
                .zip(&keep)
                .filter_map(|(b, &k)| k.then_some(*b))
                .collect();
            if pts.len() < 2 {
                break;
            }
            let Some((mx, my, slope)) = crate::numeric::line_fit(&pts) else {
                break;
            };
            fit = (my - slope * mx, slope);
            // Bands sticking out above the line by more than 6 dB hold a
            // line of their own: left out of the next fit.
            for (b, k) in bands.iter().zip(keep.iter_mut()) {
                *k = b.1 - (fit.0 + fit.1 * b.0) < 4f64.ln();
            }
        }
        let beta = (-fit.1).clamp(0.0, 6.0);
        DriftFloor {
            a: fit.0.exp(),
            beta,
            white,
        }
    }
}

/// Why a peak is not a resonance by its shape alone (frequency
/// uncertainty, damping), or `None`: [`shape_refusal_of`] on its fields.
pub fn shape_refusal(p: &Peak) -> Option<(PeakClass, String)> {
    shape_refusal_of(
        p.frequency_hz,
        p.frequency_std_hz,
        (p.damping_ratio, p.damping_ratio_std),
        &p.damping_method,
    )
}

/// The method name of a damping fitted in the time domain to a record of
/// few cycles (set by the recipe layer, which has the record).
pub const TIME_FIT: &str = "time_fit";

/// Standard deviations a [`TIME_FIT`] damping's 95% interval spans:
/// Student's t at 97.5% for 4 degrees of freedom. The fit's uncertainty is
/// the larger of the residual's and a five-block jackknife's
/// ([`crate::sinefit`]), and the jackknife's spread has four degrees of
/// freedom, so the normal distribution's 1.96 would claim too much.
pub const TIME_FIT_COVERAGE: f64 = 2.776;

/// Why a peak of frequency `f` ± `f_std` Hz and damping ratio `zeta` ±
/// `zeta_std` (by `method`; a `resolution_limit` is only an upper bound,
/// which says nothing against a mode) is not a resonance, or `None`.
/// Applied again after a time-domain refinement changes a peak's damping.
/// A [`TIME_FIT`] damping is the only measure a few-cycle record gives, and
/// it must show the damping below [`MAX_MODE_DAMPING`] at 95% confidence
/// ([`TIME_FIT_COVERAGE`] standard deviations): two or three cycles of a
/// slow wander fit a damped sinusoid too, with a damping the fit cannot
/// pin down.
pub fn shape_refusal_of(
    f: f64,
    f_std: f64,
    (zeta, zeta_std): (f64, f64),
    method: &str,
) -> Option<(PeakClass, String)> {
    if !(f.is_finite() && f > 0.0) {
        return Some((PeakClass::Broadband, "no positive frequency".into()));
    }
    if !(f_std.is_finite() && f_std <= MAX_RELATIVE_FREQUENCY_STD * f) {
        return Some((
            PeakClass::Broadband,
            format!(
                "frequency {f:.4} ± {f_std:.4} Hz: its uncertainty is not below {:.0}% of it, so no line is resolved there",
                MAX_RELATIVE_FREQUENCY_STD * 100.0
            ),
        ));
    }
    if !method.starts_with("resolution_limit") && zeta.is_finite() && zeta > MAX_MODE_DAMPING {
        return Some((
            PeakClass::Broadband,
            format!("damping ratio {zeta:.3} ({method}) is above {MAX_MODE_DAMPING}, broader than a mode"),
        ));
    }
    let bounded = zeta + TIME_FIT_COVERAGE * zeta_std <= MAX_MODE_DAMPING;
    if method == TIME_FIT && !bounded {
        return Some((
            PeakClass::Broadband,
            format!(
                "damping ratio {zeta:.3} ± {zeta_std:.3} ({method}): too few cycles in the record to bound it below {MAX_MODE_DAMPING} (at 95% confidence), so a mode cannot be told from a wander"
            ),
        ));
    }
    None
}

/// One damping estimate.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DampingEstimate {
    pub method: String,
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
}

/// A resonance.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Peak {
    pub frequency_hz: f64,
    pub frequency_std_hz: f64,
    pub power_db: f64,
    pub prominence_db: f64,
    /// The preferred estimate (the Lorentzian fit when it converged and is
    /// resolved, else the half-power bandwidth).
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
    pub damping_method: String,
    /// Every estimate made, with its method.
    pub damping_estimates: Vec<DampingEstimate>,
    /// Fit range used by the Lorentzian fit (Hz).
    pub fit_range_hz: [f64; 2],
    /// The half width is at least `MIN_RESOLVED_BINS` bins.
    pub resolved: bool,
    /// The local noise floor at the peak (dB): the median of the spectrum
    /// over [`floor_half_window`] bins either side, scaled from median to
    /// mean for the spectrum's K averages.
    pub floor_db: f64,
    /// The probability that noise alone puts a peak at least this far
    /// above its floor anywhere in the band searched (the per-bin
    /// probability times the bins searched, at most 1).
    pub false_alarm: f64,
    /// What the resonance test made of it.
    pub class: PeakClass,
    /// Why it is not a resonance (empty for a resonance).
    pub class_reason: String,
}

/// A local maximum with its prominence and the valleys that bound it.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    bin: usize,
    prominence_db: f64,
    left_base: usize,
    right_base: usize,
}

/// Local maxima of `db` in `[lo, hi]` with their prominences.
fn candidates(db: &[f64], lo: usize, hi: usize) -> Vec<Candidate> {
    let mut out = Vec::new();
    if db.len() < 3 {
        return out;
    }
    let hi = hi.min(db.len() - 2);
    for i in lo.max(1)..=hi {
        if !(db[i] > db[i - 1] && db[i] >= db[i + 1]) {
            continue;
        }
        // Walk outwards until higher ground (or the end), tracking the minimum.
        let (mut lmin, mut lbase) = (db[i], i);
        let mut j = i;
        while j > 0 {
            j -= 1;
            if db[j] > db[i] {
                break;
            }
            if db[j] < lmin {
                lmin = db[j];
                lbase = j;
            }
        }
        let (mut rmin, mut rbase) = (db[i], i);
        let mut j = i;
        while j + 1 < db.len() {
            j += 1;
            if db[j] > db[i] {
                break;
            }
            if db[j] < rmin {
                rmin = db[j];
                rbase = j;
            }
        }
        out.push(Candidate {
            bin: i,
            prominence_db: db[i] - lmin.max(rmin),
            left_base: lbase,
            right_base: rbase,
        });
    }
    out
}

/// P(X ≥ r) for X = χ²₂ₖ/2K, the ratio of a K-average power estimate of
/// noise to its mean: e^{-Kr} Σ_{j<K} (Kr)^j / j!, summed in logs.
pub fn chi2_ratio_sf(r: f64, k: usize) -> f64 {
    if r.is_nan() {
        return f64::NAN;
    }
    if r <= 0.0 {
        return 1.0;
    }
    let k = k.max(1);
    let x = k as f64 * r;
    let (mut log_term, mut log_sum) = (-x, -x);
    for j in 1..k {
        log_term += x.ln() - (j as f64).ln();
        let (a, b) = (log_sum.max(log_term), log_sum.min(log_term));
        log_sum = a + (b - a).exp().ln_1p();
    }
    log_sum.exp().min(1.0)
}

/// The level r that χ²₂ₖ/2K exceeds with probability `p` (the inverse of
/// [`chi2_ratio_sf`], by bisection; `p` in (0, 1)).
pub fn chi2_ratio_isf(p: f64, k: usize) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while chi2_ratio_sf(hi, k) > p && hi < 1e6 {
        (lo, hi) = (hi, 2.0 * hi);
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if chi2_ratio_sf(mid, k) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The median of χ²₂ₖ/2K (the ratio of a noise bin's running median to
/// its mean): ln 2 for K = 1, toward 1 as K grows.
pub fn chi2_ratio_median(k: usize) -> f64 {
    chi2_ratio_isf(0.5, k)
}

/// Bins either side of a peak over which its noise floor is the median:
/// ten of its half widths (its lobe is then a fifth of the window, so it
/// cannot hold up its own floor), at least 32; narrow enough that a bump on
/// a wide mode's skirt is measured against the skirt, not the floor below.
pub fn floor_half_window(half_width_bins: usize) -> usize {
    (10 * half_width_bins).max(32)
}

/// Half width (bins) of the lobe at `i`: the first bins either side under
/// half its power.
fn rough_half_width(p: &[f64], i: usize) -> usize {
    let half = 0.5 * p[i];
    let left = (0..i).rev().find(|&j| p[j] < half).map_or(i, |j| i - j);
    let right = (i + 1..p.len())
        .find(|&j| p[j] < half)
        .map_or(p.len() - 1 - i, |j| j - i);
    left.max(right)
}

/// The median of `p` over `half` bins either side of `i`.
fn median_around(p: &[f64], i: usize, half: usize) -> f64 {
    let mut v: Vec<f64> = p[i.saturating_sub(half)..(i + half + 1).min(p.len())]
        .iter()
        .copied()
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if v.is_empty() {
        return f64::MIN_POSITIVE;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The noise floor (mean power) under the peak at bin `i` (the median
/// around it scaled from median to mean for K averages), and the
/// false-alarm probability of its power over `searched` bins.
fn significance(p: &[f64], i: usize, k: usize, searched: usize) -> (f64, f64) {
    let half = floor_half_window(rough_half_width(p, i));
    let floor = median_around(p, i, half) / chi2_ratio_median(k);
    let r = p[i] / floor.max(f64::MIN_POSITIVE);
    (
        floor,
        (chi2_ratio_sf(r, k) * searched.max(1) as f64).min(1.0),
    )
}

/// Finds the most prominent peaks of `power` (`power[k]` at `f0 + k df`),
/// keeps those significant against the local noise floor
/// ([`PeakOptions::max_false_alarm`]) and estimates each one's damping.
/// Peaks come back strongest first.
pub fn find_peaks(power: &[f64], f0_hz: f64, df_hz: f64, opts: &PeakOptions) -> Vec<Peak> {
    find_peaks_classified(power, f0_hz, df_hz, opts).0
}

/// [`find_peaks`], and beside the resonances the peaks the resonance test
/// turned away (drift, broadband), each with its class and reason: at
/// most `max_peaks` of each, strongest first.
pub fn find_peaks_classified(
    power: &[f64],
    f0_hz: f64,
    df_hz: f64,
    opts: &PeakOptions,
) -> (Vec<Peak>, Vec<Peak>) {
    if power.len() < 5 || !(df_hz.is_finite() && df_hz > 0.0) {
        return (Vec::new(), Vec::new());
    }
    let floor = power
        .iter()
        .copied()
        .filter(|p| p.is_finite() && *p > 0.0)
        .fold(f64::INFINITY, f64::min);
    let floor = if floor.is_finite() { floor } else { 1e-300 };
    let db: Vec<f64> = power
        .iter()
        .map(|&p| 10.0 * (if p.is_finite() && p > 0.0 { p } else { floor }).log10())
        .collect();
    let bin_of = |f: f64| ((f - f0_hz) / df_hz).round().max(0.0) as usize;
    // From the second bin above DC (a slow sway in a short clip), unless
    // a band is given.
    let lo = opts.min_hz.map_or(2, |f| bin_of(f).max(1));
    let hi = opts.max_hz.map_or(power.len() - 2, bin_of);
    let k = opts.segments.max(1);
    let searched = hi.saturating_sub(lo) + 1;
    let mut c = candidates(&db, lo, hi);
    c.retain(|c| c.prominence_db >= opts.min_prominence_db);
    let alpha = opts.max_false_alarm;
    if let Some(alpha) = alpha {
        c.retain(|c| significance(power, c.bin, k, searched).1 <= alpha);
    }
    // Strongest first: each peak is tested against its floor plus the
    // lines already accepted (a noise bump on a strong line's skirt is the
    // line, not a peak of its own).
    c.sort_by(|a, b| db[b.bin].total_cmp(&db[a.bin]).then(a.bin.cmp(&b.bin)));
    let mut peaks: Vec<Peak> = Vec::new();
    let mut lines: Vec<(f64, f64, f64)> = Vec::new(); // (f0, γ, height above floor)
    for c in &c {
        let (floor, _) = significance(power, c.bin, k, searched);
        let f = f0_hz + c.bin as f64 * df_hz;
        // Within eight half widths: farther out the local median already
        // holds a real skirt, and an unresolved line's γ is only a bound.
        let skirts: f64 = lines
            .iter()
            .filter(|&&(fl, g, _)| (f - fl).abs() <= 8.0 * g)
            .map(|&(fl, g, h)| h / (1.0 + ((f - fl) / g).powi(2)))
            .sum();
        let r = power[c.bin] / (floor + skirts).max(f64::MIN_POSITIVE);
        let p = (chi2_ratio_sf(r, k) * searched as f64).min(1.0);
        if alpha.is_some_and(|a| p > a) {
            continue;
        }
        let mut pk = analyse(&opts.window_kernel, power, &db, f0_hz, df_hz, c);
        pk.floor_db = 10.0 * floor.max(f64::MIN_POSITIVE).log10();
        pk.false_alarm = p;
        let (s, quantum) = (pk.frequency_std_hz, df_hz / 12f64.sqrt());
        if !(s.is_finite() && s > 0.0) || (s > quantum && !pk.resolved) {
            // A fit too exact to scatter, or one that scattered over a
            // line no wider than the bins: the peak bin bounds the line,
            // to its quantisation.
            pk.frequency_std_hz = quantum;
        }
        classify(&mut pk, (power, f0_hz, df_hz), k, searched, alpha);
        let gamma = (pk.damping_ratio * pk.frequency_hz).max(df_hz);
        lines.push((pk.frequency_hz, gamma, (power[c.bin] - floor).max(0.0)));
        peaks.push(pk);
    }
    let (mut peaks, mut others): (Vec<Peak>, Vec<Peak>) = peaks
        .into_iter()
        .partition(|p| p.class == PeakClass::Resonance);
    for list in [&mut peaks, &mut others] {
        // The most prominent `max_peaks`, then strongest first.
        list.sort_by(|a, b| {
            b.prominence_db
                .total_cmp(&a.prominence_db)
                .then(a.frequency_hz.total_cmp(&b.frequency_hz))
        });
        list.truncate(opts.max_peaks);
        list.sort_by(|a, b| {
            b.power_db
                .total_cmp(&a.power_db)
                .then(a.frequency_hz.total_cmp(&b.frequency_hz))
        });
    }
    (peaks, others)
}

/// The resonance test of one peak of `power` (`power[i]` at `f0 + i df`):
/// where the drift fitted without the peak's own lobe
/// ([`DriftFloor::fit_without`]) dominates the white floor, its lobe's height
/// above the drift floor, which must be as unlikely from noise as `alpha`
/// (default [`DEFAULT_FALSE_ALARM`]) over the `searched` bins; then its
/// shape ([`shape_refusal`]). The lobe is the bins within the peak's half
/// width (at least its own bin): their mean of m bins of K averages
/// scatters as χ²₂ₖₘ/2Km, and the band holds searched/m such lobes, so a
/// broad mode is tested by all of its power, not by its top bin's.
fn classify(
    pk: &mut Peak,
    (power, f0_hz, df_hz): (&[f64], f64, f64),
    k: usize,
    searched: usize,
    alpha: Option<f64>,
) {
    let f = pk.frequency_hz;
    let centre = ((f - f0_hz) / df_hz).round();
    // The floor without this peak's own lobe (at least 3 bins either side).
    let own = ((pk.damping_ratio * f / df_hz).ceil()).clamp(3.0, 64.0);
    let drift = &DriftFloor::fit_without(
        power,
        f0_hz,
        df_hz,
        k,
        (centre - own).max(0.0) as usize..(centre + own + 1.0).max(0.0) as usize,
    );
    let half = ((pk.damping_ratio * f / df_hz).floor()).clamp(0.0, 64.0);
    let (lo, hi) = (
        (centre - half).max(1.0) as usize,
        ((centre + half) as usize).min(power.len().saturating_sub(1)),
    );
    let (mut lobe, mut floor) = (0.0, 0.0);
    for i in lo..=hi.max(lo) {
        let fi = f0_hz + i as f64 * df_hz;
        lobe += power.get(i).copied().unwrap_or(0.0);
        floor += drift.at(fi);
    }
    let m = hi.max(lo) - lo + 1;
    // A drift falls as 1/f^β with β from 1 (flicker) to 2 (a random
    // walk): a flatter floor is coloured noise, which the local floor
    // already measures a peak against, and a steeper one is the skirt of a
    // line (a Lorentzian falls as 1/(f - f0)², steeper than 2 in log f),
    // which must not be extrapolated back over the line itself.
    if (1.0..=MAX_DRIFT_BETA).contains(&drift.beta) && drift.drift(f) > drift.white {
        let r = lobe / floor.max(f64::MIN_POSITIVE);
        let lobes = (searched.max(1) as f64 / m as f64).max(1.0);
        let p = (chi2_ratio_sf(r, k * m) * lobes).min(1.0);
        let alpha = alpha.unwrap_or(DEFAULT_FALSE_ALARM);
        if p > alpha {
            pk.class = PeakClass::Drift;
            pk.class_reason = format!(
                "{:.1} dB above the drift floor fitted to the spectrum's low end (1/f^{:.1}) over its {m} bin(s); a line needs {:.1} dB (false alarm {alpha})",
                10.0 * r.max(f64::MIN_POSITIVE).log10(),
                drift.beta,
                10.0 * chi2_ratio_isf(alpha / lobes, k * m).log10()
            );
            return;
        }
    }
    if let Some((class, why)) = shape_refusal(pk) {
        pk.class = class;
        pk.class_reason = why;
    }
}

fn analyse(kernel: &[f64], p: &[f64], db: &[f64], f0_hz: f64, df: f64, c: &Candidate) -> Peak {
    let freq = |k: f64| f0_hz + k * df;
    let i = c.bin;
    // Sub-bin peak position by a parabola through the dB values.
    let (ym, y0, yp) = (db[i - 1], db[i], db[i + 1]);
    let den = ym - 2.0 * y0 + yp;
    let delta = if den < 0.0 {
        (0.5 * (ym - yp) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let f_peak = freq(i as f64 + delta);
    let background = p[c.left_base].max(p[c.right_base]).min(p[i]);

    // Initial half width: half-power crossings on a running mean whose
    // length follows the width found (noise dips near the top would stop a
    // walk on the raw bins early; averaging over a fraction of the width
    // barely widens the peak).
    let mut hw_bins = 1.0f64;
    for _ in 0..4 {
        let m = ((hw_bins / 3.0).floor() as usize).max(1);
        let (lo, hi) = half_power_bins(p, c, m, None);
        let new = 0.5 * (hi - lo);
        if (new - hw_bins).abs() < 0.5 {
            hw_bins = new;
            break;
        }
        hw_bins = new;
    }
    let hw0 = (hw_bins * df).max(0.5 * df);

    let fit = lorentzian_fit(kernel, p, df, f0_hz, c, (f_peak, hw0, background));
    // Half-power bandwidth: the level is half the fitted peak above the
    // fitted background (else above the valleys), the crossings are found on
    // a running mean over a quarter of the half width.
    let (level, m) = match &fit {
        Some(f) => (
            f.background + 0.5 * f.amplitude,
            ((f.gamma / df / 4.0).floor() as usize).max(1),
        ),
        None => (
            background + 0.5 * (p[i] - background),
            ((hw_bins / 3.0).floor() as usize).max(1),
        ),
    };
    let (lo_b, hi_b) = half_power_bins(p, c, m, Some(level));
    let hp_width = ((hi_b - lo_b) * df).max(0.5 * df);
    let mut estimates = Vec::new();
    let (freq_hz, freq_std, range, resolved, s_rel, gamma) = match &fit {
        Some(fit) => (
            fit.f0,
            fit.f0_std,
            [fit.lo_hz, fit.hi_hz],
            fit.gamma >= MIN_RESOLVED_BINS * df,
            fit.s,
            fit.gamma,
        ),
        None => (
            f_peak,
            df / 12f64.sqrt(),
            [freq(c.left_base as f64), freq(c.right_base as f64)],
            // No fit, so no correction for the taper's own line width
            // (a Hann line is about a bin either side): ask for twice as much.
            hw_bins >= 2.0 * MIN_RESOLVED_BINS,
            1.0,
            hw0,
        ),
    };
    let suffix = if resolved {
        ""
    } else {
        " (unresolved: upper bound)"
    };
    if let Some(fit) = &fit {
        let xi = fit.gamma / fit.f0;
        estimates.push(DampingEstimate {
            method: format!("lorentzian_ls{suffix}"),
            damping_ratio: xi,
            damping_ratio_std: xi * fit.ln_gamma_std,
        });
    }
    // Half power: each crossing moves by s·γ (and by a bin's quantisation
    // when the scatter is smaller than that).
    let edge = (s_rel * gamma).hypot(df / 12f64.sqrt());
    let xi_hp = hp_width / (2.0 * freq_hz);
    estimates.push(DampingEstimate {
        method: format!("half_power{suffix}"),
        damping_ratio: xi_hp,
        damping_ratio_std: edge * std::f64::consts::SQRT_2 / (2.0 * freq_hz),
    });
    // The preferred estimate: the fit when resolved, else half power when
    // that is resolved, else only the bound the bin spacing sets.
    let best = if resolved {
        estimates[0].clone()
    } else if fit.is_some() && 0.5 * hp_width >= 2.0 * MIN_RESOLVED_BINS * df {
        estimates[estimates.len() - 1].clone()
    } else {
        DampingEstimate {
            method: "resolution_limit (upper bound: peak narrower than the bins)".into(),
            damping_ratio: MIN_RESOLVED_BINS * df / freq_hz,
            damping_ratio_std: 0.0,
        }
    };
    Peak {
        frequency_hz: freq_hz,
        frequency_std_hz: freq_std,
        power_db: db[i],
        prominence_db: c.prominence_db,
        damping_ratio: best.damping_ratio,
        damping_ratio_std: best.damping_ratio_std,
        damping_method: best.method,
        damping_estimates: estimates,
        fit_range_hz: range,
        resolved,
        floor_db: f64::NAN,
        false_alarm: f64::NAN,
        class: PeakClass::Resonance,
        class_reason: String::new(),
    }
}

/// Half-power crossings (fractional bins) of the running mean of `p` over
/// `2m + 1` bins, walking out from the candidate's top within its valleys.
/// `level`: the half-power level (default: halfway between the smoothed
/// top and the higher valley).
fn half_power_bins(p: &[f64], c: &Candidate, m: usize, level: Option<f64>) -> (f64, f64) {
    let (a, b) = (c.left_base, c.right_base);
    let smooth = |k: usize| {
        let lo = k.saturating_sub(m).max(a);
        let hi = (k + m).min(b);
        p[lo..=hi].iter().sum::<f64>() / (hi - lo + 1) as f64
    };
    // The smoothed top near the candidate.
    let (mut top, mut top_v) = (c.bin, smooth(c.bin));
    for k in c.bin.saturating_sub(m).max(a)..=(c.bin + m).min(b) {
        let v = smooth(k);
        if v > top_v {
            top = k;
            top_v = v;
        }
    }
    let background = p[a].max(p[b]).min(top_v);
    let half = level.unwrap_or(background + 0.5 * (top_v - background));
    let frac = |k_in: usize, k_out: usize| {
        let (vi, vo) = (smooth(k_in), smooth(k_out));
        let t = if vi > vo {
            ((vi - half) / (vi - vo)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        k_in as f64 + t * (k_out as f64 - k_in as f64)
    };
    let mut l = top;
    while l > a && smooth(l - 1) > half {
        l -= 1;
    }
    let lo = if l > a { frac(l, l - 1) } else { a as f64 };
    let mut r = top;
    while r < b && smooth(r + 1) > half {
        r += 1;
    }
    let hi = if r < b { frac(r, r + 1) } else { b as f64 };
    (lo, hi)
}

/// A Lorentzian fitted to one peak.
#[derive(Clone, Debug)]
pub struct LorentzFit {
    pub f0: f64,
    pub f0_std: f64,
    /// Half width at half maximum (Hz).
    pub gamma: f64,
    /// Standard deviation of ln γ (the relative uncertainty of γ).
    pub ln_gamma_std: f64,
    pub amplitude: f64,
    pub background: f64,
    /// Residual scatter of ln P (relative power scatter).
    pub s: f64,
    pub lo_hz: f64,
    pub hi_hz: f64,
}

/// The peak model: a Lorentzian seen through the taper's spectral window
/// (the expected periodogram is the true spectrum convolved with the
/// window's power response |W|², which widens a peak a few bins wide), plus
/// a flat background.
struct Model<'a> {
    /// |W|² at steps of `KERNEL_STEP` bins, centred, summing to 1; empty = none.
    kernel: &'a [f64],
    df: f64,
}

/// Spacing of the window-kernel taps, in bins.
pub const KERNEL_STEP: f64 = 0.25;

impl Model<'_> {
    /// Kernel taps as (frequency offset, weight).
    fn taps(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        let mid = (self.kernel.len() / 2) as f64;
        let one = [(0.0, 1.0)];
        let k = self
            .kernel
            .iter()
            .enumerate()
            .map(move |(j, &w)| ((j as f64 - mid) * KERNEL_STEP * self.df, w));
        let none = self.kernel.is_empty();
        one.into_iter().filter(move |_| none).chain(k)
    }

    /// ln of the model at `f` for parameters [f0, ln γ, ln A, ln B].
    fn ln(&self, q: &[f64; 4], f: f64) -> f64 {
        let g = q[1].exp();
        let l: f64 = self
            .taps()
            .map(|(d, w)| {
                let x = (f - d - q[0]) / g;
                w / (1.0 + x * x)
            })
            .sum();
        (q[2].exp() * l + q[3].exp()).ln()
    }

    /// Gradient of ln model with respect to [f0, ln γ, ln A, ln B].
    fn jac(&self, q: &[f64; 4], f: f64) -> [f64; 4] {
        let g = q[1].exp();
        let a = q[2].exp();
        let b = q[3].exp();
        let (mut l, mut dl0, mut dlg) = (0.0, 0.0, 0.0);
        for (d, w) in self.taps() {
            let x = (f - d - q[0]) / g;
            let den = 1.0 + x * x;
            l += w / den;
            dl0 += w * 2.0 * x / (g * den * den);
            dlg += w * 2.0 * x * x / (den * den);
        }
        let m = a * l + b;
        [a * dl0 / m, a * dlg / m, a * l / m, b / m]
    }
}

/// Least squares on ln P over an automatically chosen range (see the module
/// documentation), from an initial guess (peak frequency, half width,
/// background). `None` when the fit does not converge to a peak inside
/// its range.
fn lorentzian_fit(
    kernel: &[f64],
    p: &[f64],
    df: f64,
    f0_hz: f64,
    c: &Candidate,
    (f_peak, gamma0, background): (f64, f64, f64),
) -> Option<LorentzFit> {
    let model = Model { kernel, df };
    let b0 = background.max(p[c.bin] * 1e-12);
    let a0 = (p[c.bin] - background).max(p[c.bin] * 1e-3);
    let mut q = [f_peak, gamma0.max(0.5 * df).ln(), a0.ln(), b0.ln()];
    let mut range = (0usize, 0usize);
    let mut last = None;
    for _round in 0..6 {
        let g = q[1].exp();
        let half = (RANGE_HALF_WIDTHS * g / df).ceil() as usize;
        let half = half.max(4);
        let centre = ((q[0] - f0_hz) / df).round().max(0.0) as usize;
        let lo = centre.saturating_sub(half).max(c.left_base).max(1);
        let hi = (centre + half).min(c.right_base).min(p.len() - 1);
        if hi < lo + 5 {
            // Too few bins between the valleys: widen to 5 bins either side.
            let lo2 = c.bin.saturating_sub(5).max(1);
            let hi2 = (c.bin + 5).min(p.len() - 1);
            if hi2 < lo2 + 5 {
                return None;
            }
            range = (lo2, hi2);
        } else {
            range = (lo, hi);
        }
        if last == Some(range) {
            break;
        }
        last = Some(range);
        q = gauss_newton(&model, p, f0_hz, range, q)?;
    }
    fit_stats(&model, p, f0_hz, range, q)
}

/// A Lorentzian fitted over exactly the bins of `[lo_hz, hi_hz]` of
/// `power` (`power[k]` at `f0_hz + k df_hz`, seen through the taper's
/// `kernel` as in [`PeakOptions::window_kernel`]): the thesis's damping
/// interface (5.4.2), where a person drags over a spike. The start is the
/// range's highest bin, its half-power width and the lower of the range's
/// ends as background. `None` when the range holds fewer than 6 bins or the
/// fit does not settle on a peak inside it.
pub fn fit_range(
    power: &[f64],
    f0_hz: f64,
    df_hz: f64,
    kernel: &[f64],
    lo_hz: f64,
    hi_hz: f64,
) -> Option<LorentzFit> {
    if power.len() < 6 || !(df_hz.is_finite() && df_hz > 0.0 && lo_hz < hi_hz) {
        return None;
    }
    let bin_of = |f: f64| {
        ((f - f0_hz) / df_hz)
            .round()
            .clamp(0.0, (power.len() - 1) as f64) as usize
    };
    let (lo, hi) = (bin_of(lo_hz).max(1), bin_of(hi_hz));
    if hi < lo + 5 || !power[lo..=hi].iter().all(|v| v.is_finite()) {
        return None;
    }
    let top = (lo..=hi).max_by(|&a, &b| power[a].total_cmp(&power[b]))?;
    let c = Candidate {
        bin: top,
        prominence_db: 0.0,
        left_base: lo,
        right_base: hi,
    };
    let (a, b) = half_power_bins(power, &c, 1, None);
    let gamma0 = (0.5 * (b - a) * df_hz).max(0.5 * df_hz);
    let background = power[lo].min(power[hi]).min(power[top]);
    let model = Model { kernel, df: df_hz };
    let b0 = background.max(power[top] * 1e-12);
    let a0 = (power[top] - background).max(power[top] * 1e-3);
    let q = [f0_hz + top as f64 * df_hz, gamma0.ln(), a0.ln(), b0.ln()];
    let q = gauss_newton(&model, power, f0_hz, (lo, hi), q)?;
    fit_stats(&model, power, f0_hz, (lo, hi), q)
}

impl LorentzFit {
    /// The fitted model's power at `f` (the Lorentzian through the taper's
    /// `kernel`, plus the background), to draw over the data.
    pub fn power_at(&self, kernel: &[f64], df_hz: f64, f: f64) -> f64 {
        let q = [
            self.f0,
            self.gamma.ln(),
            self.amplitude.ln(),
            self.background.ln(),
        ];
        Model { kernel, df: df_hz }.ln(&q, f).exp()
    }
}

/// The fit's uncertainties from its residuals over `range` (see the module
/// documentation); `None` when the centre left the range.
fn fit_stats(
    model: &Model,
    p: &[f64],
    f0_hz: f64,
    range: (usize, usize),
    q: [f64; 4],
) -> Option<LorentzFit> {
    let freq = |k: usize| f0_hz + k as f64 * model.df;
    let (lo, hi) = range;
    let n = hi - lo + 1;
    // Residuals, their scatter and lag-1 correlation.
    let r: Vec<f64> = (lo..=hi)
        .map(|k| p[k].max(f64::MIN_POSITIVE).ln() - model.ln(&q, freq(k)))
        .collect();
    let mean = r.iter().sum::<f64>() / n as f64;
    let var = r.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
    let s2 = var / (n as f64 - 4.0).max(1.0);
    let rho = if var > 0.0 {
        r.windows(2)
            .map(|w| (w[0] - mean) * (w[1] - mean))
            .sum::<f64>()
            / var
    } else {
        0.0
    };
    let rho = rho.clamp(0.0, 0.9);
    let inflate = (1.0 + rho) / (1.0 - rho);
    let mut jtj = normal_matrix(model, f0_hz, range, &q);
    // A background far below the peak's tails over the range is not
    // identifiable (its column vanishes): hold it fixed for the covariance.
    let trace = jtj[0][0] + jtj[1][1] + jtj[2][2];
    if jtj[3][3] < 1e-9 * trace {
        jtj[3] = [0.0; 4];
        for row in jtj.iter_mut() {
            row[3] = 0.0;
        }
        jtj[3][3] = 1.0;
    }
    let cov = nalgebra::Matrix4::from_fn(|r, c| jtj[r][c])
        .lu()
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()))?;
    let f0 = q[0];
    let gamma = q[1].exp();
    if !(f0 >= freq(lo) && f0 <= freq(hi) && gamma.is_finite()) {
        return None;
    }
    Some(LorentzFit {
        f0,
        f0_std: (s2 * inflate * cov[(0, 0)]).max(0.0).sqrt(),
        gamma,
        ln_gamma_std: (s2 * inflate * cov[(1, 1)]).max(0.0).sqrt(),
        amplitude: q[2].exp(),
        background: q[3].exp(),
        s: s2.sqrt(),
        lo_hz: freq(lo),
        hi_hz: freq(hi),
    })
}

fn normal_matrix(
    model: &Model,
    f0_hz: f64,
    (lo, hi): (usize, usize),
    q: &[f64; 4],
) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for k in lo..=hi {
        let j = model.jac(q, f0_hz + k as f64 * model.df);
        for a in 0..4 {
            for b in 0..4 {
                m[a][b] += j[a] * j[b];
            }
        }
    }
    m
}

/// Levenberg-Marquardt on ln P over bins `lo..=hi`.
fn gauss_newton(
    model: &Model,
    p: &[f64],
    f0_hz: f64,
    (lo, hi): (usize, usize),
    mut q: [f64; 4],
) -> Option<[f64; 4]> {
    let df = model.df;
    let freq = |k: usize| f0_hz + k as f64 * df;
    let y: Vec<f64> = (lo..=hi)
        .map(|k| p[k].max(f64::MIN_POSITIVE).ln())
        .collect();
    let cost = |q: &[f64; 4]| -> f64 {
        (lo..=hi)
            .zip(&y)
            .map(|(k, y)| (y - model.ln(q, freq(k))).powi(2))
            .sum()
    };
    let mut c0 = cost(&q);
    let mut lambda = 1e-3;
    for _ in 0..200 {
        let mut jtj = [[0.0; 4]; 4];
        let mut jtr = [0.0; 4];
        for (k, y) in (lo..=hi).zip(&y) {
            let f = freq(k);
            let j = model.jac(&q, f);
            let r = y - model.ln(&q, f);
            for a in 0..4 {
                jtr[a] += j[a] * r;
                for b in 0..4 {
                    jtj[a][b] += j[a] * j[b];
                }
            }
        }
        let mut improved = false;
        for _ in 0..20 {
            let mut m = jtj;
            for (a, row) in m.iter_mut().enumerate() {
                row[a] += lambda * jtj[a][a].max(1e-12);
            }
            let inv = nalgebra::Matrix4::from_fn(|r, c| m[r][c])
                .lu()
                .try_inverse()
                .filter(|m| m.iter().all(|v| v.is_finite()))?;
            let mut step = [0.0; 4];
            for a in 0..4 {
                step[a] = (0..4).map(|b| inv[(a, b)] * jtr[b]).sum();
            }
            // Keep the centre within a few bins per step.
            step[0] = step[0].clamp(-4.0 * df, 4.0 * df);
            let mut q2 = q;
            for a in 0..4 {
                q2[a] += step[a];
            }
            let c2 = cost(&q2);
            if c2.is_finite() && c2 < c0 {
                let rel = (c0 - c2) / c0.max(1e-300);
                q = q2;
                c0 = c2;
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                if rel < 1e-10 {
                    return Some(q);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    q.iter().all(|v| v.is_finite()).then_some(q)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A noiseless Lorentzian on a background: the fit returns it exactly.
    #[test]
    fn exact_lorentzian_is_recovered() {
        let df = 0.01;
        let (f0, g) = (7.3, 0.146);
        let p: Vec<f64> = (0..2000)
            .map(|k| {
                let x = (k as f64 * df - f0) / g;
                100.0 / (1.0 + x * x) + 0.1
            })
            .collect();
        let peaks = find_peaks(&p, 0.0, df, &PeakOptions::default());
        assert_eq!(peaks.len(), 1, "{peaks:?}");
        let pk = &peaks[0];
        assert!((pk.frequency_hz - f0).abs() < 1e-6, "{pk:?}");
        assert!((pk.damping_ratio - g / f0).abs() < 1e-6 * g / f0, "{pk:?}");
        assert!(pk.damping_method.starts_with("lorentzian_ls"), "{pk:?}");
        assert!(pk.resolved);
        // Half power on the exact curve: within the bin quantisation.
        let hp = &pk.damping_estimates[1];
        assert_eq!(hp.method, "half_power");
        assert!((hp.damping_ratio - g / f0).abs() < 0.05 * g / f0, "{hp:?}");
    }

    /// A range dragged over a noisy line (K = 8 averages): the fit over
    /// exactly that range recovers the half width within its stated
    /// uncertainty (3σ, over seeds), draws through the line's top, and a
    /// range with no line in it fits nothing inside it.
    #[test]
    fn a_dragged_range_fits_its_line_within_its_uncertainty() {
        let (df, f0, g) = (0.1, 40.0, 0.8);
        let mut outside = 0;
        for seed in 0..20u64 {
            let mut rng = crate::rng::Xoshiro256::new(seed + 100);
            let p: Vec<f64> = (0..1000)
                .map(|k| {
                    let x = (k as f64 * df - f0) / g;
                    let noise: f64 = (0..8)
                        .map(|_| -(1.0 - rng.next_f64()).max(1e-300).ln())
                        .sum::<f64>()
                        / 8.0;
                    (50.0 / (1.0 + x * x) + 0.5) * noise
                })
                .collect();
            let fit = fit_range(&p, 0.0, df, &[], 36.5, 43.0).expect("a fit");
            assert!(fit.lo_hz >= 36.45 && fit.hi_hz <= 43.05, "{fit:?}");
            assert!((fit.f0 - f0).abs() < 4.0 * fit.f0_std + 1e-3, "{fit:?}");
            let z = (fit.gamma / g).ln() / fit.ln_gamma_std;
            if z.abs() > 3.0 {
                outside += 1;
            }
            // The model at its centre is the line's height (ln-mean bias
            // of an 8-average: about -6%).
            let top = fit.power_at(&[], df, fit.f0);
            assert!((top / 50.5 - 1.0).abs() < 0.25, "{top} {fit:?}");
        }
        assert!(outside <= 1, "{outside} of 20 fits outside 3σ");
        // Flat noise: no peak settles inside a range with no line.
        let mut rng = crate::rng::Xoshiro256::new(7);
        let flat: Vec<f64> = (0..1000)
            .map(|_| -(1.0 - rng.next_f64()).max(1e-300).ln())
            .collect();
        let none = (0..10)
            .filter(|i| {
                fit_range(
                    &flat,
                    0.0,
                    df,
                    &[],
                    10.0 + *i as f64 * 5.0,
                    12.0 + *i as f64 * 5.0,
                )
                .is_none_or(|f| f.gamma > 2.0 || f.ln_gamma_std > 0.3)
            })
            .count();
        assert!(
            none >= 8,
            "{none} of 10 noise ranges gave no confident line"
        );
        assert!(
            fit_range(&flat, 0.0, df, &[], 10.0, 10.3).is_none(),
            "too few bins"
        );
        assert!(
            fit_range(&flat, 0.0, df, &[], 12.0, 10.0).is_none(),
            "reversed range"
        );
    }

    /// Prominence picks the two modes, not the ripples on their flanks.
    #[test]
    fn prominence_ranks_modes_above_ripples() {
        let df = 0.5;
        let p: Vec<f64> = (0..800)
            .map(|k| {
                let f = k as f64 * df;
                let l = |f0: f64, g: f64, a: f64| a / (1.0 + ((f - f0) / g).powi(2));
                let ripple = 1.0 + 0.2 * (k as f64 * 2.1).sin();
                (l(58.3, 0.6, 1e3) + l(128.0, 0.64, 1e2) + 1.0) * ripple
            })
            .collect();
        let opts = PeakOptions {
            max_peaks: 2,
            ..Default::default()
        };
        let peaks = find_peaks(&p, 0.0, df, &opts);
        let f: Vec<f64> = peaks.iter().map(|p| p.frequency_hz).collect();
        assert_eq!(f.len(), 2, "{f:?}");
        assert!(
            (f[0] - 58.3).abs() < 0.5 && (f[1] - 128.0).abs() < 0.5,
            "{f:?}"
        );
    }

    #[test]
    fn chi_square_tail_and_median() {
        for r in [0.1, 1.0, 5.0, 30.0] {
            assert!((chi2_ratio_sf(r, 1) - (-r).exp()).abs() < 1e-12 * (-r).exp().max(1e-300));
            let want = (-2.0 * r).exp() * (1.0 + 2.0 * r);
            assert!((chi2_ratio_sf(r, 2) - want).abs() <= 1e-12 * want, "{r}");
        }
        assert!((chi2_ratio_median(1) - std::f64::consts::LN_2).abs() < 1e-9);
        let m = chi2_ratio_median(1000);
        assert!(m < 1.0 && m > 0.99, "{m}");
        assert_eq!(chi2_ratio_sf(0.0, 3), 1.0);
        assert!(chi2_ratio_sf(1e4, 50) < 1e-300);
    }

    /// A K-segment average of noise (exponential bins averaged) on a
    /// sloping floor with a wide mode: the peaks reported at the default
    /// 1% are the lines put in, never the noise nor the mode's skirt, over
    /// seeds; the strongest comes first; a line two bins above DC (a slow
    /// sway) is found.
    #[test]
    fn significant_peaks_are_the_lines_not_the_noise() {
        let (n, df) = (4000, 0.05);
        let (mut false_peaks, mut missed_sway) = (0, 0);
        for seed in 0..32u64 {
            for k in [1usize, 4] {
                let mut rng = crate::rng::Xoshiro256::new(seed * 17 + k as u64);
                let p: Vec<f64> = (0..n)
                    .map(|i| {
                        let f = i as f64 * df;
                        let l = |f0: f64, g: f64, a: f64| a / (1.0 + ((f - f0) / g).powi(2));
                        let mean = 1.0 / (1.0 + f / 20.0)
                            + l(0.1, 0.01, 400.0)
                            + l(58.3, 3.0, 50.0)
                            + l(130.0, 0.1, 300.0);
                        let noise: f64 = (0..k)
                            .map(|_| -(1.0 - rng.next_f64()).max(1e-300).ln())
                            .sum::<f64>()
                            / k as f64;
                        mean * noise
                    })
                    .collect();
                let opts = PeakOptions {
                    max_peaks: 20,
                    segments: k,
                    ..Default::default()
                };
                let peaks = find_peaks(&p, 0.0, df, &opts);
                let near = |f: f64, pk: &Peak| (pk.frequency_hz - f).abs() < 0.3;
                assert!(
                    peaks.iter().any(|pk| near(130.0, pk)),
                    "K={k} seed {seed}: {peaks:?}"
                );
                // A K = 1 periodogram's bin fades below a twentieth of its
                // mean 5% of the time; averaged (K = 4) it does not.
                if !peaks.iter().any(|pk| near(0.1, pk)) {
                    assert_eq!(k, 1, "seed {seed}: {peaks:?}");
                    missed_sway += 1;
                }
                // One line, one peak.
                assert_eq!(
                    peaks.iter().filter(|pk| near(130.0, pk)).count(),
                    1,
                    "K={k} seed {seed}: {peaks:?}"
                );
                assert!(
                    peaks.windows(2).all(|w| w[0].power_db >= w[1].power_db),
                    "strongest first"
                );
                for pk in &peaks {
                    assert!(pk.false_alarm <= DEFAULT_FALSE_ALARM, "{pk:?}");
                    if ![0.1, 58.3, 130.0]
                        .iter()
                        .any(|&f| (pk.frequency_hz - f).abs() < 3.0)
                    {
                        eprintln!(
                            "false peak K={k} seed {seed}: {:.2} Hz p={:.2e}",
                            pk.frequency_hz, pk.false_alarm
                        );
                        false_peaks += 1;
                    }
                }
                // Every prominent local maximum, each with its probability.
                let all = find_peaks(
                    &p,
                    0.0,
                    df,
                    &PeakOptions {
                        max_false_alarm: None,
                        ..opts
                    },
                );
                assert!(all.len() > peaks.len(), "noise maxima exist: {}", all.len());
            }
        }
        // 64 spectra at 1% family-wise: about 0.6 false peaks expected.
        assert!(false_peaks <= 3, "{false_peaks} noise peaks reported");
        assert!(
            missed_sway <= 4,
            "the sway missed in {missed_sway} of 32 periodograms"
        );
    }

    #[test]
    fn degenerate_input_gives_no_peaks() {
        assert!(find_peaks(&[], 0.0, 1.0, &PeakOptions::default()).is_empty());
        assert!(find_peaks(&[1.0; 100], 0.0, 1.0, &PeakOptions::default()).is_empty());
        assert!(find_peaks(&[f64::NAN; 100], 0.0, 1.0, &PeakOptions::default()).is_empty());
        assert!(find_peaks(&[1.0; 10], 0.0, 0.0, &PeakOptions::default()).is_empty());
    }

    #[test]
    fn the_drift_floor_finds_a_random_walks_slope_and_the_resonance_test_its_bounds() {
        // 1/f^2 below, white above: β near 2, C near the white level.
        let df = 0.05;
        let p: Vec<f64> = (0..4000)
            .map(|i| {
                let f = i as f64 * df;
                if f > 0.0 {
                    1e-2 / (f * f) + 1e-4
                } else {
                    1.0
                }
            })
            .collect();
        let d = DriftFloor::fit(&p, 0.0, df, 1);
        assert!((d.beta - 2.0).abs() < 0.2, "{d:?}");
        assert!(
            (d.white / 1e-4 / chi2_ratio_median(1).recip() - 1.0).abs() < 0.5,
            "{d:?}"
        );
        assert!(d.drift(1.0) > d.white && d.drift(50.0) < d.white, "{d:?}");
        // A flat spectrum has no drift.
        let flat = vec![1.0; 1000];
        assert_eq!(DriftFloor::fit(&flat, 0.0, df, 1).a, 0.0);
        // The shape rules.
        assert!(shape_refusal_of(0.525, 18.366, (0.05, 0.01), "lorentzian_ls").is_some());
        assert!(shape_refusal_of(6.72, 0.1, (0.45, 0.01), "ssi_cov").is_some());
        assert!(shape_refusal_of(
            6.72,
            0.1,
            (0.45, f64::NAN),
            "resolution_limit (upper bound)"
        )
        .is_none());
        assert!(shape_refusal_of(5.46, 0.5, (0.136, 0.344), TIME_FIT).is_some());
        assert!(shape_refusal_of(0.2, 0.001, (0.001, 0.01), TIME_FIT).is_none());
        assert!(shape_refusal_of(64.0, 0.08, (0.001, f64::NAN), "ssi_cov").is_none());
        assert!(shape_refusal_of(f64::NAN, 0.1, (0.01, 0.0), "x").is_some());
    }
}
