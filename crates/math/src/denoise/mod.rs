//! Streaming single-channel noise reduction for recovered audio.
//!
//! The visual microphone leaves broadband noise on the recovered motion signal, and the
//! thesis (ch. 4.2.1) cleans it with one of two classic denoisers; both are implemented
//! here as causal, fixed-latency stream processors:
//!
//! * [`SpectralSubtraction`], magnitude spectral subtraction (Boll 1979) with Berouti's
//!   over-subtraction factor `alpha` and spectral floor `beta` — the choice when accuracy
//!   of the waveform matters,
//! * [`SpeechEnhance`], the Bayesian MMSE log-spectral-amplitude estimator (Ephraim &
//!   Malah 1985) with the decision-directed a-priori SNR — the perceptually motivated
//!   choice when intelligibility matters (the family of Loizou 2005).
//!
//! # Signal path
//!
//! Both share one short-time Fourier transform with weighted overlap-add. A frame is the
//! power of two nearest (in the logarithmic sense) to [`DenoiseConfig::frame_ms`] at the
//! stream rate, e.g. 256 samples at 8 kHz and 64 samples at 2200 Hz for the default
//! 32 ms, and the hop is a half or a quarter of it ([`DenoiseConfig::overlap`]). The
//! analysis window is the periodic Hann window (75 % overlap) or its square root (50 %
//! overlap); the synthesis window is the analysis window divided by the overlapped sum
//! of squared analysis windows, so that analysis followed by synthesis with unit gains
//! reconstructs the input exactly (to rounding). Gains are real, so the noisy phase is
//! kept.
//!
//! # Noise tracking
//!
//! The noise power spectrum is tracked while streaming, without looking ahead, by
//! minimum statistics with optimal smoothing (Martin 2001): a per-bin recursively
//! smoothed periodogram whose smoothing constant drops where the signal rises above the
//! noise estimate, its minimum over a sliding window of [`DenoiseConfig::noise_window_s`]
//! (default 1.5 s, kept as 8 sub-windows), a bias correction computed from the running
//! variance of the smoothed periodogram, and Martin's fast rise when the noise floor
//! steps up. Martin's constants, stated for 16 ms hops, are converted to time constants
//! so that the tracker behaves the same at any rate and overlap. The first 0.1 s of
//! full frames only average the periodogram (a short bootstrap that assumes the stream
//! starts with noise, like the noise-only lead of batch implementations); minimum
//! tracking takes over after that, so a signal present from the first sample is
//! suppressed as noise until its first pause. A recording can do better: `prime`
//! (on each denoiser) warms the tracker on the stream's first seconds, which are then
//! fed again from the start, so the noise floor at the start is a true minimum. The
//! frames that still overlap the implicit zeros before the stream start (the first
//! `frame - hop` samples) pass with unit gain. A noise floor that falls is followed within a fraction of a second, one that rises
//! within about one window length plus one sub-window.
//!
//! Minimum statistics treats anything stationary over the window as noise: a steady tone
//! that lasts longer than the window is suppressed like hum. Speech, and any signal that
//! leaves every frequency band quiet for a moment within each window, passes.
//!
//! # Streaming and latency
//!
//! [`SpectralSubtraction::process`] / [`SpeechEnhance::process`] accept blocks of any
//! size; the output is identical bit for bit however the input is split. Output sample
//! `k` is the estimate of input sample `k`, released exactly `latency_samples()` (one
//! frame) samples later: after `T` input samples in total, exactly
//! `T.saturating_sub(latency_samples())` output samples have been appended. `finish`
//! zero-pads the tail, appends the remaining samples (so the total output length equals
//! the total input length) and returns the processor to its freshly constructed state,
//! ready for a new stream. Once constructed, neither call allocates except to grow the
//! caller's `out` vector.
//!
//! # Robustness
//!
//! Construction validates the configuration and returns a [`DenoiseError`]; processing
//! never panics. Non-finite input samples are treated as zeros, and output samples are
//! clamped to the finite `f32` range.

mod engine;
mod noise;
mod spectral;
mod speech;
mod wiener;

pub use spectral::SpectralSubtraction;
pub use speech::{expint_e1, SpeechEnhance};
pub use wiener::Wiener;

