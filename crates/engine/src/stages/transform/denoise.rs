//! `spectral_subtraction` (Boll 1979), `speech_enhance` (MMSE
//! log-spectral amplitude, Ephraim & Malah 1985) and `wiener` (MMSE of the
//! STFT coefficients, gain xi/(1+xi), the same decision-directed a-priori
//! SNR): streaming denoisers on an audio stream
//! ([`vibroscope_math::denoise`]). All track the noise floor as
//! they go (minimum statistics; no look at the whole recording) and delay
//! the signal by one STFT frame; every output block carries the capture
//! time of its first sample, taken from the input blocks.
//!
//! Where replay and live differ (causality): on replay (no live source in
//! the graph) a denoiser first reads `noise_window_s` of the stream and
//! warms its noise tracker on it (`prime`), then denoises from the start,
//! so a signal present from the first sample is not taken for noise; its
//! first output waits for that lead. Live, it starts cold, with one frame
//! of latency.

use crate::*;
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::denoise::{
    DenoiseConfig, DenoiseError, SpectralSubtraction, SpeechEnhance, Wiener, DEFAULT_ALPHA,
    DEFAULT_BETA, LSA_DD_ALPHA, WIENER_DD_ALPHA,
};

const FRAME_MS: ParamSpec = ParamSpec::new("frame_ms", ParamType::Float, Def::Float(32.0))
    .above(0.0)
    .unit("ms")
    .doc("STFT frame length (rounded to a power of two of samples)");
const OVERLAP: ParamSpec = ParamSpec::new("overlap", ParamType::Float, Def::Float(0.75))
    .floats(0.5, 0.75)
    .doc("frame overlap: 0.5 or 0.75");
const NOISE_WINDOW: ParamSpec = ParamSpec::new("noise_window_s", ParamType::Float, Def::Float(1.5))
    .range(Range::Float {
        lo: 0.0,
        lo_open: true,
        hi: 600.0,
        hi_open: false,
    })
    .unit("s")
    .doc("window of the minimum-statistics noise tracker; on replay also the lead that warms it before the first output (live starts cold)");

params! {
    /// `spectral_subtraction`'s parameters.
    pub struct SpectralSubtractionParams for "spectral_subtraction" {
        frame_ms: f64 = FRAME_MS,
        overlap: f64 = OVERLAP,
        noise_window_s: f64 = NOISE_WINDOW,
        alpha: f64 = ParamSpec::of(ParamType::Float, Def::Float(DEFAULT_ALPHA))
            .at_least(0.0)
            .doc("over-subtraction factor"),
        beta: f64 = ParamSpec::of(ParamType::Float, Def::Float(DEFAULT_BETA))
            .floats(0.0, 1.0)
            .doc("spectral floor, a fraction of the noise power"),
    }
}

/// The decision-directed weight, whose default differs between the LSA and
/// Wiener gains ([`WIENER_DD_ALPHA`]).
const fn dd_alpha(default: f64) -> ParamSpec {
    ParamSpec::new("dd_alpha", ParamType::Float, Def::Float(default))
        .range(Range::Float {
            lo: 0.0,
            lo_open: false,
            hi: 1.0,
            hi_open: true,
        })
        .doc("weight of the previous frame in the decision-directed a-priori SNR (higher: smoother, less musical noise; lower: follows speech faster)")
}

params! {
    /// `speech_enhance`'s parameters.
    pub struct SpeechEnhanceParams for "speech_enhance" {
        frame_ms: f64 = FRAME_MS,
        overlap: f64 = OVERLAP,
        noise_window_s: f64 = NOISE_WINDOW,
        dd_alpha: f64 = dd_alpha(LSA_DD_ALPHA),
    }
}

