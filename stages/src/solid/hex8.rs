//! The trilinear hexahedron (hex8) kernel: shape functions, Jacobian, and the small-strain
//! stiffness `K_e = sum_gp B^T D B det(J) w` with 2x2x2 Gauss quadrature, or with the
//! volumetric part by mean dilatation ([`stiffness_selective`], the 3-D form of
//! [`crate::q1::stiffness_selective`], against volumetric locking).
//!
//! Reference cube `[-1, 1]^3`; nodes 0-3 counter-clockwise on the face `zeta = -1` seen from
//! `+zeta`, nodes 4-7 above them:
//!
//! ```text
//!        7 -------- 6          N_a = (1 + xi xi_a)(1 + eta eta_a)(1 + zeta zeta_a) / 8
//!       /|         /|
//!      4 -------- 5 |          zeta
//!      | 3 -------|-2           |  eta
//!      |/         |/            | /
//!      0 -------- 1             |/____ xi
//! ```
//!
//! Element dofs are interleaved: `[u_x0, u_y0, u_z0, u_x1, ...]`. Voigt order of strains and
//! stresses: `xx, yy, zz, yz, xz, xy`, shears as engineering strains.

/// `1 / sqrt(3)`, the 2-point Gauss abscissa.
const G: f64 = 0.577_350_269_189_625_8;

/// Reference coordinates of the nodes.
pub const NODES: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// The 2x2x2 Gauss points (all weights 1), ordered like the nodes.
pub const GAUSS: [[f64; 3]; 8] =
    [[-G, -G, -G], [G, -G, -G], [G, G, -G], [-G, G, -G], [-G, -G, G], [G, -G, G], [G, G, G], [-G, G, G]];

/// Shape function values at `p = (xi, eta, zeta)`.
pub fn shape(p: [f64; 3]) -> [f64; 8] {
    let mut n = [0.0; 8];
    for (a, xa) in NODES.iter().enumerate() {
        n[a] = 0.125 * (1.0 + p[0] * xa[0]) * (1.0 + p[1] * xa[1]) * (1.0 + p[2] * xa[2]);
    }
    n
}

/// Shape function derivatives `[dN_a/dxi, dN_a/deta, dN_a/dzeta]` at `p`.
pub fn shape_derivatives(p: [f64; 3]) -> [[f64; 3]; 8] {
    let mut d = [[0.0; 3]; 8];
    for (a, xa) in NODES.iter().enumerate() {
        let f = [1.0 + p[0] * xa[0], 1.0 + p[1] * xa[1], 1.0 + p[2] * xa[2]];
        d[a] = [0.125 * xa[0] * f[1] * f[2], 0.125 * xa[1] * f[0] * f[2], 0.125 * xa[2] * f[0] * f[1]];
    }
    d
}

/// The isoparametric map's Jacobian at a point and the physical shape-function gradients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jacobian {
    /// `det(dx/dxi)`.
    pub det: f64,
    /// `[dN_a/dx, dN_a/dy, dN_a/dz]`; meaningless when `det <= 0`.
    pub dn_dx: [[f64; 3]; 8],
}

/// Jacobian of the element with corner coordinates `xe` at `p`.
pub fn jacobian(xe: &[[f64; 3]; 8], p: [f64; 3]) -> Jacobian {
    let dn = shape_derivatives(p);
    // j[r][c] = d x_r / d xi_c
    let mut j = [[0.0; 3]; 3];
    for a in 0..8 {
        for r in 0..3 {
            for c in 0..3 {
                j[r][c] += xe[a][r] * dn[a][c];
            }
        }
    }
    let cof = |r0: usize, r1: usize, c0: usize, c1: usize| j[r0][c0] * j[r1][c1] - j[r0][c1] * j[r1][c0];
    let det = j[0][0] * cof(1, 2, 1, 2) - j[0][1] * cof(1, 2, 0, 2) + j[0][2] * cof(1, 2, 0, 1);
    // inv[c][r] = d xi_c / d x_r = adj(J)[c][r] / det
    let inv = [
        [cof(1, 2, 1, 2) / det, -cof(0, 2, 1, 2) / det, cof(0, 1, 1, 2) / det],
        [-cof(1, 2, 0, 2) / det, cof(0, 2, 0, 2) / det, -cof(0, 1, 0, 2) / det],
        [cof(1, 2, 0, 1) / det, -cof(0, 2, 0, 1) / det, cof(0, 1, 0, 1) / det],
    ];
    let mut dn_dx = [[0.0; 3]; 8];
    for a in 0..8 {
        for r in 0..3 {
            dn_dx[a][r] = dn[a][0] * inv[0][r] + dn[a][1] * inv[1][r] + dn[a][2] * inv[2][r];
        }
    }
    Jacobian { det, dn_dx }
}

