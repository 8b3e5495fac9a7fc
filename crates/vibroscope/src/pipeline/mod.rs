//! Pipelines as values: load one (a file or a shipped name), edit it with
//! typed operations (replay a recording, set the frame rate, add or rewire
//! stages), and run it.

use crate::engine::config::{self, ConfigError, Origin, PipelineDecl};
use crate::engine::spec::KindParams;
use crate::error::{Error, Result};
use crate::pipelines;
use crate::stages;
use crate::stages::params::{FileParams, NokhwaParams, PatternParams, V4l2Params};
use crate::stages::sources::synthetic::SyntheticParams;
use std::path::{Path, PathBuf};

mod catalog;
mod edit;
mod options;
mod run;
pub use catalog::*;
pub use edit::*;
pub use options::*;
pub use run::*;

/// A shipped pipeline or a pipeline file, with command-line changes.
#[derive(Clone, Debug, Default)]
pub struct PipelineOptions {
    /// Pipeline file, or a shipped pipeline's name.
    pub pipeline: String,
    /// `STAGE.KEY=VALUE` overrides (VALUE is TOML).
    pub set: Vec<String>,
    /// Replace the source with this recording.
    pub replay: Option<PathBuf>,
    /// The source's capture rate (Hz).
    pub fps: Option<f64>,
}

/// A pipeline file, or a shipped pipeline by name.
pub fn load(pipeline: &str) -> Result<PipelineDecl, ConfigError> {
    let path = Path::new(pipeline);
    if path.exists() {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: pipeline.to_string(),
            origin: None,
            stage: None,
            field: None,
            message: format!("cannot read: {e}"),
        })?;
        return config::parse(pipeline, &text);
    }
    if let Some(s) = pipelines::find(pipeline) {
        return config::parse(&format!("pipelines/{}.toml (shipped)", s.name), s.text);
    }
    let names: Vec<&str> = pipelines::SHIPPED.iter().map(|s| s.name).collect();
    Err(ConfigError {
        file: pipeline.to_string(),
        origin: None,
        stage: None,
        field: None,
        message: format!(
            "no such file, and no shipped pipeline of that name (shipped: {})",
            names.join(", ")
        ),
    })
}

/// Loads a pipeline and applies `set`, `replay` and `fps`, in that order.
pub fn prepare(o: &PipelineOptions) -> Result<PipelineDecl> {
    let mut decl = load(&o.pipeline)?;
    for s in &o.set {
        config::apply_set(&mut decl, s)?;
    }
    if let Some(path) = &o.replay {
        apply_replay(&mut decl, path)?;
    }
    if let Some(f) = o.fps {
        apply_fps(&mut decl, f)?;
    }
    Ok(decl)
}

/// The one source of `decl`, for an option (`what`) that changes it.
fn one_source(decl: &PipelineDecl, what: &str) -> Result<usize> {
    let src: Vec<usize> = decl
        .stages
        .iter()
        .enumerate()
        .filter(|(_, s)| stages::kind(&s.kind).is_some_and(|k| k.is_source()))
        .map(|(i, _)| i)
        .collect();
    let message = match src.as_slice() {
        [i] => return Ok(*i),
        [] => "the pipeline has no source stage".to_string(),
        many => {
            let ids: Vec<&str> = many.iter().map(|&i| decl.stages[i].id.as_str()).collect();
            format!(
                "the pipeline has several sources ({}); use --set ID.path=... instead",
                ids.join(", ")
            )
        }
    };
    Err(Error::input(&decl.file, format!("{what}: {message}")))
}

/// The id of `decl`'s one source (none when it has none or several).
pub fn source_id(decl: &PipelineDecl) -> Option<&str> {
    one_source(decl, "")
        .ok()
        .map(|i| decl.stages[i].id.as_str())
}

/// Replay: the source becomes a `file` source of the same id, feeding the
/// same stages; every edge blocks (a replay never drops).
pub fn apply_replay(decl: &mut PipelineDecl, path: &Path) -> Result<()> {
    replay_source(decl, path, false)?;
    block_every_edge(decl);
    Ok(())
}

/// The one source of `decl` becomes a `file` source of the same id
/// reading `path` (`realtime`: at the recording's own pace).
fn replay_source(decl: &mut PipelineDecl, path: &Path, realtime: bool) -> Result<()> {
    let i = one_source(decl, "--replay")?;
    let origin = Origin::Builtin(format!("--replay {}", path.display()));
    let file = decl.file.clone();
    let st = &mut decl.stages[i];
    st.kind = FileParams::KINDS[0].into();
    st.kind_origin = origin.clone();
    st.clear_params();
    st.set(&file, FileParams::path, path.to_path_buf(), origin.clone())?;
    if realtime {
        st.set(&file, FileParams::realtime, true, origin)?;
    }
    Ok(())
}

/// Live replay (the studio's `--replay`): the source becomes a `file`
/// source of the same id that plays `path` at the recording's own pace,
/// like the camera that made it; the edges keep their policies, so a
/// stage that falls behind drops as it would live (and counts it).
pub fn apply_live_replay(decl: &mut PipelineDecl, path: &Path) -> Result<()> {
    replay_source(decl, path, true)
}

