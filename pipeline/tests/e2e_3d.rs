//! 3-D scenes through the whole offline study with the real binary: a small `hertz-3d` (6
//! elements a side) from meshing to the report, and bad 3-D scene files refused before anything
//! is written.

mod common;

use common::{crom, repo, text};
use crom_pipeline::scratch::tempdir;

/// An edit of a scene file's text.
type Edit = Box<dyn Fn(String) -> String>;

/// The shipped hertz-3d scene made small: 6 elements a side, 4 training points.
fn small_hertz3d(dir: &std::path::Path, edit: impl Fn(String) -> String) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo().join("data/scenes/hertz-3d.toml")).expect("hertz-3d.toml");
    let small = text
        .replace("name = \"hertz-3d\"", "name = \"hertz-3d-small\"")
        .replace("n = 16\n", "n = 6\n")
        .replace("grading = 3.0", "grading = 1.5")
        .replace("n_train = 12", "n_train = 4")
        .replace("max_m = 11", "max_m = 3")
        .replace("loo_folds = 12", "loo_folds = 4")
        .replace("cells = [2, 3]", "cells = [2]")
        .replace("specificity_samples = 1000", "specificity_samples = 50");
    assert_ne!(small, text);
    let path = dir.join("hertz-3d-small.toml");
    std::fs::write(&path, edit(small)).expect("write scene");
    path
}

/// The offline study runs on a 3-D scene: the mesh holds hexahedra with three coordinates and
/// three dofs per node, every snapshot converged, the metrics and the comparison are stored,
/// the views name hexahedra, the online stages are reported as skipped (and not planned), and a
/// second run finds everything stored.
#[test]
fn a_3d_scene_runs_its_offline_study() {
    let dir = tempdir().expect("tempdir");
    let scene = small_hertz3d(dir.path(), |s| s);
    let store = dir.path().join("store");
    let out = crom(&store, &["run", scene.to_str().expect("utf-8")]);
    assert!(out.status.success(), "{}", text(&out));
    let log = text(&out);
    assert!(log.contains("3-D scene: the online reduced solve"), "{log}");
    let published = store.join("scenes/hertz-3d-small");
    for f in [
        "mesh.h5",
        "train.h5",
        "test.h5",
        "basis.h5",
        "compactness.parquet",
        "generalization.parquet",
        "specificity.parquet",
        "train.xdmf",
    ] {
        assert!(published.join(f).exists(), "{f} missing");
    }
    assert!(!store.join("rom").exists() && !store.join("model").exists(), "no online artifact for a 3-D scene");
    let xdmf = std::fs::read_to_string(published.join("mesh.xdmf")).expect("mesh.xdmf");
    assert!(xdmf.contains("Hexahedron") && xdmf.contains("XYZ"), "{xdmf}");
    let mesh = hdf5::File::open(published.join("mesh.h5")).expect("mesh.h5");
    assert_eq!(mesh.dataset("nodes").expect("nodes").shape(), vec![2 * 7 * 7 * 7, 3]);
    assert_eq!(mesh.dataset("cells").expect("cells").shape()[1], 8);
    assert_eq!(mesh.attr("dofs_per_node").expect("attr").read_scalar::<u64>().expect("u64"), 3);
    let again = crom(&store, &["run", scene.to_str().expect("utf-8")]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(text(&again).contains("0 solved"), "{}", text(&again));
}

/// Bad 3-D scene files exit 2 naming the field, and nothing is written: a symmetry plane missing
/// (the hemispheres free to slide along y), a registered approximation (its maps need a contact
/// curve), a stored model asked for (no online stage in 3-D).
#[test]
fn bad_3d_scenes_are_refused_before_anything_is_written() {
    let dir = tempdir().expect("tempdir");
    let cases: [(&str, Edit); 3] = [
        (
            "model.hertz3d.symmetry",
            Box::new(|s: String| {
                s.replace("{ axis = \"x\", at = 0.0 }, { axis = \"y\", at = 0.0 }", "{ axis = \"x\", at = 0.0 }")
            }),
        ),
        (
            "comparison.approximations[6]",
            Box::new(|s: String| {
                s.replace(
                    "  { kind = \"dictionary\" },",
                    "  { kind = \"dictionary\" },\n  { kind = \"registered\", map = \"moments\", basis = \"pod\" },",
                )
            }),
        ),
        ("study.model_ranks", Box::new(|s: String| s.replace("seed = 20235", "seed = 20235\nmodel_ranks = [4, 2]"))),
    ];
    for (field, edit) in cases {
        let scene = small_hertz3d(dir.path(), edit);
        let store = dir.path().join("never");
        let out = crom(&store, &["run", scene.to_str().expect("utf-8")]);
        assert_eq!(out.status.code(), Some(2), "{field}: {}", text(&out));
        assert!(text(&out).contains(field) && text(&out).contains("fix:"), "{field}: {}", text(&out));
        assert!(!store.exists(), "{field}: the store was created");
    }
}
