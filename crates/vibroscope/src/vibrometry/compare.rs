//! `vibroscope compare A B --roi X,Y,W,H [--roi ...] [--mask FILE ...]
//! --json OUT.json`: the wine-glasses experiment (thesis ch. 5.6). Each
//! region's motion spectrum and peaks (the `spectrum` graph restricted to
//! the region) in recording A and in recording B, and the shift of the
//! region's most prominent resonance, B minus A, with its uncertainty (the
//! two peaks' frequency standard deviations in quadrature). A shift is
//! `significant` beyond three standard deviations.
//!
//! ```json
//! {"regions": [{"region", "a": {"frequency_hz", "frequency_std_hz", ...},
//!   "b": {...}, "shift_hz", "shift_std_hz", "significant",
//!   "peaks_a": [...], "peaks_b": [...]}]}
//! ```

use super::TempPath;
use crate::cli::{parse_roi_arg, run_decl, spectrum_pipeline, SpectrumArgs};
use crate::engine::config::ConfigError;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `vibroscope compare`.
#[derive(clap::Args, Clone)]
pub(crate) struct CompareArgs {
    /// The reference recording.
    a: PathBuf,
    /// The recording compared with it.
    b: PathBuf,
    /// Output JSON.
    #[arg(long, value_name = "OUT.json")]
    json: PathBuf,
    /// A region X,Y,W,H in pixels; repeatable.
    #[arg(long, value_name = "X,Y,W,H")]
    roi: Vec<String>,
    /// A region as an image the size of the frame (PGM or PNG; pixels > 0
    /// count); repeatable.
    #[arg(long, value_name = "FILE")]
    mask: Vec<PathBuf>,
    /// Capture frame rate in Hz of both recordings.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Peaks listed per region and recording.
    #[arg(long, default_value_t = 3, value_name = "N")]
    peaks: usize,
    /// Only resonances in this band (Hz).
    #[arg(long, value_name = "HZ")]
    min_hz: Option<f64>,
    #[arg(long, value_name = "HZ")]
    max_hz: Option<f64>,
    /// Pyramid: complex steerable (quality) or Riesz (speed).
    #[arg(long, value_enum, default_value = "csp")]
    pyramid: crate::cli::PyramidArg,
}

pub(crate) fn compare_cmd(a: &CompareArgs) -> anyhow::Result<ExitCode> {
    if a.roi.is_empty() && a.mask.is_empty() {
        return Err(ConfigError {
            file: "--roi".into(),
            origin: None,
            stage: None,
            field: None,
            message: "give at least one region (--roi X,Y,W,H or --mask FILE)".into(),
        }
        .into());
    }
    for r in &a.roi {
        parse_roi_arg(r)?;
    }
    let regions: Vec<(String, Option<String>, Option<PathBuf>)> = a
        .roi
        .iter()
        .map(|r| (format!("roi {r}"), Some(r.clone()), None))
        .chain(
            a.mask
                .iter()
                .map(|m| (format!("mask {}", m.display()), None, Some(m.clone()))),
        )
        .collect();
    let mut out = Vec::new();
    for (name, roi, mask) in &regions {
        let mut docs = Vec::new();
        for video in [&a.a, &a.b] {
            let tmp = TempPath::new("compare.json");
            let sa = SpectrumArgs {
                video: video.clone(),
                json: tmp.path().to_path_buf(),
                fps: a.fps,
                peaks: a.peaks,
                roi: roi.clone(),
                mask: mask.clone(),
                segments: None,
                window: None,
                min_hz: a.min_hz,
                max_hz: a.max_hz,
                include_spectrum: false,
                pyramid: a.pyramid,
                stats: false,
                motion_wav: None,
                png: None,
                spectrogram: None,
                spectrogram_window: crate::cli::SPECTROGRAM_WINDOW,
            };
            let decl = spectrum_pipeline(&sa)?;
            let (code, _) = run_decl(&decl, false, false)?;
            if code != ExitCode::SUCCESS {
                return Ok(code);
            }
            let text = std::fs::read(tmp.path())
                .with_context(|| format!("{}: cannot read", tmp.path().display()))?;
            docs.push(serde_json::from_slice::<serde_json::Value>(&text)?);
        }
        out.push(region_shift(name, &docs[0], &docs[1]));
    }
    let doc = serde_json::json!({ "a": a.a, "b": a.b, "regions": out });
    crate::stages::sinks::write_atomic(&a.json, &serde_json::to_vec_pretty(&doc)?)?;
    eprintln!("wrote {}", a.json.display());
    Ok(ExitCode::SUCCESS)
}

/// The most prominent peak of a peaks document.
fn strongest(doc: &serde_json::Value) -> Option<&serde_json::Value> {
    doc["peaks"].as_array()?.iter().max_by(|x, y| {
        let p = |v: &serde_json::Value| v["prominence_db"].as_f64().unwrap_or(f64::MIN);
        p(x).total_cmp(&p(y))
    })
}

/// One region's entry: both strongest resonances and their shift.
pub fn region_shift(name: &str, a: &serde_json::Value, b: &serde_json::Value) -> serde_json::Value {
    let mut r = serde_json::json!({
        "region": name,
        "peaks_a": a["peaks"],
        "peaks_b": b["peaks"],
        "resolution_hz": [a["resolution_hz"], b["resolution_hz"]],
    });
    if let (Some(pa), Some(pb)) = (strongest(a), strongest(b)) {
        let f = |p: &serde_json::Value, k: &str| p[k].as_f64().unwrap_or(f64::NAN);
        let shift = f(pb, "frequency_hz") - f(pa, "frequency_hz");
        let sd = f(pa, "frequency_std_hz").hypot(f(pb, "frequency_std_hz"));
        r["a"] = pa.clone();
        r["b"] = pb.clone();
        r["shift_hz"] = shift.into();
        r["shift_std_hz"] = sd.into();
        r["significant"] = (shift.abs() > 3.0 * sd).into();
    }
    r
}
