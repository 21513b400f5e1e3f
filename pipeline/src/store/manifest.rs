//! The JSON manifest in every artifact directory: what produced it, from what, and the hash of
//! every file, so a read can verify the artifact before trusting it.

use std::collections::BTreeMap;
use std::path::Path;

use crom_schemas::artifact::{published, ArtifactKind, MANIFEST};
use serde::{Deserialize, Serialize};

use crate::cache::Key;

/// One file of an artifact.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileEntry {
    /// File name inside the artifact directory.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// blake3 of the content (hex).
    pub blake3: String,
}

/// `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Stage (artifact kind) name.
    pub stage: String,
    /// Cache key (the directory name).
    pub key: Key,
    /// Layout version of the artifact kind.
    pub schema_version: u32,
    /// Algorithm version of the stage.
    pub algorithm_version: u32,
    /// crom version that wrote it.
    pub crom_version: String,
    /// Scene that first produced it.
    pub scene: String,
    /// Input artifacts' keys by role.
    pub inputs: BTreeMap<String, Key>,
    /// The stage's parameters (as hashed into the key).
    pub parameters: serde_json::Value,
    /// Wall time of the stage's computation, seconds.
    pub wall_seconds: f64,
    /// Seconds since the Unix epoch when it was written.
    pub created_unix: u64,
    /// The command line that produced it.
    pub command: String,
    /// Every data file with its size and hash.
    pub files: Vec<FileEntry>,
    /// Small stage-specific facts shown by `crom ls` (e.g. shapes, ranks).
    #[serde(default)]
    pub summary: BTreeMap<String, serde_json::Value>,
}

/// blake3 and size of a file.
pub fn hash_file(path: &Path) -> std::io::Result<(u64, String)> {
    let mut hasher = blake3::Hasher::new();
    let mut file = std::fs::File::open(path)?;
    let bytes = std::io::copy(&mut file, &mut hasher)?;
    Ok((bytes, hasher.finalize().to_hex().to_string()))
}

/// Every artifact manifest under the store root `root` (unverified; for listing): in every
/// top-level directory but the published names and the hidden ones (staging, quarantine), the
/// manifests of the artifact directories whose stage is that directory's name — the shipped
/// kinds' in DAG order, then any other kind's by name (the column store's families have none).
pub fn read_all(root: &Path) -> Vec<Manifest> {
    let mut out = Vec::new();
    let mut stages: Vec<String> = std::fs::read_dir(root)
        .map(|d| d.flatten().filter_map(|e| e.file_name().into_string().ok()).collect())
        .unwrap_or_default();
    stages.retain(|s| !s.starts_with('.') && s != published::DIR && root.join(s).is_dir());
    stages.sort_by(|a, b| (ArtifactKind::order_of(a), a).cmp(&(ArtifactKind::order_of(b), b)));
    for stage in stages {
        let Ok(entries) = std::fs::read_dir(root.join(&stage)) else { continue };
        let mut entries: Vec<_> = entries.flatten().collect();
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            if let Ok(text) = std::fs::read_to_string(e.path().join(MANIFEST)) {
                match serde_json::from_str::<Manifest>(&text) {
                    Ok(m) if m.stage == stage => out.push(m),
                    _ => {}
                }
            }
        }
    }
    out
}
