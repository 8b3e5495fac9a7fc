//! A clamped rod (thesis ch. 5): the motion spectrum (the `spectrum`
//! graph), the fundamental by voting over the mode ratios
//! ([`crate::math::rod`]), and Young's modulus (given diameter, length and
//! density) or length (given diameter, modulus and density) with errors
//! propagated from the stated tolerances (Eq. 5.5).

use crate::engine::RunReport;
use crate::error::{Error, Result};
pub use crate::math::rod::Measured;
use crate::math::rod::{self, RodMode, SpectrumDb, CLAMPED_FREE};
use crate::spectrum::{run_spectrum, SpectrumOptions};
use serde::Serialize;
use std::path::PathBuf;

/// What `rod` is asked.
#[derive(Clone, Debug)]
pub struct RodOptions {
    /// The spectrum of the recording (its `json` is where the rod report goes).
    pub spectrum: SpectrumOptions,
    /// Mode frequency ratios to the fundamental, starting with 1.
    pub ratios: Vec<f64>,
    /// How far a mode may sit from its ideal ratio (fraction, in [0, 0.5)).
    pub ratio_tolerance: f64,
    pub diameter_m: Option<Measured>,
    pub length_m: Option<Measured>,
    pub density_kg_m3: Option<Measured>,
    pub youngs_pa: Option<Measured>,
}

impl RodOptions {
    /// A clamped-free rod, 1% ratio tolerance, no material inputs.
    pub fn new(spectrum: SpectrumOptions) -> RodOptions {
        RodOptions {
            spectrum,
            ratios: CLAMPED_FREE.to_vec(),
            ratio_tolerance: 0.01,
            diameter_m: None,
            length_m: None,
            density_kg_m3: None,
            youngs_pa: None,
        }
    }
}

/// What `rod` found: serialises to the JSON it writes.
#[derive(Clone, Debug, Serialize)]
pub struct RodReport {
    pub fundamental_hz: f64,
    pub fundamental_std_hz: f64,
    pub modes_hz: Vec<f64>,
    pub ratios: Vec<f64>,
    pub modes: Vec<RodMode>,
    pub fundamental_peak_hz: f64,
    pub vote_db: f64,
    pub runner_up_hz: Option<f64>,
    pub runner_up_db: Option<f64>,
    pub strongest_peak_hz: Option<f64>,
    pub sample_rate_hz: f64,
    pub resolution_hz: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub youngs_modulus_pa: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub youngs_modulus_std_pa: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub length_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub length_std_m: Option<f64>,
    /// The file written.
    #[serde(skip)]
    pub written: PathBuf,
}

/// Ratios as `R1,R2,...`: increasing, starting with 1.
pub fn parse_ratios(t: &str) -> Result<Vec<f64>> {
    let bad = || {
        Error::usage(
            "--ratios",
            format!("expected increasing numbers starting with 1, like 1,6.27,17.55; got `{t}`"),
        )
    };
    let v: Vec<f64> = t
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| bad())?;
    let increasing = v.windows(2).all(|w| w[1] > w[0]);
    if v.is_empty() || v[0] != 1.0 || !increasing || v.iter().any(|x| !x.is_finite()) {
        return Err(bad());
    }
    Ok(v)
}

fn check(o: &RodOptions) -> Result<()> {
    if !(o.ratio_tolerance.is_finite() && (0.0..0.5).contains(&o.ratio_tolerance)) {
        return Err(Error::usage(
            "--ratio-tolerance",
            format!("must be in [0, 0.5), got {}", o.ratio_tolerance),
        ));
    }
    let inputs = [
        ("--diameter-m", o.diameter_m),
        ("--length-m", o.length_m),
        ("--density-kg-m3", o.density_kg_m3),
        ("--youngs-pa", o.youngs_pa),
    ];
    for (flag, m) in inputs {
        if let Some(m) = m {
            if !(m.value.is_finite() && m.value > 0.0) {
                return Err(Error::usage(flag, format!("must be > 0, got {}", m.value)));
            }
            if !(m.std.is_finite() && m.std >= 0.0) {
                return Err(Error::usage(
                    "--tolerance",
                    format!("{}: expected a number >= 0, got `{}`", &flag[2..], m.std),
                ));
            }
        }
    }
    Ok(())
}

