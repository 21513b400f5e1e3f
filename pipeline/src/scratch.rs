//! A scratch directory removed when dropped: what the tests (unit, end-to-end and the doc
//! examples) run a store in.
//!
//! std only, on purpose: the `tempfile` crate as a dev-dependency switched on `std` in
//! `bitflags` (through `rustix`) for test builds only, so every test build recompiled
//! `flatbuffers`, `arrow-ipc`, `parquet` and this crate a second time beside the binary's build
//! (docs/design-notes.md, "One build per machine").

use std::path::{Path, PathBuf};

/// A directory under the system's temporary directory, removed with its contents on drop.
#[derive(Debug)]
pub struct ScratchDir(PathBuf);

impl ScratchDir {
    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        // Best effort, as a temporary directory is: a failure leaves it to the system's cleaner.
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A fresh, empty directory `crom-<pid>-<unique>` under [`std::env::temp_dir`]. Created with
/// `create_dir`, which fails if the name exists, so no two callers (threads or processes) share
/// one.
pub fn tempdir() -> std::io::Result<ScratchDir> {
    let root = std::env::temp_dir();
    loop {
        let dir = root.join(format!("crom-{}-{}", std::process::id(), crate::store::fs::unique_suffix()));
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(ScratchDir(dir)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_call_is_a_new_empty_directory_removed_on_drop() {
        let a = tempdir().expect("tempdir");
        let b = tempdir().expect("tempdir");
        assert_ne!(a.path(), b.path());
        assert!(a.path().is_dir() && std::fs::read_dir(a.path()).expect("read").next().is_none());
        std::fs::write(a.path().join("f"), b"x").expect("write");
        std::fs::create_dir(a.path().join("sub")).expect("mkdir");
        let kept = a.path().to_path_buf();
        drop(a);
        assert!(!kept.exists(), "a dropped scratch directory is removed with its contents");
        assert!(b.path().is_dir());
    }
}
