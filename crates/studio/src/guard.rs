//! What the studio lets in: files only under the root given at start, and
//! (when bound beyond the loopback address) only requests carrying the token
//! printed in the URL.

use std::path::{Component, Path, PathBuf};

/// Why a file name is refused, with the HTTP status it earns.
#[derive(Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Malformed (empty, NUL, backslash): 400.
    Bad(String),
    /// Leaves the root (`..`, absolute, a symlink out): 403.
    Outside(String),
    /// Does not exist: 404.
    Missing(String),
}

/// `rel` resolved under `root` (canonical): a relative path of normal
/// components whose real location (symlinks followed) is inside `root`.
pub fn resolve(root: &Path, rel: &str) -> Result<PathBuf, Refusal> {
    if rel.is_empty() {
        return Err(Refusal::Bad("no file named".into()));
    }
    if rel.contains('\0') || rel.contains('\\') {
        return Err(Refusal::Bad(format!(
            "{rel:?}: NUL or backslash in a file name"
        )));
    }
    let p = Path::new(rel);
    for c in p.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => {
                return Err(Refusal::Outside(format!("{rel:?}: `..` is not allowed")))
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(Refusal::Outside(format!(
                    "{rel:?}: absolute paths are not allowed; name a file under the studio's root"
                )))
            }
        }
    }
    let joined = root.join(p);
    let real = joined
        .canonicalize()
        .map_err(|e| Refusal::Missing(format!("{rel:?}: {e}")))?;
    if !real.starts_with(root) {
        return Err(Refusal::Outside(format!(
            "{rel:?} leads outside the studio's root (a symlink out)"
        )));
    }
    if !real.is_file() {
        return Err(Refusal::Bad(format!("{rel:?} is not a file")));
    }
    Ok(real)
}

/// True when the raw request path holds an encoded slash or backslash
/// (`%2F`, `%5C`): refused before routing, so no decoding step can turn
/// one segment into two.
pub fn has_encoded_separator(raw_path: &str) -> bool {
    let l = raw_path.to_ascii_lowercase();
    l.contains("%2f") || l.contains("%5c") || l.contains("%00")
}

/// A fresh random token (32 hex digits from the operating system's
/// random source; the standard library's randomly keyed hasher where
/// `/dev/urandom` is absent).
pub fn new_token() -> String {
    let mut bytes = [0u8; 16];
    let ok = std::fs::File::open("/dev/urandom")
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut bytes))
        .is_ok();
    if !ok {
        use std::hash::{BuildHasher, Hasher};
        for (i, chunk) in bytes.chunks_mut(8).enumerate() {
            let mut h = std::collections::hash_map::RandomState::new().build_hasher();
            h.write_usize(i);
            h.write_u128(
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos()),
            );
            chunk.copy_from_slice(&h.finish().to_le_bytes());
        }
    }
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Compares without stopping at the first difference.
pub fn same_token(given: &str, expected: &str) -> bool {
    let (a, b) = (given.as_bytes(), expected.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn refuses_what_leaves_the_root() {
        let d = tempfile::tempdir().unwrap();
        let root = d.path().canonicalize().unwrap();
        std::fs::write(root.join("a.y4m"), b"x").unwrap();
        assert!(resolve(&root, "a.y4m").is_ok());
        assert!(resolve(&root, "./a.y4m").is_ok());
        assert!(matches!(
            resolve(&root, "../a.y4m"),
            Err(Refusal::Outside(_))
        ));
        assert!(matches!(
            resolve(&root, "x/../../a"),
            Err(Refusal::Outside(_))
        ));
        assert!(matches!(
            resolve(&root, "/etc/passwd"),
            Err(Refusal::Outside(_))
        ));
        assert!(matches!(resolve(&root, "nope"), Err(Refusal::Missing(_))));
        assert!(matches!(resolve(&root, ""), Err(Refusal::Bad(_))));
        assert!(matches!(resolve(&root, "a\\b"), Err(Refusal::Bad(_))));
        assert!(has_encoded_separator("/api/x%2F..%2fy"));
        assert!(!has_encoded_separator("/api/info"));
        assert!(same_token("abc", "abc") && !same_token("abd", "abc") && !same_token("ab", "abc"));
        assert_eq!(new_token().len(), 32);
        assert_ne!(new_token(), new_token());
    }
}
