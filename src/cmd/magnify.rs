//! `vibroscope magnify`.

use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::magnify::{self, MagnifyOptions};
use vibroscope::pipeline::BandFilter;
use vibroscope::pipeline::{Roi, RunSettings};

/// `--band LO,HI` in Hz.
fn parse_band(s: &str) -> Result<(f64, f64), String> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|v| v.trim().parse::<f64>()).collect();
    match v.as_deref() {
        Ok([lo, hi]) if lo.is_finite() && hi.is_finite() => Ok((*lo, *hi)),
        _ => Err(format!("expected LO,HI in Hz (two numbers), got `{s}`")),
    }
}

/// Magnify (or attenuate) the motion in a band of frequencies; writes video.
///
/// Phase-based motion magnification (Wadhwa et al. 2013 with the complex
/// steerable pyramid, 2014 with the Riesz pyramid): per pyramid band, each
/// pixel's local phase is band-passed in time (causal Butterworth),
/// smoothed weighted by the local amplitude, multiplied by the factor and
/// put back; the pyramid is collapsed into the frame. Motion in the band
/// becomes FACTOR times larger (below 1 smaller; 0 removes it), other
/// motion is left as it is. The magnified phase is limited to a quarter of
/// each band's wavelength, so large factors saturate instead of tearing
/// the image. Colour input is magnified on its luma; its chroma is put
/// back beside it by ffmpeg (Y4M 4:4:4, or yuv420p in other containers).
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope magnify ../shared/data/guitar.mp4 --fps 600 --band 76,86 --factor 30 -o e2.y4m\n  \
    vibroscope magnify clip.y4m --band 35,45 --factor 0 -o still.mp4   # remove the motion in the band\n  \
    vibroscope magnify clip.y4m --band 35,45 --factor 20 --side-by-side --roi 0,0,128,96 -o both.mp4\n  \
    vibroscope magnify clip.y4m --band 20,80 --factor 10 --notch 50,4 -o m.y4m   # all but 48-52 Hz")]
pub struct Args {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    video: PathBuf,
    /// The band whose motion is magnified: LO,HI in Hz (0 < LO < HI < fps/2).
    #[arg(long, value_name = "LO,HI", value_parser = parse_band, allow_hyphen_values = true)]
    band: (f64, f64),
    /// Motion in the band is multiplied by this (>= 0; below 1 attenuates, 0 removes it).
    #[arg(long, value_name = "A", allow_negative_numbers = true)]
    factor: f64,
    /// Output video: .y4m, or any other extension through ffmpeg (.mp4, .mkv, ...).
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// Capture frame rate in Hz (containers such as MP4 often state the
    /// playback rate of a high-speed clip instead).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Process and write only this region: X,Y,W,H in pixels.
    #[arg(long, value_name = "X,Y,W,H", value_parser = super::parse_roi)]
    roi: Option<Roi>,
    /// Pyramid: complex steerable (quality: the stated factors hold) or
    /// Riesz (speed, approximate: x10 gives about x7, 0 removes ~9 dB).
    #[arg(long, value_enum, default_value = "csp")]
    pyramid: super::PyramidArg,
    /// Pyramid scales (octaves; default 4).
    #[arg(long, value_name = "N")]
    scales: Option<usize>,
    /// Write the original (left) and the magnified video (right) side by side.
    #[arg(long)]
    side_by_side: bool,
    /// Then remove the motion at F Hz (F - WIDTH/2 to F + WIDTH/2; WIDTH
    /// defaults to F/10), as a factor of 0 on that band would; repeatable
    /// (e.g. magnify a structure's band but not the machine's running
    /// speed inside it). Each notch costs as much as the magnification.
    #[arg(long, value_name = "F[,WIDTH]", value_parser = parse_notch, action = clap::ArgAction::Append, allow_negative_numbers = true)]
    notch: Vec<BandFilter>,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let o = MagnifyOptions {
        video: a.video,
        output: a.output,
        lo_hz: a.band.0,
        hi_hz: a.band.1,
        factor: a.factor,
        fps: a.fps,
        roi: a.roi,
        pyramid: a.pyramid.into(),
        scales: a.scales,
        side_by_side: a.side_by_side,
        notches: a.notch,
        run: RunSettings { progress: true },
    };
    super::warn_playback_rate(&o.video, o.fps);
    let bar = super::Bar::start(true);
    let r = magnify::magnify(&o);
    drop(bar);
    let r = super::stats(a.stats, r, |r| r.run.as_ref().map(|run| run.table()))?;
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    super::wrote(&r.output);
    eprintln!(
        "{} frames of {}x{} at {} fps; motion in {}-{} Hz times {} (band-pass centre {:.2} Hz)",
        r.frames,
        r.width,
        r.height,
        vibroscope::pipeline::short(r.fps),
        vibroscope::pipeline::short(o.lo_hz),
        vibroscope::pipeline::short(o.hi_hz),
        o.factor,
        r.centre_hz
    );
    for n in &o.notches {
        let (_, lo_hz, hi_hz) = n.stage();
        eprintln!(
            "then motion in {}-{} Hz removed ({})",
            vibroscope::pipeline::short(lo_hz),
            vibroscope::pipeline::short(hi_hz),
            n.flag()
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn parse_notch(s: &str) -> Result<BandFilter, String> {
    BandFilter::notch(s).map_err(|e| e.message)
}
