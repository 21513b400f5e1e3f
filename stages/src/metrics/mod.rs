//! Validation metrics of reduced bases (paper Sec. 4, after Stegmann & Gomez 2002).
//!
//! * Compactness `C(m) = ||S - Pi_{Psi[:m]}(S)||_F / ||S||_F` (eq. 16), for an orthogonal
//!   projection on POD modes or a cone projection (eq. 12) on CPG generators.
//! * Per-snapshot relative projection errors `||s - Pi(s)|| / ||s||` (the summands of the
//!   generalization G(m), eq. 17, and of the specificity S(m), eq. 18); a snapshot with zero
//!   norm has no relative error (`None`), it is reported, never divided by.
//! * Generalization by leave-one-out (eq. 17):
//!   `G(m) = 1/N sum_i ||s_i - Pi_{Psi(S \ s_i)[:m]}(s_i)|| / ||s_i||`, the basis rebuilt
//!   without `s_i` (POD at numerical rank, or CPG at tolerance 0 in selection order); a fold
//!   whose basis has fewer than m vectors uses all of them (`Psi[:m]` slicing).
//! * Specificity (eq. 18): `S(m) = 1/N_s sum_i min_j ||s_j - Psi[:, :m] alpha_i|| / ||s_j||`,
//!   `alpha_i` uniform in `mu +- sigma` of the training snapshots' reduced coordinates (POD
//!   coordinates, or NNLS coefficients on the first m generators with the interval clipped
//!   at 0), one random stream per m.
//! * Nested error (eq. 19): `H(n) = ||S^{n+1} - Pi_{S^n}(S^{n+1})||_F / ||S^{n+1}||_F`, the
//!   projection onto the span or the cone of the coarser level's snapshots.
//!
//! G and S are [`MetricCurve`]s: mean, population standard deviation and count for
//! m = 1..=M, with zero-norm snapshots counted in `n_zero` instead of divided by.

mod compactness;
mod downdate;
mod generalization;
mod nested;
pub mod order;
mod specificity;
mod stats;

pub use compactness::{
    compactness_cone, compactness_cone_with, compactness_orth, compactness_orth_modal, relative_errors_orth,
};
pub use downdate::ColumnDowndate;
pub use generalization::{
    combine_folds, generalization_cone, generalization_cone_reference, generalization_orth, loo_fold_cone,
    loo_fold_cone_reference, loo_fold_orth, FoldMethod, LooFold, LooOrth, LooOrthWorkspace,
};
pub use nested::{nested_error_cone, nested_error_orth};
pub use specificity::{
    cone_ranges_reference, specificity_cone, specificity_cone_path, specificity_orth, specificity_orth_modal,
    SpecificityParams,
};

pub use specificity::stream as specificity_stream;
pub use stats::{mean_interval95, on_rank_grid, MetricCurve, RunningStats};