params! {
    /// `wiener`'s parameters.
    pub struct WienerParams for "wiener" {
        frame_ms: f64 = FRAME_MS,
        overlap: f64 = OVERLAP,
        noise_window_s: f64 = NOISE_WINDOW,
        dd_alpha: f64 = dd_alpha(WIENER_DD_ALPHA),
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Method {
    Subtract,
    Enhance,
    Wiener,
}

fn plan(p: &Params<'_>, method: Method) -> Result<Box<dyn Plan>, ConfigError> {
    if method != Method::Subtract {
        for k in ["alpha", "beta"] {
            if p.stage.params().iter().any(|q| q.key == k) {
                return Err(p.error(k, "only `spectral_subtraction` takes this parameter"));
            }
        }
    }
    let (cfg, alpha, beta) = match method {
        Method::Subtract => {
            let v: SpectralSubtractionParams = p.resolve_typed()?;
            let cfg = DenoiseConfig {
                frame_ms: v.frame_ms,
                overlap: v.overlap,
                noise_window_s: v.noise_window_s,
                ..DenoiseConfig::default()
            };
            (cfg, v.alpha, v.beta)
        }
        Method::Enhance => {
            let v: SpeechEnhanceParams = p.resolve_typed()?;
            let cfg = DenoiseConfig {
                frame_ms: v.frame_ms,
                overlap: v.overlap,
                noise_window_s: v.noise_window_s,
                dd_alpha: v.dd_alpha,
                ..DenoiseConfig::default()
            };
            (cfg, DEFAULT_ALPHA, DEFAULT_BETA)
        }
        Method::Wiener => {
            let v: WienerParams = p.resolve_typed()?;
            let cfg = DenoiseConfig {
                frame_ms: v.frame_ms,
                overlap: v.overlap,
                noise_window_s: v.noise_window_s,
                dd_alpha: v.dd_alpha,
                ..DenoiseConfig::wiener()
            };
            (cfg, DEFAULT_ALPHA, DEFAULT_BETA)
        }
    };
    // Check the configuration now (at a typical rate) so errors name the field.
    let probe = match method {
        Method::Subtract => SpectralSubtraction::new(8000.0, &cfg, alpha, beta).map(|_| ()),
        Method::Enhance => SpeechEnhance::new(8000.0, &cfg).map(|_| ()),
        Method::Wiener => Wiener::new(8000.0, &cfg).map(|_| ()),
    };
    if let Err(e) = probe {
        let field = match &e {
            DenoiseError::InvalidOverlap(_) => "overlap",
            DenoiseError::InvalidParameter { name, .. } => name,
            _ => "frame_ms",
        };
        return Err(p.error(field, e.to_string()));
    }
    Ok(Box::new(DenoisePlan {
        method,
        cfg,
        alpha,
        beta,
    }))
}

const AUDIO_IN: &[InPort] = &[InPort::one(&[PortType::Audio])];
const AUDIO_OUT: &[OutPort] = &[OutPort::out(PortType::Audio)];

/// An audio-in, audio-out denoiser kind.
const fn audio_kind(
    name: &'static str,
    summary: &'static str,
    params: &'static [ParamSpec],
    plan: fn(&Params<'_>) -> Result<Box<dyn Plan>, ConfigError>,
) -> KindSpec {
    KindSpec {
        name,
        summary,
        inputs: AUDIO_IN,
        outputs: AUDIO_OUT,
        params,
        plan,
    }
}

pub const SUBTRACT_KIND: KindSpec = audio_kind(
    "spectral_subtraction",
    "streaming spectral subtraction (Boll 1979) with a tracked noise floor; alpha, beta, frame_ms, overlap",
    SpectralSubtractionParams::PARAMS,
    |p| plan(p, Method::Subtract),
);

pub const ENHANCE_KIND: KindSpec = audio_kind(
    "speech_enhance",
    "streaming MMSE log-spectral-amplitude speech enhancement (Ephraim-Malah) with a tracked noise floor",
    SpeechEnhanceParams::PARAMS,
    |p| plan(p, Method::Enhance),
);

pub const WIENER_KIND: KindSpec = audio_kind(
    "wiener",
    "streaming MMSE (Wiener) STFT denoiser, decision-directed a-priori SNR, tracked noise floor: raises SNR, not only segmental SNR",
    WienerParams::PARAMS,
    |p| plan(p, Method::Wiener),
);

struct DenoisePlan {
    method: Method,
    cfg: DenoiseConfig,
    alpha: f64,
    beta: f64,
}

impl Plan for DenoisePlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Denoise {
            plan: *self,
            filter: None,
            rate: 0.0,
            pending: VecDeque::new(),
            out: Vec::new(),
            lead: Lead::from_live(ctx.live),
        })))
    }
}

