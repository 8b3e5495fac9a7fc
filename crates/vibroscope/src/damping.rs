//! Time-domain damping for `spectrum`: the graph also writes the extracted
//! motion (`phase` → `align`, the bands summed as in `listen`, no
//! high-pass) to a WAV; after the run every peak gets an SSI-cov estimate
//! ([`crate::math::ssi`]) in its `damping_estimates` (`"method":
//! "ssi_cov"`, with the pole's frequency, the stable orders and block rows
//! used), and a peak the spectrum cannot resolve (`resolved: false`) takes
//! it as its `damping_ratio` and `damping_method`.

use crate::engine::config::PipelineDecl;
use crate::engine::Origin;
use crate::error::Result;
use crate::io::atomic::TempPath;
use crate::math::ssi::{identify, SsiOptions};
use crate::peaks::{DampingEstimate, SpectrumReport, SsiDetail};
use crate::pipeline;
use crate::stages::params::{AlignParams, WavParams};
use crate::stages::transform::spectrum::TaperExt;
use std::path::{Path, PathBuf};

/// Where the motion goes: a file the user keeps, or a scratch file.
pub struct MotionTap {
    kept: Option<PathBuf>,
    temp: TempPath,
}

impl MotionTap {
    /// Adds `phase` → `align` → WAV to the spectrum graph (its `phase` stage
    /// is the shared input).
    pub fn add(decl: &mut PipelineDecl, keep: Option<PathBuf>) -> Result<MotionTap> {
        let tap = MotionTap {
            kept: keep,
            temp: TempPath::new("motion.wav"),
        };
        let origin = Origin::Builtin("spectrum (time-domain damping)".into());
        pipeline::position(decl, "phase")?;
        decl.stages.push(pipeline::new_stage::<AlignParams>(
            "ssi_align",
            &["phase"],
            origin.clone(),
        ));
        let mut wav =
            pipeline::new_stage::<WavParams>("ssi_motion", &["ssi_align"], origin.clone());
        pipeline::put(&mut wav, WavParams::path, tap.path().to_path_buf(), origin)?;
        decl.stages.push(wav);
        Ok(tap)
    }

    pub fn path(&self) -> &Path {
        self.kept.as_deref().unwrap_or(self.temp.path())
    }

    /// Adds the SSI-cov estimates to the peaks of `report`.
    pub fn refine(&self, report: &mut SpectrumReport, opts: &SsiOptions) -> Result<()> {
        let (_, y) = crate::io::wav::read_mono(self.path())?;
        add_ssi(report, &y, opts);
        Ok(())
    }
}

/// SSI-cov per peak of `report`, on the motion `y` sampled at the report's
/// rate (the WAV's integer rate may round the frame rate).
pub fn add_ssi(report: &mut SpectrumReport, y: &[f64], opts: &SsiOptions) {
    let fs = report.sample_rate_hz;
    let df = report.resolution_hz;
    for pk in &mut report.peaks {
        let f = pk.frequency_hz;
        if !f.is_finite() {
            continue;
        }
        let tol = (2.0 * df).max(0.01 * f);
        let Some(m) = identify(y, fs, f, tol, opts) else {
            continue;
        };
        pk.damping_estimates.push(DampingEstimate {
            method: "ssi_cov".into(),
            damping_ratio: m.damping_ratio,
            damping_ratio_std: m.damping_ratio_std,
            ssi: Some(SsiDetail {
                frequency_hz: m.frequency_hz,
                order_std: m.order_std,
                segment_std: m.segment_std,
                stable_orders: m.stable_orders,
                block_rows: m.block_rows,
            }),
            window_s: None,
        });
        if !pk.resolved {
            pk.damping_ratio = m.damping_ratio;
            pk.damping_ratio_std = m.damping_ratio_std;
            pk.damping_method = "ssi_cov".into();
        }
    }
    add_time_domain(report, y);
    // A damping measured in the time domain may show a peak broader than
    // a mode, and a fit may resolve a sway the bins could not.
    report.recheck();
}

