//! Benchmark of the 2-D high-fidelity contact solver on the four 2-D scenes of docs/scenes.md.
//!
//! `cargo run --release -p crom-stages --example bench_contact`
//!
//! Prints a markdown table: dofs, factorisation (sparse Cholesky + Delassus operator) time,
//! mean per-snapshot time and active-set iterations over the scene's training sweep, one
//! factor-solve (forward/backward substitution) time and the ratio snapshot / factor-solve, and
//! the wall time of the full 128-point ironing-fine sweep (d_x = 3k/127) solved on 2 threads
//! with `std::thread::scope`. Scenes are built from the shipped `data/scenes/*.toml`.

use crom_stages::contact::{ContactModel, ContactSolveParams, FactoredModel};
use crom_stages::shipped::shipped_contact_model;
use crom_stages::snapshot::Snapshot;
use std::time::{Duration, Instant};

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

struct Row {
    name: &'static str,
    n_dof: usize,
    n_free: usize,
    n_cdof: usize,
    factor: Duration,
    snap_mean: Duration,
    iters_mean: f64,
    max_iters: usize,
    ties_points: usize,
    ever_in_contact: usize,
    n_slaves: usize,
    fsolve: Duration,
}

fn run(name: &'static str, model: ContactModel, params: &[f64]) -> (Row, FactoredModel) {
    let t = Instant::now();
    let fm = model.factor().expect("factor");
    let factor = t.elapsed();
    let p = ContactSolveParams::default();
    let mut total = Duration::ZERO;
    let (mut iters, mut max_iters, mut ties_points) = (0usize, 0usize, 0usize);
    let mut ever = vec![false; fm.model().slave_nodes().len()];
    for &mu in params {
        let t = Instant::now();
        let s = fm.solve(&[mu], &p).expect("solve");
        total += t.elapsed();
        for (e, &pr) in ever.iter_mut().zip(&s.pressure) {
            *e |= pr > 0.0;
        }
        iters += s.stats.iterations;
        max_iters = max_iters.max(s.stats.iterations);
        ties_points += usize::from(s.stats.vertex_ties > 0);
    }
    // one factor-solve: median of 9 forward/backward substitutions with a dense right-hand side
    let mut times: Vec<Duration> = (0..9)
        .map(|k| {
            let mut b: Vec<f64> = (0..fm.model().n_free()).map(|i| ((i * 7 + k) % 13) as f64 - 6.0).collect();
            let t = Instant::now();
            fm.solve_free_in_place(&mut b);
            std::hint::black_box(&b);
            t.elapsed()
        })
        .collect();
    times.sort();
    let row = Row {
        name,
        n_dof: fm.model().n_dof(),
        n_free: fm.model().n_free(),
        n_cdof: fm.n_contact_dof(),
        factor,
        snap_mean: total / params.len() as u32,
        iters_mean: iters as f64 / params.len() as f64,
        max_iters,
        ties_points,
        ever_in_contact: ever.iter().filter(|&&e| e).count(),
        n_slaves: ever.len(),
        fsolve: times[4],
    };
    (row, fm)
}

fn sweep_parallel(fm: &FactoredModel, params: &[f64], threads: usize) -> (Duration, Vec<Snapshot>) {
    let p = ContactSolveParams::default();
    let t = Instant::now();
    let mut out: Vec<Option<Snapshot>> = vec![None; params.len()];
    std::thread::scope(|sc| {
        let chunks: Vec<_> = out.chunks_mut(params.len().div_ceil(threads)).enumerate().collect();
        let per = params.len().div_ceil(threads);
        for (c, slot) in chunks {
            sc.spawn(move || {
                for (j, s) in slot.iter_mut().enumerate() {
                    *s = Some(fm.solve(&[params[c * per + j]], &p).expect("solve"));
                }
            });
        }
    });
    let el = t.elapsed();
    (el, out.into_iter().map(|s| s.expect("solved")).collect())
}

fn main() {
    let hertz_d: Vec<f64> = (1..=12).map(|k| 0.025 * k as f64).collect();
    let sweep: Vec<f64> = (0..128).map(|k| 3.0 * k as f64 / 127.0).collect();
    let mut rows = Vec::new();
    let (r, _) = run("hertz", shipped_contact_model("hertz"), &hertz_d);
    rows.push(r);
    let (r, _) = run("hertz-fine", shipped_contact_model("hertz-fine"), &hertz_d);
    rows.push(r);
    let (r, _) = run("ironing-coarse", shipped_contact_model("ironing-coarse"), &sweep);
    rows.push(r);
    let (r, fine) = run("ironing-fine", shipped_contact_model("ironing-fine"), &sweep);
    rows.push(r);

    println!("| scene | n_dof | free dofs | contact dofs | factor + Delassus [ms] | snapshots | mean snapshot [ms] | mean / max iterations | points with vertex ties | slaves ever in contact | factor-solve [ms] | snapshot / factor-solve |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (r, n) in rows.iter().zip([12, 12, 128, 128]) {
        println!(
            "| {} | {} | {} | {} | {:.1} | {} | {:.2} | {:.1} / {} | {} | {} / {} | {:.3} | {:.1} |",
            r.name,
            r.n_dof,
            r.n_free,
            r.n_cdof,
            ms(r.factor),
            n,
            ms(r.snap_mean),
            r.iters_mean,
            r.max_iters,
            r.ties_points,
            r.ever_in_contact,
            r.n_slaves,
            ms(r.fsolve),
            r.snap_mean.as_secs_f64() / r.fsolve.as_secs_f64(),
        );
    }
    let (t2, snaps) = sweep_parallel(&fine, &sweep, 2);
    let tied: Vec<usize> = snaps.iter().enumerate().filter(|(_, s)| s.stats.vertex_ties > 0).map(|(k, _)| k).collect();
    let fine_row = &rows[3];
    println!();
    println!(
        "ironing-fine full sweep (128 points, d_x = 3k/127, 2 threads): {:.2} s solve + {:.2} s factor = {:.2} s (target < 20 s); points with vertex ties: k = {:?}",
        t2.as_secs_f64(),
        fine_row.factor.as_secs_f64(),
        t2.as_secs_f64() + fine_row.factor.as_secs_f64(),
        tied
    );
}
