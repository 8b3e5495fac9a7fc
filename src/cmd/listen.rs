//! `vibroscope listen`.

use super::VideoArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::listen::{
    self, BandFilter, Denoise, Fill, ListenOptions, Method, OutputRate, RollingShutter, Unfold,
};
use vibroscope::pipeline::RunSettings;
use vibroscope::UsageError;

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum DenoiseArg {
    /// No denoising.
    None,
    /// Spectral subtraction.
    Subtract,
    /// Speech enhancement (perceptual: MMSE log-spectral amplitude).
    Enhance,
    /// MMSE (Wiener) STFT gain: the least squared error, the highest SNR.
    Wiener,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum MethodArg {
    /// Per-tile gradient least squares, whitened, on the tiles' first
    /// principal component: at the Cramér-Rao bound for sub-pixel motion
    /// of a textured object; still background gets no weight.
    Gradient,
    /// The thesis' pyramid local phase (A²-weighted, bands aligned and
    /// summed): for motions near a pixel or more; what `calibrate` fits on.
    Phase,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum FillArg {
    /// Autoregressive prediction from both sides.
    Ar,
    /// Straight lines.
    Linear,
}

/// Recover sound from a video (a 16-bit WAV any player takes).
///
/// Recover sound from a video: a shipped visual-microphone pipeline
/// replayed on VIDEO (per-tile sub-pixel motion on its first principal
/// component by default, or the thesis' pyramid local phase with `--method
/// phase`; then a high-pass, optional denoising, optional band-pass and
/// band-stop filters), resampled to a standard audio rate and written as a
/// 16-bit PCM WAV.
///
/// The default method reaches the noise limit of sub-pixel motion
/// (`vibroscope bound`) on a textured object without a region: tiles that
/// do not move get no weight. It is made for sub-pixel motion (it still
/// leads the phase method at 1 px peak on simulated speech, and is even
/// at 2 px); for larger motions use `--method phase`.
///
/// On a file every filter is zero-phase (forward-backward): the sound is
/// aligned with the motion to the sample, and each filter's magnitude is
/// its Butterworth design squared (-6 dB at its edges); `--stats` says
/// which mode ran and what it held back. Live pipelines (`vibroscope run
/// live-microphone`) keep the causal, low-latency filters.
#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  vibroscope listen ../shared/data/guitar.mp4 --fps 600 -o guitar.wav\n  \
    vibroscope listen ../shared/data/guitar.mp4 --fps 600 --band 70,120 --rate 48000 -o strings.wav\n  \
    vibroscope listen hum.y4m --notch 50 --notch 100,4 --float -o clean.wav\n  \
    vibroscope listen chips.cine --roi 100,40,200,160 --denoise enhance -o chips.wav"
)]
pub struct Args {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    video: PathBuf,
    /// Output WAV.
    #[arg(short, long, default_value = "sound.wav")]
    output: PathBuf,
    #[command(flatten)]
    video_args: VideoArgs,
    /// How motion is measured. Default: gradient, or phase with
    /// --calibration (calibrations are fitted on it). --pyramid applies to
    /// phase only.
    #[arg(long, value_enum)]
    method: Option<MethodArg>,
    /// Independent sources the gradient method may hear, 1-4: 1 (the
    /// default) follows the strongest motion, the best for one sound; more
    /// add further ones that stand out from the noise (a second guitar
    /// string; a flickering light's residue can stand out too).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=4))]
    sources: Option<u8>,
    /// Denoising after the high-pass.
    #[arg(long, value_enum, default_value = "none")]
    denoise: DenoiseArg,
    /// Keep only LO..HI Hz (Butterworth band-pass, -6 dB at the edges on
    /// a file; repeat for several bands in series).
    #[arg(long, value_name = "LO,HI", allow_negative_numbers = true)]
    band: Vec<String>,
    /// Remove F Hz (Butterworth band-stop from F-WIDTH/2 to F+WIDTH/2;
    /// WIDTH defaults to F/10); repeatable (mains hum and its harmonics).
    #[arg(long, value_name = "F[,WIDTH]", allow_negative_numbers = true)]
    notch: Vec<String>,
    /// Output sample rate in Hz (1000-384000: 8000, 16000, 44100, 48000
    /// play everywhere), or `native` for the signal's own (the frame rate;
    /// 1/line delay with --rolling-shutter). Default: the signal's rate when
    /// it is a standard audio rate (8000, 11025, 16000, 22050, 32000, 44100,
    /// 48000, 88200, 96000 Hz), else 48000 Hz. Band-limited: a 256-tap sinc,
    /// the speaker's resampler, with its delay compensated.
    #[arg(long, value_name = "HZ|native", allow_negative_numbers = true)]
    rate: Option<String>,
    /// Write 32-bit float samples in the signal's own units instead of
    /// 16-bit PCM peak-normalised to -1 dBFS: relative units (the tiles'
    /// whitened motion on their principal component), radians of local
    /// phase with --method phase (A²-weighted, aligned and summed over
    /// bands), or pixels along x with --rolling-shutter. A sound, not a calibrated displacement: for one
    /// in µm or mm use `spectrum --waveform OUT.csv --scale MM_PER_PX`.
    #[arg(long)]
    float: bool,
    /// With --method phase --pyramid csp: the steerable pyramid's
    /// orientations 0 and 90° on half grids (their band values every second
    /// column or row: exact, half the work): about twice as fast; the
    /// A²-weighted sums see half the samples, which costs up to 0.3 dB of
    /// SNR on noisy scenes (docs/performance.md). Not with --calibration.
    #[arg(long)]
    half_grids: bool,
    /// Also play the sound on a speaker, in real time, resampled to the
    /// device rate: the default output, part of a device's name, or
    /// `null` (a virtual device that discards audio).
    #[arg(long, value_name = "DEVICE", num_args = 0..=1, default_missing_value = "default")]
    speaker: Option<String>,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
    /// Apply a stored calibration (REPORT.json from `vibroscope
    /// calibrate` on the same object and camera): its time-base,
    /// exposure and transfer-function corrections; its interference lines,
    /// fitted again here; a static nonlinearity and the explainer's terms
    /// brought to this recording's scale (its region's motion and the
    /// terms' tiles are measured in the same run); not the per-recording
    /// ones (dropped frames, soft clipping, gain drift). The transfer
    /// function applies as a Wiener inverse against what folds into the
    /// band from above the Nyquist frequency: where the object dips, the
    /// recording there is partly the sound above the Nyquist frequency,
    /// which the object's response there (unmeasured) shaped, so the dip
    /// is boosted less than its plain inverse would, by how much this
    /// recording's falling spectrum, extrapolated, puts there (the note
    /// says; a spectrum that does not fall, or content that stops short of
    /// the Nyquist frequency, gets the plain inverse). A readout found across the rows
    /// (capture_time) recombines the strips of rows it was found on, each
    /// at its delay, and unfolds what they sampled above the frame rate's
    /// Nyquist frequency where they show it holds something (see
    /// --unfold); with --rolling-shutter, the line delay is the
    /// calibration's unless --line-delay-us is given. With --denoise, the denoiser runs
    /// again after the correction, as in the thesis' Table 4.2: an
    /// equaliser lifts the noise in the bands it boosts, so equalising
    /// noisy speech without denoising can lower its segmental SNR.
    #[arg(long, value_name = "REPORT.json")]
    calibration: Option<PathBuf>,
    /// With --calibration holding a readout across the rows (capture_time):
    /// unfold what the strips of rows sampled between the frame rate's
    /// Nyquist frequency and the frame rate (the rows are captured at
    /// different instants, so a frequency and its alias reach them with
    /// different delays and can be told apart), and write the sound at
    /// twice the frame rate. The alias is estimated per frequency by least
    /// squares over the strips and shrunk (Wiener) where it is below their
    /// noise. Without this flag, listen unfolds only where the strips show
    /// that something lies above the Nyquist frequency: each strip, left
    /// out in turn, is predicted better from the others with the alias
    /// than without (the note gives the figure). With it, listen unfolds
    /// whatever they show, and says why where it cannot (capture times too
    /// close together, or a calibration that also needs this recording's
    /// frame or tiles).
    #[arg(long, requires = "calibration", conflicts_with = "no_unfold")]
    unfold: bool,
    /// With --calibration holding a readout across the rows: keep the
    /// sound at the frame rate, the strips' delays applied there (it then
    /// holds the aliases of what lies above the frame rate's Nyquist
    /// frequency, as a global shutter's recovery does).
    #[arg(long, requires = "calibration")]
    no_unfold: bool,
    #[command(flatten)]
    rolling: RollingArgs,
}

