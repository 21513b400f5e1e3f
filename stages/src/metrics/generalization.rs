//! Generalization ability by leave-one-out (paper eq. 17):
//!
//! ```text
//! G(m) = 1/N sum_i ||s_i - Pi_{Psi(S \ s_i)[:m]}(s_i)|| / ||s_i||
//! ```
//!
//! For each fold i the basis `Psi(S \ s_i)` is rebuilt from the N - 1 other snapshots, exactly
//! as for the training set, and the left-out `s_i` is projected on its first m vectors:
//!
//! * "primal orth" / "dual orth": POD of `S \ s_i` at its numerical rank (thin SVD, the rank
//!   rule of [`pod_full`]), orthogonal projection;
//! * "dual cone": CPG of `S \ s_i` at tolerance 0 (every snapshot not already in the cone, in
//!   CPG's selection order), cone projection (eq. 12) on the first m generators.
//!
//! Conventions (docs/scenes.md#study-settings):
//!
//! * The curve covers m = 1..=max_m. A fold whose basis has fewer than m vectors (rank of
//!   `S \ s_i` below m, or CPG stopped earlier) uses its whole basis — the python slicing
//!   `Psi[:m]` of the paper's notation — so every fold contributes at every m; such folds are
//!   counted in [`MetricCurve::padded`].
//! * A left-out snapshot with zero norm (no contact) has no relative error: it is skipped and
//!   counted in [`MetricCurve::n_zero`], never divided by. The mean and the (population)
//!   standard deviation are over the others, so `1/N` in eq. 17 is `1/count`.
//! * A duplicated snapshot left out is still in the span / cone of the other folds' bases:
//!   its error is round-off at full rank.
//!
//! Folds are independent. [`LooOrth::fold_with`] and [`loo_fold_cone`] compute one fold each
//! (the pipeline runs them in parallel), [`combine_folds`] reduces them to a [`MetricCurve`], and
//! [`generalization_orth`] / [`generalization_cone`] do all folds sequentially. The direct
//! definitions are kept as references: [`loo_fold_orth`], [`LooOrth::fold_reference`] and
//! [`loo_fold_cone_reference`] / [`generalization_cone_reference`].
//!
//! # Cone folds share the greedy path
//!
//! The CPG of `S \ s_i` follows the full set's selection until the step `t_i` at which the
//! full run picks `s_i`: before it, both runs see the same cone and the same errors of every
//! other snapshot (each snapshot's warm-started projections depend only on the generators
//! pushed and on the snapshot), so the same scan picks the same generator. Removing `s_i` can
//! also change a scan it does not win when it is a running best that carries a tie to the
//! winner (the tie rule is not transitive); [`cpg_path`] checks every running best of every
//! step and moves `t_i` earlier where that happens. The tolerance-0 stop agrees as well:
//! `C(m) = 0` means every snapshot is in the cone, and before `t_i` the full run's pick is still
//! a candidate of the fold. So:
//!
//! * the errors of `s_i` on the first m < t_i generators are the ones the path's compactness
//!   pass computed for `s_i` (the same warm-started chain as the direct fold's);
//! * a snapshot never selected (`t_i = inf`: it is in the cone of the others) has the full
//!   basis as its fold's basis;
//! * a fold with `t_i <= max_m` continues on its own from the cone of the first `t_i - 1`
//!   generators ([`ConeProjector::prefix`](crate::cone::ConeProjector::prefix)), with the full
//!   run's last lazy bounds and coefficients of the other candidates at that cone size as its
//!   start, until `max_m` generators; `s_i`'s chain continues from its recorded coefficients.
//!
//! A fold costs O(max_m - t_i) lazy greedy steps instead of a whole CPG (O(N^2) projections),
//! and no C(m) of the fold is needed (only `s_i`'s own errors enter G).
//!
//! # Orthogonal folds in reduced coordinates
//!
//! With the thin QR factorisation `S = Q R` (Q n x q orthonormal, q = min(n, N)), every fold
//! satisfies `S \ s_i = Q (R \ r_i)` and `s_i = Q r_i`, so the POD modes of `S \ s_i` are `Q`
//! times those of `R \ r_i` (same singular values) and projection errors are the same in
//! either coordinates. [`LooOrth`] factors S once; up to
//! [`FoldMethod::SVD_MAX_SNAPSHOTS`] (256) snapshots each fold is an SVD of the q x (N - 1)
//! matrix `R \ r_i` instead of n x (N - 1) (for a primal field n >> N), beyond that it takes
//! one SVD `R = U Σ V^T` and gets each fold by a column downdate ([`ColumnDowndate`], O(N^2)
//! per fold instead of O(N^3)): the fold's singular values are the roots of a secular equation
//! and `s_i`'s squared coefficients on the fold's modes are its weights. The two agree to
//! round-off (docs/design-notes.md#orthogonal-folds-by-a-column-downdate); the SVD is kept where it is cheap so that the published curves
//! up to 256 snapshots stay bit for bit. The numerical rank uses the cut of the full-size fold,
//! `max(n, N - 1) eps s_max`. [`LooOrth::fold_reference`] (an SVD of `R \ r_i` with both vector
//! sets) and [`loo_fold_orth`] (POD of the n x (N - 1) fold, the definition) are kept as
//! references.
//!
//! For orthonormal modes `U` (k of them), `c = U^T s` and the explicit residual
//! `s_perp = s - U c`, the error on the first m modes is
//! `||s - U_m U_m^T s||^2 = ||s_perp||^2 + sum_{l >= m} c_l^2`: a sum of non-negative terms
//! (no cancellation), so errors reach round-off when `s` is in the span. The downdate has the
//! same form: `s_perp` is the weight of the fold's directions beyond its rank.

use std::borrow::Borrow;

use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{Mat, MatRef, Par};

use super::compactness::compactness_cone_with;
use super::downdate::ColumnDowndate;
use super::stats::{MetricCurve, RunningStats};
use crate::basis::{
    cpg_path, cpg_reference, numerical_rank, pod_frame, pod_full, CpgParams, CpgPath, CpgPathParams, LazyGreedy,
    PodError, CPG_FLOOR,
};
use crate::cone::{copy_column, norm2, ConeError, NnlsParams, IN_CONE_REL_TOL};

/// The relative projection errors of one left-out snapshot.
#[derive(Debug, Clone, PartialEq)]
pub struct LooFold {
    /// `errors[k]` is the relative error on the first m = k + 1 basis vectors (length max_m);
    /// beyond `basis_len` it repeats the error on the whole basis.
    pub errors: Vec<f64>,
    /// Number of vectors in this fold's basis (POD rank or CPG size of `S \ s_i`).
    pub basis_len: usize,
}

