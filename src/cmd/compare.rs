//! `vibroscope compare`.

use super::PyramidArg;
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::compare::{self, CompareOptions};
use vibroscope::pipeline::{Roi, RunSettings};

/// Per-region resonance shifts between two recordings.
///
/// Per-region resonance shifts between two recordings (thesis ch. 5.6):
/// each region's spectrum and peaks in A and in B, and the shift of its
/// strongest resonance with its uncertainty (significant beyond three
/// standard deviations).
#[derive(clap::Args)]
#[command(after_help = "Example:\n  \
    vibroscope compare empty.y4m filled.y4m --roi 0,0,64,64 --roi 64,0,64,64 -o shifts.json")]
pub struct Args {
    /// The reference recording.
    a: PathBuf,
    /// The recording compared with it.
    b: PathBuf,
    /// Output JSON (the main output; also spelled --json).
    #[arg(
        short = 'o',
        long = "json",
        visible_alias = "output",
        value_name = "OUT.json"
    )]
    json: PathBuf,
    /// A region X,Y,W,H in pixels; repeatable.
    #[arg(long, value_name = "X,Y,W,H", value_parser = super::parse_roi)]
    roi: Vec<Roi>,
    /// A region as an image the size of the frame (PGM or PNG; pixels > 0
    /// count); repeatable.
    #[arg(long, value_name = "FILE")]
    mask: Vec<PathBuf>,
    /// Capture frame rate in Hz of both recordings.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Peaks listed per region and recording.
    #[arg(long, default_value_t = 3, value_name = "N")]
    peaks: usize,
    /// Only resonances above this frequency (Hz).
    #[arg(long, value_name = "HZ")]
    min_hz: Option<f64>,
    /// Only resonances below this frequency (Hz).
    #[arg(long, value_name = "HZ")]
    max_hz: Option<f64>,
    /// Pyramid: complex steerable (quality) or Riesz (speed).
    #[arg(long, value_enum, default_value = "csp")]
    pyramid: PyramidArg,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let o = CompareOptions {
        a: a.a,
        b: a.b,
        json: a.json,
        rois: a.roi,
        masks: a.mask,
        fps: a.fps,
        peaks: a.peaks,
        min_hz: a.min_hz,
        max_hz: a.max_hz,
        pyramid: a.pyramid.into(),
        run: RunSettings { progress: true },
    };
    if !(o.rois.is_empty() && o.masks.is_empty()) {
        super::warn_playback_rate(&o.a, o.fps);
        super::warn_playback_rate(&o.b, o.fps);
    }
    let bar = super::Bar::start(true);
    if let Some(b) = &bar {
        b.set_prefix("spectrum 1 ".into());
    }
    let r = compare::compare(&o, &mut |done, total| {
        if let Some(b) = &bar {
            b.set_prefix(format!("spectrum {}/{total} ", (done + 1).min(total)));
        }
    });
    drop(bar);
    let r = r?;
    super::wrote(&r.written);
    for g in &r.regions {
        match (&g.a, &g.b, g.shift_hz, g.shift_std_hz) {
            (Some(pa), Some(pb), Some(s), Some(sd)) => eprintln!(
                "{}: {} -> {} Hz, shift {} ± {} Hz{}",
                g.region,
                super::num(pa.frequency_hz, 3),
                super::num(pb.frequency_hz, 3),
                super::num(s, 3),
                super::num(sd, 3),
                if g.significant == Some(true) {
                    " (significant)"
                } else {
                    " (within 3 sigma)"
                }
            ),
            _ => eprintln!("{}: no resonance in one of the recordings", g.region),
        }
    }
    Ok(ExitCode::SUCCESS)
}
