//! `vibroscope bound`.

use std::path::PathBuf;
use std::process::ExitCode;

/// The noise floor of sub-pixel motion in a recording: per region, the
/// sensor noise and the texture give the Cramér-Rao bound, the smallest
/// per-frame RMS error any motion estimate can have there (a rigid
/// translation, unbiased estimators), and with --amplitude-px the best
/// SNR a tone of that amplitude can be recovered with.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  vibroscope bound clip.y4m\n  \
    vibroscope bound guitar.mp4 --fps 600 --region 80,20,120,110 --amplitude-px 0.003\n  \
    vibroscope bound speech.y4m --region 48,48,96,96 --amplitude-px 0.03 --json bound.json\n\n\
The bound assumes the whole region moves as one: a region that is partly still \
(background, an edge) gets an optimistic floor. It is per frame over the whole \
band up to Nyquist; a signal in a narrower band gains 10 log10((fps/2)/band) dB \
by filtering.")]
pub struct Args {
    video: PathBuf,
    /// Capture rate in Hz, when the file states the wrong one (reported).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// A region, X,Y,W,H in pixels; repeat for several (default: the whole
    /// frame).
    #[arg(long = "region", visible_alias = "roi", value_name = "X,Y,W,H", value_parser = super::parse_roi, action = clap::ArgAction::Append)]
    regions: Vec<vibroscope::pipeline::Roi>,
    /// A tone's amplitude in pixels: also print the best per-frame SNR
    /// its motion can be recovered with.
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    amplitude_px: Option<f64>,
    /// Frames averaged into the reference image.
    #[arg(long, value_name = "N", default_value_t = vibroscope::bound::REFERENCE_FRAMES)]
    reference_frames: usize,
    /// Read at most this many frames.
    #[arg(long, value_name = "N")]
    frames: Option<usize>,
    /// Also write the bound as JSON to this file.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    super::check_json(&[&a.video], a.json.as_deref())?;
    let mut o = vibroscope::bound::BoundOptions::new(&a.video);
    o.fps = a.fps;
    o.regions = a.regions;
    o.amplitude_px = a.amplitude_px;
    o.reference_frames = a.reference_frames;
    o.max_frames = a.frames;
    let r = vibroscope::bound::bound(&o)?;
    super::outln!(
        "{}: {}x{}, {} frames ({} averaged into the reference)",
        r.video.display(),
        r.width,
        r.height,
        r.frames,
        r.reference_frames
    );
    for (k, reg) in r.regions.iter().enumerate() {
        let b = &reg.bound;
        let [x, y, w, h] = b.roi;
        super::outln!(
            "region {} ({x},{y},{w},{h}), {} px: noise {:.3} DN, Cramér-Rao floor {:.3e} px RMS along x, {:.3e} along y per frame",
            k + 1,
            b.pixels,
            b.noise_dn,
            b.crb_px[0],
            b.crb_px[1]
        );
        if let (Some(a), Some([sx, sy])) = (r.amplitude_px, reg.snr_db) {
            super::outln!(
                "  a tone of {a} px: at best {sx:.1} dB SNR per frame along x, {sy:.1} dB along y"
            );
        }
    }
    for n in &r.notes {
        super::outln!("note: {n}");
    }
    if let Some(p) = &a.json {
        vibroscope::files::write_atomic(p, &serde_json::to_vec_pretty(&r)?)?;
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}
