//! `vibroscope modes`.

use super::{UnitArgs, VideoArgs};
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::modes::{self, ModesOptions, Motion};
use vibroscope::pipeline::RunSettings;

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum MotionArg {
    /// Horizontal motion.
    X,
    /// Vertical motion.
    Y,
    /// Both: each pixel's motion along its own direction (x and y
    /// fitted together), signed on the side of the frame's overall
    /// direction.
    Sum,
}

/// Modal image of a video at one frequency (PNG, optionally .npy).
///
/// Modal image of a video at one frequency (thesis ch. 3.5, Eq.
/// 3.18-3.19): the A²-weighted, blurred and normalised motion spectrum
/// slice, phase as hue and amplitude as brightness; optionally the
/// complex image as .npy.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope modes ../shared/data/guitar.mp4 --fps 600 --at 80.8 -o e2.png --npy e2.npy\n  \
    vibroscope modes ../shared/data/guitar.mp4 --fps 600 --at 80.8 --at 108.6 -o m.png --figure modes.png\n  \
    vibroscope modes beam.y4m --at 58.3 --mask beam-mask.png --pyramid riesz -o m.png\n  \
    vibroscope modes beam.y4m --at 58.3 --scale 0.02 --npy m.npy -o m.png   # .npy in µm\n  \
    vibroscope modes beam.y4m --at 58.3 --motion y -o m.png --animate mode2.mp4")]
pub struct Args {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    video: PathBuf,
    /// The frequency of the image, Hz (the exact Fourier sum at this
    /// frequency, not the nearest FFT bin). Repeat for several (at most 8)
    /// in one pass over the video: -o, --npy and --animate then get
    /// -FREQhz before their extension (m.png -> m-80.8hz.png), and
    /// --figure is one sheet of all.
    #[arg(
        long = "at",
        value_name = "HZ",
        allow_negative_numbers = true,
        required = true
    )]
    at_hz: Vec<f64>,
    /// Output PNG: phase as hue, amplitude as brightness.
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// Also write the complex image (complex64, shape (H, W)): the mode's
    /// amplitude (0-peak) and phase per pixel, in px, or in µm/mm with a
    /// scale (--scale, --known-length).
    #[arg(long, value_name = "OUT.npy")]
    npy: Option<PathBuf>,
    /// Also write a figure to read: the image enlarged (to about 1280x960)
    /// and laid over the recording's first frame, titled with the file,
    /// frequency, motion and pyramid, with a wheel of the phase hues and a
    /// key of brightness against amplitude in px (µm or mm with a scale).
    #[arg(long, value_name = "OUT.png")]
    figure: Option<PathBuf>,
    /// Also write the mode shape moving (the operating deflection shape):
    /// the first frame warped by the image along --motion x or y through
    /// its cycle, 24 frames a cycle, four cycles at 24 fps, enlarged like
    /// --figure. .y4m, or .mp4 and anything else ffmpeg writes.
    #[arg(long, value_name = "OUT.mp4")]
    animate: Option<PathBuf>,
    /// The motion in the --animate video, pixels of the video: the image's
    /// 99.5th percentile of amplitude is scaled to it (default 2).
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    animate_px: Option<f64>,
    #[command(flatten)]
    video_args: VideoArgs,
    /// σ_b of the Gaussian blur, input pixels (0 = none).
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    sigma: Option<f64>,
    /// Which motion: x, y or their sum.
    #[arg(long, value_enum, default_value = "sum")]
    motion: MotionArg,
    /// Brightness = normalised amplitude to this power.
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    exponent: Option<f64>,
    /// Pyramid scale (0 = finest, 4-pixel wavelength; each next one doubles;
    /// default 1: the finest is noise-biased on smooth texture).
    #[arg(long, value_name = "S")]
    pyramid_scale: Option<usize>,
    #[command(flatten)]
    units: UnitArgs,
    /// Do not divide by the blurred weights (the images of thesis ch. 4-5:
    /// texture acts as a mask).
    #[arg(long)]
    unnormalized: bool,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let o = ModesOptions {
        video: a.video,
        at_hz: a.at_hz[0],
        also_at_hz: a.at_hz[1..].to_vec(),
        output: a.output,
        npy: a.npy,
        figure: a.figure,
        animate: a.animate,
        animate_px: a.animate_px,
        fps: a.video_args.fps,
        region: a.video_args.region(),
        sigma: a.sigma,
        motion: match a.motion {
            MotionArg::X => Motion::X,
            MotionArg::Y => Motion::Y,
            MotionArg::Sum => Motion::Sum,
        },
        exponent: a.exponent,
        pyramid_scale: a.pyramid_scale,
        scale: a.units.scale(),
        unnormalized: a.unnormalized,
        run: RunSettings { progress: true },
    };
    super::warn_playback_rate(&o.video, o.fps);
    let bar = super::Bar::start(true);
    let r = modes::modes_all(&o);
    drop(bar);
    let (images, _) = super::stats(a.stats, r, |(_, run)| Some(run.table()))?;
    for r in &images {
        super::wrote(&r.png);
        if let Some(n) = &r.npy {
            super::wrote(n);
        }
        if let Some(a) = &r.animation {
            super::wrote(a);
        }
    }
    if let Some(f) = &o.figure {
        super::wrote(f);
    }
    for r in &images {
        match &r.peak {
            Some(p) => eprintln!(
                "modal image at {} Hz: largest {} {} at ({}, {}){}",
                r.freq_hz,
                sig4(p.amplitude),
                if o.unnormalized {
                    "(texture-weighted, no unit)".to_string()
                } else {
                    r.unit.to_string()
                },
                p.x,
                p.y,
                if r.npy.is_some() && !o.unnormalized {
                    format!("; the .npy is in {}", r.unit)
                } else {
                    String::new()
                }
            ),
            None => eprintln!(
                "modal image at {} Hz: no motion at that frequency (all zero)",
                r.freq_hz
            ),
        }
        if let Some(c) = &r.shape {
            eprintln!(
                "  mode-shape checks: MPC {:.3}, MPD {:.1}° ({})",
                c.mpc,
                c.mpd_deg,
                if c.mpc >= 0.8 {
                    "a standing mode's shape: its parts move in phase or in antiphase"
                } else {
                    "not a standing mode's shape: noise, a travelling wave or mixed modes (a real mode gives MPC near 1, MPD near 0)"
                }
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `v` to four significant digits.
fn sig4(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (3 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}
