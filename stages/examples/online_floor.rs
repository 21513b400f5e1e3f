//! Where the online dual error of ironing-fine comes from: the online reduced solve (exact
//! algorithm, the POD of the 128 training contact responses as primal basis, as the online
//! stage builds it) at the 127 test midpoints with two kinds of dual basis:
//!
//! * an *oracle*, the test point's own full-order pressure, normalised, as the one dual vector:
//!   the projection error is 0, so the dual error left is what the primal space and the
//!   solve add;
//! * the registered (whole-node translation) POD of the training pressures at m = 5, 8, 10,
//!   entered as `±modes` (2m non-negative coefficients, so λ of either sign, and the reduced
//!   gaps' averages on the modes held at 0): a signed registered basis online without a sign
//!   condition on the pressure;
//! * the registered CPG at m = 5, 10, alone and with the oracle added to it (whether the solve
//!   finds the exact member when the basis holds it);
//! * the registered neighbours basis at m = 2 (the two training pressures nearest in the
//!   sub-node shift), and, as the one dual vector, the two training pressures nearest in `d_x`
//!   interpolated linearly in the reference frame (whole-node and linear maps);
//! * for the registered CPG at m = 10, the pressure read instead from the reaction `K u` of the
//!   reduced displacement at each slave node (over its tributary length).
//!
//! A second table keeps the neighbours basis (m = 2) and changes the primal space instead: the
//! POD of the training responses (the product's), the same with the test point's own response
//! added (an oracle: what the dual basis gives once the primal space holds the answer), and
//! the POD, truncated at r_u, of the training responses together with their finite-difference
//! sensitivities `(u(d_x + δ) - u(d_x)) h / δ` (δ = 1e-4, h the training spacing: 128 more
//! full-order solves), and the POD, truncated at r_u, of the training responses together with
//! their translates along the slab by ±8 slab node spacings (no further full-order solve), the
//! exact interface (the responses to unit forces on every contact dof: the reduced problem with
//! the full-order primal side), and the POD, truncated at r_u, of the training responses
//! together with the responses to the product query's contact force at the points a quarter of
//! a training spacing from each training point (one back-substitution each, no contact solve;
//! no test point is used). Per row: converged, the median dual error, the mean linearisations
//! and the median online time (fastest of 20 runs, one thread). A third table gives the
//! product's primal space and the last one (r_u = 160) with the product's warm starts (the
//! answers at the training points, interpolated to the query) at the re-pairing's stopping
//! tolerance `u_tol` = 1e-10 (the default) and 1e-6.
//!
//! `cargo run --release -p crom-stages --example online_floor`
//!
//! Prints, per basis, the converged count and the median and 95th percentile of the relative
//! dual error (tributary-weighted, as every online table) and the median relative primal error
//! (Euclidean, of the reconstructed displacement). What the numbers show:
//! docs/design-notes.md#the-registered-approximation-online-the-error-the-multiplier-adds and
//! the note after it.

use crom_stages::basis::pod_full;
use crom_stages::contact::{ContactSolveParams, FactoredModel};
use crom_stages::dual::registration::{Interpolation, Map, MapKind, Registered};
use crom_stages::dual::{Inner, Training};
use crom_stages::rom::{ContactOperator, Linearized, ReducedModel, RomOutcome, RomParams, RomWork};
use crom_stages::shipped::shipped_contact_model;
use faer::MatRef;
use rayon::prelude::*;

/// ironing-fine's model, from its shipped scene file.
fn ironing_fine() -> FactoredModel {
    shipped_contact_model("ironing-fine").factor().expect("factor")
}

