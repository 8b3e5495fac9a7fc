//! `vibroscope modes`: a modal image of a recording (thesis ch. 3.5), the
//! `modes` sink fed by a file source.

use super::{apply_fps, parse_roi_arg, run_decl};
use crate::engine::config::{self, set_param, Origin, PipelineDecl};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(super) enum MotionArg {
    X,
    Y,
    Sum,
}

/// Arguments of `vibroscope modes`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct ModesArgs {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    video: PathBuf,
    /// The frequency of the image, Hz (the exact Fourier sum at this
    /// frequency, not the nearest FFT bin).
    #[arg(long = "at", value_name = "HZ", allow_negative_numbers = true)]
    at_hz: f64,
    /// Output PNG: phase as hue, amplitude as brightness.
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// Also write the complex image (complex64, shape (H, W), pixels of motion).
    #[arg(long, value_name = "OUT.npy")]
    npy: Option<PathBuf>,
    /// Capture frame rate in Hz (containers often state the playback rate).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Region: X,Y,W,H in pixels (the image covers it; default: the whole frame).
    #[arg(long, value_name = "X,Y,W,H")]
    roi: Option<String>,
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
    scale: Option<usize>,
    /// Do not divide by the blurred weights (the images of thesis ch. 4-5:
    /// texture acts as a mask).
    #[arg(long)]
    unnormalized: bool,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
}

const BASE: &str = "[pipeline]\nname = \"modes\"\n\
    description = \"recording -> modal image (vibroscope modes)\"\n\
    [[stage]]\nid = \"src\"\nkind = \"file\"\n\
    [[stage]]\nid = \"modes\"\nkind = \"modes\"\ninput = \"src\"\n";

/// The graph `file -> modes` with the arguments set (each names its flag in errors).
pub(super) fn modes_pipeline(a: &ModesArgs) -> anyhow::Result<PipelineDecl> {
    use toml::Value;
    let mut decl = config::parse("vibroscope modes", BASE)?;
    let o = |s: &str| Origin::Set(s.to_string());
    let path = |p: &PathBuf| Value::String(p.display().to_string());
    set_param(&mut decl.stages[0], "path", path(&a.video), o("VIDEO"));
    if let Some(f) = a.fps {
        apply_fps(&mut decl, f)?;
    }
    let st = &mut decl.stages[1];
    set_param(st, "freq_hz", Value::Float(a.at_hz), o("--at"));
    set_param(st, "path", path(&a.output), o("-o"));
    if let Some(n) = &a.npy {
        set_param(st, "npy", path(n), o("--npy"));
    }
    if let Some(r) = &a.roi {
        let v = parse_roi_arg(r)?;
        let arr = Value::Array(v.into_iter().map(Value::Integer).collect());
        set_param(st, "roi", arr, o(&format!("--roi {r}")));
    }
    if let Some(s) = a.sigma {
        set_param(st, "sigma_px", Value::Float(s), o("--sigma"));
    }
    let m = match a.motion {
        MotionArg::X => "x",
        MotionArg::Y => "y",
        MotionArg::Sum => "sum",
    };
    set_param(st, "motion", Value::String(m.into()), o("--motion"));
    if let Some(e) = a.exponent {
        set_param(st, "exponent", Value::Float(e), o("--exponent"));
    }
    if let Some(s) = a.scale {
        let s = i64::try_from(s).unwrap_or(i64::MAX);
        set_param(st, "scale", Value::Integer(s), o("--scale"));
    }
    if a.unnormalized {
        set_param(st, "normalize", Value::Boolean(false), o("--unnormalized"));
    }
    Ok(decl)
}

pub(super) fn modes_cmd(a: &ModesArgs) -> anyhow::Result<ExitCode> {
    let decl = modes_pipeline(a)?;
    let (code, _) = run_decl(&decl, a.stats, false)?;
    if code == ExitCode::SUCCESS {
        eprintln!("wrote {}", a.output.display());
        if let Some(n) = &a.npy {
            eprintln!("wrote {}", n.display());
        }
    }
    Ok(code)
}
