//! Projection onto the cone spanned by the columns of a basis `Theta` (paper eq. 12):
//! `Pi(lambda) = Theta alpha`, `alpha = argmin_{gamma >= 0} ||lambda - Theta gamma||`.
//!
//! [`ConeProjector`] keeps `Theta` and its Gram matrix (through [`Nnls`]) so many vectors are
//! projected against one factorisation-free Gram matrix. Each projection takes one step of
//! iterative refinement on the final passive set (corrected semi-normal equations, Björck
//! 1987), which recovers QR-like accuracy from the Gram-matrix solve, and reports the residual
//! norm from the explicit residual `lambda - Theta alpha`, never from `||lambda||^2 - ...`.
//!
//! [`GrowingCone`] tracks the projections of a fixed snapshot set while columns are appended
//! to the cone one at a time (CPG, compactness C(m)), warm-starting each NNLS from the previous
//! coefficients.

use crate::running_stats::RunningStats;
use faer::{Mat, MatRef};

use super::nnls::{at_b, norm2, ConeError, Nnls, NnlsParams};

/// A vector whose relative cone-projection error is at most this is treated as lying in the
/// cone: it is not re-projected when the cone grows (its error can only decrease) and CPG never
/// selects it. Round-off level for well-conditioned cones.
pub const IN_CONE_REL_TOL: f64 = 1e-12;

/// A warm-started relative residual between `IN_CONE_REL_TOL` and
/// `AMBIGUOUS_FACTOR * sqrt(NnlsParams::tol)` is confirmed by a cold start (see
/// [`ConeProjector::project_warm`]).
const AMBIGUOUS_FACTOR: f64 = 1e3;

/// The projection of one vector onto the cone.
#[derive(Debug, Clone, PartialEq)]
pub struct ConeProjection {
    /// Non-negative coefficients `alpha` (length k): `Pi(lambda) = Theta alpha`.
    pub coeffs: Vec<f64>,
    /// `||lambda - Theta alpha||_2` from the explicit residual.
    pub residual_norm: f64,
}

/// Projector onto `cone(Theta)`; holds `Theta` (n x k), its Gram matrix and workspaces.
#[derive(Debug)]
pub struct ConeProjector {
    theta: Mat<f64>,
    nnls: Nnls,
    atb: Vec<f64>,
    correction: Vec<f64>,
    trial: Vec<f64>,
    cold: Vec<f64>,
    residual: Vec<f64>,
    trial_residual: Vec<f64>,
    /// Inner products of a pushed generator with the others (workspace of `push_column`).
    cross: Vec<f64>,
    /// Reserved columns of `theta`.
    col_capacity: usize,
    /// `Theta^T lambda` of [`project_warm`](Self::project_warm).
    atb_lambda: Vec<f64>,
}

impl Clone for ConeProjector {
    /// A copy that keeps the reserved capacity (so pushes on the copy stay amortised).
    fn clone(&self) -> Self {
        let mut theta = self.theta.clone();
        theta.reserve(self.nrows(), self.col_capacity);
        Self {
            theta,
            nnls: self.nnls.clone(),
            atb: self.atb.clone(),
            correction: self.correction.clone(),
            trial: self.trial.clone(),
            cold: self.cold.clone(),
            residual: self.residual.clone(),
            trial_residual: self.trial_residual.clone(),
            cross: self.cross.clone(),
            col_capacity: self.col_capacity,
            atb_lambda: Vec::new(),
        }
    }
}

impl ConeProjector {
    /// Projector onto the cone of the columns of `theta` (n x k).
    pub fn new(theta: MatRef<'_, f64>, params: NnlsParams) -> Self {
        let (n, k) = (theta.nrows(), theta.ncols());
        Self {
            theta: theta.to_owned(),
            nnls: Nnls::from_columns(theta, params),
            atb: vec![0.0; k],
            correction: vec![0.0; k],
            trial: vec![0.0; k],
            cold: vec![0.0; k],
            residual: vec![0.0; n],
            trial_residual: vec![0.0; n],
            cross: Vec::new(),
            col_capacity: k,
            atb_lambda: Vec::new(),
        }
    }

    /// Projector onto the trivial cone `{0}` in R^n (no columns yet).
    pub fn empty(nrows: usize, params: NnlsParams) -> Self {
        Self::new(Mat::<f64>::zeros(nrows, 0).as_ref(), params)
    }

