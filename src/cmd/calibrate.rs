//! `vibroscope calibrate`.

use super::VideoArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use vibroscope::calibrate::{self, CalibrateOptions, StepHook};
use vibroscope::pipeline::RunSettings;

/// Calibrate against a known sound: which camera and object effects explain the error.
///
/// Compare what the visual microphone recovers from VIDEO with the sound
/// that was played (REF.wav): fit delay and gain, then try the catalog
/// of effects (a capture time that changes across the image's rows,
/// time-base error, dropped or duplicated frames, exposure, interference
/// lines, object transfer function, soft saturation, a static
/// nonlinearity, a gain drifting over the recording), each
/// fitted on 60% of the recording (blocks of about 0.1 s, 3 of every 5)
/// and kept only if it lowers the error on the other 40%. Then explain
/// what is left with the recording's own observables (the motion and
/// intensity of tiles of the frame around the region: the camera or its
/// mount, another vibrating thing in view, the light), kept by the same
/// held-out test (a weak one that is fitted again on each recording also
/// when its gain lies far beyond what the same observable shifted in time
/// gains) and named by their likely cause (`listen --calibration`
/// measures each again on the new recording and subtracts it: fitted
/// there when it does not follow the reference, through its stored FIR
/// when it is a tile's motion that does; a tile's brightness or a
/// sensor's line that follows the reference is left out, and said).
/// Report the errors before and after and the residual nothing explains.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope calibrate chirp.y4m --reference chirp.wav --json report.json -o corrected.wav\n  \
    vibroscope calibrate fork.mp4 --fps 1000 --roi 274,35,60,88 --reference-tone 64 --json fork.json\n  \
    vibroscope listen speech.y4m --calibration report.json -o speech.wav")]