/// Fewer cycles than this in the record and a peak is also fitted in the
/// time domain (issue 51, item 2; [`add_time_domain`] says when the fit's
/// values replace the spectrum's): below it a spectral peak is a few bins
/// wide and the bins, not the line, set its precision.
pub const FEW_CYCLES: f64 = 10.0;

/// The time-domain measures of `report`'s peaks from the motion `y`:
/// - a peak with fewer than [`FEW_CYCLES`] cycles in the record (a
///   resonance, or one turned away as broadband, never a drift) gets a
///   damped sinusoid fitted by least squares
///   ([`crate::math::sinefit::fit_damped_sinusoid`]), `"method":
///   "time_fit"` among its estimates. Where the spectrum could not resolve
///   the peak (its damping only bounded, its frequency set by the bins),
///   the fit's frequency and damping become the peak's, with their
///   uncertainties, which the resonance test then weighs
///   ([`crate::math::peaks::shape_refusal_of`]); a resolved peak takes the
///   fit's frequency only when it is tighter;
/// - every resonance whose envelope falls after a maximum (a struck
///   object) gets its free-decay damping
///   ([`crate::math::sinefit::fit_free_decay`]), `"method": "free_decay"`,
///   beside the Lorentzian and SSI values.
pub fn add_time_domain(report: &mut SpectrumReport, y: &[f64]) {
    use crate::math::peaks::{PeakClass, TIME_FIT};
    use crate::math::sinefit::{fit_damped_sinusoid, fit_free_decay};
    let fs = report.sample_rate_hz;
    let df = report.resolution_hz;
    if !(fs.is_finite() && fs > 0.0) || y.is_empty() {
        return;
    }
    let record_s = y.len() as f64 / fs;
    let lines: Vec<f64> = report
        .peaks
        .iter()
        .chain(&report.others)
        .map(|p| p.frequency_hz)
        .collect();
    for pk in report.peaks.iter_mut().chain(report.others.iter_mut()) {
        let f = pk.frequency_hz;
        if pk.class == PeakClass::Drift || !(f.is_finite() && f > 0.0) {
            continue;
        }
        if f * record_s < FEW_CYCLES {
            let guess = if pk.damping_ratio.is_finite() {
                pk.damping_ratio.min(0.2)
            } else {
                0.02
            };
            if let Some(fit) = fit_damped_sinusoid(y, fs, f, guess) {
                let zeta = fit.damping_ratio.max(0.0);
                pk.damping_estimates.push(DampingEstimate {
                    method: TIME_FIT.into(),
                    damping_ratio: zeta,
                    damping_ratio_std: fit.damping_ratio_std,
                    ssi: None,
                    window_s: Some([fit.start_s, fit.duration_s]),
                });
                // An unresolved peak a few bins from zero has no spectral
                // frequency to trust (its bins, the window's leakage from
                // zero and a trend set it, whatever its fit claims): the
                // fit's is taken. A resolved one keeps the tighter.
                if fit.frequency_std_hz.is_finite()
                    && fit.frequency_std_hz > 0.0
                    && (!pk.resolved
                        || pk.frequency_std_hz.is_nan()
                        || fit.frequency_std_hz < pk.frequency_std_hz)
                {
                    pk.frequency_hz = fit.frequency_hz;
                    pk.frequency_std_hz = fit.frequency_std_hz;
                }
                // The spectrum could only bound the damping; the fit
                // measures it, with its uncertainty (which the resonance
                // test then weighs).
                if !pk.resolved && fit.damping_ratio_std.is_finite() {
                    pk.damping_ratio = zeta;
                    pk.damping_ratio_std = fit.damping_ratio_std;
                    pk.damping_method = TIME_FIT.into();
                }
            }
        }
        if pk.class != PeakClass::Resonance {
            continue;
        }
        // The envelope's band: as wide as the neighbours allow (half the
        // way to the next line, a quarter of the frequency), so its kernel,
        // which smears the strike, stays short; at least five half-widths
        // of the mode and three bins.
        let next = lines
            .iter()
            .filter(|&&g| (g - f).abs() > 0.5 * df)
            .map(|&g| (g - f).abs())
            .fold(f64::INFINITY, f64::min);
        let zeta = if pk.damping_ratio.is_finite() {
            pk.damping_ratio
        } else {
            0.0
        };
        let band = (0.5 * next)
            .min(0.25 * f)
            .max(5.0 * zeta * f)
            .max(3.0 * df)
            .min(0.5 * f);
        if let Some(d) = fit_free_decay(y, fs, f, band) {
            pk.damping_estimates.push(DampingEstimate {
                method: "free_decay".into(),
                damping_ratio: d.damping_ratio,
                damping_ratio_std: d.damping_ratio_std,
                ssi: None,
                window_s: Some([d.start_s, d.duration_s]),
            });
        }
    }
}

