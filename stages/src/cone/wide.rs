//! Cone projection onto a wide basis without its Gram matrix: Lawson–Hanson NNLS on the
//! columns themselves, for cones with many more generators than rows.
//!
//! ```text
//! min_{x >= 0} ||b - Theta x||_2,   Theta n x m,  m >> n
//! KKT:  w = Theta^T (b - Theta x),  x_j w_j = 0,  w_j <= 0 for j outside the support
//! ```
//!
//! [`Nnls`](super::Nnls) works on `G = Theta^T Theta` (m x m): the right tool while m is a few
//! hundred, but `8 m^2` bytes per solver once the cone of a large snapshot set has thousands of
//! generators (a 16 385-generator cone: 2.1 GB). Here the only dense object is `Theta` itself;
//! each outer iteration computes `w` from the explicit residual (`O(n m)`), and the passive set
//! `P` — at most `n` columns, since a cone in `R^n` needs no more than `n` generators for any
//! point (Carathéodory) — is factored from its columns' inner products (`O(n |P|)` per added
//! column), with the same incremental Cholesky and Givens downdate as [`Nnls`](super::Nnls).
//!
//! The dual update `w = Theta^T r` uses the vectorised [`dot`](crate::kernels::dot): the
//! same bits on every run, not those of an in-order sum. Given a [`ColumnIndex`] of the columns'
//! non-zero rows (a pressure snapshot is non-zero under its contact patch only), only the
//! columns that meet the residual's non-zero rows are visited, each summed over the rows they
//! share ([`dot_window`]); every other `w_j` is exactly 0 and cannot enter, so the result is the
//! same bits and the update costs the meeting columns' patches instead of `n m` products.
//!
//! Warm start: the support of a previous solution (a sparse list), typically the same
//! snapshot's projection on a smaller prefix of the same cone. Its entries are re-solved on
//! their own support first, then the iteration continues, so the answer does not depend on the
//! warm start beyond round-off (tested against the Gram solver).
//!
//! KKT scale: the generators have unit norm, so `|theta_j^T b| <= ||b||` and
//! `|(Theta^T Theta x)_j| <= ||x||_1`; convergence is `w_j <= tol (||b|| + ||x||_1)` for every j
//! outside P, the bound [`Nnls`](super::Nnls) uses with `max_j |c_j|` and `max_j G_jj = 1`
//! replaced by their Cauchy–Schwarz bounds.

use faer::MatRef;

use rayon::prelude::*;

use super::nnls::{better_entering, norm2, scan_entering, ConeError, NnlsParams, DUAL_BLOCK, PAR_DUAL_MIN};
use super::passive_factor;
use super::windows::ColumnIndex;
use crate::kernels::{dot, dot_window, nonzero_window};

/// Workspaces of [`WideNnls::project`], sized once for `n` rows and `m` columns.
#[derive(Debug, Clone)]
pub struct WideNnls {
    /// Passive columns in factor order.
    passive: Vec<usize>,
    in_passive: Vec<bool>,
    blocked: Vec<bool>,
    /// The columns set in `blocked` (cleared by list, not by a pass over every column).
    blocked_list: Vec<usize>,
    /// Lower Cholesky factor of `Theta_P^T Theta_P`, row-major, leading dimension `ld`.
    chol: Vec<f64>,
    ld: usize,
    /// Coefficients by column (dense, length m; zero outside P).
    x: Vec<f64>,
    z: Vec<f64>,
    /// The first solve of [`solve_z`](Self::solve_z), before refinement.
    z0: Vec<f64>,
    rhs: Vec<f64>,
    r: Vec<f64>,
    w: Vec<f64>,
    /// Columns whose `w` the last windowed dual update computed (every other `w_j` is 0).
    meeting: Vec<usize>,
    params: NnlsParams,
}

