//! End-to-end faults at scale: a study large enough that its primal snapshots are streamed from
//! the store (more than 1 025 training points: the keys of its bases and metrics carry
//! `primal = "streamed"`), killed (SIGKILL) during its snapshot sweep, during its basis stage and
//! during its metrics, resumes each time to the same result files, byte for byte, as an
//! uninterrupted cold run. (The small study's kills are in `e2e_faults.rs` and
//! `e2e_columns.rs`.) Settings of a large study that cannot work are refused with exit 2 before
//! anything is written, naming the field and the fix; a rank grid or a fold sample beyond the
//! training set is clamped, and the run says so.

mod common;

use std::path::Path;
use std::time::Duration;

use common::{artifacts, assert_same_results, blocks, crom, crom_cmd, kill_when, text, variant};

/// Snapshot blocks of the study: 2 049 training and 2 048 test points of the rope (201 + 201
/// rows per column: 128 columns per block).
const STUDY_BLOCKS: usize = 2049_usize.div_ceil(128) + 2048_usize.div_ceil(128);

/// Whether the study's result has been published (it names its study last).
fn finished(store: &Path) -> bool {
    store.join("scenes/rope").exists()
}

/// The rope at nested level 11 (2 049 training points, the smallest level above the streaming
/// size of 1 025), with 40 specificity samples and 16 leave-one-out folds so that the metrics
/// stay short: one run is a few seconds in release and about 20 s in the debug build.
///
/// One store is killed three times in a row: in the sweep (once 3 of its 33 blocks are
/// committed), in the basis stage of the next run (as soon as the training set is committed: the
/// basis is the next stage and takes seconds) and in the metrics of the run after (as soon as
/// the basis is committed), then resumed to the end; each run starts from the store the last
/// kill left. Chained, the test costs about two uninterrupted runs instead of four.
#[test]
fn a_streamed_study_killed_in_its_sweep_basis_and_metrics_resumes_to_identical_results() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let file = variant(
        tmp.path(),
        "rope",
        "rope-streamed.toml",
        &[
            ("n_train = 10", "train_level = 11"),
            ("specificity_samples = 1000", "specificity_samples = 40\nloo_folds = 16"),
        ],
    );
    let scene = file.to_str().expect("utf8");
    let args = ["--quiet", "run", scene, "--offline"];
    let reference = tmp.path().join("reference");
    let clean = crom(&reference, &args);
    assert!(clean.status.success(), "{}", text(&clean));
    assert_eq!(blocks(&reference), STUDY_BLOCKS, "the block layout this test counts on");
    let spec = std::fs::read_dir(reference.join("basis"))
        .expect("basis")
        .flatten()
        .map(|e| std::fs::read_to_string(e.path().join("manifest.json")).expect("manifest"))
        .next()
        .expect("one basis");
    assert!(spec.replace(' ', "").contains("\"primal\":\"streamed\""), "the study is streamed: {spec}");

    let store = tmp.path().join("killed");
    let patience = Duration::from_secs(600);
    kill_when(crom_cmd(&store, &args), "in the sweep", patience, || blocks(&store) >= 3);
    let committed = blocks(&store);
    assert!(committed < STUDY_BLOCKS, "the sweep had finished before the kill ({committed} blocks)");
    assert_eq!(artifacts(&store, "trainset"), 0, "in the sweep: no training set yet");

    kill_when(crom_cmd(&store, &args), "in the basis stage", patience, || artifacts(&store, "trainset") > 0);
    assert_eq!(blocks(&store), STUDY_BLOCKS, "in the basis stage: the sweep was complete");
    assert_eq!(artifacts(&store, "basis"), 0, "in the basis stage: no basis yet");

    kill_when(crom_cmd(&store, &args), "in the metrics", patience, || artifacts(&store, "basis") > 0);
    let metrics = ["compactness", "generalization", "specificity"].map(|s| artifacts(&store, s));
    assert!(metrics.contains(&0), "in the metrics: some metric was still to come ({metrics:?})");
    assert!(!finished(&store), "the killed runs had not finished");

    let resumed = crom(&store, &args);
    assert!(resumed.status.success(), "{}", text(&resumed));
    assert_same_results(&reference, &store, "killed in the sweep, the basis and the metrics");
    let verify = crom(&store, &["verify"]);
    assert!(verify.status.success() && text(&verify).contains(" 0 problems"), "{}", text(&verify));
}

/// Refused, exit 2, nothing written, the field and the fix named: a training level whose
/// memory estimate exceeds the limit (the rope at `train_level = 17`, 131 073 training points,
/// 1 008 MiB, under `--max-memory 256M`), and a fold sample of 0 (`study.loo_folds = 0`).
/// Clamped, not refused (earlier studies rely on it): `study.max_rank = 1000` and
/// `study.loo_folds = 50` over the rope's 10 training points run, and the run's summary states
/// the values the results are those of (m up to 10, all 10 folds).
#[test]
fn settings_that_cannot_work_exit_2_naming_the_field_and_the_fix_and_clamped_ones_are_stated() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let huge = variant(tmp.path(), "rope", "rope-level17.toml", &[("n_train = 10", "train_level = 17")]);
    let out = crom(&store, &["--max-memory", "256M", "run", huge.to_str().expect("utf8"), "--offline"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let msg = text(&out);
    assert!(msg.contains("rope-level17.toml") && msg.contains("parameter.train_level"), "{msg}");
    assert!(
        msg.contains(" MiB (of which dual training set") && msg.contains("fix:") && msg.contains("--max-memory"),
        "{msg}"
    );
    assert!(!store.exists(), "nothing written for a scene that cannot fit");

    let no_folds =
        variant(tmp.path(), "rope", "rope-no-folds.toml", &[("seed = 20231", "seed = 20231\nloo_folds = 0")]);
    let out = crom(&store, &["run", no_folds.to_str().expect("utf8"), "--offline"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let msg = text(&out);
    assert!(msg.contains("rope-no-folds.toml") && msg.contains("study.loo_folds"), "{msg}");
    assert!(msg.contains("fix: give the number of leave-one-out folds (>= 1)"), "{msg}");
    assert!(!store.exists(), "nothing written for a fold sample of 0");

    let beyond = variant(
        tmp.path(),
        "rope",
        "rope-beyond.toml",
        &[("seed = 20231", "seed = 20231\nmax_rank = 1000\nloo_folds = 50")],
    );
    let out = crom(&store, &["run", beyond.to_str().expect("utf8"), "--offline"]);
    assert!(out.status.success(), "{}", text(&out));
    let msg = text(&out);
    assert!(
        msg.contains("study.max_rank = 1000 is more than the 10 training snapshots: the metric curves stop at m = 10"),
        "{msg}"
    );
    assert!(msg.contains("study.loo_folds = 50 is more than the 10 training snapshots: G(m) averages all 10"), "{msg}");
}
