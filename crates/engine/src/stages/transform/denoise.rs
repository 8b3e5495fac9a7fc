//! `spectral_subtraction` (Boll 1979) and `speech_enhance` (MMSE
//! log-spectral amplitude, Ephraim & Malah 1985): streaming denoisers on an
//! audio stream ([`vibroscope_math::denoise`]). Both track the noise floor as
//! they go (minimum statistics; no look at the whole recording) and delay
//! the signal by one STFT frame; every output block carries the capture
//! time of its first sample, taken from the input blocks.

use crate::*;
use serde::Deserialize;
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::denoise::{
    DenoiseConfig, DenoiseError, SpectralSubtraction, SpeechEnhance, DEFAULT_ALPHA, DEFAULT_BETA,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    #[serde(default = "d_frame")]
    frame_ms: f64,
    #[serde(default = "d_overlap")]
    overlap: f64,
    #[serde(default = "d_window")]
    noise_window_s: f64,
    /// Over-subtraction factor (spectral subtraction only).
    alpha: Option<f64>,
    /// Spectral floor (spectral subtraction only).
    beta: Option<f64>,
}
fn d_frame() -> f64 {
    32.0
}
fn d_overlap() -> f64 {
    0.75
}
fn d_window() -> f64 {
    1.5
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Method {
    Subtract,
    Enhance,
}

fn plan(p: &Params<'_>, method: Method) -> Result<Box<dyn Plan>, ConfigError> {
    let v: P = p.parse()?;
    if method == Method::Enhance {
        for (k, val) in [("alpha", v.alpha), ("beta", v.beta)] {
            if val.is_some() {
                return Err(p.error(k, "only `spectral_subtraction` takes this parameter"));
            }
        }
    }
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

pub const SUBTRACT_KIND: KindSpec = KindSpec {
    name: "spectral_subtraction",
    summary: "streaming spectral subtraction (Boll 1979) with a tracked noise floor; alpha, beta, frame_ms, overlap",
    accepts: &[PortType::Audio],
    max_inputs: 1,
    output: Output::Fixed(PortType::Audio),
    plan: |p| plan(p, Method::Subtract),
};

pub const ENHANCE_KIND: KindSpec = KindSpec {
    name: "speech_enhance",
    summary: "streaming MMSE log-spectral-amplitude speech enhancement (Ephraim-Malah) with a tracked noise floor",
    accepts: &[PortType::Audio],
    max_inputs: 1,
    output: Output::Fixed(PortType::Audio),
    plan: |p| plan(p, Method::Enhance),
};

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
            return Err(StageError::msg("expected audio"));
        };
        if self.filter.is_none() {
            let p = &self.plan;
            let f = match p.method {
                Method::Subtract => SpectralSubtraction::new(a.rate_hz, &p.cfg, p.alpha, p.beta)
                    .map(|f| Filter::Subtract(Box::new(f))),
                Method::Enhance => {
                    SpeechEnhance::new(a.rate_hz, &p.cfg).map(|f| Filter::Enhance(Box::new(f)))
                }
            }
            .map_err(|e| StageError::msg(format!("denoiser at {} Hz: {e}", a.rate_hz)))?;
            self.filter = Some(f);
            self.rate = a.rate_hz;
        } else if a.rate_hz != self.rate {
            return Err(StageError::msg(format!(
                "the sample rate changed from {} to {} Hz mid-stream",
                self.rate, a.rate_hz
            )));
        }
        self.pending.push_back((a.t0_ns, a.samples.len(), 0));
        match self.filter.as_mut() {
            Some(Filter::Subtract(f)) => f.process(&a.samples, &mut self.out),
            Some(Filter::Enhance(f)) => f.process(&a.samples, &mut self.out),
            None => {}
        }
        self.emit(out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        match self.filter.as_mut() {
            Some(Filter::Subtract(f)) => f.finish(&mut self.out),
            Some(Filter::Enhance(f)) => f.finish(&mut self.out),
            None => {}
        }
        self.emit(out);
        Ok(())
    }
}
