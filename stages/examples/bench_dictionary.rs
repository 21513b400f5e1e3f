//! Benchmark of the dictionary-sparse dual approximation online: the online reduced
//! solve on ironing-fine with every training snapshot of a dictionary as a dual basis vector,
//! for the 128-snapshot training set and the 4 097-snapshot nested level 12
//! (`d_x = 3 k / 4096`), at the 127 test midpoints of the 128-point set.
//!
//! `cargo run --release -p crom-stages --example bench_dictionary [atoms] [repetitions]`
//!
//! Solves the snapshots (in parallel), takes the POD of the 128 training points' contact
//! responses as the primal basis (as the online stage does) and builds the reduced model once.
//! Each dictionary is solved two ways: with every atom as a dual basis vector
//! (`ReducedModel::set_dual` once, the exact online solve per query), and by the working set
//! the online-comparison stage uses (`WorkingSet`: the `WS_START` atoms nearest to the query,
//! then the violated ones; the whole loop timed). Each query is single-threaded, the fastest of
//! `repetitions` (default 3). Prints a markdown table: method, atoms, median online time, its
//! ratio to the same method with the 128-atom dictionary (target <= 2x for the working set),
//! median active atoms, converged points and the median relative dual error (tributary-
//! weighted) of converged points; then the working set's first size swept (8 to 64), each
//! ratio also against the fastest 128-atom start.

use crom_stages::basis::pod_full;
use crom_stages::contact::{ContactSolveParams, FactoredModel};
use crom_stages::dual::dictionary::Dictionary;
use crom_stages::dual::DualApprox;
use crom_stages::rom::working_set::{WorkingSet, WorkingSetScratch, WS_START};
use crom_stages::rom::{ContactOperator, ReducedModel, RomOutcome, RomParams, RomWork};
use crom_stages::shipped::shipped_contact_model;
use faer::MatRef;
use rayon::prelude::*;
use std::time::Instant;

