//! `resample`: band-limited resampling of an audio stream to a standard
//! audio rate (or any), so recovered sound plays everywhere: the frame
//! rate of a high-speed camera (600 Hz, 2200 Hz) is a rate many players
//! refuse.
//!
//! One resampler serves the whole project: [`Feed`], rubato's asynchronous
//! sinc interpolator (256-tap Blackman-Harris windowed sinc, 128x
//! oversampled table, cubic interpolation between its entries), the same
//! the `speaker` sink uses to reach the device rate. Here its delay is
//! compensated: the first [`Feed::delay`] output samples are dropped and
//! the output is trimmed to `round(n * rate_out / rate_in)` samples, so
//! output sample k is the signal at t0 + k / rate_out, aligned with the
//! input. [`resample_all`] does the same on a whole signal.
//!
//! `rate_hz` defaults to the input's rate when that is a standard audio
//! rate ([`STANDARD_RATES`]), else 48 kHz; a stream already at the target
//! rate passes unchanged.

use crate::*;
use rubato::audioadapter_buffers::direct::InterleavedSlice;
use rubato::{
    Async, FixedAsync, Resampler, SincInterpolationParameters, SincInterpolationType,
    WindowFunction,
};
use std::sync::Arc;

/// Audio rates every common player and sound card takes, Hz.
pub const STANDARD_RATES: &[f64] = &[
    8000.0, 11025.0, 16000.0, 22050.0, 32000.0, 44100.0, 48000.0, 88200.0, 96000.0,
];

/// The rate a stream at `rate_in` is written at by default: its own when
/// standard, else 48 kHz.
pub fn default_rate_hz(rate_in: f64) -> f64 {
    if STANDARD_RATES.iter().any(|&r| (r - rate_in).abs() < 1e-6) {
        rate_in
    } else {
        48_000.0
    }
}

params! {
    /// `resample`'s parameters.
    pub struct ResampleParams for "resample" {
        rate_hz: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .floats(1000.0, 384_000.0)
            .unit("Hz")
            .doc("output rate; default: the input's when it is a standard audio rate (8000, 11025, 16000, 22050, 32000, 44100, 48000, 88200, 96000), else 48000"),
    }
}

type P = ResampleParams;

pub const KIND: KindSpec = KindSpec {
    name: "resample",
    summary: "band-limited (256-tap sinc) resampling to rate_hz (default: a standard audio rate), delay compensated; the speaker's resampler",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        Ok(Box::new(ResamplePlan(v.rate_hz)))
    },
};

struct ResamplePlan(Option<f64>);

impl Plan for ResamplePlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(ResampleStage {
            want: self.0,
            run: None,
            buf: Vec::new(),
        })))
    }
}

/// A stream resampled with its delay compensated (see the module doc).
pub struct Aligned {
    feed: Feed,
    pub rate_in: f64,
    pub rate_out: f64,
    /// Output samples still to drop (the resampler's delay).
    skip: usize,
    /// Input samples fed and output samples given.
    n_in: u64,
    n_out: u64,
}

impl Aligned {
    pub fn new(rate_in: f64, rate_out: f64) -> Result<Aligned, String> {
        let feed = Feed::new(rate_in, rate_out)?;
        Ok(Aligned {
            skip: feed.delay(),
            feed,
            rate_in,
            rate_out,
            n_in: 0,
            n_out: 0,
        })
    }

    /// Output samples the resampler delays by (dropped here).
    pub fn delay(&self) -> usize {
        self.feed.delay()
    }

    /// Resamples `x`, appending what is ready to `out`.
    pub fn push(&mut self, x: &[f32], out: &mut Vec<f32>) -> Result<(), String> {
        self.n_in += x.len() as u64;
        let Aligned {
            feed, skip, n_out, ..
        } = self;
        feed.push(x, |y| take(skip, n_out, y, None, out))
    }

