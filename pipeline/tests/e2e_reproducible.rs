//! End-to-end: result files are byte-reproducible. A scene run into two stores — one with the
//! default thread pool, one with a single thread (as another machine might schedule it) — gives
//! byte-identical files everywhere except the ones that carry wall-clock times
//! (`crom_schemas::artifact::TIMING_FILES`) and the store's metadata (manifests, the column
//! index, the catalog, the published names), which record when and how long.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crom_schemas::artifact::{ArtifactKind, MANIFEST, TIMING_FILES};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn crom(store: &Path, threads: Option<&str>, args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_crom"));
    c.current_dir(repo()).arg("--store").arg(store).args(args).env_remove("CROM_STORE").env_remove("CROM_SCENES");
    match threads {
        Some(n) => c.env("RAYON_NUM_THREADS", n),
        None => c.env_remove("RAYON_NUM_THREADS"),
    };
    c.output().expect("crom runs")
}

/// Every result file of the store: relative path -> bytes.
fn result_files(store: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut visit = vec![store.to_path_buf()];
    while let Some(dir) = visit.pop() {
        for e in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            let path = e.path();
            let rel = path.strip_prefix(store).expect("inside").to_string_lossy().into_owned();
            let top = rel.split('/').next().unwrap_or_default();
            if e.file_type().expect("type").is_dir() {
                // The published names and failure tables are metadata (links and run records).
                if !["scenes", "runs", ".staging", ".quarantine"].contains(&top) {
                    visit.push(path);
                }
                continue;
            }
            let name = e.file_name().to_string_lossy().into_owned();
            let metadata = name == MANIFEST
                || name == ".lock"
                || rel == "catalog.parquet"
                || (top == "columns" && (name == "index.parquet" || rel.contains("/index/")));
            let timing = TIMING_FILES.iter().any(|(stage, file)| top == *stage && name == *file);
            if !metadata && !timing {
                out.insert(rel, std::fs::read(&path).expect("read"));
            }
        }
    }
    out
}

#[test]
fn results_are_byte_identical_across_runs_and_thread_counts() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    // The rope with nested levels (so that the nested stage is compared too) and hertz (Type 2).
    let rope = std::fs::read_to_string(repo().join("data/scenes/rope.toml")).expect("rope.toml");
    assert!(rope.contains("n_train = 10"), "rope.toml changed: update this test");
    let nested = tmp.path().join("rope-nested.toml");
    std::fs::write(&nested, rope.replace("n_train = 10", "n_train = 10\nnested_levels = 3")).expect("write");
    for scene in [nested.to_str().expect("utf8"), "hertz"] {
        let ra = crom(&a, None, &["--quiet", "run", scene]);
        assert!(ra.status.success(), "{}", String::from_utf8_lossy(&ra.stderr));
        let rb = crom(&b, Some("1"), &["--quiet", "run", scene]);
        assert!(rb.status.success(), "{}", String::from_utf8_lossy(&rb.stderr));
    }
    let (fa, fb) = (result_files(&a), result_files(&b));
    let names_a: Vec<&String> = fa.keys().collect();
    let names_b: Vec<&String> = fb.keys().collect();
    assert_eq!(names_a, names_b, "the same artifacts, under the same keys");
    // Every kind of result is compared: the blocks and one file of each stage at least.
    let has = |prefix: &str, suffix: &str| fa.keys().any(|k| k.starts_with(prefix) && k.ends_with(suffix));
    assert!(has("columns/", ".h5"), "snapshot blocks");
    for kind in ArtifactKind::ALL.iter().filter(|k| **k != ArtifactKind::Snapshot) {
        assert!(has(&format!("{}/", kind.name()), ""), "no {} file compared", kind.name());
    }
    for f in ["basis.h5", "online.h5", "rom_errors.parquet", "tradeoff.parquet", "solver_stats.parquet", "views.h5"] {
        assert!(has("", f), "{f} compared");
    }
    let differ: Vec<&String> = fa.iter().filter(|(k, v)| fb.get(*k) != Some(v)).map(|(k, _)| k).collect();
    assert!(differ.is_empty(), "result files differ between the runs: {differ:?}");
}
