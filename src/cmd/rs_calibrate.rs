//! `vibroscope rs-calibrate`.

use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::pipeline::Roi;
use vibroscope::rs_calibrate::{self, RowSignal, RsCalibrateOptions};

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum SignalArg {
    /// Horizontal motion of each row (a vibrating textured object).
    Motion,
    /// Mean brightness of each row (a flickering light).
    Intensity,
}

/// Estimate a rolling-shutter camera's line delay from a video of a tone.
///
/// Estimate a rolling-shutter camera's line delay (and frame delay) from
/// a video of a known tone or a flickering light (thesis ch. 4.5: the
/// slope of the tone's phase down the rows).
#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  vibroscope rs-calibrate tone440.mp4 --tone-hz 440 --fps 60 --json rs.json"
)]
pub struct Args {
    /// A video of an object vibrating with a pure tone, or of a light flickering at one.
    video: PathBuf,
    /// The tone's (or flicker's) frequency, Hz.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    tone_hz: f64,
    /// Capture frame rate in Hz (containers often state the playback rate).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// What each row measures.
    #[arg(long, value_enum, default_value = "motion")]
    signal: SignalArg,
    /// Region used: X,Y,W,H (default: the whole frame).
    #[arg(long, value_name = "X,Y,W,H", value_parser = super::parse_roi)]
    roi: Option<Roi>,
    /// Frames read at most.
    #[arg(long, default_value_t = 300)]
    max_frames: usize,
    /// Also write the estimate as JSON to this file.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    super::check_json(&[&a.video], a.json.as_deref())?;
    super::warn_playback_rate(&a.video, a.fps);
    let r = rs_calibrate::rs_calibrate(&RsCalibrateOptions {
        video: a.video,
        tone_hz: a.tone_hz,
        fps: a.fps,
        signal: match a.signal {
            SignalArg::Motion => RowSignal::Motion,
            SignalArg::Intensity => RowSignal::Intensity,
        },
        roi: a.roi,
        max_frames: a.max_frames,
    })?;
    let period = 1.0 / r.fps;
    super::outln!(
        "line delay:   {:.3} us  (one sample per row: {:.0} Hz)",
        r.line_delay_us,
        r.row_rate_hz
    );
    super::outln!(
        "frame delay:  {:.3} us  (frame period {:.3} ms, {} rows: {:.1}% of the time unseen)",
        r.frame_delay_us,
        period * 1e3,
        r.rows,
        100.0 * r.missing_fraction
    );
    super::outln!(
        "fit:          the {} Hz tone explains {:.0}% of the per-row signal ({} frames)",
        a.tone_hz,
        100.0 * r.explained,
        r.frames
    );
    if r.explained < 0.1 {
        eprintln!(
            "warning: weak fit; check --tone-hz, and that the tone is not a multiple of the frame rate"
        );
    }
    if let Some(p) = &a.json {
        vibroscope::files::write_atomic(p, &serde_json::to_vec_pretty(&r)?)?;
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}