/// Runs `rod`: writes its JSON.
pub fn rod(o: &RodOptions) -> Result<(RodReport, RunReport)> {
    check(o)?;
    crate::spectrum::check_outputs(&o.spectrum)?;
    let mut so = o.spectrum.clone();
    so.include_spectrum = true;
    let (doc, run) = run_spectrum(&so, false)?;
    let sp = doc
        .spectrum
        .as_ref()
        .ok_or_else(|| Error::Analysis("the spectrum graph gave no spectrum".into()))?;
    let db = &sp.power_db;
    let s = SpectrumDb {
        db,
        f0_hz: sp.f0_hz,
        df_hz: sp.resolution_hz,
    };
    let ratios = &o.ratios;
    let video = o.spectrum.video.display();
    let fit = rod::vote(&s, ratios, o.ratio_tolerance).ok_or_else(|| {
        Error::Analysis(format!(
            "{video}: no fundamental fits: the highest mode (ratio {}) must lie below the \
             Nyquist frequency ({} Hz bins, {} of them)",
            ratios[ratios.len() - 1],
            s.df_hz,
            db.len()
        ))
    })?;
    let strongest = (3..db.len())
        .max_by(|&i, &j| db[i].total_cmp(&db[j]))
        .map(|k| s.f0_hz + k as f64 * s.df_hz);
    let f1 = Measured {
        value: fit.fundamental_hz,
        std: fit.fundamental_std_hz,
    };
    let finite = |x: f64| x.is_finite().then_some(x);
    let mut out = RodReport {
        fundamental_hz: fit.fundamental_hz,
        fundamental_std_hz: fit.fundamental_std_hz,
        modes_hz: fit.modes.iter().map(|m| m.frequency_hz).collect(),
        ratios: ratios.clone(),
        modes: fit.modes.clone(),
        fundamental_peak_hz: fit.fundamental_peak_hz,
        vote_db: fit.vote_db,
        runner_up_hz: finite(fit.runner_up_hz),
        runner_up_db: finite(fit.runner_up_db),
        strongest_peak_hz: strongest,
        sample_rate_hz: doc.sample_rate_hz,
        resolution_hz: s.df_hz,
        youngs_modulus_pa: None,
        youngs_modulus_std_pa: None,
        length_m: None,
        length_std_m: None,
        written: o.spectrum.json.clone(),
    };
    let (d, l, rho, e) = (o.diameter_m, o.length_m, o.density_kg_m3, o.youngs_pa);
    if let (Some(d), Some(l), Some(rho)) = (d, l, rho) {
        let m = rod::propagate(rod::youngs_modulus, &[f1, d, l, rho]);
        out.youngs_modulus_pa = Some(m.value);
        out.youngs_modulus_std_pa = Some(m.std);
    }
    if let (Some(d), Some(e), Some(rho)) = (d, e, rho) {
        let m = rod::propagate(rod::length, &[f1, d, e, rho]);
        out.length_m = Some(m.value);
        out.length_std_m = Some(m.std);
    }
    crate::json::write(&o.spectrum.json, &out)?;
    Ok((out, run))
}

/// Standard uncertainties of the material inputs, in their units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tolerances {
    pub diameter_m: f64,
    pub length_m: f64,
    pub density_kg_m3: f64,
    pub youngs_pa: f64,
}

/// `NAME=VALUE` entries (NAME: diameter-m, length-m, density-kg-m3,
/// youngs-pa) as tolerances.
pub fn parse_tolerances(entries: &[String]) -> Result<Tolerances> {
    let names = ["diameter-m", "length-m", "density-kg-m3", "youngs-pa"];
    let mut std = [0.0f64; 4];
    for t in entries {
        let (k, v) = t.split_once('=').ok_or_else(|| {
            Error::usage("--tolerance", format!("expected NAME=VALUE, got `{t}`"))
        })?;
        let i = names.iter().position(|n| *n == k.trim()).ok_or_else(|| {
            Error::usage(
                "--tolerance",
                format!("unknown input `{k}` (one of {})", names.join(", ")),
            )
        })?;
        std[i] = match v.trim().parse::<f64>() {
            Ok(x) if x.is_finite() && x >= 0.0 => x,
            _ => {
                return Err(Error::usage(
                    "--tolerance",
                    format!("{k}: expected a number >= 0, got `{v}`"),
                ))
            }
        };
    }
    Ok(Tolerances {
        diameter_m: std[0],
        length_m: std[1],
        density_kg_m3: std[2],
        youngs_pa: std[3],
    })
}