/// The `q`-quantile (nearest rank) of the finite values of `v`.
fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let tol = ContactSolveParams { rel_tol: 1e-10, max_iter: 500 };
    let fm = ironing_fine();
    let (n, nc) = (fm.n_dof(), fm.n_contact());
    let train: Vec<f64> = (0..128).map(|k| 3.0 * k as f64 / 127.0).collect();
    let test: Vec<f64> = (0..127).map(|k| 3.0 * (k as f64 + 0.5) / 127.0).collect();
    let snaps: Vec<_> = train.par_iter().map(|&d| fm.solve(&[d], &tol).expect("training solve")).collect();
    let responses: Vec<f64> = train
        .iter()
        .zip(&snaps)
        .flat_map(|(&d, s)| s.u.iter().zip(fm.lift(&[d])).map(|(a, b)| a - b).collect::<Vec<_>>())
        .collect();
    let phi = pod_full(MatRef::from_column_major_slice(&responses, n, train.len())).expect("pod");
    let ru = phi.modes.ncols();
    let phi_c: Vec<f64> = (0..ru).flat_map(|j| phi.modes.col(j).iter().copied().collect::<Vec<_>>()).collect();
    let base = ReducedModel::new(&fm, &phi_c, ru, &[], 0).expect("K̂ SPD");
    let truth: Vec<_> = test.par_iter().map(|&d| fm.solve(&[d], &tol).expect("test solve")).collect();
    let w8 = fm.weights();
    // The registered (whole-node translation) POD of the training pressures, for the signed
    // variant below.
    let mesh = fm.model().mesh();
    let x: Vec<f64> = fm.contact_nodes()[..nc].iter().map(|&i| mesh.nodes[i][0]).collect();
    let train_p: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
    let params: Vec<Vec<f64>> = train.iter().map(|&d| vec![d]).collect();
    let ms: Vec<usize> = (1..=10).collect();
    let training = Training {
        snapshots: MatRef::from_column_major_slice(&train_p, nc, train.len()),
        params: &params,
        surface: &x,
        across: &[],
        ms: &ms,
    };
    let kind = MapKind::Translate { interpolation: Interpolation::Nodes };
    let reg = Registered::build(&training, kind, Inner::Pod).expect("registered POD");
    // One dual basis per test point: `basis(j, d)` is column-major, with its column count.
    let run = |basis: &(dyn Fn(usize, f64) -> (Vec<f64>, usize) + Sync)| -> Vec<(bool, f64, f64)> {
        test.par_iter()
            .zip(&truth)
            .enumerate()
            .map(|(j, (&d, full))| {
                let p = &full.pressure;
                let (theta, k) = basis(j, d);
                let mut rom = base.clone();
                rom.set_dual(&theta, k);
                let mut w = RomWork::default();
                let sol = rom.solve(&[d], &RomParams::default(), &mut w);
                let q = rom.pressure(&sol.lambda_hat);
                let num: f64 = q.iter().zip(p).zip(w8).map(|((a, b), w)| w * (a - b) * (a - b)).sum();
                let den: f64 = p.iter().zip(w8).map(|(b, w)| w * b * b).sum();
                // u = lift + Φ û
                let mut u = fm.lift(&[d]);
                for (c, &y) in sol.u_hat.iter().enumerate() {
                    u.iter_mut().zip(phi.modes.col(c).iter()).for_each(|(a, b)| *a += y * b);
                }
                let du: f64 = u.iter().zip(&full.u).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
                let un: f64 = full.u.iter().map(|v| v * v).sum::<f64>().sqrt();
                (sol.outcome == RomOutcome::Converged, (num / den).sqrt(), du / un)
            })
            .collect()
    };
    println!("| dual basis | converged | median dual error | p95 dual error | median primal error |");
    println!("|---|---|---|---|---|");
    let print = |what: &str, rows: Vec<(bool, f64, f64)>| {
        let conv: Vec<_> = rows.iter().filter(|r| r.0).collect();
        let dual: Vec<f64> = conv.iter().map(|r| r.1).collect();
        let primal: Vec<f64> = conv.iter().map(|r| r.2).collect();
        println!(
            "| {what} | {}/{} | {:.4} % | {:.4} % | {:.4} % |",
            conv.len(),
            rows.len(),
            100.0 * quantile(dual.clone(), 0.5),
            100.0 * quantile(dual, 0.95),
            100.0 * quantile(primal, 0.5)
        );
    };
    let oracle = |j: usize, _d: f64| {
        let p = &truth[j].pressure;
        let norm = p.iter().map(|v| v * v).sum::<f64>().sqrt();
        (p.iter().map(|v| v / norm).collect::<Vec<f64>>(), 1)
    };
    print(&format!("the test pressure itself (m = 1; r_u = {ru}, n_contact = {nc})"), run(&oracle));
    // The registered CPG alone, and with the oracle added: whether the solve picks the exact
    // member when the basis holds it.
    let cpg = Registered::build(&training, kind, Inner::Cpg).expect("registered CPG");
    let cone = |j: usize, d: f64, m: usize, with_oracle: bool| {
        let b = cpg.modes_at(&[d], nc);
        let (mut theta, mut k) = if with_oracle { oracle(j, d) } else { (Vec::new(), 0) };
        for c in (0..b.ncols()).filter(|&c| b.col(c).iter().any(|&v| v != 0.0)).take(m) {
            theta.extend(b.col(c).iter().copied());
            k += 1;
        }
        (theta, k)
    };
    // The registered neighbours basis (the product's `basis = "neighbours"`) at m = 2.
    let nb = Registered::build(&training, kind, Inner::Neighbours).expect("registered neighbours");
    let two = |_j: usize, d: f64| crom_stages::rom::cone_basis_columns(&nb, &[d], 2);
    print("registered neighbours, 2 generators", run(&two));
    // The two training pressures nearest in d_x, interpolated linearly in the reference frame and
    // pushed to the point, as the one dual vector.
    for map_kind in [kind, MapKind::Translate { interpolation: Interpolation::Linear { refine: 4 } }] {
        let map = Map::fit(&training, map_kind).expect("map");
        let pulled: Vec<Vec<f64>> = train
            .iter()
            .zip(&snaps)
            .map(|(&d, sn)| {
                let mut r = vec![0.0; map.len()];
                map.pull(&sn.pressure, &[d], &mut r);
                r
            })
            .collect();
        let between = |_j: usize, d: f64| {
            let k = train.partition_point(|&t| t <= d).clamp(1, train.len() - 1) - 1;
            let th = (d - train[k]) / (train[k + 1] - train[k]);
            let r: Vec<f64> = pulled[k].iter().zip(&pulled[k + 1]).map(|(a, b)| (1.0 - th) * a + th * b).collect();
            let mut q = vec![0.0; nc];
            map.push(&r, &[d], &mut q);
            let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            (q.iter().map(|v| v / norm).collect::<Vec<f64>>(), 1)
        };
        print(&format!("the nearest two in d_x interpolated ({}), one vector", map_kind.name()), run(&between));
    }
    // The pressure from the reaction of the reduced displacement (registered CPG, m = 10).
    let cn = fm.contact_nodes();
    let reaction: Vec<(bool, f64, f64)> = test
        .par_iter()
        .zip(&truth)
        .map(|(&d, full)| {
            let (theta, k) = cone(0, d, 10, false);
            let mut rom = base.clone();
            rom.set_dual(&theta, k);
            let sol = rom.solve(&[d], &RomParams::default(), &mut RomWork::default());
            let mut u = fm.lift(&[d]);
            for (c, &y) in sol.u_hat.iter().enumerate() {
                u.iter_mut().zip(phi.modes.col(c).iter()).for_each(|(a, b)| *a += y * b);
            }
            let mut ku = vec![0.0; n];
            fm.stiffness_mul(&u, &mut ku);
            let p = &full.pressure;
            let q: Vec<f64> = (0..nc).map(|s| ku[2 * cn[s]].hypot(ku[2 * cn[s] + 1]) / w8[s]).collect();
            let num: f64 = q.iter().zip(p).zip(w8).map(|((a, b), w)| w * (a - b) * (a - b)).sum();
            let den: f64 = p.iter().zip(w8).map(|(b, w)| w * b * b).sum();
            (sol.outcome == RomOutcome::Converged, (num / den).sqrt(), f64::NAN)
        })
        .collect();
    print("registered CPG, 10 generators, pressure from the reaction K u", reaction);
    for m in [5usize, 10] {
        print(&format!("registered CPG, {m} generators"), run(&|j, d| cone(j, d, m, false)));
        print(&format!("the oracle and registered CPG, {m} generators"), run(&|j, d| cone(j, d, m, true)));
    }
    // A signed basis entered as ±modes: λ of either sign, the reduced gaps' averages on the
    // modes held at 0 (bilateral), the pressure's sign not imposed.
    for m in [5usize, 8, 10] {
        let signed = |_j: usize, d: f64| {
            let b = reg.modes_at(&[d], nc);
            let k = b.ncols().min(m);
            let mut theta = Vec::with_capacity(2 * k * nc);
            for sign in [1.0, -1.0] {
                for c in 0..k {
                    theta.extend(b.col(c).iter().map(|v| sign * v));
                }
            }
            (theta, 2 * k)
        };
        print(&format!("registered POD, ±{m} modes (bilateral, sign not imposed)"), run(&signed));
    }
    primal_space(&fm, (&train, &responses), (&phi_c, &base), (&test, &truth), &nb);
}

