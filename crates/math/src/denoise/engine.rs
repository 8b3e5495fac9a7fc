//! The streaming short-time Fourier transform every denoiser runs on: the frame geometry,
//! the analysis and synthesis windows with overlap-add, the fixed-latency release of
//! samples, and the per-bin gain rule each denoiser plugs into it.

use std::collections::VecDeque;
use std::f64::consts::PI;
use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

use super::noise::NoiseTracker;
use super::{
    invalid, DenoiseConfig, DenoiseError, MAX_FRAME_SAMPLES, MAX_NOISE_WINDOW_S, MIN_FRAME_SAMPLES,
};

/// A per-bin real gain computed from the noisy power and the noise estimate.
pub(super) trait GainRule {
    /// Writes the gain of every bin into `gain` from the noisy periodogram `power` and
    /// the noise power `noise` (same units, all slices `bins` long).
    fn gains(&mut self, power: &[f64], noise: &[f64], gain: &mut [f64]);
    /// Forgets all history.
    fn reset(&mut self);
}

/// Validated frame geometry: `(frame, hop)`.
fn geometry(rate_hz: f64, cfg: &DenoiseConfig) -> Result<(usize, usize), DenoiseError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(DenoiseError::InvalidRate(rate_hz));
    }
    if !(cfg.frame_ms.is_finite() && cfg.frame_ms > 0.0) {
        return Err(DenoiseError::InvalidFrameMs(cfg.frame_ms));
    }
    let divisor = if (cfg.overlap - 0.5).abs() < 1e-9 {
        2
    } else if (cfg.overlap - 0.75).abs() < 1e-9 {
        4
    } else {
        return Err(DenoiseError::InvalidOverlap(cfg.overlap));
    };
    if !(cfg.noise_window_s.is_finite()
        && cfg.noise_window_s > 0.0
        && cfg.noise_window_s <= MAX_NOISE_WINDOW_S)
    {
        return Err(invalid(
            "noise_window_s",
            cfg.noise_window_s,
            "finite, > 0 and <= 600 s",
        ));
    }
    let length = cfg.frame_ms * 1e-3 * rate_hz;
    if length.is_nan() || length < MIN_FRAME_SAMPLES as f64 {
        return Err(DenoiseError::FrameTooShort { length });
    }
    let exponent = length.log2().round();
    if exponent.is_nan() || exponent > f64::from(MAX_FRAME_SAMPLES.trailing_zeros()) {
        return Err(DenoiseError::FrameTooLong { length });
    }
    // 3 <= exponent <= 20 here.
    let frame = 1usize << (exponent as u32);
    Ok((frame, frame / divisor))
}

pub(super) struct Engine<R> {
    pub(super) frame: usize,
    pub(super) hop: usize,
    /// Partial frames at the stream start (they overlap the implicit leading zeros).
    warm_frames: u64,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
    win_a: Vec<f64>,
    win_s: Vec<f64>,
    /// 1 / Σ w_a², turning |Y|² into units of the input variance.
    power_scale: f64,
    /// Last `frame` input samples; new samples go after the first `frame - hop`.
    inbuf: Vec<f64>,
    fill: usize,
    time: Vec<f64>,
    spec: Vec<Complex<f64>>,
    power: Vec<f64>,
    gain: Vec<f64>,
    scratch_fwd: Vec<Complex<f64>>,
    scratch_inv: Vec<Complex<f64>>,
    ola: Vec<f64>,
    ready: VecDeque<f32>,
    /// Leading finished samples that belong to the implicit zero padding.
    pad_skip: usize,
    frames: u64,
    total_in: u64,
    total_out: u64,
    flushing: bool,
    pub(super) tracker: NoiseTracker,
    pub(super) rule: R,
}

impl<R: GainRule> Engine<R> {
    /// Builds the engine; `make_rule` receives the number of frequency bins.
    pub(super) fn new(
        rate_hz: f64,
        cfg: &DenoiseConfig,
        make_rule: impl FnOnce(usize) -> R,
    ) -> Result<Self, DenoiseError> {
        let (frame, hop) = geometry(rate_hz, cfg)?;
        let bins = frame / 2 + 1;
        let mut planner = RealFftPlanner::<f64>::new();
        let forward = planner.plan_fft_forward(frame);
        let inverse = planner.plan_fft_inverse(frame);
        let sqrt_window = hop * 2 == frame;
        let win_a: Vec<f64> = (0..frame)
            .map(|i| {
                let hann = 0.5 * (1.0 - (2.0 * PI * i as f64 / frame as f64).cos());
                if sqrt_window {
                    hann.sqrt()
                } else {
                    hann
                }
            })
            .collect();
        // Overlapped sum of squared analysis windows; constant (1 or 1.5) up to rounding.
        let overlapped: Vec<f64> = (0..hop)
            .map(|i| (i..frame).step_by(hop).map(|j| win_a[j] * win_a[j]).sum())
            .collect();
        let win_s: Vec<f64> = win_a
            .iter()
            .enumerate()
            .map(|(i, w)| w / overlapped[i % hop])
            .collect();
        let energy: f64 = win_a.iter().map(|w| w * w).sum();
        let scratch_fwd = forward.make_scratch_vec();
        let scratch_inv = inverse.make_scratch_vec();
        Ok(Self {
            frame,
            hop,
            warm_frames: (frame / hop - 1) as u64,
            spec: forward.make_output_vec(),
            forward,
            inverse,
            win_a,
            win_s,
            power_scale: 1.0 / energy,
            inbuf: vec![0.0; frame],
            fill: 0,
            time: vec![0.0; frame],
            power: vec![0.0; bins],
            gain: vec![1.0; bins],
            scratch_fwd,
            scratch_inv,
            ola: vec![0.0; frame],
            ready: VecDeque::with_capacity(2 * frame + hop),
            pad_skip: frame - hop,
            frames: 0,
            total_in: 0,
            total_out: 0,
            flushing: false,
            tracker: NoiseTracker::new(bins, frame, hop, rate_hz, cfg.noise_window_s),
            rule: make_rule(bins),
        })
    }

