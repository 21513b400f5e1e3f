//! What the exact corrected re-pairing step buys on ironing-fine
//! (docs/design-notes.md#an-exact-corrected-step): the online solve with the registered
//! neighbours basis (m = 2) and the product's warm starts at the 127 test midpoints, on two
//! primal spaces — the POD of the 128 training responses (the plain one) and the POD of those
//! responses with their translates by ±8 slab columns (`primal_translates = 8`, truncated at
//! 112 and at 128, the product's rank) — with the first-order corrected step (`exact_step = 0`)
//! and with 1 to 3 GMRES iterations.
//!
//! Per row: converged, the median dual error, the mean linearisations, the median online time
//! and the speed-up over the full-order solve's median (one thread, fastest of 3). The online
//! times are the fastest of `REPS` (default 20) rounds, the rows solved in turn at each point of
//! each round, so that a change of the machine's speed meets every row alike.
//!
//! `cargo run --release -p crom-stages --example exact_step`

use crom_stages::basis::{pod_by_gram, pod_full};
use crom_stages::contact::ContactSolveParams;
use crom_stages::dual::registration::{Interpolation, MapKind, Registered};
use crom_stages::dual::{Inner, Training};
use crom_stages::rom::translates::with_translates;
use crom_stages::rom::{ContactOperator, ReducedModel, RomOutcome, RomParams, RomWork};
use crom_stages::shipped::shipped_contact_model;
use faer::MatRef;
use rayon::prelude::*;

/// The `q`-quantile (nearest rank) of `v`.
fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let tol = ContactSolveParams { rel_tol: 1e-10, max_iter: 500 };
    let fm = shipped_contact_model("ironing-fine").factor().expect("factor");
    let (n, nc) = (fm.n_dof(), fm.n_contact());
    let train: Vec<f64> = (0..128).map(|k| 3.0 * k as f64 / 127.0).collect();
    let test: Vec<f64> = (0..127).map(|k| 3.0 * (k as f64 + 0.5) / 127.0).collect();
    let snaps: Vec<_> = train.par_iter().map(|&d| fm.solve(&[d], &tol).expect("training solve")).collect();
    let truth: Vec<_> = test.par_iter().map(|&d| fm.solve(&[d], &tol).expect("test solve")).collect();
    let responses: Vec<f64> = train
        .iter()
        .zip(&snaps)
        .flat_map(|(&d, s)| s.u.iter().zip(fm.lift(&[d])).map(|(a, b)| a - b).collect::<Vec<_>>())
        .collect();
    let fom: Vec<f64> = test
        .iter()
        .map(|&d| {
            (0..3)
                .map(|_| {
                    let t = std::time::Instant::now();
                    let _ = fm.solve(&[d], &tol);
                    t.elapsed().as_secs_f64()
                })
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let fom_med = quantile(fom, 0.5);
    println!("full-order median {:.3} ms (one thread, fastest of 3)", 1e3 * fom_med);
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
    let nb = Registered::build(&training, kind, Inner::Neighbours).expect("registered neighbours");
    let model_of = |phi: &[f64], r: usize, exact_step: usize| {
        let m = ReducedModel::new(&fm, phi, r, &[], 0).expect("K̂ SPD");
        m.with_primal_starts(&nb, 2, &params, &RomParams { exact_step, ..RomParams::default() })
    };
    let plain = pod_full(MatRef::from_column_major_slice(&responses, n, train.len())).expect("pod");
    let plain_phi: Vec<f64> =
        (0..plain.modes.ncols()).flat_map(|j| plain.modes.col(j).iter().copied().collect::<Vec<_>>()).collect();
    let all = with_translates(mesh, fm.model().slave_nodes(), &responses, 8).expect("a grid");
    let (modes, _) = pod_by_gram(MatRef::from_column_major_slice(&all, n, 3 * train.len()), 128).expect("gram");
    let phi: Vec<f64> = (0..modes.ncols()).flat_map(|j| modes.col(j).iter().copied().collect::<Vec<_>>()).collect();
    let mut rows: Vec<(String, ReducedModel, usize)> = vec![
        ("training responses".into(), model_of(&plain_phi, plain.modes.ncols(), 0), 0),
        ("training responses".into(), model_of(&plain_phi, plain.modes.ncols(), 2), 2),
    ];
    for r in [112, 128] {
        for k in [0, 1, 2, 3] {
            rows.push((format!("… and their translates by ±8 (r_u = {r})"), model_of(&phi[..n * r], r, k), k));
        }
    }
    let reps: usize = std::env::var("REPS").ok().and_then(|v| v.parse().ok()).unwrap_or(20);
    let w8 = fm.weights();
    let mut best = vec![vec![f64::INFINITY; test.len()]; rows.len()];
    let mut out = vec![vec![(false, 0.0, 0usize); test.len()]; rows.len()];
    let mut work: Vec<(ReducedModel, RomWork)> = rows.iter().map(|r| (r.1.clone(), RomWork::default())).collect();
    for round in 0..reps {
        for (j, (&d, full)) in test.iter().zip(&truth).enumerate() {
            for (c, (rom, w)) in work.iter_mut().enumerate() {
                let p = RomParams { exact_step: rows[c].2, ..RomParams::default() };
                let t = std::time::Instant::now();
                rom.set_dual_of(&nb, &[d], 2);
                let sol = rom.solve(&[d], &p, w);
                best[c][j] = best[c][j].min(t.elapsed().as_secs_f64());
                if round == 0 {
                    let (pf, q) = (&full.pressure, rom.pressure(&sol.lambda_hat));
                    let num: f64 = q.iter().zip(pf).zip(w8).map(|((a, b), w)| w * (a - b) * (a - b)).sum();
                    let den: f64 = pf.iter().zip(w8).map(|(b, w)| w * b * b).sum();
                    out[c][j] = (sol.outcome == RomOutcome::Converged, (num / den).sqrt(), sol.linearizations);
                }
            }
        }
    }
    println!(
        "| primal space | GMRES iterations | converged | median dual error | linearisations | median time | speed-up |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (c, (what, _, k)) in rows.iter().enumerate() {
        let conv = out[c].iter().filter(|o| o.0).count();
        let err = quantile(out[c].iter().filter(|o| o.0).map(|o| o.1).collect(), 0.5);
        let lin = out[c].iter().map(|o| o.2 as f64).sum::<f64>() / test.len() as f64;
        let t = quantile(best[c].clone(), 0.5);
        println!(
            "| {what} | {} | {conv}/{} | {:.4} % | {lin:.2} | {:.4} ms | {:.0}x |",
            if *k == 0 { "– (first-order)".to_string() } else { k.to_string() },
            test.len(),
            100.0 * err,
            1e3 * t,
            fom_med / t
        );
    }
}
