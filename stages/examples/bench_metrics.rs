//! Timings of the cone projection and the validation metrics on a synthetic dual snapshot
//! matrix shaped like ironing-fine's contact pressure: n = 201 slave nodes on x in [0, 5],
//! N = 128 Hertz-like bumps `p0 sqrt(max(0, 1 - ((x - c_k)/a)^2))`, a = 0.2, centres moving
//! from 0.75 + a to 4.25 - a. Also a primal-sized (n = 24 000) smooth field for the POD
//! metrics, where the leave-one-out folds run in reduced QR coordinates.
//!
//! A second table times the fast metric algorithms against the kept reference implementations
//! at N = 128, 256, 512 (n = 101 and 201 rows, ironing-coarse / ironing-fine sized), single
//! threaded, with the scale targets of results.md, and the agreement of the numbers at N = 128.
//!
//! `cargo run --release -p crom-stages --example bench_metrics` prints markdown tables
//! (`-- scaling` prints only the second).

use std::time::{Duration, Instant};

use crom_stages::basis::{cpg, cpg_path, cpg_reference, pod_full, CpgParams, CpgPathParams};
use crom_stages::cone::{nnls, nnls_reference, ConeProjector, NnlsParams};
use crom_stages::metrics::{
    combine_folds, compactness_cone, cone_ranges_reference, generalization_cone, generalization_orth, loo_fold_cone,
    loo_fold_cone_reference, loo_fold_orth, nested_error_cone, nested_error_orth, specificity_cone,
    specificity_cone_path, specificity_orth, LooOrth, MetricCurve, SpecificityParams,
};
use faer::{Mat, MatRef};

const N_NODES: usize = 201;
const HALF_WIDTH: f64 = 0.2;

/// Pressure bumps centred at `centres` on x = linspace(0, 5, 201).
fn bumps(centres: &[f64]) -> Mat<f64> {
    bumps_on(N_NODES, centres)
}

/// Pressure bumps centred at `centres` on x = linspace(0, 5, rows).
fn bumps_on(rows: usize, centres: &[f64]) -> Mat<f64> {
    Mat::from_fn(rows, centres.len(), |i, k| {
        let x = 5.0 * i as f64 / (rows - 1) as f64;
        let d = (x - centres[k]) / HALF_WIDTH;
        (1.0 - d * d).max(0.0).sqrt()
    })
}

/// `count` equidistant centres on [0.75 + a, 4.25 - a].
fn centres(count: usize) -> Vec<f64> {
    let (lo, hi) = (0.75 + HALF_WIDTH, 4.25 - HALF_WIDTH);
    (0..count).map(|k| lo + (hi - lo) * k as f64 / (count - 1) as f64).collect()
}

fn time<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let start = Instant::now();
    let out = f();
    (out, start.elapsed())
}

fn ms(d: Duration) -> String {
    format!("{:.1} ms", d.as_secs_f64() * 1e3)
}

fn column(s: MatRef<'_, f64>, j: usize) -> Vec<f64> {
    s.col(j).iter().copied().collect()
}

fn summary(c: &MetricCurve, ms_: &[usize]) -> String {
    ms_.iter().map(|&m| format!("m={m}: {:.3e}±{:.1e}", c.mean[m - 1], c.std[m - 1])).collect::<Vec<_>>().join(", ")
}

fn main() {
    if std::env::args().any(|a| a == "scaling") {
        scaling();
        return;
    }
    components();
    scaling();
}