/// Reduce folds to a curve for m = 1..=max_m. `None` folds (zero-norm left-out snapshots) are
/// counted in `n_zero`; every `Some` fold must have `max_m` errors.
pub fn combine_folds<B, I>(folds: I, max_m: usize) -> MetricCurve
where
    B: Borrow<Option<LooFold>>,
    I: IntoIterator<Item = B>,
{
    let mut stats = vec![RunningStats::new(); max_m];
    let mut padded = vec![0; max_m];
    let mut n_zero = 0;
    for fold in folds {
        let Some(fold) = fold.borrow() else {
            n_zero += 1;
            continue;
        };
        assert_eq!(fold.errors.len(), max_m, "combine_folds: fold has the wrong number of errors");
        for (k, e) in fold.errors.iter().enumerate() {
            stats[k].push(*e);
            if fold.basis_len <= k {
                padded[k] += 1;
            }
        }
    }
    MetricCurve::from_stats(&stats, padded, n_zero)
}

/// S without column i (n x (N - 1)).
fn without_column(s: MatRef<'_, f64>, i: usize) -> Mat<f64> {
    Mat::from_fn(s.nrows(), s.ncols() - 1, |r, c| s[(r, if c < i { c } else { c + 1 })])
}

fn check_finite(s: MatRef<'_, f64>) -> Result<(), PodError> {
    if (0..s.ncols()).any(|j| s.col(j).iter().any(|v| !v.is_finite())) {
        return Err(PodError::NonFinite);
    }
    Ok(())
}

/// Errors of `x` (a column) on the first m of the orthonormal `modes`, m = 1..=max_m, relative
/// to `norm` (> 0); padded with the whole-basis error beyond `modes.ncols()`.
fn orth_fold_errors(modes: MatRef<'_, f64>, x: MatRef<'_, f64>, norm: f64, max_m: usize) -> LooFold {
    let k = modes.ncols();
    let c: Mat<f64> = modes.transpose() * x;
    let perp = x - modes * &c;
    fold_from_squares((0..k).map(|l| c[(l, 0)] * c[(l, 0)]), perp.squared_norm_l2(), k, norm, max_m)
}

/// A fold from the left-out snapshot's squared coefficients `sq` on the fold's modes (in mode
/// order) and `beyond`, its squared part outside them: the error on the first m modes is
/// `sqrt(beyond + sum_{l >= m} sq_l) / norm`, accumulated from the last mode up (no
/// cancellation), with m capped at the fold's rank.
fn fold_from_squares(
    sq: impl DoubleEndedIterator<Item = f64> + ExactSizeIterator,
    beyond: f64,
    rank: usize,
    norm: f64,
    max_m: usize,
) -> LooFold {
    let mut tails = vec![0.0; sq.len() + 1];
    let last = tails.len() - 1;
    tails[last] = beyond;
    for (l, v) in sq.enumerate().rev() {
        tails[l] = tails[l + 1] + v;
    }
    let errors = (1..=max_m).map(|m| tails[m.min(rank)].sqrt() / norm).collect();
    LooFold { errors, basis_len: rank }
}

/// One orthogonal leave-one-out fold by definition: POD (numerical rank) of the n x (N - 1)
/// matrix `S \ s_i`, errors of `s_i` for m = 1..=max_m. `None` when `||s_i|| = 0`.
/// [`LooOrth::fold`] computes the same in reduced coordinates, faster.
pub fn loo_fold_orth(s: MatRef<'_, f64>, i: usize, max_m: usize) -> Result<Option<LooFold>, PodError> {
    assert!(i < s.ncols(), "loo_fold_orth: fold {i} out of {} snapshots", s.ncols());
    check_finite(s)?;
    let norm = s.col(i).norm_l2();
    if norm <= 0.0 {
        return Ok(None);
    }
    let pod = pod_full(without_column(s, i).as_ref())?;
    Ok(Some(orth_fold_errors(pod.modes.as_ref(), s.subcols(i, 1), norm, max_m)))
}

/// How [`LooOrth`] computes a fold; both give the errors of `s_i` on the POD modes of
/// `S \ s_i` (they agree to round-off: docs/design-notes.md#orthogonal-folds-by-a-column-downdate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FoldMethod {
    /// An SVD of the q x (N - 1) matrix `R \ r_i` (left vectors only), O(N^3) per fold.
    Svd,
    /// A column downdate of the one SVD of R ([`ColumnDowndate`]), O(N^2) per fold.
    Downdate,
}

impl FoldMethod {
    /// Up to this many snapshots a fold is its own SVD (every fold is computed, and the
    /// curves of the paper-sized studies stay the same bit for bit); beyond, the downdate.
    pub const SVD_MAX_SNAPSHOTS: usize = 256;

    /// The method [`LooOrth::new`] uses for N snapshots.
    pub fn for_snapshots(count: usize) -> Self {
        if count <= Self::SVD_MAX_SNAPSHOTS {
            FoldMethod::Svd
        } else {
            FoldMethod::Downdate
        }
    }
}

/// Orthogonal leave-one-out folds of one snapshot matrix, sharing one QR factorisation
/// `S = Q R`, and for [`FoldMethod::Downdate`] one SVD `R = U Σ V^T`. `Sync`: folds can run in
/// parallel on a shared reference.
#[derive(Debug, Clone)]
pub struct LooOrth {
    /// `R` of `S = Q R`, q x N (the snapshots in the orthonormal frame Q).
    coords: Mat<f64>,
    method: FoldMethod,
    /// Singular values of R (descending, p = min(q, N)); empty for [`FoldMethod::Svd`].
    sigma: Vec<f64>,
    /// The first p columns of V of `R = U Σ V^T`, N x p (they pair with Σ); empty for
    /// [`FoldMethod::Svd`].
    v: Mat<f64>,
    /// `1 - ||V[i, :p]||^2` per snapshot: from the rest of the full orthogonal V on the direct
    /// path (no cancellation), from the thin V where [`pod_frame`] gives a frame.
    complement: Vec<f64>,
    /// `||s_j||` from the original columns (length N).
    norms: Vec<f64>,
    /// Rows n of S (for the numerical-rank cut of a full-size fold).
    nrows: usize,
}

impl LooOrth {
    /// Factor the snapshots `s` (n x N), folds by [`FoldMethod::for_snapshots`].
    pub fn new(s: MatRef<'_, f64>) -> Result<Self, PodError> {
        Self::with_method(s, FoldMethod::for_snapshots(s.ncols()))
    }

    /// Factor the snapshots `s` (n x N) for folds by `method`.
    pub fn with_method(s: MatRef<'_, f64>, method: FoldMethod) -> Result<Self, PodError> {
        check_finite(s)?;
        let count = s.ncols();
        let norms = (0..count).map(|j| s.col(j).norm_l2()).collect();
        if method == FoldMethod::Downdate {
            if let Some(frame) = pod_frame(s) {
                return Self::framed(frame, count, s.nrows(), norms);
            }
        }
        Self::direct(s, method, norms)
    }