impl WideNnls {
    /// Workspaces for cones of up to `m` generators in `R^n`.
    pub fn new(n: usize, m: usize, params: NnlsParams) -> Self {
        let ld = n + 1;
        Self {
            passive: Vec::with_capacity(ld),
            in_passive: vec![false; m],
            blocked: vec![false; m],
            blocked_list: Vec::new(),
            chol: vec![0.0; ld * ld],
            ld,
            x: vec![0.0; m],
            z: vec![0.0; ld],
            z0: vec![0.0; ld],
            rhs: vec![0.0; ld],
            r: vec![0.0; n],
            w: vec![0.0; m],
            meeting: Vec::new(),
            params,
        }
    }

    /// Project `b` onto the cone of the unit-norm columns of `theta` (n x m): returns
    /// `||b - Theta x||` from the explicit residual and leaves the support of `x` in `support`
    /// as `(column, coefficient)` pairs in ascending column order. `support` on entry is the
    /// warm start (entries outside `0..m` or not positive are ignored).
    pub fn project(
        &mut self,
        theta: MatRef<'_, f64>,
        b: &[f64],
        support: &mut Vec<(usize, f64)>,
    ) -> Result<f64, ConeError> {
        self.project_windowed(theta, None, b, support)
    }

    /// [`project`](Self::project) given the [`ColumnIndex`] of `theta`'s columns (or of a
    /// matrix whose first `theta.ncols()` columns they are): the same result bit for bit, with
    /// the dual update over the columns that meet the residual only.
    pub fn project_windowed(
        &mut self,
        theta: MatRef<'_, f64>,
        windows: Option<&ColumnIndex>,
        b: &[f64],
        support: &mut Vec<(usize, f64)>,
    ) -> Result<f64, ConeError> {
        let (n, m) = (theta.nrows(), theta.ncols());
        assert!(windows.is_none_or(|w| w.len() >= m), "WideNnls::project_windowed: an index of fewer columns");
        assert_eq!(b.len(), n, "WideNnls::project: b has length {}, theta has {n} rows", b.len());
        assert!(m <= self.x.len() && n < self.ld, "WideNnls::project: workspace sized for a smaller cone");
        if !b.iter().all(|v| v.is_finite()) || !support.iter().all(|(_, v)| v.is_finite()) {
            return Err(ConeError::NonFinite);
        }
        self.reset(m);
        for &(j, v) in support.iter() {
            if j < m && v > 0.0 && !self.in_passive[j] && self.try_add(theta, j) {
                self.x[j] = v;
            }
        }
        let bnorm = norm2(b);
        self.settle(theta, b);
        let max_iter = self.params.max_iter_for(m);
        let mut iterations = 0;
        loop {
            self.residual(theta, b);
            self.dual(theta, windows);
            let scale = bnorm + self.passive.iter().map(|&j| self.x[j]).sum::<f64>();
            let Some(t) = self.entering(m, scale, windows.is_some()) else { break };
            if iterations >= max_iter {
                let worst = self.outside_passive(m, windows.is_some()).map(|j| self.w[j].max(0.0)).fold(0.0, f64::max);
                return Err(ConeError::NotConverged { iterations, kkt_residual: worst / scale });
            }
            if !self.try_add(theta, t) {
                self.block(t);
                continue;
            }
            self.solve_z(theta, b);
            let last = self.passive.len() - 1;
            // In exact arithmetic z_t > 0 here; a non-positive value means w_t was round-off.
            if self.z[last] <= 0.0 {
                self.remove_at(last);
                self.block(t);
                continue;
            }
            iterations += 1;
            self.unblock_all();
            self.settle(theta, b);
        }
        support.clear();
        support.extend(self.passive.iter().map(|&j| (j, self.x[j])));
        support.sort_unstable_by_key(|p| p.0);
        self.residual(theta, b);
        Ok(norm2(&self.r))
    }

