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

#[derive(Deserialize, serde::Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Sliding,
    Whole,
}

pub use crate::item::Taper;

/// A taper's coefficients and power response (the taper is a stream fact
/// in the core's items; what it computes is this stage's).
pub trait TaperExt: Copy {
    /// The periodic taper of length `n`.
    fn coefficients(self, n: usize) -> Vec<f64>;
    /// The power response for an `n`-sample segment.
    fn power_kernel(self, n: usize, half_bins: usize) -> Vec<f64>;
}

impl TaperExt for Taper {
    /// The periodic taper of length `n` (periodic, so Welch segments at 50%
    /// overlap sum to a constant for Hann).
    fn coefficients(self, n: usize) -> Vec<f64> {
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

    /// The taper's power response |W(ν)|² for an `n`-sample segment, at
    /// ν = j·[`KERNEL_STEP`] bins for |ν| <= `half_bins`, normalised to sum
    /// to 1: what one spectral line looks like in this stage's output (from
    /// a zero-padded FFT of the taper itself).
    fn power_kernel(self, n: usize, half_bins: usize) -> Vec<f64> {
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

/// How the channels' spectra make one.
#[derive(Deserialize, serde::Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    /// Their sum (Eq. 3.17 as written).
    Sum,
    /// Each scaled to its own noise floor and weighted by how far it
    /// stands out of it (see [`snr_weights`]).
    Snr,
}

params! {
    /// `spectrum`'s parameters.
    pub struct SpectrumParams for "spectrum" {
        mode: Mode = ParamSpec::of(ParamType::Choice(&["sliding", "whole"]), Def::Str("sliding"))
            .doc("a spectrum every `hop` samples, or one of the whole recording at the end"),
        combine: Combine = ParamSpec::of(ParamType::Choice(&["sum", "snr"]), Def::Str("sum"))
            .doc("whole: add the channels' power spectra (Eq. 3.17), or `snr`: scale each to its noise floor and weight it by its excess over that floor, so channels of noise only (a band across the motion, tiles off the vibrating part) add nothing"),
        window: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(8, MAX_WINDOW as i64)
            .unit("samples")
            .doc("segment length, even; default 1024 (whole: chosen from `segments`)"),
        hop: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, MAX_WINDOW as i64)
            .unit("samples")
            .doc("step between segments, <= window; default window/4 (whole: window/2)"),
        taper: Taper = ParamSpec::of(
            ParamType::Choice(&["hann", "hamming", "blackman", "rect"]),
            Def::Str("hann"),
        )
        .doc("taper applied to each segment (travels on the spectrum to `peaks`)"),
        welch: usize = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(1, 1024)
            .doc("sliding: the last K window spectra averaged"),
        segments: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, 4096)
            .doc("whole, without `window`: segments averaged (default frames/2048, 1..=64)"),
    }
}

