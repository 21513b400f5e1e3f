//! Lawson–Hanson active-set NNLS on the Gram matrix, with an incrementally updated Cholesky
//! factor of the passive-set sub-Gram matrix.
//!
//! Solves `min ||A x - b||_2  s.t.  x >= 0` given only `G = A^T A` (k x k) and `c = A^T b`, so
//! every right-hand side against one `A` shares one Gram matrix. The dual vector is
//! `w = c - G x = A^T (b - A x)`; see the [module docs](super) for the KKT conditions.
//!
//! The passive set `P` is an ordered list; `L` (row-major, leading dimension k) is the lower
//! Cholesky factor of `G[P, P]` in that order. Adding a column appends one row to `L`
//! (forward substitution); removing one deletes its row and restores the triangle with Givens
//! rotations. All workspaces live in [`Nnls`], so the iteration loop does not allocate.
//!
//! The Gram matrix can grow one column at a time ([`Nnls::push_column`]) and shrink back to a
//! leading block ([`Nnls::prefix`], the cone of the first m generators). Storage grows by
//! capacity doubling, so a cone grown to k generators costs O(k^2) amortised copies in total
//! rather than O(k^3); the Gram entries of a prefix do not depend on later columns, so a
//! prefix solver computes exactly (bit for bit) what a solver grown to that size computes.

use faer::{Mat, MatRef};
use thiserror::Error;

use super::passive_factor;
use rayon::prelude::*;

/// Numerical failure of a cone (NNLS) computation.
#[derive(Debug, Clone, Error)]
pub enum ConeError {
    /// The active-set iteration hit `NnlsParams::max_iter` before the KKT conditions held.
    #[error(
        "NNLS did not converge in {iterations} iterations (relative KKT residual \
         {kkt_residual:e}); raise NnlsParams::max_iter or loosen NnlsParams::tol"
    )]
    NotConverged {
        /// Outer (column-adding) iterations performed.
        iterations: usize,
        /// Relative KKT residual at the last iterate (see [`NnlsStats::kkt_residual`]).
        kkt_residual: f64,
    },
    /// The Gram matrix, the right-hand side or the warm start contains NaN or infinity.
    #[error("NNLS input contains a non-finite value (NaN or infinity)")]
    NonFinite,
}

/// Parameters of the NNLS solvers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NnlsParams {
    /// Maximum number of outer (column-adding) iterations. `None` (the default) means
    /// `3 k + 10` for `k` columns. Inner (column-dropping) steps are bounded by the outer ones.
    pub max_iter: Option<usize>,
    /// Relative KKT tolerance (default `1e-12`): converged when `w_j <= tol * scale` for every
    /// column outside the passive set, with `scale = max_j |c_j| + max_j G_jj * ||x||_1`, a bound
    /// on the magnitude of the terms summed into `w` (so `tol` is a multiple of round-off).
    pub tol: f64,
    /// Relative pivot tolerance (default `1e-12`): a column `t` whose squared Cholesky pivot
    /// (`G_tt` minus its part in the span of the passive columns, i.e. `G_tt sin^2(angle)`) is
    /// `<= pivot_tol * G_tt` is numerically dependent on the passive columns and is refused.
    /// Zero columns are always refused.
    pub pivot_tol: f64,
}

impl Default for NnlsParams {
    fn default() -> Self {
        Self { max_iter: None, tol: 1e-12, pivot_tol: 1e-12 }
    }
}

impl NnlsParams {
    /// The iteration cap for `k` columns.
    pub fn max_iter_for(&self, k: usize) -> usize {
        self.max_iter.unwrap_or(3 * k + 10)
    }
}

/// Convergence evidence of one [`Nnls::solve_normal`] call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NnlsStats {
    /// Outer (column-adding) iterations performed.
    pub iterations: usize,
    /// `max(max_{j in P} |w_j|, max_{j not in P} max(w_j, 0)) / scale` (0 when scale is 0).
    pub kkt_residual: f64,
}

/// Result of [`nnls`].
#[derive(Debug, Clone, PartialEq)]
pub struct NnlsSolution {
    /// The minimiser, length k, all entries `>= 0`.
    pub x: Vec<f64>,
    /// `||b - A x||_2`, computed from the explicit residual.
    pub residual_norm: f64,
    /// Outer (column-adding) iterations performed.
    pub iterations: usize,
    /// Relative KKT residual (see [`NnlsStats::kkt_residual`]).
    pub kkt_residual: f64,
}

