//! Non-negative least squares and projection onto a finitely generated cone.
//!
//! # The cone projection (paper eq. 12)
//!
//! For a cone basis `Theta` (n x k, one generator per column) the projection of `lambda` onto
//! `cone(Theta) = { Theta gamma : gamma >= 0 }` (eq. 10) is `Pi(lambda) = Theta alpha` with
//!
//! ```text
//! alpha = argmin_{gamma >= 0} || lambda - Theta gamma ||_2 ,
//! ```
//!
//! a non-negative least-squares (NNLS) problem `min ||A x - b||, x >= 0` with `A = Theta`,
//! `b = lambda`. It is convex; `x` is a minimiser iff, with the dual vector
//! `w = A^T (b - A x) = A^T b - G x` (`G = A^T A`), the KKT conditions hold:
//!
//! ```text
//! x >= 0,        w_j = 0  for j in P = { j : x_j > 0 }  (passive set),
//!                w_j <= 0 for j in Z = { j : x_j = 0 }  (zero / active set).
//! ```
//!
//! The residual norm `||b - A x||` is unique even when the columns are dependent (then `x` is
//! not); the projection `A x` is unique too (projection onto a closed convex set), hence
//! `Pi` is idempotent and non-expansive: `||Pi(a) - Pi(b)|| <= ||a - b||`.
//!
//! # Algorithms
//!
//! * [`Nnls`] (`nnls.rs`): Lawson–Hanson active set on `G` and `A^T b`, with the Cholesky factor
//!   of `G[P, P]` updated when a column enters (one appended row) or leaves (Givens
//!   rotations); columns numerically dependent on the passive set are refused. Used by the CPG
//!   basis (Sec. 2.3.1), the cone compactness (eq. 16), generalization (eq. 17) and the online
//!   solve.
//! * [`nnls_reference`] (`reference.rs`): textbook Lawson–Hanson with every passive problem
//!   solved from scratch by a truncated SVD; for cross-checks only.
//! * [`ConeProjector`] / [`GrowingCone`] (`projector.rs`): eq. 12 for one basis and many
//!   vectors, and for a basis growing one generator at a time.

mod nnls;
mod passive_factor;
mod projector;
mod reference;
mod wide;
mod windows;

pub use nnls::{nnls, ConeError, Nnls, NnlsParams, NnlsSolution, NnlsStats};
pub use projector::{ConeProjection, ConeProjector, GrowingCone, IN_CONE_REL_TOL};
pub use reference::nnls_reference;
pub use wide::WideNnls;
pub use windows::ColumnIndex;

pub(crate) use nnls::norm2;
pub(crate) use projector::{coefficient_intervals, copy_column};