enum Filter {
    Subtract(Box<SpectralSubtraction>),
    Enhance(Box<SpeechEnhance>),
    Wiener(Box<Wiener>),
}

/// The longest lead a replay collects, in samples (16 MiB of f32; 87 s at
/// 48 kHz, longer than any noise window at a camera's rate).
const MAX_LEAD: usize = 1 << 22;

/// Replay's look at the start: the first `noise_window_s` of samples warm
/// the noise tracker before any is denoised (the denoisers' `prime`).
enum Lead {
    /// Live, or the lead is done: every block goes straight through.
    Off,
    /// Replay before the first block (its rate sets the lead's length).
    Pending,
    /// Collecting the lead: these samples, until `target`.
    Collecting { samples: Vec<f32>, target: usize },
}

impl Lead {
    fn from_live(live: bool) -> Self {
        if live {
            Lead::Off
        } else {
            Lead::Pending
        }
    }
}

struct Denoise {
    plan: DenoisePlan,
    lead: Lead,
    filter: Option<Filter>,
    rate: f64,
    /// Input blocks whose samples have not all come out yet: (t0, samples left).
    pending: VecDeque<(i64, usize, usize)>,
    out: Vec<f32>,
}

impl Denoise {
    /// Emits `self.out`, splitting it at input-block boundaries so every
    /// block carries its own first sample's capture time.
    fn emit(&mut self, out: &mut Emitter) {
        let mut start = 0;
        while start < self.out.len() {
            let Some((t0, len, done)) = self.pending.front_mut() else {
                break;
            };
            let take = (*len - *done).min(self.out.len() - start);
            let t = *t0 + (*done as f64 * 1e9 / self.rate).round() as i64;
            let _ = out.emit(Item::Audio(AudioBlock {
                t0_ns: t,
                rate_hz: self.rate,
                samples: Arc::from(&self.out[start..start + take]),
            }));
            *done += take;
            start += take;
            if *done == *len {
                self.pending.pop_front();
            }
        }
        self.out.clear();
    }
}

impl Denoise {
    fn feed(&mut self, samples: &[f32]) {
        match self.filter.as_mut() {
            Some(Filter::Subtract(f)) => f.process(samples, &mut self.out),
            Some(Filter::Enhance(f)) => f.process(samples, &mut self.out),
            Some(Filter::Wiener(f)) => f.process(samples, &mut self.out),
            None => {}
        }
    }

    /// Primes the tracker on the collected lead, then denoises it from its
    /// start; afterwards blocks go straight through.
    fn release_lead(&mut self) {
        let Lead::Collecting { samples, target } = std::mem::replace(&mut self.lead, Lead::Off)
        else {
            return;
        };
        // Exactly the lead, however the blocks fell.
        let lead = &samples[..target.min(samples.len())];
        match self.filter.as_mut() {
            Some(Filter::Subtract(f)) => f.prime(lead),
            Some(Filter::Enhance(f)) => f.prime(lead),
            Some(Filter::Wiener(f)) => f.prime(lead),
            None => {}
        }
        self.feed(&samples);
    }
}

