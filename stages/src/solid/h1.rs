//! The H1 norm of a trilinear displacement field on a hex mesh (the primal norm of the 3-D
//! scenes' reconstruction errors), as [`crate::fem::h1`] is in 2-D:
//!
//! ```text
//! ||u||²_H1 = ∫ |u|² + |∇u|² dx = sum_c u_c^T (M + G) u_c,   c = x, y, z,
//! M_ab = ∫ N_a N_b dx,   G_ab = ∫ ∇N_a · ∇N_b dx,
//! ```
//!
//! with the scalar element matrices `M_e + G_e` (8 x 8) by the 2x2x2 Gauss rule (exact for
//! parallelepipeds; the mass term `N_a N_b det J` is at most quintic per reference coordinate,
//! which the rule integrates exactly only on parallelepipeds, as the stiffness is).

use super::hex8::{jacobian, shape, GAUSS};
use super::mesh::Mesh3d;
use crate::fem::CsrMatrix;

/// Scalar element matrix `M_e + G_e` (mass plus Laplacian) with 2x2x2 Gauss quadrature (unit
/// weights). The element must have a positive Jacobian (checked when the mesh was built).
pub fn element_h1(xe: &[[f64; 3]; 8]) -> [[f64; 8]; 8] {
    let mut k = [[0.0; 8]; 8];
    for &p in &GAUSS {
        let jac = jacobian(xe, p);
        let n = shape(p);
        for a in 0..8 {
            for b in 0..8 {
                let g = (0..3).map(|c| jac.dn_dx[a][c] * jac.dn_dx[b][c]).sum::<f64>();
                k[a][b] += jac.det * (n[a] * n[b] + g);
            }
        }
    }
    k
}

/// The Gram matrix `H` of the H1 norm on `mesh` (all bodies; dofs `3 n + c`):
/// `||u||²_H1 = u^T H u`.
pub fn h1_gram(mesh: &Mesh3d) -> CsrMatrix {
    let mut t = Vec::with_capacity(mesh.hexes.len() * 192);
    for (e, h) in mesh.hexes.iter().enumerate() {
        let k = element_h1(&mesh.element_coords(e));
        for c in 0..3 {
            for a in 0..8 {
                for b in 0..8 {
                    t.push((3 * h[a] + c, 3 * h[b] + c, k[a][b]));
                }
            }
        }
    }
    CsrMatrix::from_triplets(mesh.n_dof(), t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::solid::shapes::cuboid;

    /// On the box `[0, 2] x [0, 1] x [0, 3]` (volume 6) with 2 x 3 x 4 elements:
    /// `u = (x, 0, 0)` gives `∫ x² + 1 = 3 * 8/3 + 6 = 14`, `u = (0, 0, z)` gives
    /// `∫ z² + 1 = 2 * 9 + 6 = 24`, and `u = (1, 1, 1)` gives `3 * 6 = 18` (trilinear fields,
    /// exact on box elements by the 2x2x2 rule: only rounding, 1e-13 relative); the matrix is
    /// symmetric to rounding (each entry sums the same symmetric element terms, in the order
    /// the assembly meets them: 1e-14 relative).
    #[test]
    fn the_norm_of_linear_fields_is_exact() {
        let block = cuboid([0.0; 3], [2.0, 1.0, 3.0], [2, 3, 4]);
        let (mesh, _) = Mesh3d::from_blocks(&[&block]);
        let h = h1_gram(&mesh);
        let norm = |f: &dyn Fn([f64; 3]) -> [f64; 3]| {
            let u: Vec<f64> = mesh.nodes.iter().flat_map(|&p| f(p)).collect();
            let hu = h.matvec(&u);
            u.iter().zip(&hu).map(|(a, b)| a * b).sum::<f64>()
        };
        assert_close!(norm(&|p| [p[0], 0.0, 0.0]), 14.0, Tol::rel(1e-13));
        assert_close!(norm(&|p| [0.0, 0.0, p[2]]), 24.0, Tol::rel(1e-13));
        assert_close!(norm(&|_| [1.0, 1.0, 1.0]), 18.0, Tol::rel(1e-13));
        for r in 0..h.n {
            let (cols, vals) = h.row(r);
            for (&c, &v) in cols.iter().zip(vals) {
                let (cc, cv) = h.row(c);
                let at = cc.iter().position(|&x| x == r).expect("symmetric pattern");
                assert_close!(cv[at], v, Tol::rel(1e-14));
            }
        }
    }
}
