//! The comparison of dual approximations (issue 15) end to end on the shipped hertz scene: the
//! artifact's tables have the documented columns and one row set per approximation, nothing
//! non-finite except the documented nulls, a cached rerun recomputes nothing, and the Hertz
//! contact registered by its half-width is nearly one-dimensional (Hertz theory: the pressure is
//! `p0 sqrt(1 - x^2 / b^2)`, one profile dilated by b), so three registered POD modes beat three
//! plain POD modes by more than an order of magnitude.

mod common;

use common::{crom, text};
use crom_pipeline::io::table::read_parquet;
use crom_schemas::artifact::comparison as names;

#[test]
fn hertz_comparison_tables_and_the_registered_advantage() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("store");
    let o = crom(&store, &["run", "data/scenes/hertz.toml", "--offline"]);
    assert!(o.status.success(), "{}", text(&o));
    let arts: Vec<_> = std::fs::read_dir(store.join("comparison")).expect("comparison artifacts").flatten().collect();
    assert_eq!(arts.len(), 1);
    let art = arts[0].path();
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
    let line = out.lines().find(|l| l.trim_start().starts_with("comparison ")).expect("comparison line");
    assert!(line.split_whitespace().nth(1) == Some("0"), "a cached run recomputed: {line}");
}

/// The online solve with every non-negative approximation on hertz: one row per (approximation,
/// m), outcomes that add up, no row for signed modes, and the registered cone basis converging
/// at every test point with a smaller dual error than the plain CPG basis of the same size (the
/// dilation argument above, now through the reduced solve).
#[test]
fn hertz_online_comparison() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("store");
    let o = crom(&store, &["run", "data/scenes/hertz.toml"]);
    assert!(o.status.success(), "{}", text(&o));
    let arts: Vec<_> = std::fs::read_dir(store.join("online-comparison")).expect("artifacts").flatten().collect();
    assert_eq!(arts.len(), 1);
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
