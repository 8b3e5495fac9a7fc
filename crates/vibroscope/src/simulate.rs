//! Render a scene file through the forward model to a Y4M recording: the
//! shipped `render` pipeline with its camera's parameters replaced by the
//! scene file's (one code path with the `synthetic` source; validation
//! names the file and the field).

use crate::engine::config::apply_set;
use crate::engine::RunReport;
use crate::error::Result;
use crate::pipeline::{self, by, RunSettings, SceneFile};
use crate::pipelines::stage::render;
use crate::stages::params::Y4mParams;
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

/// Runs `simulate`.
pub fn simulate(o: &SimulateOptions) -> Result<SimulateReport> {
    let scene = &o.scene;
    crate::error::check_outputs(&[scene], &[&o.output])?;
    let file = SceneFile::read(scene)?;
    let mut decl = pipeline::load("render")?;
    file.fill(&mut decl, "cam")?;
    for s in &o.set {
        apply_set(&mut decl, &format!("cam.{s}"))?;
    }
    pipeline::set(
        &mut decl,
        render::OUT,
        Y4mParams::path,
        o.output.clone(),
        by("-o"),
    )?;
    let to_stdout = o.output == Path::new("-");
    let run = pipeline::run(
        &decl,
        RunSettings {
            progress: o.run.progress && !to_stdout,
        },
    )
    .map_err(|e| file.told(e, "cam"))?;
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
