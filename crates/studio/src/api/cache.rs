//! The cache of computed answers: their keys (the file's identity, the region and the
//! request), keeping and finding them, and answering from them with the fields that stay
//! on the server taken out.

use serde_json::{json, Value};
use std::path::Path;
use std::sync::Arc;

use super::App;

/// At most this many computed answers are kept (then the cache starts over).
const CACHE_ENTRIES: usize = 64;

/// A cache key naming the file's identity (path, size, modification time).
pub(super) fn file_key(path: &Path) -> String {
    let meta = std::fs::metadata(path).ok();
    let len = meta.as_ref().map_or(0, |m| m.len());
    let mtime = meta
        .and_then(|m| m.modified().ok())
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    format!("{}|{len}|{mtime}", path.display())
}

pub(super) fn cached(app: &App, key: &str) -> Option<Arc<Value>> {
    app.cache
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .get(key)
        .cloned()
}

pub(super) fn remember(app: &App, key: String, v: Value) -> Arc<Value> {
    let v = Arc::new(v);
    let mut c = app.cache.lock().unwrap_or_else(|p| p.into_inner());
    if c.len() >= CACHE_ENTRIES {
        c.clear();
    }
    c.insert(key, v.clone());
    v
}

/// A cached answer's field that stays on the server: the motion signal
/// the region's spectrum was computed from (the damping view's SSI).
pub(super) const PRIVATE_MOTION: &str = "_motion";

/// A computed answer's mark: send it, do not keep it (too large).
pub(crate) const PRIVATE_NO_CACHE: &str = "_no_cache";

/// Answers from the cache, marking them so (`"cached": true`).
pub(super) fn answer(v: &Value, cached: bool, ms: f64) -> axum::Json<Value> {
    let mut v = v.clone();
    if let Some(o) = v.as_object_mut() {
        o.remove(PRIVATE_MOTION);
    }
    v["cached"] = json!(cached);
    v["elapsed_ms"] = json!(ms);
    axum::Json(v)
}

/// The cache key of a region's answer (`what`: its recipe's tag).
pub(super) fn region_key(
    what: &str,
    path: &Path,
    roi: Option<[u32; 4]>,
    mask: Option<&str>,
    fps: Option<f64>,
) -> String {
    use std::hash::{Hash, Hasher};
    let mask = mask.map(|m| {
        let mut h = std::hash::DefaultHasher::new();
        m.hash(&mut h);
        (h.finish(), m.len())
    });
    format!("{what}|{}|{roi:?}|{mask:?}|{fps:?}", file_key(path))
}