impl Stage for Denoise {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if self.filter.is_none() {
            let p = &self.plan;
            let f = match p.method {
                Method::Subtract => SpectralSubtraction::new(a.rate_hz, &p.cfg, p.alpha, p.beta)
                    .map(|f| Filter::Subtract(Box::new(f))),
                Method::Enhance => {
                    SpeechEnhance::new(a.rate_hz, &p.cfg).map(|f| Filter::Enhance(Box::new(f)))
                }
                Method::Wiener => {
                    Wiener::new(a.rate_hz, &p.cfg).map(|f| Filter::Wiener(Box::new(f)))
                }
            }
            .map_err(|e| StageError::dsp(format!("denoiser at {} Hz: {e}", a.rate_hz)))?;
            self.filter = Some(f);
            self.rate = a.rate_hz;
        } else if a.rate_hz != self.rate {
            return Err(StageError::format(format!(
                "the sample rate changed from {} to {} Hz mid-stream",
                self.rate, a.rate_hz
            )));
        }
        self.pending.push_back((a.t0_ns, a.samples.len(), 0));
        if let Lead::Pending = self.lead {
            // Once per stream: the lead's buffer, before any output; at
            // most `MAX_LEAD` samples (a long window at a high rate warms on
            // its first part), grown as it fills rather than reserved whole.
            let target = (self.plan.cfg.noise_window_s * a.rate_hz).ceil();
            let target = if target.is_finite() && target > 0.0 {
                (target as usize).min(MAX_LEAD)
            } else {
                0
            };
            self.lead = Lead::Collecting {
                samples: Vec::with_capacity(target.min(1 << 16)),
                target,
            };
        }
        if let Lead::Collecting { samples, target } = &mut self.lead {
            samples.extend_from_slice(&a.samples);
            if samples.len() >= *target {
                self.release_lead();
                self.emit(out);
            }
            return Ok(());
        }
        self.feed(&a.samples);
        self.emit(out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        // A stream shorter than the lead: all of it warms the tracker.
        self.release_lead();
        match self.filter.as_mut() {
            Some(Filter::Subtract(f)) => f.finish(&mut self.out),
            Some(Filter::Enhance(f)) => f.finish(&mut self.out),
            Some(Filter::Wiener(f)) => f.finish(&mut self.out),
            None => {}
        }
        self.emit(out);
        Ok(())
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// Runs `x` through a `wiener` stage built for a replay or a live graph
    /// in blocks of `block` samples; returns the output. The block times are
    /// checked here: each input block's time leaves with its first sample.
    fn run(x: &[f32], fs: f64, live: bool, block: usize) -> Vec<f32> {
        let plan = DenoisePlan {
            method: Method::Wiener,
            cfg: DenoiseConfig::wiener(),
            alpha: DEFAULT_ALPHA,
            beta: DEFAULT_BETA,
        };
        let blocks =
            crate::test_support::run_audio_stage(Box::new(plan), live, x, fs, block, 1_000);
        let times: Vec<i64> = (0..x.len().div_ceil(block))
            .map(|k| 1_000 + (k as f64 * block as f64 * 1e9 / fs).round() as i64)
            .collect();
        let t: Vec<i64> = blocks.iter().map(|a| a.t0_ns).collect();
        // An input block may leave in two pieces (the frame of latency), each
        // with its own first sample's time; every input block's time leaves.
        assert!(
            times.iter().all(|t0| t.contains(t0)),
            "an input block's time is missing"
        );
        blocks
            .iter()
            .flat_map(|a| a.samples.iter().copied())
            .collect()
    }

    /// The library's Wiener over `x`, primed on its first `noise_window_s`
    /// or cold.
    fn direct(x: &[f32], fs: f64, prime: bool) -> Vec<f32> {
        let mut d = Wiener::with_defaults(fs).unwrap();
        if prime {
            let n = (DenoiseConfig::wiener().noise_window_s * fs).ceil() as usize;
            d.prime(&x[..n.min(x.len())]);
        }
        let mut out = Vec::new();
        d.process(x, &mut out);
        d.finish(&mut out);
        out
    }

    /// Replay primes on the lead and live starts cold, whatever the block
    /// size (a block longer than the lead, a stream shorter than it), and
    /// both keep every sample and block time.
    #[test]
    fn replay_primes_on_the_lead_and_live_starts_cold() {
        let fs = 2200.0;
        let mut rng = vibroscope_math::rng::Xoshiro256::new(3);
        let x: Vec<f32> = (0..9000)
            .map(|i| {
                let t = i as f64 / fs;
                let noise = rng.next_f64() - 0.5;
                ((2.0 * std::f64::consts::PI * 300.0 * t).sin() * (1.0 + (3.0 * t).sin()) * 0.3
                    + 0.2 * noise) as f32
            })
            .collect();
        let (primed, cold) = (direct(&x, fs, true), direct(&x, fs, false));
        assert!(primed != cold, "priming changed nothing");
        for block in [1, 64, 333, 5000] {
            assert!(
                run(&x, fs, false, block) == primed,
                "replay, blocks of {block}"
            );
            assert!(run(&x, fs, true, block) == cold, "live, blocks of {block}");
        }
        let short = &x[..1000];
        assert!(
            run(short, fs, false, 64) == direct(short, fs, true),
            "a short replay"
        );
    }
}
