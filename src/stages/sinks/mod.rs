pub mod csv;
pub mod json;
pub mod modes;
pub mod null;
pub mod peaks;
pub mod speaker;
pub mod spectrum_png;
pub mod wav;
pub mod y4m;

use crate::engine::StageError;
use std::path::{Path, PathBuf};

/// Creates `path` (and reports which file could not be created).
pub fn create(path: &Path) -> Result<std::fs::File, StageError> {
    std::fs::File::create(path)
        .map_err(|e| StageError::msg(format!("cannot create {}: {e}", path.display())))
}

/// Writes a whole file atomically: a temporary sibling, then a rename, so a
/// reader never sees half a file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), StageError> {
    let mut tmp = PathBuf::from(path);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    tmp.set_file_name(format!(".{name}.partial"));
    std::fs::write(&tmp, bytes)
        .map_err(|e| StageError::msg(format!("cannot write {}: {e}", tmp.display())))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        StageError::msg(format!(
            "cannot rename {} to {}: {e}",
            tmp.display(),
            path.display()
        ))
    })
}