    /// [`new`](Self::new) of snapshots read block by block (`src`, with `norms` from
    /// [`column_norms`](crate::blocks::column_norms) of the same source): above the
    /// frame's switch-over size through the blockwise frame, one block in memory at a time,
    /// with `||S||_F` and each snapshot's norm from `norms`; elsewhere (or where the frame does
    /// not pay) on the whole matrix.
    pub fn from_blocks(
        src: &dyn crate::blocks::ColumnBlocks,
        norms: &crate::blocks::ColumnNorms,
    ) -> Result<Self, PodError> {
        Self::from_blocks_framed(src, norms, crate::basis::large_frame(src, norms)?.as_ref())
    }

    /// [`from_blocks`](Self::from_blocks) with the set's
    /// [`large_frame`](crate::basis::large_frame) computed by the caller (`frame` must be that
    /// function's answer for the same `src` and `norms`; the POD of the set reads the same one).
    pub fn from_blocks_framed(
        src: &dyn crate::blocks::ColumnBlocks,
        norms: &crate::blocks::ColumnNorms,
        frame: Option<&crate::basis::Frame>,
    ) -> Result<Self, PodError> {
        let count = src.ncols();
        if !norms.finite {
            return Err(PodError::NonFinite);
        }
        // Above the frame's switch-over size every fold method is the downdate.
        debug_assert!(
            count <= crate::basis::POD_FRAME_ABOVE || FoldMethod::for_snapshots(count) == FoldMethod::Downdate
        );
        if let Some(frame) = frame.filter(|_| count > crate::basis::POD_FRAME_ABOVE) {
            let single = norms.norm2.iter().map(|v| v.sqrt()).collect();
            return Self::framed(frame.clone(), count, src.nrows(), single);
        }
        Self::new(src.whole()?.as_ref())
    }

    /// [`with_method`](Self::with_method) on the whole QR factor of `s` at any size.
    fn direct(s: MatRef<'_, f64>, method: FoldMethod, norms: Vec<f64>) -> Result<Self, PodError> {
        let (n, count) = (s.nrows(), s.ncols());
        let coords = if n.min(count) == 0 { Mat::zeros(0, count) } else { s.qr().thin_R().to_owned() };
        let p = coords.nrows().min(count);
        let (sigma, v) = if method == FoldMethod::Svd {
            (Vec::new(), Mat::zeros(0, 0))
        } else if p == 0 {
            (Vec::new(), Mat::identity(count, count))
        } else if p == count {
            let svd = coords.thin_svd().map_err(|_| PodError::SvdNoConvergence)?;
            (svd.S().column_vector().iter().copied().collect(), svd.V().to_owned())
        } else {
            // Wide R (fewer rows than snapshots): the full V, whose last N - p columns give
            // each fold's `1 - ||v||^2` without cancellation.
            let svd = coords.svd().map_err(|_| PodError::SvdNoConvergence)?;
            (svd.S().column_vector().iter().take(p).copied().collect(), svd.V().to_owned())
        };
        let complement = (0..count).map(|i| (p..v.ncols()).map(|k| v[(i, k)] * v[(i, k)]).sum()).collect();
        let v = if v.ncols() > p { v.subcols(0, p).to_owned() } else { v };
        Ok(Self { coords, method, sigma, v, complement, norms, nrows: n })
    }

    /// Where [`pod_frame`] gives a frame: the coordinates in the blockwise frame
    /// ([`frame`](crate::basis::frame), q ~ the numerical rank rows instead of min(n, N)) and
    /// the thin SVD of those, `V` N x q. The full N x N V of the direct path (537 MB and
    /// `O(N^3)` at N = 8 193) is replaced by `1 - ||v_i||^2`, whose absolute error is a few
    /// eps: relative `eps / (1 - ||v_i||^2)`, small unless snapshot i alone carries a
    /// direction (leverage near 1), and a snapshot that does gets its own direction's weight
    /// from the pairs either way. Agreement with the direct path at the switch-over size is
    /// tested.
    fn framed(frame: crate::basis::Frame, count: usize, n: usize, norms: Vec<f64>) -> Result<Self, PodError> {
        let coords = frame.r;
        let p = coords.nrows();
        let (sigma, v) = if p == 0 {
            (Vec::new(), Mat::zeros(count, 0))
        } else {
            let svd = coords.thin_svd().map_err(|_| PodError::SvdNoConvergence)?;
            (svd.S().column_vector().iter().copied().collect(), svd.V().to_owned())
        };
        let complement =
            (0..count).map(|i| (1.0 - (0..p).map(|k| v[(i, k)] * v[(i, k)]).sum::<f64>()).max(0.0)).collect();
        Ok(Self { coords, method: FoldMethod::Downdate, sigma, v, complement, norms, nrows: n })
    }

    /// Number of snapshots N (folds).
    pub fn ncols(&self) -> usize {
        self.norms.len()
    }

    /// How the folds are computed.
    pub fn method(&self) -> FoldMethod {
        self.method
    }

    /// Fold i: the errors of `s_i` on the POD modes of `S \ s_i`, m = 1..=max_m; `None` when
    /// `||s_i|| = 0`. Allocates its buffers; [`LooOrth::fold_with`] reuses them.
    pub fn fold(&self, i: usize, max_m: usize) -> Result<Option<LooFold>, PodError> {
        self.fold_with(i, max_m, &mut self.workspace())
    }

    /// Buffers for [`LooOrth::fold_with`] (one per thread).
    pub fn workspace(&self) -> LooOrthWorkspace {
        match self.method {
            FoldMethod::Svd => {
                let (q, count) = self.coords.shape();
                let cols = count.saturating_sub(1);
                let size = q.min(cols);
                let thin = ComputeSvdVectors::Thin;
                let req = svd_scratch::<f64>(q, cols, thin, ComputeSvdVectors::No, Par::Seq, Default::default());
                LooOrthWorkspace::Svd {
                    rest: Mat::zeros(q, cols),
                    u: Mat::zeros(q, size),
                    sv: Diag::zeros(size),
                    buf: MemBuffer::new(req),
                }
            }
            FoldMethod::Downdate => {
                let p = self.sigma.len();
                LooOrthWorkspace::Downdate {
                    row: Vec::with_capacity(p),
                    omega: Vec::with_capacity(p),
                    downdate: ColumnDowndate::new(),
                }
            }
        }
    }

