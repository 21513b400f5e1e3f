//! The 3-D ironing model at about 10^5 dofs: time and memory of the model (mesh, assembly,
//! checks), the factorisation with the contact operators (Delassus on the contact dofs), and
//! the snapshots of a sweep (amortised over the threads). `just example bench_contact3d
//! [NX NY NZ]` (block elements; the die scales with them); run under `/usr/bin/time -v` for the
//! peak memory.

use crom_stages::contact::ContactSolveParams;
use crom_stages::contact3d::{build_ironing3d, Ironing3dParams};
use crom_stages::fem::Material;
use rayon::prelude::*;
use std::time::Instant;

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let block_n = if args.len() >= 3 { [args[0], args[1], args[2]] } else { [100, 15, 20] };
    let die_n = [(block_n[0] / 5).max(2), (block_n[1] * 2 / 3).max(2), (block_n[2] / 2).max(2)];
    let p = Ironing3dParams {
        block: [5.0, 0.75, 1.0],
        block_n,
        block_material: Material::new(1.0, 0.3),
        die: [1.0, 0.5, 1.0],
        die_n,
        die_material: Material::new(10.0, 0.3),
        sole_radius: 2.0,
        contact_x: 1.0,
        d_z: Some(0.04),
        slave_box: [0.5, 4.5, 0.55],
        planes: vec![crom_stages::solid::symmetry::Plane { axis: 1, at: 0.0 }],
    };
    let t = Instant::now();
    let model = build_ironing3d(&p).expect("model");
    let t_model = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let f = model.factor().expect("factor");
    let t_factor = t.elapsed().as_secs_f64();
    println!(
        "| block {:?} die {:?} | {} dofs ({} free) | {} slaves, {} contact dofs | model {:.2} s | factor + contact operators {:.2} s |",
        block_n,
        die_n,
        model.n_dof(),
        model.n_free(),
        model.slave_nodes().len(),
        f.n_contact_dof(),
        t_model,
        t_factor
    );
    let points: Vec<f64> = match std::env::var("BENCH_POINTS") {
        Ok(v) => v.split(',').filter_map(|x| x.parse().ok()).collect(),
        Err(_) => (0..16).map(|k| 3.0 * k as f64 / 15.0).collect(),
    };
    let params = ContactSolveParams::default();
    let t = Instant::now();
    let results: Vec<_> = points.par_iter().map(|&dx| f.solve(&[dx], &params)).collect();
    let wall = t.elapsed().as_secs_f64();
    for (dx, r) in points.iter().zip(&results) {
        if let Err(e) = r {
            println!("| d_x = {dx}: {e} |");
        }
    }
    let stats: Vec<_> = results.into_iter().filter_map(Result::ok).map(|s| s.stats).collect();
    let it: usize = stats.iter().map(|s| s.iterations).sum();
    let active: usize = stats.iter().map(|s| s.active).max().unwrap_or(0);
    let kkt = stats.iter().map(|s| s.kkt_residual).fold(0.0, f64::max);
    println!(
        "| {} of {} snapshots converged on {} threads | {:.3} s each, amortised | mean iterations {:.1} | most active {} | worst KKT {:.1e} |",
        stats.len(),
        points.len(),
        rayon::current_num_threads(),
        wall / points.len() as f64,
        it as f64 / stats.len().max(1) as f64,
        active,
        kkt
    );
}
