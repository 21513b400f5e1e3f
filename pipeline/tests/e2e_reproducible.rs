//! End-to-end: result files are byte-reproducible. A scene run into two stores — one with the
//! default thread pool, one with a single thread (as another machine might schedule it) — gives
//! byte-identical files everywhere except the ones that carry wall-clock times
//! (`crom_schemas::artifact::timing_files`) and the store's metadata (manifests, the column
//! index, the catalog, the published names), which record when and how long.

mod common;

use common::{crom_cmd, result_files, text};
use crom_schemas::artifact::ArtifactKind;

fn crom(store: &std::path::Path, threads: Option<&str>, args: &[&str]) -> std::process::Output {
    let mut c = crom_cmd(store, args);
    if let Some(n) = threads {
        c.env("RAYON_NUM_THREADS", n);
    }
    c.output().expect("crom runs")
}

#[test]
fn results_are_byte_identical_across_runs_and_thread_counts() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    // The rope with nested levels (so that the nested stage is compared too) and hertz (Type 2).
    let nested =
        common::variant(tmp.path(), "rope", "rope-nested.toml", &[("n_train = 10", "n_train = 10\nnested_levels = 3")]);
    for scene in [nested.to_str().expect("utf8"), "hertz"] {
        let ra = crom(&a, None, &["--quiet", "run", scene]);
        assert!(ra.status.success(), "{}", text(&ra));
        let rb = crom(&b, Some("1"), &["--quiet", "run", scene]);
        assert!(rb.status.success(), "{}", text(&rb));
    }
    let (fa, fb) = (result_files(&a), result_files(&b));
    let names_a: Vec<&String> = fa.keys().collect();
    let names_b: Vec<&String> = fb.keys().collect();
    assert_eq!(names_a, names_b, "the same artifacts, under the same keys");
    // Every kind of result is compared: the blocks and one file of each stage at least.
    let has = |prefix: &str, suffix: &str| fa.keys().any(|k| k.starts_with(prefix) && k.ends_with(suffix));
    assert!(has("columns/", ".h5"), "snapshot blocks");
    for kind in ArtifactKind::ALL.iter().filter(|k| **k != ArtifactKind::SNAPSHOT) {
        assert!(has(&format!("{}/", kind.name()), ""), "no {} file compared", kind.name());
    }
    for f in ["basis.h5", "online.h5", "rom_errors.parquet", "tradeoff.parquet", "solver_stats.parquet", "views.h5"] {
        assert!(has("", f), "{f} compared");
    }
    let differ: Vec<&String> = fa.iter().filter(|(k, v)| fb.get(*k) != Some(v)).map(|(k, _)| k).collect();
    assert!(differ.is_empty(), "result files differ between the runs: {differ:?}");
}
