//! What a pipeline and this build hold: the shipped pipelines, the
//! kinds' listing and tables, and the files a pipeline reads and writes.

use crate::engine;
use crate::engine::config::PipelineDecl;
use crate::pipelines;
use crate::stages;
use std::path::{Path, PathBuf};
use toml::Value;
/// The shipped pipelines: name and description.
pub fn shipped() -> Vec<(&'static str, String)> {
    pipelines::SHIPPED
        .iter()
        .map(|s| (s.name, pipelines::description(s)))
        .collect()
}

/// Every stage kind, one line each: name, role and what it does.
pub fn kind_listing() -> String {
    engine::spec::listing(stages::registry())
}

/// One kind's declaration as a table: ports, then each parameter's name,
/// type, default, range, unit and doc; `None` for an unknown kind.
pub fn kind_table(name: &str) -> Option<String> {
    stages::kind(name).map(|k| k.describe())
}

/// The existing files `decl` may read: the pipeline's own file and every
/// string parameter naming an existing file (at any depth, e.g. a scene's
/// `signal = { type = "wav", path = ... }`), except the sinks' `path`s.
pub fn input_files(decl: &PipelineDecl) -> Vec<PathBuf> {
    fn walk(v: &Value, out: &mut Vec<PathBuf>) {
        match v {
            Value::String(s) if s != "-" && Path::new(s).is_file() => out.push(PathBuf::from(s)),
            Value::Array(a) => a.iter().for_each(|v| walk(v, out)),
            Value::Table(t) => t.values().for_each(|v| walk(v, out)),
            _ => {}
        }
    }
    let mut out = Vec::new();
    if Path::new(&decl.file).is_file() {
        out.push(PathBuf::from(&decl.file));
    }
    for s in &decl.stages {
        let sink = stages::kind(&s.kind).is_some_and(|k| k.output() == engine::Output::None);
        for p in s.params() {
            if !(sink && p.key == "path") {
                walk(&p.value, &mut out);
            }
        }
    }
    out
}

/// The files the sinks of `decl` write (their `path`, not `-`).
pub fn outputs(decl: &PipelineDecl) -> Vec<PathBuf> {
    decl.stages
        .iter()
        .filter(|s| stages::kind(&s.kind).is_some_and(|k| k.output() == engine::Output::None))
        .filter_map(|s| s.params().iter().find(|p| p.key == "path"))
        .filter_map(|p| p.value.as_str())
        .filter(|p| *p != "-")
        .map(PathBuf::from)
        .collect()
}
