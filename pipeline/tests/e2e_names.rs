//! End-to-end: the store catalog and the stable per-scene names (`scenes/<scene>/…`). Names
//! follow finished runs only — a failed or killed run leaves the previous ones — never point
//! into the quarantine, and `crom ls` in every format agrees with `catalog.parquet`.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{artifacts, crom, crom_cmd, kill_when, text, variant};
use crom_pipeline::io::table::read_parquet;
use crom_schemas::artifact::catalog::COLUMNS;

/// A variant of the rope scene (same scene name, so it publishes under `scenes/rope`).
fn rope_variant(dir: &Path, file: &str, edits: &[(&str, &str)]) -> PathBuf {
    variant(dir, "rope", file, edits)
}

/// Where a published name leads, as a path relative to the store root.
fn resolved(store: &Path, name: &str) -> PathBuf {
    let real = std::fs::canonicalize(store.join("scenes/rope").join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    real.strip_prefix(std::fs::canonicalize(store).expect("store")).expect("inside the store").to_path_buf()
}

#[test]
fn names_follow_finished_runs_and_a_failed_or_killed_run_keeps_the_old_ones() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let first = crom(&store, &["--quiet", "run", "rope"]);
    assert!(first.status.success(), "{}", text(&first));
    let old_basis = resolved(&store, "basis.h5");
    let old_link = std::fs::read_link(store.join("scenes/rope")).expect("scenes/rope is a link");
    assert!(old_basis.starts_with("basis"), "{old_basis:?}");
    assert!(resolved(&store, "report").join("index.html").starts_with("report"));

    // A run that fails (no snapshot converges in one iteration): exit 1, names unchanged.
    let failing = rope_variant(
        tmp.path(),
        "rope-failing.toml",
        &[("max_iter = 100", "max_iter = 1"), ("dual_cone_tol_truncated = 0.2", "dual_cone_tol_truncated = 0.3")],
    );
    let failed = crom(&store, &["--quiet", "run", failing.to_str().expect("utf8")]);
    assert_eq!(failed.status.code(), Some(1), "{}", text(&failed));
    assert_eq!(std::fs::read_link(store.join("scenes/rope")).expect("link"), old_link);
    assert_eq!(resolved(&store, "basis.h5"), old_basis);

    // A run killed (SIGKILL) after it committed a new basis, during its nested sweep: the names
    // still lead to the old basis, never to the new one, a staging or a quarantined directory.
    let changed = rope_variant(
        tmp.path(),
        "rope-changed.toml",
        &[
            ("dual_cone_tol_truncated = 0.2", "dual_cone_tol_truncated = 0.3"),
            ("n_train = 10", "n_train = 10\nnested_levels = 8"),
        ],
    );
    let changed = changed.to_str().expect("utf8");
    let mut cmd = crom_cmd(&store, &["--quiet", "run", changed]);
    cmd.env("CROM_BLOCK_COLUMNS", "1");
    kill_when(cmd, "after the new basis", Duration::from_secs(300), || artifacts(&store, "basis") == 2);
    assert_eq!(artifacts(&store, "nested"), 0, "the run was killed before it finished");
    assert_eq!(std::fs::read_link(store.join("scenes/rope")).expect("link"), old_link);
    assert_eq!(resolved(&store, "basis.h5"), old_basis);
    assert!(!store.join("scenes/rope/nested").exists());

    // Finished, the same run moves every name at once.
    let done = crom(&store, &["--quiet", "run", changed]);
    assert!(done.status.success(), "{}", text(&done));
    let new_basis = resolved(&store, "basis.h5");
    assert_ne!(new_basis, old_basis);
    assert!(new_basis.starts_with("basis"));
    assert!(resolved(&store, "nested/level-8.h5").starts_with("trainset"));
    assert!(resolved(&store, "nested.parquet").starts_with("nested"));
    let versions = std::fs::read_dir(store.join("scenes/.versions")).expect("versions").count();
    assert_eq!(versions, 2, "the current and the previous link sets are kept, older ones removed");
}