fn components() {
    let nnls_params = NnlsParams::default();
    let s = bumps(&centres(128));
    let (n, count) = s.shape();
    println!("Synthetic dual snapshots: n = {n}, N = {count} (ironing-fine-like pressure bumps)\n");
    println!("| step | time | notes |");
    println!("|---|---|---|");

    // Fast vs reference NNLS: every snapshot onto the cone of the first 64.
    let theta = s.subcols(0, 64);
    let (fast, t_fast) = time(|| {
        (0..count).map(|j| nnls(theta, &column(s.as_ref(), j), nnls_params).expect("nnls")).collect::<Vec<_>>()
    });
    let (reference, t_ref) = time(|| {
        (0..count)
            .map(|j| nnls_reference(theta, &column(s.as_ref(), j), nnls_params).expect("reference"))
            .collect::<Vec<_>>()
    });
    let max_diff =
        fast.iter().zip(&reference).map(|(a, b)| (a.residual_norm - b.residual_norm).abs()).fold(0.0, f64::max);
    let max_res = fast.iter().map(|a| a.residual_norm).fold(0.0, f64::max);
    let per = |d: Duration| format!("{:.3} ms/projection", d.as_secs_f64() * 1e3 / count as f64);
    println!("| `nnls` (Gram built per call), 128 projections onto cone of 64 | {} | {} |", ms(t_fast), per(t_fast));
    println!("| `nnls_reference`, same 128 projections | {} | {}; max abs diff of residual norms {max_diff:.2e} (max residual {max_res:.3}) |", ms(t_ref), per(t_ref));
    let (proj, t_proj) = time(|| ConeProjector::new(theta, nnls_params).project_many(s.as_ref()).expect("project"));
    let diff_proj = proj.1.iter().zip(&reference).map(|(a, b)| (a - b.residual_norm).abs()).fold(0.0, f64::max);
    println!(
        "| `ConeProjector::project_many` (one Gram), same 128 | {} | {}; max diff vs reference {diff_proj:.2e} |",
        ms(t_proj),
        per(t_proj)
    );

    // A harder case: the odd snapshots sit between the even ones (partial overlaps, several
    // active generators per projection).
    let even = Mat::from_fn(n, 64, |i, c| s[(i, 2 * c)]);
    let (fast, t_fast) = time(|| {
        (0..count).map(|j| nnls(even.as_ref(), &column(s.as_ref(), j), nnls_params).expect("nnls")).collect::<Vec<_>>()
    });
    let (reference, t_ref) = time(|| {
        (0..count)
            .map(|j| nnls_reference(even.as_ref(), &column(s.as_ref(), j), nnls_params).expect("reference"))
            .collect::<Vec<_>>()
    });
    let max_diff =
        fast.iter().zip(&reference).map(|(a, b)| (a.residual_norm - b.residual_norm).abs()).fold(0.0, f64::max);
    let max_res = fast.iter().map(|a| a.residual_norm).fold(0.0, f64::max);
    println!("| `nnls`, 128 projections onto cone of the 64 even-indexed | {} | {} |", ms(t_fast), per(t_fast));
    println!("| `nnls_reference`, same | {} | {}; max abs diff of residual norms {max_diff:.2e} (max residual {max_res:.3}) |", ms(t_ref), per(t_ref));

    // CPG at tolerance 0 and cone compactness.
    let (basis, t_cpg) = time(|| cpg(s.as_ref(), CpgParams::default()).expect("cpg"));
    println!(
        "| CPG tol 0 on all 128 | {} | {} generators, C(end) = {:.1e} |",
        ms(t_cpg),
        basis.basis.ncols(),
        basis.compactness.last().copied().unwrap_or(f64::NAN)
    );
    let (cc, t_cc) = time(|| compactness_cone(s.as_ref(), basis.basis.as_ref()).expect("compactness"));
    println!("| `compactness_cone` (all m) | {} | C(32) = {:.3e}, C(64) = {:.3e} |", ms(t_cc), cc[32], cc[64]);
    let pod = pod_full(s.as_ref()).expect("pod");
    println!("| POD of the dual snapshots | – | numerical rank {} |", pod.rank);

    // Generalization: all 128 folds sequentially (each fold is independent: parallel in the pipeline).
    let max_m = count - 1;
    let (g_orth, t_go) = time(|| generalization_orth(s.as_ref(), max_m).expect("G orth"));
    println!(
        "| G(m) dual orth, 128 LOO folds, m = 1..127 (QR-reduced folds) | {} | {} |",
        ms(t_go),
        summary(&g_orth, &[1, 16, 64, 127])
    );
    let (_, t_gd) = time(|| (0..count).map(|i| loo_fold_orth(s.as_ref(), i, max_m).expect("fold")).collect::<Vec<_>>());
    println!("| same, folds by definition (`loo_fold_orth`, n x 127 SVDs) | {} | reference path |", ms(t_gd));
    let (g_cone, t_gc) = time(|| generalization_cone(s.as_ref(), max_m, nnls_params).expect("G cone"));
    println!(
        "| G(m) dual cone, 128 LOO folds (shared CPG path), m = 1..127 | {} | {} |",
        ms(t_gc),
        summary(&g_cone, &[1, 16, 64, 127])
    );

    // Specificity, 1000 samples per m, every m.
    let sp = SpecificityParams { samples: 1000, seed: 2023, ..SpecificityParams::default() };
    let (s_orth, t_so) = time(|| specificity_orth(s.as_ref(), pod.modes.as_ref(), sp));
    println!(
        "| S(m) dual orth, 1000 samples, m = 1..{} | {} | {} |",
        pod.modes.ncols(),
        ms(t_so),
        summary(&s_orth, &[1, 16, 64, pod.modes.ncols()])
    );
    let k = basis.basis.ncols();
    let (s_cone, t_sc) = time(|| specificity_cone(s.as_ref(), basis.basis.as_ref(), sp, nnls_params).expect("S cone"));
    println!("| S(m) dual cone, 1000 samples, m = 1..{k} | {} | {} |", ms(t_sc), summary(&s_cone, &[1, 16, 64, k]));

    // Nested error on levels 1..=7 (2^n + 1 centres).
    let levels: Vec<Mat<f64>> = (1..=7).map(|l| bumps(&centres((1 << l) + 1))).collect();
    let (h, t_h) = time(|| {
        levels
            .windows(2)
            .map(|w| {
                let orth = nested_error_orth(w[0].as_ref(), w[1].as_ref()).expect("H orth");
                let cone = nested_error_cone(w[0].as_ref(), w[1].as_ref(), nnls_params).expect("H cone");
                (orth, cone)
            })
            .collect::<Vec<_>>()
    });
    let hs =
        h.iter().enumerate().map(|(l, (o, c))| format!("n={}: {o:.2e}/{c:.2e}", l + 1)).collect::<Vec<_>>().join(", ");
    println!("| H(n) orth/cone, n = 1..6 | {} | {hs} |", ms(t_h));

    // Primal-sized POD metrics: smooth fields, n = 24 000, N = 128.
    let np = 24_000;
    let primal = Mat::from_fn(np, count, |i, k| {
        let x = i as f64 / np as f64;
        let mu = k as f64 / (count - 1) as f64;
        (std::f64::consts::PI * x * (1.0 + 3.0 * mu)).sin() * (1.0 + mu) + (x - mu).powi(2)
    });
    let (ppod, t_ppod) = time(|| pod_full(primal.as_ref()).expect("pod"));
    println!("| primal-sized POD (n = {np}, N = {count}) | {} | numerical rank {} |", ms(t_ppod), ppod.rank);
    let (loo, t_qr) = time(|| LooOrth::new(primal.as_ref()).expect("qr"));
    let (_, t_fold) = time(|| loo.fold(5, max_m).expect("fold"));
    let (_, t_direct) = time(|| loo_fold_orth(primal.as_ref(), 5, max_m).expect("fold"));
    println!(
        "| primal LOO: QR once / one reduced fold / one direct fold | {} / {} / {} | 128 folds ≈ {:.2} s reduced vs {:.1} s direct |",
        ms(t_qr),
        ms(t_fold),
        ms(t_direct),
        (t_qr + t_fold * 128).as_secs_f64(),
        (t_direct * 128).as_secs_f64()
    );
    let (p_orth, t_pso) = time(|| specificity_orth(primal.as_ref(), ppod.modes.as_ref(), sp));
    println!(
        "| S(m) primal orth, 1000 samples, m = 1..{} | {} | {} |",
        ppod.modes.ncols(),
        ms(t_pso),
        summary(&p_orth, &[1, ppod.modes.ncols()])
    );
}

