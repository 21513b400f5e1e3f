//! The content-addressed artifact store.
//!
//! Layout: `<root>/<stage>/<key>/` holds an artifact's files and its `manifest.json`. A stage
//! writes into a staging directory `<root>/.staging/…` which is renamed into place only when every
//! file and the manifest are complete, so a killed run never leaves a half artifact under a valid
//! key. Reads verify the manifest (stage, key, schema version, each file's size and blake3); an
//! artifact that fails verification is moved to `<root>/.quarantine/` (never deleted) and
//! recomputed. One `crom run` at a time holds `<root>/.lock` exclusively; sharded workers
//! (`crom work`) hold it shared (`store::lock`).

pub mod catalog;
pub mod columns;
mod lock;
pub mod manifest;
pub mod published;

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crom_schemas::artifact::{ArtifactKind, MANIFEST};

use crate::cache::{Key, KeySpec};
use crate::error::CromError;
pub use manifest::Manifest;
use manifest::{hash_file, FileEntry};

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

/// An open store.
#[derive(Debug)]
pub struct Store {
    root: PathBuf,
    _lock: Option<lock::StoreLock>,
}

/// Why a stored artifact was not used.
#[derive(Debug, Clone, PartialEq)]
pub enum Lookup {
    /// Present and verified.
    Hit(Box<Manifest>),
    /// Not present.
    Miss,
    /// Present but failed verification; moved to the given quarantine path.
    Quarantined(PathBuf, String),
}

