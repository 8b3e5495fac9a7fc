//! One module per command: clap arguments → options → recipe → print.
//! Shared here: the video flags, messages and the progress bar.

pub mod bound;
pub mod calibrate;
pub mod compare;
pub mod demo;
pub mod devices;
pub mod idv;
pub mod kinds;
pub mod learn;
pub mod listen;
pub mod magnify;
pub mod modes;
#[cfg(feature = "net")]
pub mod monitor;
pub mod pipelines;
pub mod pitch;
pub mod probe;
pub mod record;
pub mod rod;
pub mod rs_calibrate;
pub mod run;
pub mod score;
pub mod simulate;
pub mod spectrum;
pub mod studio;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use vibroscope::pipeline::{Pyramid, Region, Roi};
use vibroscope::units::{KnownLength, ScaleArg};

/// The first error writing to stdout; later output is dropped.
static STDOUT_ERROR: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Writes to stdout and flushes; never panics. A closed pipe (`| head -1`)
/// or a full device is recorded and later output dropped, so the command
/// still does the rest of its work (its files); `main` reports it.
pub fn write_stdout(args: std::fmt::Arguments) {
    let Ok(mut failed) = STDOUT_ERROR.lock() else {
        return;
    };
    if failed.is_some() {
        return;
    }
    let mut o = std::io::stdout().lock();
    if let Err(e) = o.write_fmt(args).and_then(|()| o.flush()) {
        *failed = Some(e);
    }
}

/// The first error writing to stdout, if any.
pub fn stdout_error() -> Option<std::io::Error> {
    STDOUT_ERROR.lock().ok().and_then(|mut g| g.take())
}

/// `print!` that never panics (see [`write_stdout`]).
macro_rules! out {
    ($($t:tt)*) => { $crate::cmd::write_stdout(format_args!($($t)*)) };
}

/// `println!` that never panics (see [`write_stdout`]).
macro_rules! outln {
    ($($t:tt)*) => { $crate::cmd::write_stdout(format_args!("{}\n", format_args!($($t)*))) };
}
pub(crate) use {out, outln};

/// `--roi X,Y,W,H`.
pub fn parse_roi(s: &str) -> Result<Roi, String> {
    s.parse::<Roi>().map_err(|e| e.message)
}

#[derive(Clone, Copy, Debug, Default, clap::ValueEnum)]
pub enum PyramidArg {
    /// Complex steerable pyramid (quality).
    #[default]
    Csp,
    /// Riesz pyramid (speed).
    Riesz,
}

impl From<PyramidArg> for Pyramid {
    fn from(p: PyramidArg) -> Pyramid {
        match p {
            PyramidArg::Csp => Pyramid::Csp,
            PyramidArg::Riesz => Pyramid::Riesz,
        }
    }
}

/// The flags of every command that analyses a video's motion.
#[derive(clap::Args, Clone, Debug)]
pub struct VideoArgs {
    /// Capture frame rate in Hz (containers such as MP4 often state the
    /// playback rate of a high-speed clip instead).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub fps: Option<f64>,
    /// Region of the object: X,Y,W,H in pixels (default: the whole frame).
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_roi)]
    pub roi: Option<Roi>,
    /// Region of the object as an image the size of the frame (PGM or
    /// PNG; pixels > 0 count); with --roi, the overlap of both.
    #[arg(long, value_name = "FILE")]
    pub mask: Option<PathBuf>,
    /// Pyramid: complex steerable (quality) or Riesz (speed).
    #[arg(long, value_enum, default_value = "csp")]
    pub pyramid: PyramidArg,
}

impl VideoArgs {
    pub fn region(&self) -> Region {
        Region {
            roi: self.roi,
            mask: self.mask.clone(),
            pyramid: self.pyramid.into(),
        }
    }
}

/// `--scale MM_PER_PX`.
pub fn parse_scale(s: &str) -> Result<ScaleArg, String> {
    ScaleArg::mm_per_px(s).map_err(|e| e.message)
}

/// `--known-length X1,Y1,X2,Y2=LENGTH_MM`.
pub fn parse_known_length(s: &str) -> Result<ScaleArg, String> {
    s.parse::<KnownLength>()
        .map(ScaleArg::KnownLength)
        .map_err(|e| e.message)
}

