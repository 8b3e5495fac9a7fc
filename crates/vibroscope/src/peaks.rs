//! The peaks document: what the engine's `peaks` sink writes (and
//! `spectrum` writes, with time-domain damping added), as Rust types.

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
    pub peaks: Vec<Peak>,
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
}
