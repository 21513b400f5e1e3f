//! Compactness (paper eq. 16): `C(m) = ||S - Pi_{Psi[:m]}(S)||_F / ||S||_F` for m = 0..=M,
//! with `Pi` the orthogonal projection onto the span of the first m orthonormal modes
//! ("primal orth", "dual orth") or the projection onto the cone of the first m generators
//! ("dual cone", eq. 12). An all-zero S gives all zeros (nothing to compress).
//!
//! For orthonormal modes, with `Q = Psi^T S` and the out-of-span part `S_perp = S - Psi Q`,
//! `||S - Psi_m Psi_m^T S||_F^2 = ||S_perp||_F^2 + sum_{i>m} ||Q_{i,:}||^2`: a sum of
//! non-negative terms, accumulated from the last mode up, so there is no cancellation and C
//! reaches round-off level at full rank.

use faer::{Mat, MatRef};

use crate::cone::{copy_column, norm2, ConeError, GrowingCone, NnlsParams};

/// `C(m)` for m = 0..=M for orthonormal `modes` (n x M); `s` is n x N.
pub fn compactness_orth(s: MatRef<'_, f64>, modes: MatRef<'_, f64>) -> Vec<f64> {
    assert_eq!(s.nrows(), modes.nrows(), "compactness_orth: S and modes have different rows");
    let total = s.norm_l2();
    let m_max = modes.ncols();
    if total <= 0.0 {
        return vec![0.0; m_max + 1];
    }
    let q: Mat<f64> = modes.transpose() * s;
    // Up to DENSE_CURVE_MAX snapshots the whole residual's norm (the paper's numbers); above,
    // the sum of its columns' squared norms in index order, formed blockwise (memory n x
    // SPAN_BLOCK, not n x N; the same value to round-off).
    let perp2 = if s.ncols() <= crate::basis::DENSE_CURVE_MAX {
        crate::kernels::out_of_span(s, modes, q.as_ref()).squared_norm_l2()
    } else {
        crate::kernels::out_of_span_norms(s, modes, q.as_ref()).iter().sum()
    };
    curve_from_coordinates(q.as_ref(), perp2, total)
}

/// [`compactness_orth`] from one [`modal_pass`](crate::blocks::modal_pass) over snapshots read
/// block by block: `||S||_F` and `||S_perp||_F^2` summed from the columns' numbers in column
/// order (the form [`compactness_orth`] uses above `DENSE_CURVE_MAX` snapshots).
pub fn compactness_orth_modal(modal: &crate::blocks::ModalCoordinates) -> Vec<f64> {
    let total = crate::blocks::frobenius(&modal.norm2);
    if total <= 0.0 {
        return vec![0.0; modal.coords.nrows() + 1];
    }
    curve_from_coordinates(modal.coords.as_ref(), modal.perp.iter().sum(), total)
}

/// `C(m) = sqrt(||S_perp||_F^2 + sum_{i>m} ||Q_i||^2) / ||S||_F`, the tail summed from the last
/// mode up.
fn curve_from_coordinates(q: MatRef<'_, f64>, perp2: f64, total: f64) -> Vec<f64> {
    let m_max = q.nrows();
    let mut c = vec![0.0; m_max + 1];
    let mut tail = 0.0;
    for m in (1..=m_max).rev() {
        c[m] = (perp2 + tail).sqrt() / total;
        tail += q.row(m - 1).squared_norm_l2();
    }
    c[0] = 1.0;
    c
}

/// `C(m)` for m = 0..=k using the first m columns of `cone_basis` (n x k) as cone generators,
/// with default [`NnlsParams`].
pub fn compactness_cone(s: MatRef<'_, f64>, cone_basis: MatRef<'_, f64>) -> Result<Vec<f64>, ConeError> {
    compactness_cone_with(s, cone_basis, NnlsParams::default())
}

/// [`compactness_cone`] with explicit NNLS parameters.
pub fn compactness_cone_with(
    s: MatRef<'_, f64>,
    cone_basis: MatRef<'_, f64>,
    params: NnlsParams,
) -> Result<Vec<f64>, ConeError> {
    assert_eq!(s.nrows(), cone_basis.nrows(), "compactness_cone: S and basis rows differ");
    let total = s.norm_l2();
    let k = cone_basis.ncols();
    if total <= 0.0 {
        return Ok(vec![0.0; k + 1]);
    }
    let mut cone = GrowingCone::new(s, params);
    let mut c = Vec::with_capacity(k + 1);
    c.push(1.0);
    let mut column = vec![0.0; s.nrows()];
    for m in 0..k {
        copy_column(cone_basis, m, &mut column);
        cone.push(&column)?;
        c.push(cone.frobenius_residual() / total);
    }
    Ok(c)
}

