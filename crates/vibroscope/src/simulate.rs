//! Render a scene file through the forward model to a Y4M recording: the
//! shipped `render` pipeline with its camera's parameters replaced by the
//! scene file's (one code path with the `synthetic` source; validation
//! names the file and the field).

use crate::engine::config::{apply_set, set_param, Origin};
use crate::engine::RunReport;
use crate::error::{Error, Result};
use crate::pipeline::{self, by, path_value, RunSettings};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What `simulate` is asked.
#[derive(Clone, Debug, Default)]
pub struct SimulateOptions {
    /// The scene file: the `synthetic` source's parameters at its top level.
    pub scene: PathBuf,
    /// Output Y4M (`-` for standard output).
    pub output: PathBuf,
    /// `KEY=VALUE` overrides of scene parameters (VALUE in TOML).
    pub set: Vec<String>,
    pub run: RunSettings,
}

/// What `simulate` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct SimulateReport {
    pub output: PathBuf,
    pub frames: u64,
    #[serde(skip)]
    pub run: Option<std::sync::Arc<RunReport>>,
}

/// A configuration error about the camera stage, told against the user's
/// scene file (its line when the field is in the file; no line when the
/// field took its default), not the shipped `render` pipeline it fills.
fn in_scene(e: Error, scene: &Path, keys: &[String]) -> Error {
    match e {
        Error::Config(mut c) if c.stage.as_deref() == Some("cam") => {
            let given = c
                .field
                .as_deref()
                .is_some_and(|f| keys.iter().any(|k| k == f));
            c.origin = match c.origin {
                Some(Origin::Line(n)) if given && n > 0 => Some(Origin::Line(n)),
                Some(Origin::Set(s)) => Some(Origin::Set(s)),
                _ => None,
            };
            c.file = scene.display().to_string();
            c.stage = None;
            Error::Config(c)
        }
        e => e,
    }
}

/// Runs `simulate`.
pub fn simulate(o: &SimulateOptions) -> Result<SimulateReport> {
    let scene = &o.scene;
    crate::error::check_outputs(&[scene], &[&o.output])?;
    let text = std::fs::read_to_string(scene)
        .map_err(|e| Error::input(scene, format!("cannot read: {e}")))?;
    let table: toml::Table = toml::from_str(&text)
        .map_err(|e| crate::engine::config::toml_error(&scene.display().to_string(), &text, &e))?;
    let mut decl = pipeline::load("render")?;
    let cam = pipeline::stage_mut(&mut decl, "cam")?;
    cam.params.clear();
    let keys: Vec<String> = table.keys().cloned().collect();
    for (k, v) in table {
        // Name the scene file and the key's line in errors.
        let line = text
            .lines()
            .position(|l| {
                l.trim_start()
                    .strip_prefix(k.as_str())
                    .is_some_and(|r| r.trim_start().starts_with('='))
            })
            .map_or(0, |i| i + 1);
        set_param(cam, &k, v, Origin::Line(line));
    }
    for s in &o.set {
        apply_set(&mut decl, &format!("cam.{s}"))?;
    }
    pipeline::set(&mut decl, "out", "path", path_value(&o.output), by("-o"))?;
    let to_stdout = o.output == Path::new("-");
    let run = pipeline::run(
        &decl,
        RunSettings {
            progress: o.run.progress && !to_stdout,
        },
    )
    .map_err(|e| in_scene(e, scene, &keys))?;
    let frames = run
        .stages
        .iter()
        .find(|s| s.id == "out")
        .map_or(0, |s| s.items_in);
    Ok(SimulateReport {
        output: o.output.clone(),
        frames,
        run: Some(std::sync::Arc::new(run)),
    })
}
