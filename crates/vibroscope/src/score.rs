//! Score a recovered signal against the reference sound: SNR, segmental
//! SNR (Hansen & Pellom), LLR and STOI (Taal et al. 2011), after finding the
//! best lag and gain (a recovery's scale and sign are arbitrary). The test
//! is resampled to the reference's rate when they differ.

use crate::error::{Error, Result};
use crate::math::metrics;
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
    /// The SNR the best fixed (stationary Wiener) filter, built from this
    /// test's true signal and noise spectra, would reach on it
    /// ([`metrics::stationary_wiener_snr_db`]): score a recovery before
    /// denoising to get the bound its denoised version is measured against.
    #[serde(serialize_with = "finite")]
    pub wiener_bound_db: f64,
    pub lag_samples: isize,
    #[serde(serialize_with = "finite")]
    pub gain: f64,
    pub sample_rate_hz: u32,
    /// Why a metric is `null`, one line each (absent when all are numbers).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

fn finite<S: Serializer>(v: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

/// Sample rates `score` accepts (Hz), checked before reading or resampling.
pub const RATES_HZ: std::ops::RangeInclusive<u32> = 1..=768_000;
/// Longest signal `score` accepts, in samples at the reference's rate
/// (each file, the test after resampling): 2^23, 3.2 minutes at 44.1 kHz.
/// Scoring needs about 170 bytes per sample of the pair (171 MB peak for
/// two 1,000,000-sample WAVs, `/usr/bin/time -f %M vibroscope score`; 137
/// MB before `wiener_bound_db`), so about 1.4 GB at this bound.
pub const MAX_SAMPLES: u64 = 1 << 23;

/// Checks a WAV's header: a rate in [`RATES_HZ`], a length (at the
/// reference's rate `at_hz`) within [`MAX_SAMPLES`].
fn check_header(path: &Path, at_hz: Option<u32>) -> Result<u32> {
    // A missing or unreadable file is a runtime error (exit 1), as before.
    let (rate, n) = crate::io::wav::info(path)?;
    if !RATES_HZ.contains(&rate) {
        return Err(Error::input(
            path,
            format!(
                "sample rate {rate} Hz is outside {}..={} Hz",
                RATES_HZ.start(),
                RATES_HZ.end()
            ),
        ));
    }
    let at = at_hz.unwrap_or(rate);
    let len = (u128::from(n) * u128::from(at)).div_ceil(u128::from(rate));
    if len > u128::from(MAX_SAMPLES) {
        return Err(Error::input(
            path,
            format!(
                "{n} samples at {rate} Hz ({len} at {at} Hz) is longer than score accepts ({MAX_SAMPLES} samples at the reference's rate); cut it first (sox IN OUT trim 0 SECONDS)"
            ),
        ));
    }
    Ok(rate)
}

/// Reads a WAV whose samples must be finite and at least `min` long.
fn read_signal(path: &Path, what: &str, min: usize) -> Result<Vec<f64>> {
    let (_, x) = crate::io::wav::read_mono(path)?;
    if x.len() < min {
        return Err(Error::input(
            path,
            format!(
                "the {what} holds {} samples; scoring needs at least {min}",
                x.len()
            ),
        ));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(Error::input(
            path,
            format!(
                "the {what}'s sample {i} is {}: every sample must be finite",
                x[i]
            ),
        ));
    }
    Ok(x)
}

/// Scores `test` against `reference`, searching lags up to `max_lag_s`.
/// A reference that is empty, shorter than 2 samples, non-finite or silent,
/// a test that is empty or non-finite, and rates or lengths out of bounds
/// ([`RATES_HZ`], [`MAX_SAMPLES`]) are input errors; a metric that cannot
/// be computed is `null` with a note saying why.
pub fn score(reference: &Path, test: &Path, max_lag_s: f64) -> Result<ScoreReport> {
    if !(max_lag_s.is_finite() && max_lag_s >= 0.0) {
        return Err(Error::usage(
            "--max-lag-s",
            format!("must be >= 0 seconds, got {max_lag_s}"),
        ));
    }
    let fr = check_header(reference, None)?;
    let ft = check_header(test, Some(fr))?;
    let r = read_signal(reference, "reference", 2)?;
    if r.iter().all(|&v| v == 0.0) {
        return Err(Error::input(
            reference,
            "the reference is silent (every sample is 0): there is nothing to score against",
        ));
    }
    let mut t = read_signal(test, "test", 1)?;
    if fr != ft {
        let g = crate::math::numeric::gcd(fr as u64, ft as u64).max(1);
        t = metrics::resample(&t, fr as u64 / g, ft as u64 / g).ok_or_else(|| {
            Error::Analysis(format!(
                "cannot resample {} from {ft} Hz to {fr} Hz",
                test.display()
            ))
        })?;
    }
    let max_lag = (max_lag_s * fr as f64).round() as usize;
    let (lag, gain) = metrics::best_lag_gain(&r, &t, max_lag);
    let s = metrics::score(&r, &t, fr as f64, max_lag);
    let wiener_bound_db = metrics::stationary_wiener_snr_db(&r, &t, fr as f64, max_lag);
    let overlap = r.len().min(t.len());
    let mut notes = Vec::new();
    let mut why = |name: &str, v: f64, reason: String| {
        if !v.is_finite() {
            notes.push(format!("{name}: cannot be computed: {reason}"));
        }
    };
    why(
        "snr_db",
        s.snr_db,
        if gain.is_finite() && gain != 0.0 {
            "the test equals the reference after gain and lag: zero error, an infinite SNR".into()
        } else {
            format!("no gain fits the test to the reference: the test is silent or too short over the {overlap}-sample overlap")
        },
    );
    why(
        "ssnr_db",
        s.ssnr_db,
        format!("the {overlap}-sample overlap is too short or too quiet for one 20 ms segment"),
    );
    why(
        "llr",
        s.llr,
        format!("the {overlap}-sample overlap is too short or too quiet for a 10th-order LPC fit"),
    );
    why(
        "stoi",
        s.stoi,
        format!(
            "the overlap ({:.3} s) has fewer than 30 non-silent 25.6 ms frames (STOI needs about 0.4 s of speech-level signal)",
            overlap as f64 / fr as f64
        ),
    );
    why(
        "wiener_bound_db",
        wiener_bound_db,
        format!(
            "the {overlap}-sample overlap is shorter than two 0.1 s spectrum segments, or no gain fits"
        ),
    );
    Ok(ScoreReport {
        notes,
        wiener_bound_db,
        snr_db: s.snr_db,
        ssnr_db: s.ssnr_db,
        llr: s.llr,
        stoi: s.stoi,
        lag_samples: lag,
        gain,
        sample_rate_hz: fr,
    })
}