/// `listen` options for rolling-shutter recordings (thesis ch. 4.5).
#[derive(clap::Args, Debug, Clone)]
struct RollingArgs {
    /// One sample per image row instead of per frame: hears far above the
    /// frame rate (needs --line-delay-us, or a --calibration that found the
    /// rows' readout).
    #[arg(long)]
    rolling_shutter: bool,
    /// Time between consecutive rows, µs (see `vibroscope rs-calibrate`).
    #[arg(long, value_name = "US", allow_negative_numbers = true)]
    line_delay_us: Option<f64>,
    /// Blind time between a frame's last row and the next frame's first, µs
    /// (checked against the frame rate and row count).
    #[arg(long, value_name = "US", allow_negative_numbers = true)]
    frame_delay_us: Option<f64>,
    /// Exposure per row, µs: low-pass at its first null 1/E.
    #[arg(long, value_name = "US", allow_negative_numbers = true)]
    exposure_us: Option<f64>,
    /// Invert the exposure boxcar where its gain is above -12 dB (needs --exposure-us).
    #[arg(long)]
    compensate_exposure: bool,
    /// Filling of the frame-delay gaps.
    #[arg(long, value_enum, default_value = "ar")]
    fill: FillArg,
}

impl RollingArgs {
    /// The rolling-shutter options, or a usage error when one is given
    /// without --rolling-shutter.
    fn options(&self) -> Result<Option<RollingShutter>, UsageError> {
        if !self.rolling_shutter {
            let used = [
                ("--line-delay-us", self.line_delay_us.is_some()),
                ("--frame-delay-us", self.frame_delay_us.is_some()),
                ("--exposure-us", self.exposure_us.is_some()),
                ("--compensate-exposure", self.compensate_exposure),
            ];
            return match used.iter().find(|(_, u)| *u) {
                Some((flag, _)) => Err(UsageError::new(*flag, "needs --rolling-shutter")),
                None => Ok(None),
            };
        }
        Ok(Some(RollingShutter {
            line_delay_us: self.line_delay_us,
            frame_delay_us: self.frame_delay_us,
            exposure_us: self.exposure_us,
            compensate_exposure: self.compensate_exposure,
            fill: match self.fill {
                FillArg::Ar => Fill::Ar,
                FillArg::Linear => Fill::Linear,
            },
        }))
    }
}

