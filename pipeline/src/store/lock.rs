//! Who may write the store: an advisory lock on `<root>/.lock`, released by the OS when the
//! process ends (so a killed run never leaves a stale lock).
//!
//! - **Exclusive** (`crom run`, `crom solve`, `crom verify`): one process, which may also clean
//!   up after killed writers (staging directories, temporary files, blocks without a fragment)
//!   and compact the column index — work that is only safe when no one else writes.
//! - **Shared** (`crom work`, the worker of a sharded sweep): any number of processes, on this
//!   node or others on a shared file system, each appending snapshot blocks and index fragments
//!   under unique names (`store::columns`). They never delete or compact anything.
//!
//! On Linux `flock` over NFS (v4, or v3 with NLM) is emulated by POSIX byte-range locks, which
//! the server arbitrates across clients; the lock is advisory, so the guarantee holds among crom
//! processes only.

use std::fs::{File, OpenOptions, TryLockError};
use std::path::Path;

use crate::error::CromError;

/// Held for as long as the store is open for writing.
#[derive(Debug)]
pub(super) struct StoreLock {
    _file: File,
}

impl StoreLock {
    /// The exclusive lock, or [`CromError::Locked`] if any other process holds either kind.
    pub(super) fn acquire(root: &Path) -> Result<Self, CromError> {
        Self::take(root, false)
    }

    /// A shared lock, or [`CromError::Locked`] if a process holds the exclusive one.
    pub(super) fn acquire_shared(root: &Path) -> Result<Self, CromError> {
        Self::take(root, true)
    }

    fn take(root: &Path, shared: bool) -> Result<Self, CromError> {
        let path = root.join(".lock");
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| CromError::io(&path, "opening the lock file", e))?;
        let taken = if shared { file.try_lock_shared() } else { file.try_lock() };
        match taken {
            Ok(()) => Ok(Self { _file: file }),
            Err(TryLockError::WouldBlock) => Err(CromError::Locked { root: root.to_path_buf(), lock: path }),
            Err(TryLockError::Error(e)) => Err(CromError::io(&path, "locking the store", e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shared locks coexist; the exclusive lock excludes both kinds (separate open file
    /// descriptions, as separate processes would have).
    #[test]
    fn shared_locks_coexist_and_exclude_the_writer() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let a = StoreLock::acquire_shared(tmp.path()).expect("first worker");
        let b = StoreLock::acquire_shared(tmp.path()).expect("second worker");
        assert!(matches!(StoreLock::acquire(tmp.path()), Err(CromError::Locked { .. })));
        drop((a, b));
        let w = StoreLock::acquire(tmp.path()).expect("writer once the workers are gone");
        assert!(matches!(StoreLock::acquire_shared(tmp.path()), Err(CromError::Locked { .. })));
        drop(w);
    }
}
