//! End-to-end: `crom query` on the stored reduced model of the rope (Type-1) and hertz (Type-2).
//!
//! * Before a run there is no model: exit 2, the fix names `crom run`, and nothing is written.
//! * After `crom run`, the model queried at the scene's test points with `--check` reproduces
//!   what the study measured for the same model (the rope's: `tradeoff.parquet`, the row of the
//!   model's algorithm and ranks; hertz's, a registered CPG basis since it is the most accurate:
//!   `online_comparison.parquet`, the row of its approximation and m — the same number of
//!   converged points and, bit for bit, the median and 95th-percentile dual error and the
//!   median number of non-zero dual coefficients); the rope's: the same number of converged
//!   points and, bit for bit, the median dual error (the same solve, the same pressure, the same full-order solution and the
//!   same error sum — any changed bit of one point's answer near the median shows) and the
//!   indicator's Spearman rank correlation with the primal error. The median primal error is
//!   compared to 1e-9 relative: the online stage evaluates it from precomputed projections, the
//!   query from the reconstructed field (the same quantity, summed in another order; measured
//!   differences are ~1e-13 relative).
//! * A scene that asks for the full ranks (`study.model_ranks`) gets the model whose every test
//!   point the online stage tabled (`rom_errors.parquet`, exact, full CPG basis): point by
//!   point, the query's outcome, steps, indicator terms and dual error have the same bits.
//! * A scene that sets `study.online_u_tol` gets it in the online stages and the stored model: a
//!   plain query answers as `--u-tol` with that value does, bit for bit.
//! * Over a two-component parameter (a small ironing-fine-2d) the stored model carries the
//!   registered CPG on the moments map and answers the test points as the online comparison
//!   measured it.
//! * Bad input — an unknown parameter, a malformed `--at`, a point outside the training domain,
//!   a points file without the parameter's column, a stale model (the scene changed) — exits 2
//!   naming the field and the fix, and leaves the store as it was.

mod common;

use std::path::Path;

use common::{crom, query_checked, text};
use crom_pipeline::io::model::StoredModel;
use crom_pipeline::io::table::{read_parquet, Table};
use crom_stages::metrics::order::{quantile, spearman};

/// Every file of the store with its size (a query must change none).
fn listing(store: &Path) -> Vec<(String, u64)> {
    let mut out = Vec::new();
    let mut visit = vec![store.to_path_buf()];
    while let Some(dir) = visit.pop() {
        for e in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            if e.file_type().expect("type").is_dir() {
                visit.push(e.path());
            } else {
                out.push((e.path().display().to_string(), e.metadata().expect("meta").len()));
            }
        }
    }
    out.sort();
    out
}

/// Write the variant of a shipped scene (`common::variant(dir, base, file, edits)`), run its whole
/// study into `store` (it must succeed) and return the variant's path.
fn run_variant(store: &Path, dir: &Path, base: &str, file: &str, edits: &[(&str, &str)]) -> String {
    let scene = common::variant(dir, base, file, edits);
    let scene = scene.to_str().expect("utf8").to_string();
    let o = crom(store, &["--quiet", "run", &scene]);
    assert!(o.status.success(), "{}", text(&o));
    scene
}

/// The rows of the online stage's table `errors` (`rom_errors.parquet`) at the test points with
/// the exact solve and the full dual basis.
fn exact_full_test_rows(errors: &Table) -> Vec<usize> {
    let (set, alg, basis) =
        (errors.strs("set").expect("set"), errors.strs("algorithm").expect("a"), errors.strs("dual_basis").expect("b"));
    (0..errors.rows()).filter(|&i| set[i] == "test" && alg[i] == "exact" && basis[i] == "full").collect()
}

fn check_against_the_online_stage(store: &Path, scene: &str, param: &str, tmp: &Path) {
    check_against(store, (scene, scene), param, tmp);
}