/// `--rate HZ|native`.
fn output_rate(r: Option<&str>) -> Result<OutputRate, UsageError> {
    let Some(r) = r else {
        return Ok(OutputRate::Standard);
    };
    if r.trim() == "native" {
        return Ok(OutputRate::Native);
    }
    match r.trim().parse::<u32>() {
        Ok(hz) if listen::RATE_RANGE.contains(&hz) => Ok(OutputRate::Hz(hz)),
        _ => Err(UsageError::new(
            "--rate",
            format!(
                "expected a whole number of Hz in {}-{} (8000, 16000, 44100, 48000, ...) or `native`, got `{r}`",
                listen::RATE_RANGE.start(),
                listen::RATE_RANGE.end()
            ),
        )),
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let mut filters = Vec::new();
    for b in &a.band {
        filters.push(BandFilter::band(b)?);
    }
    for n in &a.notch {
        filters.push(BandFilter::notch(n)?);
    }
    let o = ListenOptions {
        video: a.video.clone(),
        output: a.output.clone(),
        fps: a.video_args.fps,
        region: a.video_args.region(),
        method: a.method.map(|m| match m {
            MethodArg::Gradient => Method::Gradient,
            MethodArg::Phase => Method::Phase,
        }),
        sources: a.sources.map(usize::from),
        denoise: match a.denoise {
            DenoiseArg::None => Denoise::None,
            DenoiseArg::Subtract => Denoise::Subtract,
            DenoiseArg::Enhance => Denoise::Enhance,
            DenoiseArg::Wiener => Denoise::Wiener,
        },
        speaker: a.speaker,
        calibration: a.calibration,
        unfold: match (a.unfold, a.no_unfold) {
            (true, _) => Unfold::Asked,
            (_, true) => Unfold::Never,
            _ => Unfold::Auto,
        },
        rolling_shutter: a.rolling.options()?,
        filters,
        rate: output_rate(a.rate.as_deref())?,
        float: a.float,
        half_grids: a.half_grids,
        run: RunSettings { progress: true },
    };
    super::warn_playback_rate(&o.video, o.fps);
    let bar = super::Bar::start(true);
    let r = listen::listen(&o);
    drop(bar);
    let r = super::stats(a.stats, r, |r| r.run.as_ref().map(|r| r.table()))?;
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    if let Some(c) = &r.calibration {
        eprintln!("applied calibration: {c}");
    }
    super::wrote(&r.output);
    if r.sample_rate_hz > 0 {
        eprintln!(
            "{:.2} s of sound at {} Hz, {}",
            r.samples as f64 / f64::from(r.sample_rate_hz),
            r.sample_rate_hz,
            r.encoding
        );
    }
    Ok(ExitCode::SUCCESS)
}