/// Every edge blocks: a recording (or a scene rendered as fast as it can
/// be) is never dropped from.
fn block_every_edge(decl: &mut PipelineDecl) {
    for s in &mut decl.stages {
        s.policy = None;
        for inp in &mut s.inputs {
            inp.policy = None;
        }
    }
}

/// A scene file: the `synthetic` source's parameters at its top level
/// (`vibroscope simulate`'s input, `learn generate`'s takes).
#[derive(Clone, Debug)]
pub struct SceneFile {
    pub path: PathBuf,
    text: String,
    table: toml::Table,
}

impl SceneFile {
    /// Reads and parses a scene file (errors name the file and the line).
    pub fn read(path: &Path) -> Result<SceneFile> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
        let table: toml::Table = toml::from_str(&text)
            .map_err(|e| config::toml_error(&path.display().to_string(), &text, &e))?;
        Ok(SceneFile {
            path: path.to_path_buf(),
            text,
            table,
        })
    }

    /// The scene as the `synthetic` source reads it: its declared
    /// defaults for what the file omits, its ranges and its checks; errors
    /// name the file, the line and the field.
    pub fn synthetic(&self) -> Result<SyntheticParams> {
        let file = self.path.display().to_string();
        let mut decl = config::parse(&file, "[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\n")?;
        self.fill(&mut decl, "cam")?;
        let p = config::Params {
            file: &file,
            stage: &decl.stages[0],
        };
        // The `synthetic` kind's own plan: resolve, then check.
        let resolved = p
            .resolve_typed::<SyntheticParams>()
            .and_then(|v| v.check().map(|()| v).map_err(|(f, m)| p.error(f, m)));
        resolved.map_err(|e| self.told(Error::Config(e), "cam"))
    }

    /// The scene's parameters become stage `id`'s (which is made a
    /// `synthetic` source), each with its line in the file.
    pub fn fill(&self, decl: &mut PipelineDecl, id: &str) -> Result<()> {
        let st = stage_mut(decl, id)?;
        st.kind = SyntheticParams::KINDS[0].into();
        st.kind_origin = Origin::Builtin(format!("scene {}", self.path.display()));
        config::read_table(st, &self.table, |k| {
            let line = self
                .text
                .lines()
                .position(|l| {
                    l.trim_start()
                        .strip_prefix(k)
                        .is_some_and(|r| r.trim_start().starts_with('='))
                })
                .map_or(0, |i| i + 1);
            Origin::Line(line)
        });
        Ok(())
    }

    /// A configuration error about stage `id` (filled by [`Self::fill`]),
    /// told against the scene file: its line when the field is in the
    /// file, no line when the field took its default.
    pub fn told(&self, e: Error, id: &str) -> Error {
        match e {
            Error::Config(mut c) if c.stage.as_deref() == Some(id) => {
                let given = c
                    .field
                    .as_deref()
                    .is_some_and(|f| self.table.contains_key(f));
                c.origin = match c.origin {
                    Some(Origin::Line(n)) if given && n > 0 => Some(Origin::Line(n)),
                    Some(Origin::Set(s)) => Some(Origin::Set(s)),
                    _ => None,
                };
                c.file = self.path.display().to_string();
                c.stage = None;
                Error::Config(c)
            }
            e => e,
        }
    }
}

/// Scene replay: the source becomes the `synthetic` source of `scene`,
/// rendering the frames `vibroscope simulate` would write to a file, and
/// every edge blocks, as on a replay.
pub fn apply_scene(decl: &mut PipelineDecl, scene: &SceneFile) -> Result<()> {
    let i = one_source(decl, "a scene")?;
    let id = decl.stages[i].id.clone();
    scene.fill(decl, &id)?;
    block_every_edge(decl);
    Ok(())
}

/// Sets the source's capture rate (Hz).
pub fn apply_fps(decl: &mut PipelineDecl, fps: f64) -> Result<()> {
    let i = one_source(decl, "--fps")?;
    let file = decl.file.clone();
    let o = Origin::Set(format!("--fps {fps}"));
    let st = &mut decl.stages[i];
    if st.is::<FileParams>() {
        st.set(&file, FileParams::fps, Some(fps), o)?;
    } else if st.is::<SyntheticParams>() {
        st.set(&file, SyntheticParams::fps, fps, o)?;
    } else if st.is::<PatternParams>() {
        st.set(&file, PatternParams::fps, fps, o)?;
    } else if st.is::<V4l2Params>() {
        st.set(&file, V4l2Params::fps, Some(fps), o)?;
    } else if st.is::<NokhwaParams>() {
        // nokhwa asks the camera for a whole number of frames a second.
        if fps.fract() != 0.0 || !(1.0..=f64::from(u32::MAX)).contains(&fps) {
            return Err(Error::usage(
                "--fps",
                format!("the `nokhwa` source takes a whole number of frames a second, got {fps}"),
            ));
        }
        st.set(&file, NokhwaParams::fps, Some(fps as u32), o)?;
    } else {
        return Err(Error::input(
            &file,
            format!(
                "--fps: the source `{}` (a `{}`) has no frame rate to set",
                st.id, st.kind
            ),
        ));
    }
    Ok(())
}
