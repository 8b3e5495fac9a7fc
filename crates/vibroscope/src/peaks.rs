//! The peaks document: what the engine's `peaks` sink writes (and
//! `spectrum` writes, with time-domain damping added), as Rust types.

pub use crate::math::peaks::{find_peaks, PeakOptions, DEFAULT_FALSE_ALARM};
use serde::{Deserialize, Deserializer, Serialize};
use std::path::PathBuf;

/// `null` in the JSON (a NaN when written) as NaN.
fn nan_f64<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

fn nan() -> f64 {
    f64::NAN
}

fn nan_pair<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<[f64; 2], D::Error> {
    let v = <[Option<f64>; 2]>::deserialize(d)?;
    Ok(v.map(|x| x.unwrap_or(f64::NAN)))
}

/// The SSI-cov details of a time-domain damping estimate.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SsiDetail {
    pub block_rows: usize,
    #[serde(deserialize_with = "nan_f64")]
    pub frequency_hz: f64,
    #[serde(deserialize_with = "nan_f64")]
    pub order_std: f64,
    pub segment_std: Option<f64>,
    pub stable_orders: usize,
}

/// One damping estimate of a peak, with its method.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DampingEstimate {
    #[serde(deserialize_with = "nan_f64")]
    pub damping_ratio: f64,
    #[serde(deserialize_with = "nan_f64")]
    pub damping_ratio_std: f64,
    pub method: String,
    /// Present for `ssi_cov`.
    #[serde(flatten, skip_serializing_if = "Option::is_none", default)]
    pub ssi: Option<SsiDetail>,
    /// The stretch of the record a time-domain fit used (`time_fit`,
    /// `free_decay`): start and length, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_s: Option<[f64; 2]>,
}

/// A resonance (see [`crate::math::peaks::Peak`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Peak {
    pub damping_estimates: Vec<DampingEstimate>,
    pub damping_method: String,
    #[serde(deserialize_with = "nan_f64")]
    pub damping_ratio: f64,
    #[serde(deserialize_with = "nan_f64")]
    pub damping_ratio_std: f64,
    #[serde(deserialize_with = "nan_pair")]
    pub fit_range_hz: [f64; 2],
    #[serde(deserialize_with = "nan_f64")]
    pub frequency_hz: f64,
    #[serde(deserialize_with = "nan_f64")]
    pub frequency_std_hz: f64,
    #[serde(deserialize_with = "nan_f64")]
    pub power_db: f64,
    #[serde(deserialize_with = "nan_f64")]
    pub prominence_db: f64,
    pub resolved: bool,
    /// The local noise floor under the peak, dB (absent in reports
    /// written before it existed: NaN).
    #[serde(default = "nan", deserialize_with = "nan_f64")]
    pub floor_db: f64,
    /// The probability that noise alone puts a peak this high anywhere in
    /// the band searched.
    #[serde(default = "nan", deserialize_with = "nan_f64")]
    pub false_alarm: f64,
    /// The motion's amplitude at this frequency, in the report's
    /// `motion.unit` (`spectrum` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<f64>,
    /// The resonance test's verdict (reports written before it: a
    /// resonance).
    #[serde(default = "resonance")]
    pub class: crate::math::peaks::PeakClass,
    /// Why it is not a resonance (empty for one).
    #[serde(default)]
    pub class_reason: String,
}

fn resonance() -> crate::math::peaks::PeakClass {
    crate::math::peaks::PeakClass::Resonance
}

impl Peak {
    /// Its power above its own floor, dB: what "strongest" ranks by.
    pub fn above_floor_db(&self) -> f64 {
        if self.floor_db.is_finite() {
            self.power_db - self.floor_db
        } else {
            self.prominence_db
        }
    }
}

/// The mean spectrum, in dB.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpectrumDb {
    pub f0_hz: f64,
    pub power_db: Vec<f64>,
    pub resolution_hz: f64,
}

/// What `spectrum` found: serialises to the JSON it writes.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpectrumReport {
    /// The resonances (issue 51's test).
    pub peaks: Vec<Peak>,
    /// Peaks that are not resonances (drift, broadband), with the reason.
    #[serde(default)]
    pub others: Vec<Peak>,
    pub resolution_hz: f64,
    pub sample_rate_hz: f64,
    pub spectra_averaged: usize,
    /// The taper of the spectrum's segments (`hann`, ...): it sets how one
    /// line looks, so a fit over the spectrum needs it.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub taper: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub spectrum: Option<SpectrumDb>,
    /// How the channels' spectra were combined (`snr` or `sum`; `spectrum`
    /// only): it decides which peaks a small region can carry.
    #[serde(skip_deserializing, skip_serializing_if = "Option::is_none")]
    pub combine: Option<&'static str>,
    /// The unit and method of the peaks' `amplitude` (`spectrum` only).
    #[serde(skip_deserializing, skip_serializing_if = "Option::is_none")]
    pub motion: Option<crate::motion::MotionSummary>,
    /// The regions' waveform exports (`spectrum --waveform`).
    #[serde(skip_deserializing, skip_serializing_if = "Vec::is_empty")]
    pub waveforms: Vec<crate::motion::WaveformFiles>,
    /// The Universal File export (`--uff`).
    #[serde(skip_deserializing, skip_serializing_if = "Option::is_none")]
    pub uff: Option<crate::motion::UffExport>,
    /// Files written.
    #[serde(skip)]
    pub written: Vec<PathBuf>,
}

impl SpectrumReport {
    /// The most prominent peak.
    pub fn strongest(&self) -> Option<&Peak> {
        self.peaks
            .iter()
            .max_by(|x, y| x.prominence_db.total_cmp(&y.prominence_db))
    }

    /// The resonance test again on each peak's shape (its frequency
    /// uncertainty and damping), after a time-domain refinement changed
    /// them: a resonance that fails moves to `others`, and a peak turned
    /// away as broadband that now passes (a few-cycle sway the fit
    /// resolved) moves to `peaks`. Drift stays drift: that test is the
    /// spectrum's. Both lists end strongest first.
    pub fn recheck(&mut self) {
        use crate::math::peaks::{shape_refusal_of, PeakClass};
        let all = std::mem::take(&mut self.peaks)
            .into_iter()
            .chain(std::mem::take(&mut self.others));
        for mut p in all {
            if p.class != PeakClass::Drift {
                match shape_refusal_of(
                    p.frequency_hz,
                    p.frequency_std_hz,
                    (p.damping_ratio, p.damping_ratio_std),
                    &p.damping_method,
                ) {
                    Some((class, why)) => {
                        p.class = class;
                        p.class_reason = why;
                    }
                    None => {
                        p.class = PeakClass::Resonance;
                        p.class_reason.clear();
                    }
                }
            }
            if p.class == PeakClass::Resonance {
                self.peaks.push(p);
            } else {
                self.others.push(p);
            }
        }
        for list in [&mut self.peaks, &mut self.others] {
            list.sort_by(|a, b| {
                b.power_db
                    .total_cmp(&a.power_db)
                    .then(a.frequency_hz.total_cmp(&b.frequency_hz))
            });
        }
    }
}