    /// `w = Theta^T r`; from [`PAR_DUAL_MIN`] columns on in parallel blocks of [`DUAL_BLOCK`]
    /// (each entry is the same dot product whatever the blocks or threads).
    ///
    /// With an index: `w_j` of the columns meeting the residual's non-zero rows only, listed in
    /// `meeting` (the others are 0 and are not written).
    fn dual(&mut self, theta: MatRef<'_, f64>, windows: Option<&ColumnIndex>) {
        let m = theta.ncols();
        if let Some(index) = windows {
            let (a, b) = nonzero_window(&self.r);
            let (r, w, meeting) = (&self.r, &mut self.w, &mut self.meeting);
            meeting.clear();
            index.for_each_meeting(m, a, b, |j, lo, hi| {
                w[j] = column_dot_window(theta, j, r, lo, hi);
                meeting.push(j);
            });
            return;
        }
        let r = &self.r;
        let fill = |start: usize, w: &mut [f64]| {
            for (i, w) in w.iter_mut().enumerate() {
                *w = column_dot(theta, start + i, r);
            }
        };
        if m >= PAR_DUAL_MIN {
            self.w[..m].par_chunks_mut(DUAL_BLOCK).enumerate().for_each(|(b, w)| fill(b * DUAL_BLOCK, w));
        } else {
            fill(0, &mut self.w[..m]);
        }
    }

    fn reset(&mut self, m: usize) {
        for &j in &self.passive {
            self.x[j] = 0.0;
            self.in_passive[j] = false;
        }
        self.passive.clear();
        self.unblock_all();
        debug_assert!(!self.blocked[..m].iter().any(|&b| b));
    }

    fn block(&mut self, j: usize) {
        self.blocked[j] = true;
        self.blocked_list.push(j);
    }

    fn unblock_all(&mut self) {
        for j in self.blocked_list.drain(..) {
            self.blocked[j] = false;
        }
    }

    /// `r = b - Theta_P x_P`.
    fn residual(&mut self, theta: MatRef<'_, f64>, b: &[f64]) {
        self.r.copy_from_slice(b);
        for &j in &self.passive {
            let xj = self.x[j];
            for (ri, a) in self.r.iter_mut().zip(theta.col(j).iter()) {
                *ri -= xj * a;
            }
        }
    }

    /// The column outside P (and not refused) with the largest `w_j > tol * scale`, the first
    /// on ties (the Gram solver's scan).
    ///
    /// After a windowed dual update only the meeting columns can exceed the non-negative
    /// threshold; the larger value, then the lower column, wins as in the full scan.
    fn entering(&self, m: usize, scale: f64, windowed: bool) -> Option<usize> {
        let threshold = self.params.tol * scale;
        if windowed {
            return self
                .meeting
                .iter()
                .filter(|&&j| !self.in_passive[j] && !self.blocked[j] && self.w[j] > threshold)
                .map(|&j| (self.w[j], j))
                .fold(None, |held, c| Some(better_entering(held, c)))
                .map(|c| c.1);
        }
        scan_entering(&self.w[..m], &self.in_passive[..m], &self.blocked[..m], 0, threshold).map(|c| c.1)
    }

