//! [`ReducedModel`]: the offline/online split, the exact and the paper's online solves, and the
//! a-posteriori error indicator (see the module doc of [`crate::rom`]).
//!
//! One concept per file:
//!
//! - `types`: the public settings and results of a query ([`Algorithm`], [`RomParams`],
//!   [`RomOutcome`], [`ReducedSolution`], [`SolveInfo`]) and [`RomError`];
//! - `build`: the offline build ([`ReducedModel::new`]), leading ranks and storage;
//! - `dual_basis`: replacing the dual basis per query, and the gaps a growing one checks;
//! - `surface`: the offline data of the contact surface and its reduced quadrature;
//! - `parts`: the model as named arrays (what a file stores) and back;
//! - `registered`: a registered dual basis rebuilt at each query point ([`QueryModel`]);
//! - `warm`: the warm-start library of the exact solve;
//! - `work`: the buffers of online queries ([`RomWork`]);
//! - `solve`: the query and the exact solve (QP per linearisation, re-pairing, zone rule);
//! - `exact_step`: the exact corrected re-pairing step (GMRES on the SQP step's equation);
//! - `paper`: the paper's Algorithm 1;
//! - `linearise`: the Type-2 linearisation state and the re-pairing with proofs;
//! - `nts3`: the 3-D contact surface (node-to-surface pairs) and its linearisation;
//! - `oracle`: the reduced constraints as the QP sees them;
//! - `indicator`: the a-posteriori error indicator and the inf-sup diagnostic;
//! - `switches`: the test-only switches of the linearisation (a no-op outside tests).

mod build;
mod dual_basis;
mod exact_step;
mod indicator;
mod linearise;
mod nts3;
mod oracle;
mod paper;
mod parts;
mod registered;
mod solve;
mod surface;
mod switches;
mod types;
mod warm;
mod work;

#[cfg(test)]
pub(crate) mod test_support;

pub use exact_step::MAX_EXACT_STEP;
pub use indicator::Indicator;
pub use parts::ModelParts;
pub use registered::{cone_basis_columns, QueryModel};
pub use surface::SAMPLING_DIRECTIONS;
pub use types::{Algorithm, ReducedSolution, RomError, RomOutcome, RomParams, SolveInfo, EXACT_STEP_ITERATIONS};
pub use warm::WARM_START_SAMPLES;
pub use work::RomWork;

use build::Compressed;
use registered::PerQueryDual;
use surface::SurfaceData;
use warm::WarmStarts;

/// A reduced model: offline data whose size depends on the ranks and the contact surface only.
/// [`ReducedModel::solve`] reads nothing else — no `n_dof`-length vector.
#[derive(Debug, Clone)]
pub struct ReducedModel {
    r_u: usize,
    r_l: usize,
    n_contact: usize,
    /// The Cholesky factor `L` of `K̂ = Phi^T K Phi` (column-major). Every operator below is
    /// stored in the coordinates `y = L^T û` of the K-orthonormal basis `Psi = Phi L^{-T}`, in
    /// which the reduced stiffness is the identity; `L` only turns the answer back into `û`.
    khat_l: Vec<f64>,
    /// `L^{-T}` (column-major, upper triangular): `û = L^{-T} y` as a product.
    u_of_y: Vec<f64>,
    weights: Vec<f64>,
    /// `Theta[:, :r_l]` by node (CSR): `(column, value)`.
    by_node: Compressed,
    /// `Theta[:, :r_l]` by column (CSC): `(node, value)`.
    by_col: Compressed,
    surf: SurfaceData,
    /// Type-1 warm starts ([`ReducedModel::with_warm_starts`]); empty unless built.
    warm_starts: WarmStarts,
    /// A registered dual basis rebuilt at each query point ([`ReducedModel::dual_at`]); `None`
    /// for a fixed dual basis.
    per_query: Option<PerQueryDual>,
}

impl ReducedModel {
    /// Primal and dual ranks.
    pub fn ranks(&self) -> (usize, usize) {
        (self.r_u, self.r_l)
    }

    /// The reduced pressure `Theta λ̂` (one value per potential-contact node).
    pub fn pressure(&self, lambda_hat: &[f64]) -> Vec<f64> {
        (0..self.n_contact)
            .map(|i| {
                (self.by_node.0[i]..self.by_node.0[i + 1])
                    .map(|e| self.by_node.2[e] * lambda_hat[self.by_node.1[e]])
                    .sum()
            })
            .collect()
    }

    /// The reduced pressure at node `i` (one entry of [`Self::pressure`]).
    fn pressure_at(&self, i: usize, lam: &[f64]) -> f64 {
        (self.by_node.0[i]..self.by_node.0[i + 1]).map(|e| self.by_node.2[e] * lam[self.by_node.1[e]]).sum()
    }
}