/// Smallest accepted frame, in samples (the requested `frame_ms * rate` must reach it).
pub const MIN_FRAME_SAMPLES: usize = 8;
/// Largest frame, in samples; longer requests are rejected to bound memory.
pub const MAX_FRAME_SAMPLES: usize = 1 << 20;
/// Longest accepted noise-tracking window, in seconds.
pub const MAX_NOISE_WINDOW_S: f64 = 600.0;
/// Default over-subtraction factor of [`SpectralSubtraction`].
pub const DEFAULT_ALPHA: f64 = 2.0;
/// Default spectral floor of [`SpectralSubtraction`].
pub const DEFAULT_BETA: f64 = 0.02;

/// Errors from constructing a denoiser.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DenoiseError {
    /// The sample rate is zero, negative or not finite.
    #[error("sample rate must be finite and positive, got {0} Hz")]
    InvalidRate(f64),
    /// The frame duration is zero, negative or not finite.
    #[error("frame duration must be finite and positive, got {0} ms")]
    InvalidFrameMs(f64),
    /// The overlap is neither 0.5 nor 0.75.
    #[error("overlap must be 0.5 or 0.75, got {0}")]
    InvalidOverlap(f64),
    /// `frame_ms * rate` is shorter than [`MIN_FRAME_SAMPLES`].
    #[error("frame of {length} samples is shorter than the minimum of {MIN_FRAME_SAMPLES}")]
    FrameTooShort {
        /// Requested frame length in samples, `frame_ms * rate / 1000`.
        length: f64,
    },
    /// The frame rounds to more than [`MAX_FRAME_SAMPLES`].
    #[error("frame of {length} samples is longer than the maximum of {MAX_FRAME_SAMPLES}")]
    FrameTooLong {
        /// Requested frame length in samples, `frame_ms * rate / 1000`.
        length: f64,
    },
    /// Some other parameter is out of its range.
    #[error("parameter {name} = {value} is invalid: {expected}")]
    InvalidParameter {
        /// Name of the parameter.
        name: &'static str,
        /// Value given.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
}

/// Configuration shared by [`SpectralSubtraction`] and [`SpeechEnhance`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenoiseConfig {
    /// Target frame duration in milliseconds; the frame is the power of two nearest to
    /// it at the stream rate. Default 32 ms.
    pub frame_ms: f64,
    /// Frame overlap, 0.5 (square-root Hann windows) or 0.75 (Hann windows). Default 0.75.
    pub overlap: f64,
    /// Length of the minimum-statistics window of the noise tracker in seconds, in
    /// `(0, 600]`. Default 1.5 s.
    pub noise_window_s: f64,
    /// [`SpeechEnhance`] and [`Wiener`] only: weight of the previous frame in the
    /// decision-directed a-priori SNR, in `[0, 1)`. Default 0.98 ([`DenoiseConfig::wiener`]:
    /// [`WIENER_DD_ALPHA`]).
    pub dd_alpha: f64,
    /// [`SpeechEnhance`] and [`Wiener`] only: lower bound of the a-priori SNR in dB (finite, at most
    /// 0). Default -25 dB.
    pub xi_min_db: f64,
}

/// The decision-directed weight [`SpeechEnhance`] uses by default ([`DenoiseConfig`]'s
/// default): Ephraim & Malah's 0.98.
pub const LSA_DD_ALPHA: f64 = 0.98;

/// The decision-directed weight [`Wiener`] uses by default. The LSA gain's 0.98
/// (Ephraim & Malah's choice, for little musical noise) smooths the a-priori SNR over
/// about 50 frames; the Wiener gain is judged by squared error, which a faster prior
/// lowers: on four rendered speech scenes whose recovered SNR ranged from -15 to +8 dB,
/// 0.9 raised the denoised SNR by 0.5 to 1.6 dB over 0.98, and none of 0.95, 0.85, 0.8
/// or 0.7 was better on all four (docs/engine.md, "Denoisers").
pub const WIENER_DD_ALPHA: f64 = 0.9;

impl DenoiseConfig {
    /// The default configuration with [`WIENER_DD_ALPHA`]: what [`Wiener::with_defaults`]
    /// and the `wiener` stage kind use.
    pub fn wiener() -> Self {
        Self {
            dd_alpha: WIENER_DD_ALPHA,
            ..Self::default()
        }
    }
}

