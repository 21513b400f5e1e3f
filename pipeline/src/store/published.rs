//! Stable names for each scene's latest complete study, so that a user opens
//! `STORE/scenes/ironing-fine/train.h5` instead of a content hash.
//!
//! ```text
//! scenes/<scene>                  -> .versions/<scene>@<stamp>        (relative symbolic link)
//! scenes/.versions/<scene>@<stamp>/
//!     study.json                  scene, crom version, entries: name -> stage, key, target, schema version
//!     train.h5                    -> ../../../trainset/<key>/snapshots.h5
//!     nested/level-3.h5           -> ../../../../trainset/<key>/snapshots.h5
//!     report                      -> ../../../report/<key>            (a directory)
//! ```
//!
//! **Atomicity.** A link set is built completely in a temporary directory, renamed into
//! `.versions/`, and then the one link `scenes/<scene>` is replaced by `rename(2)` of a new link
//! over it, which POSIX makes atomic: a reader sees the old study or the new one, never a mix.
//! Only a run that finished (every stage it was asked for) publishes; a failed or killed run
//! leaves the previous link set in place. The previous version is kept (a reader that resolved
//! it a moment ago can still open its files); older ones are removed.
//!
//! **Why relative symbolic links.** They cost nothing, every tool follows them (h5py, pandas,
//! ParaView, a shell), and relative targets survive copying or moving the whole store with
//! `cp -a`, `rsync -a` or `tar`. A copy that drops links (e.g. some archive formats) still has
//! `study.json`, whose `target`s are paths relative to the store root; the Python reader uses
//! those. HDF5 external links would serve only h5py, not pandas or a file browser.
//!
//! **Never a quarantined target.** When an artifact or a snapshot block is moved to the
//! quarantine, every published study that refers to it is republished without that entry (and
//! `study.json` lists it under `withdrawn` with the reason); the next successful run restores it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crom_schemas::artifact::{published as names, trainset, ArtifactKind};
use serde::{Deserialize, Serialize};

use super::fs::{fsync_dir, named_dir, unix_now, write_atomic};
use crate::cache::Key;
use crate::error::CromError;

/// One name of a published study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// Stage (artifact kind) of the target.
    pub stage: String,
    /// Key of the target artifact.
    pub key: Key,
    /// Path of the target, relative to the store root (a file, or the artifact directory).
    pub target: String,
    /// Schema version of the target artifact.
    pub schema_version: u32,
    /// An XDMF file: the name is a copy whose HDF5 references are made relative to the link
    /// set, not a link (ParaView resolves references against the path it opened).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub relocate: bool,
}

impl Entry {
    /// The file `file` of the artifact `kind`/`key` (or the whole directory when `file` is `None`).
    pub fn new(kind: ArtifactKind, key: &Key, file: Option<&str>) -> Self {
        let dir = format!("{}/{}", kind.name(), key.0);
        Self {
            stage: kind.name().to_string(),
            key: key.clone(),
            target: file.map_or(dir.clone(), |f| format!("{dir}/{f}")),
            schema_version: kind.schema_version(),
            relocate: false,
        }
    }
}

/// `study.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Study {
    /// [`names::LAYOUT_VERSION`].
    pub layout_version: u32,
    /// Scene name.
    pub scene: String,
    /// crom version that published it.
    pub crom_version: String,
    /// Seconds since the Unix epoch.
    pub created_unix: u64,
    /// Whether the study includes the online stage and the report.
    pub online: bool,
    /// Parameter component names.
    pub parameter_names: Vec<String>,
    /// Name (relative to the link set) -> target.
    pub entries: BTreeMap<String, Entry>,
    /// Names taken out since the study was published, with the reason.
    #[serde(default)]
    pub withdrawn: BTreeMap<String, String>,
}

/// Name of the link set of scene `scene`'s versions: `<scene>@…` (`@` is not allowed in scene
/// names, so the prefix of one scene is never the prefix of another).
fn version_prefix(scene: &str) -> String {
    format!("{scene}@")
}

fn scenes_dir(root: &Path) -> PathBuf {
    root.join(names::DIR)
}