    /// The end of the stream: the rest, up to `round(n_in * rate_out / rate_in)` samples in all.
    pub fn finish(&mut self, out: &mut Vec<f32>) -> Result<(), String> {
        let total = (self.n_in as f64 * self.rate_out / self.rate_in).round() as u64;
        let Aligned {
            feed, skip, n_out, ..
        } = self;
        feed.flush(|y| take(skip, n_out, y, Some(total), out))?;
        // The flush gives the resampler's tail; more silence if still short.
        while *n_out < total {
            let before = *n_out;
            feed.push(&[0.0; 64], |y| take(skip, n_out, y, Some(total), out))?;
            feed.flush(|y| take(skip, n_out, y, Some(total), out))?;
            if *n_out == before {
                break;
            }
        }
        Ok(())
    }
}

/// Drops what is left of the delay from `y`, keeps at most `limit` samples
/// in all, and appends the rest to `out`.
fn take(skip: &mut usize, n_out: &mut u64, y: &[f32], limit: Option<u64>, out: &mut Vec<f32>) {
    let drop = (*skip).min(y.len());
    *skip -= drop;
    let mut y = &y[drop..];
    if let Some(l) = limit {
        let room = l.saturating_sub(*n_out) as usize;
        y = &y[..y.len().min(room)];
    }
    *n_out += y.len() as u64;
    out.extend_from_slice(y);
}

/// A whole signal resampled from `rate_in` to `rate_out`, aligned (the
/// stage's resampler, for recipes that post-process a finished WAV).
pub fn resample_all(x: &[f32], rate_in: f64, rate_out: f64) -> Result<Vec<f32>, String> {
    let mut a = Aligned::new(rate_in, rate_out)?;
    let mut out = Vec::with_capacity((x.len() as f64 * rate_out / rate_in) as usize + 64);
    a.push(x, &mut out)?;
    a.finish(&mut out)?;
    Ok(out)
}

struct ResampleStage {
    want: Option<f64>,
    /// The resampler (`None` inside: passing through), and the first block's time.
    run: Option<(Option<Aligned>, i64, f64)>,
    buf: Vec<f32>,
}

impl ResampleStage {
    fn emit(&mut self, out: &mut Emitter) {
        let Some((Some(a), t0, _)) = self.run.as_ref() else {
            return;
        };
        if self.buf.is_empty() {
            return;
        }
        let k = a.n_out - self.buf.len() as u64;
        let t = *t0 + (k as f64 * 1e9 / a.rate_out).round() as i64;
        let _ = out.emit(Item::Audio(AudioBlock {
            t0_ns: t,
            rate_hz: a.rate_out,
            samples: Arc::from(&self.buf[..]),
        }));
    }
}

impl Stage for ResampleStage {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if self.run.is_none() {
            let to = self.want.unwrap_or_else(|| default_rate_hz(a.rate_hz));
            let rs = if (to - a.rate_hz).abs() <= 1e-9 * to {
                None
            } else {
                Some(Aligned::new(a.rate_hz, to).map_err(StageError::dsp)?)
            };
            self.run = Some((rs, a.t0_ns, a.rate_hz));
        }
        let Some((rs, _, rate_in)) = self.run.as_mut() else {
            return Ok(());
        };
        if (a.rate_hz - *rate_in).abs() > 1e-9 * *rate_in {
            return Err(StageError::format(format!(
                "the sample rate changed from {} Hz to {} Hz mid-stream",
                rate_in, a.rate_hz
            )));
        }
        let Some(rs) = rs.as_mut() else {
            let _ = out.emit(Item::Audio(a));
            return Ok(());
        };
        self.buf.clear();
        rs.push(&a.samples, &mut self.buf)
            .map_err(StageError::dsp)?;
        self.emit(out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        let Some((Some(rs), _, _)) = self.run.as_mut() else {
            return Ok(());
        };
        self.buf.clear();
        rs.finish(&mut self.buf).map_err(StageError::dsp)?;
        self.emit(out);
        Ok(())
    }

