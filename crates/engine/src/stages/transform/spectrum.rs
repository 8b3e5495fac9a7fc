//! `spectrum`: the global motion power spectrum (thesis Eq. 3.17),
//! P(ω) = Σ_local |F(A² u)|², summed over the input's channels (the
//! A²-weighted per-band signals of `phase`, or one audio channel).
//!
//! `mode = "sliding"` (default, for live use): a tapered window of `window`
//! samples is transformed every `hop` samples and emitted at once as an
//! [`Item::Spectrum`]; `welch = K` averages the last K windows (Welch 1967).
//! `mode = "whole"` keeps the recording and emits one spectrum at the end,
//! Welch-averaged over all segments of `window` samples (50% overlap unless
//! `hop` says otherwise); without `window`, the segment is chosen so that
//! about `segments` half-overlapping segments cover the recording (the
//! finest resolution that still averages the noise down); without
//! `segments` either, one per 2048 frames, 1 to 64 (a 300-frame clip keeps
//! its full resolution; a 10-minute recording at 300 fps averages 64).
//!
//! Power is a one-sided density (input units² per Hz): each segment has its
//! mean removed, is tapered (`hann`, `hamming`, `blackman` or `rect`), and
//! |X_k|² is scaled by 2 / (fs Σ w²) (DC and Nyquist by 1 / (fs Σ w²)).
//! The spectrum is stamped with the time of the centre of its data.
//!
//! ```toml
//! [[stage]]
//! id = "spectrum"
//! kind = "spectrum"
//! input = "phase"
//! mode = "sliding"   # or "whole"
//! window = 2048      # samples (whole: optional)
//! hop = 220          # samples (default window / 4; whole: window / 2)
//! taper = "hann"
//! welch = 1          # sliding: windows averaged
//! segments = 8       # whole, without `window` (default: frames / 2048, 1..=64)
//! ```

use crate::*;
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use serde::Deserialize;
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::peaks::KERNEL_STEP;

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Sliding,
    Whole,
}

pub use crate::item::Taper;

impl Taper {
    /// The periodic taper of length `n` (periodic, so Welch segments at 50%
    /// overlap sum to a constant for Hann).
    pub fn coefficients(self, n: usize) -> Vec<f64> {
        let tau = 2.0 * std::f64::consts::PI;
        (0..n)
            .map(|i| {
                let x = tau * i as f64 / n as f64;
                match self {
                    Taper::Hann => 0.5 - 0.5 * x.cos(),
                    Taper::Hamming => 0.54 - 0.46 * x.cos(),
                    Taper::Blackman => 0.42 - 0.5 * x.cos() + 0.08 * (2.0 * x).cos(),
                    Taper::Rect => 1.0,
                }
            })
            .collect()
    }
}

