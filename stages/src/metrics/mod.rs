//! Validation metrics of reduced bases (paper Sec. 4, after Stegmann & Gomez 2002).
//!
//! * Compactness `C(m) = ||S - Pi_{Psi[:m]}(S)||_F / ||S||_F` (eq. 16), for an orthogonal
//!   projection on POD modes or a cone projection (eq. 12) on CPG generators.
//! * Per-snapshot relative projection errors `||s - Pi(s)|| / ||s||` (the summands of the
//!   generalization G(m), eq. 17, and of the specificity S(m), eq. 18); a snapshot with zero
//!   norm has no relative error (`None`), it is reported, never divided by.

mod compactness;

pub use compactness::{compactness_cone, compactness_cone_with, compactness_orth, relative_errors_orth};