/// The thesis's damping interface (5.4.2) for one range of a spectrum a
/// person chose (the studio's drag over a spike): a Lorentzian fitted over
/// exactly that range, and SSI-cov's stabilisation diagram for the same
/// range from the motion the spectrum was computed from.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RangeDamping {
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// The spectrum's bins in the range.
    pub bins: usize,
    pub taper: String,
    /// The fit, or why there is none (`fit_refusal`).
    pub fit: Option<RangeFit>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_refusal: Option<String>,
    /// Every pole of every order whose frequency is in the range.
    pub poles: Vec<crate::math::ssi::Pole>,
    pub max_order: usize,
    pub block_rows: usize,
    /// The mode the stable poles agree on in the range (with its
    /// uncertainty over orders and segments), if any.
    pub ssi: Option<crate::math::ssi::SsiMode>,
    /// The range's stable poles clustered into modes (within 1% in
    /// frequency, at three orders or more), each with its mean and spread.
    pub clusters: Vec<crate::math::ssi::PoleCluster>,
}

/// A Lorentzian over a chosen range ([`crate::math::peaks::fit_range`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct RangeFit {
    pub f0_hz: f64,
    pub f0_std_hz: f64,
    /// Half width at half maximum.
    pub gamma_hz: f64,
    /// ξ = γ / f0, and its standard deviation.
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
    /// The half width is at least [`crate::math::peaks::MIN_RESOLVED_BINS`]
    /// bins: below that the damping is only an upper bound.
    pub resolved: bool,
    /// Residual scatter of ln P (relative power scatter).
    pub scatter: f64,
    /// The model (through the taper's line shape) at the range's bins, in
    /// dB like the spectrum.
    pub curve_hz: Vec<f64>,
    pub curve_db: Vec<f64>,
}

/// Refuses a range that is not `0 <= lo < hi <= fs / 2`, naming `option`.
pub fn check_range((lo_hz, hi_hz): (f64, f64), fs: f64, option: &str) -> Result<()> {
    let bad = |m: String| crate::Error::usage(option, m);
    if !(lo_hz.is_finite() && hi_hz.is_finite() && lo_hz >= 0.0 && lo_hz < hi_hz) {
        return Err(bad(format!(
            "the range {lo_hz}..{hi_hz} Hz: give a lower and a higher frequency, from 0 Hz"
        )));
    }
    let nyquist = fs / 2.0;
    if hi_hz > nyquist * (1.0 + 1e-9) {
        return Err(bad(format!(
            "the range {lo_hz}..{hi_hz} Hz reaches above the Nyquist frequency {nyquist} Hz (frame rate {fs} Hz)"
        )));
    }
    Ok(())
}

