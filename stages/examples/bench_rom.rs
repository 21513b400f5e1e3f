//! Benchmark of the online reduced solve against the mesh: the same ironing problem on the
//! coarse mesh, the fine mesh (2x per direction) and a 4x refined mesh, at the same ranks.
//!
//! `cargo run --release -p crom-stages --example bench_rom [r | r_primal,r_dual] [repetitions] [refinement] [n_train] [tol]`
//!
//! For each mesh: build and factor the model, solve `n_train` (default 32) training snapshots
//! (d_x = 3k/(n_train - 1)) and the `n_train - 1` test points between them, take the POD of the
//! contact responses and the CPG of the pressures, build the reduced model once at full ranks
//! and query its leading block (default r = 16, or `r_primal,r_dual`), warm-started from the
//! training points as the product does, at every test point with the exact
//! online solve, single-threaded, keeping the fastest of `repetitions` (default 5) per point.
//! Prints a markdown table: dofs, contact dofs, median online time, its ratio to the coarse
//! mesh (target <= 2x at 4x refinement), median full-order time and speed-up, median relative
//! H1 error, and converged points; first a row for the rope (full bases, 9 test points).
//! `refinement` 0 runs only the rope, 1/2/4 only that mesh. A fifth argument `tol` adds, per
//! mesh, the same model on a sampled surface (`ReducedModel::with_sampled_surface` fitted to
//! the training points at relative residual `tol`; docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints), its online time against
//! the coarse mesh's sampled model and its error against the full-order solves.

use crom_stages::basis::{cpg, pod_full, CpgParams};
use crom_stages::contact::{build_ironing, ContactSolveParams, FactoredModel, IroningParams, Material};
use crom_stages::rom::{ContactOperator, PrimalErrors, ReducedModel, RomOutcome, RomParams, RomWork};
use faer::MatRef;
use std::time::Instant;

