//! `vibroscope rod VIDEO --json OUT.json`: the motion spectrum of a clamped
//! rod (the `spectrum` graph), its fundamental by voting over the mode
//! ratios ([`crate::math::rod`]), and Young's modulus (given diameter,
//! length and density) or length (given diameter, modulus and density) with
//! errors propagated from the stated tolerances (Eq. 5.5).
//!
//! ```json
//! {"fundamental_hz", "fundamental_std_hz", "modes_hz": [...], "ratios": [...],
//!  "modes": [{"ratio", "predicted_hz", "frequency_hz", "above_floor_db"}],
//!  "fundamental_peak_hz", "vote_db", "runner_up_hz", "runner_up_db",
//!  "strongest_peak_hz", "youngs_modulus_pa", "youngs_modulus_std_pa",
//!  "length_m", "length_std_m", "sample_rate_hz", "resolution_hz"}
//! ```

use super::TempPath;
use crate::cli::{run_decl, spectrum_pipeline, SpectrumArgs};
use crate::engine::config::ConfigError;
use crate::math::rod::{self, Measured, SpectrumDb, CLAMPED_FREE};
use anyhow::Context;
use std::process::ExitCode;

/// Arguments of `vibroscope rod`.
#[derive(clap::Args, Clone)]
pub(crate) struct RodArgs {
    #[command(flatten)]
    pub(crate) spectrum: SpectrumArgs,
    /// Mode frequency ratios to the fundamental, comma separated, starting
    /// with 1 (default: clamped-free rod, Eq. 5.2).
    #[arg(long, value_name = "R1,R2,...")]
    pub ratios: Option<String>,
    /// How far a mode may sit from its ideal ratio (fraction).
    #[arg(
        long,
        default_value_t = 0.01,
        value_name = "FRACTION",
        allow_negative_numbers = true
    )]
    pub ratio_tolerance: f64,
    /// Rod diameter (m).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub diameter_m: Option<f64>,
    /// Free length from the clamp (m).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub length_m: Option<f64>,
    /// Density (kg/m³).
    #[arg(
        long = "density-kg-m3",
        value_name = "KG_M3",
        allow_negative_numbers = true
    )]
    pub density_kg_m3: Option<f64>,
    /// Young's modulus (Pa): given, the length is estimated (Eq. 5.4).
    #[arg(long, value_name = "PA", allow_negative_numbers = true)]
    pub youngs_pa: Option<f64>,
    /// Standard uncertainty of an input, NAME=VALUE in its unit (NAME:
    /// diameter-m, length-m, density-kg-m3, youngs-pa); repeatable.
    #[arg(long, value_name = "NAME=VALUE")]
    pub tolerance: Vec<String>,
}

fn usage(flag: &str, message: String) -> ConfigError {
    ConfigError {
        file: flag.to_string(),
        origin: None,
        stage: None,
        field: None,
        message,
    }
}

fn parse_ratios(text: Option<&str>) -> Result<Vec<f64>, ConfigError> {
    let Some(t) = text else {
        return Ok(CLAMPED_FREE.to_vec());
    };
    let bad = || {
        usage(
            "--ratios",
            format!("expected increasing numbers starting with 1, like 1,6.27,17.55; got `{t}`"),
        )
    };
    let v: Vec<f64> = t
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let increasing = v.windows(2).all(|w| w[1] > w[0]);
    if v.is_empty() || v[0] != 1.0 || !increasing || v.iter().any(|x| !x.is_finite()) {
        return Err(bad());
    }
    Ok(v)
}

/// The inputs with their tolerances: [diameter, length, density, modulus].
fn inputs(a: &RodArgs) -> Result<[Option<Measured>; 4], ConfigError> {
    let names = ["diameter-m", "length-m", "density-kg-m3", "youngs-pa"];
    let values = [a.diameter_m, a.length_m, a.density_kg_m3, a.youngs_pa];
    let mut std = [0.0f64; 4];
    for t in &a.tolerance {
        let (k, v) = t
            .split_once('=')
            .ok_or_else(|| usage("--tolerance", format!("expected NAME=VALUE, got `{t}`")))?;
        let i = names.iter().position(|n| *n == k.trim()).ok_or_else(|| {
            usage(
                "--tolerance",
                format!("unknown input `{k}` (one of {})", names.join(", ")),
            )
        })?;
        std[i] = match v.trim().parse::<f64>() {
            Ok(x) if x.is_finite() && x >= 0.0 => x,
            _ => {
                return Err(usage(
                    "--tolerance",
                    format!("{k}: expected a number >= 0, got `{v}`"),
                ))
            }
        };
    }
    let mut out = [None; 4];
    for i in 0..4 {
        if let Some(x) = values[i] {
            if !(x.is_finite() && x > 0.0) {
                return Err(usage(
                    &format!("--{}", names[i]),
                    format!("must be > 0, got {x}"),
                ));
            }
            out[i] = Some(Measured {
                value: x,
                std: std[i],
            });
        }
    }
    Ok(out)
}

