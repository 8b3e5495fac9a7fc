//! Score a recovered signal against the reference sound: SNR, segmental
//! SNR (Hansen & Pellom), LLR and STOI (Taal et al. 2011), after finding the
//! best lag and gain (a recovery's scale and sign are arbitrary). The test
//! is resampled to the reference's rate when they differ.

use crate::error::{Error, Result};
use crate::math::metrics;
use anyhow::Context;
use serde::{Serialize, Serializer};
use std::path::Path;

/// What `score` measured: serialises to the JSON it prints (non-finite
/// values as `null`).
#[derive(Clone, Debug, Serialize)]
pub struct ScoreReport {
    #[serde(serialize_with = "finite")]
    pub snr_db: f64,
    #[serde(serialize_with = "finite")]
    pub ssnr_db: f64,
    #[serde(serialize_with = "finite")]
    pub llr: f64,
    #[serde(serialize_with = "finite")]
    pub stoi: f64,
    pub lag_samples: isize,
    #[serde(serialize_with = "finite")]
    pub gain: f64,
    pub sample_rate_hz: u32,
}

fn finite<S: Serializer>(v: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

/// Scores `test` against `reference`, searching lags up to `max_lag_s`.
pub fn score(reference: &Path, test: &Path, max_lag_s: f64) -> Result<ScoreReport> {
    if !(max_lag_s.is_finite() && max_lag_s >= 0.0) {
        return Err(Error::usage(
            "--max-lag-s",
            format!("must be >= 0 seconds, got {max_lag_s}"),
        ));
    }
    let (fr, r) = crate::io::wav::read_mono(reference).map_err(anyhow::Error::new)?;
    let (ft, mut t) = crate::io::wav::read_mono(test).map_err(anyhow::Error::new)?;
    if fr != ft {
        let g = crate::math::numeric::gcd(fr as u64, ft as u64).max(1);
        t = metrics::resample(&t, fr as u64 / g, ft as u64 / g).with_context(|| {
            format!("cannot resample {} from {ft} Hz to {fr} Hz", test.display())
        })?;
    }
    let max_lag = (max_lag_s * fr as f64).round() as usize;
    let (lag, gain) = metrics::best_lag_gain(&r, &t, max_lag);
    let s = metrics::score(&r, &t, fr as f64, max_lag);
    Ok(ScoreReport {
        snr_db: s.snr_db,
        ssnr_db: s.ssnr_db,
        llr: s.llr,
        stoi: s.stoi,
        lag_samples: lag,
        gain,
        sample_rate_hz: fr,
    })
}