impl Store {
    /// Open (creating if needed) the store at `root` for writing, taking its lock.
    pub fn open(root: &Path) -> Result<Self, CromError> {
        std::fs::create_dir_all(root).map_err(|e| CromError::io(root, "creating the store", e))?;
        let lock = lock::StoreLock::acquire(root)?;
        // Holding the lock, no other writer exists: staging directories left by a killed run
        // are garbage (never under a valid key) and can go.
        let staging = root.join(".staging");
        if staging.exists() {
            std::fs::remove_dir_all(&staging)
                .map_err(|e| CromError::io(&staging, "clearing stale staging directories", e))?;
        }
        // Likewise the temporary files of an atomic write that a kill interrupted (the catalog's,
        // a scene's link): never under their final name, so garbage.
        for dir in [root.to_path_buf(), root.join(crom_schemas::artifact::published::DIR)] {
            for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if name.starts_with(".tmp-") {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
        Ok(Self { root: root.to_path_buf(), _lock: Some(lock) })
    }

    /// Open (creating if needed) the store at `root` as one of many concurrent workers
    /// (`crom work`): a shared lock, which excludes `crom run` but not other workers. A worker
    /// only appends snapshot blocks; it cleans nothing up (the exclusive writer does).
    pub fn open_shared(root: &Path) -> Result<Self, CromError> {
        std::fs::create_dir_all(root).map_err(|e| CromError::io(root, "creating the store", e))?;
        let lock = lock::StoreLock::acquire_shared(root)?;
        Ok(Self { root: root.to_path_buf(), _lock: Some(lock) })
    }

    /// Open an existing store read-only, without the lock (for `crom ls`).
    pub fn open_read_only(root: &Path) -> Self {
        Self { root: root.to_path_buf(), _lock: None }
    }

    /// The store's root directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Directory of the artifact `kind`/`key` (whether or not it exists).
    pub fn dir(&self, kind: ArtifactKind, key: &Key) -> PathBuf {
        self.root.join(kind.name()).join(&key.0)
    }

    /// Find and verify an artifact.
    pub fn lookup(&self, kind: ArtifactKind, key: &Key) -> Result<Lookup, CromError> {
        let dir = self.dir(kind, key);
        if !dir.exists() {
            return Ok(Lookup::Miss);
        }
        match verify(&dir, kind, key) {
            Ok(m) => Ok(Lookup::Hit(Box::new(m))),
            Err(problem) => Ok(Lookup::Quarantined(self.quarantine_dir(kind, key)?, problem)),
        }
    }

    /// Move an artifact directory to `<root>/.quarantine/` (never deleted); its new path.
    pub fn quarantine_dir(&self, kind: ArtifactKind, key: &Key) -> Result<PathBuf, CromError> {
        let dir = self.dir(kind, key);
        let parent = self.root.join(".quarantine");
        let q = parent.join(format!("{}-{}-{}-{}", kind.name(), key.short(), unix_now(), unique_suffix()));
        std::fs::create_dir_all(&parent).map_err(|e| CromError::io(&parent, "creating the quarantine", e))?;
        std::fs::rename(&dir, &q).map_err(|e| CromError::io(&dir, "moving an artifact aside", e))?;
        // No published name may point into the quarantine.
        let reason = format!("quarantined to {} at {}", q.display(), catalog::iso_utc(unix_now()));
        published::withdraw_artifact(&self.root, kind, key, &reason)?;
        catalog::refresh(&self.root)?;
        Ok(q)
    }

    /// Start writing an artifact: a fresh staging directory.
    pub fn stage(&self, spec: &KeySpec) -> Result<Staging, CromError> {
        let kind = ArtifactKind::from_name(spec.stage).unwrap_or(ArtifactKind::Mesh);
        let key = spec.key();
        let tmp = self.root.join(".staging").join(format!(
            "{}-{}-{}-{}",
            spec.stage,
            key.short(),
            std::process::id(),
            unique_suffix()
        ));
        std::fs::create_dir_all(&tmp).map_err(|e| CromError::io(&tmp, "creating a staging directory", e))?;
        Ok(Staging { tmp, kind, key, spec: spec.clone() })
    }

    /// Every column family of snapshots in the store.
    pub fn families(&self) -> Vec<columns::ColumnFamily> {
        let mut out = Vec::new();
        let Ok(entries) = std::fs::read_dir(self.root.join(columns::COLUMNS_DIR)) else { return out };
        let mut names: Vec<String> = entries.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        for n in names {
            if let Ok(Some(f)) = columns::ColumnFamily::find(&self.root, &Key(n)) {
                out.push(f);
            }
        }
        out
    }

    /// Every artifact manifest in the store (unverified; for listing).
    pub fn manifests(&self) -> Vec<Manifest> {
        let mut out = Vec::new();
        for kind in ArtifactKind::ALL {
            let Ok(entries) = std::fs::read_dir(self.root.join(kind.name())) else { continue };
            for e in entries.flatten() {
                if let Ok(text) = std::fs::read_to_string(e.path().join(MANIFEST)) {
                    if let Ok(m) = serde_json::from_str::<Manifest>(&text) {
                        out.push(m);
                    }
                }
            }
        }
        out
    }
}

/// An artifact being written. Files go into [`Staging::path`]; [`Staging::commit`] hashes them,
/// writes the manifest and renames the directory into place.
#[derive(Debug)]
pub struct Staging {
    tmp: PathBuf,
    kind: ArtifactKind,
    key: Key,
    spec: KeySpec,
}

/// What a committed artifact records beyond its key spec.
#[derive(Debug, Clone, Default)]
pub struct Provenance {
    /// Scene name.
    pub scene: String,
    /// Command line.
    pub command: String,
    /// Wall time of the computation.
    pub wall_seconds: f64,
    /// Facts for `crom ls`.
    pub summary: std::collections::BTreeMap<String, serde_json::Value>,
}

impl Staging {
    /// Path of a file inside the staging directory.
    pub fn path(&self, name: &str) -> PathBuf {
        self.tmp.join(name)
    }

    /// The artifact's key.
    pub fn key(&self) -> &Key {
        &self.key
    }

    /// Hash the files, write the manifest, and move the artifact into the store atomically.
    pub fn commit(self, store: &Store, prov: Provenance) -> Result<Manifest, CromError> {
        let mut files = Vec::new();
        let mut names: Vec<_> = std::fs::read_dir(&self.tmp)
            .map_err(|e| CromError::io(&self.tmp, "listing a staging directory", e))?
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        for name in names {
            let p = self.tmp.join(&name);
            let (bytes, blake3) = hash_file(&p).map_err(|e| CromError::io(&p, "hashing", e))?;
            files.push(FileEntry { name, bytes, blake3 });
        }
        let manifest = Manifest {
            stage: self.spec.stage.to_string(),
            key: self.key.clone(),
            schema_version: self.spec.schema_version,
            algorithm_version: self.spec.algorithm_version,
            crom_version: env!("CARGO_PKG_VERSION").to_string(),
            scene: prov.scene,
            inputs: self.spec.inputs.clone(),
            parameters: self.spec.params.clone(),
            wall_seconds: prov.wall_seconds,
            created_unix: unix_now(),
            command: prov.command,
            files,
            summary: prov.summary,
        };
        let mpath = self.tmp.join(MANIFEST);
        let text = serde_json::to_string_pretty(&manifest).unwrap_or_default();
        std::fs::write(&mpath, text).map_err(|e| CromError::io(&mpath, "writing the manifest", e))?;
        let dest = store.dir(self.kind, &self.key);
        let parent = dest.parent().unwrap_or(store.root());
        std::fs::create_dir_all(parent).map_err(|e| CromError::io(parent, "creating a stage directory", e))?;
        if dest.exists() {
            // Same key, same content by construction: keep the existing one.
            let _ = std::fs::remove_dir_all(&self.tmp);
        } else {
            std::fs::rename(&self.tmp, &dest).map_err(|e| CromError::io(&dest, "moving an artifact into place", e))?;
        }
        catalog::refresh(store.root())?;
        Ok(manifest)
    }
}

fn verify(dir: &Path, kind: ArtifactKind, key: &Key) -> Result<Manifest, String> {
    let mpath = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&mpath).map_err(|e| format!("manifest unreadable: {e}"))?;
    let m: Manifest = serde_json::from_str(&text).map_err(|e| format!("manifest is not valid: {e}"))?;
    if m.stage != kind.name() || &m.key != key {
        return Err(format!("manifest names {}/{}, expected {}/{}", m.stage, m.key, kind.name(), key));
    }
    if m.schema_version != kind.schema_version() {
        return Err(format!("schema version {} (expected {})", m.schema_version, kind.schema_version()));
    }
    for f in &m.files {
        let p = dir.join(&f.name);
        let (bytes, hash) = hash_file(&p).map_err(|e| format!("{}: {e}", f.name))?;
        if bytes != f.bytes || hash != f.blake3 {
            return Err(format!("{} does not match its manifest (size or blake3)", f.name));
        }
    }
    Ok(m)
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

fn unique_suffix() -> u128 {
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