/// Largest relative difference `|a - b| / max(|a|, |b|)` over the entries with
/// `max(|a|, |b|) > floor`, and the largest absolute difference over all.
fn rel_diff(a: &[f64], b: &[f64], floor: f64) -> (f64, f64) {
    assert_eq!(a.len(), b.len(), "rel_diff: lengths differ");
    let mut rel = 0.0f64;
    let mut abs = 0.0f64;
    for (x, y) in a.iter().zip(b) {
        let d = (x - y).abs();
        abs = abs.max(d);
        let scale = x.abs().max(y.abs());
        if scale > floor {
            rel = rel.max(d / scale);
        }
    }
    (rel, abs)
}

fn secs(d: Duration) -> String {
    format!("{:.3} s", d.as_secs_f64())
}

/// Fast vs reference at N = 128, 256, 512 on ironing-like pressures (single thread).
fn scaling() {
    let nnls = NnlsParams::default();
    let agreement = std::cell::RefCell::new(Vec::<String>::new());
    println!("\n## Metric algorithms: fast vs reference (one thread; the pipeline runs folds on all cores)\n");
    println!("Ironing-like pressures: Hertz bumps (half-width 0.2) moving over x in [0, 5]; `est.` = reference");
    println!("timed on a sample of folds and scaled to all N. Max rank = N - 1 for N <= 256, 256 beyond.\n");
    println!("| rows n | N | step | fast | reference | speed-up | target |");
    println!("|---|---|---|---|---|---|---|");
    for rows in [101, 201] {
        for count in [128, 256, 512] {
            let s = bumps_on(rows, &centres(count));
            let max_m = if count <= 256 { count - 1 } else { 256 };
            let target_cone = if count == 512 { "a few s (whole run <= 20 s)" } else { "-" };
            // CPG: the lazy selection + one compactness pass vs the direct greedy.
            let (fast, t_fast) = time(|| cpg(s.as_ref(), CpgParams::default()).expect("cpg"));
            let (slow, t_slow) = time(|| cpg_reference(s.as_ref(), CpgParams::default()).expect("cpg"));
            assert_eq!(fast.selected, slow.selected, "CPG selections differ at N = {count}");
            row(rows, count, &format!("CPG tol 0 ({} generators)", fast.selected.len()), t_fast, t_slow, false, "-");
            // Cone LOO: the shared path (with the metrics' data) and every fold.
            let (curve, t_loo) = time(|| {
                let path =
                    cpg_path(s.as_ref(), CpgPathParams { nnls, max_rank: max_m, ..CpgPathParams::default() }, &|| {})
                        .expect("path");
                let folds = (0..count).map(|i| loo_fold_cone(s.as_ref(), &path, i, max_m).expect("fold"));
                combine_folds(folds.collect::<Vec<_>>(), max_m)
            });
            let sample: Vec<usize> =
                if count <= 128 { (0..count).collect() } else { (0..count).step_by(count / 4).collect() };
            let (ref_folds, t_ref) = time(|| {
                sample
                    .iter()
                    .map(|&i| loo_fold_cone_reference(s.as_ref(), i, max_m, nnls).expect("fold"))
                    .collect::<Vec<_>>()
            });
            let t_ref_all = t_ref.mul_f64(count as f64 / sample.len() as f64);
            row(
                rows,
                count,
                &format!("cone LOO, {count} folds, m <= {max_m}"),
                t_loo,
                t_ref_all,
                sample.len() < count,
                target_cone,
            );
            if count == 128 {
                let slow_curve = combine_folds(&ref_folds, max_m);
                let (rel, abs) = rel_diff(&curve.mean, &slow_curve.mean, 1e-8);
                agreement
                    .borrow_mut()
                    .push(format!("| {rows} | G(m) dual cone mean, m = 1..{max_m} | {rel:.1e} | {abs:.1e} |"));
                let (rel, abs) = rel_diff(&fast.compactness, &slow.compactness, 1e-8);
                agreement.borrow_mut().push(format!(
                    "| {rows} | C(m) dual cone, m = 0..{} | {rel:.1e} | {abs:.1e} |",
                    fast.selected.len()
                ));
            }
            // Orthogonal LOO by column downdate of one SVD vs an SVD of each fold (the reference).
            let loo = LooOrth::new(s.as_ref()).expect("qr");
            let (fast_orth, t_orth) = time(|| {
                let mut ws = loo.workspace();
                (0..count).map(|i| loo.fold_with(i, max_m, &mut ws).expect("fold")).collect::<Vec<_>>()
            });
            let sample: Vec<usize> =
                if count <= 128 { (0..count).collect() } else { (0..count).step_by(count / 16).collect() };
            let (ref_orth, t_ref) =
                time(|| sample.iter().map(|&i| loo.fold_reference(i, max_m).expect("fold")).collect::<Vec<_>>());
            let t_ref_all = t_ref.mul_f64(count as f64 / sample.len() as f64);
            row(rows, count, &format!("orth LOO, {count} folds"), t_orth, t_ref_all, sample.len() < count, "-");
            if count == 128 {
                let (a, b) = (combine_folds(&fast_orth, max_m), combine_folds(&ref_orth, max_m));
                let (rel, abs) = rel_diff(&a.mean, &b.mean, 1e-8);
                agreement
                    .borrow_mut()
                    .push(format!("| {rows} | G(m) dual orth mean, m = 1..{max_m} | {rel:.1e} | {abs:.1e} |"));
                // Specificity from the path's intervals vs its own cone pass.
                let path =
                    cpg_path(s.as_ref(), CpgPathParams { nnls, max_rank: count, ..CpgPathParams::default() }, &|| {})
                        .expect("path");
                let sp = SpecificityParams { samples: 1000, seed: 2023, ..SpecificityParams::default() };
                let a = specificity_cone_path(s.as_ref(), &path, usize::MAX, sp, &|| {});
                let b = specificity_cone(s.as_ref(), path.basis.as_ref(), sp, nnls).expect("S cone");
                let (rel, abs) = rel_diff(&a.mean, &b.mean, 1e-8);
                agreement
                    .borrow_mut()
                    .push(format!("| {rows} | S(m) dual cone mean, m = 1..{} | {rel:.1e} | {abs:.1e} |", a.len()));
                let ranges = cone_ranges_reference(s.as_ref(), path.basis.as_ref(), nnls).expect("ranges");
                let flat = |r: &[Vec<(f64, f64)>]| r.iter().flatten().flat_map(|(l, h)| [*l, *h]).collect::<Vec<_>>();
                let (rel, abs) = rel_diff(&flat(&path.cone_ranges), &flat(&ranges), 0.0);
                agreement
                    .borrow_mut()
                    .push(format!("| {rows} | specificity intervals (all m) | {rel:.1e} | {abs:.1e} |"));
            }
        }
    }
    println!("\nAgreement with the reference implementations at N = 128 (relative over values > 1e-8):\n");
    println!("| rows n | quantity | max relative diff | max absolute diff |");
    println!("|---|---|---|---|");
    for line in agreement.borrow().iter() {
        println!("{line}");
    }
}

fn row(rows: usize, count: usize, step: &str, fast: Duration, slow: Duration, estimated: bool, target: &str) {
    let est = if estimated { " est." } else { "" };
    let speedup = slow.as_secs_f64() / fast.as_secs_f64().max(1e-9);
    println!("| {rows} | {count} | {step} | {} | {}{est} | {speedup:.0}x | {target} |", secs(fast), secs(slow));
}
