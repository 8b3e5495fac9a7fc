//! Vibrometry on recordings (issue 5, thesis ch. 5): time-domain damping
//! added to `vibroscope spectrum` ([`damping`]), clamped rods
//! (`vibroscope rod`, [`rod`]) and per-region change between two recordings
//! (`vibroscope compare`, [`compare`]). The math lives in
//! [`crate::analysis`]; these modules run the spectrum graph and write JSON.

pub mod compare;
pub mod damping;
pub mod rod;

use crate::engine::config::{self, PipelineDecl};
use std::path::Path;

pub use crate::io::atomic::TempPath;

/// Appends stages written as pipeline TOML to `decl`.
pub(crate) fn append_stages(decl: &mut PipelineDecl, toml_text: &str) -> anyhow::Result<()> {
    let extra = config::parse(&format!("{} (added stages)", decl.file), toml_text)?;
    decl.stages.extend(extra.stages);
    Ok(())
}

/// A path as a TOML string literal.
pub(crate) fn toml_path(p: &Path) -> String {
    toml::Value::String(p.display().to_string()).to_string()
}