/// A non-positive Jacobian met while integrating an element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadJacobian {
    /// Index into [`GAUSS`] (the centre for the selective term: 8).
    pub gauss_point: usize,
    /// The determinant found.
    pub det: f64,
}

/// The isotropic elasticity matrix split as `D = D_dev + D_vol` (Voigt `xx, yy, zz, yz, xz,
/// xy`): `D_vol = lambda m m^T` (`m = [1, 1, 1, 0, 0, 0]`), `D_dev = mu diag(2, 2, 2, 1, 1, 1)`.
pub fn elasticity(lambda: f64, mu: f64) -> ([[f64; 6]; 6], [[f64; 6]; 6]) {
    let mut dev = [[0.0; 6]; 6];
    let mut vol = [[0.0; 6]; 6];
    for i in 0..3 {
        dev[i][i] = 2.0 * mu;
        dev[i + 3][i + 3] = mu;
        vol[i][..3].fill(lambda);
    }
    (dev, vol)
}

/// The sum of two 6x6 matrices.
pub fn sum(a: &[[f64; 6]; 6], b: &[[f64; 6]; 6]) -> [[f64; 6]; 6] {
    let mut c = *a;
    for (r, row) in c.iter_mut().enumerate() {
        for (x, y) in row.iter_mut().zip(&b[r]) {
            *x += y;
        }
    }
    c
}

/// Element stiffness `24 x 24` with 2x2x2 Gauss quadrature.
pub fn stiffness(xe: &[[f64; 3]; 8], d: &[[f64; 6]; 6]) -> Result<Box<[[f64; 24]; 24]>, BadJacobian> {
    let mut k = Box::new([[0.0; 24]; 24]);
    for (gp, &p) in GAUSS.iter().enumerate() {
        add_point(&mut k, xe, d, p, 1.0).map_err(|det| BadJacobian { gauss_point: gp, det })?;
    }
    Ok(k)
}

/// Selective integration of the volumetric part by mean dilatation (Nagtegaal, Parks & Rice
/// 1974; Hughes, *The Finite Element Method*, sec. 4.5, B-bar): the deviatoric part at 2x2x2
/// Gauss, the volumetric part as `V B̄^T D_vol B̄` with `B̄ = (1/V) ∫ B dV` the element mean
/// of `B` and `V = ∫ dV`, both by 2x2x2 Gauss (exact: `det J ∂N/∂x` is a polynomial of degree
/// at most 2 in each reference coordinate). On a parallelepiped it is the centre-point rule of
/// [`crate::q1::stiffness_selective`]; on a distorted element the centre-point rule fails the
/// patch test in 3-D (`det J ∂N/∂x` is no longer linear), the mean does not. Only the
/// volumetric term is under-integrated, so the fully integrated deviatoric term keeps every
/// non-rigid mode stiff.
pub fn stiffness_selective(
    xe: &[[f64; 3]; 8],
    d_dev: &[[f64; 6]; 6],
    d_vol: &[[f64; 6]; 6],
) -> Result<Box<[[f64; 24]; 24]>, BadJacobian> {
    let mut k = stiffness(xe, d_dev)?;
    let mut mean = [[0.0; 24]; 6];
    let mut volume = 0.0;
    for &p in GAUSS.iter() {
        let jac = jacobian(xe, p);
        let b = strain_matrix(&jac);
        for r in 0..6 {
            for c in 0..24 {
                mean[r][c] += b[r][c] * jac.det;
            }
        }
        volume += jac.det;
    }
    if volume.is_nan() || volume <= 0.0 {
        return Err(BadJacobian { gauss_point: 8, det: volume });
    }
    for row in mean.iter_mut() {
        for x in row.iter_mut() {
            *x /= volume;
        }
    }
    add_product(&mut k, &mean, d_vol, volume);
    Ok(k)
}