/// [`check_against_the_online_stage`] of the scene named `scene` given as `scene_arg` (a file).
fn check_against(store: &Path, (scene, scene_arg): (&str, &str), param: &str, tmp: &Path) {
    let published = store.join("scenes").join(scene);
    let errors = read_parquet(&published.join("rom_errors.parquet")).expect("errors");
    let mu = errors.f64s("parameter").expect("parameter");
    let tests: Vec<f64> = exact_full_test_rows(&errors).into_iter().map(|i| mu[i]).collect();
    assert!(tests.len() >= 5, "{scene}: {} test points", tests.len());
    // `{}` prints the shortest decimal that parses back to the same f64
    let lines: Vec<String> = tests.iter().map(|x| format!("{x}")).collect();
    let before = listing(store);
    let q = query_checked(store, scene_arg, param, &lines, tmp);
    assert_eq!(listing(store), before, "{scene}: the query wrote to the store");
    assert_eq!(q.rows(), tests.len());
    assert_eq!(q.f64s(param).expect("param"), tests.as_slice(), "rows in input order");
    let model = StoredModel::read(&published.join("model.h5")).expect("model.h5");
    if !["full", "truncated"].contains(&model.dual_basis.as_str()) {
        return check_registered(&published, &model, &q, scene);
    }
    let (ru, rl) = (q.u64s("r_primal").expect("ru")[0], q.u64s("r_dual").expect("rl")[0]);
    let trade = read_parquet(&published.join("tradeoff.parquet")).expect("tradeoff");
    let row = (0..trade.rows())
        .find(|&i| {
            trade.strs("algorithm").expect("a")[i] == "exact"
                && trade.u64s("r_primal").expect("ru")[i] == ru
                && trade.u64s("r_dual").expect("rl")[i] == rl
        })
        .expect("the model's row of the trade-off");
    let outcome = q.strs("outcome").expect("outcome");
    let conv: Vec<usize> = (0..q.rows()).filter(|&j| outcome[j] == "converged").collect();
    assert_eq!(conv.len() as u64, trade.u64s("converged").expect("c")[row], "{scene}: converged points");
    assert_eq!(conv.len(), q.rows(), "{scene}: the stored model is one that converged everywhere");
    let pick = |c: &str| -> Vec<f64> { conv.iter().map(|&j| q.f64s(c).expect(c)[j]).collect() };
    let (perr, derr, ind) = (pick("primal_error"), pick("dual_error"), pick("indicator"));
    let stored = |c: &str| trade.f64s(c).expect(c)[row];
    let dual_median = quantile(&derr, 0.5);
    assert_eq!(dual_median.to_bits(), stored("median_dual_error").to_bits(), "{scene}: {dual_median:e}");
    let rho = spearman(&ind, &perr);
    assert_eq!(rho.to_bits(), stored("indicator_spearman").to_bits(), "{scene}: spearman {rho}");
    let (pm, pm_stored) = (quantile(&perr, 0.5), stored("median_primal_error"));
    assert!((pm - pm_stored).abs() <= 1e-9 * pm_stored, "{scene}: median primal error {pm:e} vs {pm_stored:e}");
}

/// The query's answers `q` at the test points against the online comparison's row of the
/// stored model's registered approximation and `m`, which it must have converged at every test
/// point to be chosen.
fn check_registered(published: &Path, model: &StoredModel, q: &Table, scene: &str) {
    let online = read_parquet(&published.join("comparison/online_comparison.parquet")).expect("online comparison");
    let m = model.parts.scalar("reg_m");
    assert!(m > 0 && model.parts.scalar("reg_map") > 0, "{scene}: a registered model without its basis");
    let row = (0..online.rows())
        .find(|&i| {
            online.strs("approximation").expect("a")[i] == model.dual_basis && online.u64s("m").expect("m")[i] == m
        })
        .expect("the model's row of the online comparison");
    let outcome = q.strs("outcome").expect("outcome");
    assert!(outcome.iter().all(|o| o == "converged"), "{scene}: {outcome:?}");
    assert_eq!(online.u64s("converged").expect("c")[row], q.rows() as u64, "{scene}: converged everywhere");
    let stored = |c: &str| online.f64s(c).expect(c)[row];
    let col = |c: &str| q.f64s(c).expect(c).to_vec();
    let (perr, derr) = (col("primal_error"), col("dual_error"));
    for (what, got) in [("median_dual_error", quantile(&derr, 0.5)), ("p95_dual_error", quantile(&derr, 0.95))] {
        assert_eq!(got.to_bits(), stored(what).to_bits(), "{scene}: {what} {got:e} vs {:e}", stored(what));
    }
    let nonzero: Vec<f64> = q.u64s("nonzero_dual").expect("nz").iter().map(|&v| v as f64).collect();
    assert_eq!(quantile(&nonzero, 0.5).to_bits(), stored("median_nonzero_dual").to_bits(), "{scene}: non-zero dual");
    let (pm, pm_stored) = (quantile(&perr, 0.5), stored("median_primal_error"));
    assert!((pm - pm_stored).abs() <= 1e-9 * pm_stored, "{scene}: median primal error {pm:e} vs {pm_stored:e}");
    let dual = model.measured.median_dual_error;
    assert_eq!(dual.to_bits(), stored("median_dual_error").to_bits(), "{scene}: the measured_* attributes");
    assert!(q.u64s("r_dual").expect("rl").iter().all(|&k| k >= 1 && k <= m), "{scene}: generators per point");
}

