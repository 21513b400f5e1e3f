//! Finite elements for 2-D small-strain linear elasticity (plane strain, Q1).
//!
//! Equilibrium `K u = f` with `K = sum_e A_e^T K_e A_e` (element kernel [`crate::q1::stiffness`],
//! global assembly [`assemble_stiffness`]). Dirichlet conditions `u_D` are imposed by
//! elimination ([`DofSplit`]): with free dofs `F` and fixed dofs `D`,
//! `K_FF u_F = f_F - K_FD u_D`, the imposed displacements entering the right-hand side.

mod assembly;
mod dirichlet;
pub mod h1;
mod material;

pub use assembly::{assemble_stiffness, AssemblyError, CsrMatrix};
pub use dirichlet::DofSplit;
pub use material::Material;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::mesh::{rectangle, Mesh2d};
    use crate::rng::Rng;

    /// Patch test (Zienkiewicz & Taylor, *The Finite Element Method*, vol. 1, ch. 10; Taylor,
    /// Simo & Zienkiewicz 1986): on a mesh with distorted interior nodes, imposing a linear
    /// displacement field on the boundary must reproduce it exactly in the interior, because Q1
    /// contains every linear field and 2x2 Gauss integrates the constant-strain energy exactly.
    ///
    /// ```text
    ///   +----+----+----+----+     4 x 3 elements of [0,2] x [0,1.5],
    ///   |   /  \  |  /  |   |     every interior node moved randomly by up to
    ///   +--*----*-+-*---+---+     0.3 h in x and y (seeded Rng); boundary
    ///   |  |     \   \  |   |     nodes: u = (a + b x + c y, d + e x + f y)
    ///   +--*------*---*-+---+     interior: solve K_FF u_F = -K_FD u_D
    ///   +----+----+----+----+
    /// ```
    #[test]
    fn patch_test_distorted_mesh_reproduces_linear_field() {
        let (nx, ny) = (4, 3);
        let mut g = rectangle(0.0, 0.0, 2.0, 1.5, nx, ny).expect("valid");
        let h = 0.5;
        let mut rng = Rng::new(20230601);
        for j in 1..ny {
            for i in 1..nx {
                let n = g.node(i, j);
                g.nodes[n][0] += rng.uniform_in(-0.3, 0.3) * h;
                g.nodes[n][1] += rng.uniform_in(-0.3, 0.3) * h;
            }
        }
        let (mesh, _) = Mesh2d::from_grids(&[&g]);
        mesh.check_jacobians().expect("distorted but valid");
        let mat = Material::new(7.0, 0.3);
        let k = assemble_stiffness(&mesh, &[mat]).expect("assembly");
        let field = |p: [f64; 2]| [0.1 + 0.02 * p[0] - 0.03 * p[1], -0.05 + 0.04 * p[0] + 0.01 * p[1]];
        let mut fixed = Vec::new();
        for (n, p) in mesh.nodes.iter().enumerate() {
            let on_boundary =
                p[0].abs() < 1e-12 || (p[0] - 2.0).abs() < 1e-12 || p[1].abs() < 1e-12 || (p[1] - 1.5).abs() < 1e-12;
            if on_boundary {
                fixed.extend([2 * n, 2 * n + 1]);
            }
        }
        let split = DofSplit::new(mesh.n_dof(), &fixed);
        let mut u_full = vec![0.0; mesh.n_dof()];
        for (n, p) in mesh.nodes.iter().enumerate() {
            let u = field(*p);
            u_full[2 * n] = u[0];
            u_full[2 * n + 1] = u[1];
        }
        let exact = u_full.clone();
        split.solve_unloaded(&k, &mut u_full);
        for (a, b) in u_full.iter().zip(&exact) {
            // Exact reproduction up to the solve's rounding (condition number of a 20-node K
            // ~1e2): the brief's 1e-10.
            assert_close!(*a, *b, Tol::abs(1e-10));
        }
        // And the residual of the full system vanishes at free dofs (no spurious forces).
        let ku = k.matvec(&u_full);
        for &d in split.free() {
            assert_close!(ku[d], 0.0, Tol::abs(1e-10));
        }
    }
}
