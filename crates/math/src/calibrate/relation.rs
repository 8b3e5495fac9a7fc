//! Bad input that only the data shows (issue 15): a reference that is
//! silent, and a reference the recording does not follow (another signal
//! than the one played, the wrong file, a region that does not see the
//! object). Both are refused rather than calibrated: an error, not a
//! report.

use super::correlation::recurrence;
use super::model::Model;
use super::signal::{stft_len, welch};
use super::CalError;

/// The loudest a silent reference reaches: one step of 16-bit audio.
pub const SILENT_PEAK: f64 = 1.0 / 32768.0;
/// How far above chance the model's held-out SNR must be, dB.
pub const MARGIN_DB: f64 = 10.0;
/// How far a periodic reference's fundamental must stand above the
/// recovery's spectrum around it, dB.
pub const LINE_DB: f64 = 10.0;

/// `Err` when `r` is silent (its peak at most [`SILENT_PEAK`]).
pub fn check_silent(r: &[f64]) -> Result<(), CalError> {
    let peak = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if peak <= SILENT_PEAK {
        return Err(CalError::Silent { peak });
    }
    Ok(())
}

/// `Err` when the recovery `y` does not follow the reference. A tone (a
/// reference that repeats within half a second with half its power or more
/// in one line, which reversed in time is itself) has that line read in
/// the recovery's spectrum: the strongest bin of the reference's, within a
/// bin, at least [`LINE_DB`] above the median of the recovery's bins 3 to
/// 24 bins away from it. Any other has the
/// model's held-out SNR (`snr_db`, after the effects kept) compared with
/// what the plain linear model reaches against the same reference reversed
/// in time (a signal with the same spectrum that was not played, searched
/// over the same lags): it must be [`MARGIN_DB`] above.
pub(super) fn check_follows(m: &Model, y: &[f64], snr_db: f64) -> Result<(), CalError> {
    let n = y.len();
    let t = m.target(n, 0, 0.0, 0.0);
    let max = ((0.5 * m.fs) as usize).min(n / 4);
    let nfft = stft_len(m.fs);
    let pt = welch(&t, nfft);
    let k0 = (1..pt.len())
        .max_by(|&a, &b| pt[a].total_cmp(&pt[b]))
        .unwrap_or(1);
    // A tone: periodic, and half its power or more in its strongest line
    // (sweeps repeated every 0.4 s are periodic too, but reverse into
    // other sweeps).
    // The line's bins: the strongest and one either side.
    let around =
        |p: &[f64]| -> Vec<f64> { p[k0.saturating_sub(1)..(k0 + 2).min(p.len())].to_vec() };
    let tonal = around(&pt).iter().sum::<f64>() >= 0.5 * pt[1..].iter().sum::<f64>();
    if tonal && recurrence(&t, max, true).is_some() {
        let py = welch(y, nfft);
        let line = around(&py).iter().fold(0.0f64, |a, v| a.max(*v));
        // Against its own neighbourhood (a strong line elsewhere leaks
        // into every bin of a short window's spectrum).
        let mut sorted: Vec<f64> = (1..py.len())
            .filter(|&k| (3..=24).contains(&k.abs_diff(k0)))
            .map(|k| py[k])
            .collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
        let db = 10.0 * (line / median.max(1e-300)).log10();
        if db.is_nan() || db < LINE_DB {
            return Err(CalError::NoLine {
                hz: k0 as f64 * m.fs / nfft as f64,
                db,
            });
        }
        return Ok(());
    }
    let reversed: Vec<f64> = m.r.iter().rev().copied().collect();
    let null = Model { r: &reversed, ..*m };
    let chance = null.errors(y, &null.fit_linear(y)).snr_db;
    if snr_db.is_nan() || snr_db < chance + MARGIN_DB {
        return Err(CalError::Unrelated {
            snr_db,
            chance_db: chance,
        });
    }
    Ok(())
}
