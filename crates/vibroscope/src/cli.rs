//! The `vibroscope` command line. Exit status: 0 success, 1 runtime error,
//! 2 usage or configuration error, 130 interrupted (outputs finalised).

use crate::engine::config::{self, apply_set, set_param, ConfigError, Origin, PipelineDecl};
use crate::engine::{self, Control, Params};
use crate::stages::sources::synthetic::SyntheticParams;
use crate::stages::{self, REGISTRY};
use crate::{io, pipelines};
use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

pub mod calibrate;
mod modes;
mod plots;

#[derive(Parser)]
#[command(
    name = "vibroscope",
    version,
    about = "Hear and measure vibration through a camera: a streaming visual-vibration engine",
    long_about = "Hear and measure vibration through a camera.\n\n\
        vibroscope runs pipelines of stages (sources, analysis, sinks) joined by bounded \
        ring buffers, on live cameras or on recordings (Y4M, Phantom .cine, Photron \
        .mraw/.cih, anything ffmpeg reads). Pipelines are TOML files; the shipped ones \
        run by name.\n\n\
        Start with `vibroscope demo` (no camera or file needed), then \
        `vibroscope pipelines` and `vibroscope probe FILE`."
)]
pub struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum DenoiseArg {
    None,
    Subtract,
    Enhance,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub(crate) enum PyramidArg {
    Csp,
    Riesz,
}

#[derive(Subcommand)]
enum Command {
    /// Run a pipeline: a TOML file, or the name of a shipped pipeline.
    #[command(after_help = "Examples:\n  vibroscope run demo --stats\n  \
        vibroscope run pipelines/motion.toml --replay clip.cine --set motion.direction_deg=90\n  \
        vibroscope run motion --replay guitar.mp4 --fps 600 --set out.path=guitar.wav")]
    Run {
        /// Pipeline file, or a shipped pipeline's name (see `vibroscope pipelines`).
        pipeline: String,
        /// Override a stage parameter: STAGE.KEY=VALUE (VALUE is TOML: 600, true, "x", [1,2]).
        #[arg(long = "set", value_name = "STAGE.KEY=VALUE")]
        set: Vec<String>,
        /// Replace the pipeline's source with this recording (never drops frames).
        #[arg(long, value_name = "FILE")]
        replay: Option<PathBuf>,
        /// Capture frame rate in Hz for the source (overrides the file's stated rate).
        #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
        fps: Option<f64>,
        /// Print a per-stage summary (items, drops, queue use, time per item) at exit.
        #[arg(long)]
        stats: bool,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
    /// List the shipped pipelines.
    Pipelines,
    /// List the stage kinds a pipeline can use.
    Kinds,
    /// Describe a video file: format, size, bit depth, frames, frame rate, timestamps.
    Probe {
        file: PathBuf,
        /// Capture rate in Hz, when the file states the wrong one.
        #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
        fps: Option<f64>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Recover sound from a video: the shipped visual-microphone pipeline
    /// (pyramid local phase, band alignment, high-pass, optional denoising)
    /// replayed on VIDEO, written to a WAV at the camera's frame rate.
    #[command(
        after_help = "Examples:\n  vibroscope listen ../shared/data/guitar.mp4 --fps 600 -o guitar.wav\n  \
        vibroscope listen chips.cine --roi 100,40,200,160 --denoise enhance -o chips.wav"
    )]
    Listen {
        /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
        video: PathBuf,
        /// Output WAV.
        #[arg(short, long, default_value = "sound.wav")]
        output: PathBuf,
        /// Capture frame rate in Hz (containers often state the playback rate).
        #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
        fps: Option<f64>,
        /// Region of the object: X,Y,W,H in pixels (default: the whole frame).
        #[arg(long, value_name = "X,Y,W,H")]
        roi: Option<String>,
        /// Region of the object as an image the size of the frame (PGM or
        /// PNG; pixels > 0 count); with --roi, the overlap of both.
        #[arg(long, value_name = "FILE")]
        mask: Option<PathBuf>,
        /// Denoising after the high-pass.
        #[arg(long, value_enum, default_value = "none")]
        denoise: DenoiseArg,
        /// Pyramid: complex steerable (quality) or Riesz (speed).
        #[arg(long, value_enum, default_value = "csp")]
        pyramid: PyramidArg,
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
        /// exposure and transfer-function corrections, not the per-recording
        /// ones (dropped frames, interference). With --denoise, the denoiser
        /// runs again after the correction, as in the thesis' Table 4.2: an
        /// equaliser lifts the noise in the bands it boosts, so equalising
        /// noisy speech without denoising can lower its segmental SNR.
        #[arg(long, value_name = "REPORT.json")]
        calibration: Option<PathBuf>,
        #[command(flatten)]
        rolling: RollingArgs,
    },
    /// Estimate a rolling-shutter camera's line delay (and frame delay) from
    /// a video of a known tone or a flickering light (thesis ch. 4.5: the
    /// slope of the tone's phase down the rows).
    #[command(
        name = "rs-calibrate",
        after_help = "Example:\n  vibroscope rs-calibrate tone440.mp4 --tone-hz 440 --fps 60"
    )]
    RsCalibrate(RsCalibrateArgs),
    /// Score a recovered signal against the reference sound: SNR, segmental
    /// SNR (Hansen & Pellom), LLR and STOI (Taal et al. 2011), as JSON, after
    /// finding the best lag and gain (a recovery's scale and sign are arbitrary).
    /// The test is resampled to the reference's rate when they differ.
    Score {
        reference: PathBuf,
        test: PathBuf,
        /// Largest lag searched, in seconds.
        #[arg(long, default_value_t = 0.5, value_name = "S")]
        max_lag_s: f64,
    },
    /// Render a scene file through the forward model to a Y4M recording
    /// (with per-frame timestamps). The scene file holds the `synthetic`
    /// source's parameters at its top level: size, rate, object, motion
    /// `signal`, `amplitude_px`, `noise_std`, `bits`, rolling shutter
    /// (`line_delay_us`, `exposure_us`), the object's look (`texture`: a
    /// picture; `object_mask`: a silhouette), response (`resonances`,
    /// `soft_clip_px`, or a `modal` beam), and camera effects
    /// (`clock_error_ppm`, `drop_frames`, `duplicate_frames`,
    /// `interference`). See `vibroscope kinds` and the README's "Simulator"
    /// section.
    Simulate {
        scene: PathBuf,
        /// Output Y4M (`-` for stdout).
        #[arg(short, long, default_value = "scene.y4m")]
        output: PathBuf,
        /// Override a scene parameter (KEY=VALUE, VALUE in TOML).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        #[arg(long)]
        stats: bool,
    },
    /// List the cameras (V4L2 capture devices) with their formats, sizes and
    /// frame rates. Exits 1 with "no camera found" when there is none.
    Devices,
    /// Record a camera to Y4M (gray) with each frame's capture time in its
    /// header, to replay later with `run PIPELINE --replay REC.y4m`. Ctrl-C
    /// stops and leaves a valid file.
    #[command(
        after_help = "Examples:\n  vibroscope record --device /dev/video0 -o rec.y4m --seconds 5\n  \
        vibroscope record -o rec.y4m --width 640 --height 480 --fps 60 --format yuyv\n  \
        vibroscope run live-microphone --replay rec.y4m --set out.path=rec.wav"
    )]
    Record {
        /// The camera's device node.
        #[arg(long, default_value = "/dev/video0")]
        device: PathBuf,
        /// Output Y4M (`-` for standard output).
        #[arg(short, long)]
        output: PathBuf,
        /// Stop after this many seconds of capture (default: until Ctrl-C).
        #[arg(long, value_name = "S", allow_negative_numbers = true)]
        seconds: Option<f64>,
        /// Requested frame size (the driver may grant another; the file has the granted one).
        #[arg(long)]
        width: Option<u32>,
        #[arg(long)]
        height: Option<u32>,
        /// Requested frame rate in Hz.
        #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
        fps: Option<f64>,
        /// Pixel format to capture: grey, yuyv, mjpeg or auto.
        #[arg(long, default_value = "auto")]
        format: String,
        /// Print the per-stage summary at exit.
        #[arg(long)]
        stats: bool,
    },
    /// Compare what the visual microphone recovers from VIDEO with the sound
    /// that was played (REF.wav): fit delay and gain, then try the catalog
    /// of effects (time-base error, dropped or duplicated frames, exposure,
    /// interference lines, object transfer function, soft saturation), each fitted on 60%
    /// of the recording (blocks of about 0.1 s, 3 of every 5) and kept only
    /// if it lowers the error on the other 40%; report the errors before
    /// and after and the residual no effect explains.
    #[command(after_help = "Examples:\n  \
        vibroscope calibrate chirp.y4m --reference chirp.wav --json report.json -o corrected.wav\n  \
        vibroscope listen speech.y4m --calibration report.json -o speech.wav")]
    Calibrate(calibrate::CalibrateArgs),
    /// Motion spectrum of a video (thesis Eq. 3.17) and its resonances:
    /// frequency, damping ratio with its uncertainty and method, power and
    /// prominence of each peak, as JSON.
    #[command(after_help = "Examples:\n  \
        vibroscope spectrum ../shared/data/guitar.mp4 --fps 600 --json guitar.json\n  \
        vibroscope spectrum beam.y4m --json beam.json --peaks 3 --roi 0,0,64,64")]
    Spectrum(SpectrumArgs),
    /// Modal image of a video at one frequency (thesis ch. 3.5, Eq.
    /// 3.18-3.19): the A²-weighted, blurred and normalised motion spectrum
    /// slice, phase as hue and amplitude as brightness; optionally the
    /// complex image as .npy.
    #[command(after_help = "Example:\n  \
        vibroscope modes ../shared/data/guitar.mp4 --fps 600 --at 80.8 -o e2.png --npy e2.npy")]
    Modes(modes::ModesArgs),
    /// A clamped rod's fundamental by voting over its mode ratios (thesis
    /// Eq. 5.3), refined through the highest mode; Young's modulus (Eq. 5.1)
    /// or length (Eq. 5.4) with propagated errors (Eq. 5.5).
    #[command(after_help = "Examples:\n  \
        vibroscope rod rod.y4m --json rod.json --diameter-m 0.00635 --length-m 0.5588 --density-kg-m3 8530\n  \
        vibroscope rod rod.y4m --json rod.json --ratios 1,6.27,17.55 --tolerance length-m=0.002")]
    Rod(crate::vibrometry::rod::RodArgs),
    /// Per-region resonance shifts between two recordings (thesis ch. 5.6):
    /// each region's spectrum and peaks in A and in B, and the shift of its
    /// strongest resonance with its uncertainty.
    #[command(after_help = "Example:\n  \
        vibroscope compare empty.y4m filled.y4m --roi 0,0,64,64 --roi 64,0,64,64 --json shifts.json")]
    Compare(crate::vibrometry::compare::CompareArgs),
    /// Render the built-in synthetic scene, recover its motion, write a WAV
    /// and print the SNR against the known signal.
    Demo {
        /// Output WAV.
        #[arg(short, long, default_value = "demo.wav")]
        output: PathBuf,
        /// Override a parameter of the demo pipeline (e.g. cam.amplitude_px=0.02).
        #[arg(long = "set", value_name = "STAGE.KEY=VALUE")]
        set: Vec<String>,
    },
}