#[test]
fn query_answers_as_the_online_stage_measured_and_refuses_bad_input() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    // no model yet: a usage error, the fix, nothing created
    let o = crom(&store, &["query", "rope", "--at", "gamma=0.1"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("run `crom run rope` first"), "{}", text(&o));
    assert!(!store.exists(), "a query created the store");
    for scene in ["rope", "hertz"] {
        let o = crom(&store, &["--quiet", "run", scene]);
        assert!(o.status.success(), "{}", text(&o));
    }
    check_against_the_online_stage(&store, "rope", "gamma", tmp.path());
    // one point, printed: a header and one row
    let o = crom(&store, &["query", "hertz", "--at", "d=0.1"]);
    assert!(o.status.success(), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(stdout.lines().count(), 2, "{stdout}");
    assert!(stdout.starts_with("d,extrapolated,outcome,"), "{stdout}");
    // bad input
    let before = listing(&store);
    let bad_file = tmp.path().join("bad.csv");
    std::fs::write(&bad_file, "gamma_x\n0.1\n").expect("write");
    let stale = common::variant(tmp.path(), "rope", "rope-stale.toml", &[("n_train = 10", "n_train = 12")]);
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["query", "rope", "--at", "gam=0.1"], "no parameter `gam`"),
        (vec!["query", "rope", "--at", "gamma"], "not NAME=VALUE"),
        (vec!["query", "rope", "--at", "gamma=inf"], "not a finite number"),
        (vec!["query", "rope", "--at", "gamma=7"], "outside the training domain"),
        (vec!["query", "rope", "--points", bad_file.to_str().expect("utf8")], "no column `gamma`"),
        (vec!["query", "rope"], "--at NAME=VALUE"),
        (vec!["query", stale.to_str().expect("utf8"), "--at", "gamma=0.1"], "crom run"),
    ];
    for (args, says) in cases {
        let o = crom(&store, &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let t = text(&o);
        assert!(t.contains(says) && t.contains("fix:"), "{args:?}: {t}");
    }
    // extrapolation when asked for: answered, and flagged
    let o = crom(&store, &["query", "rope", "--at", "gamma=0.6", "--allow-extrapolation"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).lines().nth(1).is_some_and(|l| l.starts_with("0.6,true,")));
    assert_eq!(listing(&store), before, "a query wrote to the store");
    check_against_the_online_stage(&store, "hertz", "d", tmp.path());
    a_looser_re_pairing_tolerance_answers_sooner(&store, tmp.path());
    damaged_parts_are_caught_where_they_are_read(&store);
}