/// [`RangeDamping`] over `[lo_hz, hi_hz]` of the spectrum `sp` (of a
/// signal sampled at `fs`, its segments tapered with `taper`; `hann` when
/// not said), with `motion` that signal. A range outside 0..Nyquist,
/// reversed, or narrower than 6 bins is a usage error naming `option`.
pub fn damping_over(
    sp: &crate::peaks::SpectrumDb,
    fs: f64,
    taper: Option<&str>,
    motion: &[f64],
    (lo_hz, hi_hz): (f64, f64),
    option: &str,
) -> Result<RangeDamping> {
    use crate::math::peaks::{fit_range, MIN_RESOLVED_BINS};
    let bad = |m: String| crate::Error::usage(option, m);
    check_range((lo_hz, hi_hz), fs, option)?;
    let df = sp.resolution_hz;
    let bins = ((hi_hz - lo_hz) / df).floor() as usize + 1;
    if bins < 6 {
        return Err(bad(format!(
            "the range {lo_hz:.3}..{hi_hz:.3} Hz holds {bins} bins of {df:.4} Hz: drag over at least 6"
        )));
    }
    let taper_name = taper.unwrap_or("hann").to_string();
    let taper: crate::engine::item::Taper =
        serde_json::from_value(serde_json::Value::String(taper_name.clone()))
            .map_err(|_| bad(format!("the spectrum's taper `{taper_name}` is not known")))?;
    let window = (fs / df).round().max(2.0) as usize;
    let kernel = taper.power_kernel(window, 4);
    let power: Vec<f64> = sp.power_db.iter().map(|d| 10f64.powf(d / 10.0)).collect();
    let f = fit_range(&power, sp.f0_hz, df, &kernel, lo_hz, hi_hz);
    let fit_refusal = f.is_none().then(|| {
        format!("no Lorentzian settles on a peak inside {lo_hz:.3}..{hi_hz:.3} Hz: drag over one spike, with some floor either side")
    });
    let fit = f.map(|f| {
        let xi = f.gamma / f.f0;
        let first = ((f.lo_hz - sp.f0_hz) / df).round() as usize;
        let last = ((f.hi_hz - sp.f0_hz) / df).round() as usize;
        // Four points a bin, so the curve is smooth between the bins.
        let curve_hz: Vec<f64> = (first * 4..=last * 4)
            .map(|q| sp.f0_hz + q as f64 * df / 4.0)
            .collect();
        let curve_db = curve_hz
            .iter()
            .map(|&x| 10.0 * f.power_at(&kernel, df, x).max(f64::MIN_POSITIVE).log10())
            .collect();
        RangeFit {
            f0_hz: f.f0,
            f0_std_hz: f.f0_std,
            gamma_hz: f.gamma,
            damping_ratio: xi,
            damping_ratio_std: xi * f.ln_gamma_std,
            resolved: f.gamma >= MIN_RESOLVED_BINS * df,
            scatter: f.s,
            curve_hz,
            curve_db,
        }
    });
    // SSI over the same motion: the diagram's poles in the range, and the
    // mode the stable ones agree on near its middle.
    let opts = SsiOptions::default();
    let centre = fit.as_ref().map_or(0.5 * (lo_hz + hi_hz), |f| f.f0_hz);
    let i = crate::math::ssi::block_rows_for(fs, centre.max(df), &opts);
    let (poles, ssi) = if motion.len() >= 8 * i {
        let r = crate::math::ssi::autocorrelation(motion, 2 * i);
        let poles: Vec<_> = crate::math::ssi::stabilisation(&r, fs, i, &opts)
            .into_iter()
            .filter(|p| (lo_hz..=hi_hz).contains(&p.frequency_hz))
            .collect();
        let tol = (centre - lo_hz).max(hi_hz - centre);
        let mode = identify(motion, fs, centre, tol, &opts)
            .filter(|m| (lo_hz..=hi_hz).contains(&m.frequency_hz));
        (poles, mode)
    } else {
        (Vec::new(), None)
    };
    let clusters = crate::math::ssi::cluster_poles(&poles, 0.01, 3);
    Ok(RangeDamping {
        lo_hz,
        hi_hz,
        bins,
        taper: taper_name,
        fit,
        fit_refusal,
        poles,
        max_order: opts.max_order,
        block_rows: i,
        ssi,
        clusters,
    })
}
