//! End-to-end: the real `crom` binary on the rope scene in a temporary store.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crom_pipeline::store::Store;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn crom(store: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_crom"))
        .current_dir(repo())
        .arg("--store")
        .arg(store)
        .args(args)
        .env_remove("CROM_STORE")
        .env_remove("CROM_SCENES")
        .output()
        .expect("crom runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// `(stage, computed, cached)` rows of the closing summary.
fn summary(o: &Output) -> Vec<(String, usize, usize)> {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            match f.as_slice() {
                [stage, c, k, _path] => Some((stage.to_string(), c.parse().ok()?, k.parse().ok()?)),
                _ => None,
            }
        })
        .collect()
}

fn artifact_dirs(store: &Path, stage: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> =
        std::fs::read_dir(store.join(stage)).map(|rd| rd.flatten().map(|e| e.path()).collect()).unwrap_or_default();
    v.sort();
    v
}

#[test]
fn run_rope_writes_artifacts_and_rerun_is_a_full_cache_hit() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let first = crom(&store, &["run", "rope"]);
    assert!(first.status.success(), "{}", text(&first));
    let rows = summary(&first);
    let stages: Vec<&str> = rows.iter().map(|r| r.0.as_str()).collect();
    assert_eq!(
        stages,
        [
            "mesh",
            "snapshot",
            "trainset",
            "testset",
            "views",
            "basis",
            "compactness",
            "generalization",
            "specificity",
            "rom",
            "model",
            "report"
        ]
    );
    // 10 training + 9 test points, all new.
    assert_eq!(rows[1], ("snapshot".to_string(), 19, 0));
    assert!(rows.iter().all(|r| r.2 == 0), "nothing cached on a fresh store");

    for stage in
        ["mesh", "trainset", "views", "basis", "compactness", "generalization", "specificity", "rom", "model", "report"]
    {
        for dir in artifact_dirs(&store, stage) {
            let manifest: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).expect("manifest"))
                    .expect("json");
            assert_eq!(manifest["stage"], stage);
            assert_eq!(manifest["key"], dir.file_name().and_then(|n| n.to_str()).unwrap_or_default());
            assert_eq!(manifest["scene"], "rope");
            assert!(manifest["files"].as_array().is_some_and(|f| !f.is_empty()));
        }
    }
    // The 19 snapshots are columns of one family, not directories.
    assert!(!store.join("snapshot").exists());
    let families = artifact_dirs(&store, "columns");
    assert_eq!(families.len(), 1);
    let index = crom_pipeline::io::table::read_parquet(&families[0].join("index.parquet")).expect("index");
    assert_eq!(index.rows(), 19);
    assert!(artifact_dirs(&store, "mesh")[0].join("mesh.xdmf").is_file());
    assert!(!store.join(".staging").exists() || artifact_dirs(&store, ".staging").is_empty());

    let second = crom(&store, &["run", "rope"]);
    assert!(second.status.success(), "{}", text(&second));
    assert!(summary(&second).iter().all(|r| r.1 == 0), "rerun computed something:\n{}", text(&second));
    assert!(text(&second).contains("nothing computed"), "{}", text(&second));
}

#[test]
fn deleting_a_block_recomputes_exactly_its_points() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    assert!(crom(&store, &["run", "rope"]).status.success());
    let family = artifact_dirs(&store, "columns")[0].clone();
    let blocks = artifact_dirs(&family, "blocks");
    assert_eq!(blocks.len(), 1, "19 small rope snapshots fit one block");
    std::fs::remove_file(&blocks[0]).expect("delete the block");
    let out = crom(&store, &["run", "rope"]);
    assert!(out.status.success(), "{}", text(&out));
    let rows = summary(&out);
    assert_eq!(rows[1], ("snapshot".to_string(), 19, 0), "{}", text(&out));
    // A block's file is a function of its snapshots (key order): the same block is back under
    // the same name, so the sets' column references still hold and every downstream artifact
    // is a cache hit.
    assert!(blocks[0].is_file(), "the block is back under the same name");
    assert!(rows.iter().filter(|r| r.0 != "snapshot").all(|r| r.1 == 0), "{}", text(&out));
}

#[test]
fn corrupt_artifact_is_quarantined_and_recomputed() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    assert!(crom(&store, &["run", "rope"]).status.success());
    let basis = artifact_dirs(&store, "basis")[0].join("basis.h5");
    let mut bytes = std::fs::read(&basis).expect("read basis");
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0xff;
    std::fs::write(&basis, bytes).expect("corrupt basis");
    let out = crom(&store, &["run", "rope"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("failed verification"), "{}", text(&out));
    let quarantine = artifact_dirs(&store, ".quarantine");
    assert_eq!(quarantine.len(), 1, "the corrupt artifact is kept aside, not deleted");
    let rows = summary(&out);
    assert!(rows.iter().any(|r| r.0 == "basis" && r.1 == 1), "{}", text(&out));
}