impl Taper {
    /// The taper's power response |W(ν)|² for an `n`-sample segment, at
    /// ν = j·[`KERNEL_STEP`] bins for |ν| <= `half_bins`, normalised to sum
    /// to 1: what one spectral line looks like in this stage's output (from
    /// a zero-padded FFT of the taper itself).
    pub fn power_kernel(self, n: usize, half_bins: usize) -> Vec<f64> {
        let pad = (1.0 / KERNEL_STEP).round() as usize;
        let len = n.max(2) * pad;
        let mut buf = vec![Complex::new(0.0, 0.0); len];
        for (b, w) in buf.iter_mut().zip(self.coefficients(n)) {
            b.re = w;
        }
        rustfft::FftPlanner::new()
            .plan_fft_forward(len)
            .process(&mut buf);
        let h = (half_bins * pad) as isize;
        let mut k: Vec<f64> = (-h..=h)
            .map(|j| buf[j.rem_euclid(len as isize) as usize].norm_sqr())
            .collect();
        let sum: f64 = k.iter().sum();
        if sum > 0.0 {
            k.iter_mut().for_each(|v| *v /= sum);
        }
        k
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    mode: Mode,
    window: Option<usize>,
    hop: Option<usize>,
    taper: Taper,
    welch: usize,
    segments: Option<usize>,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::new(
        "mode",
        ParamType::Choice(&["sliding", "whole"]),
        Def::Str("sliding"),
    )
    .doc("a spectrum every `hop` samples, or one of the whole recording at the end"),
    ParamSpec::new("window", ParamType::Int, Def::Optional)
        .ints(8, MAX_WINDOW as i64)
        .unit("samples")
        .doc("segment length, even; default 1024 (whole: chosen from `segments`)"),
    ParamSpec::new("hop", ParamType::Int, Def::Optional)
        .ints(1, MAX_WINDOW as i64)
        .unit("samples")
        .doc("step between segments, <= window; default window/4 (whole: window/2)"),
    ParamSpec::new(
        "taper",
        ParamType::Choice(&["hann", "hamming", "blackman", "rect"]),
        Def::Str("hann"),
    )
    .doc("taper applied to each segment (travels on the spectrum to `peaks`)"),
    ParamSpec::new("welch", ParamType::Int, Def::Int(1))
        .ints(1, 1024)
        .doc("sliding: the last K window spectra averaged"),
    ParamSpec::new("segments", ParamType::Int, Def::Optional)
        .ints(1, 4096)
        .doc("whole, without `window`: segments averaged (default frames/2048, 1..=64)"),
];
/// Whole mode without `segments`: one segment per this many frames...
pub const AUTO_FRAMES_PER_SEGMENT: usize = 2048;
/// ...and at most this many (more buys little noise, costs resolution).
pub const AUTO_MAX_SEGMENTS: usize = 64;

/// Default sliding window, in samples.
pub const DEFAULT_WINDOW: usize = 1024;
/// Largest window accepted (samples).
pub const MAX_WINDOW: usize = 1 << 24;

pub const KIND: KindSpec = KindSpec {
    name: "spectrum",
    summary: "global motion power spectrum Σ|F(A² u)|² over channels (Eq. 3.17): sliding window/hop/taper/welch, or mode = \"whole\" at the end",
    inputs: &[InPort::one(&[PortType::Samples, PortType::Audio])],
    outputs: &[OutPort::out(PortType::Spectrum)],
    params: PARAMS,
    plan: |p| {
        let v: P = p.resolve(PARAMS)?;
        if let Some(w) = v.window {
            if w % 2 != 0 {
                return Err(p.error(
                    "window",
                    format!("must be an even number of samples in 8..={MAX_WINDOW}, got {w}"),
                ));
            }
        }
        let window = v.window.unwrap_or(DEFAULT_WINDOW);
        if let Some(h) = v.hop {
            if h == 0 || (v.window.is_some() && h > window) || h > MAX_WINDOW {
                return Err(p.error(
                    "hop",
                    format!("must be 1..=window ({window}) samples, got {h}"),
                ));
            }
        }
        if v.welch > 1 && v.mode == Mode::Whole {
            return Err(p.error(
                "welch",
                "applies to mode = \"sliding\"; \"whole\" always averages all segments",
            ));
        }
        Ok(Box::new(SpectrumPlan(v)))
    },
};

struct SpectrumPlan(P);

impl Plan for SpectrumPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let v = self.0;
        Ok(Node::Stage(Box::new(SpectrumStage {
            mode: v.mode,
            window: v.window,
            hop: v.hop,
            taper: v.taper,
            welch: v.welch,
            segments: v.segments,
            channels: 0,
            rate: 0.0,
            t0_ns: None,
            received: 0,
            next_end: v.window.unwrap_or(DEFAULT_WINDOW) as u64,
            hist_start: 0,
            hist: Vec::new(),
            next_check: FIRST_CHECK_BYTES,
            refused: false,
            fft: None,
            history: VecDeque::new(),
            sum: Vec::new(),
        })))
    }
}