/// Lawson–Hanson NNLS working on a fixed Gram matrix, with preallocated workspaces.
#[derive(Debug)]
pub struct Nnls {
    /// `G = A^T A`, k x k.
    gram: Mat<f64>,
    params: NnlsParams,
    /// `max_j G_jj`.
    gmax: f64,
    /// Every entry of `gram` is finite.
    gram_finite: bool,
    /// Lower Cholesky factor of `G[P, P]`, row-major with leading dimension `ld`.
    chol: Vec<f64>,
    /// Leading dimension of `chol`: grown (doubling) with the largest passive set seen, which
    /// is at most the rank of the columns — not with k (a 16 385-column cone in R^101 would
    /// otherwise hold a 2 GB factor of which 101 rows are ever used).
    ld: usize,
    /// Reserved columns (and rows) of `gram`.
    cap: usize,
    /// Passive columns in factor order.
    passive: Vec<usize>,
    in_passive: Vec<bool>,
    /// Columns refused since the last successful addition.
    blocked: Vec<bool>,
    /// The indices set in `blocked` (cleared entry by entry, not by an O(k) fill).
    blocked_list: Vec<usize>,
    /// The passive columns in ascending order (workspace of [`update_dual`](Self::update_dual)).
    sorted: Vec<usize>,
    /// Passive least-squares solution by factor position.
    z: Vec<f64>,
    /// Dual vector `w = c - G x`, by column.
    w: Vec<f64>,
}

impl Clone for Nnls {
    /// A copy that keeps the reserved capacity (so pushes on the copy stay amortised).
    fn clone(&self) -> Self {
        let mut gram = self.gram.clone();
        gram.reserve(self.cap, self.cap);
        Self {
            gram,
            params: self.params,
            gmax: self.gmax,
            gram_finite: self.gram_finite,
            chol: self.chol.clone(),
            ld: self.ld,
            cap: self.cap,
            passive: self.passive.clone(),
            in_passive: self.in_passive.clone(),
            blocked: self.blocked.clone(),
            blocked_list: self.blocked_list.clone(),
            sorted: Vec::new(),
            z: self.z.clone(),
            w: self.w.clone(),
        }
    }
}

impl Nnls {
    /// A solver for the Gram matrix `gram` (k x k, symmetric positive semi-definite).
    pub fn new(gram: Mat<f64>, params: NnlsParams) -> Self {
        assert_eq!(gram.nrows(), gram.ncols(), "Nnls::new: Gram matrix must be square");
        let k = gram.ncols();
        let gmax = (0..k).map(|j| gram[(j, j)]).fold(0.0, f64::max);
        let gram_finite = (0..k).all(|j| gram.col_as_slice(j).iter().all(|g| g.is_finite()));
        Self {
            gram,
            params,
            gmax,
            gram_finite,
            chol: Vec::new(),
            ld: 0,
            cap: k,
            passive: Vec::with_capacity(k),
            in_passive: vec![false; k],
            blocked: vec![false; k],
            blocked_list: Vec::new(),
            sorted: Vec::new(),
            z: vec![0.0; k],
            w: vec![0.0; k],
        }
    }

    /// A solver for the columns of `a` (n x k): builds `G = A^T A`.
    pub fn from_columns(a: MatRef<'_, f64>, params: NnlsParams) -> Self {
        Self::new(a.transpose() * a, params)
    }

    /// Number of columns k.
    pub fn ncols(&self) -> usize {
        self.gram.ncols()
    }

