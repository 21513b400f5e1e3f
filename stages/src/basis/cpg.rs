//! Cone-Projected Greedy (CPG) dual basis (paper Sec. 2.3.1, eq. 12; the rule is stated in
//! docs/scenes.md#study-settings).
//!
//! Start from the empty cone. At each step compute, for every training snapshot `s_j` with
//! `||s_j|| > 0`, its relative cone-projection error `e_j = ||s_j - Pi_m(s_j)|| / ||s_j||` onto
//! the cone of the generators selected so far (zero snapshots are in every cone and are
//! skipped); add the snapshot with the largest `e_j` (ties within a relative 1e-12: larger
//! norm, then lower index), normalised to unit Euclidean norm. After each addition record
//! `C(m) = ||S - Pi_m(S)||_F / ||S||_F` (eq. 16). Stop when `C(m) <= tol`, or when every
//! snapshot has `e_j <= CPG_FLOOR` ([`super::pick`]: represented by the cone to the accuracy
//! the snapshots are known to — so a duplicate, a positive multiple of a selected snapshot or a
//! near-duplicate that differs from the cone by solver noise is never added). Tolerance 0 keeps every snapshot
//! that the cone does not represent to that accuracy.
//!
//! # Lazy selection
//!
//! The cone only grows, so a snapshot's error can only shrink: its last computed error is an
//! upper bound. The selection keeps the bounds in a max-heap and, at each step, re-projects
//! (warm-started from that snapshot's last coefficients, [`ConeProjector::project_warm`]) only
//! the candidates whose bound lies within a band `BAND_REL`/`BAND_ABS` of the best fresh error
//! found so far; every other candidate's true error is below the band, so it can neither win
//! nor take part in a tie (the tie rule compares errors within a relative 1e-12, far inside
//! the band). The winner is chosen by the same scan as the direct method over the fresh
//! candidates in index order. Typically a handful of projections per step instead of N.
//!
//! The selection does not need `C(m)`: with tolerance 0, `C(m) = 0` means every snapshot is in
//! the cone, which the candidate test already detects. [`cpg_path`] therefore selects the
//! whole tolerance-0 order lazily and then computes `C(m)` for every m with one
//! [`GrowingCone`] pass over that order (the direct method's projections, so the same
//! numbers); a basis at tolerance `tol` is the prefix up to the first `C(m) <= tol` (greedy and
//! deterministic). The same pass records what the metrics need: the training snapshots' NNLS
//! coefficients (specificity) and each snapshot's own errors (cone leave-one-out, see
//! `metrics::generalization`). [`cpg_reference`](super::cpg_reference) is the direct method,
//! kept for tests.

use faer::{Mat, MatRef};
use rayon::prelude::*;

use super::lazy::{sparse, LazyGreedy, Refresh, Step};
use super::pick::{scan, scan_trajectory};
use crate::cone::{copy_column, norm2, ColumnIndex, ConeError, ConeProjector, GrowingCone, NnlsParams, WideNnls};

/// Parameters of [`cpg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpgParams {
    /// Stop once the compactness `C(m)` (eq. 16) is at most this (default 0: keep every
    /// snapshot not already in the cone).
    pub tol: f64,
    /// Parameters of the cone projections (default [`NnlsParams::default`]).
    pub nnls: NnlsParams,
}

impl Default for CpgParams {
    fn default() -> Self {
        Self { tol: 0.0, nnls: NnlsParams::default() }
    }
}

/// A CPG basis.
#[derive(Debug, Clone)]
pub struct Cpg {
    /// Unit-norm generators in order of selection, n x m.
    pub basis: Mat<f64>,
    /// Column index in the snapshot matrix of each generator (length m).
    pub selected: Vec<usize>,
    /// `C(0..=m)`: `C(0) = 1` for a nonzero S. An all-zero S gives an empty basis and
    /// `compactness = [0.0]` (nothing to compress: `||S - Pi(S)||_F = 0`).
    pub compactness: Vec<f64>,
}

/// Greedy cone basis of the snapshots `s` (n x N, one per column): the lazy selection, then
/// `C(m)` by one pass over it (stopped at the tolerance).
pub fn cpg(s: MatRef<'_, f64>, params: CpgParams) -> Result<Cpg, ConeError> {
    let path_params = CpgPathParams { nnls: params.nnls, max_rank: 0, dense_max: usize::MAX, wide_above: usize::MAX };
    let path = cpg_path_until(s, path_params, params.tol, &[], &|| {})?;
    Ok(path.truncated(params.tol))
}

/// Above this many snapshots, [`cpg_path`] computes `C(m)` beyond the metrics' ranks on a
/// rank grid (the default of [`CpgPathParams::dense_max`]). Every `C(m)` costs one cone
/// projection per snapshot, so the whole curve of a path of k ~ N generators costs ~N^2/2
/// projections: 0.5 M at N = 1 025 (a few seconds), 134 M at N = 16 385 (hours).
pub const DENSE_CURVE_MAX: usize = 1025;

