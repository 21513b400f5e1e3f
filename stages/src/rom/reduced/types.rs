//! The public settings and results of an online query, and why a model could not be built.

/// Which online iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Algorithm {
    /// Exact QP per linearisation (dual active set, finite termination) inside an outer
    /// re-pairing loop.
    Exact,
    /// The paper's Algorithm 1: one saddle solve per iteration, drop `λ̂ < 0`, add violated
    /// reduced gaps, re-linearise every iteration.
    Paper,
}

impl Algorithm {
    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Exact => "exact",
            Algorithm::Paper => "paper",
        }
    }
}

/// Settings of the online solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RomParams {
    /// The iteration.
    pub algorithm: Algorithm,
    /// Cap on linearisations (exact) or iterations (paper); default 100.
    pub max_iter: usize,
    /// A reduced constraint counts as violated when `ŝ < -gap_tol * scale`, `scale` the largest
    /// `|ĝ0|` at the first linearisation (default 1e-12: rounding of the projections).
    pub gap_tol: f64,
    /// Type-2: converged once the pairing repeats and the distance of `û` to the fixed point of
    /// the re-linearisation, estimated from the last two steps, is `<= u_tol |û|` (default
    /// 1e-10, the full-order solver's tolerance; the paper algorithm uses the last step alone).
    pub u_tol: f64,
    /// Type-2, exact algorithm: Krylov iterations of the Newton-corrected re-pairing step
    /// (GMRES on `(I + P H P) z = P H d`, [`super::exact_step`]); 0 (the default) takes the
    /// first-order step `z = P H d`. [`EXACT_STEP_ITERATIONS`] is what an enriched primal space
    /// uses.
    pub exact_step: usize,
}

/// The Krylov iterations of the exact corrected step where a model uses it (a primal space
/// with translated responses): measured on ironing-fine, two bring the linearisations from 6.3
/// to 4.3 and a third buys none (docs/design-notes.md#an-exact-corrected-step).
pub const EXACT_STEP_ITERATIONS: usize = 2;

impl Default for RomParams {
    fn default() -> Self {
        Self { algorithm: Algorithm::Exact, max_iter: 100, gap_tol: 1e-12, u_tol: 1e-10, exact_step: 0 }
    }
}

/// How an online query ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RomOutcome {
    /// A KKT point of the reduced problem (at its own linearisation).
    Converged,
    /// Refused: the reduced constraints cannot all be satisfied by `u0 + Phi û` (the primal
    /// basis is too small for the dual one at this parameter), detected by the exact QP.
    Infeasible,
    /// An earlier discrete state came back: the active set (paper algorithm) or the pairing
    /// (exact algorithm, after a change of pairing) cycles.
    Cycled,
    /// The iteration cap was reached.
    NotConverged,
}

impl RomOutcome {
    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            RomOutcome::Converged => "converged",
            RomOutcome::Infeasible => "infeasible",
            RomOutcome::Cycled => "cycled",
            RomOutcome::NotConverged => "not_converged",
        }
    }
}

/// Result of one online query (reduced coordinates only).
#[derive(Debug, Clone, PartialEq)]
pub struct ReducedSolution {
    /// Reduced displacement coordinates.
    pub u_hat: Vec<f64>,
    /// Reduced dual coordinates (`>= 0`).
    pub lambda_hat: Vec<f64>,
    /// QP steps (exact) or Algorithm 1 iterations (paper).
    pub iterations: usize,
    /// Linearisations (pairings) computed.
    pub linearizations: usize,
    /// Active reduced constraints at the end.
    pub active: usize,
    /// Reduced dual dofs with `λ̂_i > 1e-9 max λ̂` (the paper's "active dofs of λ̂").
    pub nonzero_dual: usize,
    /// How it ended.
    pub outcome: RomOutcome,
}

/// What [`ReducedModel::solve_in`](super::ReducedModel::solve_in) returns (the coordinates stay
/// in the work buffers).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SolveInfo {
    /// QP steps (exact) or Algorithm 1 iterations (paper).
    pub iterations: usize,
    /// Linearisations (pairings) computed.
    pub linearizations: usize,
    /// Active reduced constraints at the end.
    pub active: usize,
    /// How it ended.
    pub outcome: RomOutcome,
}

/// Why a [`ReducedModel`](super::ReducedModel) could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RomError {
    /// `Phi^T K Phi` is not positive definite.
    #[error("the reduced stiffness Phi^T K Phi is not positive definite (rank-deficient or non-lifted primal basis)")]
    SingularStiffness,
    /// The reduced quadrature's NNLS failed.
    #[error("the reduced quadrature of the contact constraints failed: {0}")]
    Sampling(String),
    /// Stored parts ([`ModelParts`](super::ModelParts)) that do not make a model: the array
    /// and what is wrong with it.
    #[error("the stored reduced model is not consistent: {0}")]
    Parts(String),
}
