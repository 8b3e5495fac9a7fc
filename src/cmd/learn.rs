//! `vibroscope learn`: material properties from motion spectra (thesis 5.5).

use super::{num, VideoArgs};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vibroscope::learn::generate::{self, GenerateOptions};
use vibroscope::learn::model::Method;
use vibroscope::learn::{self, EvaluateOptions, FitOptions, PredictOptions, SceneMeasure};
use vibroscope::pipeline::RunSettings;

/// Learn material properties (stiffness, area weight) from motion spectra.
///
/// Thesis 5.5: the feature vector is N = 150 samples of the normalised,
/// Gaussian-smoothed global motion spectrum from 0 to 15 Hz; PLSR (or PCR)
/// maps it to the logs of the properties; leave-one-object-out
/// cross-validation chooses the number of components and measures Pearson
/// R, mean % error and Kendall tau. Features are cached beside each video
/// or scene file (VIDEO.features.json). See docs/learning.md.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  \
    vibroscope learn generate -o fabrics --materials 30\n  \
    vibroscope learn fit fabrics/DATASET.toml -o fabric-model.json --condition A/L\n  \
    vibroscope learn predict fabric-model.json fabrics/scenes/m000-AL-0.toml\n  \
    vibroscope learn evaluate fabrics/DATASET.toml --train-on A/L --test-on S/R --png corr.png")]
pub struct Args {
    #[command(subcommand)]
    cmd: Sub,
}