/// The smallest Jacobian determinant of the element over its Gauss points and its centre, with
/// the point's index (8: the centre): a mesh check for inverted or degenerate elements.
pub fn min_jacobian(xe: &[[f64; 3]; 8]) -> (f64, usize) {
    let mut worst = (jacobian(xe, [0.0; 3]).det, 8);
    for (gp, &p) in GAUSS.iter().enumerate() {
        let det = jacobian(xe, p).det;
        if det.is_nan() || det < worst.0 {
            worst = (det, gp);
        }
    }
    worst
}

/// `B` (6 x 24, strain = `B u_e`) from the physical gradients.
fn strain_matrix(jac: &Jacobian) -> [[f64; 24]; 6] {
    let mut b = [[0.0; 24]; 6];
    for a in 0..8 {
        let [nx, ny, nz] = jac.dn_dx[a];
        let c = 3 * a;
        b[0][c] = nx;
        b[1][c + 1] = ny;
        b[2][c + 2] = nz;
        b[3][c + 1] = nz;
        b[3][c + 2] = ny;
        b[4][c] = nz;
        b[4][c + 2] = nx;
        b[5][c] = ny;
        b[5][c + 1] = nx;
    }
    b
}

/// `k += w B^T D B`.
fn add_product(k: &mut [[f64; 24]; 24], b: &[[f64; 24]; 6], d: &[[f64; 6]; 6], w: f64) {
    let mut db = [[0.0; 24]; 6];
    for r in 0..6 {
        for c in 0..24 {
            db[r][c] = (0..6).map(|s| d[r][s] * b[s][c]).sum();
        }
    }
    for r in 0..24 {
        for c in 0..24 {
            k[r][c] += w * (0..6).map(|s| b[s][r] * db[s][c]).sum::<f64>();
        }
    }
}

