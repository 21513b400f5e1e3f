//! End-to-end faults: a run killed (SIGKILL) during the metrics, the online
//! stage or the report resumes to the same result files as an uninterrupted run; two `crom`
//! processes racing on one store (same scene, other scene) — the second is refused with exit 3
//! and changes nothing; a byte flipped in a basis and in a Parquet table and a truncated
//! manifest are each detected, quarantined and recomputed to the same results. (A kill during
//! the snapshot sweep and a flipped snapshot block are tested in `e2e_columns.rs`, the kills of
//! a large study whose primal snapshots are streamed in `e2e_faults_scale.rs`.)

mod common;

use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use common::{artifacts, assert_same_results, crom, crom_cmd, kill_when, text, variant};

#[test]
fn a_run_killed_during_the_metrics_the_online_stage_or_the_report_resumes_to_identical_results() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    // A Type-2 scene with nested levels, small enough for the suite: ironing-coarse with 33
    // training points and 4 nested levels.
    let file = variant(
        tmp.path(),
        "ironing-coarse",
        "ironing-small.toml",
        &[("n_train = 128", "train_level = 5"), ("nested_levels = 7", "nested_levels = 4")],
    );
    let scene = file.to_str().expect("utf8");
    let reference = tmp.path().join("reference");
    let clean = crom(&reference, &["--quiet", "run", scene]);
    assert!(clean.status.success(), "{}", text(&clean));
    // After the basis: compactness, G(m), S(m) and the nested levels are next. After the nested
    // error: the online stage. After the online stage: its views and the report.
    let moments: [(&str, &str); 3] = [("metrics", "basis"), ("online stage", "nested"), ("report", "rom")];
    for (what, after) in moments {
        let store = tmp.path().join(what.replace(' ', "-"));
        let patience = Duration::from_secs(600);
        kill_when(crom_cmd(&store, &["--quiet", "run", scene]), what, patience, || artifacts(&store, after) > 0);
        // It names its study last: the killed run had not finished.
        assert!(!store.join("scenes/ironing-coarse").exists(), "{what}: the run had finished");
        let resumed = crom(&store, &["--quiet", "run", scene]);
        assert!(resumed.status.success(), "{what}: {}", text(&resumed));
        assert_same_results(&reference, &store, what);
        let verify = crom(&store, &["verify"]);
        assert!(verify.status.success() && text(&verify).contains(" 0 problems"), "{what}: {}", text(&verify));
    }
}

#[test]
fn a_second_process_on_a_busy_store_is_refused_and_changes_nothing() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    // A slow first run: 257 nested points, one snapshot per committed block.
    let slow = variant(tmp.path(), "rope", "rope-slow.toml", &[("n_train = 10", "n_train = 10\nnested_levels = 8")]);
    let slow = slow.to_str().expect("utf8");
    let store = tmp.path().join("store");
    let mut first = crom_cmd(&store, &["--quiet", "run", slow])
        .env("CROM_BLOCK_COLUMNS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn crom");
    let start = Instant::now();
    // The first run holds the lock from before its mesh until its end.
    while artifacts(&store, "mesh") == 0 && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(1));
    }
    for (what, scene) in [("the same scene", slow), ("another scene", "hertz")] {
        assert!(first.try_wait().expect("poll").is_none(), "the first run ended too early");
        let second = crom(&store, &["--quiet", "run", scene]);
        assert_eq!(second.status.code(), Some(3), "{what}: {}", text(&second));
        assert!(text(&second).contains("in use by another crom process"), "{what}: {}", text(&second));
    }
    assert!(first.wait().expect("wait").success(), "the first run completes undisturbed");
    assert_eq!(artifacts(&store, "mesh"), 1, "the refused hertz run wrote no mesh");
    assert!(!store.join("scenes/hertz").exists());
    let verify = crom(&store, &["verify"]);
    assert!(verify.status.success() && text(&verify).contains(" 0 problems"), "{}", text(&verify));
    // Its results are those of a run alone.
    let alone = tmp.path().join("alone");
    let solo = crom_cmd(&alone, &["--quiet", "run", slow]).env("CROM_BLOCK_COLUMNS", "1").output().expect("crom");
    assert!(solo.status.success(), "{}", text(&solo));
    assert_same_results(&alone, &store, "after a refused second process");
}

/// The first artifact directory of a stage.
fn first_dir(store: &Path, stage: &str) -> std::path::PathBuf {
    let mut dirs: Vec<_> = std::fs::read_dir(store.join(stage)).expect(stage).flatten().map(|e| e.path()).collect();
    dirs.sort();
    dirs.remove(0)
}

#[test]
fn a_flipped_byte_or_a_truncated_manifest_is_quarantined_and_recomputed_to_the_same_results() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let reference = tmp.path().join("reference");
    assert!(crom(&reference, &["--quiet", "run", "rope"]).status.success());
    /// Flip the lowest bit of the middle byte, or cut the file in half.
    fn damage(path: &Path, truncate: bool) {
        let mut bytes = std::fs::read(path).expect("read");
        let half = bytes.len() / 2;
        if truncate {
            bytes.truncate(half);
        } else {
            bytes[half] ^= 0x01;
        }
        std::fs::write(path, bytes).expect("write");
    }
    let damages = [
        ("a byte of basis.h5", "basis", "basis.h5", false),
        ("a byte of compactness.parquet", "compactness", "compactness.parquet", false),
        ("a truncated manifest", "specificity", "manifest.json", true),
    ];
    for (what, stage, file, truncate) in damages {
        let store = tmp.path().join(stage);
        assert!(crom(&store, &["--quiet", "run", "rope"]).status.success());
        damage(&first_dir(&store, stage).join(file), truncate);
        let rerun = crom(&store, &["run", "rope"]);
        assert!(rerun.status.success(), "{what}: {}", text(&rerun));
        assert!(text(&rerun).contains("failed verification"), "{what} not detected: {}", text(&rerun));
        assert_eq!(artifacts(&store, ".quarantine"), 1, "{what}: kept aside, not deleted");
        assert_same_results(&reference, &store, what);
    }
}