/// The FFT plan and every buffer one segment needs (allocated once).
pub struct SegmentFft {
    n: usize,
    taper: Vec<f64>,
    scale_dc: f64,
    fft: Arc<dyn RealToComplex<f64>>,
    input: Vec<f64>,
    output: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

impl SegmentFft {
    pub fn new(n: usize, taper: Taper, rate_hz: f64) -> Self {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        let taper = taper.coefficients(n);
        let s2: f64 = taper.iter().map(|w| w * w).sum();
        Self {
            n,
            scale_dc: 1.0 / (rate_hz * s2.max(f64::MIN_POSITIVE)),
            input: fft.make_input_vec(),
            output: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            taper,
        }
    }

    pub fn bins(&self) -> usize {
        self.n / 2 + 1
    }

    /// Adds the one-sided power density of channel `c` of the interleaved
    /// segment `data` (`n` frames of `channels`) to `acc`.
    pub fn accumulate(&mut self, data: &[f32], channels: usize, c: usize, acc: &mut [f64]) {
        let n = self.n;
        let mean = data
            .iter()
            .skip(c)
            .step_by(channels)
            .take(n)
            .map(|&x| x as f64)
            .sum::<f64>()
            / n as f64;
        for ((dst, &x), w) in self
            .input
            .iter_mut()
            .zip(data.iter().skip(c).step_by(channels))
            .zip(&self.taper)
        {
            *dst = (x as f64 - mean) * w;
        }
        if self
            .fft
            .process_with_scratch(&mut self.input, &mut self.output, &mut self.scratch)
            .is_err()
        {
            return; // lengths are fixed at construction; cannot happen
        }
        let last = self.output.len() - 1;
        for (k, (a, x)) in acc.iter_mut().zip(&self.output).enumerate() {
            let s = if k == 0 || k == last { 1.0 } else { 2.0 };
            *a += s * self.scale_dc * x.norm_sqr();
        }
    }
}

/// Whole mode keeps the recording, channels x frames: past this many
/// bytes, and at each doubling after, it checks that twice as much may be
/// taken (`crate::memory`), so a long recording of many channels (a
/// `phase` stage's `tiles`) is refused with a message, not killed for
/// memory.
const FIRST_CHECK_BYTES: usize = 64 << 20;

struct SpectrumStage {
    mode: Mode,
    window: Option<usize>,
    hop: Option<usize>,
    taper: Taper,
    welch: usize,
    segments: Option<usize>,
    channels: usize,
    rate: f64,
    t0_ns: Option<i64>,
    /// Frames received so far.
    received: u64,
    /// Sliding: frame count at which the next window ends.
    next_end: u64,
    /// Sliding: absolute index of the first frame in `hist`.
    hist_start: u64,
    /// Interleaved frames: the recording (whole) or the last window + hop (sliding).
    hist: Vec<f32>,
    /// Whole: the size of `hist` (bytes) at which the memory is checked next.
    next_check: usize,
    /// Whole: the recording was refused for memory; the end emits nothing
    /// (a spectrum of the part received would pass for the recording's).
    refused: bool,
    fft: Option<SegmentFft>,
    /// Sliding: the last `welch` window spectra, and their sum.
    history: VecDeque<Vec<f64>>,
    sum: Vec<f64>,
}

impl SpectrumStage {
    fn time_of(&self, frame: f64) -> i64 {
        self.t0_ns.unwrap_or(0) + (frame / self.rate * 1e9).round() as i64
    }

    fn emit(&self, out: &mut Emitter, power: &[f64], n: usize, centre: f64, segments: usize) {
        let _ = out.emit(Item::Spectrum(Spectrum {
            t_ns: self.time_of(centre),
            f0_hz: 0.0,
            resolution_hz: self.rate / n as f64,
            rate_hz: self.rate,
            window: n,
            taper: self.taper,
            segments,
            power: power.iter().map(|&p| p as f32).collect(),
        }));
    }

