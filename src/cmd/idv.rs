//! `vibroscope idv`.

use super::VideoArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::idv::{self, BasisOptions, IdvOptions, ModeChoice, Poke, PokeKind};
use vibroscope::pipeline::RunSettings;

/// Interactive dynamic video: poke an object in a recording and render how it responds.
///
/// Interactive dynamic video (thesis ch. 6): measures an image-space modal
/// basis from the recording (each mode's frequency and damping from the
/// motion spectrum, its x and y shape from modal images, phase-aligned so
/// its dominant axis is real), simulates every mode as an exact damped
/// oscillator kicked by the scripted pokes, and renders the response by
/// warping the first frame (pixels that move more occlude those that move
/// less). A poke of strength 1 moves the poked point by about |DX,DY|
/// pixels. --pull and --throw are direct manipulation instead (thesis Eq.
/// 6.7-6.9): at T the point is held displaced by DX,DY (pull) or set
/// moving along it (throw), then let go. The basis can be saved (--save-basis DIR) and reused (--basis
/// DIR) without the video; its format is in docs/idv.md.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope idv beam.y4m --poke 0.1,150,40,0,3 -o poke.y4m --save-basis beam-basis\n  \
    vibroscope idv --basis beam-basis --poke 0.1,150,40,0,3,2 --poke 1.0,100,40,0,-3 -o two.mp4\n  \
    vibroscope idv --basis beam-basis --pull 0.1,150,40,0,5 -o pulled.mp4\n  \
    vibroscope idv guitar.mp4 --fps 600 --modes 75-90,100-115 --mask strings.pgm --poke 0.05,382,83,0,3 -o pluck.mp4")]
pub struct Args {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads);
    /// not needed with --basis.
    #[arg(required_unless_present = "basis", conflicts_with = "basis")]
    video: Option<PathBuf>,
    /// A poke: at T seconds, an impulse at pixel X,Y in direction DX,DY
    /// (pixels), times STRENGTH (default 1). Repeat for several.
    #[arg(
        long = "poke",
        value_name = "T,X,Y,DX,DY[,STRENGTH]",
        required_unless_present_any = ["pull", "throw"],
        allow_hyphen_values = true
    )]
    pokes: Vec<Poke>,
    /// Direct manipulation (Eq. 6.7-6.8): at T seconds the point X,Y is
    /// held displaced by DX,DY pixels (times STRENGTH), then let go; the
    /// motion before is replaced. Repeat for several.
    #[arg(
        long,
        value_name = "T,X,Y,DX,DY[,STRENGTH]",
        allow_hyphen_values = true,
        value_parser = |s: &str| Poke::parse(s, PokeKind::Pull)
    )]
    pull: Vec<Poke>,
    /// Direct manipulation (Eq. 6.9): at T seconds the point X,Y is at
    /// rest and set moving along DX,DY, swinging about that far (times
    /// STRENGTH); the motion before is replaced. Repeat for several.
    #[arg(
        long,
        value_name = "T,X,Y,DX,DY[,STRENGTH]",
        allow_hyphen_values = true,
        value_parser = |s: &str| Poke::parse(s, PokeKind::Throw)
    )]
    throw: Vec<Poke>,
    /// The modes: `auto` (the significant spectral peaks, at most
    /// --max-modes) or a list of frequencies and ranges in Hz (`7.3,58`,
    /// `75-90,100-115`: the most prominent peak of each range).
    #[arg(
        long,
        value_name = "auto|F1,F2,..",
        default_value = "auto",
        conflicts_with = "basis"
    )]
    modes: ModeChoice,
    /// At most this many modes with --modes auto.
    #[arg(
        long,
        value_name = "N",
        default_value_t = idv::DEFAULT_MAX_MODES,
        conflicts_with = "basis"
    )]
    max_modes: usize,
    /// Output video: .y4m, or any container ffmpeg writes (.mp4, ...).
    #[arg(short, long, value_name = "OUT.y4m|OUT.mp4")]
    output: PathBuf,
    /// Also save the measured basis into this directory.
    #[arg(long, value_name = "DIR", conflicts_with = "basis")]
    save_basis: Option<PathBuf>,
    /// Load the basis from this directory instead of measuring it (what
    /// only a measurement uses is refused with it: a VIDEO, --modes,
    /// --max-modes, --pyramid-scale, --sigma, --fps, --roi, --mask; --pyramid is
    /// not used).
    #[arg(long, value_name = "DIR")]
    basis: Option<PathBuf>,
    /// Output frame rate, Hz (default: the recording's capture rate).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    rate: Option<f64>,
    /// Seconds rendered (default: the last poke, pull or throw + 1 s).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Multiplies every mode's damping ratio (2 = rings half as long).
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    damping_scale: f64,
    /// Pyramid scale of the shapes (0 = finest).
    #[arg(long, value_name = "S", default_value_t = 1, conflicts_with = "basis")]
    pyramid_scale: usize,
    /// σ_b of the shapes' Gaussian blur, input pixels.
    #[arg(
        long,
        value_name = "PX",
        allow_negative_numbers = true,
        conflicts_with = "basis"
    )]
    sigma: Option<f64>,
    #[command(flatten)]
    video_args: VideoArgs,
}

fn progress(k: u64, total: Option<u64>) {
    if k.is_multiple_of(200) {
        match total {
            Some(t) => eprint!("\rmodal shapes: frame {k}/{t}"),
            None => eprint!("\rmodal shapes: frame {k}"),
        }
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if a.basis.is_some() {
        let v = &a.video_args;
        let given: Vec<&str> = [
            (v.fps.is_some(), "--fps"),
            (v.roi.is_some(), "--roi"),
            (v.mask.is_some(), "--mask"),
        ]
        .into_iter()
        .filter_map(|(g, name)| g.then_some(name))
        .collect();
        if !given.is_empty() {
            return Err(vibroscope::error::UsageError::new(
                "--basis",
                format!(
                    "{} cannot be used with it: they shape a basis measured from a video, and --basis loads one measured before (measure again without --basis, or drop them)",
                    given.join(", ")
                ),
            )
            .into());
        }
    }
    let mut b = BasisOptions::new(a.video.clone().unwrap_or_default());
    b.fps = a.video_args.fps;
    b.region = a.video_args.region();
    b.modes = a.modes;
    b.max_modes = a.max_modes;
    b.scale = a.pyramid_scale;
    if let Some(s) = a.sigma {
        b.sigma_px = s;
    }
    b.run = RunSettings { progress: true };
    b.progress = Some(progress);
    let o = IdvOptions {
        basis: b,
        basis_dir: a.basis,
        save_basis: a.save_basis,
        pokes: a.pokes.into_iter().chain(a.pull).chain(a.throw).collect(),
        rate_hz: a.rate,
        duration_s: a.duration,
        damping_scale: a.damping_scale,
        output: a.output,
    };
    if let Some(v) = &a.video {
        super::warn_playback_rate(v, o.basis.fps);
    }
    let bar = super::Bar::start(o.basis_dir.is_none());
    if let Some(bar) = &bar {
        bar.set_prefix("spectrum ".into());
    }
    let r = idv::idv(&o);
    drop(bar);
    eprintln!();
    let r = r?;
    for (k, (f, xi)) in r.modes.iter().enumerate() {
        eprintln!("mode {k}: {f:.3} Hz, damping ratio {xi:.4}");
    }
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    for p in &r.basis_written {
        super::wrote(p);
    }
    super::wrote(&r.output);
    eprintln!(
        "{} frames {}x{} at {} Hz",
        r.frames, r.width, r.height, r.rate_hz
    );
    Ok(ExitCode::SUCCESS)
}
