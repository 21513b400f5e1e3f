//! The vertex-zone rule measured against flip ties alone, on every training point of
//! ironing-coarse, ironing-fine and hertz: worst values of the geometric check
//! (`contact::check`), points with tied slaves, and whether the state depends on the start
//! (cold vs warm-started from the previous training point vs a perturbed first active set).
//!
//! `cargo run --release -p crom-stages --example vertex_rule`

use crom_stages::contact::{ContactSolveParams, FactoredModel, SolveStart, VertexRule};
use crom_stages::shipped::{shipped_contact_model, shipped_scene};
use crom_stages::snapshot::Snapshot;

fn factored(name: &str) -> (FactoredModel, Vec<f64>) {
    let scene = shipped_scene(name).unwrap_or_else(|e| panic!("{e}"));
    (shipped_contact_model(name).factor().expect("factor"), scene.parameter.train())
}

/// Largest |a - b| over the displacement, relative to max |a|.
fn diff(a: &Snapshot, b: &Snapshot) -> f64 {
    let scale = a.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.u.iter().zip(&b.u).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

fn main() {
    let p = ContactSolveParams::default();
    println!("| scene | rule | points | with ties | min gap | max active gap | max cone angle | max rounds | max start dependence |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in ["ironing-coarse", "ironing-fine", "hertz"] {
        let (fm, pts) = factored(name);
        for rule in [VertexRule::FlipTies, VertexRule::Zone] {
            let snaps: Vec<Snapshot> = pts
                .iter()
                .map(|&mu| fm.solve_with_rule(&[mu], &p, &SolveStart::COLD, rule).expect("cold solve"))
                .collect();
            let mut dep = 0.0f64;
            for k in 1..pts.len() {
                let warm = SolveStart { u: Some(&snaps[k - 1].u), active: None };
                let w = fm.solve_with_rule(&[pts[k]], &p, &warm, rule).expect("warm solve");
                let mut act: Vec<bool> = snaps[k].pressure.iter().map(|&x| x > 0.0).collect();
                for (i, a) in act.iter_mut().enumerate() {
                    if i % 3 == 0 {
                        *a = !*a;
                    }
                }
                let pert = SolveStart { u: None, active: Some(&act) };
                let q = fm.solve_with_rule(&[pts[k]], &p, &pert, rule).expect("perturbed solve");
                dep = dep.max(diff(&snaps[k], &w)).max(diff(&snaps[k], &q));
            }
            let st = |f: &dyn Fn(&Snapshot) -> f64, min: bool| {
                snaps
                    .iter()
                    .map(f)
                    .fold(if min { f64::INFINITY } else { 0.0 }, |a, b| if min { a.min(b) } else { a.max(b) })
            };
            println!(
                "| {name} | {rule:?} | {} | {} | {:.2e} | {:.2e} | {:.2e} | {} | {:.1e} |",
                snaps.len(),
                snaps.iter().filter(|s| s.stats.vertex_ties > 0).count(),
                st(&|s| s.stats.min_gap, true),
                st(&|s| s.stats.active_gap, false),
                st(&|s| s.stats.cone_angle, false),
                snaps.iter().map(|s| s.stats.vertex_rounds).max().unwrap_or(0),
                dep,
            );
        }
    }
}