/// `--u-tol` trades the re-pairing's precision for time: on hertz's stored model at 20 points
/// spread over the training range (d = 0.03 .. 0.2865), `--u-tol 1e-4` converges everywhere in fewer linearisations in all than the
/// model's own 1e-10 (measured on 40 points: 212 against 262), and each answer stays within
/// `10 u_tol` of the default one, relative, in `|û|` and in the contact force. The solve stops
/// once its estimate of the distance to the fixed point is at most `u_tol |y|`, and both
/// quantities move with `y` at a rate of order one (measured: at most 1.1e-6 and 2.3e-6). With
/// the option ignored the counts are equal and the test fails. Bad values exit 2 naming the
/// option, with the store unchanged.
fn a_looser_re_pairing_tolerance_answers_sooner(store: &Path, tmp: &Path) {
    let points = tmp.join("u_tol_points.csv");
    let lines: Vec<String> = (0..20).map(|k| format!("{}", 0.03 + 0.0135 * k as f64)).collect();
    std::fs::write(&points, format!("d\n{}\n", lines.join("\n"))).expect("points");
    let answer = |extra: &[&str]| -> Table {
        let out = tmp.join(format!("u_tol_{}.parquet", extra.len()));
        let mut args = vec!["query", "hertz", "--points", points.to_str().expect("utf8"), "--out"];
        args.push(out.to_str().expect("utf8"));
        args.extend_from_slice(extra);
        let o = crom(store, &args);
        assert!(o.status.success(), "{args:?}: {}", text(&o));
        read_parquet(&out).expect("answers")
    };
    let (tight, loose) = (answer(&[]), answer(&["--u-tol", "1e-4"]));
    for q in [&tight, &loose] {
        assert!(q.strs("outcome").expect("outcome").iter().all(|o| o == "converged"), "every point converged");
    }
    let lin = |q: &Table| q.u64s("linearizations").expect("linearizations").iter().sum::<u64>();
    assert!(lin(&loose) < lin(&tight), "linearisations: {} with --u-tol 1e-4, {} without", lin(&loose), lin(&tight));
    for c in ["u_hat_norm", "contact_force"] {
        for (a, b) in loose.f64s(c).expect(c).iter().zip(tight.f64s(c).expect(c)) {
            assert!((a - b).abs() <= 1e-3 * b.abs(), "{c}: {a} with --u-tol 1e-4 against {b}");
        }
    }
    let before = listing(store);
    for bad in ["0", "-1e-6", "1", "NaN", "inf"] {
        let o = crom(store, &["query", "hertz", "--at", "d=0.1", &format!("--u-tol={bad}")]);
        assert_eq!(o.status.code(), Some(2), "--u-tol {bad}: {}", text(&o));
        assert!(text(&o).contains("--u-tol") && text(&o).contains("fix:"), "--u-tol {bad}: {}", text(&o));
    }
    assert_eq!(listing(store), before, "a refused query wrote to the store");
}

/// A query verifies what it reads: `model.h5` in full, `reconstruction.h5` by its size until a
/// `--check` reads it. A flipped byte of `reconstruction.h5` (same size) leaves a one-point
/// query answering and stops `--check` with exit 1 naming the file; a truncated one stops both;
/// a flipped byte of `model.h5` stops the one-point query.
fn damaged_parts_are_caught_where_they_are_read(store: &Path) {
    let model_dir = std::fs::read_dir(store.join("model"))
        .expect("model dir")
        .flatten()
        .map(|e| e.path())
        .find(|d| {
            let m: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(d.join("manifest.json")).expect("manifest"))
                    .expect("json");
            m["scene"] == "rope"
        })
        .expect("the rope's model");
    let flip = |path: &Path| {
        let mut bytes = std::fs::read(path).expect("read");
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0x01;
        std::fs::write(path, bytes).expect("write");
    };
    let one = ["query", "rope", "--at", "gamma=0.1"];
    let checked = ["query", "rope", "--at", "gamma=0.1", "--check"];
    let rec = model_dir.join("reconstruction.h5");
    let pristine = std::fs::read(&rec).expect("read");
    flip(&rec);
    let o = crom(store, &one);
    assert!(o.status.success(), "the one-point query does not read reconstruction.h5: {}", text(&o));
    let o = crom(store, &checked);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("failed verification") && text(&o).contains("reconstruction.h5"), "{}", text(&o));
    std::fs::write(&rec, &pristine[..pristine.len() / 2]).expect("truncate");
    let o = crom(store, &one);
    assert_eq!(o.status.code(), Some(1), "a truncated part is caught by its size: {}", text(&o));
    assert!(text(&o).contains("reconstruction.h5") && text(&o).contains("size"), "{}", text(&o));
    std::fs::write(&rec, &pristine).expect("restore");
    assert!(crom(store, &checked).status.success(), "restored");
    flip(&model_dir.join("model.h5"));
    let o = crom(store, &one);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("failed verification") && text(&o).contains("model.h5"), "{}", text(&o));
}