    fn sliding(&mut self, out: &mut Emitter) {
        let n = self.window.unwrap_or(DEFAULT_WINDOW);
        let hop = self.hop.unwrap_or((n / 4).max(1)) as u64;
        let ch = self.channels;
        while self.next_end <= self.received {
            let Some(fft) = self.fft.as_mut() else { return };
            let start = (self.next_end - n as u64 - self.hist_start) as usize * ch;
            let mut spec = if self.history.len() >= self.welch {
                self.history.pop_front().unwrap_or_default()
            } else {
                vec![0.0; fft.bins()]
            };
            spec.iter_mut().for_each(|p| *p = 0.0);
            let seg = &self.hist[start..start + n * ch];
            for c in 0..ch {
                fft.accumulate(seg, ch, c, &mut spec);
            }
            self.history.push_back(spec);
            // Welch: the mean of the last `welch` window spectra.
            let k = self.history.len() as f64;
            self.sum.iter_mut().for_each(|s| *s = 0.0);
            for h in &self.history {
                for (s, p) in self.sum.iter_mut().zip(h) {
                    *s += p / k;
                }
            }
            let centre = self.next_end as f64 - n as f64 / 2.0;
            self.emit(out, &self.sum, n, centre, self.history.len());
            self.next_end += hop;
        }
        // Drop the frames no later window needs.
        let keep_from = (self.next_end - n as u64).max(self.hist_start);
        let drop = ((keep_from - self.hist_start) as usize).min(self.hist.len() / ch);
        if drop > 0 {
            self.hist.drain(..drop * ch);
            self.hist_start += drop as u64;
        }
    }

