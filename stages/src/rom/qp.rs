//! The reduced contact problem for a fixed linearisation, solved exactly: the strictly convex QP
//!
//! ```text
//! min_x  1/2 x^T G x    subject to   s_i(x) = a_i . x + b_i >= 0,  i = 1..m
//! ```
//!
//! (`G = K̂`, `a_i` = rows of `Ĉ`, `b = ĝ0`; its KKT conditions are eq. 13 with the sign
//! conditions `λ̂ >= 0`, `ŝ >= 0`, `λ̂ ŝ = 0`) by the dual active-set method of Goldfarb and
//! Idnani (Math. Programming 27, 1983). It starts at the unconstrained minimiser `x = 0`, adds
//! the most violated constraint, and moves along the direction that keeps the active
//! constraints satisfied while the dual objective strictly increases; a constraint whose
//! multiplier would turn negative is dropped on the way. Because the dual objective increases
//! strictly between active sets, no active set repeats and the method terminates finitely with
//! either the optimum or a proof of infeasibility (a violated constraint that no combination of
//! the active ones can fix). Linearly dependent constraints — frequent when the dual basis is
//! richer than the primal one — never enter the active set together: a dependent candidate
//! triggers a pure dual step that drops one of the constraints it depends on.
//!
//! It runs in the range space of the Cholesky factor `G = L L^T`: with `y = L^T x` the
//! objective is `|y|^2 / 2` and constraint `i` reads `w_i . y + b_i >= 0`, `w_i = L^{-1} a_i`.
//! The active normals `W_A` are kept with the triangular `R` of `W_A^T W_A = R^T R`, updated by
//! appending a column (add) or by Givens rotations (drop), so a step costs `O(r q)` plus one
//! triangular solve `O(r^2 / 2)` for the candidate, with `q` active constraints — not `O(r^2)`
//! per active constraint. A warm start takes a previous active set, computes its
//! equality-constrained minimiser and drops constraints with negative multipliers until the
//! rest are non-negative: that is a valid starting point of the method (the minimiser on the
//! active constraints, dual feasible), so finite termination is kept. The constraints are
//! supplied through [`QpConstraints`], so a caller can evaluate all `s(x)` cheaply without
//! forming every row (the Type-2 online solve does).

use super::la::{axpy, dot, Factor};

/// The constraints `s_i(x) = a_i . x + b_i >= 0`.
pub trait QpConstraints {
    /// Number of constraints `m`.
    fn len(&self) -> usize;
    /// No constraints.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// `s(x)` for every constraint (`s.len() == m`).
    fn values(&mut self, x: &[f64], s: &mut [f64]);
    /// Row `a_i` (`out.len() == r`).
    fn row(&mut self, i: usize, out: &mut [f64]);
    /// Optional fast path: the row already in the range space, `w_i = L^{-1} a_i`; `false` if
    /// not available (the solver then calls [`Self::row`] and solves with `L`).
    fn range_row(&mut self, _i: usize, _out: &mut [f64]) -> bool {
        false
    }
    /// Optional fast path: `s = W^T y + b` from the range-space iterate `y = L^T x`; `false`
    /// if not available (the solver then forms `x` and calls [`Self::values`]).
    fn range_values(&mut self, _y: &[f64], _s: &mut [f64]) -> bool {
        false
    }
}

/// `w = L^{-1} a_i`, through the fast path when the constraints offer it.
fn range_row(cons: &mut dyn QpConstraints, l: Factor<'_>, r: usize, i: usize, np: &mut [f64], wp: &mut [f64]) {
    if !cons.range_row(i, wp) {
        cons.row(i, np);
        wp.copy_from_slice(np);
        l.forward(r, wp);
    }
}

/// Dense constraints: `a` row-major `m x r`, `b` length `m`.
#[derive(Debug)]
pub struct DenseConstraints<'a> {
    /// Rows.
    pub a: &'a [f64],
    /// Offsets.
    pub b: &'a [f64],
}