/// `study.online_u_tol` sets the exact solve's re-pairing tolerance of the whole study: on a
/// hertz whose scene sets 1e-4, the online stage, the comparison's online stages and the stored
/// model record 1e-4 (every such artifact's manifest, and the model file); a plain query
/// answers as `--u-tol 1e-4` does, bit for bit (answers, steps and linearisations at 20 points),
/// and `--u-tol 1e-10` (the solver's own default) takes more linearisations in all (measured:
/// 136 against 111). With the setting ignored in any of the three stages, that stage's
/// manifests read 1e-10 and the test fails (checked by reverting the online stage's).
#[test]
fn a_scene_sets_the_online_tolerance_of_its_study_and_model() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = &run_variant(
        &store,
        tmp.path(),
        "hertz",
        "hertz-loose.toml",
        &[("seed = 20232", "seed = 20232\nonline_u_tol = 1e-4")],
    );
    let mut stages = std::collections::BTreeMap::new();
    for stage in ["rom", "model", "online-approximation"] {
        for dir in std::fs::read_dir(store.join(stage)).expect(stage).flatten() {
            let m: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(dir.path().join("manifest.json")).expect("manifest"))
                    .expect("json");
            assert_eq!(m["parameters"]["u_tol"].as_f64(), Some(1e-4), "{stage} {}", dir.path().display());
            *stages.entry(stage).or_insert(0) += 1;
        }
    }
    assert_eq!(stages.len(), 3, "every online stage ran: {stages:?}");
    let model = StoredModel::read(&store.join("scenes/hertz/model.h5")).expect("model");
    assert_eq!(model.u_tol.to_bits(), 1e-4f64.to_bits(), "the stored model's u_tol");
    let points = tmp.path().join("points.csv");
    let lines: Vec<String> = (0..20).map(|k| format!("{}", 0.03 + 0.0135 * k as f64)).collect();
    std::fs::write(&points, format!("d\n{}\n", lines.join("\n"))).expect("points");
    let answer = |extra: &[&str]| -> Table {
        let out = tmp.path().join(format!("q{}.parquet", extra.concat()));
        let mut args = vec!["query", scene, "--points", points.to_str().expect("utf8"), "--out"];
        args.push(out.to_str().expect("utf8"));
        args.extend_from_slice(extra);
        let o = crom(&store, &args);
        assert!(o.status.success(), "{args:?}: {}", text(&o));
        read_parquet(&out).expect("answers")
    };
    let (plain, same, tight) = (answer(&[]), answer(&["--u-tol", "1e-4"]), answer(&["--u-tol", "1e-10"]));
    for c in ["u_hat_norm", "lambda_hat_norm", "contact_force"] {
        let bits = |q: &Table| q.f64s(c).expect(c).iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&plain), bits(&same), "{c}: the plain query is the stored tolerance's");
    }
    for c in ["iterations", "linearizations"] {
        assert_eq!(plain.u64s(c).expect(c), same.u64s(c).expect(c), "{c}");
    }
    let lin = |q: &Table| q.u64s("linearizations").expect("linearizations").iter().sum::<u64>();
    assert!(lin(&plain) < lin(&tight), "linearisations: {} stored, {} at 1e-10", lin(&plain), lin(&tight));
}

