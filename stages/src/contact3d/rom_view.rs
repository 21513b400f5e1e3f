//! The 3-D two-body model as a [`ContactOperator`] for the online reduced solve (scenes
//! hertz3d and ironing3d), as [`crate::contact`]'s `rom_view` is in 2-D. Type-2: the pairing
//! is recomputed at every linearisation with the solver's own rule ([`super::surface`]), which
//! is stateless in 3-D (no vertex ties), so the operator's linearisation at a snapshot is the
//! solver's.
//!
//! - dofs: all displacement dofs of both bodies, `(u_x, u_y, u_z)` per node;
//! - dual field: one pressure per slave node, nodal force = pressure × tributary area (the
//!   conversion [`Factored3d::solve`] uses);
//! - lift `u0(mu)`: the contact-free solution, `u_D(mu)` on the Dirichlet dofs and the factor's
//!   responses on the free ones, bit for bit what the solver adds its contact correction to;
//! - `stiffness_mul`: the sparse `K` with the Dirichlet rows zeroed;
//! - the contact compliance `W = E_c^T K_FF^{-1} E_c` is the solver's Delassus operator on the
//!   contact dofs (slaves, then masters);
//! - the primal norm is H1 ([`crate::solid::h1`]).

use super::solve::Factored3d;
use super::surface::{FacetGrid, Pair3};
use crate::full_order::{Compliance, ContactOperator, Linearized, Surface};

impl Factored3d {
    /// The global dof of each contact dof (three per contact node).
    fn contact_dofs(&self) -> Vec<usize> {
        self.contact_nodes().iter().flat_map(|&n| [3 * n, 3 * n + 1, 3 * n + 2]).collect()
    }
}

impl ContactOperator for Factored3d {
    fn n_dof(&self) -> usize {
        self.model.n_dof()
    }

    fn n_contact(&self) -> usize {
        self.model.slaves.len()
    }

    fn weights(&self) -> &[f64] {
        &self.model.area
    }

    fn lift(&self, mu: &[f64]) -> Vec<f64> {
        self.model.split.contact_free(&self.model.u_d, &self.resp, mu)
    }

    fn lift_terms(&self) -> Vec<Vec<f64>> {
        self.model.split.contact_free_terms(&self.model.u_d, &self.resp)
    }

    fn stiffness_mul(&self, x: &[f64], y: &mut [f64]) {
        self.model.split.mul_zero_fixed(&self.model.k, x, y)
    }

    /// The solver's pairing of every non-fixed slave at `u` (the rule is stateless in 3-D).
    fn linearize(&self, _mu: &[f64], u: &[f64], out: &mut Linearized) {
        let m = &self.model;
        assert_eq!(u.len(), m.n_dof(), "displacement length");
        let ns = m.slaves.len();
        let cnodes = self.contact_nodes();
        let x = |c: usize| {
            let n = cnodes[c];
            let r = m.mesh.nodes[n];
            [r[0] + u[3 * n], r[1] + u[3 * n + 1], r[2] + u[3 * n + 2]]
        };
        let xm: Vec<[f64; 3]> = (ns..cnodes.len()).map(x).collect();
        let mut grid = FacetGrid::new(&m.surface, &xm);
        out.clear();
        out.start.push(0);
        for s in 0..ns {
            let xs = x(s);
            let p = if self.slave_fixed[s] || xs.iter().any(|v| !v.is_finite()) {
                Pair3::UNPAIRED
            } else {
                grid.pair(&m.surface, &xm, xs)
            };
            let mut gap0 = 0.0;
            if p.is_paired() {
                for (cd, c) in p.row(s, ns) {
                    let n = cnodes[cd / 3];
                    out.dofs.push(3 * n + cd % 3);
                    out.coeffs.push(c);
                    gap0 += c * m.mesh.nodes[n][cd % 3];
                }
            }
            out.start.push(out.dofs.len());
            out.gap0.push(gap0);
            out.paired.push(p.is_paired());
            out.pairing.push(if p.is_paired() { p.feature.id() } else { u64::MAX });
        }
    }

    fn primal_norm_sq(&self, u: &[f64]) -> f64 {
        let mut hu = vec![0.0; u.len()];
        self.primal_gram_mul(u, &mut hu);
        u.iter().zip(&hu).map(|(a, b)| a * b).sum()
    }

    fn primal_gram_mul(&self, u: &[f64], out: &mut [f64]) {
        self.h1.get_or_init(|| crate::solid::h1::h1_gram(&self.model.mesh)).matvec_into(u, out)
    }

    fn surface(&self) -> Surface {
        let m = &self.model;
        let (planes, plane_tol) = m.surface.planes();
        Surface::NodeToSurface {
            n_slaves: m.slaves.len(),
            x_ref: self.x_ref.clone(),
            dofs: self.contact_dofs(),
            slave_fixed: self.slave_fixed.clone(),
            facets: m.surface.facets().to_vec(),
            planes: planes.to_vec(),
            plane_tol,
        }
    }

    fn contact_compliance(&self) -> Compliance {
        Compliance { dofs: self.contact_dofs(), w: self.w.clone() }
    }
}
