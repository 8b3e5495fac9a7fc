//! The motion of regions in pixels, measured alongside another graph in
//! the same pass over the video: the engine's `displacement` stage (2-D
//! least squares on a 7-tap gradient, one x and one y channel per region)
//! fed by the graph's source, written to a scratch CSV and read back once
//! into typed waveforms; and the peaks' amplitudes in physical units.

use crate::engine::config::{set_param, PipelineDecl};
use crate::engine::Origin;
use crate::error::Result;
use crate::io::atomic::TempPath;
use crate::peaks::SpectrumReport;
use crate::pipeline::{self, path_value};
use crate::units::{px_to, tone_amplitude, Quantity, Scale, Unit};
use anyhow::Context;
use serde::Serialize;
use toml::Value;

/// Adds `src -> displacement -> csv` to a graph and reads the result.
pub struct DisplacementTap {
    rois: Vec<[u32; 4]>,
    temp: TempPath,
}

/// One region's displacement over the recording, in pixels.
#[derive(Clone, Debug, Default)]
pub struct RegionMotion {
    /// `[x, y, w, h]`; none for the whole frame.
    pub roi: Option<[u32; 4]>,
    /// Samples per second.
    pub rate_hz: f64,
    /// Each sample's capture time, s.
    pub t_s: Vec<f64>,
    /// +x right, +y down, px.
    pub x: Vec<f32>,
    pub y: Vec<f32>,
}

impl DisplacementTap {
    /// The regions (none: the whole frame).
    pub fn new(rois: Vec<[u32; 4]>) -> DisplacementTap {
        DisplacementTap {
            rois,
            temp: TempPath::new("displacement.csv"),
        }
    }

    /// Adds the stages, fed by the graph's `src`.
    pub fn add(&self, decl: &mut PipelineDecl) -> Result<()> {
        let origin = Origin::Builtin("displacement in physical units".into());
        pipeline::position(decl, "src")?;
        let mut st = pipeline::new_stage("disp", "displacement", &["src"], origin.clone());
        if !self.rois.is_empty() {
            let v = self
                .rois
                .iter()
                .flatten()
                .map(|&n| Value::Integer(i64::from(n)))
                .collect();
            set_param(&mut st, "rois", Value::Array(v), pipeline::by("--roi"));
        }
        decl.stages.push(st);
        let mut out = pipeline::new_stage("disp_out", "csv", &["disp"], origin.clone());
        set_param(&mut out, "path", path_value(self.temp.path()), origin);
        decl.stages.push(out);
        Ok(())
    }

    /// The regions' waveforms, after the run.
    pub fn read(&self) -> Result<Vec<RegionMotion>> {
        let p = self.temp.path();
        let text = std::fs::read_to_string(p)
            .with_context(|| format!("{}: cannot read the displacement", p.display()))?;
        let n = self.rois.len().max(1);
        let mut regions: Vec<RegionMotion> = (0..n)
            .map(|k| RegionMotion {
                roi: self.rois.get(k).copied(),
                ..RegionMotion::default()
            })
            .collect();
        let mut t_s = Vec::new();
        for (i, line) in text.lines().enumerate().skip(1) {
            let v: std::result::Result<Vec<f64>, _> =
                line.split(',').map(str::parse::<f64>).collect();
            let v = match v {
                Ok(v) if v.len() == 1 + 2 * n => v,
                _ => {
                    return Err(anyhow::anyhow!(
                        "{}:{}: not a displacement row of {} regions: `{line}`",
                        p.display(),
                        i + 1,
                        n
                    )
                    .into())
                }
            };
            t_s.push(v[0]);
            for (k, r) in regions.iter_mut().enumerate() {
                r.x.push(v[1 + 2 * k] as f32);
                r.y.push(v[2 + 2 * k] as f32);
            }
        }
        let rate_hz = match (t_s.first(), t_s.last()) {
            (Some(a), Some(b)) if t_s.len() > 1 && b > a => (t_s.len() - 1) as f64 / (b - a),
            _ => f64::NAN,
        };
        for r in &mut regions {
            r.rate_hz = rate_hz;
            r.t_s.clone_from(&t_s);
        }
        Ok(regions)
    }
}

/// How the reported motion was measured and in which unit.
#[derive(Clone, Debug, Serialize)]
pub struct MotionSummary {
    /// The unit of every `amplitude` (and waveform value) of this report.
    pub unit: Unit,
    pub quantity: Quantity,
    /// Pixels to millimetres; absent: the values are in pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// The region measured, `[x, y, w, h]`; absent: the whole frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roi: Option<[u32; 4]>,
    pub method: &'static str,
}

/// What [`MotionSummary::method`] says.
pub const METHOD: &str = "2-D least-squares displacement of the region against the first frame (7-tap gradient); amplitude: the sinusoid fitted at the peak's frequency over the recording, x and y in quadrature";

/// Sets each peak's `amplitude` (of `quantity`, in the unit chosen for the
/// largest of them) from region `r`'s displacement.
pub fn peak_amplitudes(
    report: &mut SpectrumReport,
    r: &RegionMotion,
    scale: Option<&Scale>,
    quantity: Quantity,
) -> MotionSummary {
    let search = report.resolution_hz;
    let px: Vec<f64> = report
        .peaks
        .iter()
        .map(|p| {
            let (a, f) = tone_amplitude(&[&r.x, &r.y], r.rate_hz, p.frequency_hz, search);
            a * quantity.gain(f)
        })
        .collect();
    let largest = px
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let unit = Scale::unit(scale, quantity, largest);
    let k = px_to(unit, scale);
    for (p, a) in report.peaks.iter_mut().zip(px) {
        p.amplitude = Some(a * k);
    }
    MotionSummary {
        unit,
        quantity,
        scale: scale.copied(),
        roi: r.roi,
        method: METHOD,
    }
}
