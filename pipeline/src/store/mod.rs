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
pub mod fs;
mod lock;
pub mod manifest;
pub mod published;

use std::path::{Path, PathBuf};

use crom_schemas::artifact::{ArtifactKind, MANIFEST};

use crate::cache::{Key, KeySpec};
use crate::error::CromError;
use columns::QuarantinedBlock;
use fs::{unique_suffix, unix_now};
pub use manifest::Manifest;
use manifest::{hash_file, FileEntry};

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

    /// Verify a stored artifact without moving anything: its manifest, or what is wrong with
    /// it.
    pub fn verify(&self, kind: ArtifactKind, key: &Key) -> Result<Manifest, String> {
        verify(&self.dir(kind, key), kind, key)
    }

    /// [`Store::verify`] for a reader of some of an artifact's files (`crom query`, the Python
    /// model): the files named in `read` are checked in full (size and blake3; each must be
    /// listed in the manifest), every other listed file by its size alone (present, not
    /// truncated). A query reads `model.h5` and not the 17 MB of `reconstruction.h5`, whose
    /// hash was a fifth of a one-point query's time; it is checked in full when it is read.
    pub fn verify_reading(&self, kind: ArtifactKind, key: &Key, read: &[&str]) -> Result<Manifest, String> {
        let dir = self.dir(kind, key);
        let m = verify_manifest(&dir, kind, key)?;
        if let Some(name) = read.iter().find(|n| !m.files.iter().any(|f| f.name == **n)) {
            return Err(format!("{name} is not listed in the manifest"));
        }
        for f in &m.files {
            if read.contains(&f.name.as_str()) {
                verify_file(&dir, f)?;
            } else {
                let bytes = std::fs::metadata(dir.join(&f.name)).map_err(|e| format!("{}: {e}", f.name))?.len();
                if bytes != f.bytes {
                    return Err(format!("{} does not match its manifest (size)", f.name));
                }
            }
        }
        Ok(m)
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
        let kind = spec.kind;
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
        columns::families(&self.root)
    }

    /// Every artifact manifest in the store (unverified; for listing).
    pub fn manifests(&self) -> Vec<Manifest> {
        manifest::read_all(&self.root)
    }

    /// Move the snapshot block `block` (relative to the store root) to `<root>/.quarantine/`
    /// and bring the published names and the catalog up to date; its new path.
    pub fn quarantine_block(&self, block: &str) -> Result<PathBuf, CromError> {
        let q = columns::quarantine_block(&self.root, block)?;
        self.block_quarantined(&q)?;
        Ok(q.to)
    }

    /// Re-hash every block file and every column of `family` against its index; each block
    /// that fails is moved to the quarantine and the names and the catalog are brought up to
    /// date before the next block is checked. Returns `(blocks checked, problems)`.
    pub fn verify_family(&self, family: &columns::ColumnFamily) -> Result<(usize, Vec<String>), CromError> {
        let (checked, problems) = family.verify_each(|q| self.block_quarantined(q))?;
        Ok((checked, problems.iter().map(ToString::to_string).collect()))
    }

    /// What follows moving a block aside: a published training set reading it would read fill
    /// values, so its names are withdrawn; then the catalog is rebuilt.
    fn block_quarantined(&self, q: &QuarantinedBlock) -> Result<(), CromError> {
        let reason = format!("reads snapshot block {}, quarantined to {}", q.block, q.to.display());
        published::withdraw_block(&self.root, &q.block, &reason)?;
        catalog::refresh(&self.root)?;
        Ok(())
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
    let m = verify_manifest(dir, kind, key)?;
    for f in &m.files {
        verify_file(dir, f)?;
    }
    Ok(m)
}

/// One listed file of an artifact against its manifest entry (size and blake3).
fn verify_file(dir: &Path, f: &FileEntry) -> Result<(), String> {
    let (bytes, hash) = hash_file(&dir.join(&f.name)).map_err(|e| format!("{}: {e}", f.name))?;
    if bytes != f.bytes || hash != f.blake3 {
        return Err(format!("{} does not match its manifest (size or blake3)", f.name));
    }
    Ok(())
}

/// An artifact's manifest, read and checked against the kind, key and schema version expected.
fn verify_manifest(dir: &Path, kind: ArtifactKind, key: &Key) -> Result<Manifest, String> {
    let mpath = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&mpath).map_err(|e| format!("manifest unreadable: {e}"))?;
    let m: Manifest = serde_json::from_str(&text).map_err(|e| format!("manifest is not valid: {e}"))?;
    if m.stage != kind.name() || &m.key != key {
        return Err(format!("manifest names {}/{}, expected {}/{}", m.stage, m.key, kind.name(), key));
    }
    if m.schema_version != kind.schema_version() {
        return Err(format!("schema version {} (expected {})", m.schema_version, kind.schema_version()));
    }
    Ok(m)
}