    /// The columns outside P whose `w` the last dual update holds (for the error report).
    fn outside_passive(&self, m: usize, windowed: bool) -> Box<dyn Iterator<Item = usize> + '_> {
        if windowed {
            Box::new(self.meeting.iter().copied().filter(|&j| !self.in_passive[j]))
        } else {
            Box::new((0..m).filter(|&j| !self.in_passive[j]))
        }
    }

    /// Inner loop: from the feasible `x` towards the passive least-squares solution, dropping
    /// columns that reach zero, until that solution is positive; then `x_P = z`.
    fn settle(&mut self, theta: MatRef<'_, f64>, b: &[f64]) {
        loop {
            self.solve_z(theta, b);
            let mut alpha = f64::INFINITY;
            let mut arg = None;
            for (q, &j) in self.passive.iter().enumerate() {
                if self.z[q] <= 0.0 && self.x[j] / (self.x[j] - self.z[q]) < alpha {
                    alpha = self.x[j] / (self.x[j] - self.z[q]);
                    arg = Some(q);
                }
            }
            let Some(qmin) = arg else {
                for (q, &j) in self.passive.iter().enumerate() {
                    self.x[j] = self.z[q];
                }
                return;
            };
            for (q, &j) in self.passive.iter().enumerate() {
                self.x[j] += alpha * (self.z[q] - self.x[j]);
            }
            let drop = self.passive[qmin];
            self.x[drop] = 0.0;
            for q in (0..self.passive.len()).rev() {
                let j = self.passive[q];
                if self.x[j] <= 0.0 {
                    self.x[j] = 0.0;
                    self.remove_at(q);
                }
            }
        }
    }

    /// Append column t to the factor; false (unchanged) if its pivot is below
    /// `pivot_tol * ||theta_t||^2` (numerically in the span of P) or P already has n columns.
    fn try_add(&mut self, theta: MatRef<'_, f64>, t: usize) -> bool {
        let p = self.passive.len();
        if p + 1 >= self.ld {
            return false;
        }
        let col_t = theta.col(t);
        let dot = |a: usize| theta.col(a).iter().zip(col_t.iter()).map(|(x, y)| x * y).sum::<f64>();
        let passive = &self.passive;
        if !passive_factor::append(&mut self.chol, self.ld, p, |i| dot(passive[i]), dot(t), self.params.pivot_tol) {
            return false;
        }
        self.passive.push(t);
        self.in_passive[t] = true;
        true
    }

    /// Remove the passive column at factor position q.
    fn remove_at(&mut self, q: usize) {
        passive_factor::remove(&mut self.chol, self.ld, self.passive.len(), q);
        let col = self.passive.remove(q);
        self.in_passive[col] = false;
    }

    /// `z = (Theta_P^T Theta_P)^{-1} Theta_P^T b`, then one step of iterative refinement on
    /// the explicit residual (corrected semi-normal equations, as the Gram projector does).
    fn solve_z(&mut self, theta: MatRef<'_, f64>, b: &[f64]) {
        let p = self.passive.len();
        for q in 0..p {
            self.rhs[q] = theta.col(self.passive[q]).iter().zip(b).map(|(a, v)| a * v).sum();
        }
        self.chol_solve(p);
        // r = b - Theta_P z, then z += (Theta_P^T Theta_P)^{-1} Theta_P^T r.
        self.r.copy_from_slice(b);
        for q in 0..p {
            let zq = self.z[q];
            for (ri, a) in self.r.iter_mut().zip(theta.col(self.passive[q]).iter()) {
                *ri -= zq * a;
            }
        }
        self.z0[..p].copy_from_slice(&self.z[..p]);
        for q in 0..p {
            self.rhs[q] = theta.col(self.passive[q]).iter().zip(&self.r).map(|(a, v)| a * v).sum();
        }
        self.chol_solve(p);
        for q in 0..p {
            self.z[q] += self.z0[q];
        }
    }

    /// `z = L^{-T} L^{-1} rhs` on the first p entries.
    fn chol_solve(&mut self, p: usize) {
        self.z[..p].copy_from_slice(&self.rhs[..p]);
        passive_factor::solve(&self.chol, self.ld, p, &mut self.z);
    }
}

/// `theta_j . v` with the vectorised [`dot`] (contiguous columns, as every caller passes), or
/// in order for a strided view. The `O(n m)` dual update is the whole cost of a wide solve.
fn column_dot(theta: MatRef<'_, f64>, j: usize, v: &[f64]) -> f64 {
    match theta.col(j).try_as_col_major() {
        Some(col) => dot(col.as_slice(), v),
        None => theta.col(j).iter().zip(v).map(|(a, r)| a * r).sum(),
    }
}