/// The second table: the neighbours basis at m = 2 with other primal spaces; `phi_c` and
/// `base` are the product's (the POD of the training responses, as `main` built them).
fn primal_space(
    fm: &FactoredModel,
    (train, responses): (&[f64], &[f64]),
    (phi_c, base): (&[f64], &ReducedModel),
    (test, truth): (&[f64], &[crom_stages::snapshot::Snapshot]),
    nb: &Registered,
) {
    let tol = ContactSolveParams { rel_tol: 1e-10, max_iter: 500 };
    let (n, w8) = (fm.n_dof(), fm.weights());
    let model_of = |cols: &[f64], count: usize, r: usize| {
        let pod = pod_full(MatRef::from_column_major_slice(cols, n, count)).expect("pod");
        let r = r.min(pod.modes.ncols());
        let c: Vec<f64> = (0..r).flat_map(|j| pod.modes.col(j).iter().copied().collect::<Vec<_>>()).collect();
        ReducedModel::new(fm, &c, r, &[], 0).expect("K̂ SPD")
    };
    let row_at = |what: &str, make: &(dyn Fn(usize) -> ReducedModel + Sync), params: &RomParams| {
        let rows: Vec<(bool, f64, usize, f64, usize)> = test
            .iter()
            .zip(truth)
            .enumerate()
            .map(|(j, (&d, full))| {
                let mut rom = make(j);
                let r = rom.ranks().0;
                let (mut w, mut best, mut sol) = (RomWork::default(), f64::INFINITY, None);
                for _ in 0..20 {
                    let t = std::time::Instant::now();
                    rom.set_dual_of(nb, &[d], 2);
                    let s = rom.solve(&[d], params, &mut w);
                    best = best.min(t.elapsed().as_secs_f64());
                    sol = Some(s);
                }
                let sol = sol.expect("solved");
                let (p, q) = (&full.pressure, rom.pressure(&sol.lambda_hat));
                let num: f64 = q.iter().zip(p).zip(w8).map(|((a, b), w)| w * (a - b) * (a - b)).sum();
                let den: f64 = p.iter().zip(w8).map(|(b, w)| w * b * b).sum();
                (sol.outcome == RomOutcome::Converged, (num / den).sqrt(), sol.linearizations, best, r)
            })
            .collect();
        let conv = rows.iter().filter(|r| r.0).count();
        let dual: Vec<f64> = rows.iter().filter(|r| r.0).map(|r| r.1).collect();
        println!(
            "| {what} | {} | {conv}/{} | {:.4} % | {:.2} | {:.4} ms |",
            rows[0].4,
            rows.len(),
            100.0 * quantile(dual, 0.5),
            rows.iter().map(|r| r.2 as f64).sum::<f64>() / rows.len() as f64,
            1e3 * quantile(rows.iter().map(|r| r.3).collect(), 0.5)
        );
    };
    let row = |what: &str, make: &(dyn Fn(usize) -> ReducedModel + Sync)| row_at(what, make, &RomParams::default());
    println!();
    println!(
        "| primal space (neighbours, m = 2) | r_u | converged | median dual error | linearisations | median time |"
    );
    println!("|---|---|---|---|---|---|");
    row("the training responses", &|_| base.clone());
    row("the training responses and the point's own (oracle)", &|j| {
        let mut cols = responses.to_vec();
        cols.extend(truth[j].u.iter().zip(fm.lift(&[test[j]])).map(|(a, b)| a - b));
        model_of(&cols, train.len() + 1, usize::MAX)
    });
    let (delta, h) = (1e-4, train[1] - train[0]);
    let shifted: Vec<_> = train.par_iter().map(|&d| fm.solve(&[d + delta], &tol).expect("shifted solve")).collect();
    let mut both = responses.to_vec();
    for ((&d, s), r) in train.iter().zip(&shifted).zip(responses.chunks_exact(n)) {
        let lift = fm.lift(&[d + delta]);
        both.extend(s.u.iter().zip(&lift).zip(r).map(|((u, l), r0)| (u - l - r0) * h / delta));
    }
    for r in [128, 160, 256] {
        let model = model_of(&both, 2 * train.len(), r);
        row("the training responses and their sensitivities", &|_| model.clone());
    }
    let translated = translates(fm, responses, &[-8, 8]);
    for r in [112, 128] {
        let model = model_of(&translated, 3 * train.len(), r);
        row("the training responses and their translates by ±8 slab nodes", &|_| model.clone());
    }
    // The exact interface: the responses to a unit force on each contact dof (zero for a
    // Dirichlet dof, left out). Every contact response is a combination of them.
    let mut interface = Vec::new();
    for &node in fm.contact_nodes() {
        for c in 0..2 {
            let mut f = vec![0.0; n];
            f[2 * node + c] = 1.0;
            let v = fm.response(&f);
            if v.iter().any(|&x| x != 0.0) {
                interface.extend(v);
            }
        }
    }
    let model = model_of(&interface, interface.len() / n, usize::MAX);
    row("the exact interface: the responses to unit forces on the contact dofs", &|_| model.clone());
    // The responses to the product query's contact force (its pressure through the full-order
    // gap rows at its displacement) at the points a quarter of a training spacing from each
    // training point: no test point, one back-substitution each, no contact solve.
    let quarter: Vec<f64> =
        train.windows(2).flat_map(|t| [0.75 * t[0] + 0.25 * t[1], 0.25 * t[0] + 0.75 * t[1]]).collect();
    let corrections: Vec<f64> = quarter
        .par_iter()
        .flat_map(|&d| {
            let mut rom = base.clone();
            rom.set_dual_of(nb, &[d], 2);
            let sol = rom.solve(&[d], &RomParams::default(), &mut RomWork::default());
            let p = rom.pressure(&sol.lambda_hat);
            let u = ReducedModel::displacement(fm, phi_c, &[d], &sol.u_hat);
            let mut lin = Linearized::default();
            fm.linearize(&[d], &u, &mut lin);
            let mut f = vec![0.0; n];
            lin.add_forces(w8, &p, &mut f);
            fm.response(&f)
        })
        .collect();
    let mut enriched = responses.to_vec();
    enriched.extend_from_slice(&corrections);
    for r in [112, 128, 160] {
        let model = model_of(&enriched, train.len() + quarter.len(), r);
        row("the training responses and the responses to the product query's force at quarter points", &|_| {
            model.clone()
        });
    }
    // The third table: the product's primal space and the last one (r_u = 160), each with the
    // product's warm starts (the answers at the training points, interpolated) and at two
    // stopping tolerances of the re-pairing.
    println!();
    println!("| primal space (neighbours, m = 2, warm starts) | u_tol | r_u | converged | median dual error | linearisations | median time |");
    println!("|---|---|---|---|---|---|---|");
    let points: Vec<Vec<f64>> = train.iter().map(|&d| vec![d]).collect();
    let enriched = model_of(&enriched, train.len() + quarter.len(), 160);
    for (what, model) in [("the training responses", base), ("… and the responses at quarter points", &enriched)] {
        let warm = model.clone().with_primal_starts(nb, 2, &points, &RomParams::default());
        for u_tol in [1e-10, 1e-6] {
            row_at(&format!("{what} | {u_tol:e}"), &|_| warm.clone(), &RomParams { u_tol, ..RomParams::default() });
        }
    }
}

