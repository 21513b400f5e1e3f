//! One writer per store: an exclusive advisory lock on `<root>/.lock`, released by the OS when
//! the process ends (so a killed run never leaves a stale lock).

use std::fs::{File, OpenOptions, TryLockError};
use std::path::Path;

use crate::error::CromError;

/// Held for as long as the store is open for writing.
#[derive(Debug)]
pub(super) struct StoreLock {
    _file: File,
}

impl StoreLock {
    pub(super) fn acquire(root: &Path) -> Result<Self, CromError> {
        let path = root.join(".lock");
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| CromError::io(&path, "opening the lock file", e))?;
        match file.try_lock() {
            Ok(()) => Ok(Self { _file: file }),
            Err(TryLockError::WouldBlock) => Err(CromError::Locked { root: root.to_path_buf(), lock: path }),
            Err(TryLockError::Error(e)) => Err(CromError::io(&path, "locking the store", e)),
        }
    }
}