impl QpConstraints for DenseConstraints<'_> {
    fn len(&self) -> usize {
        self.b.len()
    }
    fn values(&mut self, x: &[f64], s: &mut [f64]) {
        let r = x.len();
        for (i, si) in s.iter_mut().enumerate() {
            *si = self.a[i * r..(i + 1) * r].iter().zip(x).map(|(a, x)| a * x).sum::<f64>() + self.b[i];
        }
    }
    fn row(&mut self, i: usize, out: &mut [f64]) {
        let r = out.len();
        out.copy_from_slice(&self.a[i * r..(i + 1) * r]);
    }
}

/// Relative size below which a candidate's component outside the span of the active normals
/// (`|z|` against `|w_p|`, in the range space) counts as zero: the candidate is linearly
/// dependent on the active constraints. `1e-8`: the component is computed from `R` (the
/// seminormal equations lose up to `cond(W_A)^2 eps`), and no two distinct reduced constraints
/// of crom's bases are that close to dependent.
pub const DEPENDENT_TOL: f64 = 1e-8;

/// How a QP solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QpOutcome {
    /// Optimal: every constraint satisfied within the tolerance, multipliers `>= 0`.
    Solved,
    /// Constraint `i` is violated and cannot be satisfied together with the active ones.
    Infeasible(usize),
    /// The step limit was reached (only through rounding: the exact method terminates).
    StepLimit,
}

/// Buffers of a QP solve (allocated once, reused across solves of size up to their capacity).
#[derive(Debug, Clone, Default)]
pub struct QpWork {
    y: Vec<f64>,
    /// Active normals in the range space, column `k` at `k r`.
    wa: Vec<f64>,
    /// `R`, column-major with stride `r`.
    rm: Vec<f64>,
    wp: Vec<f64>,
    np: Vec<f64>,
    c: Vec<f64>,
    rv: Vec<f64>,
    z: Vec<f64>,
    s: Vec<f64>,
    up: Vec<f64>,
    zero: Vec<f64>,
    warm: Vec<usize>,
    /// Active constraints, in the order of the columns of `R`.
    pub active: Vec<usize>,
    /// Their multipliers.
    pub u: Vec<f64>,
    /// Number of add/drop steps of the last solve.
    pub steps: usize,
}

impl QpWork {
    /// `c = W_A^T v`, then `d1 = R^{-T} c` in place (forward substitution with `R^T`).
    fn project(&mut self, r: usize, v_is_wp: bool) {
        let q = self.active.len();
        self.c.clear();
        for k in 0..q {
            let v = if v_is_wp { &self.wp } else { &self.z };
            self.c.push(dot(&self.wa[k * r..(k + 1) * r], v));
        }
        for i in 0..q {
            let s = dot(&self.rm[i * r..i * r + i], &self.c[..i]);
            self.c[i] = (self.c[i] - s) / self.rm[i + i * r];
        }
    }

    /// `v <- (I - P_A) v`, `P_A` the orthogonal projector onto the span of the active normals
    /// of the last solve (`P_A = W_A (W_A^T W_A)^{-1} W_A^T`, through `R`).
    pub fn remove_active_span(&mut self, r: usize, v: &mut [f64]) {
        let q = self.active.len();
        if q == 0 {
            return;
        }
        self.z.clear();
        self.z.extend_from_slice(v);
        self.project(r, false);
        self.back(r);
        for k in 0..q {
            axpy(-self.rv[k], &self.wa[k * r..(k + 1) * r], v);
        }
    }

    /// `rv = R^{-1} c` (back substitution).
    fn back(&mut self, r: usize) {
        let q = self.active.len();
        self.rv.clear();
        self.rv.resize(q, 0.0);
        for i in (0..q).rev() {
            let mut v = self.c[i];
            for k in i + 1..q {
                v -= self.rm[i + k * r] * self.rv[k];
            }
            self.rv[i] = v / self.rm[i + i * r];
        }
    }