/// ironing-fine's model, from its shipped scene file.
fn ironing_fine() -> FactoredModel {
    shipped_contact_model("ironing-fine").factor().expect("factor")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let big: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(4097).max(2);
    let reps: usize = std::env::args().nth(2).and_then(|a| a.parse().ok()).unwrap_or(3).max(1);
    let tol = ContactSolveParams { rel_tol: 1e-10, max_iter: 500 };
    let fm = ironing_fine();
    let (n, nc) = (fm.n_dof(), fm.n_contact());
    let grid = |count: usize| -> Vec<f64> { (0..count).map(|k| 3.0 * k as f64 / (count - 1) as f64).collect() };
    let train = grid(128);
    let test: Vec<f64> = (0..127).map(|k| 3.0 * (k as f64 + 0.5) / 127.0).collect();
    let t = Instant::now();
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
    let truth: Vec<Vec<f64>> = test.par_iter().map(|&d| fm.solve(&[d], &tol).expect("test solve").pressure).collect();
    let pressures = |points: &[f64]| -> Vec<f64> {
        points.par_iter().flat_map_iter(|&d| fm.solve(&[d], &tol).expect("dictionary solve").pressure).collect()
    };
    let small = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect::<Vec<f64>>();
    let large = pressures(&grid(big));
    eprintln!("snapshots solved in {:.1} s", t.elapsed().as_secs_f64());
    let w8 = fm.weights().to_vec();
    let points_of = |count: usize| -> Vec<Vec<f64>> {
        if count == 128 {
            train.iter().map(|&d| vec![d]).collect()
        } else {
            grid(count).iter().map(|&d| vec![d]).collect()
        }
    };
    let dictionaries = [("training set", &small, 128), ("nested level", &large, big)];
    // One method on one dictionary: per-query times, active atoms, converged count, errors,
    // rounds and final working-set sizes.
    let run = |data: &Vec<f64>, count: usize, start: Option<usize>| -> Run {
        let dict = Dictionary::new(MatRef::from_column_major_slice(data, nc, count));
        let atoms = dict.cone_basis(&[0.0], 0).expect("atoms");
        let k = atoms.ncols();
        let theta: Vec<f64> = (0..k).flat_map(|j| atoms.col(j).iter().copied().collect::<Vec<_>>()).collect();
        let ws = start
            .map(|st| WorkingSet::new(MatRef::from_column_major_slice(data, nc, count), &points_of(count), &w8, st));
        let mut rom = base.clone();
        if ws.is_none() {
            rom.set_dual(&theta, k);
        }
        let (mut w, mut sc) = (RomWork::default(), WorkingSetScratch::default());
        let mut r = Run { atoms: k, ..Run::default() };
        for (j, &d) in test.iter().enumerate() {
            let mut best = f64::INFINITY;
            let mut info = None;
            for _ in 0..reps {
                let t = Instant::now();
                let i = match &ws {
                    None => rom.solve_in(&[d], &RomParams::default(), &mut w),
                    Some(ws) => {
                        let out = ws.solve(&mut rom, &[d], &RomParams::default(), &mut w, &mut sc);
                        r.rounds.push(out.rounds as f64);
                        r.sizes.push(out.atoms as f64);
                        out.info
                    }
                };
                best = best.min(t.elapsed().as_secs_f64());
                info = Some(i);
            }
            let s = w.solution(&info.expect("at least one repetition"));
            r.times.push(best);
            if s.outcome == RomOutcome::Converged {
                r.converged += 1;
                r.active.push(s.nonzero_dual as f64);
                let p = rom.pressure(&s.lambda_hat);
                let num: f64 = p.iter().zip(&truth[j]).zip(&w8).map(|((a, b), w)| w * (a - b) * (a - b)).sum();
                let den: f64 = truth[j].iter().zip(&w8).map(|(b, w)| w * b * b).sum();
                r.errors.push((num / den).sqrt());
            }
        }
        r
    };
    println!("| method | dictionary | atoms | median online (ms) | vs 128 atoms | target | median active atoms | converged | median dual error | median rounds / working set |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (method, start) in [("all atoms", None), ("working set", Some(WS_START))] {
        let mut first = None;
        for (name, data, count) in dictionaries {
            let r = run(data, count, start);
            let on = median(r.times.clone());
            let ratio = on / *first.get_or_insert(on);
            let target = if count != 128 && start.is_some() { "<= 2" } else { "" };
            println!(
                "| {method} | {name} | {} | {:.4} | {ratio:.2} | {target} | {:.0} | {}/{} | {:.2e} | {} |",
                r.atoms,
                on * 1e3,
                median(r.active),
                r.converged,
                test.len(),
                median(r.errors),
                if r.rounds.is_empty() {
                    String::new()
                } else {
                    format!("{:.0} / {:.0}", median(r.rounds), median(r.sizes))
                }
            );
        }
    }
    // The first working set's size, swept: the ratio against the 128-atom dictionary with the
    // same start, and against the fastest 128-atom start (so a larger start cannot meet the
    // target by slowing the reference down).
    let starts = [8, 16, 32, 64];
    let rows: Vec<(usize, Run, Run)> =
        starts.iter().map(|&st| (st, run(&small, 128, Some(st)), run(&large, big, Some(st)))).collect();
    let fastest = rows.iter().map(|(_, a, _)| median(a.times.clone())).fold(f64::INFINITY, f64::min);
    println!();
    println!("| first working set | 128 atoms (ms) | {big} atoms (ms) | ratio | vs fastest 128 | median rounds ({big}) | median working set ({big}) |");
    println!("|---|---|---|---|---|---|---|");
    for (st, a, b) in rows {
        let (ta, tb) = (median(a.times), median(b.times));
        println!(
            "| {st}{} | {:.4} | {:.4} | {:.2} | {:.2} | {:.0} | {:.0} |",
            if st == WS_START { " (default)" } else { "" },
            ta * 1e3,
            tb * 1e3,
            tb / ta,
            tb / fastest,
            median(b.rounds),
            median(b.sizes)
        );
    }
}

/// The measurements of one method on one dictionary.
#[derive(Default)]
struct Run {
    atoms: usize,
    times: Vec<f64>,
    active: Vec<f64>,
    converged: usize,
    errors: Vec<f64>,
    rounds: Vec<f64>,
    sizes: Vec<f64>,
}
