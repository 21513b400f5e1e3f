//! End-to-end: the columnar snapshot store — a study grown by one level solves only the new
//! points, and a sweep killed mid-way resumes to the same results as an uninterrupted run.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::Duration;

use common::{blocks, crom, crom_cmd, kill_when, repo, text};

/// `(computed, cached)` of one stage in the closing summary.
fn stage_counts(o: &Output, stage: &str) -> (usize, usize) {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .find_map(|l| match l.split_whitespace().collect::<Vec<_>>().as_slice() {
            [s, c, k, _] if *s == stage => Some((c.parse().ok()?, k.parse().ok()?)),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no `{stage}` line in:\n{}", text(o)))
}

/// The rope scene with its training grid replaced by nested level `level` and no nested study.
fn rope_level(dir: &Path, level: u32) -> PathBuf {
    let rope = std::fs::read_to_string(repo().join("data/scenes/rope.toml")).expect("rope.toml");
    assert!(rope.contains("n_train = 10"), "rope.toml changed: update this test");
    let path = dir.join(format!("rope-level{level}.toml"));
    std::fs::write(&path, rope.replace("n_train = 10", &format!("train_level = {level}"))).expect("write scene");
    path
}

#[test]
fn growing_a_study_by_one_level_solves_only_the_new_points() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let lo = rope_level(tmp.path(), 3);
    let hi = rope_level(tmp.path(), 4);
    let first = crom(&store, &["run", lo.to_str().expect("utf8")]);
    assert!(first.status.success(), "{}", text(&first));
    // Level 3: 9 training points and the 8 midpoints as test points.
    assert_eq!(stage_counts(&first, "snapshot"), (17, 0));
    let second = crom(&store, &["run", hi.to_str().expect("utf8")]);
    assert!(second.status.success(), "{}", text(&second));
    // Level 4 trains on the 17 points of level 3 (train + test, all reused) and tests on the
    // 16 new midpoints: exactly those are solved.
    assert_eq!(stage_counts(&second, "snapshot"), (16, 17), "{}", text(&second));
    assert!(text(&second).contains("16 solved, 17 reused"), "{}", text(&second));
    // `crom status` has a line per level: levels 3 and 4 studied, 1 and 2 not (their points are
    // all stored, as points of level 3, but no study of them ran).
    let status = crom(&store, &["status", hi.to_str().expect("utf8")]);
    assert!(status.status.success(), "{}", text(&status));
    let out = text(&status);
    let line = |k: u32| {
        out.lines().find(|l| l.trim_start().starts_with(&format!("level {k:>2}:"))).unwrap_or_else(|| panic!("{out}"))
    };
    assert!(line(4).contains("17 training points; 33 of 33 points stored; studied"), "{out}");
    assert!(line(3).contains("9 training points; 17 of 17 points stored; studied"), "{out}");
    for k in [1, 2] {
        assert!(line(k).contains("offline stages stored") && !line(k).contains("studied"), "{out}");
    }
}

/// Result files that carry no wall-clock time and no storage layout: must be byte-identical.
const RESULT_FILES: [(&str, &str); 5] = [
    ("basis", "basis.h5"),
    ("compactness", "compactness.parquet"),
    ("generalization", "generalization.parquet"),
    ("specificity", "specificity.parquet"),
    ("nested", "nested.parquet"),
];

/// The rope scene with nested levels 1..=levels (2^levels + 1 points on the finest).
fn rope_nested(dir: &Path, levels: u32) -> PathBuf {
    let rope = std::fs::read_to_string(repo().join("data/scenes/rope.toml")).expect("rope.toml");
    assert!(rope.contains("n_train = 10"), "rope.toml changed: update this test");
    let path = dir.join(format!("rope-nested{levels}.toml"));
    let text = rope.replace("n_train = 10", &format!("n_train = 10\nnested_levels = {levels}"));
    std::fs::write(&path, text).expect("write scene");
    path
}

fn only(store: &Path, stage: &str, file: &str) -> PathBuf {
    let dirs: Vec<PathBuf> = std::fs::read_dir(store.join(stage)).expect(stage).flatten().map(|e| e.path()).collect();
    assert_eq!(dirs.len(), 1, "{stage}: {dirs:?}");
    dirs[0].join(file)
}

#[test]
fn a_sweep_killed_mid_way_resumes_to_identical_results() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    // 10 training + 9 test points, then nested levels up to 2^8 + 1 = 257 points.
    let scene = rope_nested(tmp.path(), 8);
    let scene = scene.to_str().expect("utf8");
    let reference = tmp.path().join("reference");
    let clean = crom(&reference, &["--quiet", "run", scene]);
    assert!(clean.status.success(), "{}", text(&clean));

    let store = tmp.path().join("killed");
    let mut cmd = crom_cmd(&store, &["--quiet", "run", scene]);
    cmd.env("CROM_BLOCK_COLUMNS", "1");
    // Kill (SIGKILL) as soon as a few one-snapshot blocks are committed, during the sweep.
    kill_when(cmd, "during the sweep", Duration::from_secs(120), || blocks(&store) >= 3);
    let done_before = blocks(&store);
    assert!(done_before >= 3, "no block was committed before the kill");
    assert!(done_before < 19 + 257, "the sweep had finished before the kill");

    let resumed = crom(&store, &["run", scene]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    // The summary's snapshot line adds up both sweeps (train + test, then the nested levels).
    let (solved, reused) = stage_counts(&resumed, "snapshot");
    let (ref_solved, ref_reused) = stage_counts(&clean, "snapshot");
    assert_eq!(solved + reused, ref_solved + ref_reused, "{}", text(&resumed));
    assert!(reused >= 3, "the committed blocks were reused: {}", text(&resumed));
    for (stage, file) in RESULT_FILES {
        let a = std::fs::read(only(&reference, stage, file)).expect("reference file");
        let b = std::fs::read(only(&store, stage, file)).expect("resumed file");
        assert!(a == b, "{stage}/{file} differs between the uninterrupted and the resumed run");
    }
}

#[test]
fn a_damaged_block_is_quarantined_and_its_points_solved_again() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let first = crom(&store, &["run", "rope"]);
    assert!(first.status.success(), "{}", text(&first));
    let reference = std::fs::read(only(&store, "basis", "basis.h5")).expect("basis");
    // Flip the lowest bit of one stored displacement value: same size, a valid HDF5 file, so
    // only the column checksums can tell. Delete the basis so that the next run has to read
    // the training set.
    let store_obj = crom_pipeline::store::Store::open_read_only(&store);
    let fam = store_obj.families().pop().expect("one family");
    let index = fam.load_index().expect("index");
    let train = std::fs::read_dir(store.join("trainset"))
        .expect("sets")
        .flatten()
        .map(|e| crom_pipeline::io::table::read_parquet(&e.path().join("solver_stats.parquet")).expect("stats"))
        .find(|t| t.rows() == 10)
        .expect("the 10-point training set");
    let key = crom_pipeline::cache::Key(train.strs("snapshot_key").expect("keys")[4].clone());
    let row = &index.rows[&key];
    let (primal, _) = crom_pipeline::store::columns::read_columns(&store, 201, 201, &[row]).expect("clean read");
    assert_eq!(index.rows.len(), 19);
    let block = store.join(&row.block);
    let mut bytes = std::fs::read(&block).expect("read block");
    let needle = primal.col(0)[100].to_le_bytes();
    assert!(primal.col(0)[100].abs() > 0.0, "a non-zero value to flip");
    // Every copy of that value (another column may hold the same bits): the training column's
    // copy is among them.
    let at: Vec<usize> = bytes.windows(8).enumerate().filter(|(_, w)| *w == needle).map(|(i, _)| i).collect();
    assert!(!at.is_empty(), "the value is stored verbatim");
    for i in at {
        bytes[i] ^= 1;
    }
    std::fs::write(&block, &bytes).expect("write block");
    let basis_dir = only(&store, "basis", "basis.h5").parent().expect("dir").to_path_buf();
    std::fs::remove_dir_all(&basis_dir).expect("drop basis");
    let second = crom(&store, &["run", "rope"]);
    assert!(second.status.success(), "{}", text(&second));
    let out = text(&second);
    assert!(out.contains("does not match its blake3") && out.contains("solved again"), "{out}");
    assert_eq!(stage_counts(&second, "snapshot"), (19, 0), "{out}");
    let quarantined: Vec<_> = std::fs::read_dir(store.join(".quarantine")).expect("quarantine").flatten().collect();
    assert_eq!(quarantined.len(), 1, "the damaged block is kept aside");
    assert_eq!(std::fs::read(only(&store, "basis", "basis.h5")).expect("basis"), reference, "same basis as before");
    // And `crom verify` finds the store clean again.
    let verify = crom(&store, &["verify"]);
    assert!(verify.status.success(), "{}", text(&verify));
    assert!(text(&verify).contains("0 problems"), "{}", text(&verify));
}
