//! Wiener denoising: the MMSE estimate of each STFT coefficient, gain `xi / (1 + xi)`, on
//! the speech enhancer's decision-directed a-priori SNR and the shared noise tracker.

use super::engine::{engine_methods, Engine};
use super::speech::{LogMmse, SpeechEnhance};
use super::{DenoiseConfig, DenoiseError};

/// Streaming MMSE (Wiener) estimation of the STFT coefficients: per bin gain
/// `xi / (1 + xi)`, the linear MMSE estimate of the complex coefficient under
/// Gaussian speech and noise, which minimises the waveform's squared error
/// (the SNR) where [`SpeechEnhance`]'s log-amplitude gain minimises a
/// perceptual error. `xi` is the same decision-directed a-priori SNR
/// (`dd_alpha`, floored at `xi_min_db`), the noise power the same
/// minimum-statistics tracker (Martin 2001) as the other denoisers; see the
/// [module documentation](super) for framing, noise tracking and latency.
pub struct Wiener {
    engine: Engine<LogMmse>,
}

impl Wiener {
    /// A Wiener denoiser for a stream at `rate_hz`; uses `cfg.dd_alpha` and
    /// `cfg.xi_min_db`. Errors as [`SpeechEnhance::new`].
    pub fn new(rate_hz: f64, cfg: &DenoiseConfig) -> Result<Self, DenoiseError> {
        let mut e = SpeechEnhance::new(rate_hz, cfg)?;
        e.engine.rule.wiener = true;
        Ok(Self { engine: e.engine })
    }

    /// [`Wiener::new`] with [`DenoiseConfig::wiener`].
    pub fn with_defaults(rate_hz: f64) -> Result<Self, DenoiseError> {
        Self::new(rate_hz, &DenoiseConfig::wiener())
    }

    engine_methods!();

    /// Tracked noise power per frequency bin; see [`SpectralSubtraction::noise_psd`](super::SpectralSubtraction::noise_psd).
    pub fn noise_psd(&self) -> &[f64] {
        self.engine.tracker.noise()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::super::tests::{add_noise, speech_like, to_f32};
    use super::Wiener;
    use crate::metrics::snr_db;

    /// The Wiener mode raises the waveform SNR itself (not only segmental SNR)
    /// by at least 1 dB on the speech-like signal at 0 and 5 dB input SNR,
    /// at 8 kHz and at a camera's 2200 Hz.
    #[test]
    fn wiener_raises_snr() {
        for fs in [8000.0, 2200.0] {
            let clean = speech_like(fs, 6.0);
            for snr in [0.0, 5.0] {
                let noisy = add_noise(&clean, snr, 7);
                let mut d = Wiener::with_defaults(fs).unwrap();
                let mut out = Vec::new();
                d.process(&to_f32(&noisy), &mut out);
                d.finish(&mut out);
                let out: Vec<f64> = out.iter().map(|&v| v as f64).collect();
                let (a, b) = (snr_db(&clean, &noisy), snr_db(&clean, &out));
                println!("fs {fs} Hz, SNR {a:.2} -> {b:.2} dB (Wiener)");
                assert!(b >= a + 1.0, "fs {fs} Hz: SNR {a:.2} -> {b:.2} dB");
            }
        }
    }
}