    /// The NNLS parameters of its projections.
    pub fn params(&self) -> NnlsParams {
        *self.nnls.params()
    }

    /// Dimension n of the vectors.
    pub fn nrows(&self) -> usize {
        self.theta.nrows()
    }

    /// Number k of cone generators.
    pub fn ncols(&self) -> usize {
        self.theta.ncols()
    }

    /// The cone basis `Theta` (n x k).
    pub fn basis(&self) -> MatRef<'_, f64> {
        self.theta.as_ref()
    }

    /// Reserve room for `columns` generators in all (`Theta` and the Gram matrix), so pushes
    /// up to that count copy nothing ([`Nnls::reserve`]).
    pub fn reserve(&mut self, columns: usize) {
        if columns > self.col_capacity {
            self.col_capacity = columns;
            self.theta.reserve(self.nrows(), columns);
        }
        self.nnls.reserve(columns);
    }

    /// Append a generator (length n) to the cone. `Theta` and the Gram matrix grow in place
    /// (capacity doubling: amortised O(n + k) per push, no copy of `Theta`).
    pub fn push_column(&mut self, column: &[f64]) {
        let (n, k) = (self.nrows(), self.ncols());
        assert_eq!(column.len(), n, "ConeProjector::push_column: column length differs from n");
        let mut cross = std::mem::take(&mut self.cross);
        cross.resize(k + 1, 0.0);
        at_b(self.theta.as_ref(), column, &mut cross[..k]);
        cross[k] = column.iter().map(|v| v * v).sum();
        if k + 1 > self.col_capacity {
            self.col_capacity = (2 * self.col_capacity).max(k + 1).max(4);
            self.theta.reserve(n, self.col_capacity);
        }
        self.theta.resize_with(n, k + 1, |i, _| column[i]);
        self.nnls.push_column(&cross);
        self.cross = cross;
        self.resize_workspaces();
    }

    /// The projector onto the cone of the first `m` generators (`m <= k`): the same `Theta`
    /// columns and Gram entries, so it computes bit for bit what a projector grown to those m
    /// generators computes.
    pub fn prefix(&self, m: usize) -> Self {
        assert!(m <= self.ncols(), "ConeProjector::prefix: {m} generators requested, {} held", self.ncols());
        let n = self.nrows();
        let mut out = Self {
            theta: Mat::from_fn(n, m, |i, j| self.theta[(i, j)]),
            nnls: self.nnls.prefix(m),
            atb: Vec::new(),
            correction: Vec::new(),
            trial: Vec::new(),
            cold: Vec::new(),
            residual: vec![0.0; n],
            trial_residual: vec![0.0; n],
            cross: Vec::new(),
            col_capacity: m,
            atb_lambda: Vec::new(),
        };
        out.resize_workspaces();
        out
    }

    fn resize_workspaces(&mut self) {
        let k = self.ncols();
        for buf in [&mut self.atb, &mut self.correction, &mut self.trial, &mut self.cold] {
            buf.resize(k, 0.0);
        }
    }

    /// Project `lambda` (length n) onto the cone, cold start (eq. 12).
    pub fn project(&mut self, lambda: &[f64]) -> Result<ConeProjection, ConeError> {
        let mut coeffs = vec![0.0; self.ncols()];
        let residual_norm = self.project_warm(lambda, &mut coeffs)?;
        Ok(ConeProjection { coeffs, residual_norm })
    }

    /// Project `lambda` starting from the coefficients in `coeffs` (length k; zeros = cold
    /// start), which receive the result; returns the residual norm.
    ///
    /// The KKT test `w_j <= tol * scale` only resolves relative residuals down to about
    /// `sqrt(tol)`: when `lambda` is (nearly) in an ill-conditioned cone, the column that
    /// would remove the last residual `r` has `w = O(||r||^2 / ||lambda||)`. A warm start from
    /// a large passive set of nearly parallel generators can stop there (seen: 1e-6 where a
    /// cold start reaches 1e-17), or with a column refused as dependent on the warm passive set
    /// (KKT residual above `tol`). In both cases the projection is repeated from a cold start,
    /// which enters the most correlated generator first, and the smaller residual is kept.
    pub fn project_warm(&mut self, lambda: &[f64], coeffs: &mut [f64]) -> Result<f64, ConeError> {
        assert_eq!(lambda.len(), self.nrows(), "ConeProjector: vector length differs from n");
        let mut atb = std::mem::take(&mut self.atb_lambda);
        atb.resize(self.ncols(), 0.0);
        at_b(self.theta.as_ref(), lambda, &mut atb);
        let out = self.project_warm_atb(lambda, &atb, coeffs);
        self.atb_lambda = atb;
        out
    }

    /// [`project_warm`](Self::project_warm) with `Theta^T lambda` given (`atb`, length k), e.g.
    /// kept per vector and extended by one inner product per new generator
    /// ([`dot_column`](Self::dot_column)): the same numbers as computing it here.
    pub fn project_warm_atb(&mut self, lambda: &[f64], atb: &[f64], coeffs: &mut [f64]) -> Result<f64, ConeError> {
        assert_eq!(lambda.len(), self.nrows(), "ConeProjector: vector length differs from n");
        assert_eq!(atb.len(), self.ncols(), "ConeProjector: Theta^T lambda has the wrong length");
        let warm = coeffs.iter().any(|c| *c > 0.0);
        let (mut norm, kkt) = self.solve_refined(lambda, atb, coeffs)?;
        let tol = self.nnls.params().tol;
        let rel = norm / norm2(lambda).max(f64::MIN_POSITIVE);
        let ambiguous = rel > IN_CONE_REL_TOL && rel < AMBIGUOUS_FACTOR * tol.sqrt();
        if warm && (kkt > tol || ambiguous) {
            let mut cold = std::mem::take(&mut self.cold);
            cold.fill(0.0);
            let (cold_norm, _) = self.solve_refined(lambda, atb, &mut cold)?;
            if cold_norm < norm {
                norm = cold_norm;
                coeffs.copy_from_slice(&cold);
            }
            self.cold = cold;
        }
        Ok(norm)
    }

    /// `theta_g^T v`, summed in the order [`project_warm`](Self::project_warm) uses for
    /// `Theta^T lambda`.
    pub fn dot_column(&self, g: usize, v: &[f64]) -> f64 {
        self.theta.col_as_slice(g).iter().zip(v).map(|(a, b)| a * b).sum()
    }

    /// NNLS from `coeffs`, then one refinement step on the passive set
    /// (`alpha_P += G_PP^{-1} Theta_P^T r`, kept only if it stays feasible and lowers the
    /// explicit residual). Returns the residual norm and the NNLS KKT residual.
    ///
    /// Residuals skip the zero coefficients and the refinement right-hand side is formed on the
    /// passive columns only (the passive solve reads nothing else): O(n p) instead of O(n k)
    /// for p passive columns, with the same numbers (a skipped term is `0 * theta`, which can
    /// only change the sign of a zero).
    fn solve_refined(&mut self, lambda: &[f64], atb: &[f64], coeffs: &mut [f64]) -> Result<(f64, f64), ConeError> {
        let stats = self.nnls.solve_normal(atb, coeffs)?;
        let theta = self.theta.as_ref();
        residual_sparse_into(theta, coeffs, lambda, &mut self.residual);
        let mut norm = norm2(&self.residual);
        for &j in self.nnls.passive_set() {
            self.atb[j] = theta.col(j).iter().zip(&self.residual).map(|(a, b)| a * b).sum();
        }
        self.nnls.solve_passive(&self.atb, &mut self.correction);
        for ((t, c), d) in self.trial.iter_mut().zip(coeffs.iter()).zip(&self.correction) {
            *t = c + d;
        }
        if self.trial.iter().all(|t| *t >= 0.0) {
            residual_sparse_into(theta, &self.trial, lambda, &mut self.trial_residual);
            let trial_norm = norm2(&self.trial_residual);
            if trial_norm < norm {
                norm = trial_norm;
                coeffs.copy_from_slice(&self.trial);
            }
        }
        Ok((norm, stats.kkt_residual))
    }

    /// Project every column of `snapshots` (n x N), each from a cold start: returns the
    /// coefficients (k x N) and the residual norms (length N).
    pub fn project_many(&mut self, snapshots: MatRef<'_, f64>) -> Result<(Mat<f64>, Vec<f64>), ConeError> {
        assert_eq!(snapshots.nrows(), self.nrows(), "ConeProjector: snapshot rows differ from n");
        let (k, count) = (self.ncols(), snapshots.ncols());
        let mut coeffs = Mat::zeros(k, count);
        let mut norms = Vec::with_capacity(count);
        let mut lambda = vec![0.0; self.nrows()];
        let mut alpha = vec![0.0; k];
        for j in 0..count {
            copy_column(snapshots, j, &mut lambda);
            alpha.fill(0.0);
            norms.push(self.project_warm(&lambda, &mut alpha)?);
            for (i, a) in alpha.iter().enumerate() {
                coeffs[(i, j)] = *a;
            }
        }
        Ok((coeffs, norms))
    }
}