    /// [`LooOrth::fold`] with caller-owned buffers (from [`LooOrth::workspace`] of the same
    /// matrix).
    ///
    /// * [`FoldMethod::Svd`]: `R \ r_i` is written into the reused q x (N - 1) buffer (no
    ///   allocation) and the SVD computes the left singular vectors only.
    /// * [`FoldMethod::Downdate`]: with `z = Σ V[i, :p]^T` (`r_i = U z`), the squared singular
    ///   values of `R \ r_i` are the eigenvalues of `Σ^2 - z z^T` and `s_i`'s squared
    ///   coefficients on its modes are the weights of [`ColumnDowndate`]; the error on the
    ///   first m modes is the sum of the weights from m on (no cancellation).
    ///
    /// Either way the numerical rank cuts the fold's `min(q, N - 1)` singular values as
    /// [`pod_full`] does.
    pub fn fold_with(&self, i: usize, max_m: usize, ws: &mut LooOrthWorkspace) -> Result<Option<LooFold>, PodError> {
        let count = self.ncols();
        assert!(i < count, "LooOrth::fold: fold {i} out of {count} snapshots");
        let norm = self.norms[i];
        if norm <= 0.0 {
            return Ok(None);
        }
        match ws {
            LooOrthWorkspace::Svd { rest, u, sv, buf } => {
                assert_eq!(self.method, FoldMethod::Svd, "LooOrth::fold_with: a workspace of the other method");
                let q = self.coords.nrows();
                for c in 0..count - 1 {
                    let from = if c < i { c } else { c + 1 };
                    rest.col_mut(c).copy_from(self.coords.col(from));
                }
                let rank = if count - 1 == 0 || q == 0 || rest.norm_l2() <= 0.0 {
                    0
                } else {
                    let stack = MemStack::new(buf);
                    svd(rest.as_ref(), sv.as_mut(), Some(u.as_mut()), None, Par::Seq, stack, Default::default())
                        .map_err(|_| PodError::SvdNoConvergence)?;
                    let values: Vec<f64> = sv.column_vector().iter().copied().collect();
                    numerical_rank(&values, self.nrows, count - 1)
                };
                Ok(Some(orth_fold_errors(u.subcols(0, rank), self.coords.subcols(i, 1), norm, max_m)))
            }
            LooOrthWorkspace::Downdate { row, omega, downdate } => {
                assert_eq!(self.method, FoldMethod::Downdate, "LooOrth::fold_with: a workspace of the other method");
                let p = self.sigma.len();
                row.clear();
                row.extend((0..p).map(|k| self.v[(i, k)]));
                let complement = self.complement[i];
                let pairs = downdate.solve(&self.sigma, row, complement);
                // The fold has min(q, N - 1) singular values; with V square the extra pair is
                // its 0.
                let size = self.coords.nrows().min(count - 1);
                omega.clear();
                omega.extend(pairs[..size].iter().map(|p| p.0));
                let rank = numerical_rank(omega, self.nrows, count - 1);
                // every pair's weight: beyond the rank they are s_i's part outside the fold's span
                Ok(Some(fold_from_squares(pairs.iter().map(|p| p.1), 0.0, rank, norm, max_m)))
            }
        }
    }

    /// Fold i by an SVD of `R \ r_i` (kept as the reference): a copy of `R \ r_i` and a thin
    /// SVD with both singular vector sets.
    pub fn fold_reference(&self, i: usize, max_m: usize) -> Result<Option<LooFold>, PodError> {
        let count = self.ncols();
        assert!(i < count, "LooOrth::fold: fold {i} out of {count} snapshots");
        let norm = self.norms[i];
        if norm <= 0.0 {
            return Ok(None);
        }
        let rest = without_column(self.coords.as_ref(), i);
        let q = rest.nrows();
        let modes = if rest.ncols() == 0 || rest.norm_l2() <= 0.0 {
            Mat::zeros(q, 0)
        } else {
            let svd = rest.thin_svd().map_err(|_| PodError::SvdNoConvergence)?;
            let values: Vec<f64> = svd.S().column_vector().iter().copied().collect();
            let rank = numerical_rank(&values, self.nrows, count - 1);
            svd.U().subcols(0, rank).to_owned()
        };
        Ok(Some(orth_fold_errors(modes.as_ref(), self.coords.subcols(i, 1), norm, max_m)))
    }
}

/// Reusable buffers of [`LooOrth::fold_with`], one kind per [`FoldMethod`].
pub enum LooOrthWorkspace {
    Svd { rest: Mat<f64>, u: Mat<f64>, sv: Diag<f64>, buf: MemBuffer },
    Downdate { row: Vec<f64>, omega: Vec<f64>, downdate: ColumnDowndate },
}

impl std::fmt::Debug for LooOrthWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LooOrthWorkspace::Svd { rest, .. } => {
                f.debug_struct("LooOrthWorkspace::Svd").field("rest", &rest.shape()).finish_non_exhaustive()
            }
            LooOrthWorkspace::Downdate { row, .. } => {
                f.debug_struct("LooOrthWorkspace::Downdate").field("p", &row.capacity()).finish_non_exhaustive()
            }
        }
    }
}

/// G(m) for m = 1..=max_m with POD bases ("primal orth", "dual orth"), every fold in turn.
pub fn generalization_orth(s: MatRef<'_, f64>, max_m: usize) -> Result<MetricCurve, PodError> {
    let loo = LooOrth::new(s)?;
    let mut ws = loo.workspace();
    let folds = (0..s.ncols()).map(|i| loo.fold_with(i, max_m, &mut ws)).collect::<Result<Vec<_>, _>>()?;
    Ok(combine_folds(&folds, max_m))
}

/// G(m) for m = 1..=max_m with CPG bases ("dual cone"): the shared path, then every fold in
/// turn ([`loo_fold_cone`]).
pub fn generalization_cone(s: MatRef<'_, f64>, max_m: usize, nnls: NnlsParams) -> Result<MetricCurve, ConeError> {
    let path = cpg_path(s, CpgPathParams { nnls, max_rank: max_m, ..CpgPathParams::default() }, &|| {})?;
    let folds = (0..s.ncols()).map(|i| loo_fold_cone(s, &path, i, max_m)).collect::<Result<Vec<_>, _>>()?;
    Ok(combine_folds(&folds, max_m))
}

/// One cone leave-one-out fold from the tolerance-0 CPG path of `s` (`path` =
/// [`cpg_path`] of the same `s` with `max_rank >= max_m`): the relative cone projection errors
/// of `s_i` on the first m generators of the CPG basis of `S \ s_i`, m = 1..=max_m; `None`
/// when `||s_i|| = 0`. Equals [`loo_fold_cone_reference`] (see the module docs); `basis_len`
/// is exact below `max_m` and otherwise a lower bound `>= max_m` (the fold stops growing at
/// `max_m`).
pub fn loo_fold_cone(s: MatRef<'_, f64>, path: &CpgPath, i: usize, max_m: usize) -> Result<Option<LooFold>, ConeError> {
    let d = &path.loo;
    assert_eq!(s.ncols(), d.norms.len(), "loo_fold_cone: the path is of another snapshot set");
    assert!(i < s.ncols(), "loo_fold_cone: fold {i} out of {} snapshots", s.ncols());
    assert!(max_m <= path.max_rank, "loo_fold_cone: max_m {max_m} above the path's max_rank {}", path.max_rank);
    if d.norms[i] <= 0.0 {
        return Ok(None);
    }
    let k = path.len();
    let t = d.diverge[i];
    // c[m]: error on the first m generators of the fold's basis; c[0] = 1 (empty cone).
    let shared = if t == usize::MAX { k } else { t - 1 }.min(max_m);
    let mut c = Vec::with_capacity(max_m + 1);
    c.push(1.0);
    c.extend_from_slice(&d.errors[i][..shared]);
    let basis_len = if t == usize::MAX {
        k
    } else if t > max_m {
        t - 1
    } else {
        continue_fold(s, path, i, max_m, &mut c)?
    };
    let used = c.len() - 1;
    let errors = (1..=max_m).map(|m| c[m.min(used)]).collect();
    Ok(Some(LooFold { errors, basis_len }))
}

