//! Helpers shared by the end-to-end tests: running the real `crom` binary and comparing stores.
#![allow(dead_code)] // each test file uses its own subset

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crom_pipeline::io::table::{read_parquet, Table};
use crom_schemas::artifact::{timing_files, MANIFEST};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `crom --store STORE ARGS…` from the repository root, without the caller's CROM_* settings.
pub fn crom_cmd(store: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_crom"));
    c.current_dir(repo())
        .arg("--store")
        .arg(store)
        .args(args)
        .env_remove("CROM_STORE")
        .env_remove("CROM_SCENES")
        .env_remove("CROM_BLOCK_COLUMNS")
        .env_remove("RAYON_NUM_THREADS");
    c
}

/// Run `crom` to completion.
pub fn crom(store: &Path, args: &[&str]) -> Output {
    crom_cmd(store, args).output().expect("crom runs")
}

/// Standard output and error of a finished command.
pub fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// `crom query SCENE --points … --check` at the points `lines` (CSV rows under `header`), written
/// in `dir`; the answers, after asserting success.
pub fn query_checked(store: &Path, scene: &str, header: &str, lines: &[String], dir: &Path) -> Table {
    let csv: Vec<&str> = std::iter::once(header).chain(lines.iter().map(String::as_str)).collect();
    let points = dir.join("points.csv");
    std::fs::write(&points, csv.join("\n")).expect("points");
    let out = dir.join("answers.parquet");
    let o = crom(
        store,
        &["query", scene, "--points", points.to_str().expect("utf8"), "--check", "--out", out.to_str().expect("utf8")],
    );
    assert!(o.status.success(), "{}", text(&o));
    read_parquet(&out).expect("answers")
}

/// Spawn `cmd` and kill it (SIGKILL) as soon as `ready()` holds (waiting at most `patience`),
/// asserting that it was still running then: the kill lands mid-run, never after the end.
pub fn kill_when(mut cmd: Command, what: &str, patience: Duration, ready: impl Fn() -> bool) {
    let mut child = cmd.stdout(Stdio::null()).stderr(Stdio::null()).spawn().expect("spawn crom");
    let start = Instant::now();
    while !ready() && start.elapsed() < patience {
        assert!(child.try_wait().expect("poll").is_none(), "{what}: the run ended before it could be killed");
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(ready(), "{what}: the moment never came");
    assert!(child.try_wait().expect("poll").is_none(), "{what}: the run ended before it could be killed");
    child.kill().expect("kill");
    let _ = child.wait();
}

/// Artifacts (directories) of one stage.
pub fn artifacts(store: &Path, stage: &str) -> usize {
    std::fs::read_dir(store.join(stage)).map_or(0, |d| d.flatten().count())
}

/// Snapshot blocks written to the column store (block files, not their temporary files).
pub fn blocks(store: &Path) -> usize {
    let Ok(fams) = std::fs::read_dir(store.join("columns")) else { return 0 };
    fams.flatten()
        .filter_map(|f| std::fs::read_dir(f.path().join("blocks")).ok())
        .map(|rd| rd.flatten().filter(|e| !e.file_name().to_string_lossy().starts_with(".tmp")).count())
        .sum()
}

/// A scene file in `dir`: the shipped scene `scene` with `edits` applied (each must apply).
pub fn variant(dir: &Path, scene: &str, file: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(repo().join(format!("data/scenes/{scene}.toml"))).expect("scene");
    for (from, to) in edits {
        assert!(text.contains(from), "{scene}.toml no longer contains `{from}`: update this test");
        text = text.replace(from, to);
    }
    let path = dir.join(file);
    std::fs::write(&path, text).expect("write scene");
    path
}

/// Every result file of a store: relative path -> bytes. Left out: the files that carry
/// wall-clock times (`timing_files`) and the store's metadata (manifests, the columns' index,
/// the catalog, the published names, run records, staging, quarantine).
pub fn result_files(store: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut visit = vec![store.to_path_buf()];
    while let Some(dir) = visit.pop() {
        for e in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            let path = e.path();
            let rel = path.strip_prefix(store).expect("inside").to_string_lossy().into_owned();
            let top = rel.split('/').next().unwrap_or_default().to_string();
            if e.file_type().expect("type").is_dir() {
                if !["scenes", "runs", ".staging", ".quarantine"].contains(&top.as_str()) {
                    visit.push(path);
                }
                continue;
            }
            let name = e.file_name().to_string_lossy().into_owned();
            let metadata = name == MANIFEST
                || name == ".lock"
                || rel == "catalog.parquet"
                || (top == "columns" && (name == "index.parquet" || rel.contains("/index/")));
            let timing = timing_files().any(|(stage, file)| top == stage && name == file);
            if !metadata && !timing {
                out.insert(rel, std::fs::read(&path).expect("read"));
            }
        }
    }
    out
}

/// Assert two stores hold the same result files, byte for byte.
pub fn assert_same_results(a: &Path, b: &Path, what: &str) {
    let (fa, fb) = (result_files(a), result_files(b));
    let (ka, kb): (Vec<&String>, Vec<&String>) = (fa.keys().collect(), fb.keys().collect());
    assert_eq!(ka, kb, "{what}: the same artifacts, under the same keys");
    let differ: Vec<&String> = fa.iter().filter(|(k, v)| fb.get(*k) != Some(v)).map(|(k, _)| k).collect();
    assert!(differ.is_empty(), "{what}: result files differ: {differ:?}");
}