/// `r = b - A x` over the non-zero entries of x (same order as `residual_into`).
fn residual_sparse_into(a: MatRef<'_, f64>, x: &[f64], b: &[f64], r: &mut [f64]) {
    r.copy_from_slice(b);
    for (j, &xj) in x.iter().enumerate() {
        if xj != 0.0 {
            for (ri, aij) in r.iter_mut().zip(a.col(j).iter()) {
                *ri -= xj * aij;
            }
        }
    }
}

/// Copy column j of `m` into `out`.
pub(crate) fn copy_column(m: MatRef<'_, f64>, j: usize, out: &mut [f64]) {
    for (o, v) in out.iter_mut().zip(m.col(j).iter()) {
        *o = *v;
    }
}

/// Cone projections of a fixed snapshot set (n x N) onto a cone grown one generator at a time.
#[derive(Debug, Clone)]
pub struct GrowingCone<'a> {
    snapshots: MatRef<'a, f64>,
    projector: ConeProjector,
    coeffs: Vec<Vec<f64>>,
    /// `Theta^T s_j` of the snapshots not yet in the cone, one entry per generator.
    atb: Vec<Vec<f64>>,
    residuals: Vec<f64>,
    norms: Vec<f64>,
    lambda: Vec<f64>,
}

impl<'a> GrowingCone<'a> {
    /// Start from the empty cone: every residual equals the snapshot norm.
    pub fn new(snapshots: MatRef<'a, f64>, params: NnlsParams) -> Self {
        let count = snapshots.ncols();
        let norms: Vec<f64> = (0..count).map(|j| snapshots.col(j).norm_l2()).collect();
        Self {
            snapshots,
            projector: ConeProjector::empty(snapshots.nrows(), params),
            coeffs: vec![Vec::new(); count],
            atb: vec![Vec::new(); count],
            residuals: norms.clone(),
            norms,
            lambda: vec![0.0; snapshots.nrows()],
        }
    }