#[test]
fn a_model_at_the_full_ranks_answers_every_test_point_as_the_online_stage() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = &run_variant(
        &store,
        tmp.path(),
        "rope",
        "rope-full-model.toml",
        &[("seed = 20231", "seed = 20231\nmodel_ranks = [1000, 1000]")],
    );
    let errors = read_parquet(&store.join("scenes/rope/rom_errors.parquet")).expect("errors");
    let rows = exact_full_test_rows(&errors);
    let mu = errors.f64s("parameter").expect("parameter");
    let lines: Vec<String> = rows.iter().map(|&i| format!("{}", mu[i])).collect();
    let q = query_checked(&store, scene, "gamma", &lines, tmp.path());
    let ranks = (errors.u64s("r_primal").expect("ru")[rows[0]], errors.u64s("r_dual").expect("rl")[rows[0]]);
    assert_eq!(
        (q.u64s("r_primal").expect("ru")[0], q.u64s("r_dual").expect("rl")[0]),
        ranks,
        "clipped to the full ranks"
    );
    for (j, &i) in rows.iter().enumerate() {
        assert_eq!(q.strs("outcome").expect("o")[j], errors.strs("outcome").expect("o")[i], "point {j}");
        for c in ["iterations", "linearizations", "nonzero_dual"] {
            assert_eq!(q.u64s(c).expect(c)[j], errors.u64s(c).expect(c)[i], "{c} at point {j}");
        }
        for c in ["indicator", "penetration", "complementarity", "unpaired_force", "dual_error"] {
            let (a, b) = (q.f64s(c).expect(c)[j], errors.f64s(c).expect(c)[i]);
            assert_eq!(a.to_bits(), b.to_bits(), "{c} at point {j}: {a:e} vs {b:e}");
        }
    }
}

/// `study.model_dual`: `cpg` keeps the study's CPG basis on hertz (where the registered basis
/// would win), a registered approximation with `study.model_ranks = [12, 3]` stores it with 3
/// generators per point, each answering the test points as measured; a name that is not a
/// registered CPG approximation of the scene is refused before anything runs (exit 2, the
/// field, the names it could be, nothing written).
#[test]
fn a_scene_chooses_the_dual_approximation_of_its_model() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let seed = "seed = 20232";
    let bad = common::variant(
        tmp.path(),
        "hertz",
        "hertz-bad.toml",
        &[(seed, "seed = 20232\nmodel_dual = \"registered-translate-nodes-cpg\"")],
    );
    let o = crom(&store, &["run", bad.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("study.model_dual") && t.contains("registered-moments-cpg") && t.contains("fix:"), "{t}");
    assert!(!store.exists(), "a refused scene created the store");
    let cpg =
        &run_variant(&store, tmp.path(), "hertz", "hertz-cpg.toml", &[(seed, "seed = 20232\nmodel_dual = \"cpg\"")]);
    let model = StoredModel::read(&store.join("scenes/hertz/model.h5")).expect("model");
    assert!(["full", "truncated"].contains(&model.dual_basis.as_str()), "{}", model.dual_basis);
    assert_eq!(model.parts.scalar("reg_map"), 0);
    check_against(&store, ("hertz", cpg), "d", tmp.path());
    let pinned = &run_variant(
        &store,
        tmp.path(),
        "hertz",
        "hertz-reg3.toml",
        &[(seed, "seed = 20232\nmodel_dual = \"registered-moments-cpg\"\nmodel_ranks = [12, 3]")],
    );
    let model = StoredModel::read(&store.join("scenes/hertz/model.h5")).expect("model");
    assert_eq!((model.dual_basis.as_str(), model.parts.scalar("reg_m")), ("registered-moments-cpg", 3));
    check_against(&store, ("hertz", pinned), "d", tmp.path());
}