/// The fold without snapshot i from step t = diverge[i]: the cone of the full path's first
/// t - 1 generators, every other snapshot not yet selected as a candidate with its last bound
/// and coefficients from the full run's lazy projections at cone size <= t - 1, then the lazy
/// greedy on its own until max_m generators or none is left; the error of s_i continues its
/// warm-started chain of the full path's pass. Returns the fold's basis size.
fn continue_fold(
    s: MatRef<'_, f64>,
    path: &CpgPath,
    i: usize,
    max_m: usize,
    c: &mut Vec<f64>,
) -> Result<usize, ConeError> {
    let d = &path.loo;
    let t = d.diverge[i];
    let projector = d.projector.as_ref().expect("cpg_path records the cone for max_rank > 0").prefix(t - 1);
    let mut early = vec![false; s.ncols()];
    path.selected[..t - 1].iter().for_each(|&g| early[g] = true);
    let candidates = (0..s.ncols()).filter(|&j| j != i && d.norms[j] > 0.0 && !early[j]).filter_map(|j| {
        let h = &d.history[j];
        let last = h.partition_point(|r| r.m < t);
        let (err, m, coeffs) = match last.checked_sub(1).map(|q| &h[q]) {
            Some(r) => (r.err, r.m, r.coeffs.clone()),
            None => (1.0, 0, Vec::new()), // empty cone: ||s_j|| / ||s_j|| = 1 exactly
        };
        (err > CPG_FLOOR).then_some((j, err, m, coeffs))
    });
    let mut lazy = LazyGreedy::resume(s, &d.norms, projector, candidates);
    let (mut coeffs, mut residual) = d.start[i].clone().expect("cpg_path records the start of folds up to max_rank");
    let mut lambda = vec![0.0; s.nrows()];
    copy_column(s, i, &mut lambda);
    let mut atb: Vec<f64> = (0..t - 1).map(|g| lazy.projector.dot_column(g, &lambda)).collect();
    while lazy.len() < max_m {
        if lazy.step()?.is_none() {
            break;
        }
        coeffs.push(0.0);
        if residual > IN_CONE_REL_TOL * d.norms[i] {
            atb.push(lazy.projector.dot_column(lazy.len() - 1, &lambda));
            residual = lazy.projector.project_warm_atb(&lambda, &atb, &mut coeffs)?;
        }
        c.push(norm2(&[residual]) / d.single_norms[i]);
    }
    Ok(lazy.len())
}

/// One cone leave-one-out fold by definition (kept as the slow reference): CPG (tolerance 0,
/// [`cpg_reference`]) of `S \ s_i`, then the relative cone projection error of `s_i` on its
/// first m generators in selection order, m = 1..=max_m; `None` when `||s_i|| = 0`.
pub fn loo_fold_cone_reference(
    s: MatRef<'_, f64>,
    i: usize,
    max_m: usize,
    nnls: NnlsParams,
) -> Result<Option<LooFold>, ConeError> {
    assert!(i < s.ncols(), "loo_fold_cone: fold {i} out of {} snapshots", s.ncols());
    if s.col(i).norm_l2() <= 0.0 {
        return Ok(None);
    }
    let basis = cpg_reference(without_column(s, i).as_ref(), CpgParams { tol: 0.0, nnls })?.basis;
    let k = basis.ncols();
    let used = k.min(max_m);
    // C(m) of the single column s_i is its relative error (eq. 16 with N = 1), m = 0..=used.
    let c = compactness_cone_with(s.subcols(i, 1), basis.subcols(0, used), nnls)?;
    let errors = (1..=max_m).map(|m| c[m.min(used)]).collect();
    Ok(Some(LooFold { errors, basis_len: k }))
}