    /// Append the candidate `wp` with `R` column `[c; rho]`.
    fn append(&mut self, r: usize, rho: f64) {
        let q = self.active.len();
        for i in 0..q {
            self.rm[i + q * r] = self.c[i];
        }
        self.rm[q + q * r] = rho;
        self.wa[q * r..(q + 1) * r].copy_from_slice(&self.wp);
    }

    /// Remove active constraint `l`: its `W_A` column and `R` column, then restore the triangle
    /// with Givens rotations on rows `l..q` (`R^T R` is unchanged by them).
    fn remove(&mut self, r: usize, l: usize) {
        let q = self.active.len();
        self.active.remove(l);
        self.wa.copy_within((l + 1) * r..q * r, l * r);
        for k in l..q - 1 {
            for i in 0..=k + 1 {
                self.rm[i + k * r] = self.rm[i + (k + 1) * r];
            }
        }
        for i in 0..q {
            self.rm[i + (q - 1) * r] = 0.0;
        }
        for j in l..q - 1 {
            let (a, b) = (self.rm[j + j * r], self.rm[j + 1 + j * r]);
            if b == 0.0 {
                continue;
            }
            let h = a.hypot(b);
            let (c, s) = (a / h, b / h);
            for k in j..q - 1 {
                let (x, y) = (self.rm[j + k * r], self.rm[j + 1 + k * r]);
                self.rm[j + k * r] = c * x + s * y;
                self.rm[j + 1 + k * r] = -s * x + c * y;
            }
            self.rm[j + 1 + j * r] = 0.0;
        }
    }
}

/// Solve the QP. `l`: the Cholesky factor of `G` (column-major `r x r`, lower triangle), or
/// [`Factor::Identity`] when `G = I` (then no triangular solve is made);
/// `feas_tol`: a constraint counts as satisfied when `s_i >= -feas_tol`; `max_steps`: cap on
/// add/drop steps; `warm`: an active set to start from (may be empty or not optimal). On return
/// `x` holds the minimiser and `w.active`, `w.u` the active constraints and their multipliers.
#[allow(clippy::too_many_arguments)]
pub fn solve_qp(
    l: Factor<'_>,
    r: usize,
    cons: &mut dyn QpConstraints,
    feas_tol: f64,
    max_steps: usize,
    warm: &[usize],
    x: &mut [f64],
    w: &mut QpWork,
) -> QpOutcome {
    let m = cons.len();
    if let Factor::Lower(f) = l {
        assert_eq!(f.len(), r * r, "factor shape");
    }
    assert_eq!(x.len(), r, "x length");
    reset(w, r, m, warm);
    if !w.warm.is_empty() {
        warm_start(cons, l, r, w);
    }
    loop {
        // Step 1: the most violated constraint at x = L^{-T} y.
        let Some(p) = most_violated(cons, l, r, feas_tol, x, w) else {
            x.copy_from_slice(&w.y);
            l.backward_t(r, x);
            return QpOutcome::Solved;
        };
        // Step 2: add it (dropping constraints whose multipliers reach zero on the way).
        if let Some(outcome) = add_violated(cons, l, r, p, max_steps, w) {
            return outcome;
        }
    }
}

/// The work vectors sized for `r` unknowns and `m` constraints, nothing active, and the warm
/// start's constraints (those that exist).
fn reset(w: &mut QpWork, r: usize, m: usize, warm: &[usize]) {
    for v in [&mut w.y, &mut w.wp, &mut w.np, &mut w.z, &mut w.zero] {
        v.clear();
        v.resize(r, 0.0);
    }
    // W_A and R are written before they are read (columns < q only): no need to clear them
    if w.wa.len() < r * r {
        w.wa.resize(r * r, 0.0);
    }
    if w.rm.len() < r * r {
        w.rm.resize(r * r, 0.0);
    }
    w.s.clear();
    w.s.resize(m, 0.0);
    w.active.clear();
    w.u.clear();
    w.steps = 0;
    w.warm.clear();
    w.warm.extend(warm.iter().copied().filter(|&a| a < m));
}