    fn summary(&self) -> Option<String> {
        let (rs, _, rate_in) = self.run.as_ref()?;
        Some(match rs {
            None => format!("{rate_in} Hz is already the output rate: passed unchanged"),
            Some(a) => format!(
                "{} Hz -> {} Hz, 256-tap sinc (the speaker's resampler); its delay of {} output samples ({:.2} ms) is compensated: output aligned with its input",
                a.rate_in,
                a.rate_out,
                a.delay(),
                a.delay() as f64 * 1e3 / a.rate_out
            ),
        })
    }
}

/// Resampling from the signal's rate to the device's, into the ring.
pub struct Feed {
    rs: Async<f32>,
    chunk: usize,
    staged: Vec<f32>,
    out: Vec<f32>,
}

/// Input samples per resampler call: small, for latency.
const CHUNK: usize = 32;

impl Feed {
    /// A sinc resampler from `rate_in` to `rate_out` (256-tap Blackman-Harris
    /// windowed sinc, cutoff chosen by rubato for its sidelobe level).
    pub fn new(rate_in: f64, rate_out: f64) -> Result<Feed, String> {
        // rubato sizes its buffers by the ratio (and panics when they
        // overflow): refuse a ratio no signal needs.
        let ratio = rate_out / rate_in;
        if !(1e-5..=1e5).contains(&ratio) {
            return Err(format!(
                "cannot resample {rate_in} Hz to {rate_out} Hz: the ratio must be within 1e-5..1e5"
            ));
        }
        let params = SincInterpolationParameters::new(256, WindowFunction::BlackmanHarris2)
            .oversampling_factor(128)
            .interpolation(SincInterpolationType::Cubic);
        let rs = Async::<f32>::new_sinc(
            rate_out / rate_in,
            1.02,
            &params,
            CHUNK,
            1,
            FixedAsync::Input,
        )
        .map_err(|e| format!("cannot resample {rate_in} Hz to {rate_out} Hz: {e}"))?;
        let out = vec![0.0; rs.output_frames_max()];
        Ok(Feed {
            rs,
            chunk: CHUNK,
            staged: Vec::with_capacity(CHUNK),
            out,
        })
    }

    /// Output samples by which the resampler delays its input.
    pub fn delay(&self) -> usize {
        self.rs.output_delay()
    }

    /// Nudges the ratio by `rel` (1.0 = nominal; at most ±2%).
    pub fn adjust(&mut self, rel: f64) {
        if let Some(a) = self.rs.as_adjustable() {
            let _ = a.set_resample_ratio_relative(rel.clamp(0.985, 1.015), true);
        }
    }

    /// Feeds input samples; `sink` receives each resampled chunk.
    pub fn push(&mut self, x: &[f32], mut sink: impl FnMut(&mut [f32])) -> Result<(), String> {
        for &v in x {
            self.staged.push(v);
            if self.staged.len() == self.chunk {
                self.run_chunk(&mut sink)?;
            }
        }
        Ok(())
    }

    /// Pushes what is staged, padded with silence, and the resampler's tail.
    pub fn flush(&mut self, mut sink: impl FnMut(&mut [f32])) -> Result<(), String> {
        if !self.staged.is_empty() {
            self.staged.resize(self.chunk, 0.0);
            self.run_chunk(&mut sink)?;
        }
        let mut tail = self.delay();
        while tail > 0 {
            self.staged.resize(self.chunk, 0.0);
            let n = self.run_chunk(&mut sink)?;
            if n == 0 {
                break;
            }
            tail = tail.saturating_sub(n);
        }
        Ok(())
    }

