//! Whole-file writes that a reader never sees half done, and scratch files
//! that clean up after themselves.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A file that could not be written, naming it.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {source}", path.display())]
pub struct WriteError {
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

/// A sibling of `path` no other writer uses: `.NAME.PID-N.partial`.
pub fn temp_sibling(path: &Path) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut tmp = PathBuf::from(path);
    tmp.set_file_name(format!(".{name}.{}-{n}.partial", std::process::id()));
    tmp
}

/// Writes a whole file atomically: a temporary sibling, then a rename, so a
/// reader never sees half a file. On error the temporary file is removed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let tmp = temp_sibling(path);
    let done = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    done.map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        WriteError {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// A file written as it goes under a unique temporary sibling
/// ([`temp_sibling`]) and renamed to its final path by [`Pending::commit`]:
/// two writers of one path each write their own file (the last rename
/// wins, neither splices into the other), and a reader of the final path
/// sees a previous whole file or the new whole file. Dropped without a
/// commit, the temporary file is removed.
#[derive(Debug)]
pub struct Pending {
    tmp: PathBuf,
    path: PathBuf,
    committed: bool,
}

impl Pending {
    /// Creates the temporary sibling of `path` (create_new: never an
    /// existing file) and returns it open for writing.
    pub fn create(path: &Path) -> std::io::Result<(Pending, std::fs::File)> {
        let tmp = temp_sibling(path);
        let f = std::fs::OpenOptions::new()
            .write(true)
            .read(true)
            .create_new(true)
            .open(&tmp)?;
        Ok((
            Pending {
                tmp,
                path: path.to_path_buf(),
                committed: false,
            },
            f,
        ))
    }

    /// The temporary file being written.
    pub fn temp_path(&self) -> &Path {
        &self.tmp
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the temporary file to the final path (replacing what was
    /// there). On error the temporary file is removed.
    pub fn commit(mut self) -> std::io::Result<()> {
        let r = std::fs::rename(&self.tmp, &self.path);
        self.committed = r.is_ok();
        r
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Whether `a` and `b` name one existing file: the same device and inode on
/// Unix (so hard links, symlinks and `./x` vs `x` all count), the same
/// canonical path elsewhere. A path that does not exist is no file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        match (a.canonicalize(), b.canonicalize()) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

/// A scratch file in the system's temporary directory, removed on drop.
pub struct TempPath(PathBuf);

impl TempPath {
    pub fn new(label: &str) -> TempPath {
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        TempPath(
            std::env::temp_dir().join(format!("vibroscope-{}-{n}-{label}", std::process::id())),
        )
    }

    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempPath {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_whole_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.json");
        write_atomic(&p, b"{}").expect("write");
        assert_eq!(std::fs::read(&p).expect("read"), b"{}");
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
        assert_eq!(left.len(), 1);
    }

    #[test]
    fn same_file_sees_through_links_and_spellings() {
        let dir = tempfile::tempdir().expect("tempdir");
        let a = dir.path().join("a.y4m");
        std::fs::write(&a, b"x").expect("write");
        let dotted = dir.path().join(".").join("a.y4m");
        assert!(same_file(&a, &dotted));
        let link = dir.path().join("link.y4m");
        std::fs::hard_link(&a, &link).expect("link");
        assert!(same_file(&a, &link));
        let b = dir.path().join("b.y4m");
        std::fs::write(&b, b"x").expect("write");
        assert!(!same_file(&a, &b));
        assert!(!same_file(&a, &dir.path().join("missing")));
    }

    #[test]
    fn pending_files_rename_on_commit_and_vanish_otherwise() {
        use std::io::Write;
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.wav");
        std::fs::write(&p, b"old").expect("write");
        let (a, mut fa) = Pending::create(&p).expect("a");
        let (b, mut fb) = Pending::create(&p).expect("b");
        assert_ne!(a.temp_path(), b.temp_path());
        fa.write_all(b"first").expect("a");
        fb.write_all(b"second").expect("b");
        // Until a commit the final path keeps what it had.
        assert_eq!(std::fs::read(&p).expect("read"), b"old");
        a.commit().expect("commit a");
        assert_eq!(std::fs::read(&p).expect("read"), b"first");
        b.commit().expect("commit b");
        assert_eq!(std::fs::read(&p).expect("read"), b"second");
        let (c, _) = Pending::create(&p).expect("c");
        let tmp = c.temp_path().to_path_buf();
        assert!(tmp.exists());
        drop(c);
        assert!(!tmp.exists());
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
        assert_eq!(left.len(), 1);
    }

    #[test]
    fn a_failed_write_names_the_file_and_leaves_nothing() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("missing-dir").join("a.json");
        let e = write_atomic(&p, b"{}").expect_err("no directory");
        assert!(e.to_string().contains("a.json"), "{e}");
    }
}