    pub(super) fn latency(&self) -> usize {
        self.frame
    }

    fn reset(&mut self) {
        self.reset_stream();
        self.tracker.reset();
    }

    /// Resets everything but the noise tracker.
    fn reset_stream(&mut self) {
        self.inbuf.fill(0.0);
        self.fill = 0;
        self.ola.fill(0.0);
        self.ready.clear();
        self.pad_skip = self.frame - self.hop;
        self.frames = 0;
        self.total_in = 0;
        self.total_out = 0;
        self.flushing = false;
        self.rule.reset();
    }

    /// Feeds `lead` to the noise tracker alone (analysis frames, no output), then
    /// starts the stream afresh with the tracker kept. See `prime` of the denoisers.
    pub(super) fn prime(&mut self, lead: &[f32]) {
        self.reset_stream();
        let head = self.frame - self.hop;
        for chunk in lead.chunks_exact(self.hop) {
            for (dst, &x) in self.inbuf[head..].iter_mut().zip(chunk) {
                *dst = if x.is_finite() { f64::from(x) } else { 0.0 };
            }
            self.analyse();
            if self.frames >= self.warm_frames {
                self.tracker.update(&self.power);
            }
            self.inbuf.copy_within(self.hop.., 0);
            self.frames += 1;
        }
        self.reset_stream();
    }

    /// The windowed frame's power spectrum into `power` (its spectrum in `spec`).
    fn analyse(&mut self) {
        for ((t, &x), &w) in self.time.iter_mut().zip(&self.inbuf).zip(&self.win_a) {
            *t = x * w;
        }
        if self
            .forward
            .process_with_scratch(&mut self.time, &mut self.spec, &mut self.scratch_fwd)
            .is_err()
        {
            self.spec.fill(Complex::new(0.0, 0.0));
        }
        for (p, s) in self.power.iter_mut().zip(&self.spec) {
            *p = s.norm_sqr() * self.power_scale;
        }
    }

    pub(super) fn process(&mut self, input: &[f32], out: &mut Vec<f32>) {
        let head = self.frame - self.hop;
        let mut rest = input;
        while !rest.is_empty() {
            let take = (self.hop - self.fill).min(rest.len());
            let (chunk, tail) = rest.split_at(take);
            let start = head + self.fill;
            for (dst, &x) in self.inbuf[start..start + take].iter_mut().zip(chunk) {
                *dst = if x.is_finite() { f64::from(x) } else { 0.0 };
            }
            self.fill += take;
            self.total_in += take as u64;
            rest = tail;
            if self.fill == self.hop {
                self.process_frame();
                self.release(out);
            }
        }
        self.release(out);
    }

    pub(super) fn finish(&mut self, out: &mut Vec<f32>) {
        self.flushing = true;
        let head = self.frame - self.hop;
        while self.total_out + (self.ready.len() as u64) < self.total_in {
            self.inbuf[head + self.fill..].fill(0.0);
            self.fill = self.hop;
            self.process_frame();
            // Release what the fixed latency allows so the queue stays within capacity.
            self.release(out);
        }
        while self.total_out < self.total_in {
            match self.ready.pop_front() {
                Some(v) => {
                    out.push(v);
                    self.total_out += 1;
                }
                None => break,
            }
        }
        self.reset();
    }

    /// Appends finished samples up to `total_in - latency`.
    fn release(&mut self, out: &mut Vec<f32>) {
        let allowed = self.total_in.saturating_sub(self.frame as u64);
        while self.total_out < allowed {
            match self.ready.pop_front() {
                Some(v) => {
                    out.push(v);
                    self.total_out += 1;
                }
                None => break,
            }
        }
    }

