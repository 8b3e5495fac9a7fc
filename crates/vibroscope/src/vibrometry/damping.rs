//! Time-domain damping for `vibroscope spectrum`: the graph also writes the
//! extracted motion (`phase` → `align`, the bands summed as in `listen`,
//! no high-pass) to a WAV; after the run every peak of the JSON gets an
//! SSI-cov estimate ([`crate::math::ssi`]) in its `damping_estimates`
//! (`"method": "ssi_cov"`, with the pole's frequency, the stable orders and
//! block rows used), and a peak the spectrum cannot resolve
//! (`"resolved": false`) takes it as its `damping_ratio` and
//! `damping_method`.

use super::{append_stages, toml_path, TempPath};
use crate::engine::config::PipelineDecl;
use crate::math::ssi::{identify, SsiOptions};
use anyhow::Context;
use std::path::{Path, PathBuf};

/// Where the motion goes: a file the user keeps, or a scratch file.
pub struct MotionTap {
    kept: Option<PathBuf>,
    temp: TempPath,
}

impl MotionTap {
    /// Adds `phase` → `align` → WAV to the spectrum graph (its `phase` stage
    /// is the shared input).
    pub fn add(decl: &mut PipelineDecl, keep: Option<PathBuf>) -> anyhow::Result<MotionTap> {
        let tap = MotionTap {
            kept: keep,
            temp: TempPath::new("motion.wav"),
        };
        let text = format!(
            "[[stage]]\nid = \"ssi_align\"\nkind = \"align\"\ninput = \"phase\"\n\
             [[stage]]\nid = \"ssi_motion\"\nkind = \"wav\"\ninput = \"ssi_align\"\npath = {}\n",
            toml_path(tap.path())
        );
        append_stages(decl, &text)?;
        Ok(tap)
    }

    pub fn path(&self) -> &Path {
        self.kept.as_deref().unwrap_or(self.temp.path())
    }

    /// Adds the SSI-cov estimates to the peaks of the JSON at `json`.
    pub fn refine(&self, json: &Path, opts: &SsiOptions) -> anyhow::Result<()> {
        let text =
            std::fs::read(json).with_context(|| format!("{}: cannot read", json.display()))?;
        let mut doc: serde_json::Value = serde_json::from_slice(&text)
            .with_context(|| format!("{}: not the peaks JSON", json.display()))?;
        let mut r = hound::WavReader::open(self.path())
            .with_context(|| format!("{}: cannot read the motion", self.path().display()))?;
        let y: Vec<f64> = r
            .samples::<f32>()
            .map(|s| s.map(f64::from))
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}: cannot read the motion", self.path().display()))?;
        add_ssi(&mut doc, &y, opts);
        let bytes = serde_json::to_vec_pretty(&doc)?;
        crate::stages::sinks::write_atomic(json, &bytes)?;
        Ok(())
    }
}

/// SSI-cov per peak of a peaks document (`sample_rate_hz`, `resolution_hz`,
/// `peaks`), on the motion `y` sampled at the document's rate (the WAV's
/// integer rate may round the frame rate).
pub fn add_ssi(doc: &mut serde_json::Value, y: &[f64], opts: &SsiOptions) {
    let fs = doc["sample_rate_hz"].as_f64().unwrap_or(0.0);
    let df = doc["resolution_hz"].as_f64().unwrap_or(0.0);
    let Some(peaks) = doc["peaks"].as_array_mut() else {
        return;
    };
    for pk in peaks {
        let Some(f) = pk["frequency_hz"].as_f64() else {
            continue;
        };
        let tol = (2.0 * df).max(0.01 * f);
        let Some(m) = identify(y, fs, f, tol, opts) else {
            continue;
        };
        let est = serde_json::json!({
            "method": "ssi_cov",
            "damping_ratio": m.damping_ratio,
            "damping_ratio_std": m.damping_ratio_std,
            "frequency_hz": m.frequency_hz,
            "order_std": m.order_std,
            "segment_std": m.segment_std,
            "stable_orders": m.stable_orders,
            "block_rows": m.block_rows,
        });
        if let Some(list) = pk["damping_estimates"].as_array_mut() {
            list.push(est);
        }
        if pk["resolved"].as_bool() == Some(false) {
            pk["damping_ratio"] = m.damping_ratio.into();
            pk["damping_ratio_std"] = m.damping_ratio_std.into();
            pk["damping_method"] = "ssi_cov".into();
        }
    }
}