/// [`generalization_cone`] by definition: every fold through [`loo_fold_cone_reference`].
pub fn generalization_cone_reference(
    s: MatRef<'_, f64>,
    max_m: usize,
    nnls: NnlsParams,
) -> Result<MetricCurve, ConeError> {
    let folds = (0..s.ncols()).map(|i| loo_fold_cone_reference(s, i, max_m, nnls)).collect::<Result<Vec<_>, _>>()?;
    Ok(combine_folds(&folds, max_m))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cone::nnls_reference;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::testing::{bumps, hertz_family};
    use crate::{assert_all_close, assert_close};
    use faer::prelude::SolveLstsq;
    use faer::Side;

    fn random_mat(rng: &mut Rng, n: usize, k: usize, lo: f64, hi: f64) -> Mat<f64> {
        Mat::from_fn(n, k, |_, _| rng.uniform_in(lo, hi))
    }

    /// Every orthogonal fold through the paths (reduced QR coordinates by SVD and by downdate,
    /// and the definition).
    fn both_orth_paths(s: MatRef<'_, f64>, max_m: usize) -> Vec<Option<LooFold>> {
        let loo = LooOrth::new(s).expect("finite");
        let by_downdate = LooOrth::with_method(s, FoldMethod::Downdate).expect("finite");
        (0..s.ncols())
            .map(|i| {
                let fast = loo.fold(i, max_m).expect("svd");
                let other = by_downdate.fold(i, max_m).expect("downdate");
                assert_eq!(fast.as_ref().map(|f| f.basis_len), other.as_ref().map(|f| f.basis_len));
                if let (Some(f), Some(o)) = (&fast, &other) {
                    // As below: both backward stable, cond <= 1e3 here.
                    assert_all_close!(f.errors, o.errors, Tol::abs(1e-10));
                }
                let direct = loo_fold_orth(s, i, max_m).expect("svd");
                match (&fast, &direct) {
                    (Some(f), Some(d)) => {
                        assert_eq!(f.basis_len, d.basis_len, "fold {i}: ranks differ");
                        // Two backward-stable factorisations of the same fold: 1e-10 absolute
                        // on a relative error (O(cond eps) apart, cond <= 1e3 here).
                        assert_all_close!(f.errors, d.errors, Tol::abs(1e-10));
                    }
                    (None, None) => {}
                    _ => panic!("fold {i}: zero-norm detection differs"),
                }
                fast
            })
            .collect()
    }

    #[test]
    fn orth_loo_in_a_plane_is_exact_from_two_modes() {
        // 8 snapshots a_j v1 + b_j v2 in R^10: every fold has rank 2 and contains the plane.
        let mut rng = Rng::new(71);
        let v = random_mat(&mut rng, 10, 2, -1.0, 1.0);
        let coeffs = random_mat(&mut rng, 2, 8, -1.0, 1.0);
        let s = &v * &coeffs;
        let max_m = 7;
        let folds = both_orth_paths(s.as_ref(), max_m);
        assert!(folds.iter().all(|f| f.as_ref().is_some_and(|f| f.basis_len == 2)));
        let g = generalization_orth(s.as_ref(), max_m).expect("svd");
        assert_eq!((g.len(), g.n_zero), (max_m, 0));
        assert_eq!(g.count, vec![8; max_m]);
        assert_eq!(g.padded, vec![0, 0, 8, 8, 8, 8, 8]); // rank 2: m >= 3 reuses both modes
        for m in 2..=max_m {
            // In the span: round-off of an SVD of O(1) data, 1e-10 as required.
            assert_close!(g.mean[m - 1], 0.0, Tol::abs(1e-10));
            assert_close!(g.std[m - 1], 0.0, Tol::abs(1e-10));
        }
        // One mode cannot hold a plane of isotropic combinations.
        assert!(g.mean[0] > 0.01, "G(1) = {}", g.mean[0]);
    }

    #[test]
    fn orth_fold_matches_brute_force_projections() {
        // Independent reference for fold i: the POD modes of S \ s_i from the eigenvectors of
        // the n x n matrix (S \ s_i)(S \ s_i)^T (no SVD), and at full rank the least-squares
        // residual of s_i on the remaining columns by QR.
        let mut rng = Rng::new(72);
        let (n, count, i) = (15, 6, 2);
        let s = random_mat(&mut rng, n, count, -1.0, 1.0);
        let rest = without_column(s.as_ref(), i);
        let x = s.subcols(i, 1);
        let norm = x.norm_l2();
        let cov = &rest * rest.transpose();
        let eig = cov.self_adjoint_eigen(Side::Lower).expect("evd");
        let vecs = eig.U(); // ascending eigenvalues: the top modes are the last columns
        let brute: Vec<f64> = (1..count)
            .map(|m| {
                let u = vecs.subcols(n - m, m);
                let r = x - u * (u.transpose() * x);
                r.norm_l2() / norm
            })
            .collect();
        let fold = LooOrth::new(s.as_ref()).expect("finite").fold(i, count - 1).expect("svd").expect("nonzero");
        // Eigenvectors of the squared matrix: the gaps between the eigenvalues (singular
        // values ~1 of a random 15 x 5 matrix) keep the subspaces accurate to ~1e-14; 1e-10.
        assert_all_close!(fold.errors, brute, Tol::abs(1e-10));
        let ls = rest.qr().solve_lstsq(x);
        let full = (x - &rest * &ls).norm_l2() / norm;
        assert_close!(fold.errors[count - 2], full, Tol::abs(1e-12)); // two QR solutions
        assert!(full > 0.1, "a random 15-vector is far from a 5-dimensional span: {full}");
    }

    #[test]
    fn orth_reduced_and_direct_folds_agree_on_a_wide_matrix() {
        // n = 6 < N = 10: Q is square and every fold has rank 6 (padded beyond).
        let mut rng = Rng::new(73);
        let s = random_mat(&mut rng, 6, 10, -1.0, 1.0);
        let folds = both_orth_paths(s.as_ref(), 9);
        for fold in folds.iter().flatten() {
            assert_eq!(fold.basis_len, 6);
            assert_close!(fold.errors[8], 0.0, Tol::abs(1e-12)); // R^6 is spanned: round-off
        }
    }

    #[test]
    fn cone_loo_inside_the_cone_is_exact_at_full_size() {
        // Three non-negative generators g1..g3 in R^12, each present twice, and four interior
        // combinations: any left-out snapshot lies in the cone of the others (a copy of its
        // generator remains, the interior ones lie in cone(g1, g2, g3)).
        let mut rng = Rng::new(74);
        let g = random_mat(&mut rng, 12, 3, 0.0, 1.0);
        let w = random_mat(&mut rng, 3, 4, 0.1, 1.0);
        let interior = &g * &w;
        let s = Mat::from_fn(12, 10, |r, c| if c < 6 { g[(r, c / 2)] } else { interior[(r, c - 6)] });
        let max_m = 9;
        let curve = generalization_cone(s.as_ref(), max_m, NnlsParams::default()).expect("converges");
        assert_eq!((curve.count[max_m - 1], curve.n_zero), (10, 0));
        // Cone projection of a member of the cone: NNLS round-off on unit generators, 1e-10.
        assert_close!(curve.mean[max_m - 1], 0.0, Tol::abs(1e-10));
        // One generator cannot reproduce a cone of three directions.
        assert!(curve.mean[0] > 0.01, "G(1) = {}", curve.mean[0]);
        for w in curve.mean.windows(2) {
            assert!(w[1] <= w[0] + 1e-12, "cone G(m) increased: {w:?}"); // nested cones
        }
    }

    #[test]
    fn cone_fold_matches_reference_nnls() {
        // Fold 3 of non-negative bump-like data: the incremental warm-started projections
        // against a textbook Lawson–Hanson on the first m generators of the same CPG basis.
        let mut rng = Rng::new(75);
        let (n, count, i) = (25, 9, 3);
        let s = Mat::from_fn(n, count, |r, _| {
            let x = r as f64 / n as f64;
            (rng.uniform_in(0.0, 1.0) * (1.0 - (x - 0.5).powi(2) * 3.0)).max(0.0)
        });
        let fold =
            loo_fold_cone_reference(s.as_ref(), i, count - 1, NnlsParams::default()).expect("ok").expect("nonzero");
        let basis = cpg_reference(without_column(s.as_ref(), i).as_ref(), CpgParams::default()).expect("ok").basis;
        assert_eq!(fold.basis_len, basis.ncols());
        let b: Vec<f64> = s.col(i).iter().copied().collect();
        let norm = s.col(i).norm_l2();
        for m in 1..count {
            let used = m.min(basis.ncols());
            let reference = nnls_reference(basis.subcols(0, used), &b, NnlsParams::default()).expect("ok");
            // Two NNLS solvers on the same convex problem: the residual norm is unique; 1e-10
            // of ||s_i|| covers the Gram-matrix path's round-off.
            assert_close!(fold.errors[m - 1], reference.residual_norm / norm, Tol::abs(1e-10));
        }
    }

    #[test]
    fn loo_of_duplicates_is_zero() {
        let mut rng = Rng::new(76);
        // Four copies of one non-negative field: every fold's basis is that field.
        let v = random_mat(&mut rng, 20, 1, 0.0, 1.0);
        let copies = Mat::from_fn(20, 4, |r, _| v[(r, 0)]);
        let orth = generalization_orth(copies.as_ref(), 3).expect("svd");
        let cone = generalization_cone(copies.as_ref(), 3, NnlsParams::default()).expect("ok");
        for curve in [&orth, &cone] {
            assert_eq!(curve.count, vec![4; 3]);
            assert_eq!(curve.padded, vec![0, 4, 4]); // rank 1 (POD) / one generator (CPG)
                                                     // s_i is a multiple of the unit basis vector: one rounding per entry, 1e-14.
            assert_all_close!(curve.mean, [0.0; 3], Tol::abs(1e-14));
        }
        // Four distinct random fields, each twice: at full size every fold reproduces its
        // left-out snapshot (its twin is in the basis' span / cone).
        let base = random_mat(&mut rng, 20, 4, 0.0, 1.0);
        let pairs = Mat::from_fn(20, 8, |r, c| base[(r, c / 2)]);
        let orth = generalization_orth(pairs.as_ref(), 7).expect("svd");
        let cone = generalization_cone(pairs.as_ref(), 7, NnlsParams::default()).expect("ok");
        // Round-off of SVD / NNLS on O(1) data: 1e-10.
        assert_close!(orth.mean[6], 0.0, Tol::abs(1e-10));
        assert_close!(cone.mean[6], 0.0, Tol::abs(1e-10));
        assert!(orth.mean[0] > 0.01 && cone.mean[0] > 0.01, "m = 1 cannot hold 4 directions");
    }

    #[test]
    fn zero_column_is_counted_not_divided_by() {
        let mut rng = Rng::new(77);
        let mut s = random_mat(&mut rng, 10, 6, 0.0, 1.0);
        s.col_mut(4).fill(0.0);
        let orth = generalization_orth(s.as_ref(), 5).expect("svd");
        let cone = generalization_cone(s.as_ref(), 5, NnlsParams::default()).expect("ok");
        for curve in [&orth, &cone] {
            assert_eq!(curve.n_zero, 1);
            assert_eq!(curve.count, vec![5; 5]);
            assert!(curve.mean.iter().chain(&curve.std).all(|v| v.is_finite()), "{curve:?}");
        }
        assert!(LooOrth::new(s.as_ref()).expect("finite").fold(4, 5).expect("ok").is_none());
        assert!(loo_fold_cone_reference(s.as_ref(), 4, 5, NnlsParams::default()).expect("ok").is_none());
        // The zero column sits in every other fold's set and changes nothing there: the folds
        // equal those of the matrix without it (5 random fields in R^10, rank 4 per fold).
        let kept = without_column(s.as_ref(), 4);
        let reference = generalization_orth(kept.as_ref(), 5).expect("svd");
        assert_all_close!(orth.mean, reference.mean, Tol::abs(1e-12)); // same folds, round-off
    }

    #[test]
    fn non_finite_snapshots_are_an_error() {
        let mut s = Mat::<f64>::identity(3, 3);
        s[(0, 1)] = f64::NAN;
        assert!(matches!(generalization_orth(s.as_ref(), 2), Err(PodError::NonFinite)));
        assert!(matches!(loo_fold_orth(s.as_ref(), 0, 2), Err(PodError::NonFinite)));
    }

    #[test]
    fn single_snapshot_has_an_empty_basis() {
        // N = 1: the fold's basis is empty, the error is 1 at every m (nothing to project on).
        let s = Mat::from_fn(4, 1, |r, _| r as f64 + 1.0);
        let orth = generalization_orth(s.as_ref(), 2).expect("svd");
        let cone = generalization_cone(s.as_ref(), 2, NnlsParams::default()).expect("ok");
        for curve in [&orth, &cone] {
            assert_all_close!(curve.mean, [1.0, 1.0], Tol::abs(1e-15)); // sqrt(x^2)/|x|
            assert_eq!(curve.padded, vec![1, 1]);
        }
    }

    /// Every cone fold from the shared path against the direct fold (a whole CPG without s_i).
    fn check_cone_folds(s: MatRef<'_, f64>, max_m: usize) -> usize {
        let path =
            cpg_path(s, CpgPathParams { max_rank: max_m, ..CpgPathParams::default() }, &|| {}).expect("converges");
        let mut continued = 0;
        for i in 0..s.ncols() {
            continued += usize::from(path.loo.diverge[i] <= max_m);
            let fast = loo_fold_cone(s, &path, i, max_m).expect("converges");
            let slow = loo_fold_cone_reference(s, i, max_m, NnlsParams::default()).expect("converges");
            match (&fast, &slow) {
                (Some(f), Some(r)) => {
                    assert_eq!(f.basis_len.min(max_m), r.basis_len.min(max_m), "fold {i}: basis sizes differ");
                    // Same generators and the same warm-started chain of s_i: equal up to the
                    // last bits of the generators (the direct fold normalises a copied matrix);
                    // 1e-12 relative, plus 1e-14 absolute for errors at round-off level.
                    assert_all_close!(f.errors, r.errors, Tol { abs: 1e-14, rel: 1e-12 });
                }
                (None, None) => {}
                _ => panic!("fold {i}: zero-norm detection differs"),
            }
        }
        continued
    }

    #[test]
    fn cone_loo_from_the_path_equals_the_reference() {
        let s = hertz_family(&mut Rng::new(78), 101, 64);
        let continued = check_cone_folds(s.as_ref(), 63);
        // Most snapshots are extreme rays of this family: their folds need a continuation.
        assert!(continued > 30, "only {continued} folds continued");
        // A smaller max rank: the folds stop growing at 12 generators.
        check_cone_folds(s.as_ref(), 12);
        // More snapshots than nodes (a cone needs more generators than n) and random bumps.
        check_cone_folds(hertz_family(&mut Rng::new(79), 24, 40).as_ref(), 39);
        check_cone_folds(bumps(&mut Rng::new(80), 30, 36, (1.0, 4.0)).as_ref(), 35);
    }

    #[test]
    fn cone_generalization_equals_the_reference_curve() {
        let s = hertz_family(&mut Rng::new(81), 60, 48);
        let fast = generalization_cone(s.as_ref(), 47, NnlsParams::default()).expect("converges");
        let slow = generalization_cone_reference(s.as_ref(), 47, NnlsParams::default()).expect("converges");
        // Means of per-fold errors that agree to 1e-12 relative (see check_cone_folds).
        assert_all_close!(fast.mean, slow.mean, Tol { abs: 1e-14, rel: 1e-12 });
        assert_all_close!(fast.std, slow.std, Tol { abs: 1e-14, rel: 1e-10 }); // std of near-equal values
        assert_eq!((fast.count, fast.padded, fast.n_zero), (slow.count, slow.padded, slow.n_zero));
    }

    #[test]
    fn orth_folds_without_right_vectors_equal_the_reference() {
        // Ironing-like pressures (near-duplicates, a zero column, a multiple, a sum: rank
        // deficient, so the numerical-rank rule matters) and a wide case (n < N).
        for s in [hertz_family(&mut Rng::new(74), 101, 64), hertz_family(&mut Rng::new(75), 30, 48)] {
            let loo = LooOrth::new(s.as_ref()).expect("finite");
            assert_eq!(loo.method(), FoldMethod::Svd);
            let mut ws = loo.workspace();
            let max_m = s.ncols() - 1;
            for i in 0..s.ncols() {
                let fast = loo.fold_with(i, max_m, &mut ws).expect("svd");
                let slow = loo.fold_reference(i, max_m).expect("svd");
                match (&fast, &slow) {
                    (Some(f), Some(r)) => {
                        assert_eq!(f.basis_len, r.basis_len, "fold {i}: numerical ranks differ");
                        // The same bidiagonal SVD with and without the right vectors: equal up
                        // to round-off of the left ones; 1e-12 relative plus 1e-14 absolute
                        // (errors at round-off level at full rank).
                        assert_all_close!(f.errors, r.errors, Tol { abs: 1e-14, rel: 1e-12 });
                    }
                    (None, None) => {}
                    _ => panic!("fold {i}: zero-norm detection differs"),
                }
            }
        }
    }

    #[test]
    fn orth_folds_by_downdate_equal_the_reference() {
        // Ironing-like pressures (near-duplicates, a zero column, a multiple, a sum: rank
        // deficient, so the numerical-rank rule matters, and singular values down to 1e-9 of
        // the largest) and a wide case (n < N).
        for s in [hertz_family(&mut Rng::new(74), 101, 64), hertz_family(&mut Rng::new(75), 30, 48)] {
            let loo = LooOrth::with_method(s.as_ref(), FoldMethod::Downdate).expect("finite");
            let mut ws = loo.workspace();
            let max_m = s.ncols() - 1;
            let (n, count) = s.shape();
            let sigma_1 = loo.sigma[0];
            for i in 0..count {
                let fast = loo.fold_with(i, max_m, &mut ws).expect("svd");
                let slow = loo.fold_reference(i, max_m).expect("svd");
                match (&fast, &slow) {
                    (Some(f), Some(r)) => {
                        assert_eq!(f.basis_len, r.basis_len, "fold {i}: numerical ranks differ");
                        // Two backward-stable computations, each exact for a matrix within
                        // ||E|| <= max(n, N) eps σ_1 of S \ s_i. By Wedin's sin θ theorem the
                        // span of the first m modes moves by at most ||E|| / gap_m (gap_m the
                        // distance between the fold's m-th and (m+1)-th singular values), and a
                        // relative projection error by at most that angle; plus 1e-13 for the
                        // round-off of the errors themselves.
                        let rest = without_column(loo.coords.as_ref(), i);
                        let values: Vec<f64> =
                            rest.thin_svd().expect("svd").S().column_vector().iter().copied().collect();
                        let bound = n.max(count) as f64 * f64::EPSILON * sigma_1;
                        for m in 1..=max_m {
                            let used = m.min(r.basis_len).max(1);
                            let gap = values[used - 1] - values.get(used).copied().unwrap_or(0.0);
                            let tol = Tol::abs(1e-13 + bound / gap);
                            assert_close!(f.errors[m - 1], r.errors[m - 1], tol);
                        }
                    }
                    (None, None) => {}
                    _ => panic!("fold {i}: zero-norm detection differs"),
                }
            }
        }
    }

    /// At N = 513, G(m) from 64 evenly spaced folds (the sample `study.loo_folds = 64` takes)
    /// agrees with G(m) from every fold within the sample's stated 95 % interval at every m; and
    /// the interval is informative (narrower than the mean itself), so the check is not vacuous.
    #[test]
    fn sampled_folds_agree_with_every_fold_within_their_interval() {
        let mut rng = Rng::new(7);
        let n = 513;
        let s = hertz_family(&mut rng, 120, n);
        let max_m = 24;
        let loo = LooOrth::new(s.as_ref()).expect("finite");
        let all: Vec<Option<LooFold>> = (0..n).map(|i| loo.fold(i, max_m).expect("fold")).collect();
        let every = combine_folds(&all, max_m);
        let sample: Vec<usize> = (0..64).map(|k| k * n / 64).collect();
        let sampled = combine_folds(sample.iter().map(|&i| &all[i]), max_m);
        let mut worst: f64 = 0.0;
        for k in 0..max_m {
            let h = crate::metrics::mean_interval95(sampled.std[k], sampled.count[k], n);
            let d = (sampled.mean[k] - every.mean[k]).abs();
            assert!(h > 0.0 && h < sampled.mean[k], "m = {}: interval {h} against mean {}", k + 1, sampled.mean[k]);
            assert!(d <= h, "m = {}: sampled {} vs every fold {}, interval {h}", k + 1, sampled.mean[k], every.mean[k]);
            worst = worst.max(d / h);
        }
        eprintln!("largest |difference| / half-width over m: {worst:.3}");
    }

    /// Above the switch-over size the framed folds agree with the direct ones (whole QR, full
    /// V) to 1e-9 relative to ||s_i|| at every m: both are the same downdate of the same
    /// singular values, which differ by the frame's round-off bound, and the complements
    /// differ by a few eps (see `LooOrth::framed`).
    #[test]
    fn framed_folds_agree_with_direct_ones() {
        let mut rng = Rng::new(93);
        let s = bumps(&mut rng, 60, crate::basis::POD_FRAME_ABOVE + 40, (3.0, 12.0));
        let norms: Vec<f64> = (0..s.ncols()).map(|j| s.col(j).norm_l2()).collect();
        let framed = LooOrth::with_method(s.as_ref(), FoldMethod::Downdate).expect("factor");
        let direct = LooOrth::direct(s.as_ref(), FoldMethod::Downdate, norms).expect("factor");
        assert!(framed.coords.nrows() < direct.coords.nrows() || framed.coords.nrows() <= 60);
        for i in [0, 1, 17, 500, s.ncols() - 1] {
            let a = framed.fold(i, 40).expect("fold").expect("nonzero");
            let b = direct.fold(i, 40).expect("fold").expect("nonzero");
            assert_eq!(a.basis_len, b.basis_len, "fold {i}");
            for (m, (x, y)) in a.errors.iter().zip(&b.errors).enumerate() {
                assert!((x - y).abs() <= 1e-9, "fold {i}, m = {}: {x} vs {y}", m + 1);
            }
        }
    }
}