    /// The Gram matrix (k x k).
    pub fn gram(&self) -> MatRef<'_, f64> {
        self.gram.as_ref()
    }

    /// The parameters.
    pub fn params(&self) -> &NnlsParams {
        &self.params
    }

    /// The passive set of the last solve, in factor order.
    pub fn passive_set(&self) -> &[usize] {
        &self.passive
    }

    /// Reserve room for `columns` columns in all: pushes up to that count then grow the Gram
    /// matrix in place, without the doubling's copies. A caller that knows its final size
    /// (a greedy over N candidates never holds more than N generators) avoids the transient
    /// of the last doubling, which at 8 193 generators copies a 0.5 GB Gram matrix into a
    /// 2 GB reservation. Only the written entries are touched, so an unused reservation costs
    /// address space, not memory.
    pub fn reserve(&mut self, columns: usize) {
        if columns > self.cap {
            self.cap = columns;
            self.gram.reserve(columns, columns);
        }
    }

    /// Grow the Gram matrix by one column: `cross[i] = a_i^T a_new` for `i < k` and
    /// `cross[k] = a_new^T a_new`. Storage grows by doubling (amortised O(k) per push); the
    /// passive set is reset.
    pub fn push_column(&mut self, cross: &[f64]) {
        let k = self.ncols();
        assert_eq!(cross.len(), k + 1, "Nnls::push_column: need k + 1 inner products");
        if k + 1 > self.cap {
            self.cap = (2 * self.cap).max(k + 1).max(4);
            self.gram.reserve(self.cap, self.cap);
        }
        self.gram.resize_with(k + 1, k + 1, |i, j| if i == k { cross[j] } else { cross[i] });
        self.gmax = self.gmax.max(cross[k]);
        self.gram_finite = self.gram_finite && cross.iter().all(|g| g.is_finite());
        self.reset_workspaces();
    }

    /// The solver of the leading `m x m` block of the Gram matrix (the first `m` columns,
    /// `m <= k`): the same Gram entries, so it computes bit for bit what a solver grown to `m`
    /// columns computes.
    pub fn prefix(&self, m: usize) -> Self {
        assert!(m <= self.ncols(), "Nnls::prefix: {m} columns requested, {} held", self.ncols());
        Self::new(Mat::from_fn(m, m, |i, j| self.gram[(i, j)]), self.params)
    }

    /// Size the per-column workspaces to k and clear the passive set.
    fn reset_workspaces(&mut self) {
        let k = self.ncols();
        self.passive.clear();
        for v in [&mut self.in_passive, &mut self.blocked] {
            v.clear();
            v.resize(k, false);
        }
        self.blocked_list.clear();
        self.z.resize(k, 0.0);
        self.w.resize(k, 0.0);
    }

    /// Solve the NNLS problem with `c = A^T b`, starting from `x` (length k; negative entries
    /// are clipped, the support is the initial passive set — pass zeros for a cold start).
    /// On success `x` holds the minimiser and the passive set is kept for
    /// [`solve_passive`](Self::solve_passive).
    pub fn solve_normal(&mut self, atb: &[f64], x: &mut [f64]) -> Result<NnlsStats, ConeError> {
        let k = self.ncols();
        assert_eq!(atb.len(), k, "Nnls::solve_normal: A^T b has the wrong length");
        assert_eq!(x.len(), k, "Nnls::solve_normal: x has the wrong length");
        let finite = |v: &[f64]| v.iter().all(|a| a.is_finite());
        if !finite(atb) || !finite(x) || !self.gram_finite {
            return Err(ConeError::NonFinite);
        }
        self.warm_start(x);
        self.settle(atb, x);
        let max_iter = self.params.max_iter_for(k);
        let mut iterations = 0;
        let cmax = atb.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        loop {
            let (scale, entering) = self.update_dual(atb, x, cmax);
            let Some(t) = entering else {
                return Ok(NnlsStats { iterations, kkt_residual: self.kkt_residual(scale) });
            };
            if iterations >= max_iter {
                let kkt_residual = self.kkt_residual(scale);
                return Err(ConeError::NotConverged { iterations, kkt_residual });
            }
            if !self.try_add(t) {
                self.block(t);
                continue;
            }
            self.solve_z(atb);
            let last = self.passive.len() - 1;
            // In exact arithmetic z_t = w_t / pivot^2 > 0; a non-positive value means w_t was
            // round-off: refuse t rather than cycle.
            if self.z[last] <= 0.0 {
                self.remove_at(last);
                self.block(t);
                continue;
            }
            iterations += 1;
            self.unblock_all();
            self.settle(atb, x);
        }
    }

    /// Solve `G[P, P] d_P = rhs[P]` with the factor of the last solve's passive set; `out`
    /// (length k) receives `d` at the passive columns and 0 elsewhere. Used for iterative
    /// refinement (corrected semi-normal equations).
    pub fn solve_passive(&mut self, rhs: &[f64], out: &mut [f64]) {
        assert_eq!(rhs.len(), self.ncols(), "Nnls::solve_passive: rhs has the wrong length");
        assert_eq!(out.len(), self.ncols(), "Nnls::solve_passive: out has the wrong length");
        self.solve_z(rhs);
        out.fill(0.0);
        for (q, &j) in self.passive.iter().enumerate() {
            out[j] = self.z[q];
        }
    }

    /// Reset the active set and factor the support of `x` (clipping refused or negative
    /// entries to zero).
    fn warm_start(&mut self, x: &mut [f64]) {
        self.passive.clear();
        self.in_passive.fill(false);
        self.unblock_all();
        for (j, xj) in x.iter_mut().enumerate() {
            if !(*xj > 0.0 && self.try_add(j)) {
                *xj = 0.0;
            }
        }
    }

    /// Inner loop: move from the feasible `x` towards the passive least-squares solution `z`,
    /// dropping columns that hit zero, until `z > 0` on the passive set; then `x_P = z`.
    fn settle(&mut self, rhs: &[f64], x: &mut [f64]) {
        loop {
            self.solve_z(rhs);
            let mut alpha = f64::INFINITY;
            let mut arg = None;
            for (q, &j) in self.passive.iter().enumerate() {
                // x_j > 0 on P, so x_j - z_q > 0 here.
                if self.z[q] <= 0.0 && x[j] / (x[j] - self.z[q]) < alpha {
                    alpha = x[j] / (x[j] - self.z[q]);
                    arg = Some(q);
                }
            }
            let Some(qmin) = arg else {
                for (q, &j) in self.passive.iter().enumerate() {
                    x[j] = self.z[q];
                }
                return;
            };
            for (q, &j) in self.passive.iter().enumerate() {
                x[j] += alpha * (self.z[q] - x[j]);
            }
            x[self.passive[qmin]] = 0.0;
            for q in (0..self.passive.len()).rev() {
                let j = self.passive[q];
                if x[j] <= 0.0 {
                    x[j] = 0.0;
                    self.remove_at(q);
                }
            }
        }
    }

    /// Refuse column t until the next successful addition.
    fn block(&mut self, t: usize) {
        self.blocked[t] = true;
        self.blocked_list.push(t);
    }

    fn unblock_all(&mut self) {
        for &t in &self.blocked_list {
            self.blocked[t] = false;
        }
        self.blocked_list.clear();
    }

    /// `w = c - G x` (using the sparsity of x) and the entering column: the one outside P
    /// and the refused set with the largest `w_j > tol * scale`, the first on ties. Returns
    /// the KKT scale `cmax + gmax ||x||_1` (`cmax = max_j |c_j|`) and that column.
    ///
    /// x is zero off the passive set, so `||x||_1` is summed over the passive columns in
    /// ascending order: the same bits as the sum over all k entries (adding +0 to a
    /// non-negative sum is exact). Above [`PAR_DUAL_MIN`] columns the rows of `w` are done in
    /// parallel blocks, each entry by the same operations in the same order, and the blocks'
    /// candidates merged by (value, then lower index): the same `w` and the same column on
    /// any thread count.
    fn update_dual(&mut self, atb: &[f64], x: &[f64], cmax: f64) -> (f64, Option<usize>) {
        self.sorted.clear();
        self.sorted.extend_from_slice(&self.passive);
        self.sorted.sort_unstable();
        let x1: f64 = self.sorted.iter().fold(0.0, |acc, &j| acc + x[j].abs());
        let scale = cmax + self.gmax * x1;
        let threshold = self.params.tol * scale;
        let (gram, passive, in_passive, blocked) = (&self.gram, &self.passive, &self.in_passive, &self.blocked);
        let block = |start: usize, w: &mut [f64]| {
            let end = start + w.len();
            w.copy_from_slice(&atb[start..end]);
            for &j in passive {
                let gj = &gram.col_as_slice(j)[start..end];
                for (wi, gi) in w.iter_mut().zip(gj) {
                    *wi -= x[j] * gi;
                }
            }
            scan_entering(w, &in_passive[start..end], &blocked[start..end], start, threshold)
        };
        let k = self.w.len();
        let pick = if k < PAR_DUAL_MIN {
            block(0, &mut self.w)
        } else {
            let found: Vec<Option<(f64, usize)>> =
                self.w.par_chunks_mut(DUAL_BLOCK).enumerate().map(|(b, w)| block(b * DUAL_BLOCK, w)).collect();
            found.into_iter().flatten().fold(None, |held, c| Some(better_entering(held, c)))
        };
        (scale, pick.map(|(_, j)| j))
    }

    fn kkt_residual(&self, scale: f64) -> f64 {
        if scale <= 0.0 {
            return 0.0;
        }
        let worst = (0..self.ncols())
            .map(|j| if self.in_passive[j] { self.w[j].abs() } else { self.w[j].max(0.0) })
            .fold(0.0, f64::max);
        worst / scale
    }

    /// Append column t to the factor; false (factor unchanged) if its pivot is too small.
    fn try_add(&mut self, t: usize) -> bool {
        let p = self.passive.len();
        if p + 1 > self.ld {
            self.grow_factor(p + 1);
        }
        let (gram, passive) = (&self.gram, &self.passive);
        let ok = passive_factor::append(
            &mut self.chol,
            self.ld,
            p,
            |i| gram[(passive[i], t)],
            gram[(t, t)],
            self.params.pivot_tol,
        );
        if ok {
            self.passive.push(t);
            self.in_passive[t] = true;
        }
        ok
    }

    /// Room for a factor of `rows` rows: a new leading dimension (doubling), the current
    /// p x p factor copied over (the same values, so the same bits downstream).
    fn grow_factor(&mut self, rows: usize) {
        let ld = (2 * self.ld).max(rows).max(8);
        let mut chol = vec![0.0; ld * ld];
        for i in 0..self.passive.len() {
            chol[i * ld..i * ld + i + 1].copy_from_slice(&self.chol[i * self.ld..i * self.ld + i + 1]);
        }
        self.chol = chol;
        self.ld = ld;
    }

    /// Remove the passive column at factor position q (see [`passive_factor::remove`]).
    fn remove_at(&mut self, q: usize) {
        passive_factor::remove(&mut self.chol, self.ld, self.passive.len(), q);
        let col = self.passive.remove(q);
        self.in_passive[col] = false;
    }

    /// `z = G[P, P]^{-1} rhs[P]` by forward and backward substitution with L.
    fn solve_z(&mut self, rhs: &[f64]) {
        for (q, &j) in self.passive.iter().enumerate() {
            self.z[q] = rhs[j];
        }
        passive_factor::solve(&self.chol, self.ld, self.passive.len(), &mut self.z);
    }
}