/// Warm start: add the given constraints (skipping dependent ones), then drop negative
/// multipliers until the equality-constrained minimiser is dual feasible; `y` is then that
/// minimiser and `u` its multipliers.
fn warm_start(cons: &mut dyn QpConstraints, l: Factor<'_>, r: usize, w: &mut QpWork) {
    let zero = std::mem::take(&mut w.zero);
    cons.values(&zero, &mut w.s);
    w.zero = zero;
    for k in 0..w.warm.len() {
        let a = w.warm[k];
        if w.active.len() >= r || w.active.contains(&a) {
            continue;
        }
        range_row(cons, l, r, a, &mut w.np, &mut w.wp);
        direction(w, r);
        let (z2, wn) = (dot(&w.z, &w.z), dot(&w.wp, &w.wp));
        if z2 > DEPENDENT_TOL * DEPENDENT_TOL * wn {
            w.append(r, z2.sqrt());
            w.active.push(a);
        }
    }
    loop {
        // u = -R^{-1} R^{-T} b_A
        let q = w.active.len();
        w.c.clear();
        for i in 0..q {
            let s = dot(&w.rm[i * r..i * r + i], &w.c[..i]);
            let b = w.s[w.active[i]];
            w.c.push((-b - s) / w.rm[i + i * r]);
        }
        w.back(r);
        let worst = (0..q).filter(|&i| w.rv[i] < 0.0).min_by(|&i, &j| w.rv[i].total_cmp(&w.rv[j]));
        match worst {
            Some(i) => w.remove(r, i),
            None => break,
        }
    }
    w.u.clear();
    w.u.extend_from_slice(&w.rv);
    for i in 0..w.active.len() {
        let ui = w.u[i];
        let (wa, y) = (&w.wa[i * r..(i + 1) * r], &mut w.y);
        axpy(ui, wa, y);
    }
}

/// The step direction of the constraint row `wp` against the active set: `rv = R^{-1} W_A^T wp`
/// (the multipliers' rates) and `z = wp - W_A rv`, its part orthogonal to the active rows.
fn direction(w: &mut QpWork, r: usize) {
    w.project(r, true);
    w.back(r);
    w.z.copy_from_slice(&w.wp);
    for i in 0..w.active.len() {
        let rv = w.rv[i];
        let (wa, z) = (&w.wa[i * r..(i + 1) * r], &mut w.z);
        axpy(-rv, wa, z);
    }
}

/// The most violated inactive constraint (below `-feas_tol`) at `x = L^{-T} y`, or `None`;
/// the constraint values are in `s`.
fn most_violated(
    cons: &mut dyn QpConstraints,
    l: Factor<'_>,
    r: usize,
    feas_tol: f64,
    x: &mut [f64],
    w: &mut QpWork,
) -> Option<usize> {
    if !cons.range_values(&w.y, &mut w.s) {
        x.copy_from_slice(&w.y);
        l.backward_t(r, x);
        cons.values(x, &mut w.s);
    }
    let mut p = None;
    let mut worst = -feas_tol;
    for i in 0..w.s.len() {
        if w.s[i] < worst && !w.active.contains(&i) {
            worst = w.s[i];
            p = Some(i);
        }
    }
    p
}