/// A stored model over a two-component parameter carries the registered CPG on the moments map
/// (a small ironing-fine-2d: 9 x 3 training points, the map interpolated over the grid level by
/// level): the model stage stores it (`reg_dims` = 2, the table one row per training point with
/// contact; a damaged component count refused), and `crom query --check` at the scene's test
/// points, given by both components, answers as the online comparison measured its row (bit for
/// bit: the median and 95th percentile dual error, the median number of non-zero dual
/// coefficients). A points file without the second component is refused (exit 2, naming it) and
/// writes nothing. Then the registered neighbours over both components, pinned as the model's
/// dual basis, are stored with their second components (`reg_second`, a short one refused) and
/// answer as measured in the same way.
#[test]
fn a_moments_map_over_two_components_is_stored_and_answers_as_measured() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = &run_variant(
        &store,
        tmp.path(),
        "ironing-fine-2d",
        "ironing-2d-small.toml",
        &[
            ("name = \"ironing-fine-2d\"", "name = \"ironing-2d-small\""),
            ("nx = 200\nny = 40", "nx = 50\nny = 10"),
            ("nx = 60\nny = 60", "nx = 15\nny = 15"),
            ("train_level = 7", "train_level = 3"),
            ("train_level = 5", "train_level = 1"),
            ("max_m = 32", "max_m = 4"),
            ("loo_folds = 32", "loo_folds = 4"),
            (
                "  { kind = \"pod\" },\n  { kind = \"registered\", map = \"translate\", interpolation = \"nodes\", basis = \"pod\" },\n",
                "",
            ),
        ],
    );
    let published = store.join("scenes/ironing-2d-small");
    let model = StoredModel::read(&published.join("model.h5")).expect("model.h5");
    assert_eq!(model.dual_basis, "registered-moments-cpg");
    assert_eq!(model.parts.scalar("reg_dims"), 2);
    let table = model.parts.float("reg_table");
    assert!(!table.is_empty() && table.len().is_multiple_of(4) && table.len() / 4 <= 27, "{} values", table.len());
    // the parts make a model; a damaged component count is refused, never a wrong map
    assert!(crom_stages::rom::ReducedModel::from_parts(&model.parts).is_ok());
    for dims in [3, 70] {
        let mut bad = model.parts.clone();
        bad.scalars.iter_mut().filter(|(n, _)| *n == "reg_dims").for_each(|(_, v)| *v = dims);
        assert!(crom_stages::rom::ReducedModel::from_parts(&bad).is_err(), "reg_dims = {dims} accepted");
    }
    let errors = read_parquet(&published.join("rom_errors.parquet")).expect("errors");
    let (dx, dy) = (errors.f64s("d_x").expect("d_x"), errors.f64s("d_y").expect("d_y"));
    let rows = exact_full_test_rows(&errors);
    assert!(rows.len() >= 8, "{} test points", rows.len());
    let lines: Vec<String> = rows.iter().map(|&i| format!("{},{}", dx[i], dy[i])).collect();
    let before = listing(&store);
    let q = query_checked(&store, scene, "d_x,d_y", &lines, tmp.path());
    assert_eq!(listing(&store), before, "the query wrote to the store");
    assert_eq!(q.rows(), rows.len());
    check_registered(&published, &model, &q, "ironing-2d-small");
    let one = tmp.path().join("one.csv");
    std::fs::write(&one, "d_x\n0.5\n").expect("points");
    let o = crom(&store, &["query", scene, "--points", one.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("d_y") && text(&o).contains("fix:"), "{}", text(&o));
    assert_eq!(listing(&store), before, "a refused query wrote to the store");
    // The same study with the registered neighbours over both components pinned as the model's
    // dual basis (only the model stage and the report run again): the model keeps each
    // generator's second component and their scale, a short one is refused, and the query
    // answers as the online comparison measured that row.
    let text_of = std::fs::read_to_string(scene).expect("scene");
    let pinned = tmp.path().join("ironing-2d-small-neighbours.toml");
    std::fs::write(
        &pinned,
        text_of.replace("seed = 20234", "seed = 20234\nmodel_dual = \"registered-translate-nodes-neighbours\""),
    )
    .expect("pinned scene");
    let pinned = pinned.to_str().expect("utf8");
    let o = crom(&store, &["--quiet", "run", pinned]);
    assert!(o.status.success(), "{}", text(&o));
    let model = StoredModel::read(&published.join("model.h5")).expect("model.h5");
    assert_eq!(model.dual_basis, "registered-translate-nodes-neighbours");
    let generators = usize::try_from(model.parts.scalar("reg_generators")).expect("count");
    assert_eq!(model.parts.float("reg_second").len(), generators, "a second component per generator");
    assert_eq!(model.parts.float("reg_second_scale").len(), 1);
    assert!(crom_stages::rom::ReducedModel::from_parts(&model.parts).is_ok());
    let mut short = model.parts.clone();
    short.floats.iter_mut().filter(|(n, _)| *n == "reg_second").for_each(|(_, v)| {
        v.pop();
    });
    assert!(crom_stages::rom::ReducedModel::from_parts(&short).is_err(), "a short reg_second accepted");
    let q = query_checked(&store, pinned, "d_x,d_y", &lines, tmp.path());
    check_registered(&published, &model, &q, "ironing-2d-small");
}
