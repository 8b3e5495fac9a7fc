//! `vibroscope simulate`.

use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::pipeline::RunSettings;
use vibroscope::simulate::{self, SimulateOptions};

/// Render a scene file to a Y4M recording through the forward model.
///
/// Render a scene file through the forward model to a Y4M recording
/// (with per-frame timestamps). The scene file holds the `synthetic`
/// source's parameters at its top level: size, rate, object, motion
/// `signal`, `amplitude_px`, `noise_std`, `bits`, rolling shutter
/// (`line_delay_us`, `exposure_us`), the object's look (`texture`: a
/// picture; `object_mask`: a silhouette), response (`resonances`,
/// `soft_clip_px`, or a `modal` beam), and camera effects
/// (`clock_error_ppm`, `drop_frames`, `duplicate_frames`,
/// `interference`). See `vibroscope kinds` and the README's "Simulator"
/// section.
#[derive(clap::Args)]
#[command(after_help = "Example:\n  vibroscope simulate beam.toml -o beam.y4m --set fps=2200.0")]
pub struct Args {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output Y4M (`-` for stdout).
    #[arg(short, long, default_value = "scene.y4m")]
    output: PathBuf,
    /// Override a scene parameter (KEY=VALUE, VALUE in TOML).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let to_stdout = a.output.as_os_str() == "-";
    let o = SimulateOptions {
        scene: a.scene,
        output: a.output,
        set: a.set,
        run: RunSettings {
            progress: !to_stdout,
        },
    };
    let bar = super::Bar::start(!to_stdout);
    let r = simulate::simulate(&o);
    drop(bar);
    let r = super::stats(a.stats, r, |r| r.run.as_ref().map(|r| r.table()))?;
    if !to_stdout {
        eprintln!("wrote {} ({} frames)", r.output.display(), r.frames);
    }
    Ok(ExitCode::SUCCESS)
}
