//! Time-domain damping for `spectrum`: the graph also writes the extracted
//! motion (`phase` → `align`, the bands summed as in `listen`, no
//! high-pass) to a WAV; after the run every peak gets an SSI-cov estimate
//! ([`crate::math::ssi`]) in its `damping_estimates` (`"method":
//! "ssi_cov"`, with the pole's frequency, the stable orders and block rows
//! used), and a peak the spectrum cannot resolve (`resolved: false`) takes
//! it as its `damping_ratio` and `damping_method`.

use crate::engine::config::{set_param, PipelineDecl};
use crate::engine::Origin;
use crate::error::Result;
use crate::io::atomic::TempPath;
use crate::math::ssi::{identify, SsiOptions};
use crate::peaks::{DampingEstimate, SpectrumReport, SsiDetail};
use crate::pipeline::{self, path_value};
use std::path::{Path, PathBuf};

/// Where the motion goes: a file the user keeps, or a scratch file.
pub struct MotionTap {
    kept: Option<PathBuf>,
    temp: TempPath,
}

impl MotionTap {
    /// Adds `phase` → `align` → WAV to the spectrum graph (its `phase` stage
    /// is the shared input).
    pub fn add(decl: &mut PipelineDecl, keep: Option<PathBuf>) -> Result<MotionTap> {
        let tap = MotionTap {
            kept: keep,
            temp: TempPath::new("motion.wav"),
        };
        let origin = Origin::Builtin("spectrum (time-domain damping)".into());
        pipeline::position(decl, "phase")?;
        decl.stages.push(pipeline::new_stage(
            "ssi_align",
            "align",
            &["phase"],
            origin.clone(),
        ));
        let mut wav = pipeline::new_stage("ssi_motion", "wav", &["ssi_align"], origin.clone());
        set_param(&mut wav, "path", path_value(tap.path()), origin);
        decl.stages.push(wav);
        Ok(tap)
    }

    pub fn path(&self) -> &Path {
        self.kept.as_deref().unwrap_or(self.temp.path())
    }

    /// Adds the SSI-cov estimates to the peaks of `report`.
    pub fn refine(&self, report: &mut SpectrumReport, opts: &SsiOptions) -> Result<()> {
        let (_, y) = crate::io::wav::read_mono(self.path())?;
        add_ssi(report, &y, opts);
        Ok(())
    }
}

/// SSI-cov per peak of `report`, on the motion `y` sampled at the report's
/// rate (the WAV's integer rate may round the frame rate).
pub fn add_ssi(report: &mut SpectrumReport, y: &[f64], opts: &SsiOptions) {
    let fs = report.sample_rate_hz;
    let df = report.resolution_hz;
    for pk in &mut report.peaks {
        let f = pk.frequency_hz;
        if !f.is_finite() {
            continue;
        }
        let tol = (2.0 * df).max(0.01 * f);
        let Some(m) = identify(y, fs, f, tol, opts) else {
            continue;
        };
        pk.damping_estimates.push(DampingEstimate {
            method: "ssi_cov".into(),
            damping_ratio: m.damping_ratio,
            damping_ratio_std: m.damping_ratio_std,
            ssi: Some(SsiDetail {
                frequency_hz: m.frequency_hz,
                order_std: m.order_std,
                segment_std: m.segment_std,
                stable_orders: m.stable_orders,
                block_rows: m.block_rows,
            }),
        });
        if !pk.resolved {
            pk.damping_ratio = m.damping_ratio;
            pk.damping_ratio_std = m.damping_ratio_std;
            pk.damping_method = "ssi_cov".into();
        }
    }
}