type P = SpectrumParams;

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
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
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
        if v.combine == Combine::Snr && v.mode == Mode::Sliding {
            return Err(p.error(
                "combine",
                "\"snr\" applies to mode = \"whole\" (it weighs channels over the whole recording)",
            ));
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
            combine: v.combine,
            weighed: None,
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

/// `mode = "whole"`'s segments of a recording of `frames` (at least 8):
/// their length and the first frame of each. `window` (else the length
/// that lets about `segments` half-overlapping segments cover the
/// recording, else one per [`AUTO_FRAMES_PER_SEGMENT`] frames), `hop`
/// (else half the length); the segments are spread evenly so that the
/// first starts at 0 and the last ends at the last frame (no data left
/// out at the end).
pub fn whole_segments(
    frames: usize,
    window: Option<usize>,
    hop: Option<usize>,
    segments: Option<usize>,
) -> (usize, Vec<usize>) {
    let n = match window {
        Some(w) => w.min(frames & !1),
        None => {
            let k =
                segments.unwrap_or((frames / AUTO_FRAMES_PER_SEGMENT).clamp(1, AUTO_MAX_SEGMENTS));
            ((2 * frames) / (k + 1)).clamp(8, frames) & !1
        }
    };
    let hop = hop.unwrap_or(n / 2).clamp(1, n);
    let nseg = (frames - n) / hop + 1;
    let spread = if nseg > 1 {
        (frames - n) as f64 / (nseg - 1) as f64
    } else {
        0.0
    };
    let starts = (0..nseg)
        .map(|s| ((s as f64 * spread).round() as usize).min(frames - n))
        .collect();
    (n, starts)
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
    combine: Combine,
    /// Whole with `snr`: channels that stood out, and the largest weight's
    /// channel and share (for the summary).
    weighed: Option<(usize, usize, f64)>,
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
        let (n, starts) = whole_segments(frames, self.window, self.hop, self.segments);
        let mut fft = SegmentFft::new(n, self.taper, self.rate);
        let bins = fft.bins();
        // One spectrum per channel when they are weighed, else one sum.
        let per_channel = self.combine == Combine::Snr && ch > 1;
        let rows = if per_channel { ch } else { 1 };
        if per_channel {
            crate::memory::check(
                (rows * bins * std::mem::size_of::<f64>()) as u64,
                &format!("the spectra of {ch} channels of {bins} bins (combine = \"snr\")"),
                "use fewer channels (a `phase` stage's `tiles`, scales or orientations) or `combine = \"sum\"`",
            )
            .map_err(|message| StageError::Config {
                field: "memory",
                message,
            })?;
        }
        let mut acc = vec![0.0; rows * bins];
        let count = starts.len();
        for &start in &starts {
            let seg = &self.hist[start * ch..(start + n) * ch];
            for c in 0..ch {
                let row = if per_channel { c } else { 0 };
                fft.accumulate(seg, ch, c, &mut acc[row * bins..(row + 1) * bins]);
            }
        }
        acc.iter_mut().for_each(|p| *p /= count as f64);
        if per_channel {
            let w = snr_weights(&acc, bins, count);
            let stood = w.iter().filter(|&&(_, x)| x > 0.0).count();
            let total: f64 = w.iter().map(|&(_, x)| x).sum();
            let mut sum = vec![0.0; bins];
            if total > 0.0 {
                // Σ w_c P_c / floor_c, scaled by Σ w_c floor_c: one channel
                // alone gives its own spectrum.
                let level: f64 = w.iter().map(|&(f, x)| x / total * f).sum();
                for (c, &(floor, x)) in w.iter().enumerate() {
                    if x > 0.0 {
                        let k = x / total / floor * level;
                        for (s, p) in sum.iter_mut().zip(&acc[c * bins..(c + 1) * bins]) {
                            *s += k * p;
                        }
                    }
                }
                let (top, share) = w
                    .iter()
                    .enumerate()
                    .map(|(c, &(_, x))| (c, x / total))
                    .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
                self.weighed = Some((stood, top, share));
            } else {
                // No channel stands out: the plain sum (Eq. 3.17).
                for c in 0..ch {
                    for (s, p) in sum.iter_mut().zip(&acc[c * bins..(c + 1) * bins]) {
                        *s += p;
                    }
                }
                self.weighed = Some((0, 0, 0.0));
            }
            acc = sum;
        }
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

    fn summary(&self) -> Option<String> {
        let (stood, top, share) = self.weighed?;
        Some(if stood == 0 {
            format!(
                "combine = snr: no channel of {} stands out of its noise floor; the channels' spectra are summed",
                self.channels
            )
        } else {
            format!(
                "combine = snr: {stood} of {} channels stand out of their noise floor and make the spectrum; channel {top} weighs most ({:.0}%)",
                self.channels,
                100.0 * share
            )
        })
    }
}

/// The local noise floor of a power spectrum `p` of `segments` averages,
/// written to `floor`: at anchor bins, the median over ±max(16, f/4) bins
/// (f the bin; wide enough that a mode of 5% damping leaves the floor
/// under it, narrow enough at low frequencies to follow a 1/f rise),
/// converted from median to mean (χ²₂ₖ/2K), linear between anchors.
fn local_floor(p: &[f64], segments: usize, scratch: &mut Vec<f64>, floor: &mut [f64]) {
    let n = p.len();
    let to_mean = 1.0 / vibroscope_math::peaks::chi2_ratio_median(segments.max(1));
    let half = |b: usize| (b / 4).max(16);
    let at = |a: usize, scratch: &mut Vec<f64>| -> f64 {
        let h = half(a);
        scratch.clear();
        scratch.extend(
            p[a.saturating_sub(h)..(a + h + 1).min(n)]
                .iter()
                .copied()
                .filter(|v| v.is_finite() && *v > 0.0),
        );
        if scratch.is_empty() {
            return f64::MIN_POSITIVE;
        }
        let mid = scratch.len() / 2;
        *scratch.select_nth_unstable_by(mid, f64::total_cmp).1 * to_mean
    };
    let (mut a, mut fa) = (0usize, at(0, scratch));
    while a < n {
        let b = (a + (half(a) / 4).max(4)).min(n - 1);
        let fb = if b == a { fa } else { at(b, scratch) };
        let end = if b == n - 1 { n } else { b };
        for (k, f) in floor.iter_mut().enumerate().take(end).skip(a) {
            let t = if b > a {
                (k - a) as f64 / (b - a) as f64
            } else {
                0.0
            };
            *f = (fa + t * (fb - fa)).max(f64::MIN_POSITIVE);
        }
        if b == n - 1 {
            break;
        }
        (a, fa) = (b, fb);
    }
}

/// The bins under this one count for nothing in a channel's weight: there
/// a 1/f rise makes the local floor uncertain (a median of bins on one
/// side), and noise would pass for a line. A slow sway down there is still
/// found when no channel stands out elsewhere (the plain sum).
const LOW_BINS: usize = 8;

/// Widths (bins) over which a channel's excess is looked for: a line is
/// one or two bins wide, a damped mode tens; averaging `m` bins lowers
/// the level noise alone reaches.
const EXCESS_WIDTHS: [usize; 2] = [1, 8];

/// For each channel's K-segment power spectrum (`spectra`, channel-major,
/// `bins` each): its noise level (the median over the bins, DC and
/// Nyquist left out) and its weight, from bin [`LOW_BINS`] up, the excess of r = P/F over θ_m summed
/// over the spectrum, where F is the channel's local floor
/// ([`local_floor`]) and r is averaged over blocks of m = 1 and 8 bins
/// (a line, a damped mode); θ_m is the level noise alone passes with
/// probability 10⁻³ over all blocks of all channels and widths (χ²₂ₖ/2K;
/// K·m/2 averages for a block of m, since neighbouring bins of a tapered
/// segment are correlated). A channel of noise only has weight 0 (save 1
/// run in 1000); a channel that carries a line or a mode weighs by how far
/// it stands out (for a line, the weights of maximal-ratio combining: gain
/// over noise).
pub fn snr_weights(spectra: &[f64], bins: usize, segments: usize) -> Vec<(f64, f64)> {
    use vibroscope_math::peaks::chi2_ratio_isf;
    let ch = spectra.len() / bins.max(1);
    let tests = (bins * ch * EXCESS_WIDTHS.len()).max(1) as f64;
    let k = segments.max(1);
    // θ_m: where the χ² tail falls to 10⁻³ over all tests.
    let theta: Vec<f64> = EXCESS_WIDTHS
        .iter()
        .map(|&m| chi2_ratio_isf(1e-3 / tests, (k * m / 2).max(k)))
        .collect();
    let mut scratch = Vec::with_capacity(bins);
    let mut floor = vec![0.0; bins];
    let inner = 1..bins.saturating_sub(1).max(1);
    let tested = LOW_BINS.min(inner.end)..inner.end;
    (0..ch)
        .map(|c| {
            let p = &spectra[c * bins..(c + 1) * bins];
            scratch.clear();
            scratch.extend(
                p[inner.clone()]
                    .iter()
                    .copied()
                    .filter(|v| v.is_finite() && *v > 0.0),
            );
            if scratch.is_empty() {
                return (1.0, 0.0);
            }
            let mid = scratch.len() / 2;
            let level = *scratch.select_nth_unstable_by(mid, f64::total_cmp).1;
            local_floor(p, k, &mut scratch, &mut floor);
            // r over the bins tested, then its excess at each width.
            scratch.clear();
            scratch.extend(
                p[tested.clone()]
                    .iter()
                    .zip(&floor[tested.clone()])
                    .map(|(v, f)| if v.is_finite() { v / f } else { 0.0 }),
            );
            let excess: f64 = EXCESS_WIDTHS
                .iter()
                .zip(&theta)
                .map(|(&m, &th)| {
                    scratch
                        .chunks(m)
                        .map(|b| {
                            let r = b.iter().sum::<f64>() / b.len() as f64;
                            (r - th).max(0.0) * b.len() as f64
                        })
                        .sum::<f64>()
                })
                .sum();
            (level, excess)
        })
        .collect()
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

    /// `snr_weights` on K-averaged noise spectra with a 1/f rise and a
    /// 5%-damped mode's skirt: over 20 seeds no noise-only channel takes
    /// a weight in more than one; a channel with a line 12x its floor, or
    /// with a wide mode, always does.
    #[test]
    fn snr_weights_pick_the_channels_that_carry_a_line() {
        use vibroscope_math::rng::Xoshiro256;
        let (bins, k, ch) = (1025usize, 4usize, 40usize);
        let mut false_runs = 0;
        for seed in 0..20u64 {
            let mut r = Xoshiro256::new(seed + 1);
            let mut spectra = vec![0.0; bins * ch];
            for c in 0..ch {
                for b in 0..bins {
                    let mean = 1e-6 * (1.0 + 40.0 / (1.0 + b as f64)) * (1.0 + c as f64);
                    // χ²₂ₖ/2K: the mean of K exponential draws.
                    let e: f64 = (0..k).map(|_| -(1.0 - r.next_f64()).ln()).sum::<f64>() / k as f64;
                    spectra[c * bins + b] = mean * e;
                }
            }
            // Channel 3: a narrow line; channel 7: a mode of 5% damping
            // at bin 400 (half width 20 bins) 10x its floor.
            for b in 299..=301 {
                spectra[3 * bins + b] += 12.0 * 4e-6;
            }
            for b in 300..500 {
                let x = (b as f64 - 400.0) / 20.0;
                spectra[7 * bins + b] += 10.0 * 8e-6 / (1.0 + x * x);
            }
            let w = snr_weights(&spectra, bins, k);
            assert!(w[3].1 > 0.0, "seed {seed}: the line's channel {:?}", w[3]);
            assert!(w[7].1 > 0.0, "seed {seed}: the mode's channel {:?}", w[7]);
            let noise: Vec<usize> = (0..ch)
                .filter(|&c| c != 3 && c != 7 && w[c].1 > 0.0)
                .collect();
            if !noise.is_empty() {
                false_runs += 1;
            }
            // The level is the channel's median: about its mean at mid band.
            assert!(
                w[20].0 > 1e-6 * 21.0 * 0.8 && w[20].0 < 1e-6 * 21.0 * 1.5,
                "{:?}",
                w[20]
            );
        }
        assert!(
            false_runs <= 1,
            "{false_runs} of 20 runs weighed a noise channel"
        );
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