/// Publish `study` as the current names of its scene (see the module doc for the protocol).
pub fn publish(root: &Path, study: &Study) -> Result<PathBuf, CromError> {
    let scenes = scenes_dir(root);
    let named = named_dir(root, names::DIR, &study.scene)?;
    // A rerun that found everything in the cache names the same files: nothing to swap.
    let current =
        std::fs::read_to_string(named.join(names::STUDY)).ok().and_then(|t| serde_json::from_str::<Study>(&t).ok());
    if let Some(c) = current {
        let same = c.entries == study.entries && c.online == study.online && c.withdrawn == study.withdrawn;
        if same && c.layout_version == study.layout_version && c.entries.values().all(|e| root.join(&e.target).exists())
        {
            return Ok(named);
        }
    }
    let versions = scenes.join(names::VERSIONS);
    std::fs::create_dir_all(&versions).map_err(|e| CromError::io(&versions, "creating the scene names", e))?;
    let version = {
        use std::sync::atomic::{AtomicU64, Ordering};
        static PUBLISHED: AtomicU64 = AtomicU64::new(0);
        let n = PUBLISHED.fetch_add(1, Ordering::Relaxed);
        format!("{}{}-{}-{n}", version_prefix(&study.scene), study.created_unix, std::process::id())
    };
    let tmp = versions.join(format!(".tmp-{version}"));
    std::fs::create_dir_all(&tmp).map_err(|e| CromError::io(&tmp, "creating a link set", e))?;
    for (name, entry) in &study.entries {
        let target = root.join(&entry.target);
        if !target.exists() {
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(CromError::artifact(
                &target,
                format!("scene {} would name it {name}, but it does not exist", study.scene),
                "rerun the scene: the missing artifact is recomputed",
            ));
        }
        let link = tmp.join(name);
        let depth = 3 + name.matches('/').count();
        if let Some(parent) = link.parent() {
            std::fs::create_dir_all(parent).map_err(|e| CromError::io(parent, "creating a link set", e))?;
        }
        if entry.relocate {
            let text = std::fs::read_to_string(&target).map_err(|e| CromError::io(&target, "reading", e))?;
            let from = Path::new(&entry.target).parent().map(|p| p.to_string_lossy().into_owned()).unwrap_or_default();
            let moved = crate::io::xdmf::relocate(&text, &from, depth);
            std::fs::write(&link, moved).map_err(|e| CromError::io(&link, "writing a relocated XDMF file", e))?;
            continue;
        }
        let relative = format!("{}{}", "../".repeat(depth), entry.target);
        std::os::unix::fs::symlink(&relative, &link).map_err(|e| CromError::io(&link, "creating a name", e))?;
    }
    let text = serde_json::to_string_pretty(study).unwrap_or_default();
    write_atomic(&tmp.join(names::STUDY), text.as_bytes())?;
    let dest = versions.join(&version);
    std::fs::rename(&tmp, &dest).map_err(|e| CromError::io(&dest, "moving a link set into place", e))?;
    fsync_dir(&versions);

    // Swap the one link: a new link under a temporary name, renamed over the old one.
    let link = named;
    if link.exists() && !link.is_symlink() {
        return Err(CromError::artifact(
            &link,
            "is a file or directory, not the link crom maintains",
            "move it out of the store's scenes/ directory and rerun",
        ));
    }
    let previous = std::fs::read_link(&link).ok();
    let tmp_link = scenes.join(format!(".tmp-link-{version}"));
    std::os::unix::fs::symlink(format!("{}/{version}", names::VERSIONS), &tmp_link)
        .map_err(|e| CromError::io(&tmp_link, "creating a name", e))?;
    std::fs::rename(&tmp_link, &link).map_err(|e| CromError::io(&link, "replacing a scene's names", e))?;
    fsync_dir(&scenes);

    // Keep the new and the previous version; older ones and leftovers of killed publishes go.
    let keep_previous = previous.as_ref().and_then(|p| p.file_name()).map(|n| n.to_string_lossy().into_owned());
    if let Ok(entries) = std::fs::read_dir(&versions) {
        for e in entries.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            let ours = n.starts_with(&version_prefix(&study.scene))
                || n.starts_with(&format!(".tmp-{}", version_prefix(&study.scene)));
            if ours && n != version && Some(&n) != keep_previous.as_ref() {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
    }
    Ok(link)
}

/// The current study of every published scene (scene name, study), in name order. A scene
/// whose `study.json` cannot be read is skipped (it is rebuilt by its next run).
pub fn studies(root: &Path) -> Vec<(String, Study)> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(scenes_dir(root)) else { return out };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        let path = e.path().join(names::STUDY);
        if let Some(s) = std::fs::read_to_string(&path).ok().and_then(|t| serde_json::from_str::<Study>(&t).ok()) {
            out.push((name, s));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// Republish every study with the entries `drop` selects removed (listed under `withdrawn`);
/// entries whose target has disappeared otherwise (deleted by hand) go too.
fn withdraw(root: &Path, reason: &str, drop: impl Fn(&Entry) -> bool) -> Result<(), CromError> {
    for (_, mut study) in studies(root) {
        let gone: Vec<String> = study.entries.iter().filter(|(_, e)| drop(e)).map(|(n, _)| n.clone()).collect();
        if gone.is_empty() {
            continue;
        }
        for n in gone {
            study.entries.remove(&n);
            study.withdrawn.insert(n, reason.to_string());
        }
        let missing: Vec<String> =
            study.entries.iter().filter(|(_, e)| !root.join(&e.target).exists()).map(|(n, _)| n.clone()).collect();
        for n in missing {
            study.entries.remove(&n);
            study.withdrawn.insert(n, "its artifact is missing from the store".to_string());
        }
        study.created_unix = unix_now();
        publish(root, &study)?;
    }
    Ok(())
}

/// Take the artifact `kind`/`key` out of every published study (it was quarantined).
pub fn withdraw_artifact(root: &Path, kind: ArtifactKind, key: &Key, reason: &str) -> Result<(), CromError> {
    withdraw(root, reason, |e| e.stage == kind.name() && &e.key == key)
}

/// Take every published training set that reads columns from `block` (relative to the store
/// root) out of the published studies: its file would read the missing block as fill values.
pub fn withdraw_block(root: &Path, block: &str, reason: &str) -> Result<(), CromError> {
    let uses_block = |e: &Entry| {
        if e.stage != ArtifactKind::TRAINING_SET.name() {
            return false;
        }
        let stats = root.join(ArtifactKind::TRAINING_SET.name()).join(&e.key.0).join(trainset::STATS);
        crate::io::table::read_parquet(&stats)
            .ok()
            .and_then(|t| t.strs("block").map(|b| b.iter().any(|x| x == block)))
            // An unreadable set cannot be vouched for: withdraw it too.
            .unwrap_or(true)
    };
    withdraw(root, reason, uses_block)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn study(scene: &str, entries: &[(&str, &str)]) -> Study {
        Study {
            layout_version: names::LAYOUT_VERSION,
            scene: scene.to_string(),
            crom_version: "test".to_string(),
            created_unix: 1,
            online: true,
            parameter_names: vec!["p".to_string()],
            entries: entries
                .iter()
                .map(|(n, t)| {
                    let e = Entry {
                        stage: "basis".into(),
                        key: Key((*t).into()),
                        target: format!("basis/{t}/f"),
                        schema_version: 1,
                        relocate: false,
                    };
                    (n.to_string(), e)
                })
                .collect(),
            withdrawn: BTreeMap::new(),
        }
    }

    fn target(root: &Path, key: &str, content: &str) {
        let d = root.join("basis").join(key);
        std::fs::create_dir_all(&d).expect("mkdir");
        std::fs::write(d.join("f"), content).expect("write");
    }

    #[test]
    fn names_resolve_swap_and_keep_one_previous_version() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let root = tmp.path();
        for (k, c) in [("k1", "one"), ("k2", "two"), ("k3", "three")] {
            target(root, k, c);
        }
        let read = |name: &str| std::fs::read_to_string(root.join("scenes/s").join(name)).expect("name resolves");
        publish(root, &study("s", &[("a.h5", "k1"), ("nested/level-1.h5", "k1")])).expect("publish");
        assert_eq!((read("a.h5"), read("nested/level-1.h5")), ("one".into(), "one".into()));
        publish(root, &study("s", &[("a.h5", "k2")])).expect("publish");
        assert_eq!(read("a.h5"), "two");
        assert!(!root.join("scenes/s/nested/level-1.h5").exists(), "the link set is replaced as a whole");
        publish(root, &study("s", &[("a.h5", "k3")])).expect("publish");
        let versions = std::fs::read_dir(root.join("scenes/.versions")).expect("versions").count();
        assert_eq!(versions, 2, "the current and the previous link set are kept");
        // A scene whose name extends another's keeps its own versions.
        publish(root, &study("s.b", &[("a.h5", "k1")])).expect("publish");
        publish(root, &study("s", &[("a.h5", "k2")])).expect("publish");
        assert_eq!(std::fs::read_to_string(root.join("scenes/s.b/a.h5")).expect("s.b"), "one");
        // The names survive copying the store (relative links).
        let copy = tmp.path().join("copy");
        std::fs::create_dir_all(&copy).expect("mkdir");
        let status = std::process::Command::new("cp")
            .arg("-a")
            .arg(root.join("scenes"))
            .arg(root.join("basis"))
            .arg(&copy)
            .status()
            .expect("cp");
        assert!(status.success());
        assert_eq!(std::fs::read_to_string(copy.join("scenes/s/a.h5")).expect("copied name"), "two");
    }

    #[test]
    fn a_missing_target_publishes_nothing_and_keeps_the_old_names() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let root = tmp.path();
        target(root, "k1", "one");
        publish(root, &study("s", &[("a.h5", "k1")])).expect("publish");
        let err = publish(root, &study("s", &[("a.h5", "k1"), ("b.h5", "nope")])).expect_err("missing target");
        assert!(err.to_string().contains("does not exist"), "{err}");
        assert_eq!(std::fs::read_to_string(root.join("scenes/s/a.h5")).expect("old"), "one");
        assert!(!root.join("scenes/s/b.h5").exists());
    }

    #[test]
    fn withdrawing_an_artifact_removes_its_names_only() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let root = tmp.path();
        target(root, "k1", "one");
        target(root, "k2", "two");
        publish(root, &study("s", &[("a.h5", "k1"), ("b.h5", "k2")])).expect("publish");
        withdraw_artifact(root, ArtifactKind::BASIS, &Key("k1".into()), "quarantined").expect("withdraw");
        assert!(!root.join("scenes/s/a.h5").exists());
        assert_eq!(std::fs::read_to_string(root.join("scenes/s/b.h5")).expect("kept"), "two");
        let s = &studies(root)[0].1;
        assert_eq!(s.withdrawn.get("a.h5").map(String::as_str), Some("quarantined"));
    }
}