/// Add `w B^T D B det J` at `p` to `k`; `Err(det)` for a non-positive Jacobian.
fn add_point(
    k: &mut [[f64; 24]; 24],
    xe: &[[f64; 3]; 8],
    d: &[[f64; 6]; 6],
    p: [f64; 3],
    weight: f64,
) -> Result<(), f64> {
    let jac = jacobian(xe, p);
    if jac.det.is_nan() || jac.det <= 0.0 {
        return Err(jac.det);
    }
    add_product(k, &strain_matrix(&jac), d, jac.det * weight);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    /// An arbitrary element: the unit cube with its corners moved (still convex).
    fn skewed() -> [[f64; 3]; 8] {
        let mut xe = NODES.map(|p| p.map(|c| 0.5 * (c + 1.0)));
        let moves = [[0.05, -0.03, 0.02], [0.1, 0.0, -0.04], [-0.02, 0.08, 0.0], [0.0, 0.0, 0.06]];
        for (k, m) in moves.iter().enumerate() {
            for c in 0..3 {
                xe[2 * k][c] += m[c];
            }
        }
        xe
    }

    /// The shape functions are a partition of unity and interpolate the nodes (Kronecker).
    #[test]
    fn shape_functions_interpolate_and_sum_to_one() {
        for (a, &p) in NODES.iter().enumerate() {
            let n = shape(p);
            for (b, &v) in n.iter().enumerate() {
                assert_close!(v, if a == b { 1.0 } else { 0.0 }, Tol::abs(1e-15));
            }
        }
        let n = shape([0.3, -0.7, 0.1]);
        assert_close!(n.iter().sum::<f64>(), 1.0, Tol::abs(1e-15));
    }

    /// The Jacobian of the cube `[0, 2] x [0, 3] x [0, 4]` is `diag(1, 1.5, 2)`: det 3, and the
    /// physical gradients are the reference ones divided by the half-lengths.
    #[test]
    fn jacobian_of_a_box() {
        let xe = NODES.map(|p| [p[0] + 1.0, 1.5 * (p[1] + 1.0), 2.0 * (p[2] + 1.0)]);
        let j = jacobian(&xe, [0.2, -0.4, 0.6]);
        assert_close!(j.det, 3.0, Tol::rel(1e-14));
        let dn = shape_derivatives([0.2, -0.4, 0.6]);
        for (g, r) in j.dn_dx.iter().zip(&dn) {
            assert_close!(g[0], r[0], Tol::abs(1e-15));
            assert_close!(g[1], r[1] / 1.5, Tol::abs(1e-15));
            assert_close!(g[2], r[2] / 2.0, Tol::abs(1e-15));
        }
    }

    /// `K_e` is symmetric and annihilates the six rigid-body modes (three translations and
    /// three infinitesimal rotations, whose strain is zero), with both integrations; it has
    /// exactly six zero eigenvalues, so no other mode is free (no hourglass): its rank is 18.
    /// Tolerances: entries are O(E h) = O(1), sums of 24 such, so 1e-12 absolute.
    #[test]
    fn stiffness_is_symmetric_with_exactly_the_rigid_modes_in_its_kernel() {
        let xe = skewed();
        let (dev, vol) = elasticity(0.6, 0.4);
        for k in [stiffness(&xe, &sum(&dev, &vol)).expect("k"), stiffness_selective(&xe, &dev, &vol).expect("k")] {
            for r in 0..24 {
                for c in 0..24 {
                    assert_close!(k[r][c], k[c][r], Tol::abs(1e-12));
                }
            }
            let rigid = |m: usize| -> [f64; 24] {
                let mut u = [0.0; 24];
                for a in 0..8 {
                    let x = xe[a];
                    let v = match m {
                        0..=2 => {
                            let mut t = [0.0; 3];
                            t[m] = 1.0;
                            t
                        }
                        3 => [0.0, -x[2], x[1]],
                        4 => [x[2], 0.0, -x[0]],
                        _ => [-x[1], x[0], 0.0],
                    };
                    u[3 * a..3 * a + 3].copy_from_slice(&v);
                }
                u
            };
            for m in 0..6 {
                let u = rigid(m);
                for row in k.iter() {
                    let f: f64 = row.iter().zip(&u).map(|(a, b)| a * b).sum();
                    assert_close!(f, 0.0, Tol::abs(1e-12));
                }
            }
            let km = faer::Mat::from_fn(24, 24, |r, c| k[r][c]);
            let eig = km.self_adjoint_eigenvalues(faer::Side::Lower).expect("eigenvalues");
            let zero = eig.iter().filter(|&&l| l.abs() < 1e-10).count();
            assert_eq!(zero, 6, "eigenvalues {eig:?}");
            assert!(eig.iter().all(|&l| l > -1e-10));
        }
    }

    /// An inverted element (two faces swapped) is refused with its Gauss point's determinant.
    #[test]
    fn an_inverted_element_is_refused() {
        let mut xe = skewed();
        xe.swap(0, 4);
        xe.swap(1, 5);
        xe.swap(2, 6);
        xe.swap(3, 7);
        let (dev, vol) = elasticity(0.6, 0.4);
        let err = stiffness(&xe, &sum(&dev, &vol)).expect_err("inverted");
        assert!(err.det < 0.0);
        assert!(min_jacobian(&xe).0 < 0.0);
    }
}
