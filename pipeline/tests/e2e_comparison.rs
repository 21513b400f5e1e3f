//! The comparison of dual approximations end to end on the shipped hertz scene: the
//! artifact's tables have the documented columns and one row set per approximation, nothing
//! non-finite except the documented nulls, a cached rerun recomputes nothing, and the Hertz
//! contact registered by its half-width is nearly one-dimensional (Hertz theory: the pressure is
//! `p0 sqrt(1 - x^2 / b^2)`, one profile dilated by b), so three registered POD modes beat three
//! plain POD modes by more than an order of magnitude. Each approximation is its own cached
//! stage: changing one approximation's settings recomputes it and the side-by-side artifact,
//! nothing else, and a parameter-independent basis is stored for the online stage.

mod common;

use common::{crom, text};
use crom_pipeline::io::table::read_parquet;
use crom_schemas::artifact::comparison as names;

#[test]
fn hertz_comparison_tables_and_the_registered_advantage() {
    let dir = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = dir.path().join("store");
    let o = crom(&store, &["run", "data/scenes/hertz.toml", "--offline"]);
    assert!(o.status.success(), "{}", text(&o));
    let arts: Vec<_> = std::fs::read_dir(store.join("comparison")).expect("comparison artifacts").flatten().collect();
    assert_eq!(arts.len(), 1);
    let art = arts[0].path();
    // One artifact per approximation (local gives one per cell count): 9.
    assert_eq!(artifacts(&store, "approximation").len(), 9);
    let curves = read_parquet(&art.join(names::CURVES)).expect("curves");
    let (Some(a), Some(metric), Some(m), Some(mean), Some(count)) = (
        curves.strs("approximation"),
        curves.strs("metric"),
        curves.u64s("m"),
        curves.f64s("mean"),
        curves.u64s("count"),
    ) else {
        panic!("comparison.parquet lacks a documented column");
    };
    let expected = [
        "pod",
        "cpg",
        "angle-greedy",
        "nnmf",
        "local-2",
        "local-3",
        "dictionary",
        "registered-moments-pod",
        "registered-moments-cpg",
    ];
    for name in expected {
        for which in ["compactness", "generalization", "test", "specificity"] {
            let rows = (0..a.len()).filter(|&i| a[i] == name && metric[i] == which).count();
            // hertz: 12 training points, comparison.max_m = 11, every m up to 11 on the grid;
            // the dictionary has no modes, so no specificity.
            let want = if name == "dictionary" && which == "specificity" { 0 } else { 11 };
            assert_eq!(rows, want, "{name} {which}");
        }
    }
    assert!(mean.iter().all(|v| v.is_finite()), "a mean is null");
    assert!((0..a.len()).all(|i| metric[i] != "test" || count[i] == 11), "11 test snapshots, all with contact");
    // hertz has no nested levels: the H(n) table exists and is empty.
    let nested = read_parquet(&art.join(names::NESTED)).expect("nested table");
    assert_eq!(nested.rows(), 0);
    let at = |name: &str, mm: u64| {
        (0..a.len()).find(|&i| a[i] == name && metric[i] == "test" && m[i] == mm).map(|i| mean[i]).expect("row")
    };
    let (pod, reg) = (at("pod", 3), at("registered-moments-pod", 3));
    assert!(reg * 10.0 < pod, "registered {reg} vs plain POD {pod} at m = 3");
    // Local bases per cell: only local approximations, and their cells split the 11 test points.
    let cells = read_parquet(&art.join(names::CELLS)).expect("cells table");
    let (Some(ca), Some(cm), Some(cmm), Some(cc)) =
        (cells.strs("approximation"), cells.strs("metric"), cells.u64s("m"), cells.u64s("count"))
    else {
        panic!("comparison_cells.parquet lacks a documented column");
    };
    assert!(ca.iter().all(|n| n.starts_with("local-")), "per-cell rows of a global approximation");
    for name in ["local-2", "local-3"] {
        let points: u64 =
            (0..ca.len()).filter(|&i| ca[i] == name && cm[i] == "test" && cmm[i] == 1).map(|i| cc[i]).sum();
        assert_eq!(points, 11, "{name}: the cells' test points");
    }
    for file in [names::REACHED, names::FACTS, names::TIMINGS] {
        let t = read_parquet(&art.join(file)).expect("table");
        assert!(t.rows() > 0, "{file} is empty");
        assert!(t.strs("approximation").is_some(), "{file} has no approximation column");
    }
    let again = crom(&store, &["run", "data/scenes/hertz.toml", "--offline"]);
    assert!(again.status.success(), "{}", text(&again));
    let out = text(&again);
    for stage in ["approximation", "comparison"] {
        assert_eq!(
            counts(&out, stage),
            (0, if stage == "comparison" { 1 } else { 9 }),
            "a cached run recomputed:\n{out}"
        );
    }
}

/// The artifact directories of one kind in a store.
fn artifacts(store: &std::path::Path, kind: &str) -> Vec<std::path::PathBuf> {
    std::fs::read_dir(store.join(kind)).map(|d| d.flatten().map(|e| e.path()).collect()).unwrap_or_default()
}