#[test]
fn bad_scene_file_exits_2_naming_file_and_field() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = tmp.path().join("broken.toml");
    let rope = std::fs::read_to_string(repo().join("data/scenes/rope.toml")).expect("rope.toml");
    std::fs::write(&scene, rope.replace("n_elements = 200", "n_elements = 1")).expect("write scene");
    let out = crom(&store, &["run", scene.to_str().expect("utf8 path")]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let msg = text(&out);
    assert!(msg.contains("broken.toml") && msg.contains("model.rope.n_elements") && msg.contains("fix:"), "{msg}");
    assert!(!store.join("columns").exists(), "nothing written for a bad scene");
}

#[test]
fn unknown_scene_lists_the_available_ones() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let out = crom(&tmp.path().join("store"), &["run", "ropes"]);
    assert_eq!(out.status.code(), Some(2));
    let msg = text(&out);
    assert!(msg.contains("unknown scene `ropes`") && msg.contains("hertz, ") && msg.contains(", rope"), "{msg}");
}

#[test]
fn locked_store_exits_3_and_writes_nothing() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let held = Store::open(&store).expect("take the lock");
    let out = crom(&store, &["run", "rope"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    assert!(text(&out).contains("in use by another crom process"));
    assert!(artifact_dirs(&store, "mesh").is_empty());
    drop(held);
    assert!(crom(&store, &["run", "rope"]).status.success());
}

#[test]
fn ls_lists_every_artifact() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    assert!(crom(&store, &["run", "rope"]).status.success());
    let out = crom(&store, &["ls"]);
    assert!(out.status.success());
    // mesh + train + test + 4 views (train, test, basis, online) + basis + compactness + G + S
    // + rom + model + report, and one column family
    let listing = String::from_utf8_lossy(&out.stdout);
    assert!(listing.contains("14 artifacts"), "{}", text(&out));
    assert!(listing.contains("19 snapshots (201 x 201) in 1 blocks"), "{}", text(&out));
}

#[test]
fn failed_points_are_named_tabled_and_exit_1() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = tmp.path().join("rope-strict.toml");
    let rope = std::fs::read_to_string(repo().join("data/scenes/rope.toml")).expect("rope.toml");
    // One active-set iteration cannot settle the contact set of any training point.
    std::fs::write(&scene, rope.replace("max_iter = 100", "max_iter = 1")).expect("write scene");
    let out = crom(&store, &["run", scene.to_str().expect("utf8 path")]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let msg = text(&out);
    assert!(
        msg.contains("19 of 19 snapshots") && msg.contains("gamma = -0.5") && msg.contains("no convergence"),
        "{msg}"
    );
    assert!(store.join("runs/rope/solver_failures.parquet").is_file(), "{msg}");
    assert!(artifact_dirs(&store, "trainset").is_empty(), "nothing downstream of failed snapshots");
}

fn variant(dir: &Path, name: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let rope = std::fs::read_to_string(repo().join("data/scenes/rope.toml")).expect("rope.toml");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, edit(rope)).expect("write scene");
    path
}

fn table(store: &Path, stage: &str, file: &str) -> crom_pipeline::io::table::Table {
    let dir = &artifact_dirs(store, stage)[0];
    crom_pipeline::io::table::read_parquet(&dir.join(file)).expect("table reads")
}

/// Extreme: the obstacle is far below, no point touches it. Every dual snapshot is zero: the
/// dual bases are empty, the metrics count the zero snapshots instead of dividing by them, the
/// online solve returns the lift, and the report is still written.
#[test]
fn no_contact_anywhere_runs_to_the_report() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = variant(tmp.path(), "rope-free", |t| t.replace("offset = -0.5 }", "offset = -10.0 }"));
    let out = crom(&store, &["run", scene.to_str().expect("utf8")]);
    assert!(out.status.success(), "{}", text(&out));
    let g = table(&store, "generalization", "generalization.parquet");
    let (fields, n_zero) = (g.strs("field").expect("field"), g.u64s("n_zero").expect("n_zero"));
    assert!(fields.iter().zip(n_zero).all(|(f, z)| f != "dual" || *z == 10), "all 10 dual snapshots are zero");
    let rom = table(&store, "rom", "rom_errors.parquet");
    // The primal error is exactly 0 (the ROM returns the lift, which is the snapshot); the dual
    // error is undefined (NaN), not a division by zero.
    assert!(rom.f64s("primal_error").expect("col").iter().all(|e| e.abs() < 1e-12));
    assert!(rom.f64s("dual_error").expect("col").iter().all(|e| e.is_nan()));
    assert!(artifact_dirs(&store, "report")[0].join("index.html").is_file());
}

