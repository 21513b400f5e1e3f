//! What the reduced model needs from a full-order contact model (paper Sec. 2.3.2).
//!
//! This interface sits below both the full-order models ([`crate::contact`], [`crate::rope`])
//! and the reduced model ([`crate::rom`]), so neither depends on the other.
//!
//! The reduced model is built **offline** from this interface (everything of length `n_dof`:
//! the lift, `K Φ`, the reconstruction) and then queried **online** with data whose size
//! depends only on the ranks and on the contact surface ([`Surface`]):
//!
//! - the lift `u0(mu)` is affine in the parameter, `u0 = t_0 + sum_k mu_k t_{k+1}`
//!   ([`ContactOperator::lift_terms`]); its contact-dof rows are all the online solve reads;
//! - Type-1 (fixed pairs, the rope): the gap rows `C` are constant and the gap offsets affine in
//!   the parameter, so the reduced operators `Ĉ = Θ^T W C Φ`, `ĝ0(mu)` are precomputed;
//! - Type-2 (node-to-segment, Hertz and ironing): the pairing depends on the deformed
//!   configuration, so the online solve needs the reference positions of the contact nodes
//!   (slaves, then the master polyline) and their dofs; the gap row of a pairing is
//!   [`crate::contact::pairing::GapRow`], the one the full-order solver uses.

/// Full-order contact constraints linearised at one displacement: for each potential-contact node
/// `i` with a partner, `gap_i(v) = sum_k coeffs[k] v[dofs[k]] + gap0[i]` over
/// `k in start[i]..start[i + 1]`; a node without a partner has an empty row and `paired[i] =
/// false` (its pressure is zero and it imposes nothing).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Linearized {
    /// Row starts (CSR), length `n_contact + 1`.
    pub start: Vec<usize>,
    /// Dof indices of the row entries.
    pub dofs: Vec<usize>,
    /// Coefficients of the row entries.
    pub coeffs: Vec<f64>,
    /// Constant part of each gap.
    pub gap0: Vec<f64>,
    /// Whether the node has a partner.
    pub paired: Vec<bool>,
    /// An identifier of the discrete pairing (segment or vertex per node), to detect re-pairing.
    pub pairing: Vec<u64>,
}

impl Linearized {
    /// Clear, keeping capacity.
    pub fn clear(&mut self) {
        self.start.clear();
        self.dofs.clear();
        self.coeffs.clear();
        self.gap0.clear();
        self.paired.clear();
        self.pairing.clear();
    }

    /// `f += Cᵀ W p`: the nodal forces (all dofs) of the pressures `p` on the paired rows,
    /// `weights` the tributary lengths (pressure → nodal force); unpaired rows carry none.
    pub fn add_forces(&self, weights: &[f64], p: &[f64], f: &mut [f64]) {
        for (i, (&wi, &pi)) in weights.iter().zip(p).enumerate() {
            if self.paired[i] {
                for k in self.start[i]..self.start[i + 1] {
                    f[self.dofs[k]] += self.coeffs[k] * wi * pi;
                }
            }
        }
    }

    /// `gap_i(v)` for row `i`.
    pub fn gap(&self, i: usize, v: &[f64]) -> f64 {
        let r = self.start[i]..self.start[i + 1];
        self.dofs[r.clone()].iter().zip(&self.coeffs[r]).map(|(&d, c)| c * v[d]).sum::<f64>() + self.gap0[i]
    }
}