/// Entry point of the binary.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    init_tracing(cli.verbose);
    match dispatch(cli.command) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            match e.downcast_ref::<ConfigError>() {
                Some(_) => ExitCode::from(2),
                None => ExitCode::from(1),
            }
        }
    }
}

fn init_tracing(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    use std::io::IsTerminal;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}

fn dispatch(cmd: Command) -> anyhow::Result<ExitCode> {
    match cmd {
        Command::Run {
            pipeline,
            set,
            replay,
            fps,
            stats,
            quiet,
        } => {
            let decl = prepare(&pipeline, &set, replay.as_deref(), fps)?;
            run_decl(&decl, stats, !quiet).map(|(code, _)| code)
        }
        Command::Pipelines => {
            for s in pipelines::SHIPPED {
                println!("{:<12} {}", s.name, pipelines::description(s));
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Kinds => {
            for k in REGISTRY {
                let role = if k.is_source() {
                    "source"
                } else if k.output == engine::Output::None {
                    "sink"
                } else {
                    "stage"
                };
                println!("{:<16} {:<7} {}", k.name, role, k.summary);
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Probe { file, fps, json } => probe(&file, fps, json),
        Command::Devices => devices(),
        Command::Record {
            device,
            output,
            seconds,
            width,
            height,
            fps,
            format,
            stats,
        } => record(&RecordArgs {
            device,
            output,
            seconds,
            width,
            height,
            fps,
            format,
            stats,
        }),
        Command::Demo { output, set } => demo(&output, &set),
        Command::Simulate {
            scene,
            output,
            set,
            stats,
        } => simulate(&scene, &output, &set, stats),
        Command::Listen {
            video,
            output,
            fps,
            roi,
            mask,
            denoise,
            pyramid,
            speaker,
            stats,
            calibration,
            rolling,
        } => {
            let corrections = match &calibration {
                Some(path) => {
                    if rolling.rolling_shutter || speaker.is_some() {
                        let flag = if speaker.is_some() {
                            "--speaker"
                        } else {
                            "--rolling-shutter"
                        };
                        return Err(cfg_error(
                            "--calibration",
                            format!("not available with {flag} (the correction is applied to the finished WAV)"),
                        )
                        .into());
                    }
                    Some(calibrate::load_calibration(path)?)
                }
                None => None,
            };
            if mask.is_some() && rolling.rolling_shutter {
                return Err(cfg_error(
                    "--mask",
                    "not available with --rolling-shutter yet (use --roi)".into(),
                )
                .into());
            }
            let mut decl = if rolling.rolling_shutter {
                if !matches!(denoise, DenoiseArg::None) {
                    return Err(cfg_error(
                        "--denoise",
                        "not available with --rolling-shutter yet".into(),
                    )
                    .into());
                }
                rs_listen_pipeline(&video, &output, fps, roi.as_deref(), &rolling)?
            } else {
                rolling.check_unused()?;
                let mut decl =
                    listen_pipeline(&video, &output, fps, roi.as_deref(), denoise, pyramid)?;
                if let Some(m) = mask {
                    if let Some(st) = decl.stages.iter_mut().find(|s| s.id == "phase") {
                        let origin = Origin::Set(format!("--mask {}", m.display()));
                        let v = toml::Value::String(m.display().to_string());
                        set_param(st, "mask", v, origin);
                    }
                }
                decl
            };
            if let Some(dev) = speaker {
                add_speaker(&mut decl, &dev)?;
            }
            let (code, _) = run_decl(&decl, stats, true)?;
            if code == ExitCode::SUCCESS {
                if let Some(c) = &corrections {
                    let again = (!matches!(denoise, DenoiseArg::None)).then_some(denoise);
                    calibrate::apply_to_wav(&output, c, again)?;
                    eprintln!("applied calibration: {}", calibrate::describe(c));
                }
                eprintln!("wrote {}", output.display());
            }
            Ok(code)
        }
        Command::Calibrate(a) => calibrate::run(&a),
        Command::RsCalibrate(a) => rs_calibrate(&a),
        Command::Spectrum(a) => spectrum_cmd(&a),
        Command::Modes(a) => modes::modes_cmd(&a),
        Command::Rod(a) => crate::vibrometry::rod::rod_cmd(&a),
        Command::Compare(a) => crate::vibrometry::compare::compare_cmd(&a),
        Command::Score {
            reference,
            test,
            max_lag_s,
        } => score(&reference, &test, max_lag_s),
    }
}

/// Loads a pipeline by path or shipped name and applies command-line changes.
pub fn prepare(
    pipeline: &str,
    set: &[String],
    replay: Option<&Path>,
    fps: Option<f64>,
) -> anyhow::Result<PipelineDecl> {
    let mut decl = load(pipeline)?;
    for s in set {
        apply_set(&mut decl, s)?;
    }
    if let Some(path) = replay {
        apply_replay(&mut decl, path)?;
    }
    if let Some(f) = fps {
        apply_fps(&mut decl, f)?;
    }
    Ok(decl)
}

fn cfg_error(file: &str, msg: String) -> ConfigError {
    ConfigError {
        file: file.to_string(),
        origin: None,
        stage: None,
        field: None,
        message: msg,
    }
}

/// A pipeline file, or a shipped pipeline by name.
pub fn load(pipeline: &str) -> Result<PipelineDecl, ConfigError> {
    let path = Path::new(pipeline);
    if path.exists() {
        let text = std::fs::read_to_string(path)
            .map_err(|e| cfg_error(pipeline, format!("cannot read: {e}")))?;
        return config::parse(pipeline, &text);
    }
    if let Some(s) = pipelines::find(pipeline) {
        return config::parse(&format!("pipelines/{}.toml (shipped)", s.name), s.text);
    }
    let names: Vec<&str> = pipelines::SHIPPED.iter().map(|s| s.name).collect();
    Err(cfg_error(
        pipeline,
        format!(
            "no such file, and no shipped pipeline of that name (shipped: {})",
            names.join(", ")
        ),
    ))
}

fn source_indices(decl: &PipelineDecl) -> Vec<usize> {
    decl.stages
        .iter()
        .enumerate()
        .filter(|(_, s)| stages::kind(&s.kind).is_some_and(|k| k.is_source()))
        .map(|(i, _)| i)
        .collect()
}

fn one_source(decl: &PipelineDecl, what: &str) -> Result<usize, ConfigError> {
    let src = source_indices(decl);
    match src.as_slice() {
        [i] => Ok(*i),
        [] => Err(cfg_error(
            &decl.file,
            format!("{what}: the pipeline has no source stage"),
        )),
        many => {
            let ids: Vec<&str> = many.iter().map(|&i| decl.stages[i].id.as_str()).collect();
            Err(cfg_error(
                &decl.file,
                format!(
                    "{what}: the pipeline has several sources ({}); use --set ID.path=... instead",
                    ids.join(", ")
                ),
            ))
        }
    }
}

/// `--replay FILE`: the source becomes a file source of the same id, feeding
/// the same stages; every edge blocks (a replay never drops).
pub fn apply_replay(decl: &mut PipelineDecl, path: &Path) -> Result<(), ConfigError> {
    let i = one_source(decl, "--replay")?;
    let origin = Origin::Builtin(format!("--replay {}", path.display()));
    let st = &mut decl.stages[i];
    st.kind = "file".into();
    st.kind_origin = origin.clone();
    st.params.clear();
    set_param(
        st,
        "path",
        toml::Value::String(path.display().to_string()),
        origin,
    );
    for s in &mut decl.stages {
        s.policy = None;
        for inp in &mut s.inputs {
            inp.policy = None;
        }
    }
    Ok(())
}

/// `--fps HZ`: sets the source's capture rate.
pub fn apply_fps(decl: &mut PipelineDecl, fps: f64) -> Result<(), ConfigError> {
    let i = one_source(decl, "--fps")?;
    let st = &mut decl.stages[i];
    set_param(
        st,
        "fps",
        toml::Value::Float(fps),
        Origin::Set(format!("--fps {fps}")),
    );
    Ok(())
}

/// Validates and runs; returns the exit code and the report.
pub fn run_decl(
    decl: &PipelineDecl,
    stats: bool,
    progress: bool,
) -> anyhow::Result<(ExitCode, engine::RunReport)> {
    let graph = engine::graph::validate(decl, REGISTRY)?;
    let control = Control::new();
    install_ctrlc(&control);
    let report = engine::run(
        graph,
        Arc::clone(&control),
        &engine::RunOptions { progress },
    )
    .context(format!("{}: cannot start the pipeline", decl.file))?;
    if stats {
        eprint!("{}", report.table());
    }
    for e in &report.errors {
        eprintln!("error: {}", engine::error_chain(e));
    }
    let code = if !report.errors.is_empty() {
        ExitCode::from(1)
    } else if report.interrupted {
        eprintln!("interrupted: outputs were finalised with what was processed");
        ExitCode::from(130)
    } else {
        ExitCode::SUCCESS
    };
    Ok((code, report))
}

static CTRLC: std::sync::OnceLock<std::sync::Mutex<Option<Arc<Control>>>> =
    std::sync::OnceLock::new();
static PRESSES: AtomicUsize = AtomicUsize::new(0);

/// First Ctrl-C: stop the sources and drain; second: stop at once (sinks
/// still finalise); third: exit.
fn install_ctrlc(control: &Arc<Control>) {
    let slot = CTRLC.get_or_init(|| {
        let _ = ctrlc::set_handler(|| {
            let n = PRESSES.fetch_add(1, Ordering::SeqCst);
            let c = CTRLC.get().and_then(|m| m.lock().ok().and_then(|g| g.clone()));
            match (n, c) {
                (0, Some(c)) => {
                    eprintln!("\nstopping: draining queues and finalising outputs (Ctrl-C again to stop at once)");
                    c.stop();
                }
                (1, Some(c)) => c.abort(),
                _ => std::process::exit(130),
            }
        });
        std::sync::Mutex::new(None)
    });
    if let Ok(mut g) = slot.lock() {
        *g = Some(Arc::clone(control));
    }
}

fn probe(file: &Path, fps: Option<f64>, json: bool) -> anyhow::Result<ExitCode> {
    if let Some(f) = fps {
        stages::sources::check_fps(f).map_err(|m| cfg_error("--fps", m))?;
    }
    let reader = io::open(file, io::Format::Auto)?;
    let info = reader.info();
    let rate = fps.or(info.fps);
    if json {
        let v = serde_json::json!({
            "file": file.display().to_string(),
            "format": info.format_name,
            "width": info.width,
            "height": info.height,
            "bits": info.bits,
            "frames": info.frame_count,
            "fps": rate,
            "fps_stated": info.fps,
            "timestamps": info.has_timestamps,
            "exposure_s": info.exposure_s,
            "notes": info.notes,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("file:        {}", file.display());
        println!("format:      {}", info.format_name);
        println!("size:        {}x{}", info.width, info.height);
        println!("bit depth:   {} bits", info.bits);
        match info.frame_count {
            Some(n) => println!("frames:      {n}"),
            None => println!("frames:      unknown (stream)"),
        }
        match (fps, info.fps) {
            (Some(f), Some(s)) => println!("frame rate:  {f} Hz (given; the file states {s} Hz)"),
            (Some(f), None) => println!("frame rate:  {f} Hz (given)"),
            (None, Some(s)) => println!("frame rate:  {s} Hz"),
            (None, None) => println!("frame rate:  not stated (pass --fps)"),
        }
        if let (Some(n), Some(r)) = (info.frame_count, rate) {
            println!("duration:    {:.3} s", n as f64 / r);
        }
        println!(
            "timestamps:  {}",
            if info.has_timestamps {
                "present"
            } else {
                "absent"
            }
        );
        if let Some(e) = info.exposure_s {
            println!("exposure:    {:.3} us", e * 1e6);
        }
        for n in &info.notes {
            println!("note:        {n}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs the demo pipeline, then scores the WAV against the known motion.
fn demo(output: &Path, set: &[String]) -> anyhow::Result<ExitCode> {
    let mut decl = load("demo")?;
    set_param(
        decl.stages
            .iter_mut()
            .find(|s| s.id == "out")
            .context("the demo pipeline has no `out` stage")?,
        "path",
        toml::Value::String(output.display().to_string()),
        Origin::Set(format!("-o {}", output.display())),
    );
    for s in set {
        apply_set(&mut decl, s)?;
    }
    let cam = decl
        .stages
        .iter()
        .find(|s| s.id == "cam")
        .context("the demo pipeline has no `cam` stage")?;
    let truth_params: SyntheticParams = Params {
        file: &decl.file,
        stage: cam,
    }
    .parse()?;
    eprintln!(
        "rendering {} frames of {}x{} at {} fps: object moving {} px with {:?}",
        truth_params.frame_count(),
        truth_params.width,
        truth_params.height,
        truth_params.fps,
        truth_params.amplitude_px,
        truth_params.signal
    );
    let (code, report) = run_decl(&decl, false, true)?;
    if code != ExitCode::SUCCESS {
        return Ok(code);
    }
    let mut reader = hound::WavReader::open(output)
        .with_context(|| format!("cannot read back {}", output.display()))?;
    let rate = reader.spec().sample_rate;
    let est: Vec<f64> = reader
        .samples::<f32>()
        .map(|s| s.map(f64::from))
        .collect::<Result<_, _>>()
        .with_context(|| format!("{}: bad samples", output.display()))?;
    let scene = truth_params.scene().map_err(|m| anyhow::anyhow!(m))?;
    let truth: Vec<f64> = (0..est.len())
        .map(|n| scene.displacement_px(n as f64 / truth_params.fps))
        .collect();
    let snr = crate::math::truth::snr_db_fit(&truth, &est);
    let secs = report.elapsed.as_secs_f64();
    let mpix =
        truth_params.frame_count() as f64 * (truth_params.width * truth_params.height) as f64 / 1e6;
    println!(
        "wrote {} ({} samples at {} Hz); SNR against the true motion: {:.1} dB; {:.1} Mpix/s",
        output.display(),
        est.len(),
        rate,
        snr,
        mpix / secs
    );
    Ok(ExitCode::SUCCESS)
}

/// Reads the first channel of a WAV file (see [`crate::io::wav::read_mono`]).
pub fn read_wav_mono(path: &Path) -> anyhow::Result<(u32, Vec<f64>)> {
    Ok(crate::io::wav::read_mono(path)?)
}

fn score(reference: &Path, test: &Path, max_lag_s: f64) -> anyhow::Result<ExitCode> {
    if !(max_lag_s.is_finite() && max_lag_s >= 0.0) {
        return Err(cfg_error(
            "--max-lag-s",
            format!("must be >= 0 seconds, got {max_lag_s}"),
        )
        .into());
    }
    let (fr, r) = read_wav_mono(reference)?;
    let (ft, mut t) = read_wav_mono(test)?;
    if fr != ft {
        let g = crate::math::numeric::gcd(fr as u64, ft as u64).max(1);
        t = crate::math::metrics::resample(&t, fr as u64 / g, ft as u64 / g).with_context(
            || format!("cannot resample {} from {ft} Hz to {fr} Hz", test.display()),
        )?;
    }
    let max_lag = (max_lag_s * fr as f64).round() as usize;
    let (lag, gain) = crate::math::metrics::best_lag_gain(&r, &t, max_lag);
    let s = crate::math::metrics::score(&r, &t, fr as f64, max_lag);
    let num = |v: f64| {
        if v.is_finite() {
            serde_json::json!(v)
        } else {
            serde_json::Value::Null
        }
    };
    let v = serde_json::json!({
        "snr_db": num(s.snr_db),
        "ssnr_db": num(s.ssnr_db),
        "llr": num(s.llr),
        "stoi": num(s.stoi),
        "lag_samples": lag,
        "gain": num(gain),
        "sample_rate_hz": fr,
    });
    println!("{}", serde_json::to_string_pretty(&v)?);
    Ok(ExitCode::SUCCESS)
}

/// The visual-microphone pipeline set up for `listen`.
/// Adds a `speaker` sink fed by whatever feeds the `out` sink (fan-out:
/// the WAV and the speaker get the same blocks).
fn add_speaker(decl: &mut PipelineDecl, device: &str) -> anyhow::Result<()> {
    let Some(out) = decl.stages.iter().position(|s| s.id == "out") else {
        anyhow::bail!("the pipeline has no stage `out` to play alongside");
    };
    let origin = Origin::Set(format!("--speaker {device}"));
    let mut st = decl.stages[out].clone();
    st.id = "speaker".into();
    st.kind = "speaker".into();
    st.kind_origin = origin.clone();
    st.params.clear();
    set_param(
        &mut st,
        "device",
        toml::Value::String(device.into()),
        origin,
    );
    decl.stages.push(st);
    Ok(())
}

fn listen_pipeline(
    video: &Path,
    output: &Path,
    fps: Option<f64>,
    roi: Option<&str>,
    denoise: DenoiseArg,
    pyramid: PyramidArg,
) -> anyhow::Result<PipelineDecl> {
    let mut decl = prepare("visual-microphone", &[], Some(video), fps)?;
    let origin = |what: &str| Origin::Set(what.to_string());
    let find = |decl: &mut PipelineDecl, id: &str| decl.stages.iter().position(|s| s.id == id);
    let (Some(out), Some(phase), Some(hp)) = (
        find(&mut decl, "out"),
        find(&mut decl, "phase"),
        find(&mut decl, "highpass"),
    ) else {
        anyhow::bail!(
            "the shipped visual-microphone pipeline lacks a stage `out`, `phase` or `highpass`"
        );
    };
    set_param(
        &mut decl.stages[out],
        "path",
        toml::Value::String(output.display().to_string()),
        origin("-o"),
    );
    let pyr = match pyramid {
        PyramidArg::Csp => "csp",
        PyramidArg::Riesz => "riesz",
    };
    set_param(
        &mut decl.stages[phase],
        "pyramid",
        toml::Value::String(pyr.into()),
        origin("--pyramid"),
    );
    if let Some(r) = roi {
        let parts: Vec<Result<i64, _>> = r.split(',').map(|v| v.trim().parse::<i64>()).collect();
        let vals: Vec<i64> = match parts.into_iter().collect::<Result<Vec<_>, _>>() {
            Ok(v) if v.len() == 4 && v.iter().all(|&x| x >= 0) => v,
            _ => {
                return Err(cfg_error(
                    "--roi",
                    format!("expected X,Y,W,H (four whole numbers >= 0), got `{r}`"),
                )
                .into())
            }
        };
        let arr = toml::Value::Array(vals.into_iter().map(toml::Value::Integer).collect());
        set_param(
            &mut decl.stages[phase],
            "roi",
            arr,
            origin(&format!("--roi {r}")),
        );
    }
    let kind = match denoise {
        DenoiseArg::None => None,
        DenoiseArg::Subtract => Some("spectral_subtraction"),
        DenoiseArg::Enhance => Some("speech_enhance"),
    };
    if let Some(kind) = kind {
        let mut st = decl.stages[hp].clone();
        st.id = "denoise".into();
        st.kind = kind.into();
        st.kind_origin = origin("--denoise");
        st.params.clear();
        st.inputs = vec![config::InputDecl {
            from: "highpass".into(),
            capacity: None,
            policy: None,
            origin: origin("--denoise"),
        }];
        decl.stages.insert(hp + 1, st);
        if let Some(o) = find(&mut decl, "out") {
            for inp in &mut decl.stages[o].inputs {
                inp.from = "denoise".into();
            }
        }
    }
    Ok(decl)
}

fn devices() -> anyhow::Result<ExitCode> {
    let list = stages::sources::v4l2::list_devices().map_err(|m| anyhow::anyhow!(m))?;
    if list.is_empty() {
        eprintln!("no camera found (no V4L2 video capture device among /dev/video*)");
        return Ok(ExitCode::from(1));
    }
    for d in list {
        print!("{d}");
    }
    Ok(ExitCode::SUCCESS)
}

/// What `vibroscope record` was asked.
pub struct RecordArgs {
    pub device: PathBuf,
    pub output: PathBuf,
    pub seconds: Option<f64>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub fps: Option<f64>,
    pub format: String,
    pub stats: bool,
}

/// The pipeline `record` runs: a `v4l2` source `cam` into a `y4m` sink `rec`.
pub fn record_pipeline(a: &RecordArgs) -> Result<PipelineDecl, ConfigError> {
    let q = |s: String| toml::Value::String(s).to_string();
    let mut cam = format!(
        "[[stage]]\nid = \"cam\"\nkind = \"v4l2\"\ndevice = {}\nformat = {}\n",
        q(a.device.display().to_string()),
        q(a.format.clone())
    );
    for (k, v) in [("width", a.width), ("height", a.height)] {
        if let Some(v) = v {
            cam += &format!("{k} = {v}\n");
        }
    }
    let float = |v: f64| toml::Value::Float(v).to_string();
    if let Some(f) = a.fps {
        cam += &format!("fps = {}\n", float(f));
    }
    if let Some(s) = a.seconds {
        cam += &format!("duration_s = {}\n", float(s));
    }
    let text = format!(
        "[pipeline]\nname = \"record\"\n\n{cam}\n[[stage]]\nid = \"rec\"\nkind = \"y4m\"\ninput = \"cam\"\npath = {}\n",
        q(a.output.display().to_string())
    );
    config::parse("record", &text)
}

fn record(a: &RecordArgs) -> anyhow::Result<ExitCode> {
    let decl = record_pipeline(a)?;
    let (code, report) = run_decl(&decl, a.stats, true)?;
    let stage = |id: &str| report.stages.iter().find(|s| s.id == id);
    let (Some(cam), Some(rec)) = (stage("cam"), stage("rec")) else {
        return Ok(code);
    };
    let frames = rec.items_in;
    let what = if a.output.as_os_str() == "-" || frames == 0 {
        String::new()
    } else {
        match io::open(&a.output, io::Format::Y4m) {
            Ok(r) => {
                let i = r.info();
                format!(
                    " of {}x{} at {} fps",
                    i.width,
                    i.height,
                    i.fps.unwrap_or(f64::NAN)
                )
            }
            Err(e) => format!(" (cannot read it back: {e})"),
        }
    };
    // Frames lost: sequence gaps at the device, and frames the recorder's
    // queue evicted because the disk fell behind (drop-oldest).
    eprintln!(
        "recorded {frames} frames{what} to {}; dropped {} (device {}, queue {})",
        a.output.display(),
        cam.dropped + rec.dropped,
        cam.dropped,
        rec.dropped
    );
    Ok(code)
}

// ---------------------------------------------------------------------------
// Rolling shutter (issue 4): `listen --rolling-shutter` and `rs-calibrate`.
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum FillArg {
    Ar,
    Linear,
}

/// `listen` options for rolling-shutter recordings (thesis ch. 4.5).
#[derive(clap::Args, Debug, Clone)]
struct RollingArgs {
    /// One sample per image row instead of per frame: hears far above the
    /// frame rate (needs --line-delay-us).
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
    /// Resample the output to this rate in Hz (needs --exposure-us); default 1/d.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    rate: Option<f64>,
}

impl RollingArgs {
    /// Rolling-shutter options without --rolling-shutter are a usage error.
    fn check_unused(&self) -> anyhow::Result<()> {
        let used = [
            ("--line-delay-us", self.line_delay_us.is_some()),
            ("--frame-delay-us", self.frame_delay_us.is_some()),
            ("--exposure-us", self.exposure_us.is_some()),
            ("--compensate-exposure", self.compensate_exposure),
            ("--rate", self.rate.is_some()),
        ];
        match used.iter().find(|(_, u)| *u) {
            Some((flag, _)) => Err(cfg_error(flag, "needs --rolling-shutter".into()).into()),
            None => Ok(()),
        }
    }
}

/// The shipped rolling-shutter pipeline replayed on `video` with the
/// camera's timing from the command line.
fn rs_listen_pipeline(
    video: &Path,
    output: &Path,
    fps: Option<f64>,
    roi: Option<&str>,
    a: &RollingArgs,
) -> anyhow::Result<PipelineDecl> {
    let mut decl = prepare("rolling-shutter", &[], Some(video), fps)?;
    let set = |decl: &mut PipelineDecl, id: &str, key: &str, v: toml::Value, flag: String| {
        if let Some(st) = decl.stages.iter_mut().find(|s| s.id == id) {
            set_param(st, key, v, Origin::Set(flag));
        }
    };
    let Some(d) = a.line_delay_us else {
        return Err(cfg_error(
            "--line-delay-us",
            "required with --rolling-shutter (estimate it with `vibroscope rs-calibrate`)".into(),
        )
        .into());
    };
    set(
        &mut decl,
        "rows",
        "line_delay_us",
        toml::Value::Float(d),
        format!("--line-delay-us {d}"),
    );
    if let Some(g) = a.frame_delay_us {
        set(
            &mut decl,
            "rows",
            "frame_delay_us",
            toml::Value::Float(g),
            format!("--frame-delay-us {g}"),
        );
    }
    // The shipped region is the simulator's object: a recording starts from the whole frame.
    if let Some(st) = decl.stages.iter_mut().find(|s| s.id == "rows") {
        st.params.retain(|p| p.key != "roi");
    }
    if let Some(r) = roi {
        let v = parse_roi_arg(r)?;
        let arr = toml::Value::Array(v.iter().map(|&x| toml::Value::Integer(x)).collect());
        set(&mut decl, "rows", "roi", arr, format!("--roi {r}"));
    }
    let method = match a.fill {
        FillArg::Ar => "ar",
        FillArg::Linear => "linear",
    };
    set(
        &mut decl,
        "fill",
        "method",
        toml::Value::String(method.into()),
        "--fill".into(),
    );
    match a.exposure_us {
        Some(e) => {
            set(
                &mut decl,
                "exposure",
                "exposure_us",
                toml::Value::Float(e),
                format!("--exposure-us {e}"),
            );
            if a.compensate_exposure {
                let v = toml::Value::String("compensate".into());
                set(
                    &mut decl,
                    "exposure",
                    "mode",
                    v,
                    "--compensate-exposure".into(),
                );
            }
            if let Some(r) = a.rate {
                set(
                    &mut decl,
                    "exposure",
                    "rate_hz",
                    toml::Value::Float(r),
                    format!("--rate {r}"),
                );
            }
        }
        None => {
            if a.compensate_exposure || a.rate.is_some() {
                let flag = if a.rate.is_some() {
                    "--rate"
                } else {
                    "--compensate-exposure"
                };
                return Err(cfg_error(flag, "needs --exposure-us".into()).into());
            }
            eprintln!("note: no --exposure-us: the output is not band-limited to the exposure's first null");
            decl.stages.retain(|s| s.id != "exposure");
            for s in decl.stages.iter_mut().filter(|s| s.id == "out") {
                for inp in &mut s.inputs {
                    inp.from = "fill".into();
                }
            }
        }
    }
    if let Some(st) = decl.stages.iter_mut().find(|s| s.id == "out") {
        let v = toml::Value::String(output.display().to_string());
        set_param(st, "path", v, Origin::Set("-o".into()));
    }
    Ok(decl)
}

/// `X,Y,W,H` as four whole numbers >= 0.
pub(crate) fn parse_roi_arg(r: &str) -> Result<Vec<i64>, ConfigError> {
    let v: Result<Vec<i64>, _> = r.split(',').map(|v| v.trim().parse::<i64>()).collect();
    match v {
        Ok(v) if v.len() == 4 && v.iter().all(|&x| x >= 0) => Ok(v),
        _ => Err(cfg_error(
            "--roi",
            format!("expected X,Y,W,H (four whole numbers >= 0), got `{r}`"),
        )),
    }
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum CalSignal {
    /// Horizontal motion of each row (a vibrating textured object).
    Motion,
    /// Mean brightness of each row (a flickering light).
    Intensity,
}

/// Arguments of `vibroscope rs-calibrate`.
#[derive(clap::Args, Debug, Clone)]
struct RsCalibrateArgs {
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
    signal: CalSignal,
    /// Region used: X,Y,W,H (default: the whole frame).
    #[arg(long, value_name = "X,Y,W,H")]
    roi: Option<String>,
    /// Frames read at most.
    #[arg(long, default_value_t = 300)]
    max_frames: usize,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

fn rs_calibrate(a: &RsCalibrateArgs) -> anyhow::Result<ExitCode> {
    use crate::math::row_phase::RowPhase;
    use crate::math::rs_calibrate::{estimate, remove_row_means};
    if !(a.tone_hz.is_finite() && a.tone_hz > 0.0) {
        return Err(cfg_error("--tone-hz", format!("must be > 0 Hz, got {}", a.tone_hz)).into());
    }
    if let Some(f) = a.fps {
        stages::sources::check_fps(f).map_err(|m| cfg_error("--fps", m))?;
    }
    let mut reader = io::open(&a.video, io::Format::Auto)?;
    let info = reader.info().clone();
    let fps = a.fps.or(info.fps).ok_or_else(|| {
        cfg_error(
            "--fps",
            format!(
                "{}: the file states no frame rate; pass --fps",
                a.video.display()
            ),
        )
    })?;
    let (w, h) = (info.width as usize, info.height as usize);
    let (x, y, rw, rh) = match &a.roi {
        Some(r) => {
            let v = parse_roi_arg(r)?;
            let (x, y, rw, rh) = (v[0] as usize, v[1] as usize, v[2] as usize, v[3] as usize);
            if rw == 0 || rh < 8 || x + rw > w || y + rh > h {
                return Err(cfg_error(
                    "--roi",
                    format!("`{r}` does not fit a {w}x{h} frame (at least 8 rows)"),
                )
                .into());
            }
            (x, y, rw, rh)
        }
        None => (0, 0, w, h),
    };
    let mut rp = match a.signal {
        CalSignal::Motion => Some(
            RowPhase::new(w, x, x + rw, rh, &[8.0, 16.0])
                .map_err(|m| cfg_error("--roi", m.to_string()))?,
        ),
        CalSignal::Intensity => None,
    };
    let mut buf8 = vec![0u8; w * h];
    let mut buf16 = vec![0u16; w * h];
    let mut line = vec![0.0f32; w];
    let mut frames: Vec<Vec<f64>> = Vec::new();
    for n in 0..a.max_frames {
        let dst = match info.depth {
            io::Depth::U8 => io::FrameDest::U8(&mut buf8),
            io::Depth::U16 => io::FrameDest::U16(&mut buf16),
        };
        if reader.read_frame(dst)?.is_none() {
            break;
        }
        let mut rows = Vec::with_capacity(rh);
        for i in 0..rh {
            let s = (y + i) * w;
            match info.depth {
                io::Depth::U8 => line
                    .iter_mut()
                    .zip(&buf8[s..s + w])
                    .for_each(|(o, &v)| *o = v as f32),
                io::Depth::U16 => line
                    .iter_mut()
                    .zip(&buf16[s..s + w])
                    .for_each(|(o, &v)| *o = v as f32),
            }
            let v = match rp.as_mut() {
                Some(rp) if n == 0 => {
                    rp.set_reference(i, &line);
                    0.0
                }
                Some(rp) => rp.displacement(i, &line),
                None => line[x..x + rw].iter().map(|&v| v as f64).sum::<f64>() / rw as f64,
            };
            rows.push(v);
        }
        // The motion reference frame reads zero everywhere: leave it out.
        if rp.is_none() || n > 0 {
            frames.push(rows);
        }
    }
    if frames.len() < 2 {
        anyhow::bail!(
            "{}: need at least 3 frames, got {}",
            a.video.display(),
            frames.len() + 1
        );
    }
    remove_row_means(&mut frames);
    let period = 1.0 / fps;
    let est = estimate(&frames, a.tone_hz, period / h as f64).ok_or_else(|| {
        anyhow::anyhow!(
            "{}: cannot fit: the tone must make at least a quarter cycle during the readout of {rh} rows",
            a.video.display()
        )
    })?;
    let d = est.line_delay_s;
    let gap = (period - h as f64 * d).max(0.0);
    if a.json {
        let v = serde_json::json!({
            "line_delay_us": d * 1e6,
            "frame_delay_us": gap * 1e6,
            "rows": h,
            "fps": fps,
            "row_rate_hz": 1.0 / d,
            "missing_fraction": gap / period,
            "explained": est.explained,
            "frames": frames.len(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "line delay:   {:.3} us  (one sample per row: {:.0} Hz)",
            d * 1e6,
            1.0 / d
        );
        println!(
            "frame delay:  {:.3} us  (frame period {:.3} ms, {h} rows: {:.1}% of the time unseen)",
            gap * 1e6,
            period * 1e3,
            100.0 * gap / period
        );
        println!(
            "fit:          the {} Hz tone explains {:.0}% of the per-row signal ({} frames)",
            a.tone_hz,
            100.0 * est.explained,
            frames.len()
        );
    }
    if est.explained < 0.1 {
        eprintln!(
            "warning: weak fit; check --tone-hz, and that the tone is not a multiple of the frame rate"
        );
    }
    Ok(ExitCode::SUCCESS)
}

// ---------------------------------------------------------------- simulate

/// `vibroscope simulate`: the shipped `render` pipeline with its camera's
/// parameters replaced by the scene file's (one code path with the
/// `synthetic` source; validation names the file and the field).
pub fn simulate(
    scene: &Path,
    output: &Path,
    set: &[String],
    stats: bool,
) -> anyhow::Result<ExitCode> {
    let text = std::fs::read_to_string(scene)
        .map_err(|e| cfg_error(&scene.display().to_string(), format!("cannot read: {e}")))?;
    let table: toml::Table = toml::from_str(&text)
        .map_err(|e| cfg_error(&scene.display().to_string(), format!("{e}")))?;
    let mut decl = load("render")?;
    let Some(cam) = decl.stages.iter_mut().find(|s| s.id == "cam") else {
        anyhow::bail!("the shipped render pipeline has no stage `cam`");
    };
    cam.params.clear();
    for (k, v) in table {
        // Name the scene file and the key's line in errors.
        let line = text
            .lines()
            .position(|l| {
                l.trim_start()
                    .strip_prefix(k.as_str())
                    .is_some_and(|r| r.trim_start().starts_with('='))
            })
            .map_or(String::new(), |i| format!(":{}", i + 1));
        let origin = Origin::Builtin(format!("scene {}{line}", scene.display()));
        set_param(cam, &k, v, origin);
    }
    for s in set {
        apply_set(&mut decl, &format!("cam.{s}"))?;
    }
    if let Some(out) = decl.stages.iter_mut().find(|s| s.id == "out") {
        set_param(
            out,
            "path",
            toml::Value::String(output.display().to_string()),
            Origin::Set("-o".into()),
        );
    }
    let (code, _) = run_decl(&decl, stats, output != Path::new("-"))?;
    if code == ExitCode::SUCCESS && output != Path::new("-") {
        eprintln!("wrote {}", output.display());
    }
    Ok(code)
}

// ---------------------------------------------------------------------------
// Spectra and damping (issue 5): `vibroscope spectrum`.
// ---------------------------------------------------------------------------

/// Arguments of `vibroscope spectrum`.
#[derive(clap::Args, Clone)]
pub(crate) struct SpectrumArgs {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    pub(crate) video: PathBuf,
    /// Output JSON: sample_rate_hz, resolution_hz and the peaks.
    #[arg(long, value_name = "OUT.json")]
    pub(crate) json: PathBuf,
    /// Capture frame rate in Hz (containers often state the playback rate).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub(crate) fps: Option<f64>,
    /// Report at most this many peaks (the most prominent).
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub(crate) peaks: usize,
    /// Region of the object: X,Y,W,H in pixels (default: the whole frame).
    #[arg(long, value_name = "X,Y,W,H")]
    pub(crate) roi: Option<String>,
    /// Region as an image the size of the frame (PGM or PNG; pixels > 0
    /// count); with --roi, the overlap of both.
    #[arg(long, value_name = "FILE")]
    pub(crate) mask: Option<PathBuf>,
    /// Welch segments over the recording (more: less noise, coarser bins;
    /// default one per 2048 frames, 1 to 64).
    #[arg(long, value_name = "K")]
    pub(crate) segments: Option<usize>,
    /// Segment length in frames instead of --segments (even).
    #[arg(long, value_name = "FRAMES")]
    pub(crate) window: Option<usize>,
    /// Only peaks in this band (Hz).
    #[arg(long, value_name = "HZ")]
    pub(crate) min_hz: Option<f64>,
    #[arg(long, value_name = "HZ")]
    pub(crate) max_hz: Option<f64>,
    /// Also write the spectrum (dB) into the JSON.
    #[arg(long)]
    pub(crate) include_spectrum: bool,
    /// Pyramid: complex steerable (quality) or Riesz (speed).
    #[arg(long, value_enum, default_value = "csp")]
    pub(crate) pyramid: PyramidArg,
    /// Also plot the spectrum (dB, peaks marked) to this PNG.
    #[arg(long, value_name = "OUT.png")]
    pub(crate) png: Option<PathBuf>,
    /// Also plot sliding spectra over time (a spectrogram) to this PNG.
    #[arg(long, value_name = "OUT.png")]
    pub(crate) spectrogram: Option<PathBuf>,
    /// The spectrogram's window in frames (hop: an eighth of it).
    #[arg(long, value_name = "FRAMES", default_value_t = SPECTROGRAM_WINDOW)]
    pub(crate) spectrogram_window: usize,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    pub(crate) stats: bool,
    /// Keep the extracted motion (bands aligned and summed) that the
    /// time-domain damping (SSI-cov) ran on, as a WAV.
    #[arg(long, value_name = "OUT.wav")]
    pub(crate) motion_wav: Option<PathBuf>,
}

/// The shipped live-spectrum graph on a recording, with one
/// whole-recording spectrum (finest resolution) feeding the peak picker.
pub(crate) fn spectrum_pipeline(a: &SpectrumArgs) -> anyhow::Result<PipelineDecl> {
    let mut decl = prepare("live-spectrum", &[], Some(&a.video), a.fps)?;
    let pos = |decl: &PipelineDecl, id: &str| decl.stages.iter().position(|s| s.id == id);
    let (Some(phase), Some(spec), Some(out)) = (
        pos(&decl, "phase"),
        pos(&decl, "spectrum"),
        pos(&decl, "out"),
    ) else {
        anyhow::bail!(
            "the shipped live-spectrum pipeline lacks a stage `phase`, `spectrum` or `out`"
        );
    };
    let o = |s: &str| Origin::Set(s.to_string());
    let st = &mut decl.stages[phase];
    let pyr = match a.pyramid {
        PyramidArg::Csp => "csp",
        PyramidArg::Riesz => "riesz",
    };
    set_param(
        st,
        "pyramid",
        toml::Value::String(pyr.into()),
        o("--pyramid"),
    );
    set_param(st, "scales", toml::Value::Integer(4), o("spectrum"));
    set_param(st, "block", toml::Value::Integer(64), o("spectrum"));
    if let Some(r) = &a.roi {
        let v = parse_roi_arg(r)?;
        let arr = toml::Value::Array(v.into_iter().map(toml::Value::Integer).collect());
        set_param(st, "roi", arr, o(&format!("--roi {r}")));
    }
    if let Some(m) = &a.mask {
        let v = toml::Value::String(m.display().to_string());
        set_param(st, "mask", v, o(&format!("--mask {}", m.display())));
    }
    let st = &mut decl.stages[spec];
    st.params
        .retain(|p| !matches!(p.key.as_str(), "window" | "hop" | "welch"));
    set_param(
        st,
        "mode",
        toml::Value::String("whole".into()),
        o("spectrum"),
    );
    if let Some(k) = a.segments {
        let k = i64::try_from(k).unwrap_or(i64::MAX);
        set_param(st, "segments", toml::Value::Integer(k), o("--segments"));
    }
    if let Some(w) = a.window {
        let w = i64::try_from(w).unwrap_or(i64::MAX);
        set_param(st, "window", toml::Value::Integer(w), o("--window"));
    }
    let st = &mut decl.stages[out];
    let path = toml::Value::String(a.json.display().to_string());
    set_param(st, "path", path, o("--json"));
    let n = i64::try_from(a.peaks).unwrap_or(i64::MAX);
    set_param(st, "peaks", toml::Value::Integer(n), o("--peaks"));
    for (key, v) in [("min_hz", a.min_hz), ("max_hz", a.max_hz)] {
        if let Some(f) = v {
            set_param(
                st,
                key,
                toml::Value::Float(f),
                o(&format!("--{}", key.replace('_', "-"))),
            );
        }
    }
    if a.include_spectrum {
        set_param(
            st,
            "include_spectrum",
            toml::Value::Boolean(true),
            o("--include-spectrum"),
        );
    }
    let plots = plots::PlotArgs {
        png: a.png.as_deref(),
        spectrogram: a.spectrogram.as_deref(),
        window: a.spectrogram_window,
        peaks: a.peaks,
        min_hz: a.min_hz,
        max_hz: a.max_hz,
    };
    plots::add_plots(&mut decl, &plots)?;
    Ok(decl)
}

/// The spectrogram's default window in frames (`spectrum --spectrogram-window`).
pub(crate) const SPECTROGRAM_WINDOW: usize = 256;

fn spectrum_cmd(a: &SpectrumArgs) -> anyhow::Result<ExitCode> {
    let mut decl = spectrum_pipeline(a)?;
    let tap = crate::vibrometry::damping::MotionTap::add(&mut decl, a.motion_wav.clone())?;
    let (code, _) = run_decl(&decl, a.stats, false)?;
    if code == ExitCode::SUCCESS {
        tap.refine(&a.json, &Default::default())?;
        for p in [Some(&a.json), a.png.as_ref(), a.spectrogram.as_ref()]
            .into_iter()
            .flatten()
        {
            eprintln!("wrote {}", p.display());
        }
    }
    Ok(code)
}