/// Lanes of [`scan_entering`].
const ENTER_LANES: usize = 8;

/// From this many columns on, [`Nnls`]'s dual update runs in parallel blocks of
/// [`DUAL_BLOCK`] rows (below, a block's work is shorter than a thread hand-off).
pub(crate) const PAR_DUAL_MIN: usize = 4096;

/// Rows per block of the parallel dual update.
pub(crate) const DUAL_BLOCK: usize = 2048;

/// The entering candidate of one block of the dual (`offset` = its first column): the largest
/// `w_j > threshold` outside the passive and refused columns, the first on ties. Scanned in
/// [`ENTER_LANES`] interleaved lanes, each keeping its first strict maximum, merged by
/// [`better_entering`]: the same column as one in-order scan, without a dependent compare per
/// column.
pub(super) fn scan_entering(
    w: &[f64],
    in_passive: &[bool],
    blocked: &[bool],
    offset: usize,
    threshold: f64,
) -> Option<(f64, usize)> {
    let k = w.len();
    let mut best = [threshold; ENTER_LANES];
    let mut arg = [usize::MAX; ENTER_LANES];
    let whole = k - k % ENTER_LANES;
    for base in (0..whole).step_by(ENTER_LANES) {
        for l in 0..ENTER_LANES {
            let j = base + l;
            let v = if in_passive[j] | blocked[j] { f64::NEG_INFINITY } else { w[j] };
            if v > best[l] {
                best[l] = v;
                arg[l] = j;
            }
        }
    }
    let lanes = (0..ENTER_LANES).filter(|&l| arg[l] != usize::MAX).map(|l| (best[l], arg[l]));
    let tail = (whole..k).filter(|&j| !in_passive[j] && !blocked[j] && w[j] > threshold).map(|j| (w[j], j));
    lanes.chain(tail).map(|(v, j)| (v, j + offset)).fold(None, |held, c| Some(better_entering(held, c)))
}

