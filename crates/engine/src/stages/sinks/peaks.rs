//! `peaks`: resonances of a motion spectrum, written as one JSON document at
//! the end (atomically). The spectra that arrive are averaged (one from
//! `spectrum` in `mode = "whole"`; from a sliding `spectrum`, the mean over
//! the run), then peaks are picked by prominence and their damping estimated
//! ([`vibroscope_math::peaks`]).
//!
//! ```json
//! {"sample_rate_hz": 600.0, "resolution_hz": 0.29, "spectra_averaged": 1,
//!  "peaks": [{"frequency_hz", "frequency_std_hz", "damping_ratio",
//!             "damping_ratio_std", "damping_method", "power_db",
//!             "prominence_db", "damping_estimates": [{"method",
//!             "damping_ratio", "damping_ratio_std"}], "fit_range_hz",
//!             "resolved"}]}
//! ```
//! `include_spectrum = true` adds `"spectrum": {"f0_hz", "resolution_hz",
//! "power_db": [...]}`.

use crate::stages::transform::spectrum::Taper;
use crate::*;
use serde::Deserialize;
use std::path::PathBuf;
use vibroscope_math::peaks::{find_peaks, PeakOptions};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    path: PathBuf,
    #[serde(default = "d_peaks")]
    peaks: usize,
    #[serde(default = "d_prom")]
    min_prominence_db: f64,
    min_hz: Option<f64>,
    max_hz: Option<f64>,
    #[serde(default)]
    include_spectrum: bool,
    /// The taper the spectrum was computed with: the fit sees each line
    /// through its spectral window (`"none"` fits the bare Lorentzian).
    #[serde(default = "d_taper")]
    taper: String,
}
fn d_taper() -> String {
    "hann".into()
}

pub(crate) fn taper_of(name: &str) -> Option<Option<Taper>> {
    Some(match name {
        "hann" => Some(Taper::Hann),
        "hamming" => Some(Taper::Hamming),
        "blackman" => Some(Taper::Blackman),
        "rect" => Some(Taper::Rect),
        "none" => None,
        _ => return None,
    })
}
fn d_peaks() -> usize {
    5
}
fn d_prom() -> f64 {
    6.0
}

pub const KIND: KindSpec = KindSpec {
    name: "peaks",
    summary: "picks resonances (prominence) of the mean spectrum, with damping and uncertainties, as JSON at the end",
    accepts: &[PortType::Spectrum],
    max_inputs: 1,
    output: Output::None,
    plan: |p| {
        let v: P = p.parse()?;
        if !(1..=1000).contains(&v.peaks) {
            return Err(p.error("peaks", format!("must be 1..=1000, got {}", v.peaks)));
        }
        if !(v.min_prominence_db.is_finite() && v.min_prominence_db >= 0.0) {
            return Err(p.error(
                "min_prominence_db",
                format!("must be >= 0 dB, got {}", v.min_prominence_db),
            ));
        }
        check_band_taper(p, v.min_hz, v.max_hz, &v.taper)?;
        Ok(Box::new(PeaksPlan(v)))
    },
};

/// Checks the band (`min_hz`, `max_hz`) and `taper` fields, which
/// `peaks` and `spectrum_png` share.
pub(crate) fn check_band_taper(
    p: &Params<'_>,
    min_hz: Option<f64>,
    max_hz: Option<f64>,
    taper: &str,
) -> Result<(), ConfigError> {
    for (name, f) in [("min_hz", min_hz), ("max_hz", max_hz)] {
        if let Some(f) = f {
            if !(f.is_finite() && f >= 0.0) {
                return Err(p.error(name, format!("must be >= 0 Hz, got {f}")));
            }
        }
    }
    if let (Some(a), Some(b)) = (min_hz, max_hz) {
        if a >= b {
            return Err(p.error("max_hz", format!("must exceed min_hz ({a}), got {b}")));
        }
    }
    if taper_of(taper).is_none() {
        return Err(p.error(
            "taper",
            format!("must be hann, hamming, blackman, rect or none, got `{taper}`"),
        ));
    }
    Ok(())
}

struct PeaksPlan(P);

impl Plan for PeaksPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Peaks {
            p: self.0,
            sum: Vec::new(),
            count: 0,
            f0: 0.0,
            df: 0.0,
        })))
    }
}

struct Peaks {
    p: P,
    sum: Vec<f64>,
    count: usize,
    f0: f64,
    df: f64,
}

impl Stage for Peaks {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Spectrum(s) = item else {
            return Ok(());
        };
        if s.power.len() != self.sum.len() || s.resolution_hz != self.df || s.f0_hz != self.f0 {
            // A new layout: start the average again.
            self.sum = vec![0.0; s.power.len()];
            self.count = 0;
            self.f0 = s.f0_hz;
            self.df = s.resolution_hz;
        }
        for (a, &p) in self.sum.iter_mut().zip(s.power.iter()) {
            *a += p as f64;
        }
        self.count += 1;
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        if self.count == 0 {
            return Err(StageError::msg(format!(
                "{}: no spectrum arrived (is the recording shorter than one window?)",
                self.p.path.display()
            )));
        }
        let mean: Vec<f64> = self.sum.iter().map(|s| s / self.count as f64).collect();
        let opts = PeakOptions {
            max_peaks: self.p.peaks,
            min_prominence_db: self.p.min_prominence_db,
            min_hz: self.p.min_hz,
            max_hz: self.p.max_hz,
            // One-sided spectrum of an even-length segment: n = 2 (bins - 1).
            window_kernel: match taper_of(&self.p.taper).flatten() {
                Some(t) => t.power_kernel(2 * (mean.len() - 1), 4),
                None => Vec::new(),
            },
        };
        let peaks = find_peaks(&mean, self.f0, self.df, &opts);
        for pk in &peaks {
            tracing::info!(
                frequency_hz = pk.frequency_hz,
                damping_ratio = pk.damping_ratio,
                method = %pk.damping_method,
                "peak"
            );
        }
        // One-sided spectrum of an even-length window: fs = 2 (bins - 1) df.
        let rate = 2.0 * (mean.len().saturating_sub(1)) as f64 * self.df;
        let mut doc = serde_json::json!({
            "sample_rate_hz": rate,
            "resolution_hz": self.df,
            "spectra_averaged": self.count,
            "peaks": peaks,
        });
        if self.p.include_spectrum {
            let db: Vec<f64> = mean
                .iter()
                .map(|&p| 10.0 * p.max(f64::MIN_POSITIVE).log10())
                .collect();
            doc["spectrum"] = serde_json::json!({
                "f0_hz": self.f0,
                "resolution_hz": self.df,
                "power_db": db,
            });
        }
        let text = serde_json::to_vec_pretty(&doc)
            .map_err(|e| StageError::msg(format!("{}: {e}", self.p.path.display())))?;
        super::write_atomic(&self.p.path, &text)
    }
}
