//! The JSON documents the recipes write and read back, with errors that
//! name the file.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::Path;

/// Writes `value` as pretty JSON (ending in a newline) to `path`,
/// atomically: a reader sees the old file or the whole new one.
pub fn write<T: Serialize + ?Sized>(path: &Path, value: &T) -> Result<()> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| Error::Document {
        path: path.to_path_buf(),
        message: format!("cannot encode the document: {e}"),
    })?;
    bytes.push(b'\n');
    crate::io::atomic::write_atomic(path, &bytes)?;
    Ok(())
}

/// Reads the JSON document `what` (e.g. "the peaks document") from `path`.
pub fn read<T: DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    let doc = |message: String| Error::Document {
        path: path.to_path_buf(),
        message,
    };
    let text = std::fs::read(path).map_err(|e| doc(format!("cannot read {what}: {e}")))?;
    serde_json::from_slice(&text).map_err(|e| doc(format!("not {what}: {e}")))
}