    fn whole(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        let ch = self.channels.max(1);
        let frames = self.hist.len() / ch;
        if frames < 8 {
            return Err(StageError::dsp(format!(
                "spectrum: mode = \"whole\" needs at least 8 samples, got {frames}"
            )));
        }
        let n = match self.window {
            Some(w) => w.min(frames & !1),
            None => {
                let k = self
                    .segments
                    .unwrap_or((frames / AUTO_FRAMES_PER_SEGMENT).clamp(1, AUTO_MAX_SEGMENTS));
                ((2 * frames) / (k + 1)).clamp(8, frames) & !1
            }
        };
        let hop = self.hop.unwrap_or(n / 2).clamp(1, n);
        let mut fft = SegmentFft::new(n, self.taper, self.rate);
        let mut acc = vec![0.0; fft.bins()];
        let mut count = 0usize;
        // Segments are spread evenly so that the first starts at 0 and the
        // last ends at the last frame (no data left out at the end).
        let nseg = (frames - n) / hop + 1;
        let spread = if nseg > 1 {
            (frames - n) as f64 / (nseg - 1) as f64
        } else {
            0.0
        };
        for s in 0..nseg {
            let a = (s as f64 * spread).round() as usize;
            let start = a.min(frames - n);
            let seg = &self.hist[start * ch..(start + n) * ch];
            for c in 0..ch {
                fft.accumulate(seg, ch, c, &mut acc);
            }
            count += 1;
        }
        acc.iter_mut().for_each(|p| *p /= count as f64);
        tracing::info!(
            segments = count,
            window = n,
            resolution_hz = self.rate / n as f64,
            "whole-recording spectrum"
        );
        self.emit(out, &acc, n, frames as f64 / 2.0, count);
        Ok(())
    }
}

impl Stage for SpectrumStage {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let (t0, rate, ch, data) = match item {
            Item::Samples(s) => (s.t0_ns, s.rate_hz, s.channels.max(1), s.data),
            Item::Audio(a) => (a.t0_ns, a.rate_hz, 1, a.samples),
            _ => return Err(StageError::expected("samples or audio")),
        };
        if !(rate.is_finite() && rate > 0.0) {
            return Err(StageError::format(format!(
                "spectrum: input sample rate must be > 0 Hz, got {rate}"
            )));
        }
        if self.t0_ns.is_none() {
            self.t0_ns = Some(t0);
            self.rate = rate;
            self.channels = ch;
            if self.mode == Mode::Sliding {
                let n = self.window.unwrap_or(DEFAULT_WINDOW);
                let hop = self.hop.unwrap_or((n / 4).max(1));
                let f = SegmentFft::new(n, self.taper, rate);
                self.sum = vec![0.0; f.bins()];
                self.fft = Some(f);
                self.hist.reserve((n + hop + 4096) * ch);
            }
        } else if ch != self.channels || (rate - self.rate).abs() > 1e-9 * self.rate {
            return Err(StageError::format(format!(
                "spectrum: input changed from {} channels at {} Hz to {ch} at {rate} Hz",
                self.channels, self.rate
            )));
        }
        let frames = data.len() / ch;
        let bytes = (self.hist.len() + frames * ch) * std::mem::size_of::<f32>();
        if self.mode == Mode::Whole && bytes >= self.next_check {
            crate::memory::check(
                2 * bytes as u64,
                &format!(
                    "the whole-recording spectrum of {ch} channels ({} frames so far)",
                    self.received + frames as u64
                ),
                "use fewer channels (a `phase` stage's `tiles`, scales or orientations), `mode = \"sliding\"` or a shorter recording",
            )
            .map_err(|message| {
                self.refused = true;
                self.hist = Vec::new();
                StageError::Config {
                    field: "memory",
                    message,
                }
            })?;
            self.next_check = 2 * bytes;
        }
        self.hist.extend_from_slice(&data[..frames * ch]);
        self.received += frames as u64;
        if self.mode == Mode::Sliding {
            self.sliding(out);
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        if self.mode == Mode::Whole && self.t0_ns.is_some() && !self.refused {
            return self.whole(out);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a naive DFT of the tapered, mean-removed segment, with the
    /// one-sided density scaling; and Parseval: a sine of amplitude a
    /// integrates over frequency to its mean square a²/2.
    #[test]
    fn segment_power_matches_naive_dft_and_parseval() {
        let (n, fs) = (64usize, 100.0);
        let x: Vec<f32> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * 12.5 * i as f64 / fs).sin() as f32 * 2.0 + 0.3)
            .collect();
        let mut f = SegmentFft::new(n, Taper::Hann, fs);
        let mut acc = vec![0.0; f.bins()];
        f.accumulate(&x, 1, 0, &mut acc);
        let w = Taper::Hann.coefficients(n);
        let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
        let s2: f64 = w.iter().map(|v| v * v).sum();
        for (k, got) in acc.iter().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, (&xi, wi)) in x.iter().zip(&w).enumerate() {
                let ph = -2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
                re += (xi as f64 - mean) * wi * ph.cos();
                im += (xi as f64 - mean) * wi * ph.sin();
            }
            let one_sided = if k == 0 || k == n / 2 { 1.0 } else { 2.0 };
            let want = one_sided * (re * re + im * im) / (fs * s2);
            assert!(
                (got - want).abs() <= 1e-9 * want.max(1e-12),
                "bin {k}: {got} vs {want}"
            );
        }
        // 12.5 Hz is bin 8 exactly: the Hann line spreads over bins 7-9.
        let total: f64 = acc.iter().sum::<f64>() * fs / n as f64;
        assert!((total - 2.0).abs() < 0.05, "power {total}, want a²/2 = 2");
    }

    /// The power kernel sums to 1, is symmetric and peaks at the centre.
    #[test]
    fn power_kernel_is_a_normalised_line() {
        let k = Taper::Hann.power_kernel(1024, 4);
        assert_eq!(k.len(), 33);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        for j in 0..16 {
            assert!((k[j] - k[32 - j]).abs() < 1e-12);
            assert!(k[16] >= k[j]);
        }
        // Hann: |W(±1 bin)|² = |W(0)|²/4.
        assert!((k[20] / k[16] - 0.25).abs() < 1e-3, "{}", k[20] / k[16]);
    }
}
