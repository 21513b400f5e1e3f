//! File-system primitives of the store: atomic writes (temporary file, fsync, rename, fsync of
//! the directory), names no concurrent writer shares, and the check that keeps a name from a
//! scene file inside the store.
//!
//! The bottom of the store's module graph: it imports nothing else from `store`, so every other
//! module (and the executors) can use it without a cycle.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::CromError;

/// `root/dir/name`, where `name` comes from a scene file (a scene name under `runs/` or
/// `scenes/`): refused unless it is one plain path component — no separator, not `.` or `..`,
/// no leading dot — so that no scene file can make crom write outside its store. Scene
/// validation refuses such names first (`scene.name`); this is the second line, at the place
/// where the path is made.
pub fn named_dir(root: &Path, dir: &str, name: &str) -> Result<PathBuf, CromError> {
    use std::path::Component;
    let mut parts = Path::new(name).components();
    let plain = matches!((parts.next(), parts.next()), (Some(Component::Normal(_)), None))
        && !name.starts_with('.')
        && !name.contains(['/', '\\']);
    if !plain {
        return Err(CromError::Usage {
            message: format!("scene name {name:?} would make a path outside {}/{dir}", root.display()),
            fix: "give scene.name a plain name of letters, digits, '-', '_' and '.' (not first)".into(),
        });
    }
    Ok(root.join(dir).join(name))
}

/// Write `bytes` to `path` through a temporary file, fsync and rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CromError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let tmp = dir.join(format!(
        ".tmp-{}-{}",
        path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
        writer_token()
    ));
    let mut f = std::fs::File::create(&tmp).map_err(|e| CromError::io(&tmp, "creating", e))?;
    f.write_all(bytes).map_err(|e| CromError::io(&tmp, "writing", e))?;
    drop(f);
    publish(&tmp, path)
}

/// Make the complete file `tmp` durable and move it to `dest` atomically: fsync the file,
/// rename, fsync the directory (the commit step of blocks, fragments and the index).
pub(crate) fn publish(tmp: &Path, dest: &Path) -> Result<(), CromError> {
    fsync_file(tmp)?;
    std::fs::rename(tmp, dest).map_err(|e| CromError::io(dest, "moving into place", e))?;
    fsync_dir(dest.parent().unwrap_or(Path::new(".")));
    Ok(())
}

fn fsync_file(path: &Path) -> Result<(), CromError> {
    let f = std::fs::File::open(path).map_err(|e| CromError::io(path, "opening for fsync", e))?;
    f.sync_all().map_err(|e| CromError::io(path, "fsync", e))
}

pub(crate) fn fsync_dir(path: &Path) {
    // Best effort: directory fsync makes the rename durable on Linux; not every FS supports it.
    if let Ok(d) = std::fs::File::open(path) {
        let _ = d.sync_all();
    }
}

pub(crate) fn unix_now() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0)
}

/// A suffix no other writer uses at the same time: time, a process-wide counter, this process
/// and this host (workers on several nodes share the store's directories).
pub(crate) fn writer_token() -> String {
    format!("{}-{}-{}", host_name(), std::process::id(), unique_suffix())
}

/// This machine's host name (`/proc/sys/kernel/hostname`; `localhost` where unknown).
pub(crate) fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().chars().filter(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == '.').collect())
        .filter(|s: &String| !s.is_empty())
        .unwrap_or_else(|| "localhost".to_string())
}

pub(crate) fn unique_suffix() -> u128 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let nanos = SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_nanos()).unwrap_or(0);
    nanos.wrapping_mul(1000) + u128::from(COUNTER.fetch_add(1, Ordering::Relaxed))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every traversal through a name is refused; plain names pass and stay inside the store.
    #[test]
    fn named_dirs_stay_inside_the_store() {
        let root = Path::new("/store");
        for bad in ["../../../escaped", "..", ".", "a/b", "a\\b", "/abs", ".hidden", "", "x/../.."] {
            assert!(named_dir(root, "runs", bad).is_err(), "{bad:?} accepted");
        }
        for good in ["rope", "ironing-fine-2d", "a.b_c"] {
            let p = named_dir(root, "runs", good).expect("plain name");
            assert_eq!(p, root.join("runs").join(good));
        }
    }
}
