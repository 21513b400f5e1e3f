//! The sampled surface (`study.contact_sampling`, docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints) end to end on hertz: the
//! online stage adds one `exact-sampled` trade-off row per asked rank pair, every test point
//! converges, and a quadrature fitted to zero residual is the full surface — its row's errors
//! equal the exact solve's at the same ranks (the fit's unique solution is the tributary
//! weights; the unit test `sampled_surface_is_exact_at_zero_tolerance_and_trades_accuracy_above`
//! shows the answers agree to 1e-8 relative, so the medians of the errors, ~1e-2, agree to
//! 1e-6 relative). The figure draws the rows.

mod common;

use common::{crom, repo, text};
use crom_pipeline::io::table::read_parquet;
use crom_schemas::artifact::rom as names;

#[test]
fn sampled_rows_on_hertz() {
    let dir = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = dir.path().join("store");
    let shipped = std::fs::read_to_string(repo().join("data/scenes/hertz.toml")).expect("hertz.toml");
    // the comparison of dual approximations is another test's
    let cut = shipped.find("[comparison]").unwrap_or(shipped.len());
    let scene =
        shipped[..cut].replace("[study]\n", "[study]\ncontact_sampling = { tol = 0.0, ranks = [[12, 12], [6, 7]] }\n");
    assert!(scene.contains("contact_sampling"), "hertz.toml has no [study] section: update this test");
    let path = dir.path().join("hertz.toml");
    std::fs::write(&path, scene).expect("write scene");
    let o = crom(&store, &["run", path.to_str().expect("utf8 path")]);
    assert!(o.status.success(), "{}", text(&o));
    let rom = std::fs::read_dir(store.join("rom")).expect("rom artifacts").flatten().next().expect("one").path();
    let t = read_parquet(&rom.join(names::TRADEOFF)).expect("tradeoff");
    let (Some(alg), Some(basis), Some(ru), Some(rl), Some(points), Some(conv), Some(err)) = (
        t.strs("algorithm"),
        t.strs("dual_basis"),
        t.u64s("r_primal"),
        t.u64s("r_dual"),
        t.u64s("points"),
        t.u64s("converged"),
        t.f64s("median_primal_error"),
    ) else {
        panic!("tradeoff.parquet lacks a documented column");
    };
    let row = |a: &str, b: &str, pair: (u64, u64)| {
        (0..alg.len()).find(|&i| alg[i] == a && basis[i] == b && (ru[i], rl[i]) == pair)
    };
    let sampled: Vec<usize> = (0..alg.len()).filter(|&i| alg[i] == names::SAMPLED).collect();
    assert_eq!(sampled.len(), 2, "one sampled row per asked rank pair");
    for &i in &sampled {
        assert_eq!(conv[i], points[i], "sampled ({}, {}): every test point converges", ru[i], rl[i]);
    }
    let (s, e) = (
        row(names::SAMPLED, "full", (12, 12)).expect("sampled (12, 12)"),
        row("exact", "full", (12, 12)).expect("exact (12, 12)"),
    );
    assert!((err[s] - err[e]).abs() <= 1e-6 * err[e], "tol 0: sampled {} vs exact {}", err[s], err[e]);
    assert!(row(names::SAMPLED, "full", (6, 7)).is_some());
    let report = std::fs::read_dir(store.join("report")).expect("report").flatten().next().expect("one").path();
    let svg = std::fs::read_to_string(report.join("fig_tradeoff.svg")).expect("figure");
    assert!(svg.contains("sampled surface"), "the trade-off figure draws the sampled rows");
}
