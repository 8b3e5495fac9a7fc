//! `vibroscope spectrum --png/--spectrogram`: plot sinks added to the
//! spectrum graph.

use crate::engine::config::{set_param, InputDecl, Origin, PipelineDecl};
use std::path::Path;
use toml::Value;

/// What `spectrum` plots.
pub(super) struct PlotArgs<'a> {
    pub png: Option<&'a Path>,
    pub spectrogram: Option<&'a Path>,
    /// Sliding window of the spectrogram, frames (hop: an eighth of it).
    pub window: usize,
    pub peaks: usize,
    pub min_hz: Option<f64>,
    pub max_hz: Option<f64>,
}

/// Adds `plot` (power spectrum PNG, fed by `spectrum`) and
/// `spectrogram_spectrum` -> `spectrogram` (sliding spectra from `phase`).
pub(super) fn add_plots(decl: &mut PipelineDecl, a: &PlotArgs<'_>) -> anyhow::Result<()> {
    let pos = |decl: &PipelineDecl, id: &str| decl.stages.iter().position(|s| s.id == id);
    let (Some(spec), Some(out)) = (pos(decl, "spectrum"), pos(decl, "out")) else {
        anyhow::bail!("the spectrum graph lacks a stage `spectrum` or `out`");
    };
    let o = |s: &str| Origin::Set(s.to_string());
    let band = |st: &mut crate::engine::config::StageDecl| {
        for (key, v) in [("min_hz", a.min_hz), ("max_hz", a.max_hz)] {
            if let Some(f) = v {
                let flag = format!("--{}", key.replace('_', "-"));
                set_param(st, key, Value::Float(f), o(&flag));
            }
        }
    };
    // A sink like `out` (fed by `spectrum`), of kind spectrum_png.
    let sink = |decl: &PipelineDecl, id: &str, path: &Path, flag: &str| {
        let mut st = decl.stages[out].clone();
        st.id = id.into();
        st.kind = "spectrum_png".into();
        st.kind_origin = o(flag);
        st.params.clear();
        set_param(
            &mut st,
            "path",
            Value::String(path.display().to_string()),
            o(flag),
        );
        st
    };
    if let Some(p) = a.png {
        let mut st = sink(decl, "plot", p, "--png");
        let n = i64::try_from(a.peaks).unwrap_or(i64::MAX).min(100);
        set_param(&mut st, "peaks", Value::Integer(n), o("--peaks"));
        band(&mut st);
        decl.stages.push(st);
    }
    if let Some(p) = a.spectrogram {
        let flag = "--spectrogram-window";
        let mut sp = decl.stages[spec].clone();
        sp.id = "spectrogram_spectrum".into();
        sp.params.clear();
        let w = i64::try_from(a.window).unwrap_or(i64::MAX);
        set_param(
            &mut sp,
            "mode",
            Value::String("sliding".into()),
            o("--spectrogram"),
        );
        set_param(&mut sp, "window", Value::Integer(w), o(flag));
        set_param(&mut sp, "hop", Value::Integer((w / 8).max(1)), o(flag));
        decl.stages.push(sp);
        let mut st = sink(decl, "spectrogram", p, "--spectrogram");
        st.inputs = vec![InputDecl {
            from: "spectrogram_spectrum".into(),
            capacity: None,
            policy: None,
            origin: o("--spectrogram"),
        }];
        set_param(
            &mut st,
            "style",
            Value::String("spectrogram".into()),
            o("--spectrogram"),
        );
        band(&mut st);
        decl.stages.push(st);
    }
    Ok(())
}
