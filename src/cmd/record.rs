//! `vibroscope record`.

use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::pipeline::RunSettings;
use vibroscope::record::{self, RecordOptions};
use vibroscope::ErrorKind;

/// Record a camera to Y4M with each frame's capture time.
///
/// Record a camera to Y4M (gray) with each frame's capture time in its
/// header, to replay later with `run PIPELINE --replay REC.y4m`. Ctrl-C
/// stops and leaves a valid file.
#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  vibroscope record --device /dev/video0 -o rec.y4m --seconds 5\n  \
    vibroscope record -o rec.y4m --width 640 --height 480 --fps 60 --format yuyv\n  \
    vibroscope run live-microphone --replay rec.y4m --set out.path=rec.wav"
)]
pub struct Args {
    /// The camera's device node.
    #[arg(long, default_value = "/dev/video0")]
    device: PathBuf,
    /// Output Y4M (`-` for standard output).
    #[arg(short, long)]
    output: PathBuf,
    /// Stop after this many seconds of capture (default: until Ctrl-C).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    seconds: Option<f64>,
    /// Requested frame width (the driver may grant another; the file has the granted one).
    #[arg(long)]
    width: Option<u32>,
    /// Requested frame height.
    #[arg(long)]
    height: Option<u32>,
    /// Requested frame rate in Hz.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Pixel format to capture: grey, yuyv, mjpeg or auto.
    #[arg(long, default_value = "auto")]
    format: String,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let o = RecordOptions {
        device: a.device,
        output: a.output,
        seconds: a.seconds,
        width: a.width,
        height: a.height,
        fps: a.fps,
        format: a.format,
        run: RunSettings::default(),
    };
    let r = record::record(&o);
    let r = super::stats(a.stats, r, |r| r.run.as_ref().map(|r| r.table()))?;
    for e in &r.errors {
        eprintln!("error: {e}");
    }
    let what = match (&r.recorded, &r.read_back_error) {
        (Some((w, h, fps)), _) => format!(" of {w}x{h} at {} fps", fps.unwrap_or(f64::NAN)),
        (None, Some(e)) => format!(" (cannot read it back: {e})"),
        (None, None) => String::new(),
    };
    // Frames lost: sequence gaps at the device, and frames the recorder's
    // queue evicted because the disk fell behind (drop-oldest).
    eprintln!(
        "recorded {} frames{what} to {}; dropped {} (device {}, queue {})",
        r.frames,
        r.output.display(),
        r.dropped_device + r.dropped_queue,
        r.dropped_device,
        r.dropped_queue
    );
    let kind = if !r.errors.is_empty() {
        Some(ErrorKind::Runtime)
    } else if r.interrupted {
        eprintln!("interrupted: outputs were finalised with what was processed");
        Some(ErrorKind::Interrupted)
    } else {
        None
    };
    Ok(kind.map_or(ExitCode::SUCCESS, |k| ExitCode::from(k.exit_code())))
}
