//! The online reduced solve (paper Sec. 2.3.2, Algorithm 1, eqs. 11 and 13), made exact and
//! independent of the mesh size.
//!
//! **Lifting.** The full displacement is written `u = u0(mu) + Phi û`, where `u0(mu)` is the
//! contact-free solution at `mu` (Dirichlet data and loads included; affine in `mu` for every
//! scene of crom) and `Phi` (`n_dof x r_u`) is the POD of the *contact responses*
//! `u_k - u0(mu_k)` of the training snapshots, which vanish on the Dirichlet dofs. Equilibrium
//! then reads `K Phi û = Phi^T C^T W Theta λ̂` with no load term. (The paper leaves the
//! treatment of the parameter-dependent Dirichlet data open; lifting makes the reduced space
//! exact on it.)
//!
//! **Reduced operators** (eq. 11, Alg. 1 step 6). With the full-order constraints linearised at
//! the current iterate, `gap(v) = C v + gap0 >= 0` (one row per potential-contact node, `W` the
//! diagonal of tributary lengths turning pressure into nodal force), and the dual basis `Theta`
//! (`n_contact x r_λ`, non-negative CPG generators, pressure):
//!
//! ```text
//! K̂ = Phi^T K Phi,   Ĉ = Theta^T W C Phi,   ĝ0 = Theta^T W (C u0 + gap0),
//! K̂ û - Ĉ_A^T λ̂_A = 0,   Ĉ_A û + ĝ0_A = 0            (eq. 13 on the active set A)
//! ```
//!
//! **Offline / online.** Everything of length `n_dof` happens offline ([`ReducedModel::new`]):
//! `K̂` and its Cholesky factor, the contact-dof rows `Phi_c` of `Phi`, the contact-dof rows of
//! the lift's affine terms, and for Type-1 problems `Ĉ` and the affine terms of `ĝ0` outright.
//! A Type-2 query positions only the contact nodes, `x_c = X_c + u0_c(mu) + Phi_c û`, pairs the
//! slaves in the support of `Theta` with the full-order solver's own rule
//! ([`crate::contact::vertex::VertexTies::pair`], closest point with vertex ties) and builds
//! their gap rows with the solver's [`crate::contact::pairing::GapRow`]; `C Phi` is then
//! `GapRow · Phi_c`. Its cost depends on the ranks and on the number of contact nodes, never on
//! `n_dof`; the full field `u0 + Phi û` is reconstructed only for error evaluation, outside the
//! timed query ([`ReducedModel::displacement`]).
//!
//! **K-orthonormal coordinates.** Offline, every operator on `û` is rewritten for
//! `y = L^T û` (`K̂ = L L^T`), i.e. for the basis `Psi = Phi L^{-T}` with `Psi^T K Psi = I`:
//! `Phi_c` becomes `Psi_c = Phi_c L^{-T}` (each row through one triangular solve) and Type-1's
//! `Ĉ` is built from `C Psi`. The QP's metric is then the identity, so the online solve makes no
//! triangular solve at all (before: two per QP step, `O(r²)` each, a quarter of the query at
//! r = 128); the answer is turned back into `û = L^{-T} y` once, by a product with the stored
//! `L^{-T}`. `Psi`'s leading columns are the `Psi` of the leading ranks (`L^{-T}` is upper
//! triangular), so [`ReducedModel::leading`] keeps working by truncation.
//!
//! **Exact solve** ([`Algorithm::Exact`]). For a fixed linearisation the reduced problem is the
//! strictly convex QP `min 1/2 ûᵀK̂û s.t. Ĉû + ĝ0 >= 0`, whose KKT conditions are eq. 13 plus
//! sign conditions; `qp` ([`solve_qp`]) solves it by a dual active-set method with finite termination that
//! also proves infeasibility (a primal basis too small for the dual one is refused with that
//! reason, not iterated). Type-2 wraps it in an outer loop: re-pair at `u0 + Phi û`, rebuild
//! the rows, solve again, until the pairing repeats and `û` stops moving. Once the pairing has
//! settled, each step is Newton-corrected for the gaps' curvature (`curvature`: the term of
//! the Lagrangian's Hessian the fixed-point iteration drops), which turns its linear rate of
//! about 1e-2 into about 2e-4 and leaves the fixed point unchanged. A pairing reached again by a
//! change is a cycle: the first drops the Newton correction, the second makes every later step
//! a half step toward the QP's answer (the same fixed points), the third ends the solve
//! `cycled`. A slave is searched
//! again only when it may have moved by its safe radius since its last search (budgets along
//! the path of `y`, [`ReducedModel`]'s `linearize_with`); a later round of the vertex-zone rule
//! resumes from the previous round's answer.
//!
//! **Paper** ([`Algorithm::Paper`], Algorithm 1). Start from the single reduced constraint most
//! violated at `û = 0` (the paper draws one at random; a fixed choice makes runs reproducible).
//! Solve eq. 13; drop constraints with `λ̂_i < 0`, add those with reduced gap `< 0`,
//! re-linearise every iteration (Type-2). Stop when the active set and the pairing do not change
//! and `û` stopped moving — converged; when an active set repeats — cycled; or at `max_iter`.
//!
//! **Error indicator** ([`ReducedModel::indicator`]). From the reduced solution alone, over
//! every potential-contact node: largest penetration, force-weighted mean `|gap|` under the
//! reduced pressure (complementarity), the share of force on unpaired nodes, and the relative
//! energy-norm equilibrium residual `||Phi û - K^{-1} F(p̂)||_K / ||Phi û||_K` evaluated with the
//! contact-dof compliance `W_c = E_c^T K^{-1} E_c`:
//! `|y - Psi_c^T F_c|^2 + (F_c^T W_c F_c - |Psi_c^T F_c|^2)` in the coordinates above.

mod curvature;
mod error;
mod la;
mod qp;
mod reduced;
#[cfg(test)]
pub(crate) use reduced::test_support;
mod saddle;
pub mod sampling;
pub mod translates;
pub mod working_set;

pub use crate::full_order::{Compliance, ContactOperator, Linearized, Surface};
pub use error::PrimalErrors;
pub use la::Factor;
pub use qp::{solve_qp, DenseConstraints, QpConstraints, QpOutcome, QpWork};
pub use reduced::{
    cone_basis_columns, Algorithm, Indicator, ModelParts, QueryModel, ReducedModel, ReducedSolution, RomError,
    RomOutcome, RomParams, RomWork, SolveInfo, EXACT_STEP_ITERATIONS, MAX_EXACT_STEP, SAMPLING_DIRECTIONS,
    WARM_START_SAMPLES,
};
pub use saddle::solve_saddle;
