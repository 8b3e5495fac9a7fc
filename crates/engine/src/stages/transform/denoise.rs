//! `spectral_subtraction` (Boll 1979), `speech_enhance` (MMSE
//! log-spectral amplitude, Ephraim & Malah 1985) and `wiener` (MMSE of the
//! STFT coefficients, gain xi/(1+xi), the same decision-directed a-priori
//! SNR): streaming denoisers on an audio stream
//! ([`vibroscope_math::denoise`]). All track the noise floor as
//! they go (minimum statistics; no look at the whole recording) and delay
//! the signal by one STFT frame; every output block carries the capture
//! time of its first sample, taken from the input blocks.

use crate::*;
use serde::Deserialize;
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::denoise::{
    DenoiseConfig, DenoiseError, SpectralSubtraction, SpeechEnhance, Wiener, DEFAULT_ALPHA,
    DEFAULT_BETA,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    frame_ms: f64,
    overlap: f64,
    noise_window_s: f64,
    alpha: Option<f64>,
    beta: Option<f64>,
}

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
    .doc("window of the minimum-statistics noise tracker");

const SUBTRACT_PARAMS: &[ParamSpec] = &[
    FRAME_MS,
    OVERLAP,
    NOISE_WINDOW,
    ParamSpec::new("alpha", ParamType::Float, Def::Float(DEFAULT_ALPHA))
        .at_least(0.0)
        .doc("over-subtraction factor"),
    ParamSpec::new("beta", ParamType::Float, Def::Float(DEFAULT_BETA))
        .floats(0.0, 1.0)
        .doc("spectral floor, a fraction of the noise power"),
];
const ENHANCE_PARAMS: &[ParamSpec] = &[FRAME_MS, OVERLAP, NOISE_WINDOW];

#[derive(Clone, Copy, PartialEq, Eq)]
enum Method {
    Subtract,
    Enhance,
    Wiener,
}

fn plan(p: &Params<'_>, method: Method) -> Result<Box<dyn Plan>, ConfigError> {
    if method != Method::Subtract {
        for k in ["alpha", "beta"] {
            if p.stage.params.iter().any(|q| q.key == k) {
                return Err(p.error(k, "only `spectral_subtraction` takes this parameter"));
            }
        }
    }
    let v: P = p.resolve(match method {
        Method::Subtract => SUBTRACT_PARAMS,
        Method::Enhance | Method::Wiener => ENHANCE_PARAMS,
    })?;
    let cfg = DenoiseConfig {
        frame_ms: v.frame_ms,
        overlap: v.overlap,
        noise_window_s: v.noise_window_s,
        ..DenoiseConfig::default()
    };
    let (alpha, beta) = (
        v.alpha.unwrap_or(DEFAULT_ALPHA),
        v.beta.unwrap_or(DEFAULT_BETA),
    );
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
    SUBTRACT_PARAMS,
    |p| plan(p, Method::Subtract),
);

pub const ENHANCE_KIND: KindSpec = audio_kind(
    "speech_enhance",
    "streaming MMSE log-spectral-amplitude speech enhancement (Ephraim-Malah) with a tracked noise floor",
    ENHANCE_PARAMS,
    |p| plan(p, Method::Enhance),
);

pub const WIENER_KIND: KindSpec = audio_kind(
    "wiener",
    "streaming MMSE (Wiener) STFT denoiser, decision-directed a-priori SNR, tracked noise floor: raises SNR, not only segmental SNR",
    ENHANCE_PARAMS,
    |p| plan(p, Method::Wiener),
);

struct DenoisePlan {
    method: Method,
    cfg: DenoiseConfig,
    alpha: f64,
    beta: f64,
}

impl Plan for DenoisePlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Denoise {
            plan: *self,
            filter: None,
            rate: 0.0,
            pending: VecDeque::new(),
            out: Vec::new(),
        })))
    }
}

enum Filter {
    Subtract(Box<SpectralSubtraction>),
    Enhance(Box<SpeechEnhance>),
    Wiener(Box<Wiener>),
}

struct Denoise {
    plan: DenoisePlan,
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
        match self.filter.as_mut() {
            Some(Filter::Subtract(f)) => f.process(&a.samples, &mut self.out),
            Some(Filter::Enhance(f)) => f.process(&a.samples, &mut self.out),
            Some(Filter::Wiener(f)) => f.process(&a.samples, &mut self.out),
            None => {}
        }
        self.emit(out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
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