pub struct Args {
    /// The recording of the object while the reference sound played
    /// (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    video: PathBuf,
    /// The sound that was played (WAV, first channel): a chirp or ramp, or
    /// speech. It must cover the video's duration and be sampled at least
    /// at the video's frame rate.
    #[arg(
        long,
        value_name = "REF.wav",
        required_unless_present = "reference_tone",
        conflicts_with = "reference_tone"
    )]
    reference: Option<PathBuf>,
    /// Instead of a WAV: the object rang at a known pitch whose phase and
    /// exact frequency are unknown (a tuning fork struck by hand). The
    /// delay fits the phase; the time base then measures the pitch (or the
    /// camera's rate: against one tone they are one parameter, and the
    /// report says so).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    reference_tone: Option<f64>,
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
    /// whatever the order given (default: all of capture_time, region_gain,
    /// time_base, dropped_frames, exposure, interference,
    /// transfer_function, soft_clip, static_nonlinearity, gain_drift).
    /// capture_time and region_gain also recover the region as 8 strips of
    /// rows (in the same run) and are tried first: capture_time when the
    /// strips' delays against the reference differ beyond their noise
    /// (rows read out one after another; parts of the object that hear the
    /// sound at different times), region_gain when parts move in antiphase
    /// (a non-rigid object), which a sum over the region cancels; `listen
    /// --calibration` then recovers the same strips. Of the two
    /// nonlinearities one is kept at most, and static_nonlinearity (a
    /// polynomial with even and odd terms) is only tried when the residual
    /// holds harmonics of the reference; gain_drift only when the gain
    /// moves over the recording and nothing else gains in that round.
    #[arg(long, value_name = "LIST")]
    effects: Option<String>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let effects = a
        .effects
        .as_deref()
        .map(calibrate::parse_effects)
        .transpose()?;
    // Progress: the recovery's frames bar, then one bar per greedy round
    // over the candidate effects.
    let frames = Arc::new(Mutex::new(super::Bar::start(true)));
    if let Ok(g) = frames.lock() {
        if let Some(b) = g.as_ref() {
            b.set_prefix("recover ".into());
        }
    }
    // Hidden until the first candidate (drawn beside the frames bar, it
    // would show an empty bar during the recovery).
    let rounds = indicatif::ProgressBar::hidden();
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("round {prefix} {bar:30} {pos}/{len} fitting {msg}")
    {
        rounds.set_style(style);
    }
    let on_step = {
        let (frames, rounds) = (Arc::clone(&frames), rounds.clone());
        StepHook(Arc::new(move |s: calibrate::Step| {
            // The recovery is over: its bar goes.
            if let Ok(mut g) = frames.lock() {
                if g.take().is_some() {
                    rounds.set_draw_target(indicatif::ProgressDrawTarget::stderr_with_hz(10));
                }
            }
            rounds.set_prefix(s.round.to_string());
            rounds.set_length(s.of as u64);
            rounds.set_position(s.index as u64);
            rounds.set_message(s.effect.name());
        }))
    };
    let o = CalibrateOptions {
        video: a.video,
        reference: a.reference.unwrap_or_default(),
        reference_tone_hz: a.reference_tone,
        json: a.json,
        output: a.output,
        fps: a.video_args.fps,
        region: a.video_args.region(),
        effects,
        run: RunSettings { progress: true },
        on_step: Some(on_step),
    };
    super::warn_playback_rate(&o.video, o.fps);
    let started = std::time::Instant::now();
    let r = calibrate::calibrate(&o);
    if let Ok(mut g) = frames.lock() {
        g.take();
    }
    rounds.finish_and_clear();
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
    for u in &r.report.linear_residual {
        eprintln!("linear model's residual: {}", u.description());
    }
    for u in &r.report.unexplained {
        eprintln!("unexplained: {}", u.description());
    }
    for c in &r.report.confounded {
        eprintln!("confounded: {}", c.description);
    }
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    for e in &r.report.effects {
        if let Some(s) = &e.cannot_correct {
            eprintln!("{} cannot correct: {s}", e.name);
        }
    }
    // The summary: every effect fitted, kept or not, its held-out gain
    // and parameters (± one standard deviation in REPORT.json).
    eprintln!();
    eprintln!(
        "{:<19} {:<5} {:>14}  parameters",
        "effect", "kept", "held-out gain"
    );
    for e in &r.report.effects {
        eprintln!(
            "{:<19} {:<5} {:>11} dB  {}",
            e.name,
            "yes",
            format!("{:+.2}", e.snr_gain_db),
            brief(&e.parameters)
        );
    }
    for (name, gain, p) in &r.rejected {
        eprintln!(
            "{:<19} {:<5} {:>11} dB  {}",
            name,
            "no",
            if gain.is_finite() {
                format!("{gain:+.2}")
            } else {
                "n/a".into()
            },
            brief(p)
        );
    }
    // What the recording's own observables explained after the catalog.
    for e in &r.report.explained {
        let [x, y, w, h] = e.rect;
        let what = match e.observable {
            vibroscope::calibrate::Observable::MotionX => "motion x",
            vibroscope::calibrate::Observable::MotionY => "motion y",
            vibroscope::calibrate::Observable::Intensity => "intensity",
            vibroscope::calibrate::Observable::RowIntensity => "each row's intensity",
            vibroscope::calibrate::Observable::ColumnIntensity => "each column's intensity",
        };
        // How `listen --calibration` carries it to the next recording.
        let carried = if e.refit {
            "fitted again on each recording".to_string()
        } else {
            format!(
                "follows the reference ({:.0}% of it): its FIR is kept as fitted here",
                100.0 * e.follows_reference
            )
        };
        eprintln!(
            "{:<19} {:<5} {:>11} dB  {what} of [{x}, {y}, {w}, {h}], kept with {:+.2} dB after the terms above ({:.0}% of the residual): {}; {carried}",
            format!("explained:{}", e.cause),
            "yes",
            format!("{:+.2}", e.snr_gain_db),
            e.kept_gain_db,
            100.0 * e.residual_share,
            e.label
        );
    }
    eprintln!(
        "{:<19} {:<5} {:>11} dB  (SNR {} -> {} dB, in {:.1} s)",
        "total",
        "",
        format!("{:+.2}", af.snr_db - b.snr_db),
        db(b.snr_db),
        db(af.snr_db),
        started.elapsed().as_secs_f64()
    );
    for p in &r.written {
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}

/// The numeric parameters of an effect on one line (`key value`, four
/// decimals, whole numbers as they are; lists of up to four numbers in
/// full, longer ones as their length).
fn brief(p: &vibroscope::calibrate::Parameters) -> String {
    let Ok(serde_json::Value::Object(m)) = serde_json::to_value(p) else {
        return String::new();
    };
    m.iter()
        .map(|(k, v)| match v {
            serde_json::Value::Number(n) if n.is_u64() || n.is_i64() => format!("{k} {n}"),
            serde_json::Value::Number(n) => {
                format!(
                    "{k} {}",
                    n.as_f64().map_or(n.to_string(), |x| format!("{x:.4}"))
                )
            }
            serde_json::Value::Array(a) if a.len() <= 4 && a.iter().all(|v| v.is_f64()) => {
                let v: Vec<String> = a
                    .iter()
                    .filter_map(|v| v.as_f64())
                    .map(|x| format!("{x:.4}"))
                    .collect();
                format!("{k} [{}]", v.join(", "))
            }
            serde_json::Value::Array(a) => format!("{k} [{}]", a.len()),
            other => format!("{k} {other}"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}