/// [`column_dot`] where the products outside `lo..hi` are zero: the same bits.
fn column_dot_window(theta: MatRef<'_, f64>, j: usize, v: &[f64], lo: usize, hi: usize) -> f64 {
    if lo >= hi {
        return 0.0;
    }
    match theta.col(j).try_as_col_major() {
        Some(col) => dot_window(col.as_slice(), v, lo, hi),
        // An in-order sum skipping exact-zero products is the whole in-order sum.
        None => (lo..hi).map(|i| theta[(i, j)] * v[i]).fold(0.0, |s, p| s + p),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cone::nnls;
    use crate::float_cmp::{close, Tol};
    use crate::rng::Rng;
    use faer::Mat;

    /// Unit-norm non-negative bumps on a line (pressure-like generators), m of them in R^n.
    fn bumps(n: usize, m: usize, width: f64) -> Mat<f64> {
        let mut a = Mat::from_fn(n, m, |i, j| {
            let c = (j as f64 + 0.5) / m as f64;
            let x = i as f64 / (n - 1) as f64;
            (1.0 - ((x - c) / width).powi(2)).max(0.0)
        });
        for j in 0..m {
            let s = a.col(j).norm_l2();
            a.col_mut(j).iter_mut().for_each(|v| *v /= s);
        }
        a
    }

    /// A cone wide enough for the parallel dual update (6 000 generators, three blocks) gives the same
    /// support and residual, bit for bit, on one thread and on four.
    #[test]
    fn the_parallel_dual_update_is_the_same_on_any_thread_count() {
        let m = 6000;
        assert!(m >= PAR_DUAL_MIN.max(2 * DUAL_BLOCK + 1), "the test needs several parallel blocks");
        let theta = bumps(60, m, 0.05);
        let mut rng = Rng::new(17);
        let b: Vec<f64> = (0..60).map(|_| rng.uniform_in(0.0, 1.0)).collect();
        let solve_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let mut solver = WideNnls::new(60, m, NnlsParams::default());
                let mut support = Vec::new();
                let r = solver.project(theta.as_ref(), &b, &mut support).expect("converges");
                (r.to_bits(), support.iter().map(|&(j, v)| (j, v.to_bits())).collect::<Vec<_>>())
            })
        };
        let (one, four) = (solve_on(1), solve_on(4));
        assert!(!one.1.is_empty(), "a non-trivial projection");
        assert_eq!(one, four);
    }

    /// Residual norms agree with the Gram-matrix solver (`nnls`, an independent implementation
    /// on `Theta^T Theta`) to 1e-10 relative to `||b||`: both solve the same strictly convex
    /// problem in the residual, so the residuals agree up to each solver's KKT tolerance
    /// (1e-12 relative) amplified by the conditioning of the passive set.
    #[test]
    fn matches_the_gram_solver_cold_and_warm() {
        let mut rng = Rng::new(7);
        for (n, m, width) in [(20, 60, 0.15), (31, 200, 0.05), (12, 12, 0.3)] {
            let theta = bumps(n, m, width);
            let mut wide = WideNnls::new(n, m, NnlsParams::default());
            for trial in 0..20 {
                let b: Vec<f64> = (0..n).map(|_| rng.uniform_in(-0.2, 1.0)).collect();
                let reference = nnls(theta.as_ref(), &b, NnlsParams::default()).expect("converges");
                let mut support = Vec::new();
                let cold = wide.project(theta.as_ref(), &b, &mut support).expect("converges");
                let scale = norm2(&b);
                assert!(
                    close(cold, reference.residual_norm, Tol::abs(1e-10 * scale)),
                    "{trial}: {cold} vs {}",
                    reference.residual_norm
                );
                assert!(support.iter().all(|&(_, v)| v > 0.0));
                // Warm from a deliberately wrong support: same answer.
                let mut wrong: Vec<(usize, f64)> = (0..m).step_by(3).map(|j| (j, 0.5)).collect();
                let warm = wide.project(theta.as_ref(), &b, &mut wrong).expect("converges");
                assert!(close(warm, cold, Tol::abs(1e-10 * scale)), "{trial}: warm {warm} vs cold {cold}");
            }
        }
    }

    /// A point of the cone (a positive combination of two generators) has residual ~0, and a
    /// prefix view projects onto the prefix cone only.
    #[test]
    fn cone_points_and_prefixes() {
        let theta = bumps(25, 40, 0.1);
        let b: Vec<f64> = (0..25).map(|i| 0.7 * theta[(i, 3)] + 0.2 * theta[(i, 30)]).collect();
        let mut wide = WideNnls::new(25, 40, NnlsParams::default());
        let mut support = Vec::new();
        let r = wide.project(theta.as_ref(), &b, &mut support).expect("converges");
        assert!(r <= 1e-13, "residual {r}");
        let prefix = wide.project(theta.subcols(0, 10), &b, &mut support).expect("converges");
        let reference = nnls(theta.subcols(0, 10), &b, NnlsParams::default()).expect("converges");
        assert!(close(prefix, reference.residual_norm, Tol::abs(1e-12)));
        assert!(prefix > 0.1, "column 30 is outside the prefix: {prefix}");
        assert!(support.iter().all(|&(j, _)| j < 10));
    }

    /// With each column's window the projection is the same bits as without, cold and warm,
    /// on narrow bumps (most columns do not meet a residual) and on wide ones, for right-hand
    /// sides that are zero outside a patch and for dense ones.
    #[test]
    fn windows_change_no_bit() {
        let mut rng = Rng::new(11);
        for (n, m, width) in [(101, 3000, 0.06), (40, 300, 0.5), (12, 30, 0.2)] {
            let theta = bumps(n, m, width);
            let windows = ColumnIndex::of(theta.as_ref());
            assert!((0..m).all(|j| windows.window(j).0 < windows.window(j).1), "every bump is non-zero somewhere");
            let mut plain = WideNnls::new(n, m, NnlsParams::default());
            let mut windowed = WideNnls::new(n, m, NnlsParams::default());
            for trial in 0..30 {
                let patch = if trial % 2 == 0 { (n / 3, n / 3 + n / 5 + 1) } else { (0, n) };
                let b: Vec<f64> = (0..n)
                    .map(|i| if (patch.0..patch.1).contains(&i) { rng.uniform_in(-0.2, 1.0) } else { 0.0 })
                    .collect();
                let (mut s1, mut s2) = (Vec::new(), Vec::new());
                for _ in 0..2 {
                    // cold, then warm from the cold support
                    let r1 = plain.project(theta.as_ref(), &b, &mut s1).expect("converges");
                    let r2 = windowed.project_windowed(theta.as_ref(), Some(&windows), &b, &mut s2).expect("converges");
                    assert_eq!(r1.to_bits(), r2.to_bits(), "{n} x {m}, trial {trial}");
                    let bits = |s: &[(usize, f64)]| s.iter().map(|&(j, v)| (j, v.to_bits())).collect::<Vec<_>>();
                    assert_eq!(bits(&s1), bits(&s2), "{n} x {m}, trial {trial}");
                }
                // A prefix of the cone with the whole cone's index.
                let half = theta.subcols(0, m / 2);
                let r1 = plain.project(half, &b, &mut s1).expect("converges");
                let r2 = windowed.project_windowed(half, Some(&windows), &b, &mut s2).expect("converges");
                assert_eq!(r1.to_bits(), r2.to_bits(), "{n} x {m}, trial {trial}, prefix");
                assert!(s2.iter().all(|&(j, _)| j < m / 2));
            }
        }
    }

    #[test]
    fn non_finite_input_is_an_error() {
        let theta = bumps(5, 5, 0.5);
        let mut wide = WideNnls::new(5, 5, NnlsParams::default());
        let b = [1.0, f64::NAN, 0.0, 0.0, 0.0];
        assert!(matches!(wide.project(theta.as_ref(), &b, &mut Vec::new()), Err(ConeError::NonFinite)));
    }
}