    fn run_chunk(&mut self, sink: &mut impl FnMut(&mut [f32])) -> Result<usize, String> {
        let input = InterleavedSlice::new(&self.staged[..], 1, self.chunk)
            .map_err(|e| format!("resampler input: {e}"))?;
        let cap = self.out.len();
        let mut output = InterleavedSlice::new_mut(&mut self.out[..], 1, cap)
            .map_err(|e| format!("resampler output: {e}"))?;
        let (_, produced) = self
            .rs
            .process_into_buffer(&input, &mut output, None)
            .map_err(|e| format!("resampler: {e}"))?;
        self.staged.clear();
        sink(&mut self.out[..produced]);
        Ok(produced)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 440 Hz tone at 2200 Hz comes out of the resampler at 48 kHz as the
    /// same tone: compared sample by sample with the exact sine, after the
    /// resampler's reported delay.
    #[test]
    fn resampled_tone_matches_the_exact_tone() {
        let (fin, fout, f) = (2200.0, 48000.0, 440.0);
        let x: Vec<f32> = (0..4400)
            .map(|n| (2.0 * std::f64::consts::PI * f * n as f64 / fin).sin() as f32)
            .collect();
        let mut feed = Feed::new(fin, fout).unwrap();
        let mut y = Vec::new();
        for block in x.chunks(100) {
            feed.push(block, |c| y.extend_from_slice(c)).unwrap();
        }
        feed.flush(|c| y.extend_from_slice(c)).unwrap();
        let d = feed.delay();
        let expect_len = (x.len() as f64 * fout / fin) as usize;
        assert!(y.len() >= expect_len, "{} < {expect_len}", y.len());
        // The middle (past the filter's start-up), shifted by the reported
        // delay: fit a sin + b cos at 440 Hz; the fit must have unit
        // amplitude, a phase within one output sample of the reported delay
        // (which is rounded), and a residual 60 dB down.
        let w = 2.0 * std::f64::consts::PI * f / fout;
        let idx: Vec<usize> = (4800..expect_len - 4800).collect();
        let (amp, phase) =
            vibroscope_math::numeric::fit_tone(&y[d..], f, fout, 4800..expect_len - 4800);
        let (a, b) = (amp * phase.cos(), amp * phase.sin());
        let lag_samples = -phase / w;
        let (mut err, mut sig) = (0.0f64, 0.0f64);
        for &m in &idx {
            let fit = a * (w * m as f64).sin() + b * (w * m as f64).cos();
            err += (y[m + d] as f64 - fit).powi(2);
            sig += fit * fit;
        }
        let snr = 10.0 * (sig / err).log10();
        assert!((amp - 1.0).abs() < 0.005, "gain {amp}");
        assert!(
            lag_samples.abs() < 1.0,
            "delay off by {lag_samples} samples"
        );
        assert!(snr > 60.0, "resampled tone: residual {snr:.1} dB down");
    }

    /// The stage's aligned resampler: a 100 Hz tone at 600 Hz, resampled
    /// to 48 kHz, has the right length, unit gain, and the same timing:
    /// its phase against the exact tone at the output times is within
    /// 0.05 input samples (83 us; the resampler reports its delay rounded
    /// to whole output samples).
    #[test]
    fn aligned_resampling_keeps_time_and_length() {
        let (fin, fout, f) = (600.0, 48000.0, 100.0);
        let x: Vec<f32> = (0..1200)
            .map(|n| (2.0 * std::f64::consts::PI * f * n as f64 / fin).sin() as f32)
            .collect();
        let y = resample_all(&x, fin, fout).unwrap();
        assert_eq!(y.len(), 96_000);
        let (gain, ph) = vibroscope_math::numeric::fit_tone(&y, f, fout, 24_000..72_000);
        let lag_in = -ph / (2.0 * std::f64::consts::PI * f) * fin;
        eprintln!("aligned resampling: gain {gain:.5}, lag {lag_in:.4} input samples");
        assert!((gain - 1.0).abs() < 0.005, "gain {gain}");
        assert!(lag_in.abs() < 0.05, "lag {lag_in} input samples");
    }
}
