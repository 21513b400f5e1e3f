//! What the online solve needs from a full-order contact model.

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

    /// `gap_i(v)` for row `i`.
    pub fn gap(&self, i: usize, v: &[f64]) -> f64 {
        let r = self.start[i]..self.start[i + 1];
        self.dofs[r.clone()].iter().zip(&self.coeffs[r]).map(|(&d, c)| c * v[d]).sum::<f64>() + self.gap0[i]
    }
}

/// A full-order contact model as seen by the online stage (paper Alg. 1 step 5).
pub trait ContactOperator: Sync {
    /// Number of displacement dofs (all, Dirichlet included).
    fn n_dof(&self) -> usize;
    /// Number of potential-contact nodes (length of the dual field).
    fn n_contact(&self) -> usize;
    /// Tributary length of each potential-contact node (pressure → nodal force).
    fn weights(&self) -> &[f64];
    /// The contact-free solution `u0(mu)` (all dofs).
    fn lift(&self, mu: &[f64]) -> Vec<f64>;
    /// `y = K x` for a displacement `x` that vanishes on the Dirichlet dofs (`y` on all dofs,
    /// zero on Dirichlet rows).
    fn stiffness_mul(&self, x: &[f64], y: &mut [f64]);
    /// Linearise the constraints at the full displacement `u` (Type-1 problems ignore `u`).
    fn linearize(&self, mu: &[f64], u: &[f64], out: &mut Linearized);
    /// Squared norm used for primal reconstruction errors (H1 for every scene of crom).
    fn primal_norm_sq(&self, u: &[f64]) -> f64;
    /// True when the pairing depends on the displacement (Type-2).
    fn repairs(&self) -> bool;
    /// The dofs of `u` that [`ContactOperator::linearize`] reads (the contact surfaces' nodes);
    /// the online loop updates only these between linearisations and reconstructs the whole
    /// displacement once at the end. Empty when `linearize` ignores `u` (Type-1).
    fn read_dofs(&self) -> Vec<usize>;
}
