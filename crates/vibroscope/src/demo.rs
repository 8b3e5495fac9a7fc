//! The built-in synthetic scene: render it, recover its motion, write a
//! WAV and score it against the known motion.

use crate::engine::config::apply_set;
use crate::engine::Params;
use crate::error::{Error, Result};
use crate::pipeline::{self, by, RunSettings};
use crate::pipelines::stage::demo;
use crate::stages::params::WavParams;
use crate::stages::sources::synthetic::SyntheticParams;
use serde::Serialize;
use std::path::PathBuf;

/// What `demo` is asked.
#[derive(Clone, Debug, Default)]
pub struct DemoOptions {
    /// Output WAV.
    pub output: PathBuf,
    /// `STAGE.KEY=VALUE` overrides of the demo pipeline.
    pub set: Vec<String>,
    pub run: RunSettings,
}

/// The scene `demo` renders, for a message before the run.
#[derive(Clone, Debug, Serialize)]
pub struct DemoScene {
    pub frames: u64,
    pub width: u32,
    pub height: u32,
    pub fps: f64,
    pub amplitude_px: f64,
    /// The motion signal, in words.
    pub signal: String,
}

/// What `demo` measured.
#[derive(Clone, Debug, Serialize)]
pub struct DemoReport {
    pub output: PathBuf,
    pub samples: usize,
    pub sample_rate_hz: u32,
    /// SNR of the recovery against the true motion (dB).
    pub snr_db: f64,
    /// Throughput, megapixels per second.
    pub mpix_per_s: f64,
}

fn setup(o: &DemoOptions) -> Result<(crate::engine::PipelineDecl, SyntheticParams)> {
    let mut decl = pipeline::load("demo")?;
    let out = format!("-o {}", o.output.display());
    pipeline::set(
        &mut decl,
        demo::OUT,
        WavParams::path,
        o.output.clone(),
        by(&out),
    )?;
    for s in &o.set {
        apply_set(&mut decl, s)?;
    }
    let cam = decl
        .stages
        .iter()
        .find(|s| s.id == "cam")
        .ok_or_else(|| pipeline::no_stage(&decl.file, "cam"))?;
    let truth: SyntheticParams = Params {
        file: &decl.file,
        stage: cam,
    }
    .parse()?;
    Ok((decl, truth))
}

/// The scene the demo will render.
pub fn scene(o: &DemoOptions) -> Result<DemoScene> {
    let (_, p) = setup(o)?;
    Ok(DemoScene {
        frames: p.frame_count(),
        width: p.width,
        height: p.height,
        fps: p.fps,
        amplitude_px: p.amplitude_px,
        signal: describe_signal(&p.signal),
    })
}

/// A motion signal in words (`a 440 Hz tone`).
pub fn describe_signal(s: &crate::sim::signal::SignalSpec) -> String {
    use crate::sim::signal::SignalSpec;
    let hz = |v: &[f64]| {
        v.iter()
            .map(|f| format!("{f}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match s {
        SignalSpec::Tone { freq_hz, .. } => format!("a {freq_hz} Hz tone"),
        SignalSpec::Tones { freqs_hz, .. } => format!("tones at {} Hz", hz(freqs_hz)),
        SignalSpec::Chirp {
            f0_hz,
            f1_hz,
            duration_s,
        } => format!("a chirp from {f0_hz} to {f1_hz} Hz over {duration_s} s"),
        SignalSpec::Wav { path } => format!("the sound of {}", path.display()),
        SignalSpec::Noise { .. } => "white noise".to_string(),
    }
}

/// Runs the demo and scores the WAV against the known motion.
pub fn demo(o: &DemoOptions) -> Result<DemoReport> {
    let (decl, truth_params) = setup(o)?;
    let report = pipeline::run(&decl, o.run)?;
    let (rate, est) = crate::io::wav::read_mono(&o.output)?;
    let scene = truth_params.scene().map_err(|message| {
        Error::Config(crate::engine::ConfigError {
            file: decl.file.clone(),
            origin: None,
            stage: Some("cam".into()),
            field: None,
            message,
        })
    })?;
    let truth: Vec<f64> = (0..est.len())
        .map(|n| scene.displacement_px(n as f64 / truth_params.fps))
        .collect();
    let snr = crate::math::truth::snr_db_fit(&truth, &est);
    let secs = report.elapsed.as_secs_f64();
    let mpix =
        truth_params.frame_count() as f64 * (truth_params.width * truth_params.height) as f64 / 1e6;
    Ok(DemoReport {
        output: o.output.clone(),
        samples: est.len(),
        sample_rate_hz: rate,
        snr_db: snr,
        mpix_per_s: mpix / secs,
    })
}