/// (computed, cached) of a stage's line in the run summary (`<stage> <computed> <cached> ..`).
fn counts(out: &str, stage: &str) -> (u64, u64) {
    let line = out
        .lines()
        .find(|l| l.split_whitespace().next() == Some(stage))
        .unwrap_or_else(|| panic!("no `{stage}` line in:\n{out}"));
    let mut w = line.split_whitespace().skip(1).map(|x| x.parse::<u64>().unwrap_or(u64::MAX));
    (w.next().unwrap_or(u64::MAX), w.next().unwrap_or(u64::MAX))
}

/// Changing NNMF's iteration count in the scene file recomputes the NNMF approximation and the
/// side-by-side table, and nothing else of the comparison; the parameter-independent bases
/// (CPG, Angle-Greedy, NNMF) are stored with one dataset per online size, `n_contact` rows and
/// non-negative entries, and the others (POD: signed; local and registered: parameter-dependent;
/// the dictionary: its atoms are the training set) store none.
#[test]
fn one_changed_approximation_recomputes_only_itself() {
    let dir = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = dir.path().join("store");
    let first = crom(&store, &["run", "data/scenes/hertz.toml", "--offline"]);
    assert!(first.status.success(), "{}", text(&first));
    let with_bases: Vec<_> =
        artifacts(&store, "approximation").into_iter().filter(|d| d.join(names::BASES).exists()).collect();
    assert_eq!(with_bases.len(), 3, "cpg, angle-greedy and nnmf store their bases");
    for d in &with_bases {
        let f = hdf5::File::open(d.join(names::BASES)).expect("bases.h5");
        for m in [1usize, 2, 3, 5, 8, 10] {
            let ds = f.dataset(&format!("m{m}")).expect("one dataset per online size up to max_m = 11");
            let shape = ds.shape();
            assert!(shape.len() == 2 && shape.contains(&m), "m{m}: shape {shape:?}");
            let v = ds.read_raw::<f64>().expect("read");
            assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "m{m}: a negative or non-finite generator");
        }
        assert!(f.dataset("m16").is_err(), "m = 16 exceeds max_m = 11");
    }
    let text_of = std::fs::read_to_string(common::repo().join("data/scenes/hertz.toml")).expect("hertz.toml");
    let changed = text_of.replace("{ kind = \"nnmf\", iterations = 300 }", "{ kind = \"nnmf\", iterations = 299 }");
    assert_ne!(changed, text_of, "the shipped hertz scene lists nnmf with 300 iterations");
    let scene = dir.path().join("hertz.toml");
    std::fs::write(&scene, changed).expect("write scene");
    let second = crom(&store, &["run", scene.to_str().expect("utf-8 path"), "--offline"]);
    assert!(second.status.success(), "{}", text(&second));
    let out = text(&second);
    assert_eq!(counts(&out, "approximation"), (1, 8), "{out}");
    assert_eq!(counts(&out, "comparison"), (1, 0), "{out}");
    assert_eq!(counts(&out, "generalization"), (0, 1), "{out}");
}

/// The online solve with every non-negative approximation on hertz: one row per (approximation,
/// m), outcomes that add up, no row for signed modes, and the registered cone basis converging
/// at every test point with a smaller dual error than the plain CPG basis of the same size (the
/// dilation argument above, now through the reduced solve).
#[test]
fn hertz_online_comparison() {
    let dir = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = dir.path().join("store");
    let o = crom(&store, &["run", "data/scenes/hertz.toml"]);
    assert!(o.status.success(), "{}", text(&o));
    let arts: Vec<_> = std::fs::read_dir(store.join("online-comparison")).expect("artifacts").flatten().collect();
    assert_eq!(arts.len(), 1);
    // One online artifact per approximation with a non-negative basis: all but the two POD.
    assert_eq!(artifacts(&store, "online-approximation").len(), 7);
    let t = read_parquet(&arts[0].path().join(names::ONLINE)).expect("online table");
    let (Some(a), Some(m), Some(points), Some(conv), Some(inf), Some(failed), Some(err)) = (
        t.strs("approximation"),
        t.u64s("m"),
        t.u64s("points"),
        t.u64s("converged"),
        t.u64s("infeasible"),
        t.u64s("failed"),
        t.f64s("median_dual_error"),
    ) else {
        panic!("online_comparison.parquet lacks a documented column");
    };
    assert!(!a.iter().any(|n| n == "pod" || n == "registered-moments-pod"), "signed modes were solved online");
    for i in 0..a.len() {
        assert_eq!(points[i], 11, "{} m {}", a[i], m[i]);
        assert_eq!(conv[i] + inf[i] + failed[i], points[i], "{} m {}", a[i], m[i]);
    }
    let row = |name: &str, mm: u64| (0..a.len()).find(|&i| a[i] == name && m[i] == mm).expect("row");
    let (reg, cpg) = (row("registered-moments-cpg", 3), row("cpg", 3));
    assert_eq!(conv[reg], 11, "registered CPG, m = 3: every test point converges");
    assert!(err[reg] * 10.0 < err[cpg], "registered {} vs plain CPG {} at m = 3", err[reg], err[cpg]);
    let times = read_parquet(&arts[0].path().join(names::ONLINE_TIMINGS)).expect("timings");
    assert_eq!(times.rows(), t.rows());
    assert!(times.f64s("median_online_ms").is_some_and(|v| v.iter().all(|x| *x > 0.0)));
}