/// Where the rank grid of a large path starts when no larger `max_rank` is asked for: every
/// `C(m)` up to this rank is computed (the part of the curve a reader looks at).
pub const GRID_START: usize = 256;

/// Parameters of [`cpg_path`] (default: default NNLS parameters, `max_rank` 0, the whole
/// curve up to [`DENSE_CURVE_MAX`] snapshots).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpgPathParams {
    /// Parameters of the cone projections.
    pub nnls: NnlsParams,
    /// Record the metrics' data (specificity intervals, leave-one-out errors) for
    /// m = 1..=max_rank (capped at the basis size). 0 records nothing.
    pub max_rank: usize,
    /// Up to this many snapshots `C(m)` is computed for every m (the paper's curve). Above it,
    /// for every m up to `max(max_rank, GRID_START)`, then on the doubling grid
    /// `2 m_0, 4 m_0, ...` and at k; the other entries of [`CpgPath::compactness`] are NaN.
    pub dense_max: usize,
    /// Above this many snapshots the selection holds its cone without the Gram matrix
    /// ([`WideNnls`]): a path of k generators needs `8 k^2` bytes of Gram matrix (2.1 GB at
    /// k = 16 385) and `Theta^T s_j` per candidate (as much again), against `8 n k` for the
    /// generators themselves.
    pub wide_above: usize,
}

impl Default for CpgPathParams {
    fn default() -> Self {
        Self { nnls: NnlsParams::default(), max_rank: 0, dense_max: DENSE_CURVE_MAX, wide_above: DENSE_CURVE_MAX }
    }
}

/// The whole tolerance-0 CPG path of a snapshot set, shared by the basis (any tolerance is a
/// prefix), the cone compactness, the cone specificity and the cone leave-one-out.
#[derive(Debug, Clone)]
pub struct CpgPath {
    /// Unit-norm generators in order of selection, n x k.
    pub basis: Mat<f64>,
    /// Snapshot index of each generator (length k).
    pub selected: Vec<usize>,
    /// `C(0..=k)` of eq. 16 (`[0.0]` for an all-zero S). Above
    /// [`CpgPathParams::dense_max`] snapshots, NaN at the ranks off the grid (see
    /// [`CpgPathParams::dense_max`]) except where a tolerance asked of [`cpg_path_refined`]
    /// was located.
    pub compactness: Vec<f64>,
    /// The `max_rank` requested: the metrics' data is recorded for m = 1..=min(k, max_rank),
    /// and leave-one-out folds can be evaluated up to m = max_rank.
    pub max_rank: usize,
    /// Specificity sampling intervals: `cone_ranges[m - 1]` (m entries) from the NNLS
    /// coefficients of every training snapshot on the first m generators, m = 1..=min(k,
    /// max_rank) (the same numbers as `metrics::specificity_cone` computes).
    pub cone_ranges: Vec<Vec<(f64, f64)>>,
    pub(crate) loo: LooData,
}

/// What the cone leave-one-out folds need from the full path (see
/// `metrics::generalization`).
#[derive(Debug, Clone, Default)]
pub(crate) struct LooData {
    /// `||s_j||` (column norms, as the projections use them).
    pub(crate) norms: Vec<f64>,
    /// `||s_j||` as the single-column compactness of the direct fold computes it.
    pub(crate) single_norms: Vec<f64>,
    /// First step (1-based) at which the selection without snapshot j differs from the full
    /// one (`usize::MAX`: never).
    pub(crate) diverge: Vec<usize>,
    /// Relative errors of s_j on the first m generators, m = 1..=min(k, max_rank).
    pub(crate) errors: Vec<Vec<f64>>,
    /// Coefficients and residual of s_j on the cone of the first `diverge[j] - 1` generators
    /// (recorded when `diverge[j] <= max_rank`).
    pub(crate) start: Vec<Option<(Vec<f64>, f64)>>,
    /// Every lazy projection of the full selection, per snapshot.
    pub(crate) history: Vec<Vec<Refresh>>,
    /// The cone of all k generators.
    pub(crate) projector: Option<ConeProjector>,
}

impl CpgPath {
    /// Number k of generators on the path.
    pub fn len(&self) -> usize {
        self.selected.len()
    }

    /// True for an empty path (all-zero snapshots).
    pub fn is_empty(&self) -> bool {
        self.selected.is_empty()
    }

    /// Number of generators of the basis at tolerance `tol`: the first m with `C(m) <= tol`,
    /// else k. On a grid path, exact for the tolerances given to [`cpg_path_refined`]; for
    /// others the first grid rank with `C(m) <= tol` (an upper bound).
    pub fn rank_at(&self, tol: f64) -> usize {
        self.compactness.iter().position(|&c| c <= tol).unwrap_or(self.len()).min(self.len())
    }

    /// The CPG basis at tolerance `tol` (what [`cpg`] returns): a prefix of the path.
    pub fn truncated(&self, tol: f64) -> Cpg {
        let m = self.rank_at(tol);
        let compactness = if self.is_empty() { vec![self.compactness[0]] } else { self.compactness[..=m].to_vec() };
        Cpg { basis: self.basis.subcols(0, m).to_owned(), selected: self.selected[..m].to_vec(), compactness }
    }
}

