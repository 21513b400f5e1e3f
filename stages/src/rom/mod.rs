//! The online reduced solve (paper Sec. 2.3.2, Algorithm 1, eqs. 11 and 13).
//!
//! **Lifting.** The full displacement is written `u = u0(mu) + Phi û`, where `u0(mu)` is the
//! contact-free solution at `mu` (Dirichlet data and loads included; for every scene of crom it
//! is affine in `mu` and costs nothing online) and `Phi` (`n_dof x r_u`) is the POD of the
//! *contact responses* `u_k - u0(mu_k)` of the training snapshots, which vanish on the Dirichlet
//! dofs. Equilibrium then reads `K Phi û = Phi^T C^T W Theta λ̂` with no load term: the loads are
//! balanced by `u0`. (The paper leaves the treatment of the parameter-dependent Dirichlet data
//! open; lifting makes the reduced space exact on it.)
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
//! **Algorithm 1.** Start from a deterministic active set: the single reduced constraint that is
//! most violated at `û = 0` (the paper draws one at random; a fixed choice makes runs
//! reproducible). Solve eq. 13; drop constraints with `λ̂_i < 0`, add those with reduced gap
//! `< 0`; for Type-2 problems re-linearise `C`, `gap0` (pairing, normals) at `u0 + Phi û` every
//! iteration (step 5). Stop when the active set does not change (and, for Type-2, the pairing
//! is unchanged) — converged; when an active set repeats — cycled; or at `max_iter` — not
//! converged. Non-convergence is an outcome, never an error.

mod online;
mod operator;
mod saddle;

pub use online::{OnlineRom, RomOutcome, RomParams, RomSolution};
pub use operator::{ContactOperator, Linearized};
pub use saddle::solve_saddle;