    fn process_frame(&mut self) {
        self.analyse();
        if self.frames >= self.warm_frames {
            if !self.flushing {
                self.tracker.update(&self.power);
            }
            self.rule
                .gains(&self.power, self.tracker.noise(), &mut self.gain);
        } else {
            self.gain.fill(1.0);
        }
        for (s, &g) in self.spec.iter_mut().zip(&self.gain) {
            *s *= g;
        }
        // A real signal's DC and Nyquist bins are real.
        if let Some(first) = self.spec.first_mut() {
            first.im = 0.0;
        }
        if let Some(last) = self.spec.last_mut() {
            last.im = 0.0;
        }
        if self
            .inverse
            .process_with_scratch(&mut self.spec, &mut self.time, &mut self.scratch_inv)
            .is_err()
        {
            self.time.fill(0.0);
        }
        let scale = 1.0 / self.frame as f64;
        for ((o, &t), &w) in self.ola.iter_mut().zip(&self.time).zip(&self.win_s) {
            *o += t * w * scale;
        }
        for &v in &self.ola[..self.hop] {
            if self.pad_skip > 0 {
                self.pad_skip -= 1;
            } else {
                let clamped = v.clamp(-f64::from(f32::MAX), f64::from(f32::MAX));
                // NaN cannot arise from finite input; map it to silence regardless.
                self.ready.push_back(if clamped.is_nan() {
                    0.0
                } else {
                    clamped as f32
                });
            }
        }
        self.ola.copy_within(self.hop.., 0);
        let n = self.frame;
        self.ola[n - self.hop..].fill(0.0);
        self.inbuf.copy_within(self.hop.., 0);
        self.fill = 0;
        self.frames += 1;
    }
}

/// The stream methods both denoisers share, forwarded to their `engine`.
macro_rules! engine_methods {
    () => {
        /// Feeds any number of samples; appends every finished output sample to `out`.
        pub fn process(&mut self, input: &[f32], out: &mut Vec<f32>) {
            self.engine.process(input, out);
        }

        /// Flushes the tail (zero-padded) at end of stream, so that the total output length
        /// equals the total input length, then resets for a new stream.
        pub fn finish(&mut self, out: &mut Vec<f32>) {
            self.engine.finish(out);
        }

        /// Replay only: warms the noise tracker on the stream's first samples `lead`
        /// (which are then fed again, from the start, through `process`) and resets
        /// the stream, keeping the tracker. The noise floor at the start is then the
        /// minimum over the lead rather than the cold start's short average (module
        /// documentation, "Noise tracking"), which counts a signal present from the
        /// first sample as noise. A live stream cannot look ahead and starts cold.
        /// Allocates nothing; a lead shorter than a hop does nothing but the reset.
        pub fn prime(&mut self, lead: &[f32]) {
            self.engine.prime(lead);
        }

        /// Fixed latency in samples: one frame.
        pub fn latency_samples(&self) -> usize {
            self.engine.latency()
        }

        /// Frame length in samples.
        pub fn frame_len(&self) -> usize {
            self.engine.frame
        }

        /// Hop between frames in samples.
        pub fn hop_len(&self) -> usize {
            self.engine.hop
        }
    };
}

pub(super) use engine_methods;

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::super::tests::{to_f32, white};
    use super::super::{DenoiseConfig, SpectralSubtraction, SpeechEnhance};

    #[test]
    fn frame_geometry_follows_rate_and_overlap() {
        let ss = SpectralSubtraction::with_defaults(8000.0).unwrap();
        assert_eq!(
            (ss.frame_len(), ss.hop_len(), ss.latency_samples()),
            (256, 64, 256)
        );
        let se = SpeechEnhance::with_defaults(2200.0).unwrap();
        assert_eq!(
            (se.frame_len(), se.hop_len(), se.latency_samples()),
            (64, 16, 64)
        );
        let cfg = DenoiseConfig {
            overlap: 0.5,
            ..DenoiseConfig::default()
        };
        let ss = SpectralSubtraction::new(44100.0, &cfg, 2.0, 0.02).unwrap();
        assert_eq!((ss.frame_len(), ss.hop_len()), (1024, 512));
        assert_eq!(ss.noise_psd().len(), 513);
    }

    /// With unit gains (alpha = 0) the STFT/overlap-add chain reconstructs the input
    /// exactly and aligned, at any length, for both window/overlap pairs.
    #[test]
    fn unit_gain_reconstructs_input_exactly() {
        for fs in [8000.0, 2200.0] {
            for overlap in [0.5, 0.75] {
                let cfg = DenoiseConfig {
                    overlap,
                    ..DenoiseConfig::default()
                };
                for len in [0usize, 1, 17, 63, 64, 65, 255, 256, 257, 1000, 12_345] {
                    let x = to_f32(&white(len, 0.3, len as u64 + 1));
                    for block in [1usize, 37, 4096] {
                        let mut d = SpectralSubtraction::new(fs, &cfg, 0.0, 0.02).unwrap();
                        let mut out = Vec::new();
                        for chunk in x.chunks(block) {
                            d.process(chunk, &mut out);
                        }
                        d.finish(&mut out);
                        assert_eq!(out.len(), x.len());
                        for (k, (a, b)) in x.iter().zip(&out).enumerate() {
                            assert!(
                                (a - b).abs() <= 1e-6,
                                "fs {fs} overlap {overlap} len {len} k {k}: {a} vs {b}"
                            );
                        }
                    }
                }
            }
        }
    }
}