/// The tolerance-0 CPG path of `s` (n x N) with the metrics' data up to `params.max_rank`;
/// `tick` is called once per selected generator and once per rank m of the compactness pass
/// (2k times in all, k <= N: a progress bar of 2N steps that jumps to its end when k < N).
pub fn cpg_path(s: MatRef<'_, f64>, params: CpgPathParams, tick: &(dyn Fn() + Sync)) -> Result<CpgPath, ConeError> {
    cpg_path_until(s, params, -1.0, &[], tick)
}

/// The first `max_m` generators (unit columns, in order) of the tolerance-0 CPG path of `s`:
/// the lazy selection stopped after `max_m` steps, without the path's compactness pass. The
/// greedy picks each generator from the ones before it only, so these are the first columns of
/// [`cpg_path`]'s basis, bit for bit.
pub fn cpg_prefix(s: MatRef<'_, f64>, max_m: usize, nnls: NnlsParams) -> Result<Mat<f64>, ConeError> {
    let norms: Vec<f64> = (0..s.ncols()).map(|j| s.col(j).norm_l2()).collect();
    let wide = s.ncols() > CpgPathParams::default().wide_above;
    let mut lazy = LazyGreedy::new(s, &norms, nnls, 0, wide);
    if s.norm_l2() > 0.0 {
        while lazy.len() < max_m && lazy.step()?.is_some() {}
    }
    Ok(lazy.basis())
}

/// [`cpg_path`] whose [`rank_at`](CpgPath::rank_at) is exact at each of `tols` also on a grid
/// path: the grid interval where `C(m)` first reaches a tolerance is bisected (`C(m)` does not
/// increase with m, the cone only grows), about `log2(interval)` more evaluations.
pub fn cpg_path_refined(
    s: MatRef<'_, f64>,
    params: CpgPathParams,
    tols: &[f64],
    tick: &(dyn Fn() + Sync),
) -> Result<CpgPath, ConeError> {
    cpg_path_until(s, params, -1.0, tols, tick)
}

/// [`cpg_path`] whose compactness pass stops at the first `C(m) <= stop` (`stop < 0`: never).
fn cpg_path_until(
    s: MatRef<'_, f64>,
    params: CpgPathParams,
    stop: f64,
    tols: &[f64],
    tick: &(dyn Fn() + Sync),
) -> Result<CpgPath, ConeError> {
    let count = s.ncols();
    let norms: Vec<f64> = (0..count).map(|j| s.col(j).norm_l2()).collect();
    let total = s.norm_l2();
    let record = params.max_rank > 0;
    let mut lazy = LazyGreedy::new(s, &norms, params.nnls, params.max_rank, count > params.wide_above);
    let mut selected = Vec::new();
    let mut diverge = vec![usize::MAX; count];
    if total > 0.0 {
        while let Some(step) = lazy.step()? {
            let t = selected.len() + 1;
            if record {
                mark_divergence(&step, &norms, t, &mut diverge);
            }
            selected.push(step.pick);
            tick();
        }
    }
    let k = selected.len();
    let max_rank = params.max_rank.min(k);
    let requested = params.max_rank;
    let dense_to = if count <= params.dense_max { k } else { k.min(params.max_rank.max(GRID_START)) };
    let mut compactness = vec![if total > 0.0 { 1.0 } else { 0.0 }];
    let mut cone_ranges = Vec::with_capacity(max_rank);
    let mut errors = vec![Vec::with_capacity(max_rank); if record { count } else { 0 }];
    let mut start = vec![None; if record { count } else { 0 }];
    let single_norms: Vec<f64> =
        if record { (0..count).map(|j| s.subcols(j, 1).norm_l2()).collect() } else { Vec::new() };
    let mut cone = ChunkedCone::new(s, params.nnls);
    let mut column = vec![0.0; s.nrows()];
    for (t, &g) in selected[..dense_to].iter().enumerate() {
        if compactness[t] <= stop {
            break;
        }
        if record {
            for j in (0..count).filter(|&j| diverge[j] == t + 1 && t < max_rank) {
                start[j] = Some((cone.coeffs(j).to_vec(), cone.residual(j)));
            }
        }
        copy_column(s, g, &mut column);
        column.iter_mut().for_each(|v| *v /= norms[g]);
        cone.push(&column)?;
        compactness.push(cone.frobenius_residual() / total);
        if t < max_rank {
            if record {
                for (j, e) in errors.iter_mut().enumerate() {
                    e.push(norm2(&[cone.residual(j)]) / single_norms[j]);
                }
            }
            cone_ranges.push(cone.coefficient_intervals(t + 1));
        }
        tick();
    }
    let basis = lazy.basis();
    if compactness.len() == dense_to + 1 && dense_to < k && compactness[dense_to] > stop {
        let mut grid = RankGrid::new(s, basis.as_ref(), &selected, &norms, total, &cone, params.nnls);
        drop(cone);
        compactness.resize(k + 1, f64::NAN);
        let mut m = dense_to;
        while m < k {
            let next = (2 * m).min(k);
            compactness[next] = grid.eval(next)?;
            (m..next).for_each(|_| tick());
            m = next;
            if compactness[m] <= stop {
                compactness.truncate(m + 1);
                break;
            }
        }
        for &tol in tols.iter().filter(|&&tol| tol > 0.0) {
            grid.locate(&mut compactness, tol)?;
        }
    }
    let history = lazy.history.take().unwrap_or_default();
    let projector = record.then(|| lazy.prefix(max_rank));
    let loo = LooData { norms, single_norms, diverge, errors, start, history, projector };
    Ok(CpgPath { basis, selected, compactness, max_rank: requested, cone_ranges, loo })
}

