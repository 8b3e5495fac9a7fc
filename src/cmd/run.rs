//! `vibroscope run`: a pipeline file or a shipped pipeline.

use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::pipeline::{self, PipelineOptions, RunSettings};

/// Run a pipeline: a TOML file, or the name of a shipped pipeline.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  vibroscope run demo --stats\n  \
    vibroscope run pipelines/motion.toml --replay clip.cine --set motion.direction_deg=90\n  \
    vibroscope run motion --replay guitar.mp4 --fps 600 --set out.path=guitar.wav")]
pub struct Args {
    /// Pipeline file, or a shipped pipeline's name (see `vibroscope pipelines`).
    pipeline: String,
    /// Override a stage parameter: STAGE.KEY=VALUE (VALUE is TOML: 600, true, "x", [1,2]).
    #[arg(long = "set", value_name = "STAGE.KEY=VALUE")]
    set: Vec<String>,
    /// Replace the pipeline's source with this recording (never drops frames).
    #[arg(long, value_name = "FILE")]
    replay: Option<PathBuf>,
    /// Capture frame rate in Hz for the source (overrides the file's stated rate).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Print a per-stage summary (items, drops, queue use, time per item) at exit.
    #[arg(long)]
    stats: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if let Some(r) = &a.replay {
        super::warn_playback_rate(r, a.fps);
    }
    let decl = pipeline::prepare(&PipelineOptions {
        pipeline: a.pipeline,
        set: a.set,
        replay: a.replay,
        fps: a.fps,
    })?;
    let settings = RunSettings { progress: !a.quiet };
    let bar = super::Bar::start(!a.quiet);
    let r = pipeline::run(&decl, settings);
    drop(bar);
    let report = super::stats(a.stats, r, |r| Some(r.table()))?;
    for p in pipeline::outputs(&decl) {
        super::wrote(&p);
    }
    eprintln!(
        "ran `{}` in {:.2} s",
        decl.name,
        report.elapsed.as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
