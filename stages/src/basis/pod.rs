//! Proper Orthogonal Decomposition (paper eq. 9): the left singular vectors of the snapshot
//! matrix, truncated by a relative Frobenius tolerance.
//!
//! With the thin SVD `S = U diag(s) V^T` (s descending) the best rank-m approximation error is
//! `||S - U_m U_m^T S||_F = sqrt(sum_{i>m} s_i^2)` (Eckart–Young), so the truncation rule
//! "smallest m with `sqrt(sum_{i>m} s_i^2) / sqrt(sum_i s_i^2) <= delta`" keeps exactly the
//! modes needed for a compactness C(m) (eq. 16) at most `delta`.

use faer::{Mat, MatRef};
use thiserror::Error;

use crate::blocks::{ColumnBlocks, ColumnNorms};

/// Parameters of [`pod`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PodParams {
    /// Relative Frobenius truncation tolerance `delta` of eq. 9 (default 0: keep the numerical
    /// rank, every mode with `s_i > max(n, N) eps s_max`).
    pub rel_tol: f64,
}

impl Default for PodParams {
    fn default() -> Self {
        Self { rel_tol: 0.0 }
    }
}

/// Numerical failure of [`pod`].
#[derive(Debug, Clone, Error)]
pub enum PodError {
    /// The SVD iteration did not converge.
    #[error("the SVD of the snapshot matrix did not converge")]
    SvdNoConvergence,
    /// The snapshot matrix contains NaN or infinity.
    #[error("the snapshot matrix contains a non-finite value (NaN or infinity)")]
    NonFinite,
    /// A block of snapshots could not be read.
    #[error("reading the snapshots: {0}")]
    Read(#[from] crate::blocks::BlockError),
}

/// A POD basis.
#[derive(Debug, Clone)]
pub struct Pod {
    /// Orthonormal modes, n x m (first m left singular vectors).
    pub modes: Mat<f64>,
    /// Every singular value of the snapshot matrix, descending (length min(n, N)).
    pub singular_values: Vec<f64>,
    /// Numerical rank (count of `s_i > max(n, N) eps s_max`); `m <= rank`.
    pub rank: usize,
}

/// Above this many snapshots (the SVD of an n x N matrix costs `O(min(n, N)^2 max(n, N))`),
/// [`pod`] goes through the blockwise
/// [`frame`](super::frame) `S ~ Q R` and the SVD of the small `R`: `O(n q N)` for a frame of q
/// columns. Up to it, the direct SVD (the paper's studies, bit for bit as before).
pub const POD_FRAME_ABOVE: usize = 1025;

/// The frame [`pod`] (and the orthogonal leave-one-out) of `s` goes through: above
/// [`POD_FRAME_ABOVE`] snapshots, when it has at most
/// [`frame_pays_up_to`](super::frame::frame_pays_up_to) columns (else `None`: the direct SVD
/// is as cheap). Measured: ironing-coarse level 12 (6 164 x 4 097, q = 192) 192 s → 48 s
/// offline; ironing-fine-2d on 65 x 17 points (11 800 x 1 105, rank 391) keeps the direct SVD.
pub fn pod_frame(s: MatRef<'_, f64>) -> Option<super::Frame> {
    (s.ncols() > POD_FRAME_ABOVE)
        .then(|| super::frame::frame_within(s, super::frame::frame_pays_up_to(s.ncols())))
        .flatten()
}

/// POD of the snapshots `s` (n x N, one snapshot per column). A zero (or empty) matrix gives
/// zero modes, zero singular values and rank 0. Where [`pod_frame`] gives one, through it: the singular values past the frame's size are reported as 0 (they are below
/// the frame's stored bound, itself below the numerical-rank cut; see `basis::frame`).
pub fn pod(s: MatRef<'_, f64>, params: PodParams) -> Result<Pod, PodError> {
    let (n, count) = (s.nrows(), s.ncols());
    if count <= POD_FRAME_ABOVE || (0..count).any(|j| s.col(j).iter().any(|v| !v.is_finite())) {
        return pod_direct(s, params);
    }
    let Some(f) = pod_frame(s) else { return pod_direct(s, params) };
    pod_of_frame(&f, n, count, params)
}

/// [`pod`] of snapshots read block by block (`src`, with `norms` from
/// [`column_norms`](crate::blocks::column_norms) of the same source): above
/// [`POD_FRAME_ABOVE`] snapshots through the frame, one block in memory at a time, with
/// `||S||_F` summed from the columns' norms; at or below it, or where the frame does not pay,
/// the whole matrix is read and [`pod`] runs on it.
pub fn pod_blocks(src: &dyn ColumnBlocks, norms: &ColumnNorms, params: PodParams) -> Result<Pod, PodError> {
    pod_blocks_framed(src, norms, super::frame::large_frame(src, norms)?.as_ref(), params)
}

/// [`pod_blocks`] with the set's [`large_frame`](super::large_frame) computed by the caller
/// (`frame` must be that function's answer for the same `src` and `norms`).
pub fn pod_blocks_framed(
    src: &dyn ColumnBlocks,
    norms: &ColumnNorms,
    frame: Option<&super::Frame>,
    params: PodParams,
) -> Result<Pod, PodError> {
    let (n, count) = (src.nrows(), src.ncols());
    if !norms.finite {
        return Err(PodError::NonFinite);
    }
    if count <= POD_FRAME_ABOVE {
        return pod(src.whole()?.as_ref(), params);
    }
    match frame {
        Some(f) => pod_of_frame(f, n, count, params),
        None => pod_direct(src.whole()?.as_ref(), params),
    }
}

/// The POD from a frame `S ~ Q R` of n x N snapshots: the SVD of the small R.
pub fn pod_of_frame(f: &super::Frame, n: usize, count: usize, params: PodParams) -> Result<Pod, PodError> {
    let len = n.min(count);
    if f.q.ncols() == 0 {
        return Ok(Pod { modes: Mat::zeros(n, 0), singular_values: vec![0.0; len], rank: 0 });
    }
    let svd = f.r.thin_svd().map_err(|_| PodError::SvdNoConvergence)?;
    let mut singular_values: Vec<f64> = svd.S().column_vector().iter().copied().collect();
    singular_values.resize(len, 0.0);
    let rank = numerical_rank(&singular_values, n, count);
    let m = truncation_rank(&singular_values, params.rel_tol).min(rank);
    let modes = &f.q * svd.U().subcols(0, m);
    Ok(Pod { modes, singular_values, rank })
}

/// [`pod`] by the direct thin SVD of `s`, at any size.
pub fn pod_direct(s: MatRef<'_, f64>, params: PodParams) -> Result<Pod, PodError> {
    let (n, count) = (s.nrows(), s.ncols());
    if (0..count).any(|j| s.col(j).iter().any(|v| !v.is_finite())) {
        return Err(PodError::NonFinite);
    }
    let len = n.min(count);
    if len == 0 || s.norm_l2() <= 0.0 {
        return Ok(Pod { modes: Mat::zeros(n, 0), singular_values: vec![0.0; len], rank: 0 });
    }
    let svd = s.thin_svd().map_err(|_| PodError::SvdNoConvergence)?;
    let singular_values: Vec<f64> = svd.S().column_vector().iter().copied().collect();
    let rank = numerical_rank(&singular_values, n, count);
    let m = truncation_rank(&singular_values, params.rel_tol).min(rank);
    let modes = svd.U().subcols(0, m).to_owned();
    Ok(Pod { modes, singular_values, rank })
}

/// POD keeping the numerical rank (no truncation).
pub fn pod_full(s: MatRef<'_, f64>) -> Result<Pod, PodError> {
    pod(s, PodParams::default())
}

/// Count of singular values (descending) above `max(nrows, ncols) eps s_max`.
pub fn numerical_rank(singular_values: &[f64], nrows: usize, ncols: usize) -> usize {
    let smax = singular_values.first().copied().unwrap_or(0.0);
    let cut = nrows.max(ncols) as f64 * f64::EPSILON * smax;
    singular_values.iter().take_while(|&&v| v > cut).count()
}

/// Smallest m with `sqrt(sum_{i>=m} s_i^2) / sqrt(sum_i s_i^2) <= rel_tol` (0-based: the tail
/// after keeping m values). The tails are accumulated from the smallest value up, so no
/// cancellation. All-zero values give 0.
pub fn truncation_rank(singular_values: &[f64], rel_tol: f64) -> usize {
    let tails = tail_energies(singular_values);
    let total = tails.first().copied().unwrap_or(0.0).sqrt();
    (0..=singular_values.len()).find(|&m| tails[m].sqrt() <= rel_tol * total).unwrap_or(singular_values.len())
}

/// `tails[m] = sum_{i>=m} s_i^2` for m = 0..=len (so `tails[len] = 0`).
pub fn tail_energies(values: &[f64]) -> Vec<f64> {
    let mut tails = vec![0.0; values.len() + 1];
    for i in (0..values.len()).rev() {
        tails[i] = tails[i + 1] + values[i] * values[i];
    }
    tails
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::{assert_all_close, assert_close};

    /// n x k matrix with orthonormal columns (thin Q of a random matrix).
    fn random_orthonormal(rng: &mut Rng, n: usize, k: usize) -> Mat<f64> {
        Mat::from_fn(n, k, |_, _| rng.uniform_in(-1.0, 1.0)).qr().compute_thin_Q()
    }

    /// S = U diag(s) V^T with random orthonormal U (n x r), V (N x r).
    fn with_singular_values(rng: &mut Rng, n: usize, count: usize, s: &[f64]) -> Mat<f64> {
        let u = random_orthonormal(rng, n, s.len());
        let v = random_orthonormal(rng, count, s.len());
        let us = Mat::from_fn(n, s.len(), |i, j| u[(i, j)] * s[j]);
        us * v.transpose()
    }

    #[test]
    fn modes_are_orthonormal_and_reconstruct_at_full_rank() {
        let mut rng = Rng::new(41);
        let s = Mat::from_fn(60, 15, |_, _| rng.uniform_in(-1.0, 1.0));
        let pod = pod_full(s.as_ref()).expect("svd");
        assert_eq!((pod.rank, pod.modes.ncols()), (15, 15));
        let gram = pod.modes.transpose() * &pod.modes;
        // Householder-based SVD: orthonormality to ~n eps; 1e-12 in the Frobenius norm.
        assert!((gram - Mat::<f64>::identity(15, 15)).norm_l2() <= 1e-12);
        let recon = &pod.modes * (pod.modes.transpose() * &s);
        // Full-rank reconstruction: 1e-12 relative to ||S||_F.
        assert!((recon - &s).norm_l2() <= 1e-12 * s.norm_l2());
        assert!(pod.singular_values.windows(2).all(|w| w[0] >= w[1]), "descending");
    }

    #[test]
    fn known_singular_values_are_recovered() {
        let mut rng = Rng::new(42);
        let sv = [10.0, 5.0, 1.0, 0.1, 0.01];
        let s = with_singular_values(&mut rng, 40, 12, &sv);
        let pod = pod_full(s.as_ref()).expect("svd");
        assert_eq!(pod.singular_values.len(), 12);
        assert_eq!(pod.rank, 5);
        // Backward-stable SVD: absolute error ~ eps s_max = 2e-15; 1e-13 with headroom.
        assert_all_close!(pod.singular_values[..5], sv, Tol::abs(1e-13));
        assert_all_close!(pod.singular_values[5..], [0.0; 7], Tol::abs(1e-13));
    }

    #[test]
    fn truncation_keeps_the_smallest_sufficient_m() {
        let mut rng = Rng::new(43);
        let sv = [10.0, 5.0, 1.0, 0.1, 0.01];
        let s = with_singular_values(&mut rng, 40, 12, &sv);
        let total = sv.iter().map(|v: &f64| v * v).sum::<f64>().sqrt();
        // tail(m) = sqrt(sum_{i>=m} s_i^2) / total, by hand.
        let tail = |m: usize| sv[m..].iter().map(|v| v * v).sum::<f64>().sqrt() / total;
        for m in 0..5 {
            // A tolerance just above tail(m) keeps m modes; just below it keeps m + 1.
            let above = PodParams { rel_tol: tail(m) * (1.0 + 1e-6) };
            let below = PodParams { rel_tol: tail(m) * (1.0 - 1e-6) };
            assert_eq!(pod(s.as_ref(), above).expect("svd").modes.ncols(), m, "above tail({m})");
            assert_eq!(pod(s.as_ref(), below).expect("svd").modes.ncols(), m + 1, "below");
        }
        assert_eq!(pod(s.as_ref(), PodParams { rel_tol: 1.0 }).expect("svd").modes.ncols(), 0);
        // rel_tol = 0 stops at the numerical rank, not at min(n, N) = 12.
        assert_eq!(pod_full(s.as_ref()).expect("svd").modes.ncols(), 5);
    }

    #[test]
    fn zero_and_empty_matrices_give_no_modes() {
        for (n, count) in [(10, 4), (0, 3), (5, 0)] {
            let pod = pod_full(Mat::<f64>::zeros(n, count).as_ref()).expect("no SVD needed");
            assert_eq!((pod.modes.nrows(), pod.modes.ncols(), pod.rank), (n, 0, 0));
            assert_all_close!(pod.singular_values, vec![0.0; n.min(count)], Tol::abs(0.0));
        }
        let mut bad = Mat::<f64>::zeros(3, 3);
        bad[(1, 1)] = f64::NAN;
        assert!(matches!(pod_full(bad.as_ref()), Err(PodError::NonFinite)));
    }

    #[test]
    fn truncation_rank_by_hand() {
        // tails: [25+9+0+0 ...] for s = [4, 3, 0]: total 5, tail(1) = 3/5, tail(2) = 0.
        let sv = [4.0, 3.0, 0.0];
        assert_eq!(truncation_rank(&sv, 0.0), 2);
        assert_eq!(truncation_rank(&sv, 0.6), 1);
        assert_eq!(truncation_rank(&sv, 0.59), 2);
        assert_eq!(truncation_rank(&[0.0, 0.0], 0.0), 0);
        assert_close!(tail_energies(&sv)[0], 25.0, Tol::abs(0.0)); // exact in binary
    }

    /// At the switch-over size the frame path and the direct SVD agree: singular values within
    /// the frame's bound plus 1e-12 of s_max (round-off of two SVDs), the truncation rank
    /// equal, and the modes spanning the same space (principal angles: `||U_d^T U_f||_F^2 = m`
    /// to 1e-10, the subspace of modes separated from the rest by a spectral gap).
    #[test]
    fn frame_path_agrees_with_the_direct_svd() {
        let mut rng = crate::rng::Rng::new(91);
        let s = crate::testing::bumps(&mut rng, 80, POD_FRAME_ABOVE + 200, (3.0, 12.0));
        let params = PodParams { rel_tol: 1e-6 };
        let framed = pod(s.as_ref(), params).expect("svd");
        let direct = pod_direct(s.as_ref(), params).expect("svd");
        assert_eq!(framed.rank, direct.rank);
        assert_eq!(framed.modes.ncols(), direct.modes.ncols());
        let bound = super::super::frame(s.as_ref()).dropped + 1e-12 * direct.singular_values[0];
        for (a, b) in framed.singular_values.iter().zip(&direct.singular_values) {
            assert!((a - b).abs() <= bound, "{a} vs {b}");
        }
        let m = direct.modes.ncols();
        let overlap = (direct.modes.transpose() * &framed.modes).squared_norm_l2();
        assert!((overlap - m as f64).abs() <= 1e-10 * m as f64, "overlap {overlap} of {m}");
    }
}
