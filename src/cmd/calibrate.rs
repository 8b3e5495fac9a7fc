//! `vibroscope calibrate`.

use super::VideoArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::calibrate::{self, CalibrateOptions};
use vibroscope::pipeline::RunSettings;

/// Calibrate against a known sound: which camera and object effects explain the error.
///
/// Compare what the visual microphone recovers from VIDEO with the sound
/// that was played (REF.wav): fit delay and gain, then try the catalog
/// of effects (time-base error, dropped or duplicated frames, exposure,
/// interference lines, object transfer function, soft saturation), each
/// fitted on 60% of the recording (blocks of about 0.1 s, 3 of every 5)
/// and kept only if it lowers the error on the other 40%; report the
/// errors before and after and the residual no effect explains.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope calibrate chirp.y4m --reference chirp.wav --json report.json -o corrected.wav\n  \
    vibroscope listen speech.y4m --calibration report.json -o speech.wav")]
pub struct Args {
    /// The recording of the object while the reference sound played
    /// (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    video: PathBuf,
    /// The sound that was played (WAV, first channel): a chirp or ramp, or
    /// speech. It must cover the video's duration and be sampled at least
    /// at the video's frame rate.
    #[arg(long, value_name = "REF.wav")]
    reference: PathBuf,
    /// Where to write the report: errors on the held-out part before and
    /// after, the effects kept (name, parameters, uncertainty, SNR gain) and
    /// the residual no effect explains.
    #[arg(long, value_name = "REPORT.json")]
    json: PathBuf,
    /// Also write the corrected recovery, aligned and scaled to the
    /// reference, at the reference's sample rate (band-limited to half the
    /// frame rate, and still high-passed like every recovery).
    #[arg(short, long, value_name = "CORRECTED.wav")]
    output: Option<PathBuf>,
    #[command(flatten)]
    video_args: VideoArgs,
    /// The effects to try, comma-separated, in the catalog's order
    /// whatever the order given (default: all of time_base,
    /// dropped_frames, exposure, interference, transfer_function,
    /// soft_clip).
    #[arg(long, value_name = "LIST")]
    effects: Option<String>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let effects = a
        .effects
        .as_deref()
        .map(calibrate::parse_effects)
        .transpose()?;
    let o = CalibrateOptions {
        video: a.video,
        reference: a.reference,
        json: a.json,
        output: a.output,
        fps: a.video_args.fps,
        region: a.video_args.region(),
        effects,
        run: RunSettings { progress: true },
    };
    super::warn_playback_rate(&o.video, o.fps);
    let bar = super::Bar::start(true);
    let r = calibrate::calibrate(&o);
    drop(bar);
    let r = r?;
    let (b, af) = (&r.report.before, &r.report.after);
    let db = |v: f64| super::num(v, 2);
    eprintln!(
        "linear model: delay {:.3} ms, gain {:.4e}; held-out part (40%): SNR {} -> {} dB, segmental SNR {} -> {} dB, LSD {} -> {} dB",
        r.delay_s * 1e3,
        r.gain,
        db(b.snr_db),
        db(af.snr_db),
        db(b.ssnr_db),
        db(af.ssnr_db),
        db(b.lsd_db),
        db(af.lsd_db)
    );
    for e in &r.report.effects {
        eprintln!("kept {}: +{:.2} dB", e.name, e.snr_gain_db);
    }
    for (name, gain, _) in &r.rejected {
        eprintln!("tried {name}: {} dB, not kept", db(*gain));
    }
    for u in &r.report.unexplained {
        eprintln!("unexplained: {}", u.description());
    }
    for p in &r.written {
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}