    /// Append a generator and re-project every snapshot that is not yet in the cone (relative
    /// error above [`IN_CONE_REL_TOL`]), warm-started from its previous coefficients. Each
    /// snapshot keeps `Theta^T s_j`, extended by one inner product per generator.
    pub fn push(&mut self, column: &[f64]) -> Result<(), ConeError> {
        self.projector.push_column(column);
        let k = self.projector.ncols() - 1;
        for j in 0..self.snapshots.ncols() {
            self.coeffs[j].push(0.0);
            if self.residuals[j] > IN_CONE_REL_TOL * self.norms[j] {
                copy_column(self.snapshots, j, &mut self.lambda);
                let atb = &mut self.atb[j];
                atb.push(self.projector.dot_column(k, &self.lambda));
                self.residuals[j] = self.projector.project_warm_atb(&self.lambda, atb, &mut self.coeffs[j])?;
            } else if !self.atb[j].is_empty() {
                self.atb[j] = Vec::new(); // in the cone: never projected again
            }
        }
        Ok(())
    }

    /// Number of generators so far.
    pub fn len(&self) -> usize {
        self.projector.ncols()
    }

    /// True before the first generator.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The cone basis so far (n x m).
    pub fn basis(&self) -> MatRef<'_, f64> {
        self.projector.basis()
    }

    /// Euclidean norms of the snapshots (length N).
    pub fn norms(&self) -> &[f64] {
        &self.norms
    }

    /// Projection residual norms `||s_j - Pi(s_j)||` (length N).
    pub fn residuals(&self) -> &[f64] {
        &self.residuals
    }

    /// Coefficients of snapshot j on the current generators.
    pub fn coeffs(&self, j: usize) -> &[f64] {
        &self.coeffs[j]
    }

    /// The clipped intervals `[max(0, mu - sigma), mu + sigma]` of the coefficients of every
    /// snapshot on the first `m` generators (the specificity's sampling ranges, paper eq. 18).
    pub fn coefficient_intervals(&self, m: usize) -> Vec<(f64, f64)> {
        coefficient_intervals(m, (0..self.norms.len()).map(|j| self.coeffs(j)))
    }

    /// Relative projection error of snapshot j, `None` for a zero snapshot.
    pub fn relative_error(&self, j: usize) -> Option<f64> {
        (self.norms[j] > 0.0).then(|| self.residuals[j] / self.norms[j])
    }

    /// `||S - Pi(S)||_F`.
    pub fn frobenius_residual(&self) -> f64 {
        norm2(&self.residuals)
    }
}

