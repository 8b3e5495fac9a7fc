//! `vibroscope pitch`.

use super::VideoArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::pipeline::RunSettings;
use vibroscope::pitch::YinParams;
use vibroscope::pitch::{self, PitchOptions};

/// Track the pitch of a sound, or of the sound in a video (YIN).
///
/// Track the fundamental frequency (pitch) of a recovered sound frame by
/// frame with YIN (de Cheveigné and Kawahara 2002), as the thesis does in
/// 4.6 (Fig. 4-11) to show that a recovery keeps the speaker's intonation
/// even where the words are unintelligible. INPUT is a WAV (first channel)
/// or a video, whose sound is recovered first at the frame rate (the
/// `listen` pipeline). Writes CSV (time_s, f0_hz, confidence, voiced) and,
/// with --png, the track over the sound's spectrogram, voiced frames
/// marked.
#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  vibroscope pitch speech.wav -o pitch.csv --png pitch.png\n  \
    vibroscope pitch speech.y4m --roi 20,20,150,150 -o pitch.csv --png pitch.png"
)]
pub struct Args {
    /// A WAV file, or a video (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    input: PathBuf,
    /// The track as CSV.
    #[arg(short, long, default_value = "pitch.csv")]
    output: PathBuf,
    /// Also draw the track over the spectrogram (PNG).
    #[arg(long, value_name = "OUT.png")]
    png: Option<PathBuf>,
    /// Also write the summary as JSON.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
    /// Lowest pitch searched, Hz.
    #[arg(
        long,
        default_value_t = 60.0,
        value_name = "HZ",
        allow_negative_numbers = true
    )]
    fmin: f64,
    /// Highest pitch searched, Hz (at most a quarter of the sample rate).
    #[arg(
        long,
        default_value_t = 500.0,
        value_name = "HZ",
        allow_negative_numbers = true
    )]
    fmax: f64,
    /// YIN's threshold on the normalised difference: a frame is voiced
    /// when it dips below (0.1 in the paper; higher accepts noisier frames).
    #[arg(long, default_value_t = 0.15, allow_negative_numbers = true)]
    threshold: f64,
    #[command(flatten)]
    video_args: VideoArgs,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let o = PitchOptions {
        input: a.input,
        fps: a.video_args.fps,
        region: a.video_args.region(),
        params: YinParams {
            fmin_hz: a.fmin,
            fmax_hz: a.fmax,
            threshold: a.threshold,
            ..YinParams::default()
        },
        csv: a.output,
        png: a.png,
        run: RunSettings { progress: true },
    };
    let mut inputs = vec![o.input.as_path()];
    inputs.extend(o.region.mask.as_deref());
    super::check_json(&inputs, a.json.as_deref())?;
    if !pitch::is_wav(&o.input) {
        super::warn_playback_rate(&o.input, o.fps);
    }
    let r = pitch::pitch(&o)?;
    for p in &r.written {
        super::wrote(p);
    }
    if let Some(j) = &a.json {
        vibroscope::json::write(j, &r)?;
        super::wrote(j);
    }
    if r.voiced_frames == 0 {
        eprintln!(
            "no voiced frame among {} ({} Hz sampling): no pitch between {} and {} Hz found",
            r.frames, r.sample_rate_hz, a.fmin, a.fmax
        );
    } else {
        eprintln!(
            "{} of {} frames voiced; pitch median {} Hz (10-90%: {}-{} Hz)",
            r.voiced_frames,
            r.frames,
            super::num(r.median_hz, 1),
            super::num(r.p10_hz, 1),
            super::num(r.p90_hz, 1)
        );
    }
    Ok(ExitCode::SUCCESS)
}
