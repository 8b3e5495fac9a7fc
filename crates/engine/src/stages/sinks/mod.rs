pub mod csv;
pub mod json;
pub mod modes;
pub mod null;
pub mod peaks;
pub mod spectrum_png;
pub mod tap;
pub mod wav;
pub mod y4m;

use crate::StageError;
use std::path::Path;

/// Creates `path` (and reports which file could not be created).
pub fn create(path: &Path) -> Result<std::fs::File, StageError> {
    std::fs::File::create(path).map_err(|e| StageError::file("create", path, e))
}

/// Creates the temporary sibling a streaming sink writes, renamed to `path`
/// on finish (see [`vibroscope_io::atomic::Pending`]).
pub fn create_pending(
    path: &Path,
) -> Result<(vibroscope_io::atomic::Pending, std::fs::File), StageError> {
    vibroscope_io::atomic::Pending::create(path).map_err(|e| StageError::file("create", path, e))
}

/// Writes a whole file atomically (see [`vibroscope_io::atomic::write_atomic`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), StageError> {
    vibroscope_io::atomic::write_atomic(path, bytes)
        .map_err(|e| StageError::file("write", path, e.source))
}
