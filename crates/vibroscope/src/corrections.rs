//! A stored calibration (REPORT.json of `calibrate`) applied to a finished
//! recovery (`listen --calibration`).

use crate::error::{Error, Result};
use crate::math::calibrate::{self as cal, Correction};
use crate::pipeline::Denoise;
use std::path::Path;

/// The reusable corrections of a stored report (`listen --calibration`).
pub fn load_calibration(path: &Path) -> Result<Vec<Correction>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not JSON: {e}")))?;
    cal::reusable_from_report(&v).map_err(|m| Error::input(path, m.to_string()))
}

/// Applies `corrections` to the WAV at `path` in place (at its own rate).
/// With `denoise` (the recovery was denoised), the same denoiser runs
/// again after the corrections, as in the thesis' Table 4.2: equalising
/// boosts the noise in the bands it lifts, and that noise is removed
/// again. Samples keep their times.
pub fn apply_to_wav(path: &Path, corrections: &[Correction], denoise: Denoise) -> Result<()> {
    let (rate, y) = crate::io::wav::read_mono(path)?;
    let mut z = cal::apply_all(corrections, &y, rate as f64);
    z = denoise_again(&z, rate as f64, denoise)?;
    let peak = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let ypeak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Keep the recovery's scale (the equaliser's level is arbitrary).
    let s = if peak > 0.0 { ypeak / peak } else { 1.0 };
    let z: Vec<f64> = z.iter().map(|v| v * s).collect();
    crate::io::wav::write_mono_f32(path, rate, &z)?;
    Ok(())
}

/// Runs the denoiser (default settings, as the stage's) over `x`; `x`
/// itself for [`Denoise::None`]. Output sample `k` is the estimate of input
/// sample `k` (the denoisers' latency is only in when a sample is
/// released), so the whole signal is fed and finished. The signal is a
/// recording, so each denoiser is first primed on its lead, as the stage
/// does on replay.
fn denoise_again(x: &[f64], rate: f64, kind: Denoise) -> Result<Vec<f64>> {
    use crate::math::denoise::{DenoiseConfig, SpectralSubtraction, SpeechEnhance, Wiener};
    use crate::math::MathError;
    let input: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    // Every default configuration has the same noise window.
    let lead_len = (DenoiseConfig::default().noise_window_s * rate).ceil() as usize;
    let lead = &input[..lead_len.min(input.len())];
    let mut out = Vec::with_capacity(input.len());
    match kind {
        Denoise::None => return Ok(x.to_vec()),
        Denoise::Subtract => {
            let mut d = SpectralSubtraction::with_defaults(rate).map_err(MathError::from)?;
            d.prime(lead);
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
        Denoise::Enhance => {
            let mut d = SpeechEnhance::with_defaults(rate).map_err(MathError::from)?;
            d.prime(lead);
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
        Denoise::Wiener => {
            let mut d = Wiener::with_defaults(rate).map_err(MathError::from)?;
            d.prime(lead);
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
    }
    Ok(out.iter().map(|&v| v as f64).collect())
}

/// The names of the corrections a report holds, for messages.
pub fn describe(corrections: &[Correction]) -> String {
    if corrections.is_empty() {
        return "none (the report keeps no object or camera effect)".into();
    }
    corrections
        .iter()
        .map(|c| c.kind().name())
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// Denoising again after a calibration keeps every sample at its time:
    /// a chirp in noise comes out at lag 0, as long as it went in.
    #[test]
    fn denoising_again_keeps_sample_times() {
        let fs = 2200.0;
        let mut s = 12345u64;
        let x: Vec<f64> = (0..4400)
            .map(|i| {
                let t = i as f64 / fs;
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                let noise = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.05;
                (2.0 * std::f64::consts::PI * (100.0 * t + 100.0 * t * t)).sin() + noise
            })
            .collect();
        for kind in [Denoise::Subtract, Denoise::Enhance] {
            let y = denoise_again(&x, fs, kind).unwrap();
            assert_eq!(y.len(), x.len(), "{kind:?}");
            let (lag, _) = crate::math::metrics::best_lag_gain(&x, &y, 500);
            assert_eq!(lag, 0, "{kind:?}");
        }
    }
}
