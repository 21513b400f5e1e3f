use crom_stages::contact::*;
use std::time::Instant;

fn main() {
    let mat = Material { young: 1.0, poisson: 0.3 };
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map(String::as_str).unwrap_or("hertz");
    let t = Instant::now();
    let model = match which {
        "hertz" => build_hertz(&HertzParams { radius: 1.0, material: mat, n_arc: 78, n_side: None }),
        "hertz-fine" => build_hertz(&HertzParams { radius: 1.0, material: mat, n_arc: 312, n_side: None }),
        w => {
            let fine = w == "ironing-fine";
            let f = if fine { 2 } else { 1 };
            build_ironing(&IroningParams {
                slab_length: 5.0, slab_height: 1.0, slab_nx: 100 * f, slab_ny: 20 * f, slab: mat,
                iron_width: 1.0, iron_height: 1.0, sole_radius: 2.0, iron_nx: 30 * f, iron_ny: 30 * f,
                iron: Material { young: 10.0, poisson: 0.3 }, contact_x: 1.0, d_y: 0.04,
            })
        }
    }
    .unwrap();
    println!("build {:?} n_dof {}", t.elapsed(), model.n_dof());
    let t = Instant::now();
    let fm = model.factor().unwrap();
    println!("factor {:?}", t.elapsed());
    let params: Vec<f64> = if which.starts_with("hertz") {
        (1..=12).map(|k| 0.025 * k as f64).collect()
    } else {
        (0..128).map(|k| 3.0 * k as f64 / 127.0).collect()
    };
    let p = ContactSolveParams::default();
    for mu in params {
        let t = Instant::now();
        match fm.solve(mu, &p) {
            Ok(s) => {
                let sumf: f64 = s.pressure.iter().zip(model.tributary_lengths()).map(|(a, b)| a * b).sum();
                println!(
                    "mu {mu:.4} {:?} it {} act {} pen {:.2e} comp {:.2e} kkt {:.2e} ties {} P {:.5} pmax {:.4}",
                    t.elapsed(), s.stats.iterations, s.stats.active, s.stats.max_penetration,
                    s.stats.complementarity, s.stats.kkt_residual, s.stats.vertex_ties, sumf,
                    s.pressure.iter().cloned().fold(0.0, f64::max)
                );
            }
            Err(e) => println!("mu {mu:.4} ERR {e}"),
        }
    }
}