/// The flags that put motion into physical units (every command that
/// reports motion).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct UnitArgs {
    /// Millimetres per pixel on the object: motion is then reported in µm
    /// (below 1 mm) or mm instead of px.
    #[arg(long, value_name = "MM_PER_PX", value_parser = parse_scale, allow_negative_numbers = true, conflicts_with = "known_length")]
    pub scale: Option<ScaleArg>,
    /// The scale from two points (pixels, as read off a frame) on a
    /// feature of known length in mm: scale = LENGTH / distance. Points
    /// rounded to whole pixels err by up to 1 px over the distance: pick
    /// points 100 px or more apart for 1%.
    #[arg(long, value_name = "X1,Y1,X2,Y2=LENGTH_MM", value_parser = parse_known_length, allow_negative_numbers = true)]
    pub known_length: Option<ScaleArg>,
}

impl UnitArgs {
    pub fn scale(&self) -> Option<ScaleArg> {
        self.scale.or(self.known_length)
    }
}

/// Warns once when the frame rate will come from a container and looks
/// like a playback rate.
pub fn warn_playback_rate(video: &Path, fps: Option<f64>) {
    if let Some(w) = vibroscope::pipeline::playback_rate_warning(video, fps) {
        eprintln!("{w}");
    }
}

/// Refuses a `--json` path that is one of the inputs or cannot be
/// written, before the work starts.
pub fn check_json(inputs: &[&Path], json: Option<&Path>) -> vibroscope::Result<()> {
    match json {
        Some(j) => vibroscope::error::check_outputs(inputs, &[j]),
        None => Ok(()),
    }
}

/// `wrote PATH`.
pub fn wrote(p: &Path) {
    eprintln!("wrote {}", p.display());
}

/// Prints the per-stage table of a run (`--stats`), also when the run failed.
pub fn stats<T>(
    on: bool,
    r: vibroscope::Result<T>,
    table: impl Fn(&T) -> Option<String>,
) -> vibroscope::Result<T> {
    if on {
        match &r {
            Ok(v) => {
                if let Some(t) = table(v) {
                    eprint!("{t}");
                }
            }
            Err(e) => {
                if let Some(rep) = e.run_report() {
                    eprint!("{}", rep.table());
                }
            }
        }
    }
    r
}

pub use vibroscope::live::thousands;

/// A progress bar over the frames of the runs a recipe makes (drawn on a
/// terminal only), with a whole-number rate (`4,452/s`).
pub struct Bar {
    stop: Arc<AtomicBool>,
    bar: indicatif::ProgressBar,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Bar {
    /// Starts polling the library's progress; `None` when `on` is false.
    pub fn start(on: bool) -> Option<Bar> {
        if !on {
            return None;
        }
        let bar = indicatif::ProgressBar::with_draw_target(
            None,
            indicatif::ProgressDrawTarget::stderr_with_hz(10),
        );
        let rate = |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = write!(w, "{}/s", thousands(s.per_sec().round() as u64));
        };
        let known = indicatif::ProgressStyle::with_template(
            "{prefix}{bar:40} {human_pos}/{human_len} frames  {rate}  eta {eta}",
        )
        .map(|s| s.with_key("rate", rate));
        let unknown = indicatif::ProgressStyle::with_template(
            "{prefix}{spinner} {human_pos} frames  {rate}  {elapsed}",
        )
        .map(|s| s.with_key("rate", rate));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (bar, stop) = (bar.clone(), Arc::clone(&stop));
            std::thread::spawn(move || {
                let mut runs = 0;
                while !stop.load(Ordering::Relaxed) {
                    let p = vibroscope::pipeline::progress();
                    if p.runs != runs {
                        runs = p.runs;
                        bar.reset();
                        match (p.total, &known, &unknown) {
                            (Some(t), Ok(k), _) => {
                                bar.set_style(k.clone());
                                bar.set_length(t);
                            }
                            (None, _, Ok(u)) => {
                                bar.set_style(u.clone());
                                bar.unset_length();
                            }
                            _ => {}
                        }
                    }
                    if runs > 0 {
                        bar.set_position(p.frames);
                    }
                    // Woken at once by Drop, so a short run does not wait.
                    std::thread::park_timeout(Duration::from_millis(100));
                }
            })
        };
        Some(Bar {
            stop,
            bar,
            thread: Some(thread),
        })
    }

    /// A label before the bar (`spectrum 2/4 `).
    pub fn set_prefix(&self, p: String) {
        self.bar.set_prefix(p);
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
        self.bar.finish_and_clear();
    }
}

/// A number for people: `n/a` when not finite.
pub fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "n/a".into()
    }
}