/// Step 2 for the violated constraint `p`: move until it is satisfied (full step: it joins the
/// active set) or an active multiplier reaches zero (partial step: that constraint leaves, and
/// the move goes on). `None` once `p` is active; otherwise how the solve ends (the step cap,
/// or infeasible: `p` cannot be satisfied).
fn add_violated(
    cons: &mut dyn QpConstraints,
    l: Factor<'_>,
    r: usize,
    p: usize,
    max_steps: usize,
    w: &mut QpWork,
) -> Option<QpOutcome> {
    let mut sp = w.s[p];
    range_row(cons, l, r, p, &mut w.np, &mut w.wp);
    let wn = dot(&w.wp, &w.wp);
    w.up.clear();
    w.up.extend_from_slice(&w.u);
    w.up.push(0.0);
    loop {
        w.steps += 1;
        if w.steps > max_steps {
            return Some(QpOutcome::StepLimit);
        }
        let q = w.active.len();
        direction(w, r);
        // partial step: the first active multiplier to reach zero
        let (mut t1, mut lidx) = (f64::INFINITY, usize::MAX);
        for k in 0..q {
            if w.rv[k] > 0.0 {
                let t = w.up[k] / w.rv[k];
                if t < t1 {
                    t1 = t;
                    lidx = k;
                }
            }
        }
        // full step: s_p reaches zero along z (z . w_p = |z|^2)
        let z2 = dot(&w.z, &w.z);
        let t2 = if z2 > DEPENDENT_TOL * DEPENDENT_TOL * wn { -sp / z2 } else { f64::INFINITY };
        if t1.is_infinite() && t2.is_infinite() {
            return Some(QpOutcome::Infeasible(p));
        }
        let t = t1.min(t2);
        for k in 0..q {
            w.up[k] -= t * w.rv[k];
        }
        w.up[q] += t;
        if t2.is_finite() {
            let (z, y) = (&w.z, &mut w.y);
            axpy(t, z, y);
            sp += t * z2;
        }
        if t2 <= t1 {
            w.append(r, z2.sqrt());
            w.active.push(p);
            w.u.clear();
            w.u.extend_from_slice(&w.up);
            return None;
        }
        // partial (or pure dual) step: drop the constraint whose multiplier reached zero
        // and go on with p (still violated: t1 < t2 leaves s_p < 0)
        w.remove(r, lidx);
        w.up.remove(lidx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::rom::la::Factor;
    use crate::rom::saddle::cholesky;
    use crate::testing::spd;

    /// Independent reference: enumerate every subset of constraints as the active set, solve
    /// the equality-constrained KKT system densely (Gaussian elimination with pivoting on the
    /// full saddle matrix), keep the subsets whose solution is feasible with non-negative
    /// multipliers, return the best objective (the optimum is unique for SPD `G`).
    fn brute_force(g: &[f64], a: &[f64], b: &[f64], r: usize) -> Option<(Vec<f64>, f64)> {
        let m = b.len();
        let mut best: Option<(Vec<f64>, f64)> = None;
        for mask in 0u32..(1 << m) {
            let act: Vec<usize> = (0..m).filter(|i| mask & (1 << i) != 0).collect();
            let n = r + act.len();
            let mut mat = vec![0.0; n * n];
            let mut rhs = vec![0.0; n];
            for i in 0..r {
                for j in 0..r {
                    mat[i * n + j] = g[i + j * r];
                }
            }
            for (k, &c) in act.iter().enumerate() {
                for j in 0..r {
                    mat[(r + k) * n + j] = a[c * r + j];
                    mat[j * n + r + k] = -a[c * r + j];
                }
                rhs[r + k] = -b[c];
            }
            let Some(sol) = gauss(&mut mat, &mut rhs, n) else { continue };
            let x = &sol[..r];
            let ok_dual = sol[r..].iter().all(|&l| l >= -1e-9);
            let ok_primal = (0..m).all(|i| (0..r).map(|j| a[i * r + j] * x[j]).sum::<f64>() + b[i] >= -1e-9);
            if ok_dual && ok_primal {
                let f = 0.5 * (0..r).map(|i| x[i] * (0..r).map(|j| g[i + j * r] * x[j]).sum::<f64>()).sum::<f64>();
                if best.as_ref().is_none_or(|(_, bf)| f < *bf) {
                    best = Some((x.to_vec(), f));
                }
            }
        }
        best
    }

    fn gauss(mat: &mut [f64], rhs: &mut [f64], n: usize) -> Option<Vec<f64>> {
        for c in 0..n {
            let p = (c..n).max_by(|&i, &j| mat[i * n + c].abs().total_cmp(&mat[j * n + c].abs()))?;
            if mat[p * n + c].abs() < 1e-10 {
                return None;
            }
            for k in 0..n {
                mat.swap(c * n + k, p * n + k);
            }
            rhs.swap(c, p);
            for i in c + 1..n {
                let f = mat[i * n + c] / mat[c * n + c];
                for k in c..n {
                    mat[i * n + k] -= f * mat[c * n + k];
                }
                rhs[i] -= f * rhs[c];
            }
        }
        let mut x = vec![0.0; n];
        for i in (0..n).rev() {
            x[i] = (rhs[i] - (i + 1..n).map(|k| mat[i * n + k] * x[k]).sum::<f64>()) / mat[i * n + i];
        }
        Some(x)
    }

    /// Against the brute-force reference on 400 random problems (r = 1..6, m = 1..8, some with
    /// duplicated rows and more constraints than unknowns): the same minimiser (1e-8: the
    /// reference eliminates a saddle matrix of condition up to ~1e6) or both infeasible, and
    /// the returned multipliers satisfy `G x = sum u_i a_i` (1e-9) with `u >= 0`; a warm start
    /// from a random subset of the constraints returns the cold start's minimiser (1e-9).
    #[test]
    fn matches_active_set_enumeration() {
        let mut rng = Rng::new(11);
        let (mut solved, mut infeasible) = (0, 0);
        for case in 0..400 {
            let r = 1 + case % 6;
            let m = 1 + (case / 6) % 8;
            let g = spd(r, 0.5, &mut rng);
            let mut a: Vec<f64> = (0..m * r).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let b: Vec<f64> = (0..m).map(|_| rng.uniform_in(-1.0, 0.5)).collect();
            if case % 5 == 0 && m >= 2 {
                let row0 = a[..r].to_vec();
                a[r..2 * r].copy_from_slice(&row0);
            }
            let mut l = g.clone();
            assert!(cholesky(&mut l, r));
            let mut x = vec![0.0; r];
            let mut w = QpWork::default();
            // cold, then warm-started from a random subset (must not change the answer)
            let warm: Vec<usize> = (0..m).filter(|_| rng.uniform() < 0.5).collect();
            let cold = solve_qp(
                Factor::Lower(&l),
                r,
                &mut DenseConstraints { a: &a, b: &b },
                1e-12,
                1000,
                &[],
                &mut x,
                &mut w,
            );
            let x_cold = x.clone();
            let out = solve_qp(
                Factor::Lower(&l),
                r,
                &mut DenseConstraints { a: &a, b: &b },
                1e-12,
                1000,
                &warm,
                &mut x,
                &mut w,
            );
            assert_eq!(std::mem::discriminant(&cold), std::mem::discriminant(&out), "case {case}: warm start");
            if cold == QpOutcome::Solved {
                for (p, q) in x.iter().zip(&x_cold) {
                    assert!((p - q).abs() <= 1e-9 * (1.0 + q.abs()), "case {case}: warm {x:?} vs cold {x_cold:?}");
                }
            }
            match (out, brute_force(&g, &a, &b, r)) {
                (QpOutcome::Solved, Some((xr, _))) => {
                    solved += 1;
                    for (p, q) in x.iter().zip(&xr) {
                        assert!((p - q).abs() <= 1e-8 * (1.0 + q.abs()), "case {case}: {x:?} vs {xr:?}");
                    }
                    assert!(w.u.iter().all(|&u| u >= 0.0), "case {case}: {:?}", w.u);
                    for i in 0..r {
                        let gx: f64 = (0..r).map(|j| g[i + j * r] * x[j]).sum();
                        let nu: f64 = w.active.iter().zip(&w.u).map(|(&c, u)| u * a[c * r + i]).sum();
                        assert!((gx - nu).abs() <= 1e-9, "case {case}: stationarity {gx} vs {nu}");
                    }
                }
                (QpOutcome::Infeasible(_), None) => infeasible += 1,
                (o, reference) => panic!("case {case}: {o:?} vs reference {reference:?}"),
            }
        }
        assert!(solved > 200 && infeasible > 5, "coverage: {solved} solved, {infeasible} infeasible");
    }
}