impl Default for DenoiseConfig {
    fn default() -> Self {
        Self {
            frame_ms: 32.0,
            overlap: 0.75,
            noise_window_s: 1.5,
            dd_alpha: LSA_DD_ALPHA,
            xi_min_db: -25.0,
        }
    }
}

fn invalid(name: &'static str, value: f64, expected: &'static str) -> DenoiseError {
    DenoiseError::InvalidParameter {
        name,
        value,
        expected,
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::metrics::{best_lag_gain, segmental_snr_db, snr_db, stoi};
    use std::f64::consts::PI;

    // ----- deterministic test signals --------------------------------------------------

    /// SplitMix64 generator with Box-Muller Gaussian samples.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        /// Uniform in (0, 1].
        fn uniform(&mut self) -> f64 {
            ((self.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
        }

        fn gauss(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
        }
    }

    pub(super) fn white(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng(seed);
        (0..n).map(|_| sigma * rng.gauss()).collect()
    }

    /// On/off gate at `phase` in [0, 1) of a period of `period_s`: on for the first
    /// `duty` of the period, with 25 ms raised-cosine ramps inside the on part.
    fn gate(phase: f64, duty: f64, period_s: f64) -> f64 {
        gate_with_ramp(phase, duty, period_s, 0.025)
    }

    /// [`gate`] with ramps of `ramp_s` seconds.
    fn gate_with_ramp(phase: f64, duty: f64, period_s: f64, ramp_s: f64) -> f64 {
        let ramp = (ramp_s / period_s).min(duty / 2.0);
        if phase < ramp {
            0.5 - 0.5 * (PI * phase / ramp).cos()
        } else if phase < duty - ramp {
            1.0
        } else if phase < duty {
            0.5 + 0.5 * (PI * (phase - duty + ramp) / ramp).cos()
        } else {
            0.0
        }
    }

    /// Speech-like test signal at `fs`, RMS 0.1: a harmonic series on a pitch gliding
    /// between 120 and 220 Hz, shaped by three drifting formant resonances over a
    /// -6 dB/octave source tilt above 400 Hz, and gated on and off at a syllabic rate of
    /// 4 ± 0.6 Hz (on for 75 % of each syllable, 25 ms ramps). Harmonics fade out
    /// towards 0.45 fs.
    pub(super) fn speech_like(fs: f64, seconds: f64) -> Vec<f64> {
        let n = (seconds * fs) as usize;
        let mut out = Vec::with_capacity(n);
        let (mut pitch_phase, mut syllable_phase) = (0.0f64, 0.0f64);
        let top = 0.45 * fs;
        for i in 0..n {
            let t = i as f64 / fs;
            let f0 = 170.0 + 50.0 * (2.0 * PI * 0.35 * t).sin();
            pitch_phase = (pitch_phase + f0 / fs).fract();
            let rate = 4.0 + 0.6 * (2.0 * PI * 0.23 * t).sin();
            syllable_phase = (syllable_phase + rate / fs).fract();
            let g = gate(syllable_phase, 0.75, 1.0 / rate);
            let formants = [
                (600.0 + 150.0 * (2.0 * PI * 1.1 * t).sin(), 90.0, 1.0),
                (
                    1500.0 + 300.0 * (2.0 * PI * 0.7 * t + 1.0).sin(),
                    130.0,
                    0.5,
                ),
                (2500.0, 180.0, 0.25),
            ];
            let mut s = 0.0;
            for h in 1.. {
                let f = h as f64 * f0;
                if f >= top {
                    break;
                }
                let mut env = 0.03;
                for &(fc, bw, gain) in &formants {
                    let d = (f - fc) / bw;
                    env += gain / (1.0 + d * d);
                }
                env *= ((top - f) / (0.05 * fs)).clamp(0.0, 1.0);
                env /= (1.0 + (f / 400.0).powi(2)).sqrt();
                s += env * (2.0 * PI * h as f64 * pitch_phase).sin();
            }
            out.push(g * s);
        }
        let rms = rms(&out);
        out.iter().map(|v| 0.1 * v / rms).collect()
    }

    /// Clean multi-tone: five tones spread over the band at least four frequency bins
    /// apart, each switched on and off independently (periods 0.45 to 1.05 s, on 60 %,
    /// 20 ms ramps), after 0.3 s of silence. The gaps and the silent lead matter: minimum
    /// statistics would take a tone that never pauses, or one sounding from the first
    /// sample, for noise (see the module documentation).
    fn gated_multitone(fs: f64, seconds: f64) -> Vec<f64> {
        let n = (seconds * fs) as usize;
        let freqs = [0.08, 0.22, 0.38, 0.55, 0.75].map(|r| r * fs / 2.0);
        let periods = [0.45, 0.6, 0.75, 0.9, 1.05];
        (0..n)
            .map(|i| {
                let t = i as f64 / fs - 0.3;
                if t < 0.0 {
                    return 0.0;
                }
                freqs
                    .iter()
                    .zip(periods)
                    .enumerate()
                    .map(|(j, (&f, p))| {
                        let phase = (t / p + 0.13 * j as f64).fract();
                        let g = gate_ramped(phase, 0.6, p);
                        0.1 * g * (2.0 * PI * f * t + j as f64).sin()
                    })
                    .sum()
            })
            .collect()
    }

    /// Like [`gate`] but with 20 ms ramps.
    fn gate_ramped(phase: f64, duty: f64, period_s: f64) -> f64 {
        gate_with_ramp(phase, duty, period_s, 0.02)
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt()
    }

    /// `clean` plus white Gaussian noise at the given global SNR.
    pub(super) fn add_noise(clean: &[f64], snr_db: f64, seed: u64) -> Vec<f64> {
        let sigma = rms(clean) / 10f64.powf(snr_db / 20.0);
        let noise = white(clean.len(), sigma, seed);
        clean.iter().zip(&noise).map(|(s, n)| s + n).collect()
    }

    pub(super) fn to_f32(x: &[f64]) -> Vec<f32> {
        x.iter().map(|&v| v as f32).collect()
    }

    fn to_f64(x: &[f32]) -> Vec<f64> {
        x.iter().map(|&v| f64::from(v)).collect()
    }

    // ----- running either denoiser -----------------------------------------------------

    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Method {
        Subtraction,
        Lsa,
    }

    const METHODS: [Method; 2] = [Method::Subtraction, Method::Lsa];

    enum Denoiser {
        Ss(SpectralSubtraction),
        Lsa(SpeechEnhance),
    }

    impl Denoiser {
        fn new(method: Method, fs: f64, cfg: &DenoiseConfig) -> Self {
            match method {
                Method::Subtraction => Denoiser::Ss(
                    SpectralSubtraction::new(fs, cfg, DEFAULT_ALPHA, DEFAULT_BETA).unwrap(),
                ),
                Method::Lsa => Denoiser::Lsa(SpeechEnhance::new(fs, cfg).unwrap()),
            }
        }

        fn process(&mut self, x: &[f32], out: &mut Vec<f32>) {
            match self {
                Denoiser::Ss(d) => d.process(x, out),
                Denoiser::Lsa(d) => d.process(x, out),
            }
        }

        fn finish(&mut self, out: &mut Vec<f32>) {
            match self {
                Denoiser::Ss(d) => d.finish(out),
                Denoiser::Lsa(d) => d.finish(out),
            }
        }

        fn latency(&self) -> usize {
            match self {
                Denoiser::Ss(d) => d.latency_samples(),
                Denoiser::Lsa(d) => d.latency_samples(),
            }
        }

        fn frame_len(&self) -> usize {
            match self {
                Denoiser::Ss(d) => d.frame_len(),
                Denoiser::Lsa(d) => d.frame_len(),
            }
        }

        fn noise_psd(&self) -> &[f64] {
            match self {
                Denoiser::Ss(d) => d.noise_psd(),
                Denoiser::Lsa(d) => d.noise_psd(),
            }
        }
    }

    /// Runs a whole signal through `d` in blocks of `block` samples and finishes.
    fn run_on(d: &mut Denoiser, x: &[f32], block: usize) -> Vec<f32> {
        let mut out = Vec::new();
        for chunk in x.chunks(block.max(1)) {
            d.process(chunk, &mut out);
        }
        d.finish(&mut out);
        out
    }

    fn run(method: Method, fs: f64, x: &[f64]) -> Vec<f64> {
        let mut d = Denoiser::new(method, fs, &DenoiseConfig::default());
        to_f64(&run_on(&mut d, &to_f32(x), usize::MAX))
    }

    /// Writes `x` as a 32-bit float WAV into `$VIBROSCOPE_DENOISE_WAV_DIR`, if set.
    fn maybe_write_wav(name: &str, fs: f64, x: &[f64]) {
        let Ok(dir) = std::env::var("VIBROSCOPE_DENOISE_WAV_DIR") else {
            return;
        };
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: fs as u32,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let path = std::path::Path::new(&dir).join(format!("{name}.wav"));
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for &v in x {
            w.write_sample(v as f32).unwrap();
        }
        w.finalize().unwrap();
    }

    // ----- framing, reconstruction, alignment ------------------------------------------

    /// Zero noise: a clean (gated) multi-tone comes out with SNR > 25 dB, the same
    /// length, and aligned (cross-correlation peak at lag 0).
    #[test]
    fn clean_signal_passes_nearly_unchanged() {
        for fs in [8000.0, 2200.0] {
            let clean = gated_multitone(fs, 5.0);
            for method in METHODS {
                let out = run(method, fs, &clean);
                assert_eq!(out.len(), clean.len());
                let snr = snr_db(&clean, &out);
                let frame = Denoiser::new(method, fs, &DenoiseConfig::default()).frame_len();
                let (lag, gain) = best_lag_gain(&clean, &out, 2 * frame);
                println!("clean multitone fs {fs} {method:?}: SNR {snr:.1} dB, lag {lag}, gain {gain:.4}");
                assert!(snr > 25.0, "{method:?} at {fs} Hz: SNR {snr:.1} dB");
                assert_eq!(lag, 0, "{method:?} at {fs} Hz");
                assert!((gain - 1.0).abs() < 0.05);
            }
        }
    }

    // ----- denoising ---------------------------------------------------------------------

    /// Speech-like signal plus white noise at 0 and 5 dB, at 8 kHz and 2200 Hz: the
    /// segmental SNR improves. The MMSE-LSA estimator gains at least 3 dB everywhere.
    /// Spectral subtraction with the default over-subtraction alpha = 2 gains at least
    /// 3 dB at 8 kHz / 0 dB; elsewhere its speech attenuation (alpha = 2 removes about
    /// 1.8 noise magnitudes from every bin) limits it to the smaller asserted bounds
    /// (measured: +2.9 dB at 8 kHz / 5 dB and 2200 Hz / 0 dB, +1.5 dB at 2200 Hz / 5 dB,
    /// stable to ±0.2 dB over noise seeds). Run with `--nocapture` for the table, and set
    /// `VIBROSCOPE_DENOISE_WAV_DIR` to listen to the signals.
    #[test]
    fn speech_like_noise_is_reduced() {
        let mut report = String::new();
        for fs in [8000.0, 2200.0] {
            let clean = speech_like(fs, 6.0);
            for snr in [0.0, 5.0] {
                let noisy = add_noise(&clean, snr, 7);
                let seg_in = segmental_snr_db(&clean, &noisy, fs);
                let stoi_in = stoi(&clean, &noisy, fs);
                maybe_write_wav(&format!("speech_{fs}_{snr}_clean"), fs, &clean);
                maybe_write_wav(&format!("speech_{fs}_{snr}_noisy"), fs, &noisy);
                for method in METHODS {
                    let out = run(method, fs, &noisy);
                    maybe_write_wav(&format!("speech_{fs}_{snr}_{method:?}"), fs, &out);
                    assert_eq!(out.len(), noisy.len());
                    let seg_out = segmental_snr_db(&clean, &out, fs);
                    let stoi_out = stoi(&clean, &out, fs);
                    let gain = seg_out - seg_in;
                    let line = format!(
                        "fs {fs:>6} Hz, SNR {snr} dB, {method:?}: segSNR {seg_in:.2} -> \
                         {seg_out:.2} dB ({gain:+.2}), STOI {stoi_in:.3} -> {stoi_out:.3}, \
                         SNR {:.2} -> {:.2} dB\n",
                        snr_db(&clean, &noisy),
                        snr_db(&clean, &out)
                    );
                    report += &line;
                    let needed = match (method, fs > 3000.0, snr > 0.0) {
                        (Method::Lsa, _, _) => 3.0,
                        (Method::Subtraction, true, false) => 3.0,
                        (Method::Subtraction, true, true) => 2.5,
                        (Method::Subtraction, false, false) => 2.5,
                        (Method::Subtraction, false, true) => 1.0,
                    };
                    assert!(gain >= needed, "{line} needs +{needed} dB");
                    assert!(stoi_out.is_finite());
                }
            }
        }
        println!("{report}");
    }

    /// A signal sounding from the first sample: cold, the tracker's start takes it for
    /// noise and the first half second loses SNR; primed on the stream's first 1.5 s
    /// (replay), it does not. Both give one output sample per input sample, and the
    /// primed stream is as block-size independent as the cold one.
    #[test]
    fn priming_spares_a_signal_present_from_the_first_sample() {
        let fs = 2200.0;
        let clean = speech_like(fs, 4.0);
        let noisy = add_noise(&clean, 5.0, 11);
        let x = to_f32(&noisy);
        let lead = &x[..(1.5 * fs) as usize];
        let head = (0.5 * fs) as usize;
        let run = |prime: bool, block: usize| {
            let mut d = Wiener::with_defaults(fs).unwrap();
            if prime {
                d.prime(lead);
            }
            let mut out = Vec::new();
            for c in x.chunks(block) {
                d.process(c, &mut out);
            }
            d.finish(&mut out);
            out.iter().map(|&v| v as f64).collect::<Vec<_>>()
        };
        let (cold, primed) = (run(false, 64), run(true, 64));
        assert_eq!(cold.len(), x.len());
        assert_eq!(primed.len(), x.len());
        assert_eq!(primed, run(true, 7), "block size changed the primed output");
        let (a, b, c) = (
            snr_db(&clean[..head], &noisy[..head]),
            snr_db(&clean[..head], &cold[..head]),
            snr_db(&clean[..head], &primed[..head]),
        );
        println!("first 0.5 s: SNR {a:.2} dB in, {b:.2} cold, {c:.2} primed");
        assert!(
            c >= b + 1.0 && c >= a + 1.0,
            "first 0.5 s: {a:.2} in, {b:.2} cold, {c:.2} primed"
        );
        // A lead shorter than a hop only resets.
        let mut d = Wiener::with_defaults(fs).unwrap();
        d.prime(&x[..3]);
        let mut out = Vec::new();
        d.process(&x, &mut out);
        d.finish(&mut out);
        assert_eq!(out.iter().map(|&v| v as f64).collect::<Vec<_>>(), cold);
    }

    // ----- streaming ---------------------------------------------------------------------

    /// Feeding blocks of 1, 37 or 4096 samples gives the same output bit for bit, and
    /// after every call exactly `total_in - latency` samples have been released.
    #[test]
    fn block_size_does_not_change_output() {
        for fs in [8000.0, 2200.0] {
            let noisy = to_f32(&add_noise(&speech_like(fs, 2.5), 3.0, 11));
            for method in METHODS {
                let mut outputs = Vec::new();
                for block in [1usize, 37, 4096] {
                    let mut d = Denoiser::new(method, fs, &DenoiseConfig::default());
                    let latency = d.latency();
                    let mut out = Vec::new();
                    let mut fed = 0usize;
                    for chunk in noisy.chunks(block) {
                        d.process(chunk, &mut out);
                        fed += chunk.len();
                        assert_eq!(out.len(), fed.saturating_sub(latency));
                    }
                    d.finish(&mut out);
                    assert_eq!(out.len(), noisy.len());
                    outputs.push(out);
                }
                for other in &outputs[1..] {
                    assert!(
                        outputs[0]
                            .iter()
                            .zip(other)
                            .all(|(a, b)| a.to_bits() == b.to_bits()),
                        "{method:?} at {fs} Hz differs between block sizes"
                    );
                }
            }
        }
    }

    /// `finish` resets: a second stream through the same object matches a fresh one.
    #[test]
    fn finish_resets_for_a_new_stream() {
        let fs = 8000.0;
        let x = to_f32(&add_noise(&speech_like(fs, 1.0), 0.0, 5));
        for method in METHODS {
            let mut d = Denoiser::new(method, fs, &DenoiseConfig::default());
            let first = run_on(&mut d, &x, 100);
            let second = run_on(&mut d, &x, 333);
            assert_eq!(first.len(), x.len());
            assert!(first
                .iter()
                .zip(&second)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    // ----- noise tracking ----------------------------------------------------------------

    /// Mean tracked noise power over the inner bins, in dB relative to `truth`.
    fn tracked_db(d: &Denoiser, truth: f64) -> f64 {
        let psd = d.noise_psd();
        let inner = &psd[1..psd.len() - 1];
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        10.0 * (mean / truth).log10()
    }

    /// White noise whose level steps up by 10 dB after 5 s: the tracked floor is within
    /// 3 dB of the old level before the step, still near it right after the step (no
    /// look-ahead), and within 3 dB of the new level 2 s after it. A 10 dB step down is
    /// followed within 0.5 s.
    #[test]
    fn noise_tracker_follows_level_steps() {
        for fs in [8000.0, 2200.0] {
            for overlap in [0.5, 0.75] {
                let cfg = DenoiseConfig {
                    overlap,
                    ..DenoiseConfig::default()
                };
                for method in METHODS {
                    let sigma2: f64 = 1e-4;
                    let step = (5.0 * fs) as usize;
                    let mut x = white(2 * step, sigma2.sqrt(), 3);
                    for v in &mut x[step..] {
                        *v *= 10f64.sqrt();
                    }
                    let x = to_f32(&x);
                    let mut d = Denoiser::new(method, fs, &cfg);
                    let mut out = Vec::new();
                    let at = |t: f64| (t * fs) as usize;

                    // Calibration on stationary noise, averaged over 2..5 s.
                    d.process(&x[..at(2.0)], &mut out);
                    let mut sum = 0.0;
                    let mut count = 0.0;
                    for w in (at(2.0)..step).collect::<Vec<_>>().chunks(at(0.25)) {
                        d.process(&x[w[0]..=w[w.len() - 1]], &mut out);
                        sum += tracked_db(&d, sigma2);
                        count += 1.0;
                    }
                    let before = sum / count;
                    d.process(&x[step..step + at(0.2)], &mut out);
                    let just_after = tracked_db(&d, 10.0 * sigma2);
                    d.process(&x[step + at(0.2)..step + at(2.0)], &mut out);
                    let after = tracked_db(&d, 10.0 * sigma2);
                    println!(
                        "fs {fs} overlap {overlap} {method:?}: before {before:+.2} dB, \
                         0.2 s after step {just_after:+.2} dB, 2 s after {after:+.2} dB"
                    );
                    assert!(before.abs() < 1.5, "stationary calibration {before:.2} dB");
                    assert!(just_after < -6.0, "reacted within 0.2 s: {just_after:.2}");
                    assert!(after.abs() < 3.0, "2 s after the step: {after:.2} dB");

                    // Step back down by 10 dB.
                    let down: Vec<f32> = white(at(0.5), sigma2.sqrt(), 9)
                        .iter()
                        .map(|&v| v as f32)
                        .collect();
                    d.process(&down, &mut out);
                    let after_down = tracked_db(&d, sigma2);
                    assert!(
                        after_down.abs() < 3.0,
                        "0.5 s after step down: {after_down:.2}"
                    );
                }
            }
        }
    }

    // ----- configuration errors and hostile input ------------------------------------------

    #[test]
    fn bad_configuration_is_rejected() {
        let ok = DenoiseConfig::default();
        for rate in [0.0, -8000.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                SpectralSubtraction::new(rate, &ok, 2.0, 0.02),
                Err(DenoiseError::InvalidRate(_))
            ));
            assert!(matches!(
                SpeechEnhance::new(rate, &ok),
                Err(DenoiseError::InvalidRate(_))
            ));
        }
        for overlap in [0.0, 0.6, 0.9, 1.0, f64::NAN] {
            let cfg = DenoiseConfig { overlap, ..ok };
            assert!(matches!(
                SpectralSubtraction::new(8000.0, &cfg, 2.0, 0.02),
                Err(DenoiseError::InvalidOverlap(_))
            ));
            assert!(matches!(
                SpeechEnhance::new(8000.0, &cfg),
                Err(DenoiseError::InvalidOverlap(_))
            ));
        }
        // 32 ms at 200 Hz is 6.4 samples; tiny rates likewise.
        for rate in [200.0, 1.0, 1e-300, f64::MIN_POSITIVE] {
            assert!(matches!(
                SpeechEnhance::new(rate, &ok),
                Err(DenoiseError::FrameTooShort { .. })
            ));
        }
        let short = DenoiseConfig {
            frame_ms: 0.5,
            ..ok
        };
        assert!(matches!(
            SpectralSubtraction::new(8000.0, &short, 2.0, 0.02),
            Err(DenoiseError::FrameTooShort { .. })
        ));
        // Exactly 8 samples is accepted.
        let eight = DenoiseConfig {
            frame_ms: 1.0,
            ..ok
        };
        let d = SpectralSubtraction::new(8000.0, &eight, 2.0, 0.02).unwrap();
        assert_eq!(d.frame_len(), 8);
        for rate in [1e12, 1e300, f64::MAX] {
            assert!(matches!(
                SpeechEnhance::new(rate, &ok),
                Err(DenoiseError::FrameTooLong { .. })
            ));
        }
        for frame_ms in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let cfg = DenoiseConfig { frame_ms, ..ok };
            assert!(matches!(
                SpeechEnhance::new(8000.0, &cfg),
                Err(DenoiseError::InvalidFrameMs(_))
            ));
        }
        for noise_window_s in [0.0, -1.0, f64::NAN, 1e9] {
            let cfg = DenoiseConfig {
                noise_window_s,
                ..ok
            };
            assert!(matches!(
                SpeechEnhance::new(8000.0, &cfg),
                Err(DenoiseError::InvalidParameter {
                    name: "noise_window_s",
                    ..
                })
            ));
        }
        for (alpha, beta) in [
            (-1.0, 0.02),
            (f64::NAN, 0.02),
            (2.0, -0.1),
            (2.0, 1.5),
            (2.0, f64::NAN),
        ] {
            assert!(matches!(
                SpectralSubtraction::new(8000.0, &ok, alpha, beta),
                Err(DenoiseError::InvalidParameter { .. })
            ));
        }
        for dd_alpha in [-0.1, 1.0, f64::NAN] {
            let cfg = DenoiseConfig { dd_alpha, ..ok };
            assert!(SpeechEnhance::new(8000.0, &cfg).is_err());
        }
        for xi_min_db in [1.0, f64::NAN, f64::NEG_INFINITY] {
            let cfg = DenoiseConfig { xi_min_db, ..ok };
            assert!(SpeechEnhance::new(8000.0, &cfg).is_err());
        }
        // Errors render.
        let msg = SpeechEnhance::new(0.0, &ok).err().unwrap().to_string();
        assert!(msg.contains("sample rate"));
    }

    #[test]
    fn hostile_input_never_panics() {
        let cfgs = [
            DenoiseConfig::default(),
            DenoiseConfig {
                overlap: 0.5,
                frame_ms: 4.0,
                noise_window_s: 1e-3,
                ..DenoiseConfig::default()
            },
        ];
        let specials = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            -f32::MAX,
            f32::MIN_POSITIVE,
            1e-45,
            0.0,
        ];
        let mut rng = Rng(99);
        let mixed: Vec<f32> = (0..5000)
            .map(|_| {
                let u = rng.next_u64();
                if u.is_multiple_of(7) {
                    specials[(u >> 8) as usize % specials.len()]
                } else {
                    rng.gauss() as f32
                }
            })
            .collect();
        let inputs: Vec<Vec<f32>> = vec![
            vec![],
            vec![0.5],
            vec![0.0; 3000],
            vec![f32::NAN; 3000],
            vec![f32::MAX; 3000],
            vec![1e-45; 3000],
            (0..3000)
                .map(|i| if i % 2 == 0 { f32::MAX } else { -f32::MAX })
                .collect(),
            mixed,
        ];
        for cfg in &cfgs {
            for method in METHODS {
                for fs in [8000.0, 2200.0, 192_000.0] {
                    let mut d = Denoiser::new(method, fs, cfg);
                    for x in &inputs {
                        let out = run_on(&mut d, x, 211);
                        assert_eq!(out.len(), x.len());
                        assert!(out.iter().all(|v| v.is_finite()), "{method:?} {fs}");
                        if x.iter().all(|&v| v == 0.0 || !v.is_finite()) {
                            assert!(out.iter().all(|&v| v == 0.0));
                        }
                    }
                }
            }
        }
    }
}