/// The dense compactness pass split into contiguous column blocks, one [`GrowingCone`] each,
/// pushed in parallel. Each snapshot's chain of warm-started projections depends only on the
/// generators (the same Gram entries in every block) and on itself, so every number is the
/// same bit for bit whatever the blocks; the sums over snapshots run in index order.
struct ChunkedCone<'a> {
    size: usize,
    chunks: Vec<GrowingCone<'a>>,
}

impl<'a> ChunkedCone<'a> {
    fn new(s: MatRef<'a, f64>, nnls: NnlsParams) -> Self {
        let count = s.ncols();
        let pieces = (2 * rayon::current_num_threads()).clamp(1, count.max(1));
        let size = count.div_ceil(pieces).max(1);
        let chunks =
            (0..count).step_by(size).map(|a| GrowingCone::new(s.subcols(a, size.min(count - a)), nnls)).collect();
        Self { size, chunks }
    }

    fn push(&mut self, column: &[f64]) -> Result<(), ConeError> {
        self.chunks.par_iter_mut().map(|c| c.push(column)).collect::<Result<Vec<()>, _>>().map(|_| ())
    }

    fn residual(&self, j: usize) -> f64 {
        self.chunks[j / self.size].residuals()[j % self.size]
    }

    fn coeffs(&self, j: usize) -> &[f64] {
        self.chunks[j / self.size].coeffs(j % self.size)
    }

    /// `||S - Pi(S)||_F`, summed in snapshot order (as [`GrowingCone::frobenius_residual`]).
    fn frobenius_residual(&self) -> f64 {
        self.chunks.iter().flat_map(|c| c.residuals()).map(|a| a * a).sum::<f64>().sqrt()
    }

    /// [`GrowingCone::coefficient_intervals`] over every block, in snapshot order.
    fn coefficient_intervals(&self, m: usize) -> Vec<(f64, f64)> {
        let coeffs = self.chunks.iter().flat_map(|c| (0..c.norms().len()).map(move |j| c.coeffs(j)));
        crate::cone::coefficient_intervals(m, coeffs)
    }
}

/// `C(m)` at single ranks beyond the dense part of a large path: every snapshot that is not
/// one of the first m generators is projected on their cone with [`WideNnls`] (no m x m Gram
/// matrix), warm-started from its support at the previous evaluation; a generator's own error
/// is 0 (it is a positive multiple of a generator). Snapshots are projected in parallel, each
/// on its own, and summed in index order: the same bits whatever the thread count.
struct RankGrid<'s> {
    s: MatRef<'s, f64>,
    basis: MatRef<'s, f64>,
    /// Each generator's non-zero rows.
    windows: ColumnIndex,
    /// Position of each snapshot on the path (`usize::MAX`: not selected).
    position: Vec<usize>,
    norms: &'s [f64],
    total: f64,
    nnls: NnlsParams,
    /// Supports at the end of the dense pass (warm starts of the bisection's evaluations).
    dense: Vec<Vec<(usize, f64)>>,
    /// Supports at the last grid rank.
    last: Vec<Vec<(usize, f64)>>,
}

impl<'s> RankGrid<'s> {
    fn new(
        s: MatRef<'s, f64>,
        basis: MatRef<'s, f64>,
        selected: &[usize],
        norms: &'s [f64],
        total: f64,
        cone: &ChunkedCone<'_>,
        nnls: NnlsParams,
    ) -> Self {
        let mut position = vec![usize::MAX; s.ncols()];
        selected.iter().enumerate().for_each(|(p, &j)| position[j] = p);
        let dense: Vec<Vec<(usize, f64)>> = (0..s.ncols()).map(|j| sparse(cone.coeffs(j))).collect();
        let windows = ColumnIndex::of(basis);
        Self { s, basis, windows, position, norms, total, nnls, last: dense.clone(), dense }
    }

    /// `C(m)`, warm-started from the last grid rank's supports (which it replaces).
    fn eval(&mut self, m: usize) -> Result<f64, ConeError> {
        let mut supports = std::mem::take(&mut self.last);
        let c = self.eval_with(m, &mut supports);
        self.last = supports;
        c
    }

