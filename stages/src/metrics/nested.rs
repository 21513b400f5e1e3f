//! Nested error (paper eq. 19): with level-n training snapshots `S^n` (`2^n + 1` equidistant
//! parameter points) a subset of level n + 1,
//!
//! ```text
//! H(n) = ||S^{n+1} - Pi_{S^n}(S^{n+1})||_F / ||S^{n+1}||_F ,
//! ```
//!
//! the part of the finer level that the coarser level cannot represent:
//!
//! * orthogonal: `Pi` projects each column onto `span(S^n)`, through the POD modes of `S^n` at
//!   its numerical rank ([`pod_full`]); the residual is formed explicitly, so H reaches
//!   round-off when the new snapshots are in the span;
//! * cone: `Pi` is the cone projection (eq. 12) onto `cone(S^n)`, the non-negative
//!   combinations of the level-n snapshots; the generators are the non-zero columns of `S^n`
//!   scaled to unit norm (zero columns add nothing to a cone), and `||S^{n+1} - Pi||_F` is the
//!   root sum of squares of the per-column residual norms.
//!
//! An all-zero `S^{n+1}` (no contact at any point) has nothing to represent: H = 0. An all-zero
//! `S^n` with a non-zero `S^{n+1}` gives H = 1 (both projections are 0).

use faer::{Mat, MatRef};

use crate::basis::{pod_full, PodError};
use crate::cone::{ConeError, ConeProjector, NnlsParams};

/// H(n) with the orthogonal projection onto `span(lower)`; `lower` is n x N_n, `upper` is
/// n x N_{n+1} (the same field on the finer level).
pub fn nested_error_orth(lower: MatRef<'_, f64>, upper: MatRef<'_, f64>) -> Result<f64, PodError> {
    assert_eq!(lower.nrows(), upper.nrows(), "nested_error_orth: levels have different rows");
    let modes = pod_full(lower)?.modes;
    let total = upper.norm_l2();
    if total <= 0.0 {
        return Ok(0.0);
    }
    let coords: Mat<f64> = modes.transpose() * upper;
    let residual = crate::kernels::out_of_span(upper, modes.as_ref(), coords.as_ref());
    Ok(residual.norm_l2() / total)
}

/// H(n) with the projection onto `cone(lower)`; shapes as in [`nested_error_orth`].
pub fn nested_error_cone(lower: MatRef<'_, f64>, upper: MatRef<'_, f64>, nnls: NnlsParams) -> Result<f64, ConeError> {
    assert_eq!(lower.nrows(), upper.nrows(), "nested_error_cone: levels have different rows");
    let total = upper.norm_l2();
    if total <= 0.0 {
        return Ok(0.0);
    }
    let norms: Vec<(usize, f64)> =
        (0..lower.ncols()).map(|j| (j, lower.col(j).norm_l2())).filter(|(_, norm)| *norm > 0.0).collect();
    if norms.is_empty() {
        return Ok(1.0);
    }
    let theta = Mat::from_fn(lower.nrows(), norms.len(), |i, c| lower[(i, norms[c].0)] / norms[c].1);
    let (_, residuals) = ConeProjector::new(theta.as_ref(), nnls).project_many(upper)?;
    Ok(residuals.iter().map(|r| r * r).sum::<f64>().sqrt() / total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;

    /// Level n: 5 non-negative random fields in R^20; level n + 1 interleaves them with the
    /// midpoints (s_k + s_{k+1}) / 2, as a parameter-linear field would on a nested grid.
    fn levels(rng: &mut Rng) -> (Mat<f64>, Mat<f64>) {
        let lower = Mat::from_fn(20, 5, |_, _| rng.uniform_in(0.0, 1.0));
        let upper = Mat::from_fn(20, 9, |i, c| {
            if c % 2 == 0 {
                lower[(i, c / 2)]
            } else {
                0.5 * (lower[(i, c / 2)] + lower[(i, c / 2 + 1)])
            }
        });
        (lower, upper)
    }

    #[test]
    fn midpoints_add_nothing() {
        let (lower, upper) = levels(&mut Rng::new(91));
        let orth = nested_error_orth(lower.as_ref(), upper.as_ref()).expect("svd");
        let cone = nested_error_cone(lower.as_ref(), upper.as_ref(), NnlsParams::default()).expect("ok");
        // Every column is in the span (1e-12: SVD round-off on O(1) data) and in the cone (the
        // average of two generators; 1e-10: NNLS on a Gram matrix).
        assert_close!(orth, 0.0, Tol::abs(1e-12));
        assert_close!(cone, 0.0, Tol::abs(1e-10));
    }

    #[test]
    fn new_directions_give_the_known_value() {
        // Level n: e0, e1 (and a zero column, which must be ignored). Level n + 1 adds
        //   (e0 + e1)/2      in span and cone,
        //   e0 - e1          in span, cone projection e0: residual 1 (cone only),
        //   2 e2             orthogonal to both: residual 2.
        // ||S^{n+1}||_F^2 = 1 + 1 + 1/2 + 2 + 4 = 8.5, so H_orth = 2/sqrt(8.5) and
        // H_cone = sqrt(1 + 4)/sqrt(8.5). Embedded by a random orthonormal Q (10 x 3): both
        // projections commute with isometries, so the values are unchanged.
        let mut rng = Rng::new(92);
        let q = Mat::from_fn(10, 3, |_, _| rng.uniform_in(-1.0, 1.0)).qr().compute_thin_Q();
        let lower3 = Mat::from_fn(3, 3, |i, j| if i == j && j < 2 { 1.0 } else { 0.0 });
        let cols: [[f64; 3]; 5] =
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 2.0]];
        let upper3 = Mat::from_fn(3, 5, |i, j| cols[j][i]);
        let (lower, upper) = (&q * &lower3, &q * &upper3);
        let orth = nested_error_orth(lower.as_ref(), upper.as_ref()).expect("svd");
        let cone = nested_error_cone(lower.as_ref(), upper.as_ref(), NnlsParams::default()).expect("ok");
        // Exact values up to the round-off of Q (orthonormal to ~1e-15): 1e-12.
        assert_close!(orth, 2.0 / 8.5f64.sqrt(), Tol::abs(1e-12));
        assert_close!(cone, 5f64.sqrt() / 8.5f64.sqrt(), Tol::abs(1e-12));
    }

    #[test]
    fn zero_levels() {
        let (lower, _) = levels(&mut Rng::new(93));
        let zero = Mat::<f64>::zeros(20, 9);
        assert_close!(nested_error_orth(lower.as_ref(), zero.as_ref()).expect("svd"), 0.0, Tol::abs(0.0));
        let cone = nested_error_cone(lower.as_ref(), zero.as_ref(), NnlsParams::default()).expect("ok");
        assert_close!(cone, 0.0, Tol::abs(0.0));
        let nothing = Mat::<f64>::zeros(20, 5);
        assert_close!(nested_error_orth(nothing.as_ref(), lower.as_ref()).expect("svd"), 1.0, Tol::abs(1e-15));
        let cone = nested_error_cone(nothing.as_ref(), lower.as_ref(), NnlsParams::default()).expect("ok");
        assert_close!(cone, 1.0, Tol::abs(0.0));
    }
}