#[test]
fn a_quarantined_artifact_loses_its_name_until_the_next_run() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    assert!(crom(&store, &["--quiet", "run", "rope"]).status.success());
    let basis = store.join(resolved(&store, "basis.h5"));
    let mut bytes = std::fs::read(&basis).expect("basis");
    let at = bytes.len() / 2;
    bytes[at] ^= 0xff;
    std::fs::write(&basis, bytes).expect("damage");
    let verify = crom(&store, &["verify"]);
    assert_eq!(verify.status.code(), Some(1), "{}", text(&verify));
    assert!(!store.join("scenes/rope/basis.h5").exists(), "no name may lead into the quarantine");
    assert!(store.join("scenes/rope/train.h5").exists(), "the other names stay");
    // The stored reduced model is published under its names (an online run of a native scene).
    for name in ["model.h5", "reconstruction.h5", "model_speed.parquet"] {
        assert!(resolved(&store, name).starts_with("model"), "{name}");
    }
    let study = std::fs::read_to_string(store.join("scenes/rope/study.json")).expect("study.json");
    assert!(study.contains("\"withdrawn\"") && study.contains("quarantined"), "{study}");
    let catalog = read_parquet(&store.join("catalog.parquet")).expect("catalog");
    let paths = catalog.strs("path").expect("path");
    assert!(paths.iter().all(|p| !basis.ends_with(Path::new(p).join("basis.h5"))), "catalog lists it no more");

    let rerun = crom(&store, &["--quiet", "run", "rope"]);
    assert!(rerun.status.success(), "{}", text(&rerun));
    assert!(store.join("scenes/rope/basis.h5").is_file(), "restored by the next run");
}

#[test]
fn ls_in_every_format_agrees_with_the_catalog() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    assert!(crom(&store, &["--quiet", "run", "rope"]).status.success());
    let catalog = read_parquet(&store.join("catalog.parquet")).expect("catalog");
    let names: Vec<&str> = catalog.columns.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, COLUMNS);
    // 1 column family + mesh, train, test, their views and the basis's, basis, compactness,
    // generalization, specificity, rom, model, report: counted from the stage directories.
    let stages = [
        "mesh",
        "trainset",
        "views",
        "basis",
        "compactness",
        "generalization",
        "specificity",
        "rom",
        "model",
        "report",
    ];
    let expected = 1 + stages.iter().map(|s| artifacts(&store, s)).sum::<usize>();
    assert_eq!(catalog.rows(), expected);

    let out = tmp.path().join("ls.parquet");
    let ls = crom(&store, &["ls", "--format", "parquet", "--output", out.to_str().expect("utf8")]);
    assert!(ls.status.success(), "{}", text(&ls));
    assert_eq!(read_parquet(&out).expect("ls parquet"), catalog);
    // Parquet on standard output (redirected) is the same table.
    let piped = crom(&store, &["ls", "--format", "parquet"]);
    let piped_path = tmp.path().join("piped.parquet");
    std::fs::write(&piped_path, &piped.stdout).expect("write");
    assert_eq!(read_parquet(&piped_path).expect("piped parquet"), catalog);

    let csv = crom(&store, &["ls", "--format", "csv"]);
    let csv = String::from_utf8_lossy(&csv.stdout).into_owned();
    assert_eq!(csv.lines().next(), Some(COLUMNS.join(",").as_str()));
    assert_eq!(csv.lines().count(), 1 + catalog.rows());
    let json = crom(&store, &["ls", "--format", "json", "--stage", "trainset"]);
    let rows: serde_json::Value = serde_json::from_slice(&json.stdout).expect("json");
    let sets: Vec<&str> = rows.as_array().expect("array").iter().filter_map(|r| r["set"].as_str()).collect();
    assert_eq!(sets.len(), 2);
    assert!(sets.contains(&"train") && sets.contains(&"test"), "{sets:?}");

    let bad = crom(&store, &["ls", "--stage", "bassis"]);
    assert_eq!(bad.status.code(), Some(2), "{}", text(&bad));
    assert!(text(&bad).contains("--stage bassis") && text(&bad).contains("fix:"), "{}", text(&bad));

    // `crom catalog` rebuilds the same table from the manifests after the file is lost.
    std::fs::remove_file(store.join("catalog.parquet")).expect("rm");
    let rebuilt = crom(&store, &["catalog"]);
    assert!(rebuilt.status.success(), "{}", text(&rebuilt));
    assert_eq!(read_parquet(&store.join("catalog.parquet")).expect("rebuilt"), catalog);
}