/// The contact surface as the online solve sees it.
#[derive(Debug, Clone, PartialEq)]
pub enum Surface {
    /// Type-1: `gap(u) = C u + gap0(mu)` with `C` constant (`rows`, whose own `gap0` is unused)
    /// and `gap0(mu) = g_0 + sum_k mu_k g_{k+1}` (`gap0_terms`, one vector of length
    /// `n_contact` per affine term).
    Fixed {
        /// The constant rows of `C`.
        rows: Linearized,
        /// Affine terms of the gap offsets.
        gap0_terms: Vec<Vec<f64>>,
    },
    /// Type-2: node-to-segment pairs between `n_slaves` slave nodes and a master polyline.
    /// Contact nodes are the slaves then the masters; contact dof `2 c + j` is global dof
    /// `dofs[2 c + j]`.
    NodeToSegment {
        /// Number of slaves (the first contact nodes); the dual field has one entry per slave.
        n_slaves: usize,
        /// Reference coordinates of the contact nodes.
        x_ref: Vec<[f64; 2]>,
        /// Global dof of every contact dof.
        dofs: Vec<usize>,
        /// Slaves whose two dofs are Dirichlet (never paired).
        slave_fixed: Vec<bool>,
    },
    /// Type-2 in 3-D: node-to-surface pairs between `n_slaves` slave nodes and a master surface
    /// of bilinear quadrilateral facets (`crate::contact3d`'s pairing rule). Contact nodes are the
    /// slaves then the masters; contact dof `3 c + j` is global dof `dofs[3 c + j]`.
    NodeToSurface {
        /// Number of slaves (the first contact nodes); the dual field has one entry per slave.
        n_slaves: usize,
        /// Reference coordinates of the contact nodes.
        x_ref: Vec<[f64; 3]>,
        /// Global dof of every contact dof.
        dofs: Vec<usize>,
        /// Slaves whose three dofs are Dirichlet (never paired).
        slave_fixed: Vec<bool>,
        /// The master facets over master-local node ids (master `k` is contact node
        /// `n_slaves + k`), in the master body's outward orientation.
        facets: Vec<[usize; 4]>,
        /// The symmetry planes the surface's normal field respects, and the distance that puts a
        /// node on one.
        planes: Vec<crate::solid::symmetry::Plane>,
        /// See `planes`.
        plane_tol: f64,
    },
}

/// The compliance `W = E^T K_FF^{-1} E` on a set of dofs (zero rows and columns on Dirichlet
/// dofs): the displacement of those dofs under unit forces on them.
#[derive(Debug, Clone, PartialEq)]
pub struct Compliance {
    /// Global dofs, in the order of `w`'s rows.
    pub dofs: Vec<usize>,
    /// Row-major `dofs.len() x dofs.len()`.
    pub w: Vec<f64>,
}

/// A full-order contact model as seen by the reduced model.
pub trait ContactOperator: Sync {
    /// Number of displacement dofs (all, Dirichlet included).
    fn n_dof(&self) -> usize;
    /// Number of potential-contact nodes (length of the dual field).
    fn n_contact(&self) -> usize;
    /// Tributary length of each potential-contact node (pressure → nodal force).
    fn weights(&self) -> &[f64];
    /// The contact-free solution `u0(mu)` (all dofs).
    fn lift(&self, mu: &[f64]) -> Vec<f64>;
    /// Affine terms of the lift: `u0(mu) = t_0 + sum_k mu_k t_{k+1}` (equal to [`Self::lift`]
    /// up to the rounding of the sum).
    fn lift_terms(&self) -> Vec<Vec<f64>>;
    /// `y = K x` for a displacement `x` that vanishes on the Dirichlet dofs (`y` on all dofs,
    /// zero on Dirichlet rows).
    fn stiffness_mul(&self, x: &[f64], y: &mut [f64]);
    /// Linearise the constraints at the full displacement `u` with the stateless closest-point
    /// rule (Type-1 problems ignore `u`). For checks; the online solve uses [`Self::surface`].
    fn linearize(&self, mu: &[f64], u: &[f64], out: &mut Linearized);
    /// Squared norm used for primal reconstruction errors (H1 for every scene of crom).
    fn primal_norm_sq(&self, u: &[f64]) -> f64;
    /// `out = H u`, `H` the Gram matrix of [`Self::primal_norm_sq`] (for error evaluation).
    fn primal_gram_mul(&self, u: &[f64], out: &mut [f64]);
    /// [`Self::primal_gram_mul`] of `cols` column-major vectors at once, the columns in
    /// parallel (each column's product is the one [`Self::primal_gram_mul`] computes alone).
    fn primal_gram_mul_cols(&self, u: &[f64], cols: usize, out: &mut [f64]) {
        use rayon::prelude::*;
        let n = self.n_dof();
        if n == 0 {
            return;
        }
        out[..n * cols]
            .par_chunks_mut(n)
            .zip(u[..n * cols].par_chunks(n))
            .for_each(|(o, x)| self.primal_gram_mul(x, o));
    }
    /// The contact surface for the online solve.
    fn surface(&self) -> Surface;
    /// The compliance on the dofs that contact forces act on (for the error indicator).
    fn contact_compliance(&self) -> Compliance;

    /// Estimate of the extreme eigenvalues of the stiffness on the free dofs
    /// ([`crate::condition`]); `None` where the operator has none to offer.
    fn stiffness_condition(&self) -> Option<crate::condition::Condition> {
        None
    }
}
