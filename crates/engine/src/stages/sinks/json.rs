//! `json`: collects a signal or spectra and writes one JSON document on
//! finish (atomically: a reader never sees half a file).
//!
//! Audio: `{"kind": "audio", "sample_rate_hz", "t0_s", "samples": [...]}`;
//! spectra: `{"kind": "spectra", "spectra": [{"t_s", "f0_hz",
//! "resolution_hz", "power": [...]}]}`.

use crate::*;
use std::path::PathBuf;

params! {
    /// `json`'s parameters.
    pub struct JsonParams for "json" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required)
            .doc("the JSON file (written atomically at the end)"),
    }
}

type P = JsonParams;

pub const KIND: KindSpec = KindSpec {
    name: "json",
    summary: "writes audio, samples or spectra as one JSON document at the end",
    inputs: &[InPort::one(&[
        PortType::Audio,
        PortType::Samples,
        PortType::Spectrum,
    ])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        Ok(Box::new(Json {
            path: v.path,
            rate: None,
            t0: None,
            channels: 1,
            samples: Vec::new(),
            spectra: Vec::new(),
        }))
    },
};

struct Json {
    path: PathBuf,
    rate: Option<f64>,
    t0: Option<i64>,
    channels: usize,
    samples: Vec<f32>,
    spectra: Vec<serde_json::Value>,
}

impl Plan for Json {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}

impl Stage for Json {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        match item {
            Item::Audio(a) => {
                self.rate.get_or_insert(a.rate_hz);
                self.t0.get_or_insert(a.t0_ns);
                self.samples.extend_from_slice(&a.samples);
            }
            Item::Samples(s) => {
                self.rate.get_or_insert(s.rate_hz);
                self.t0.get_or_insert(s.t0_ns);
                self.channels = s.channels.max(1);
                self.samples.extend_from_slice(&s.data);
            }
            Item::Spectrum(s) => self.spectra.push(serde_json::json!({
                "t_s": s.t_ns as f64 * 1e-9,
                "f0_hz": s.f0_hz,
                "resolution_hz": s.resolution_hz,
                "power": &s.power[..],
            })),
            Item::Frame(_) | Item::Pyramid(_) | Item::Peaks(_) => {}
        }
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let doc = if !self.spectra.is_empty() {
            serde_json::json!({ "kind": "spectra", "spectra": std::mem::take(&mut self.spectra) })
        } else {
            serde_json::json!({
                "kind": if self.channels > 1 { "samples" } else { "audio" },
                "sample_rate_hz": self.rate,
                "t0_s": self.t0.map(|t| t as f64 * 1e-9),
                "channels": self.channels,
                "samples": &self.samples,
            })
        };
        let text = serde_json::to_vec_pretty(&doc)
            .map_err(|e| StageError::file("write", &self.path, e.into()))?;
        super::write_atomic(&self.path, &text)
    }
}