/// `responses` (column-major, `n_dof` rows) followed by each of them translated along the slab
/// by `k` node columns for each `k` of `shifts`: the slab's part moved (zero where nothing moves
/// in), the iron's part as it is. No full-order solve: the slab is a regular grid, so a
/// response translated by whole node spacings is, away from the slab's ends, the response the
/// iron would cause that much further on with the same sub-node offset.
fn translates(fm: &FactoredModel, responses: &[f64], shifts: &[i64]) -> Vec<f64> {
    let mesh = fm.model().mesh();
    let cn = &fm.contact_nodes()[..fm.n_contact()];
    let slab = mesh.node_body[cn[0]];
    let x = |i: usize| mesh.nodes[i][0];
    let (lo, hi) = cn.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| (a.min(x(i)), b.max(x(i))));
    let h = (hi - lo) / (cn.len() - 1) as f64;
    let column = |i: usize| ((x(i) - lo) / h).round() as i64;
    let at: std::collections::HashMap<(i64, u64), usize> = (0..mesh.nodes.len())
        .filter(|&i| mesh.node_body[i] == slab)
        .map(|i| ((column(i), mesh.nodes[i][1].to_bits()), i))
        .collect();
    let n = fm.n_dof();
    let mut out = responses.to_vec();
    for &k in shifts {
        // each slab node and the node its values come from (none: they become zero), once per
        // shift rather than once per response
        let from: Vec<(usize, Option<usize>)> =
            at.iter().map(|(&(c, y), &i)| (i, at.get(&(c - k, y)).copied())).collect();
        for r in responses.chunks_exact(n) {
            let mut t = r.to_vec();
            for &(i, j) in &from {
                for d in 0..2 {
                    t[2 * i + d] = j.map_or(0.0, |j| r[2 * j + d]);
                }
            }
            out.extend(t);
        }
    }
    out
}
