//! The H1 norm of a Q1 displacement field (the primal norm for reconstruction errors,
//! docs/scenes.md#study-settings).
//!
//! For `u = (u_x, u_y)` on the mesh,
//!
//! ```text
//! ||u||²_H1 = ∫ |u|² + |∇u|² dx = sum_c u_c^T (M + G) u_c,   c = x, y,
//! M_ab = ∫ N_a N_b dx,   G_ab = ∫ ∇N_a · ∇N_b dx,
//! ```
//!
//! with the scalar element matrices `M_e + G_e` (4 x 4) integrated by the 2x2 Gauss rule (exact
//! for parallelogram elements; for a general quad the mass term is exact too since
//! `N_a N_b det J` is at most cubic per reference coordinate). [`h1_norm_sq`] loops over the
//! elements and allocates nothing.

use crate::mesh::Mesh2d;
use crate::q1::{jacobian, shape, GAUSS_2X2};

/// Scalar Q1 element matrix `M_e + G_e` (mass plus Laplacian) with 2x2 Gauss quadrature.
/// The element must have a positive Jacobian (checked when the mesh was built).
pub fn element_h1(xe: &[[f64; 2]; 4]) -> [[f64; 4]; 4] {
    let mut k = [[0.0; 4]; 4];
    for &[xi, eta] in &GAUSS_2X2 {
        let jac = jacobian(xe, xi, eta);
        let n = shape(xi, eta);
        let w = jac.det; // Gauss weight 1
        for a in 0..4 {
            for b in 0..4 {
                let grad = jac.dn_dx[a][0] * jac.dn_dx[b][0] + jac.dn_dx[a][1] * jac.dn_dx[b][1];
                k[a][b] += w * (n[a] * n[b] + grad);
            }
        }
    }
    k
}

/// `||u||²_H1` over every element of `mesh` (all bodies), `u` interleaved `(u_x, u_y)` per node.
pub fn h1_norm_sq(mesh: &Mesh2d, u: &[f64]) -> f64 {
    assert_eq!(u.len(), mesh.n_dof(), "displacement length");
    let mut total = 0.0;
    for (e, q) in mesh.quads.iter().enumerate() {
        let k = element_h1(&mesh.element_coords(e));
        for c in 0..2 {
            let ue = [u[2 * q[0] + c], u[2 * q[1] + c], u[2 * q[2] + c], u[2 * q[3] + c]];
            for a in 0..4 {
                total += ue[a] * (0..4).map(|b| k[a][b] * ue[b]).sum::<f64>();
            }
        }
    }
    total
}

/// The Gram matrix `H` of [`h1_norm_sq`] assembled (both components), for repeated products.
pub fn h1_gram(mesh: &Mesh2d) -> super::CsrMatrix {
    let mut t = Vec::with_capacity(mesh.quads.len() * 32);
    for (e, q) in mesh.quads.iter().enumerate() {
        let k = element_h1(&mesh.element_coords(e));
        for c in 0..2 {
            for a in 0..4 {
                for b in 0..4 {
                    t.push((2 * q[a] + c, 2 * q[b] + c, k[a][b]));
                }
            }
        }
    }
    super::CsrMatrix::from_triplets(mesh.n_dof(), t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::mesh::rectangle;
    use crate::rng::Rng;

    /// `u = (x, 0)` and `u = (0, y)` on the unit square: `∫ x² + 1 dx = 1/3 + 1 = 4/3`, also
    /// on a mesh with randomly distorted interior nodes (both fields are in the isoparametric Q1
    /// space, their gradients are exactly constant, and 2x2 Gauss integrates `x² det J` exactly
    /// on any quad), so the only error is rounding: 1e-14 relative.
    #[test]
    fn linear_field_on_unit_square() {
        for distort in [false, true] {
            let (nx, ny) = (5, 4);
            let mut g = rectangle(0.0, 0.0, 1.0, 1.0, nx, ny).expect("valid");
            if distort {
                let mut rng = Rng::new(7);
                for j in 1..ny {
                    for i in 1..nx {
                        let n = g.node(i, j);
                        g.nodes[n][0] += rng.uniform_in(-0.05, 0.05);
                        g.nodes[n][1] += rng.uniform_in(-0.05, 0.05);
                    }
                }
            }
            let (mesh, _) = Mesh2d::from_grids(&[&g]);
            mesh.check_jacobians().expect("valid mesh");
            let ux: Vec<f64> = mesh.nodes.iter().flat_map(|p| [p[0], 0.0]).collect();
            let uy: Vec<f64> = mesh.nodes.iter().flat_map(|p| [0.0, p[1]]).collect();
            assert_close!(h1_norm_sq(&mesh, &ux), 4.0 / 3.0, Tol::rel(1e-14));
            assert_close!(h1_norm_sq(&mesh, &uy), 4.0 / 3.0, Tol::rel(1e-14));
            // a constant field has no gradient: ∫ 1 dx = area = 1
            let c: Vec<f64> = mesh.nodes.iter().flat_map(|_| [1.0, 0.0]).collect();
            assert_close!(h1_norm_sq(&mesh, &c), 1.0, Tol::rel(1e-14));
        }
    }

    /// The assembled Gram matrix gives the element-wise norm (1e-12 relative).
    #[test]
    fn assembled_gram_matches_the_norm() {
        let g = rectangle(0.0, 0.0, 2.0, 1.0, 7, 4).expect("mesh");
        let (mesh, _) = Mesh2d::from_grids(&[&g]);
        let mut rng = Rng::new(10);
        let u: Vec<f64> = (0..mesh.n_dof()).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let hu = h1_gram(&mesh).matvec(&u);
        let q: f64 = u.iter().zip(&hu).map(|(a, b)| a * b).sum();
        assert_close!(q, h1_norm_sq(&mesh, &u), Tol::rel(1e-12));
    }
}