fn ironing(refine: usize) -> FactoredModel {
    let p = IroningParams {
        slab_length: 5.0,
        slab_height: 1.0,
        slab_nx: 100 * refine,
        slab_ny: 20 * refine,
        slab: Material::new(1.0, 0.3),
        iron_width: 1.0,
        iron_height: 1.0,
        sole_radius: 2.0,
        iron_nx: 30 * refine,
        iron_ny: 30 * refine,
        iron: Material::new(10.0, 0.3),
        contact_x: 1.0,
        d_y: Some(0.04),
    };
    build_ironing(&p).expect("ironing").factor().expect("factor")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn columns(m: MatRef<'_, f64>, r: usize) -> Vec<f64> {
    (0..r).flat_map(|j| m.col(j).iter().copied().collect::<Vec<_>>()).collect()
}

fn main() {
    // `r` or `r_primal,r_dual`
    let ranks: Vec<usize> =
        std::env::args().nth(1).map(|a| a.split(',').filter_map(|x| x.parse().ok()).collect()).unwrap_or_default();
    let (r_p, r_d) = match ranks[..] {
        [r] => (r, r),
        [a, b] => (a, b),
        _ => (16, 16),
    };
    let reps: usize = std::env::args().nth(2).and_then(|a| a.parse().ok()).unwrap_or(5).max(1);
    let only: Option<usize> = std::env::args().nth(3).and_then(|a| a.parse().ok());
    let tol = ContactSolveParams { rel_tol: 1e-10, max_iter: 500 };
    let n_train: usize = std::env::args().nth(4).and_then(|a| a.parse().ok()).unwrap_or(32).max(2);
    let sampling: Option<f64> = std::env::args().nth(5).and_then(|a| a.parse().ok());
    let train: Vec<f64> = (0..n_train).map(|k| 3.0 * k as f64 / (n_train - 1) as f64).collect();
    let test: Vec<f64> = (0..n_train - 1).map(|k| 3.0 * (k as f64 + 0.5) / (n_train - 1) as f64).collect();
    println!("| mesh | dofs | contact dofs | ranks | median online (ms) | vs coarse | target | median full-order (ms) | speed-up | median H1 error | converged | mean linearisations |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    if only.is_none_or(|o| o == 0) {
        rope_row(reps.max(50));
    }
    let mut base = None;
    let mut base_sampled = None;
    for (name, refine) in [("ironing-coarse", 1), ("ironing-fine (2x)", 2), ("ironing 4x", 4)] {
        if only.is_some_and(|o| o != refine) {
            continue;
        }
        let fm = ironing(refine);
        let (n, nc) = (fm.n_dof(), fm.n_contact());
        let snaps: Vec<_> = train.iter().map(|&d| fm.solve(&[d], &tol).expect("training solve")).collect();
        let responses: Vec<f64> = train
            .iter()
            .zip(&snaps)
            .flat_map(|(&d, s)| s.u.iter().zip(fm.lift(&[d])).map(|(a, b)| a - b).collect::<Vec<_>>())
            .collect();
        let duals: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
        let phi = pod_full(MatRef::from_column_major_slice(&responses, n, train.len())).expect("pod");
        let theta = cpg(MatRef::from_column_major_slice(&duals, nc, train.len()), CpgParams::default()).expect("cpg");
        let (ru, rl) = (phi.modes.ncols(), theta.basis.ncols());
        let phi_c = columns(phi.modes.as_ref(), ru);
        let full = ReducedModel::new(&fm, &phi_c, ru, &columns(theta.basis.as_ref(), rl), rl).expect("K̂ SPD");
        let samples: Vec<Vec<f64>> = train.iter().map(|&d| vec![d]).collect();
        let rom = full.leading(r_p.min(ru), r_d.min(rl));
        // the product's setting: warm starts from the training points (docs/design-notes.md#warm-starts)
        let rom = rom.with_warm_starts(&samples, &RomParams::default());
        let mut fom_t = Vec::new();
        let mut refs = Vec::new();
        for &d in &test {
            let t = Instant::now();
            let s = fm.solve(&[d], &tol).expect("test solve");
            fom_t.push(t.elapsed().as_secs_f64());
            refs.push((vec![d], s.u));
        }
        let refs_view: Vec<(&[f64], &[f64])> = refs.iter().map(|(m, u)| (m.as_slice(), u.as_slice())).collect();
        let pe = PrimalErrors::new(&fm, &phi_c, ru, &refs_view).expect("M SPD");
        let sampled = sampling.map(|t| {
            let (m, sel) = rom.with_sampled_surface(&samples, &RomParams::default(), t).expect("sampling");
            (m.with_warm_starts(&samples, &RomParams::default()), sel)
        });
        let mut variants = vec![(name.to_string(), rom.clone(), None)];
        if let Some((m, sel)) = sampled {
            let label = format!("{name}, sampled ({} slaves, fit {:.1e})", sel.columns.len(), sel.residual);
            variants.push((label, m, Some(())));
        }
        for (label, rom, is_sampled) in variants {
            let mut w = RomWork::default();
            let (mut times, mut errs, mut conv, mut lins) = (Vec::new(), Vec::new(), 0, 0);
            for (j, &d) in test.iter().enumerate() {
                let mut best = f64::INFINITY;
                let mut info = None;
                for _ in 0..reps {
                    let t = Instant::now();
                    let i = rom.solve_in(&[d], &RomParams::default(), &mut w);
                    best = best.min(t.elapsed().as_secs_f64());
                    info = Some(i);
                }
                let s = w.solution(&info.expect("at least one repetition"));
                conv += usize::from(s.outcome == RomOutcome::Converged);
                lins += s.linearizations;
                errs.push(pe.relative(j, &s.u_hat));
                times.push(best);
            }
            let (on, fom) = (median(times), median(fom_t.clone()));
            let slot = if is_sampled.is_some() { &mut base_sampled } else { &mut base };
            let ratio = on / *slot.get_or_insert(on);
            let (ranks, target) = (rom.ranks(), if refine == 4 { "<= 2" } else { "" });
            println!(
                "| {label} | {n} | {} | ({}, {}) | {:.4} | {:.2} | {target} | {:.2} | {:.0} | {:.2e} | {conv}/{} | {:.1} |",
                fm.n_contact_dof(),
                ranks.0,
                ranks.1,
                on * 1e3,
                ratio,
                fom * 1e3,
                fom / on,
                median(errs),
                test.len(),
                lins as f64 / test.len() as f64
            );
        }
    }
}

/// The rope (Type-1): full bases from the shipped scene's 10 training points, online time of
/// the exact solve at the 9 test midpoints against the full-order solve (fastest of `reps`),
/// with the QP started cold and from the nearest training point's active set (the product's
/// setting, `ReducedModel::with_warm_starts`).
fn rope_row(reps: usize) {
    use crom_schemas::scene::Model;
    use crom_stages::rope::{solve, Rope, RopeParams, RopeSolveParams};
    let scene = crom_stages::shipped::shipped_scene("rope").expect("rope scene");
    let Model::Rope(spec) = &scene.model else { panic!("rope scene is not a rope") };
    let rope = Rope::new(RopeParams::from(spec));
    let rope = &rope;
    let train: Vec<f64> = (0..10).map(|k| -0.5 + k as f64 / 9.0).collect();
    let test: Vec<f64> = (0..9).map(|k| -0.5 + (k as f64 + 0.5) / 9.0).collect();
    let sp = RopeSolveParams::default();
    let n = rope.n_nodes();
    let u0 = rope.lift(&[0.0]);
    let rope: &Rope = rope;
    let snaps: Vec<_> = train.iter().map(|&g| solve(rope, g, &sp).expect("rope solve")).collect();
    let resp: Vec<f64> =
        snaps.iter().flat_map(|s| s.u.iter().zip(&u0).map(|(a, b)| a - b).collect::<Vec<_>>()).collect();
    let duals: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
    let phi = pod_full(MatRef::from_column_major_slice(&resp, n, train.len())).expect("pod");
    let theta = cpg(MatRef::from_column_major_slice(&duals, n, train.len()), CpgParams::default()).expect("cpg");
    let (ru, rl) = (phi.modes.ncols(), theta.basis.ncols());
    let cold = ReducedModel::new(rope, &columns(phi.modes.as_ref(), ru), ru, &columns(theta.basis.as_ref(), rl), rl)
        .expect("K̂ SPD");
    let samples: Vec<Vec<f64>> = train.iter().map(|&g| vec![g]).collect();
    let warm = cold.clone().with_warm_starts(&samples, &RomParams::default());
    for (label, rom) in [("rope, cold QP start", &cold), ("rope", &warm)] {
        let mut w = RomWork::default();
        let (mut on, mut fom) = (Vec::new(), Vec::new());
        for &g in &test {
            let (mut b_on, mut b_fom) = (f64::INFINITY, f64::INFINITY);
            for _ in 0..reps {
                let t = Instant::now();
                let s = rom.solve_in(&[g], &RomParams::default(), &mut w);
                b_on = b_on.min(t.elapsed().as_secs_f64());
                assert_eq!(s.outcome, RomOutcome::Converged);
                let t = Instant::now();
                let _ = solve(rope, g, &sp);
                b_fom = b_fom.min(t.elapsed().as_secs_f64());
            }
            on.push(b_on);
            fom.push(b_fom);
        }
        let (on, fom) = (median(on), median(fom));
        println!(
            "| {label} | {n} | {n} | ({ru}, {rl}) | {:.5} | | | {:.4} | {:.0} | | {}/{} | 1 |",
            on * 1e3,
            fom * 1e3,
            fom / on,
            test.len(),
            test.len()
        );
    }
}
