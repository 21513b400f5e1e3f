//! Test data shared by the unit tests of several modules.

use std::sync::OnceLock;

use faer::Mat;

use crate::contact::{
    build_hertz, build_ironing, ContactSolveParams, FactoredModel, HertzParams, IroningParams, Material,
};
use crate::rng::Rng;

/// `count` non-negative "pressure-like" snapshots on `n` points: parabolic bumps
/// `h (1 - ((i - c)/w)^2)_+` with random centre `c` in `[0, n)`, width `w` in `widths` and height
/// `h` in `[0.5, 2)`.
pub(crate) fn bumps(rng: &mut Rng, n: usize, count: usize, widths: (f64, f64)) -> Mat<f64> {
    let mut s = Mat::zeros(n, count);
    for j in 0..count {
        let centre = rng.uniform_in(0.0, n as f64);
        let width = rng.uniform_in(widths.0, widths.1);
        let height = rng.uniform_in(0.5, 2.0);
        for i in 0..n {
            let d = (i as f64 - centre) / width;
            s[(i, j)] = height * (1.0 - d * d).max(0.0);
        }
    }
    s
}

/// Ironing-like contact pressures on `n` nodes of `[0, 1]`: Hertz bumps
/// `p0 sqrt(1 - ((x - c)/a)^2)_+` whose centre `c` moves across the slab while the half-width
/// `a` and the height `p0` drift with it (neighbouring snapshots nearly parallel, a badly
/// conditioned cone), with the awkward cases of real training sets planted (`count >= 24`):
/// column 5 is zero (no contact), column 9 an exact copy of column 8 (a tie in error and norm),
/// column 13 column 12 with a 1e-9 relative wobble (a near-duplicate), column 17 twice column 16
/// (a positive multiple, in the cone of 16), column 21 the sum of columns 19 and 20.
pub(crate) fn hertz_family(rng: &mut Rng, n: usize, count: usize) -> Mat<f64> {
    assert!(count >= 24, "hertz_family plants special columns up to index 21");
    let mut s = Mat::from_fn(n, count, |i, k| {
        let x = i as f64 / (n - 1) as f64;
        let mu = k as f64 / (count - 1) as f64;
        let a = 0.06 + 0.03 * (3.0 * mu).sin().abs();
        let d = (x - 0.15 - 0.7 * mu) / a;
        (1.0 + 0.5 * mu) * (1.0 - d * d).max(0.0).sqrt()
    });
    s.col_mut(5).fill(0.0);
    for i in 0..n {
        s[(i, 9)] = s[(i, 8)];
        s[(i, 13)] = s[(i, 12)] * (1.0 + 1e-9 * rng.uniform_in(-1.0, 1.0));
        s[(i, 17)] = 2.0 * s[(i, 16)];
        s[(i, 21)] = s[(i, 19)] + s[(i, 20)];
    }
    s
}

/// A random symmetric positive definite `n x n` matrix (column-major): `B B^T + shift I` with
/// `B` uniform in `[-1, 1]`.
pub(crate) fn spd(n: usize, shift: f64, rng: &mut Rng) -> Vec<f64> {
    let b: Vec<f64> = (0..n * n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            a[i + j * n] = (0..n).map(|k| b[i + k * n] * b[j + k * n]).sum::<f64>() + if i == j { shift } else { 0.0 };
        }
    }
    a
}

/// The full-order solver's settings of the contact-operator and reduced-model tests.
pub(crate) const TOL: ContactSolveParams = ContactSolveParams { rel_tol: 1e-10, max_iter: 500 };

/// The hertz scene (n_arc = 78), built and factored once per test process.
pub(crate) fn hertz() -> &'static FactoredModel {
    static M: OnceLock<FactoredModel> = OnceLock::new();
    M.get_or_init(|| {
        let p = HertzParams { radius: 1.0, material: Material::new(1.0, 0.3), n_arc: 78, n_side: None };
        build_hertz(&p).expect("hertz").factor().expect("factor")
    })
}

/// The ironing-coarse scene, built and factored once per test process.
pub(crate) fn ironing_coarse() -> &'static FactoredModel {
    static M: OnceLock<FactoredModel> = OnceLock::new();
    M.get_or_init(|| build_ironing(&ironing_coarse_params()).expect("ironing").factor().expect("factor"))
}

/// The parameters of ironing-coarse.
pub(crate) fn ironing_coarse_params() -> IroningParams {
    IroningParams {
        slab_length: 5.0,
        slab_height: 1.0,
        slab_nx: 100,
        slab_ny: 20,
        slab: Material::new(1.0, 0.3),
        iron_width: 1.0,
        iron_height: 1.0,
        sole_radius: 2.0,
        iron_nx: 30,
        iron_ny: 30,
        iron: Material::new(10.0, 0.3),
        contact_x: 1.0,
        d_y: Some(0.04),
    }
}
