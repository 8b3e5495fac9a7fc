//! `vibroscope demo`.

use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::demo::{self, DemoOptions};
use vibroscope::pipeline::RunSettings;

/// Render the built-in synthetic scene, recover it and score the recovery.
///
/// Render the built-in synthetic scene, recover its motion, write a WAV
/// and print the SNR against the known signal.
#[derive(clap::Args)]
#[command(after_help = "Example:\n  vibroscope demo -o demo.wav --set cam.amplitude_px=0.02")]
pub struct Args {
    /// Output WAV.
    #[arg(short, long, default_value = "demo.wav")]
    output: PathBuf,
    /// Override a parameter of the demo pipeline (e.g. cam.amplitude_px=0.02).
    #[arg(long = "set", value_name = "STAGE.KEY=VALUE")]
    set: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let o = DemoOptions {
        output: a.output,
        set: a.set,
        run: RunSettings { progress: true },
    };
    let s = demo::scene(&o)?;
    eprintln!(
        "rendering {} frames of {}x{} at {} fps: object moving {} px with {}",
        s.frames, s.width, s.height, s.fps, s.amplitude_px, s.signal
    );
    let bar = super::Bar::start(true);
    let r = demo::demo(&o);
    drop(bar);
    let r = r?;
    super::outln!(
        "wrote {} ({} samples at {} Hz); SNR against the true motion: {:.1} dB; {:.1} Mpix/s",
        r.output.display(),
        r.samples,
        r.sample_rate_hz,
        r.snr_db,
        r.mpix_per_s
    );
    Ok(ExitCode::SUCCESS)
}
