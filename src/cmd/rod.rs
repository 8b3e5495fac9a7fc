//! `vibroscope rod`.

use super::spectrum::SpectrumArgs;
use std::process::ExitCode;
use vibroscope::rod::Measured;
use vibroscope::rod::{self, RodOptions};

/// A clamped rod's fundamental, and Young's modulus or length.
///
/// A clamped rod's fundamental by voting over its mode ratios (thesis
/// Eq. 5.3), refined through the highest mode; Young's modulus (Eq. 5.1)
/// or length (Eq. 5.4) with propagated errors (Eq. 5.5).
#[derive(clap::Args, Clone)]
#[command(after_help = "Examples:\n  \
    vibroscope rod rod.y4m -o rod.json --diameter-m 0.00635 --length-m 0.5588 --density-kg-m3 8530\n  \
    vibroscope rod rod.y4m --json rod.json --ratios 1,6.27,17.55 --tolerance length-m=0.002")]
pub struct Args {
    #[command(flatten)]
    spectrum: SpectrumArgs,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    stats: bool,
    /// Mode frequency ratios to the fundamental, comma separated, starting
    /// with 1 (default: clamped-free rod, Eq. 5.2).
    #[arg(long, value_name = "R1,R2,...")]
    ratios: Option<String>,
    /// How far a mode may sit from its ideal ratio (fraction).
    #[arg(
        long,
        default_value_t = 0.01,
        value_name = "FRACTION",
        allow_negative_numbers = true
    )]
    ratio_tolerance: f64,
    /// Rod diameter (m).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    diameter_m: Option<f64>,
    /// Free length from the clamp (m).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    length_m: Option<f64>,
    /// Density (kg/m³).
    #[arg(
        long = "density-kg-m3",
        value_name = "KG_M3",
        allow_negative_numbers = true
    )]
    density_kg_m3: Option<f64>,
    /// Young's modulus (Pa): given, the length is estimated (Eq. 5.4).
    #[arg(long, value_name = "PA", allow_negative_numbers = true)]
    youngs_pa: Option<f64>,
    /// Standard uncertainty of an input, NAME=VALUE in its unit (NAME:
    /// diameter-m, length-m, density-kg-m3, youngs-pa); repeatable.
    #[arg(long, value_name = "NAME=VALUE")]
    tolerance: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let spectrum = a.spectrum.options(true);
    let mut o = RodOptions::new(spectrum);
    if let Some(r) = &a.ratios {
        o.ratios = rod::parse_ratios(r)?;
    }
    o.ratio_tolerance = a.ratio_tolerance;
    let t = rod::parse_tolerances(&a.tolerance)?;
    let m = |v: Option<f64>, std: f64| v.map(|value| Measured { value, std });
    o.diameter_m = m(a.diameter_m, t.diameter_m);
    o.length_m = m(a.length_m, t.length_m);
    o.density_kg_m3 = m(a.density_kg_m3, t.density_kg_m3);
    o.youngs_pa = m(a.youngs_pa, t.youngs_pa);
    super::warn_playback_rate(&o.spectrum.video, o.spectrum.fps);
    let bar = super::Bar::start(true);
    let r = rod::rod(&o);
    drop(bar);
    let (r, _) = super::stats(a.stats, r, |(_, run)| Some(run.table()))?;
    super::wrote(&r.written);
    eprintln!(
        "fundamental {:.4} ± {:.4} Hz ({} modes found)",
        r.fundamental_hz,
        r.fundamental_std_hz,
        r.modes.len()
    );
    if let (Some(e), Some(s)) = (r.youngs_modulus_pa, r.youngs_modulus_std_pa) {
        eprintln!("Young's modulus {:.4} ± {:.4} GPa", e / 1e9, s / 1e9);
    }
    if let (Some(l), Some(s)) = (r.length_m, r.length_std_m) {
        eprintln!("length {:.4} ± {:.4} m", l, s);
    }
    Ok(ExitCode::SUCCESS)
}
