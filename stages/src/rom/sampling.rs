//! A reduced quadrature of the contact constraints (hyper-reduction; beyond the paper).
//!
//! The Type-2 reduced constraints are sums over the paired supported slaves (eq. 11),
//!
//! ```text
//! ŝ_a(û) = sum_s w_s Theta_{s,a} g_s(û),        w_s the tributary length of slave s,
//! ```
//!
//! so every linearisation of an online query positions, pairs and assembles every supported
//! slave: work that follows the number of contact nodes, not the ranks (docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints). A
//! reduced quadrature keeps a subset `E` of the slaves with non-negative weights `xi_s`,
//!
//! ```text
//! ŝ_a(û) ≈ sum_{s in E} xi_s Theta_{s,a} g_s(û),
//! ```
//!
//! chosen, as in the energy-conserving sampling and weighting of Farhat, Avery, Chapman and
//! Cortial (IJNME 98, 2014), so that the quadrature reproduces the full sums on training
//! states: the values `ŝ_a` and their derivatives along a few fixed directions of `û` (a sketch
//! of `Ĉ`). [`greedy_nnls`] is the selection: a non-negative least-squares fit grown one
//! column at a time (the column most correlated with the residual, then the NNLS on the
//! chosen ones), stopped at a relative residual `tol`. It changes the answers — the constraints
//! are enforced in the quadrature's average, not the exact one — so it is an option of the
//! reduced model ([`crate::rom::ReducedModel::with_sampled_surface`]), measured against the
//! exact reduced solve, never a silent default.

use faer::MatRef;

use crate::cone::{ConeError, ConeProjector, NnlsParams};

/// The outcome of [`greedy_nnls`]: chosen columns, their non-negative weights and the relative
/// residual `||A x - b|| / ||b||` reached.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Chosen columns, in the order they entered (only those with a positive weight).
    pub columns: Vec<usize>,
    /// Their weights (> 0).
    pub weights: Vec<f64>,
    /// `||A x - b|| / ||b||` (0 for `b = 0`).
    pub residual: f64,
}

/// Sparse non-negative least squares `min ||A x - b||, x >= 0`, grown greedily: while the
/// relative residual exceeds `tol` and fewer than `max_columns` are chosen, add the column
/// with the largest positive correlation `a_j . r / |a_j|` with the residual `r`, and solve the
/// NNLS on the chosen columns (the cone projection of `b`, [`ConeProjector`]). Stops early when
/// no column correlates positively (the NNLS optimum over all columns is reached).
pub fn greedy_nnls(a: MatRef<'_, f64>, b: &[f64], tol: f64, max_columns: usize) -> Result<Selection, ConeError> {
    let (rows, n) = a.shape();
    assert_eq!(b.len(), rows, "greedy_nnls: b has the wrong length");
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let bnorm = norm(b);
    if bnorm == 0.0 || n == 0 {
        return Ok(Selection { columns: Vec::new(), weights: Vec::new(), residual: 0.0 });
    }
    let col_norms: Vec<f64> = (0..n).map(|j| a.col(j).norm_l2()).collect();
    let mut projector = ConeProjector::empty(rows, NnlsParams::default());
    let (mut chosen, mut taken) = (Vec::new(), vec![false; n]);
    let mut coeffs: Vec<f64> = Vec::new();
    let mut residual = b.to_vec();
    let mut rnorm = bnorm;
    let mut column = vec![0.0; rows];
    while rnorm > tol * bnorm && chosen.len() < max_columns {
        let mut best = (0.0, usize::MAX);
        for j in (0..n).filter(|&j| !taken[j] && col_norms[j] > 0.0) {
            let c: f64 = a.col(j).iter().zip(&residual).map(|(x, r)| x * r).sum::<f64>() / col_norms[j];
            if c > best.0 {
                best = (c, j);
            }
        }
        let j = best.1;
        if j == usize::MAX {
            break;
        }
        taken[j] = true;
        column.iter_mut().zip(a.col(j).iter()).for_each(|(o, v)| *o = *v);
        projector.push_column(&column);
        chosen.push(j);
        coeffs.push(0.0);
        rnorm = projector.project_warm(b, &mut coeffs)?;
        residual.copy_from_slice(b);
        for (&c, &k) in coeffs.iter().zip(&chosen) {
            if c != 0.0 {
                residual.iter_mut().zip(a.col(k).iter()).for_each(|(r, v)| *r -= c * v);
            }
        }
    }
    let (columns, weights) = chosen.iter().zip(&coeffs).filter(|(_, &c)| c > 0.0).map(|(&j, &c)| (j, c)).unzip();
    Ok(Selection { columns, weights, residual: rnorm / bnorm })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::cone::nnls;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use faer::Mat;

    #[test]
    fn a_sparse_combination_is_recovered_exactly() {
        // b = 2 a_3 + 0.5 a_7 with random non-negative columns: the greedy picks 3 and 7 (the
        // others are not needed) and the weights to round-off.
        let mut rng = Rng::new(3);
        let a = Mat::from_fn(40, 12, |_, _| rng.uniform_in(0.0, 1.0));
        let b: Vec<f64> = (0..40).map(|r| 2.0 * a[(r, 3)] + 0.5 * a[(r, 7)]).collect();
        let s = greedy_nnls(a.as_ref(), &b, 1e-12, 12).expect("nnls");
        let mut pairs: Vec<(usize, f64)> = s.columns.iter().copied().zip(s.weights.iter().copied()).collect();
        pairs.sort_by_key(|p| p.0);
        assert_eq!(pairs.iter().map(|p| p.0).collect::<Vec<_>>(), vec![3, 7], "{s:?}");
        // NNLS on two O(1) columns: 1e-10 on O(1) weights.
        assert_close!(pairs[0].1, 2.0, Tol::abs(1e-10));
        assert_close!(pairs[1].1, 0.5, Tol::abs(1e-10));
        assert!(s.residual <= 1e-12);
    }

    #[test]
    fn without_a_tolerance_it_reaches_the_nnls_optimum() {
        // An inconsistent b: the greedy run to the end reaches the residual of the full NNLS
        // (the reference solver), and every weight is non-negative.
        let mut rng = Rng::new(4);
        let a = Mat::from_fn(30, 8, |_, _| rng.uniform_in(-1.0, 1.0));
        let b: Vec<f64> = (0..30).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let s = greedy_nnls(a.as_ref(), &b, 0.0, 8).expect("nnls");
        let full = nnls(a.as_ref(), &b, NnlsParams::default()).expect("nnls");
        let bnorm = b.iter().map(|x| x * x).sum::<f64>().sqrt();
        // Two NNLS solvers on an O(1) problem: 1e-9 on the relative residual.
        assert_close!(s.residual, full.residual_norm / bnorm, Tol::abs(1e-9));
        assert!(s.weights.iter().all(|&w| w > 0.0));
    }

    #[test]
    fn it_stops_at_the_tolerance_and_the_column_cap() {
        let mut rng = Rng::new(5);
        let a = Mat::from_fn(50, 40, |_, _| rng.uniform_in(0.0, 1.0));
        let b: Vec<f64> = (0..50).map(|r| (0..40).map(|j| a[(r, j)]).sum()).collect();
        let loose = greedy_nnls(a.as_ref(), &b, 1e-1, 40).expect("nnls");
        assert!(loose.residual <= 1e-1 && loose.columns.len() < 40, "{} columns", loose.columns.len());
        let capped = greedy_nnls(a.as_ref(), &b, 0.0, 3).expect("nnls");
        assert!(capped.columns.len() <= 3);
    }
}