/// The larger candidate, the lower column on equal values (candidates exceed a non-negative
/// threshold: no NaN).
pub(super) fn better_entering(held: Option<(f64, usize)>, c: (f64, usize)) -> (f64, usize) {
    match held {
        Some((bv, bj)) if bv.total_cmp(&c.0).then(c.1.cmp(&bj)).is_gt() => (bv, bj),
        _ => c,
    }
}

/// `r = b - A x` for `a` n x k.
pub(crate) fn residual_into(a: MatRef<'_, f64>, x: &[f64], b: &[f64], r: &mut [f64]) {
    r.copy_from_slice(b);
    for (j, &xj) in x.iter().enumerate() {
        for (i, ri) in r.iter_mut().enumerate() {
            *ri -= xj * a[(i, j)];
        }
    }
}

/// Euclidean norm (plain sum of squares; inputs are physical fields far from overflow).
pub(crate) fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// `A^T b` for `a` n x k.
pub(crate) fn at_b(a: MatRef<'_, f64>, b: &[f64], out: &mut [f64]) {
    for (j, o) in out.iter_mut().enumerate() {
        *o = a.col(j).iter().zip(b).map(|(x, y)| x * y).sum();
    }
}

/// Solve `min ||A x - b||, x >= 0` for one right-hand side (cold start); `a` is n x k, `b`
/// has length n. The residual norm comes from the explicit residual.
pub fn nnls(a: MatRef<'_, f64>, b: &[f64], params: NnlsParams) -> Result<NnlsSolution, ConeError> {
    assert_eq!(a.nrows(), b.len(), "nnls: A has {} rows but b has length {}", a.nrows(), b.len());
    let k = a.ncols();
    let mut solver = Nnls::from_columns(a, params);
    let mut atb = vec![0.0; k];
    at_b(a, b, &mut atb);
    let mut x = vec![0.0; k];
    let stats = solver.solve_normal(&atb, &mut x)?;
    let mut r = vec![0.0; b.len()];
    residual_into(a, &x, b, &mut r);
    Ok(NnlsSolution { x, residual_norm: norm2(&r), iterations: stats.iterations, kkt_residual: stats.kkt_residual })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cone::nnls_reference;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::{assert_all_close, assert_close};

    fn random_mat(rng: &mut Rng, n: usize, k: usize, lo: f64, hi: f64) -> Mat<f64> {
        Mat::from_fn(n, k, |_, _| rng.uniform_in(lo, hi))
    }

    fn random_vec(rng: &mut Rng, n: usize) -> Vec<f64> {
        (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect()
    }

    /// Check the KKT conditions from the explicit residual: x >= 0, w = A^T (b - A x) <= tol on
    /// the zero set and |w| <= tol on the passive set, tol relative to max_j ||a_j|| ||b||.
    fn assert_kkt(a: MatRef<'_, f64>, b: &[f64], x: &[f64], rel: f64) {
        let mut r = vec![0.0; b.len()];
        residual_into(a, x, b, &mut r);
        let mut w = vec![0.0; a.ncols()];
        at_b(a, &r, &mut w);
        let amax = (0..a.ncols()).map(|j| a.col(j).norm_l2()).fold(0.0, f64::max);
        let tol = rel * amax * norm2(b);
        for j in 0..x.len() {
            assert!(x[j] >= 0.0, "x[{j}] = {} < 0", x[j]);
            if x[j] > 0.0 {
                assert!(w[j].abs() <= tol, "passive w[{j}] = {:e} (tol {tol:e})", w[j]);
            } else {
                assert!(w[j] <= tol, "zero-set w[{j}] = {:e} > tol {tol:e}", w[j]);
            }
        }
    }

    /// Fast and reference solvers agree on the (unique) residual norm and both satisfy KKT.
    fn check_against_reference(a: MatRef<'_, f64>, b: &[f64]) {
        let fast = nnls(a, b, NnlsParams::default()).expect("fast NNLS converges");
        let slow = nnls_reference(a, b, NnlsParams::default()).expect("reference converges");
        // KKT to 1e-10 of ||A|| ||b||: round-off of Gram solves on these O(1)-conditioned
        // random problems is ~1e-14; 1e-10 leaves room for the 20x30 rank-deficient cases.
        assert_kkt(a, b, &fast.x, 1e-10);
        assert_kkt(a, b, &slow.x, 1e-10);
        // The residual norm is unique even when x is not: 1e-9 relative to ||b|| (the
        // residuals are O(||b||) or zero; both solvers reach ~1e-14).
        let tol = Tol { abs: 1e-9 * norm2(b), rel: 1e-9 };
        assert_close!(fast.residual_norm, slow.residual_norm, tol);
    }

    #[test]
    fn kkt_and_reference_on_tall_random_problems() {
        let mut rng = Rng::new(11);
        for _ in 0..20 {
            let a = random_mat(&mut rng, 50, 10, -1.0, 1.0);
            let b = random_vec(&mut rng, 50);
            check_against_reference(a.as_ref(), &b);
        }
    }

    #[test]
    fn kkt_and_reference_on_wide_random_problems() {
        // 20 x 30: more columns than rows, G singular.
        let mut rng = Rng::new(12);
        for _ in 0..20 {
            let a = random_mat(&mut rng, 20, 30, -1.0, 1.0);
            let b = random_vec(&mut rng, 20);
            check_against_reference(a.as_ref(), &b);
        }
    }

    #[test]
    fn kkt_and_reference_on_nonnegative_cones() {
        // Non-negative generators as for pressure snapshots; b anywhere.
        let mut rng = Rng::new(13);
        for _ in 0..20 {
            let a = random_mat(&mut rng, 40, 15, 0.0, 1.0);
            let b = random_vec(&mut rng, 40);
            check_against_reference(a.as_ref(), &b);
        }
    }

    #[test]
    fn duplicate_and_collinear_columns_are_handled() {
        let mut rng = Rng::new(14);
        for _ in 0..20 {
            let mut a = random_mat(&mut rng, 30, 8, -1.0, 1.0);
            for i in 0..30 {
                a[(i, 3)] = a[(i, 1)]; // exact duplicate
                a[(i, 5)] = 2.5 * a[(i, 2)]; // positive multiple
                a[(i, 7)] = -a[(i, 0)]; // opposite direction
            }
            let b = random_vec(&mut rng, 30);
            let sol = nnls(a.as_ref(), &b, NnlsParams::default()).expect("converges");
            assert!(sol.x.iter().all(|v| v.is_finite()), "no NaN with dependent columns");
            check_against_reference(a.as_ref(), &b);
        }
    }

    #[test]
    fn zero_right_hand_side_gives_zero() {
        let mut rng = Rng::new(15);
        let a = random_mat(&mut rng, 20, 6, -1.0, 1.0);
        let sol = nnls(a.as_ref(), &[0.0; 20], NnlsParams::default()).expect("converges");
        // Exactly zero: no column ever enters (w = 0 everywhere).
        assert_all_close!(sol.x, [0.0; 6], Tol::abs(0.0));
        assert_close!(sol.residual_norm, 0.0, Tol::abs(0.0));
        assert_eq!(sol.iterations, 0);
    }

    #[test]
    fn right_hand_side_in_the_cone_is_recovered() {
        // A (50 x 10) has full column rank, so x0 is the unique minimiser.
        let mut rng = Rng::new(16);
        for _ in 0..10 {
            let a = random_mat(&mut rng, 50, 10, -1.0, 1.0);
            let x0: Vec<f64> = (0..10).map(|j| if j % 3 == 0 { 0.0 } else { rng.uniform_in(0.5, 2.0) }).collect();
            let mut b = vec![0.0; 50];
            residual_into(a.as_ref(), &x0, &vec![0.0; 50], &mut b);
            b.iter_mut().for_each(|v| *v = -*v); // b = A x0
            let sol = nnls(a.as_ref(), &b, NnlsParams::default()).expect("converges");
            // cond(A) ~ 10 here: 1e-12 is ~1000 eps of headroom on x and on the residual.
            assert_all_close!(sol.x, x0, Tol { abs: 1e-12, rel: 1e-12 });
            assert_close!(sol.residual_norm, 0.0, Tol::abs(1e-12 * norm2(&b)));
        }
    }

    #[test]
    fn zero_column_is_never_used() {
        let mut rng = Rng::new(17);
        let mut a = random_mat(&mut rng, 25, 6, -1.0, 1.0);
        for i in 0..25 {
            a[(i, 2)] = 0.0;
        }
        for _ in 0..10 {
            let b = random_vec(&mut rng, 25);
            let sol = nnls(a.as_ref(), &b, NnlsParams::default()).expect("converges");
            assert_close!(sol.x[2], 0.0, Tol::abs(0.0)); // never enters: exactly 0
            check_against_reference(a.as_ref(), &b);
        }
    }

    #[test]
    fn no_columns() {
        let a = Mat::<f64>::zeros(4, 0);
        let b = [1.0, -2.0, 2.0, 0.0];
        let sol = nnls(a.as_ref(), &b, NnlsParams::default()).expect("trivial");
        assert!(sol.x.is_empty());
        assert_close!(sol.residual_norm, 3.0, Tol::rel(1e-15)); // ||b|| = 3, one rounding
    }

    #[test]
    fn warm_start_reaches_the_cold_solution() {
        let mut rng = Rng::new(18);
        let a = random_mat(&mut rng, 40, 12, -1.0, 1.0);
        let mut solver = Nnls::from_columns(a.as_ref(), NnlsParams::default());
        for _ in 0..10 {
            let b = random_vec(&mut rng, 40);
            let cold = nnls(a.as_ref(), &b, NnlsParams::default()).expect("converges");
            let mut atb = vec![0.0; 12];
            at_b(a.as_ref(), &b, &mut atb);
            // Arbitrary (partly negative) warm start.
            let mut x: Vec<f64> = (0..12).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            solver.solve_normal(&atb, &mut x).expect("converges");
            // Full column rank: unique minimiser; both are Gram solves of cond ~ 100.
            assert_all_close!(x, cold.x, Tol { abs: 1e-11, rel: 1e-11 });
        }
    }

    #[test]
    fn iteration_cap_and_non_finite_input_are_errors() {
        let mut rng = Rng::new(19);
        let a = random_mat(&mut rng, 10, 4, 0.0, 1.0);
        let b = vec![1.0; 10]; // A^T b > 0: at least one column must enter
        let capped = NnlsParams { max_iter: Some(0), ..NnlsParams::default() };
        let err = nnls(a.as_ref(), &b, capped).expect_err("cap of 0 iterations");
        assert!(matches!(err, ConeError::NotConverged { iterations: 0, .. }), "{err}");
        let mut bad = b.clone();
        bad[3] = f64::NAN;
        let err = nnls(a.as_ref(), &bad, NnlsParams::default()).expect_err("NaN input");
        assert!(matches!(err, ConeError::NonFinite));
    }

    #[test]
    fn cholesky_downdate_matches_refactorisation() {
        let mut rng = Rng::new(20);
        let a = random_mat(&mut rng, 30, 8, -1.0, 1.0);
        let mut solver = Nnls::from_columns(a.as_ref(), NnlsParams::default());
        for t in [4, 0, 6, 2, 7, 1] {
            assert!(solver.try_add(t));
        }
        solver.remove_at(1); // column 0
        solver.remove_at(3); // column 7 (now at position 3)
        let p = solver.passive.clone();
        assert_eq!(p, vec![4, 6, 2, 1]);
        let k = solver.ld;
        for i in 0..p.len() {
            for j in 0..=i {
                let llt: f64 = (0..=j).map(|q| solver.chol[i * k + q] * solver.chol[j * k + q]).sum();
                // Givens rotations are backward stable: 1e-13 of G entries that are O(10).
                assert_close!(llt, solver.gram[(p[i], p[j])], Tol::abs(1e-13 * solver.gmax));
            }
            for j in i + 1..p.len() {
                assert_close!(solver.chol[i * k + j], 0.0, Tol::abs(0.0)); // stays triangular
            }
        }
    }

    /// The laned scan picks what one in-order scan picks: the first column of the largest
    /// `w_j > tol * scale` outside P and the refused set, on random duals with many exact ties
    /// (values from a set of 4) and lengths around the lane count.
    #[test]
    fn laned_entering_equals_the_in_order_scan() {
        let mut rng = Rng::new(23);
        for k in [1, 5, 8, 9, 16, 23, 64, 101] {
            let mut solver = Nnls::new(Mat::identity(k, k), NnlsParams::default());
            for _ in 0..50 {
                for j in 0..k {
                    solver.w[j] = [-1.0, 0.0, 0.5, 2.0][(rng.uniform() * 4.0) as usize % 4];
                    solver.in_passive[j] = rng.uniform() < 0.2;
                    solver.blocked[j] = rng.uniform() < 0.1;
                }
                let scale = 1.0;
                let mut reference = None;
                let mut best = solver.params.tol * scale;
                for j in 0..k {
                    if !solver.in_passive[j] && !solver.blocked[j] && solver.w[j] > best {
                        best = solver.w[j];
                        reference = Some(j);
                    }
                }
                let threshold = solver.params.tol * scale;
                let laned = scan_entering(&solver.w, &solver.in_passive, &solver.blocked, 0, threshold);
                assert_eq!(laned.map(|c| c.1), reference, "k = {k}");
                // Split into two blocks and merged: the same column.
                let h = k / 2;
                let a = scan_entering(&solver.w[..h], &solver.in_passive[..h], &solver.blocked[..h], 0, threshold);
                let b = scan_entering(&solver.w[h..], &solver.in_passive[h..], &solver.blocked[h..], h, threshold);
                let merged = [a, b].into_iter().flatten().fold(None, |held, c| Some(better_entering(held, c)));
                assert_eq!(merged.map(|c| c.1), reference, "k = {k}, split");
            }
        }
    }

    /// Above `PAR_DUAL_MIN` columns the dual update runs in parallel blocks: the solution is
    /// the same bits on one thread and on four, and satisfies the KKT conditions (1e-9
    /// relative, the check's round-off allowance for O(1) data).
    #[test]
    fn parallel_dual_update_is_the_same_on_any_thread_count() {
        let mut rng = Rng::new(24);
        let (n, k) = (12, PAR_DUAL_MIN + 900);
        let a = random_mat(&mut rng, n, k, 0.0, 1.0);
        let b: Vec<f64> = (0..n).map(|_| rng.uniform_in(-0.5, 1.0)).collect();
        let mut atb = vec![0.0; k];
        at_b(a.as_ref(), &b, &mut atb);
        let solver = Nnls::from_columns(a.as_ref(), NnlsParams::default());
        let solve_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let mut s = solver.clone();
                let mut x = vec![0.0; k];
                s.solve_normal(&atb, &mut x).expect("converges");
                x
            })
        };
        let (one, four) = (solve_on(1), solve_on(4));
        assert!(one.iter().zip(&four).all(|(p, q)| p.to_bits() == q.to_bits()));
        assert!(one.iter().any(|&v| v > 0.0));
        assert_kkt(a.as_ref(), &b, &one, 1e-9);
    }

    #[test]
    fn push_column_equals_building_from_all_columns() {
        let mut rng = Rng::new(21);
        let a = random_mat(&mut rng, 15, 5, -1.0, 1.0);
        let mut grown = Nnls::from_columns(a.subcols(0, 4), NnlsParams::default());
        let mut cross = vec![0.0; 5];
        at_b(a.as_ref(), &a.col(4).iter().copied().collect::<Vec<_>>(), &mut cross);
        grown.push_column(&cross);
        let full = Nnls::from_columns(a.as_ref(), NnlsParams::default());
        for j in 0..5 {
            for i in 0..5 {
                // Same dot products, possibly summed in a different order: 1e-14 of O(5).
                assert_close!(grown.gram()[(i, j)], full.gram()[(i, j)], Tol::abs(1e-13));
            }
        }
    }

    #[test]
    fn push_column_grows_storage_geometrically() {
        // 200 pushes: with capacity doubling the Gram storage is reallocated ~log2(200) times,
        // not 200 times.
        let mut rng = Rng::new(22);
        let a = random_mat(&mut rng, 10, 200, -1.0, 1.0);
        let mut solver = Nnls::new(Mat::zeros(0, 0), NnlsParams::default());
        let mut reallocations = 0;
        for k in 0..200 {
            let column: Vec<f64> = a.col(k).iter().copied().collect();
            let mut cross = vec![0.0; k + 1];
            at_b(a.subcols(0, k + 1), &column, &mut cross);
            let cap = solver.cap;
            solver.push_column(&cross);
            reallocations += usize::from(solver.cap != cap);
        }
        assert!(reallocations <= 8, "{reallocations} reallocations for 200 pushes");
        // The factor is sized by the passive set (at most rank 10 here), not by k = 200: one
        // solve per column as right-hand side, then ld is the doubling step above 10.
        for j in 0..200 {
            let b: Vec<f64> = a.col(j).iter().map(|v| v + 0.3).collect();
            let mut atb = vec![0.0; 200];
            at_b(a.as_ref(), &b, &mut atb);
            solver.solve_normal(&atb, &mut vec![0.0; 200]).expect("converges");
            assert!(solver.passive.len() <= 10);
        }
        assert_eq!(solver.ld, 16, "factor leading dimension");
        let full = Nnls::from_columns(a.as_ref(), NnlsParams::default());
        for j in 0..200 {
            for i in 0..200 {
                // Plain sums vs faer's product kernel: round-off of 10-term sums of O(1) terms.
                assert_close!(solver.gram()[(i, j)], full.gram()[(i, j)], Tol::abs(1e-13));
            }
        }
    }

    #[test]
    fn reserved_pushes_never_move_the_gram_and_solve_the_same() {
        // With the final count reserved, no push reallocates (the storage address is fixed),
        // and every solve gives the same bits as a solver grown by doubling.
        let mut rng = Rng::new(23);
        let a = random_mat(&mut rng, 12, 90, -1.0, 1.0);
        let mut reserved = Nnls::new(Mat::zeros(0, 0), NnlsParams::default());
        reserved.reserve(90);
        let mut doubling = Nnls::new(Mat::zeros(0, 0), NnlsParams::default());
        let at = reserved.gram.as_ptr();
        for k in 0..90 {
            let column: Vec<f64> = a.col(k).iter().copied().collect();
            let mut cross = vec![0.0; k + 1];
            at_b(a.subcols(0, k + 1), &column, &mut cross);
            reserved.push_column(&cross);
            doubling.push_column(&cross);
            assert_eq!(reserved.gram.as_ptr(), at, "push {k} moved the reserved Gram matrix");
            let b: Vec<f64> = (0..12).map(|_| rng.uniform_in(0.0, 1.0)).collect();
            let mut atb = vec![0.0; k + 1];
            at_b(a.subcols(0, k + 1), &b, &mut atb);
            let (mut x, mut y) = (vec![0.0; k + 1], vec![0.0; k + 1]);
            reserved.solve_normal(&atb, &mut x).expect("converges");
            doubling.solve_normal(&atb, &mut y).expect("converges");
            assert_eq!(
                x.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                y.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
        assert_eq!(reserved.cap, 90);
    }
}
