//! Per-region resonance shifts between two recordings (the wine-glasses
//! experiment, thesis ch. 5.6). Each region's motion spectrum and peaks
//! (the `spectrum` graph restricted to the region) in recording A and in
//! recording B, and the shift of the region's most prominent resonance, B
//! minus A, with its uncertainty (the two peaks' frequency standard
//! deviations in quadrature). A shift is `significant` beyond three
//! standard deviations.

use crate::error::{Error, Result};
use crate::peaks::{Peak, SpectrumReport};
use crate::pipeline::{Pyramid, Region, Roi, RunSettings};
use crate::spectrum::{run_spectrum, SpectrumOptions};
use serde::Serialize;
use std::path::PathBuf;

/// What `compare` is asked.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// The reference recording.
    pub a: PathBuf,
    /// The recording compared with it.
    pub b: PathBuf,
    /// Output JSON.
    pub json: PathBuf,
    /// Rectangular regions.
    pub rois: Vec<Roi>,
    /// Regions as mask images.
    pub masks: Vec<PathBuf>,
    /// Capture frame rate of both recordings.
    pub fps: Option<f64>,
    /// Peaks listed per region and recording.
    pub peaks: usize,
    pub min_hz: Option<f64>,
    pub max_hz: Option<f64>,
    pub pyramid: Pyramid,
    pub run: RunSettings,
}

/// One region: both strongest resonances and their shift.
#[derive(Clone, Debug, Serialize)]
pub struct RegionShift {
    pub region: String,
    pub peaks_a: Vec<Peak>,
    pub peaks_b: Vec<Peak>,
    pub resolution_hz: [f64; 2],
    #[serde(skip_serializing_if = "Option::is_none")]
    pub a: Option<Peak>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub b: Option<Peak>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shift_hz: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shift_std_hz: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub significant: Option<bool>,
}

/// What `compare` found: serialises to the JSON it writes.
#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    pub a: PathBuf,
    pub b: PathBuf,
    pub regions: Vec<RegionShift>,
    #[serde(skip)]
    pub written: PathBuf,
}

/// One region's entry from its two spectra.
pub fn region_shift(name: &str, a: &SpectrumReport, b: &SpectrumReport) -> RegionShift {
    let mut r = RegionShift {
        region: name.into(),
        peaks_a: a.peaks.clone(),
        peaks_b: b.peaks.clone(),
        resolution_hz: [a.resolution_hz, b.resolution_hz],
        a: None,
        b: None,
        shift_hz: None,
        shift_std_hz: None,
        significant: None,
    };
    if let (Some(pa), Some(pb)) = (a.strongest(), b.strongest()) {
        let shift = pb.frequency_hz - pa.frequency_hz;
        let sd = pa.frequency_std_hz.hypot(pb.frequency_std_hz);
        r.a = Some(pa.clone());
        r.b = Some(pb.clone());
        r.shift_hz = Some(shift);
        r.shift_std_hz = Some(sd);
        r.significant = Some(shift.abs() > 3.0 * sd);
    }
    r
}

/// Runs `compare`: writes its JSON. `progress` is told each finished
/// spectrum (done, total).
pub fn compare(
    o: &CompareOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<CompareReport> {
    let mut inputs = vec![o.a.as_path(), o.b.as_path()];
    inputs.extend(o.masks.iter().map(PathBuf::as_path));
    crate::error::check_outputs(&inputs, &[&o.json])?;
    if o.rois.is_empty() && o.masks.is_empty() {
        return Err(Error::usage(
            "--roi",
            "give at least one region (--roi X,Y,W,H or --mask FILE)",
        ));
    }
    let regions: Vec<(String, Region)> = o
        .rois
        .iter()
        .map(|r| {
            (
                format!("roi {r}"),
                Region {
                    roi: Some(*r),
                    mask: None,
                    pyramid: o.pyramid,
                },
            )
        })
        .chain(o.masks.iter().map(|m| {
            (
                format!("mask {}", m.display()),
                Region {
                    roi: None,
                    mask: Some(m.clone()),
                    pyramid: o.pyramid,
                },
            )
        }))
        .collect();
    let total = 2 * regions.len();
    let mut out = Vec::new();
    for (i, (name, region)) in regions.iter().enumerate() {
        let mut docs = Vec::new();
        for (j, video) in [&o.a, &o.b].into_iter().enumerate() {
            let so = SpectrumOptions {
                fps: o.fps,
                peaks: o.peaks,
                region: region.clone(),
                min_hz: o.min_hz,
                max_hz: o.max_hz,
                run: o.run,
                ..SpectrumOptions::new(video, &o.json)
            };
            docs.push(run_spectrum(&so, false)?.0);
            progress(2 * i + j + 1, total);
        }
        out.push(region_shift(name, &docs[0], &docs[1]));
    }
    let report = CompareReport {
        a: o.a.clone(),
        b: o.b.clone(),
        regions: out,
        written: o.json.clone(),
    };
    crate::json::write(&o.json, &report)?;
    Ok(report)
}