/// Extreme: at gamma = 0 every interior node is in contact (obstacle -0.2 sin(pi x): the
/// multiplier f - nu g'' = 250 - 59 sin(pi x) > 0 everywhere).
#[test]
fn full_contact_runs_to_the_report() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = variant(tmp.path(), "rope-full", |t| {
        t.replace(
            "modes = [1.0, 3.0], amplitudes = [-0.2, 0.2], offset = -0.5",
            "modes = [1.0], amplitudes = [-0.2], offset = 0.0",
        )
        .replace("max = 0.5", "max = 0.0")
    });
    let out = crom(&store, &["run", scene.to_str().expect("utf8")]);
    assert!(out.status.success(), "{}", text(&out));
    let train = artifact_dirs(&store, "trainset")
        .into_iter()
        .map(|d| crom_pipeline::io::table::read_parquet(&d.join("solver_stats.parquet")).expect("stats"))
        .find(|t| t.f64s("parameter").is_some_and(|p| p.iter().any(|x| x.abs() < 1e-15)))
        .expect("the training set holds gamma = 0");
    let active = train.u64s("active").expect("active");
    assert_eq!(*active.last().expect("rows"), 199, "all 199 interior nodes in contact at gamma = 0");
    assert!(artifact_dirs(&store, "report")[0].join("index.html").is_file());
}

/// Each metric is its own stage: changing the specificity sample count recomputes specificity
/// and the report that shows it, and nothing else.
#[test]
fn changing_one_metric_setting_recomputes_only_that_stage() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let a = variant(tmp.path(), "rope-a", |t| t);
    let b = variant(tmp.path(), "rope-b", |t| t.replace("specificity_samples = 1000", "specificity_samples = 300"));
    assert!(crom(&store, &["run", a.to_str().expect("utf8")]).status.success());
    let out = crom(&store, &["run", b.to_str().expect("utf8")]);
    assert!(out.status.success(), "{}", text(&out));
    let computed: Vec<String> = summary(&out).into_iter().filter(|r| r.1 > 0).map(|r| r.0).collect();
    assert_eq!(computed, ["specificity", "report"], "{}", text(&out));
}

/// `crom run --offline` stops before the online ROM and the report; the next full run computes
/// exactly those (and the online solutions' views) and finds everything else in the store.
#[test]
fn offline_run_stops_before_the_online_stage() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let off = crom(&store, &["run", "--offline", "rope"]);
    assert!(off.status.success(), "{}", text(&off));
    assert!(artifact_dirs(&store, "rom").is_empty() && artifact_dirs(&store, "report").is_empty());
    assert!(artifact_dirs(&store, "model").is_empty());
    let full = crom(&store, &["run", "rope"]);
    assert!(full.status.success(), "{}", text(&full));
    let computed: Vec<String> = summary(&full).into_iter().filter(|r| r.1 > 0).map(|r| r.0).collect();
    // The online views (one XDMF per test point's online solution) come with the rom stage.
    assert_eq!(computed, ["views", "rom", "model", "report"], "{}", text(&full));
}

/// A scene that parses and is within every bound but cannot fit in memory (an
/// ironing slab of 100 000 x 20 elements: 200 002 contact dofs, a Delassus operator of ~300
/// GiB) is refused before anything is written, exit 2, naming the file, the field that drives
/// the estimate, the estimate and the `--max-memory` fix; so is a small scene under a
/// `--max-memory` below its estimate, while the same scene runs under a generous one. An
/// absurd size, `nx = 1000000000`, is out of the scene file's bounds (exit 2 too).
#[test]
fn scene_too_big_for_memory_exits_2_and_writes_nothing() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let ironing = std::fs::read_to_string(repo().join("data/scenes/ironing-coarse.toml")).expect("scene");
    // "both.toml": slab 100 000 x 20 000, whose snapshot sets (n_dof x 639 columns) are a
    // larger term than its factor; the factor alone exceeds any machine, so the message names
    // the mesh, not `parameter.n_train` (it did, found by the stress matrix).
    for (name, nx) in
        [("huge.toml", "nx = 100000"), ("absurd.toml", "nx = 1000000000"), ("both.toml", "nx = 100000\nny = 20000")]
    {
        let scene = tmp.path().join(name);
        let text_of = ironing.replace("nx = 100", nx);
        let text_of = if name == "both.toml" { text_of.replacen("ny = 20\n", "", 1) } else { text_of };
        std::fs::write(&scene, text_of).expect("write scene");
        let out = crom(&store, &["run", scene.to_str().expect("utf8 path")]);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out));
        let msg = text(&out);
        assert!(msg.contains(name) && msg.contains("model.ironing.slab.nx") && msg.contains("fix:"), "{msg}");
        if name != "absurd.toml" {
            assert!(msg.contains("GiB") && msg.contains("--max-memory"), "{msg}");
        }
        assert!(!store.exists(), "nothing written for a refused scene");
    }
    let out = crom(&store, &["--max-memory", "64K", "run", "rope"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        text(&out).contains("model.rope.n_elements") && text(&out).contains("--max-memory setting"),
        "{}",
        text(&out)
    );
    assert!(!store.exists(), "nothing written for a refused scene");
    let out = crom(&store, &["--max-memory", "lots", "run", "rope"]);
    assert_eq!(out.status.code(), Some(2), "a malformed --max-memory is a usage error: {}", text(&out));
    assert!(crom(&store, &["--max-memory", "2G", "run", "rope", "--offline"]).status.success());
}