pub(crate) fn rod_cmd(a: &RodArgs) -> anyhow::Result<ExitCode> {
    let ratios = parse_ratios(a.ratios.as_deref())?;
    if !(a.ratio_tolerance.is_finite() && (0.0..0.5).contains(&a.ratio_tolerance)) {
        return Err(usage(
            "--ratio-tolerance",
            format!("must be in [0, 0.5), got {}", a.ratio_tolerance),
        )
        .into());
    }
    let [d, l, rho, e] = inputs(a)?;
    let tmp = TempPath::new("rod-spectrum.json");
    let mut sa = a.spectrum.clone();
    sa.json = tmp.path().to_path_buf();
    sa.include_spectrum = true;
    let decl = spectrum_pipeline(&sa)?;
    let (code, _) = run_decl(&decl, sa.stats, false)?;
    if code != ExitCode::SUCCESS {
        return Ok(code);
    }
    let text = std::fs::read(tmp.path())
        .with_context(|| format!("{}: cannot read", tmp.path().display()))?;
    let doc: serde_json::Value = serde_json::from_slice(&text)?;
    let sp = &doc["spectrum"];
    let db: Vec<f64> = sp["power_db"]
        .as_array()
        .map(|v| v.iter().filter_map(|x| x.as_f64()).collect())
        .unwrap_or_default();
    let s = SpectrumDb {
        db: &db,
        f0_hz: sp["f0_hz"].as_f64().unwrap_or(0.0),
        df_hz: sp["resolution_hz"].as_f64().unwrap_or(0.0),
    };
    let video = a.spectrum.video.display();
    let fit = rod::vote(&s, &ratios, a.ratio_tolerance).ok_or_else(|| {
        anyhow::anyhow!(
            "{video}: no fundamental fits: the highest mode (ratio {}) must lie below the \
             Nyquist frequency ({} Hz bins, {} of them)",
            ratios[ratios.len() - 1],
            s.df_hz,
            db.len()
        )
    })?;
    let strongest = (3..db.len())
        .max_by(|&i, &j| db[i].total_cmp(&db[j]))
        .map(|k| s.f0_hz + k as f64 * s.df_hz);
    let f1 = Measured {
        value: fit.fundamental_hz,
        std: fit.fundamental_std_hz,
    };
    let mut out = serde_json::json!({
        "fundamental_hz": fit.fundamental_hz,
        "fundamental_std_hz": fit.fundamental_std_hz,
        "modes_hz": fit.modes.iter().map(|m| m.frequency_hz).collect::<Vec<_>>(),
        "ratios": ratios,
        "modes": fit.modes,
        "fundamental_peak_hz": fit.fundamental_peak_hz,
        "vote_db": fit.vote_db,
        "runner_up_hz": finite(fit.runner_up_hz),
        "runner_up_db": finite(fit.runner_up_db),
        "strongest_peak_hz": strongest,
        "sample_rate_hz": doc["sample_rate_hz"],
        "resolution_hz": s.df_hz,
    });
    if let (Some(d), Some(l), Some(rho)) = (d, l, rho) {
        let m = rod::propagate(rod::youngs_modulus, &[f1, d, l, rho]);
        out["youngs_modulus_pa"] = m.value.into();
        out["youngs_modulus_std_pa"] = m.std.into();
    }
    if let (Some(d), Some(e), Some(rho)) = (d, e, rho) {
        let m = rod::propagate(rod::length, &[f1, d, e, rho]);
        out["length_m"] = m.value.into();
        out["length_std_m"] = m.std.into();
    }
    let bytes = serde_json::to_vec_pretty(&out)?;
    crate::stages::sinks::write_atomic(&a.spectrum.json, &bytes)?;
    eprintln!(
        "fundamental {:.4} ± {:.4} Hz; wrote {}",
        fit.fundamental_hz,
        fit.fundamental_std_hz,
        a.spectrum.json.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn finite(x: f64) -> serde_json::Value {
    if x.is_finite() {
        x.into()
    } else {
        serde_json::Value::Null
    }
}