/// Relative orthogonal projection error of each snapshot on orthonormal `modes` (n x m):
/// `||s_j - Psi Psi^T s_j|| / ||s_j||` from the explicit residual; `None` for a zero snapshot.
pub fn relative_errors_orth(s: MatRef<'_, f64>, modes: MatRef<'_, f64>) -> Vec<Option<f64>> {
    assert_eq!(s.nrows(), modes.nrows(), "relative_errors_orth: S and modes rows differ");
    let q: Mat<f64> = modes.transpose() * s;
    let perp = crate::kernels::out_of_span(s, modes, q.as_ref());
    let mut column = vec![0.0; s.nrows()];
    (0..s.ncols())
        .map(|j| {
            copy_column(s, j, &mut column);
            let norm = norm2(&column);
            (norm > 0.0).then(|| perp.col(j).norm_l2() / norm)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{cpg, pod_full, tail_energies, CpgParams};
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::{assert_all_close, assert_close};

    fn random_mat(rng: &mut Rng, n: usize, k: usize, lo: f64, hi: f64) -> Mat<f64> {
        Mat::from_fn(n, k, |_, _| rng.uniform_in(lo, hi))
    }

    #[test]
    fn orth_compactness_equals_the_singular_value_tail() {
        let mut rng = Rng::new(61);
        // Rank 6 plus a small full-rank perturbation: a spread of singular values.
        let low = random_mat(&mut rng, 40, 6, -1.0, 1.0) * random_mat(&mut rng, 6, 20, -1.0, 1.0);
        let s = low + random_mat(&mut rng, 40, 20, -1e-3, 1e-3);
        let pod = pod_full(s.as_ref()).expect("svd");
        let c = compactness_orth(s.as_ref(), pod.modes.as_ref());
        let tails = tail_energies(&pod.singular_values);
        let total = tails[0].sqrt();
        let expected: Vec<f64> = (0..=pod.modes.ncols()).map(|m| tails[m].sqrt() / total).collect();
        // Two independent formulas (projection residual vs singular values): both exact to
        // ~n eps; 1e-10 absolute (C is relative to ||S||) as required.
        assert_all_close!(c, expected, Tol::abs(1e-10));
        assert_close!(c[pod.modes.ncols()], 0.0, Tol::abs(1e-13)); // full rank: round-off
    }

    #[test]
    fn orth_compactness_of_zero_snapshots_is_zero() {
        let modes = Mat::<f64>::identity(4, 2);
        let c = compactness_orth(Mat::<f64>::zeros(4, 3).as_ref(), modes.as_ref());
        assert_all_close!(c, [0.0; 3], Tol::abs(0.0));
    }

    #[test]
    fn orth_compactness_by_hand() {
        // S = [[3, 0], [0, 0], [4, 0]], modes e_0, e_2: C = [1, 4/5, 0].
        let s = Mat::from_fn(3, 2, |i, j| match (i, j) {
            (0, 0) => 3.0,
            (2, 0) => 4.0,
            _ => 0.0,
        });
        let modes = Mat::from_fn(3, 2, |i, j| if (i, j) == (0, 0) || (i, j) == (2, 1) { 1.0 } else { 0.0 });
        let c = compactness_orth(s.as_ref(), modes.as_ref());
        assert_all_close!(c, [1.0, 0.8, 0.0], Tol::abs(1e-15)); // one sqrt and one division
    }

    #[test]
    fn cone_compactness_matches_cpg() {
        let mut rng = Rng::new(62);
        let s = random_mat(&mut rng, 30, 15, 0.0, 1.0);
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        let c = compactness_cone(s.as_ref(), out.basis.as_ref()).expect("converges");
        // Same projections through the same incremental path: 1e-12.
        assert_all_close!(c, out.compactness, Tol::abs(1e-12));
        assert_close!(*c.last().expect("nonempty"), 0.0, Tol::abs(1e-10)); // tol 0: all in cone
    }

    #[test]
    fn cone_compactness_by_hand() {
        // Generators e_0 and e_1 in R^2; snapshot (-1, 2): projections (0, 0) then (0, 2).
        // C = [1, 1, 1/sqrt(5)] (the first generator does not help a negative component).
        let s = Mat::from_fn(2, 1, |i, _| if i == 0 { -1.0 } else { 2.0 });
        let basis = Mat::<f64>::identity(2, 2);
        let c = compactness_cone(s.as_ref(), basis.as_ref()).expect("converges");
        assert_all_close!(c, [1.0, 1.0, 1.0 / 5f64.sqrt()], Tol::abs(1e-15));
        let zero = compactness_cone(Mat::<f64>::zeros(2, 3).as_ref(), basis.as_ref());
        assert_all_close!(zero.expect("trivial"), [0.0; 3], Tol::abs(0.0));
    }

    #[test]
    fn relative_errors_orth_per_snapshot() {
        // Mode e_0 in R^3; snapshots (1, 0, 0), (3, 4, 0), 0.
        let s = Mat::from_fn(3, 3, |i, j| match (i, j) {
            (0, 0) => 1.0,
            (0, 1) => 3.0,
            (1, 1) => 4.0,
            _ => 0.0,
        });
        let modes = Mat::<f64>::identity(3, 1);
        let e = relative_errors_orth(s.as_ref(), modes.as_ref());
        assert_eq!(e.len(), 3);
        assert_close!(e[0].expect("nonzero"), 0.0, Tol::abs(1e-15));
        assert_close!(e[1].expect("nonzero"), 0.8, Tol::abs(1e-15)); // 4 / 5
        assert!(e[2].is_none(), "zero snapshot has no relative error");
    }
}