    fn eval_with(&self, m: usize, supports: &mut [Vec<(usize, f64)>]) -> Result<f64, ConeError> {
        let (n, theta) = (self.s.nrows(), self.basis.subcols(0, m));
        let residuals = supports
            .par_iter_mut()
            .enumerate()
            .map_init(
                || (WideNnls::new(n, m, self.nnls), vec![0.0; n]),
                |(wide, lambda), (j, support)| {
                    if self.norms[j] <= 0.0 || self.position[j] < m {
                        return Ok(0.0);
                    }
                    copy_column(self.s, j, lambda);
                    wide.project_windowed(theta, Some(&self.windows), lambda, support)
                },
            )
            .collect::<Result<Vec<f64>, ConeError>>()?;
        Ok(norm2(&residuals) / self.total)
    }

    /// Fill `C(m)` at the first m with `C(m) <= tol` by bisecting the grid interval that
    /// contains it (nothing to do when its lower end is already evaluated).
    fn locate(&self, compactness: &mut [f64], tol: f64) -> Result<(), ConeError> {
        let Some(mut hi) = compactness.iter().position(|&c| c <= tol) else { return Ok(()) };
        let Some(mut lo) = compactness[..hi].iter().rposition(|c| !c.is_nan()) else { return Ok(()) };
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            let mut supports = self.dense.clone();
            compactness[mid] = self.eval_with(mid, &mut supports)?;
            if compactness[mid] <= tol {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Ok(())
    }
}

/// Fold j (snapshot j left out) picks differently from the full run at step t when the full
/// run picks j, or when j carried the tie scan to the winner (the scan is not transitive:
/// removing a running best can change the outcome).
fn mark_divergence(step: &Step, norms: &[f64], t: usize, diverge: &mut [usize]) {
    diverge[step.pick] = diverge[step.pick].min(t);
    let trajectory = scan_trajectory(&step.band, norms);
    for &c in trajectory.iter().filter(|&&c| c != step.pick) {
        if scan(step.band.iter().copied(), norms, Some(c)) != Some(step.pick) {
            diverge[c] = diverge[c].min(t);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::basis::CPG_FLOOR;
    use crate::cone::ConeProjector;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::testing::{bumps, hertz_family};
    use crate::{assert_all_close, basis::cpg_reference};

    fn relative_cone_errors(basis: MatRef<'_, f64>, s: MatRef<'_, f64>) -> Vec<f64> {
        let mut proj = ConeProjector::new(basis, NnlsParams::default());
        let (_, res) = proj.project_many(s).expect("converges");
        (0..s.ncols()).map(|j| res[j] / s.col(j).norm_l2().max(f64::MIN_POSITIVE)).collect()
    }

    #[test]
    fn tolerance_zero_spans_every_snapshot() {
        let mut rng = Rng::new(51);
        let s = bumps(&mut rng, 40, 25, (1.0, 4.0));
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        for (j, e) in relative_cone_errors(out.basis.as_ref(), s.as_ref()).iter().enumerate() {
            // Every training snapshot is in the final cone: 1e-10 relative (round-off of a
            // Gram-matrix NNLS on unit generators).
            assert!(*e <= 1e-10, "snapshot {j} has relative cone error {e:e}");
        }
        // Compactness ends at ~0 (same 1e-10) and the basis has unit columns.
        assert_close!(*out.compactness.last().expect("nonempty"), 0.0, Tol::abs(1e-10));
        for m in 0..out.basis.ncols() {
            assert_close!(out.basis.col(m).norm_l2(), 1.0, Tol::abs(1e-14)); // one division
        }
    }

    #[test]
    fn duplicates_multiples_and_zeros_are_not_selected() {
        let mut rng = Rng::new(52);
        let base = bumps(&mut rng, 30, 8, (1.0, 4.0));
        // Columns: 0..8 base, 8 = copy of 2, 9 = 3 * column 5, 10 = zero, 11 = copy of 0.
        let s = Mat::from_fn(30, 12, |i, j| match j {
            0..=7 => base[(i, j)],
            8 => base[(i, 2)],
            9 => 3.0 * base[(i, 5)],
            10 => 0.0,
            _ => base[(i, 0)],
        });
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        assert!(!out.selected.contains(&10), "zero snapshot selected: {:?}", out.selected);
        for (a, b) in [(2, 8), (5, 9), (0, 11)] {
            let both = out.selected.contains(&a) && out.selected.contains(&b);
            assert!(!both, "rays {a} and {b} both selected: {:?}", out.selected);
        }
        let mut sorted = out.selected.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), out.selected.len(), "an index selected twice");
        assert!(out.selected.len() <= 8, "at most the 8 distinct rays: {:?}", out.selected);
    }

    #[test]
    fn compactness_is_non_increasing_and_stops_at_tolerance() {
        let mut rng = Rng::new(53);
        let s = bumps(&mut rng, 50, 40, (1.0, 4.0));
        let full = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        assert_close!(full.compactness[0], 1.0, Tol::abs(0.0)); // set exactly
        for w in full.compactness.windows(2) {
            // The cone only grows: C can only decrease, up to NNLS round-off (1e-12).
            assert!(w[1] <= w[0] + 1e-12, "compactness increased: {w:?}");
        }
        let tol = 0.2;
        let cut = cpg(s.as_ref(), CpgParams { tol, ..CpgParams::default() }).expect("converges");
        let m = cut.selected.len();
        assert!(cut.compactness[m] <= tol && cut.compactness[m - 1] > tol);
        // Greedy and deterministic: the truncated run is a prefix of the full one.
        assert_eq!(cut.selected[..], full.selected[..m]);
    }

    #[test]
    fn ties_prefer_larger_norm_then_lower_index() {
        // Empty cone: every relative error is 1, so the first pick is the largest norm.
        let s = Mat::from_fn(3, 4, |i, j| match (i, j) {
            (0, 0) => 1.0,
            (1, 1) | (2, 2) => 3.0,
            (0, 3) => 2.0,
            _ => 0.0,
        });
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        // Columns 1 and 2 tie (error 1, norm 3): lower index first; column 3 is a multiple of
        // column 0, and column 0 (err 1, norm 1) loses to column 3 (err 1, norm 2).
        assert_eq!(out.selected, vec![1, 2, 3]);
    }

    #[test]
    fn all_zero_snapshots_give_an_empty_basis() {
        let out = cpg(Mat::<f64>::zeros(5, 3).as_ref(), CpgParams::default()).expect("trivial");
        assert_eq!((out.basis.nrows(), out.basis.ncols()), (5, 0));
        assert!(out.selected.is_empty());
        assert_eq!(out.compactness.len(), 1);
        assert_close!(out.compactness[0], 0.0, Tol::abs(0.0));
    }

    #[test]
    fn cone_of_the_snapshots_reproduces_them() {
        let mut rng = Rng::new(54);
        let s = bumps(&mut rng, 30, 10, (1.0, 4.0));
        for (j, e) in relative_cone_errors(s.as_ref(), s.as_ref()).iter().enumerate() {
            // s_j = Theta e_j exactly: the residual is round-off, 1e-12 relative.
            assert!(*e <= 1e-12, "snapshot {j}: relative error {e:e}");
        }
    }

    #[test]
    fn tolerance_zero_on_an_ill_conditioned_family_reaches_zero() {
        // Hertz-like pressures sqrt(1 - ((x - c)/a)^2)_+ with slowly moving centre and width:
        // neighbouring snapshots are nearly parallel, the cone is badly conditioned. Every
        // snapshot is selected (each is an extreme ray), so C(m) must end at round-off;
        // warm-started projections alone stalled at ~1e-6 here (KKT test resolution).
        let (n, count) = (60, 64);
        let s = Mat::from_fn(n, count, |i, j| {
            let x = i as f64 / n as f64;
            let mu = j as f64 / (count - 1) as f64;
            let d = (x - 0.3 - 0.4 * mu) / (0.05 + 0.4 * mu);
            (1.0 - d * d).max(0.0).sqrt() * (1.0 + mu)
        });
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        // 1e-10: round-off of unit generators is ~1e-14; the stalled value was ~1e-7.
        assert_close!(*out.compactness.last().expect("nonempty"), 0.0, Tol::abs(1e-10));
    }

    /// Snapshots known to a relative accuracy of 1e-10: three unit generators with disjoint
    /// supports, then 60 convex combinations of them (all weights positive), each perturbed by
    /// non-negative noise of relative size up to 1e-10, as solver noise perturbs near-duplicate
    /// pressures. A generator has relative error 1 against a cone of the others (disjoint
    /// support) and a combination less, and a combination's norm is below 1, so the greedy
    /// takes the generators first, in index order; then every combination lies within about
    /// 1e-10 of their cone, below [`CPG_FLOOR`], and no generator is added (the noise makes
    /// each combination an extreme ray: with the floor at round-off, 1e-12, all 63 would be
    /// selected). The direct method agrees.
    #[test]
    fn noise_below_the_floor_adds_no_generator() {
        let (block, count) = (15, 63);
        let n = 3 * block;
        let bump = |i: usize| {
            let d = (i as f64 + 0.5) / block as f64 * 2.0 - 1.0;
            1.0 - d * d
        };
        let unit = (0..block).map(|i| bump(i) * bump(i)).sum::<f64>().sqrt();
        let base = |i: usize, g: usize| if i / block == g { bump(i % block) / unit } else { 0.0 };
        let mut rng = Rng::new(57);
        let s = Mat::from_fn(n, count, |i, j| match j {
            0..=2 => base(i, j),
            _ => {
                let w = [(j % 7) as f64 + 0.5, (j % 5) as f64 + 0.25, (j % 3) as f64 + 0.1];
                let sum: f64 = w.iter().sum();
                (0..3).map(|g| w[g] / sum * base(i, g)).sum::<f64>() + 1e-10 * rng.uniform() / (n as f64).sqrt()
            }
        });
        let errors = relative_cone_errors(s.subcols(0, 3), s.as_ref());
        assert!(errors.iter().skip(3).all(|e| *e > 1e-12), "the noise puts every combination outside the cone");
        assert!(errors.iter().all(|e| *e < CPG_FLOOR), "and within the floor: {errors:?}");
        let lazy = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        let direct = cpg_reference(s.as_ref(), CpgParams::default()).expect("converges");
        assert_eq!(lazy.selected, vec![0, 1, 2]);
        assert_eq!(direct.selected, vec![0, 1, 2]);
    }

    /// The lazy selection against the direct one on ironing-like pressures (near-duplicates,
    /// an exact duplicate tie, a zero column, a positive multiple, a sum) and random bumps.
    #[test]
    fn lazy_cpg_equals_the_reference() {
        let cases = [
            hertz_family(&mut Rng::new(55), 101, 64),
            hertz_family(&mut Rng::new(56), 101, 128),
            hertz_family(&mut Rng::new(57), 30, 48), // more snapshots than nodes
            bumps(&mut Rng::new(58), 40, 60, (1.0, 4.0)),
        ];
        for s in &cases {
            let slow = cpg_reference(s.as_ref(), CpgParams::default()).expect("converges");
            let fast = cpg(s.as_ref(), CpgParams::default()).expect("converges");
            assert_eq!(fast.selected, slow.selected, "selection order differs");
            // Same generators pushed in the same order, and C(m) from the same warm-started
            // projections of every snapshot (the direct method's pass): bit for bit.
            assert_all_close!(fast.compactness, slow.compactness, Tol::abs(0.0));
            assert_close!((&fast.basis - &slow.basis).norm_l2(), 0.0, Tol::abs(0.0));
            for tol in [0.05, 0.2] {
                let slow = cpg_reference(s.as_ref(), CpgParams { tol, ..CpgParams::default() }).expect("ok");
                let fast = cpg(s.as_ref(), CpgParams { tol, ..CpgParams::default() }).expect("ok");
                assert_eq!(fast.selected, slow.selected, "tol {tol}");
                assert_all_close!(fast.compactness, slow.compactness, Tol::abs(0.0));
                // as above
            }
        }
        let s = &cases[0];
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        assert!(!out.selected.contains(&5), "zero column selected");
        assert!(!(out.selected.contains(&8) && out.selected.contains(&9)), "both twins selected");
        // Column 21 = 19 + 20 is in their cone: never selected after both of them.
        let at = |j| out.selected.iter().position(|&g| g == j).unwrap_or(usize::MAX);
        assert!(at(21) == usize::MAX || at(21) < at(19).max(at(20)), "{:?}", out.selected);
    }

    #[test]
    fn one_path_serves_every_tolerance() {
        let s = hertz_family(&mut Rng::new(59), 101, 64);
        let path = cpg_path(s.as_ref(), CpgPathParams { max_rank: 10, ..CpgPathParams::default() }, &|| {})
            .expect("converges");
        let full = cpg_reference(s.as_ref(), CpgParams::default()).expect("converges");
        assert_eq!(path.selected, full.selected);
        assert_all_close!(path.compactness, full.compactness, Tol::abs(0.0)); // same pass, bit for bit
        for tol in [0.0, 0.01, 0.05, 0.3, 1.0] {
            let cut = cpg_reference(s.as_ref(), CpgParams { tol, ..CpgParams::default() }).expect("ok");
            let mine = path.truncated(tol);
            assert_eq!(mine.selected, cut.selected, "tol {tol}");
            assert_all_close!(mine.compactness, cut.compactness, Tol::abs(0.0));
        }
        assert_eq!(path.cone_ranges.len(), 10);
    }

    /// The selection without the Gram matrix (forced on a small set) picks the Gram
    /// selection's generators in the same order on two families (smooth Hertz-like pressures,
    /// random bumps with many near-ties late in the path), so the basis, the curve (the same
    /// compactness pass) and the metrics' data of that pass are the same bits; the two
    /// selections differ only in the round-off of the candidates' errors, far below the
    /// refresh band.
    #[test]
    fn selection_without_the_gram_picks_the_same_generators() {
        let families = [hertz_family(&mut Rng::new(63), 101, 300), bumps(&mut Rng::new(64), 60, 400, (2.0, 9.0))];
        for (f, s) in families.iter().enumerate() {
            let gram_params = CpgPathParams { max_rank: 8, wide_above: usize::MAX, ..CpgPathParams::default() };
            let gram = cpg_path(s.as_ref(), gram_params, &|| {}).expect("converges");
            let wide = cpg_path(s.as_ref(), CpgPathParams { wide_above: 0, ..gram_params }, &|| {}).expect("converges");
            assert!(gram.len() > 50, "family {f}: the test needs a long path, got {}", gram.len());
            assert_eq!(wide.selected, gram.selected, "family {f}");
            assert_eq!(wide.basis, gram.basis, "family {f}");
            assert_eq!(wide.compactness, gram.compactness, "family {f}");
            assert_eq!(wide.cone_ranges, gram.cone_ranges, "family {f}");
            // Bit patterns: the errors hold NaN where a snapshot has no error at a rank.
            let bits = |e: &[Vec<f64>]| {
                e.iter().map(|r| r.iter().map(|v| v.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>()
            };
            assert_eq!(bits(&wide.loo.errors), bits(&gram.loo.errors), "family {f}");
        }
    }

    /// A path on a rank grid (dense part forced small) against the whole curve: the dense
    /// part and the selection are bit-identical (the same projections), every grid value
    /// agrees with the whole curve's to 1e-10 (the Gram-free projections against the Gram
    /// projector's, both at a 1e-12 KKT tolerance on unit generators; C(m) <= 1), and the
    /// refined tolerances give the same basis size as the whole curve.
    #[test]
    fn rank_grid_agrees_with_the_whole_curve() {
        let mut rng = Rng::new(61);
        let s = bumps(&mut rng, 60, 400, (2.0, 9.0));
        let dense_params = CpgPathParams { max_rank: 8, dense_max: usize::MAX, ..CpgPathParams::default() };
        let dense = cpg_path(s.as_ref(), dense_params, &|| {}).expect("converges");
        let k = dense.len();
        assert!(k > GRID_START + 40, "the test needs a path past the grid start, got {k}");
        // Tolerances reached inside the dense part, and one (midway between the whole curve's
        // C at GRID_START + 36 and + 37, far from both next to the 1e-10 agreement) reached
        // between two grid ranks, which the bisection must find.
        let c = &dense.compactness;
        assert!(c[GRID_START + 36] - c[GRID_START + 37] > 1e-8);
        let tols = [0.05, 0.01, 0.5 * (c[GRID_START + 36] + c[GRID_START + 37]), 0.0];
        assert!(dense.rank_at(tols[2]) > GRID_START && dense.rank_at(tols[2]) < 2 * GRID_START);
        let grid_params = CpgPathParams { dense_max: 10, ..dense_params };
        let ticks = std::sync::atomic::AtomicUsize::new(0);
        let tick = || {
            ticks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        };
        let grid = cpg_path_refined(s.as_ref(), grid_params, &tols, &tick).expect("converges");
        assert_eq!(ticks.into_inner(), 2 * k, "one tick per selection and per rank");
        assert_eq!(grid.selected, dense.selected);
        assert_eq!(grid.compactness.len(), k + 1);
        let dense_to = GRID_START.min(k);
        assert_eq!(grid.compactness[..=dense_to], dense.compactness[..=dense_to]);
        let mut evaluated = 0;
        for m in dense_to + 1..=k {
            if grid.compactness[m].is_nan() {
                continue;
            }
            evaluated += 1;
            assert_close!(grid.compactness[m], dense.compactness[m], Tol::abs(1e-10));
        }
        assert!(evaluated >= 1 && grid.compactness[k] <= 1e-10, "C(k) = {}", grid.compactness[k]);
        for tol in tols {
            assert_eq!(grid.rank_at(tol), dense.rank_at(tol), "tolerance {tol}");
        }
        // The metrics' data is the dense pass's.
        assert_eq!(grid.cone_ranges, dense.cone_ranges);
        assert_eq!(grid.loo.errors, dense.loo.errors);
    }

    /// The dense pass splits the snapshots into blocks by thread count; the path is the same
    /// bits on one thread and on three.
    #[test]
    fn path_is_the_same_on_any_thread_count() {
        let mut rng = Rng::new(62);
        let s = bumps(&mut rng, 40, 150, (2.0, 8.0));
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            let params = CpgPathParams { max_rank: 20, dense_max: 60, ..CpgPathParams::default() };
            pool.install(|| cpg_path_refined(s.as_ref(), params, &[0.02], &|| {}).expect("converges"))
        };
        let (one, three) = (run(1), run(3));
        assert_eq!(one.selected, three.selected);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one.compactness), bits(&three.compactness));
        assert_eq!(one.cone_ranges, three.cone_ranges);
        assert_eq!(one.loo.errors, three.loo.errors);
    }

    /// The prefix is the full path's first generators bit for bit, at sizes below, at and above
    /// the path's length, on bumps and on a Hertz family.
    #[test]
    fn the_prefix_is_the_paths_first_generators() {
        let mut rng = Rng::new(41);
        for s in [bumps(&mut rng, 40, 25, (1.0, 4.0)), hertz_family(&mut rng, 30, 26)] {
            let path = cpg_path(s.as_ref(), CpgPathParams::default(), &|| {}).expect("path");
            assert!(path.len() > 4, "a path of {} checks little", path.len());
            for m in [0, 1, 4, path.len(), path.len() + 3] {
                let prefix = cpg_prefix(s.as_ref(), m, NnlsParams::default()).expect("prefix");
                let k = m.min(path.len());
                assert_eq!(prefix, path.basis.subcols(0, k).to_owned(), "m = {m}");
            }
        }
    }
}