/// The specificity's sampling interval of each of the first m coordinates (mean ± standard
/// deviation, clipped at 0) over the snapshots' coefficient vectors, pushed in the given order.
pub(crate) fn coefficient_intervals<'c>(m: usize, coeffs: impl IntoIterator<Item = &'c [f64]>) -> Vec<(f64, f64)> {
    let mut stats = vec![RunningStats::new(); m];
    for c in coeffs {
        for (st, a) in stats.iter_mut().zip(c) {
            st.push(*a);
        }
    }
    stats.iter().map(|st| st.interval(true)).collect()
}

#[cfg(test)]
mod tests {
    use super::super::nnls::residual_into;
    use super::*;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::{assert_all_close, assert_close};

    fn random_mat(rng: &mut Rng, n: usize, k: usize, lo: f64, hi: f64) -> Mat<f64> {
        Mat::from_fn(n, k, |_, _| rng.uniform_in(lo, hi))
    }

    fn random_vec(rng: &mut Rng, n: usize) -> Vec<f64> {
        (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect()
    }

    /// `Theta alpha`.
    fn image(theta: MatRef<'_, f64>, alpha: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; theta.nrows()];
        residual_into(theta, alpha, &vec![0.0; theta.nrows()], &mut out);
        out.iter_mut().for_each(|v| *v = -*v);
        out
    }

    fn diff_norm(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
    }

    #[test]
    fn projection_is_idempotent() {
        let mut rng = Rng::new(31);
        let theta = random_mat(&mut rng, 40, 12, 0.0, 1.0);
        let mut proj = ConeProjector::new(theta.as_ref(), NnlsParams::default());
        for _ in 0..20 {
            let lambda = random_vec(&mut rng, 40);
            let p1 = image(theta.as_ref(), &proj.project(&lambda).expect("converges").coeffs);
            let second = proj.project(&p1).expect("converges");
            let p2 = image(theta.as_ref(), &second.coeffs);
            // P(P(a)) = P(a): cond(Theta) ~ 30 for uniform [0,1] generators, so 1e-11 of
            // ||P(a)|| is ~1e4 eps of headroom after refinement.
            let scale = norm2(&p1);
            assert_close!(second.residual_norm, 0.0, Tol::abs(1e-11 * scale));
            assert_all_close!(p2, p1, Tol::abs(1e-11 * scale));
        }
    }

    #[test]
    fn projection_is_non_expansive_and_orthogonal() {
        let mut rng = Rng::new(32);
        let theta = random_mat(&mut rng, 30, 20, 0.0, 1.0);
        let mut proj = ConeProjector::new(theta.as_ref(), NnlsParams::default());
        for _ in 0..50 {
            let a = random_vec(&mut rng, 30);
            let mut b = a.clone();
            let step = rng.uniform_in(1e-3, 1.0);
            b.iter_mut().for_each(|v| *v += step * rng.uniform_in(-1.0, 1.0));
            let pa = image(theta.as_ref(), &proj.project(&a).expect("converges").coeffs);
            let pb = image(theta.as_ref(), &proj.project(&b).expect("converges").coeffs);
            // ||P(a) - P(b)|| <= ||a - b||; slack 1e-12 (relative) + 1e-12 ||a|| (absolute)
            // for the round-off of two projections.
            let slack = 1e-12 * diff_norm(&a, &b) + 1e-12 * norm2(&a);
            assert!(diff_norm(&pa, &pb) <= diff_norm(&a, &b) + slack);
            // Projection onto a cone: the residual is orthogonal to the projection.
            let dot: f64 = a.iter().zip(&pa).map(|(x, p)| (x - p) * p).sum();
            assert_close!(dot, 0.0, Tol::abs(1e-11 * norm2(&a) * norm2(&a)));
        }
    }

    #[test]
    fn residual_norm_is_explicit() {
        let mut rng = Rng::new(33);
        let theta = random_mat(&mut rng, 25, 6, 0.0, 1.0);
        let mut proj = ConeProjector::new(theta.as_ref(), NnlsParams::default());
        let lambda = random_vec(&mut rng, 25);
        let out = proj.project(&lambda).expect("converges");
        let p = image(theta.as_ref(), &out.coeffs);
        // Same residual recomputed here: only summation order differs (1e-14 relative).
        assert_close!(out.residual_norm, diff_norm(&lambda, &p), Tol::rel(1e-14));
        assert!(out.coeffs.iter().all(|c| *c >= 0.0));
    }

    #[test]
    fn project_many_matches_project() {
        let mut rng = Rng::new(34);
        let theta = random_mat(&mut rng, 20, 7, 0.0, 1.0);
        let snaps = random_mat(&mut rng, 20, 9, -1.0, 1.0);
        let mut proj = ConeProjector::new(theta.as_ref(), NnlsParams::default());
        let (coeffs, norms) = proj.project_many(snaps.as_ref()).expect("converges");
        for (j, norm) in norms.iter().enumerate() {
            let lambda: Vec<f64> = snaps.col(j).iter().copied().collect();
            let one = proj.project(&lambda).expect("converges");
            // Identical computations (cold start each): bitwise equal in practice.
            assert_close!(*norm, one.residual_norm, Tol::rel(1e-15));
            let col: Vec<f64> = coeffs.col(j).iter().copied().collect();
            assert_all_close!(col, one.coeffs, Tol::abs(1e-15));
        }
    }

    #[test]
    fn growing_cone_matches_cold_projections() {
        let mut rng = Rng::new(35);
        let theta = random_mat(&mut rng, 30, 10, 0.0, 1.0);
        let snaps = random_mat(&mut rng, 30, 12, -0.5, 1.0);
        let mut cone = GrowingCone::new(snaps.as_ref(), NnlsParams::default());
        assert_all_close!(cone.residuals(), cone.norms(), Tol::abs(0.0));
        for m in 0..10 {
            let col: Vec<f64> = theta.col(m).iter().copied().collect();
            cone.push(&col).expect("converges");
            let mut cold = ConeProjector::new(theta.subcols(0, m + 1), NnlsParams::default());
            let (_, norms) = cold.project_many(snaps.as_ref()).expect("converges");
            // Warm and cold starts reach the same unique residual norm; 1e-12 of the snapshot
            // norms (O(3)) covers the different round-off paths.
            assert_all_close!(cone.residuals(), norms, Tol::abs(1e-12 * 3.0));
        }
    }

    #[test]
    fn empty_cone_projects_to_zero() {
        let mut proj = ConeProjector::empty(3, NnlsParams::default());
        let out = proj.project(&[3.0, 0.0, -4.0]).expect("trivial");
        assert!(out.coeffs.is_empty());
        assert_close!(out.residual_norm, 5.0, Tol::rel(1e-15)); // ||lambda|| = 5
    }

    #[test]
    fn prefix_projects_like_a_projector_grown_to_that_size() {
        let mut rng = Rng::new(36);
        let theta = random_mat(&mut rng, 30, 12, 0.0, 1.0);
        let mut grown = ConeProjector::empty(30, NnlsParams::default());
        let mut small = ConeProjector::empty(30, NnlsParams::default());
        for m in 0..12 {
            let col: Vec<f64> = theta.col(m).iter().copied().collect();
            grown.push_column(&col);
            if m < 7 {
                small.push_column(&col);
            }
        }
        let mut prefix = grown.prefix(7);
        for _ in 0..10 {
            let lambda = random_vec(&mut rng, 30);
            let a = prefix.project(&lambda).expect("converges");
            let b = small.project(&lambda).expect("converges");
            // Same Theta columns, same Gram entries, same arithmetic: bit for bit.
            assert_close!(a.residual_norm, b.residual_norm, Tol::abs(0.0));
            assert_all_close!(a.coeffs, b.coeffs, Tol::abs(0.0));
        }
        // The prefix keeps growing like the original.
        let col: Vec<f64> = theta.col(7).iter().copied().collect();
        prefix.push_column(&col);
        small.push_column(&col);
        let lambda = random_vec(&mut rng, 30);
        let (a, b) = (prefix.project(&lambda).expect("ok"), small.project(&lambda).expect("ok"));
        assert_close!(a.residual_norm, b.residual_norm, Tol::abs(0.0)); // as above
    }
}