#[derive(clap::Subcommand)]
enum Sub {
    Generate(GenerateArgs),
    Fit(FitArgs),
    Predict(PredictArgs),
    Evaluate(EvaluateArgs),
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum MethodArg {
    Pls,
    Pcr,
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum SoundArg {
    Kick,
    Chirp,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Method {
        match m {
            MethodArg::Pls => Method::Pls,
            MethodArg::Pcr => Method::Pcr,
        }
    }
}

/// Render a dataset of simulated hanging fabrics with known properties.
///
/// Fabrics spread over bending rigidity 1e-6..1e-4 N m and area weight
/// 30..400 g/m^2; conditions A/S (ambient air, sound) x L/R (viewpoints).
/// Writes DIR/scenes/*.toml (one per take), DIR/DATASET.toml and the
/// feature cache. The dataset lists the scenes, which fit, evaluate and
/// predict render in memory (the same frames `vibroscope simulate` writes);
/// --videos also writes each take as DIR/videos/*.y4m and lists those.
/// Each take is listed with its region (`roi`, the cloth's rectangle);
/// give it to `learn predict --roi` too.
#[derive(clap::Args)]
struct GenerateArgs {
    /// Output directory.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Number of fabrics (stiffness needs many: with 30 even perfect
    /// measurement reaches R 0.92-0.94, with 60 0.98; docs/learning.md).
    #[arg(long, default_value_t = GenerateOptions::default().materials)]
    materials: usize,
    /// Takes per fabric per condition.
    #[arg(long, default_value_t = GenerateOptions::default().per_condition)]
    per_condition: usize,
    /// Conditions to film (comma-separated; A/L, A/R, S/L, S/R).
    #[arg(long, value_delimiter = ',', default_value = "A/L,A/R,S/L,S/R")]
    conditions: Vec<String>,
    /// Length of each video, s (the thesis's were about a minute).
    #[arg(long, default_value_t = GenerateOptions::default().seconds)]
    seconds: f64,
    /// Frame side, px (fewer pixels: a higher noise floor, which hides the
    /// upper modes where stiffness shows).
    #[arg(long, default_value_t = GenerateOptions::default().size)]
    size: u32,
    #[arg(long, default_value_t = GenerateOptions::default().seed)]
    seed: u64,
    /// Welch segments of each spectrum (the dataset's [features] segments;
    /// 16 over 60 s: 7 s segments, 0.14 Hz bins).
    #[arg(long, default_value_t = GenerateOptions::default().segments)]
    segments: usize,
    /// Also write every take as a Y4M video and list the videos in the
    /// dataset (at the defaults about 40-50 MB each, 32 GB for all 720).
    #[arg(long)]
    videos: bool,
    /// What the S conditions play. kick: the thesis's (5.5), ambient air
    /// throughout plus a one-second 15-100 Hz logarithmic sweep at a random
    /// time; chirp: a stationary 0.3-20 Hz logarithmic chirp alone.
    #[arg(long, value_enum, default_value = "kick")]
    sound: SoundArg,
    /// The kick's motion power over the ambient air's, dB, over the
    /// forcing's 50 s period (about a 60 s take; docs/learning.md: what
    /// the level changes).
    #[arg(long, default_value_t = GenerateOptions::default().kick_db, allow_hyphen_values = true)]
    kick_db: f64,
    /// Write the scenes and DATASET.toml only: the features are measured
    /// (and cached) when fit or evaluate first need them, and evaluate
    /// --exact (the bound) and --true-motion need none.
    #[arg(long, conflicts_with = "videos")]
    no_features: bool,
}

/// Fit a model on a dataset (components by leave-one-object-out CV).
#[derive(clap::Args)]
struct FitArgs {
    /// The dataset file (TOML; see docs/learning.md).
    dataset: PathBuf,
    /// The model file to write (JSON).
    #[arg(short, long, value_name = "MODEL.json")]
    output: PathBuf,
    #[arg(long, value_enum, default_value = "pls")]
    method: MethodArg,
    /// Train on these conditions only (comma-separated; default all); only
    /// their videos are measured.
    #[arg(long, value_delimiter = ',')]
    condition: Vec<String>,
    /// Try 1..=N components.
    #[arg(long, default_value_t = 10)]
    max_components: usize,
    /// Use exactly this many components.
    #[arg(long)]
    components: Option<usize>,
}

/// Predict the properties of a video (or a spectrum JSON) with a model.
#[derive(clap::Args)]
struct PredictArgs {
    /// The model file (from `learn fit`).
    model: PathBuf,
    /// A video, a scene file (.toml, rendered in memory), or a spectrum
    /// JSON written with `spectrum --include-spectrum`.
    input: PathBuf,
    #[command(flatten)]
    video: VideoArgs,
    /// Also write the prediction as JSON.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
}

/// Train on one condition, test on another (Table 5.3), leave-one-object-out.
///
/// Only the videos of the conditions asked are measured (the others'
/// features are neither computed nor needed).
#[derive(clap::Args)]
struct EvaluateArgs {
    dataset: PathBuf,
    /// Training conditions (comma-separated; default all).
    #[arg(long, value_delimiter = ',')]
    train_on: Vec<String>,
    /// Test conditions (comma-separated; default all).
    #[arg(long, value_delimiter = ',')]
    test_on: Vec<String>,
    /// Largest number of components tried (chosen on the training condition).
    #[arg(long, default_value_t = 10)]
    max_components: usize,
    /// Learn from each video's expected spectrum instead (computed from
    /// the scene file `learn generate` wrote: no texture, sensor, pyramid
    /// or estimation noise): the bound perfect measurement would reach.
    #[arg(long)]
    exact: bool,
    /// Learn from each take's true motion instead (the cloth's parts'
    /// mean displacement, every frame, from the scene file `learn
    /// generate` wrote, through the videos' spectral estimator: no
    /// texture, sensor or pyramid): what one take of its length holds.
    #[arg(long, conflicts_with = "exact")]
    true_motion: bool,
    /// Correlation plot of the PLSR predictions (Fig. 5-10).
    #[arg(long, value_name = "OUT.png")]
    png: Option<PathBuf>,
    /// Everything as JSON.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
}

fn labelled(bar: &Option<super::Bar>) -> impl FnMut(usize, usize, &Path) + '_ {
    move |i, n, p| {
        if let Some(b) = bar {
            let name = p.file_name().map(|s| s.to_string_lossy().into_owned());
            b.set_prefix(format!("{}/{} {} ", i + 1, n, name.unwrap_or_default()));
        }
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let run = RunSettings { progress: true };
    match a.cmd {
        Sub::Generate(g) => {
            let o = GenerateOptions {
                dir: g.output,
                materials: g.materials,
                per_condition: g.per_condition,
                conditions: g.conditions,
                seconds: g.seconds,
                size: g.size,
                seed: g.seed,
                segments: g.segments,
                videos: g.videos,
                sound: match g.sound {
                    SoundArg::Kick => generate::Sound::Kick,
                    SoundArg::Chirp => generate::Sound::Chirp,
                },
                kick_db: g.kick_db,
                measure: !g.no_features,
                run,
            };
            let bar = super::Bar::start(true);
            let r = generate::generate(&o, &mut labelled(&bar));
            drop(bar);
            let takes = if o.videos { "videos" } else { "scenes" };
            eprintln!(
                "wrote {} (its takes are the {takes} in {})",
                r?.display(),
                o.dir.join(takes).display()
            );
        }
        Sub::Fit(f) => {
            let o = FitOptions {
                dataset: f.dataset,
                output: f.output,
                method: f.method.into(),
                conditions: f.condition,
                max_components: f.max_components,
                components: f.components,
                run,
            };
            let bar = super::Bar::start(true);
            let r = learn::fit(&o, &mut labelled(&bar));
            drop(bar);
            let m = r?;
            println!(
                "one model per property, on {} videos of {} objects ({}); leave-one-object-out:",
                m.videos,
                m.objects,
                m.conditions.join(", ")
            );
            for tm in &m.models {
                let c = &tm.cv;
                println!(
                    "  {:<5} {:>2} comp.  {:<20} R {} (fabric means {})  error {}%  tau {}",
                    tm.model.method.name(),
                    tm.model.components,
                    tm.target,
                    num(c.r, 3),
                    num(c.r_objects, 3),
                    num(c.pct_error, 1),
                    num(c.kendall_tau, 3)
                );
            }
            eprintln!("wrote {}", o.output.display());
        }
        Sub::Predict(p) => {
            let o = PredictOptions {
                model: p.model,
                input: p.input,
                fps: p.video.fps,
                region: p.video.region(),
                json: p.json,
                run,
            };
            let bar = super::Bar::start(true);
            let r = learn::predict(&o);
            drop(bar);
            let r = r?;
            for pp in &r.properties {
                println!(
                    "{:<20} {:.4e}  (95% interval {:.4e} .. {:.4e})  T2 {} (limit {}), Q {} (limit {}){}",
                    pp.name,
                    pp.value,
                    pp.low,
                    pp.high,
                    num(pp.t2, 2),
                    num(pp.t2_limit, 2),
                    num(pp.q, 4),
                    num(pp.q_limit, 4),
                    if pp.out_of_distribution {
                        ": OUTSIDE the training distribution, not to be trusted"
                    } else {
                        ""
                    }
                );
            }
            if let Some(j) = &o.json {
                eprintln!("wrote {}", j.display());
            }
        }
        Sub::Evaluate(e) => {
            let o = EvaluateOptions {
                dataset: e.dataset,
                train_on: e.train_on,
                test_on: e.test_on,
                methods: vec![Method::Pls, Method::Pcr],
                max_components: e.max_components,
                from: if e.exact {
                    Some(SceneMeasure::Expected)
                } else if e.true_motion {
                    Some(SceneMeasure::TrueMotion)
                } else {
                    None
                },
                png: e.png,
                json: e.json,
                run,
            };
            let bar = super::Bar::start(true);
            let r = learn::evaluate(&o, &mut labelled(&bar));
            drop(bar);
            let r = r?;
            let all = |v: &Vec<String>| {
                if v.is_empty() {
                    "all".to_string()
                } else {
                    v.join(",")
                }
            };
            println!(
                "train on {}, test on {} ({} objects, {} test videos), leave-one-object-out{}",
                all(&r.train_on),
                all(&r.test_on),
                r.objects,
                r.test_videos,
                match o.from {
                    Some(SceneMeasure::Expected) => ", exact expected spectra (the bound)",
                    Some(SceneMeasure::TrueMotion) =>
                        ", the takes' true motion (no texture, sensor or pyramid)",
                    None => "",
                }
            );
            for m in &r.methods {
                for (k, (t, c)) in r.targets.iter().zip(&m.metrics).enumerate() {
                    println!(
                        "  {:<5} {:>2} comp.  {t:<20} R {} (fabric means {})  error {}%  tau {}",
                        m.method.name(),
                        m.components[k],
                        num(c.r, 3),
                        num(c.r_objects, 3),
                        num(c.pct_error, 1),
                        num(c.kendall_tau, 3)
                    );
                }
            }
            for w in &r.written {
                eprintln!("wrote {}", w.display());
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
