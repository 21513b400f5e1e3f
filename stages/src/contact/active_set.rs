//! The condensed contact problem for a frozen pairing: a linear complementarity problem
//!
//! ```text
//! g = q + D lambda,   lambda >= 0,   g >= 0,   lambda_i g_i = 0,
//! ```
//!
//! with `D = B W B^T` symmetric positive definite (Delassus operator, see [`super::delassus`]),
//! `lambda` the nodal contact forces and `g` the linearised gaps. It is the KKT system of
//! `min 1/2 lambda^T D lambda + q^T lambda, lambda >= 0` (the dual of paper eq. 6 for fixed `C`).
//!
//! Solved by the primal-dual active set method (PDAS; Hintermüller, Ito & Kunisch 2002, a
//! semismooth Newton method on `min(lambda, c g) = 0`): given the active set `A`, solve
//! `D_AA lambda_A = -q_A`, `lambda_I = 0`, compute `g`, and take the new active set
//! `{i in A: lambda_i > 0} U {i in I: c g_i < -eps}`; stop when it repeats. Each step is one dense
//! Cholesky solve of size `|A|`. PDAS is finite for M-matrices; `D` is not one, so if PDAS
//! cycles or exceeds its step budget the solve falls back to a Lawson–Hanson-type primal active
//! set method on the same QP, which is finite and monotone for SPD `D`.
//!
//! All buffers live in [`LcpWork`], allocated once per snapshot solve.

/// Preallocated buffers for [`solve_lcp`]; sized for at most `n` unknowns.
#[derive(Debug, Clone)]
pub struct LcpWork {
    idx: Vec<usize>,
    chol: Vec<f64>,
    z: Vec<f64>,
    new_active: Vec<bool>,
    prev_active: Vec<bool>,
}

impl LcpWork {
    /// Buffers for problems with up to `n` unknowns.
    pub fn new(n: usize) -> Self {
        Self {
            idx: Vec::with_capacity(n),
            chol: vec![0.0; n * n],
            z: vec![0.0; n],
            new_active: vec![false; n],
            prev_active: vec![false; n],
        }
    }
}

/// Failure of the condensed solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LcpError {
    /// `D_AA` is not positive definite (dependent constraints); carries the failing pivot.
    NotPositiveDefinite(f64),
    /// The iteration budget ran out in the fallback too.
    Budget,
}

/// Outcome of one condensed solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LcpOutcome {
    /// Dense solves performed.
    pub iterations: usize,
    /// True when PDAS cycled and the primal active set method finished the job.
    pub fell_back: bool,
}

/// The LCP data: `D` row-major `n x n` (leading dimension `n`) and `q`.
#[derive(Debug, Clone, Copy)]
pub struct Lcp<'a> {
    /// `D`, row-major, `n * n`.
    pub d: &'a [f64],
    /// `q`, length `n`.
    pub q: &'a [f64],
    /// Scale turning gaps into forces (`c ~ 1 / diag(D)`), used in the activation test.
    pub c: f64,
    /// Activation threshold in force units: inactive `i` becomes active when `c g_i < -eps`.
    pub eps: f64,
}

impl Lcp<'_> {
    fn n(&self) -> usize {
        self.q.len()
    }
}

/// Solve the LCP, warm-started from `active` (length `n`, updated in place). On return `lambda`
/// and `g` (length `n`) hold the solution and its gaps. `max_iter` bounds the dense solves.
pub fn solve_lcp(
    lcp: &Lcp<'_>,
    active: &mut [bool],
    lambda: &mut [f64],
    g: &mut [f64],
    ws: &mut LcpWork,
    max_iter: usize,
) -> Result<LcpOutcome, LcpError> {
    let n = lcp.n();
    assert!(lcp.d.len() >= n * n && active.len() == n && lambda.len() == n && g.len() == n, "LCP shape mismatch");
    assert!(ws.z.len() >= n, "LCP workspace too small");
    let pdas_budget = max_iter.min(2 * n + 20);
    let mut it = 0;
    ws.prev_active[..n].fill(false);
    while it < pdas_budget {
        solve_on_set(lcp, active, lambda, ws)?;
        it += 1;
        gaps(lcp, lambda, g);
        let mut changed = false;
        for i in 0..n {
            let a = if active[i] { lambda[i] > 0.0 } else { lcp.c * g[i] < -lcp.eps };
            ws.new_active[i] = a;
            changed |= a != active[i];
        }
        if !changed {
            return Ok(LcpOutcome { iterations: it, fell_back: false });
        }
        // period-2 cycle: the new set equals the one before the current one
        let cycled = it > 1 && ws.new_active[..n] == ws.prev_active[..n];
        ws.prev_active[..n].copy_from_slice(&active[..n]);
        active.copy_from_slice(&ws.new_active[..n]);
        if cycled {
            break;
        }
    }
    let extra = primal_active_set(lcp, active, lambda, g, ws, max_iter.saturating_sub(it))?;
    Ok(LcpOutcome { iterations: it + extra, fell_back: true })
}

/// `g = q + D lambda` using only the nonzero entries of `lambda`.
fn gaps(lcp: &Lcp<'_>, lambda: &[f64], g: &mut [f64]) {
    let n = lcp.n();
    g.copy_from_slice(lcp.q);
    for (j, &lj) in lambda.iter().enumerate() {
        if lj != 0.0 {
            for (i, gi) in g.iter_mut().enumerate() {
                *gi += lcp.d[i * n + j] * lj;
            }
        }
    }
}

/// `lambda_A = -D_AA^{-1} q_A`, `lambda_I = 0`, with `A = {i: set[i]}`.
fn solve_on_set(lcp: &Lcp<'_>, set: &[bool], lambda: &mut [f64], ws: &mut LcpWork) -> Result<(), LcpError> {
    let n = lcp.n();
    ws.idx.clear();
    ws.idx.extend((0..n).filter(|&i| set[i]));
    let m = ws.idx.len();
    lambda.fill(0.0);
    if m == 0 {
        return Ok(());
    }
    for (r, &i) in ws.idx.iter().enumerate() {
        for (c, &j) in ws.idx.iter().enumerate().take(r + 1) {
            ws.chol[r * m + c] = lcp.d[i * n + j];
        }
        ws.z[r] = -lcp.q[i];
    }
    cholesky_solve_in_place(&mut ws.chol[..m * m], m, &mut ws.z[..m])?;
    for (r, &i) in ws.idx.iter().enumerate() {
        lambda[i] = ws.z[r];
    }
    Ok(())
}

/// In-place Cholesky `A = L L^T` of the lower triangle of the row-major `m x m` matrix `a`, then
/// solve `A x = b` into `b`.
pub fn cholesky_solve_in_place(a: &mut [f64], m: usize, b: &mut [f64]) -> Result<(), LcpError> {
    for j in 0..m {
        let mut s = a[j * m + j];
        for k in 0..j {
            s -= a[j * m + k] * a[j * m + k];
        }
        if s.is_nan() || s <= 0.0 {
            return Err(LcpError::NotPositiveDefinite(s));
        }
        let ljj = s.sqrt();
        a[j * m + j] = ljj;
        for i in j + 1..m {
            let mut t = a[i * m + j];
            for k in 0..j {
                t -= a[i * m + k] * a[j * m + k];
            }
            a[i * m + j] = t / ljj;
        }
    }
    for i in 0..m {
        let mut t = b[i];
        for k in 0..i {
            t -= a[i * m + k] * b[k];
        }
        b[i] = t / a[i * m + i];
    }
    for i in (0..m).rev() {
        let mut t = b[i];
        for k in i + 1..m {
            t -= a[k * m + i] * b[k];
        }
        b[i] = t / a[i * m + i];
    }
    Ok(())
}

/// Lawson–Hanson-type primal active set method for `min 1/2 l^T D l + q^T l, l >= 0`, started
/// from `l = 0` (always feasible). Returns the dense solves used.
fn primal_active_set(
    lcp: &Lcp<'_>,
    set: &mut [bool],
    lambda: &mut [f64],
    g: &mut [f64],
    ws: &mut LcpWork,
    budget: usize,
) -> Result<usize, LcpError> {
    let n = lcp.n();
    set.fill(false);
    lambda.fill(0.0);
    let mut it = 0;
    loop {
        gaps(lcp, lambda, g);
        // most violated inactive constraint (largest negative gradient = most negative gap)
        let mut best = None;
        let mut best_v = -lcp.eps;
        for i in 0..n {
            if !set[i] && lcp.c * g[i] < best_v {
                best_v = lcp.c * g[i];
                best = Some(i);
            }
        }
        let Some(j) = best else {
            return Ok(it);
        };
        set[j] = true;
        loop {
            if it >= budget {
                return Err(LcpError::Budget);
            }
            // trial point z_P = -D_PP^{-1} q_P on the current passive set (in ws.z)
            solve_on_set_into_z(lcp, set, ws)?;
            it += 1;
            // all positive: accept
            let mut alpha = 1.0f64;
            let mut blocking = false;
            for (r, &i) in ws.idx.iter().enumerate() {
                let zi = ws.z[r];
                if zi <= 0.0 {
                    blocking = true;
                    let li = lambda[i];
                    let a = if li - zi > 0.0 { li / (li - zi) } else { 0.0 };
                    alpha = alpha.min(a);
                }
            }
            if !blocking {
                for (r, &i) in ws.idx.iter().enumerate() {
                    lambda[i] = ws.z[r];
                }
                break;
            }
            for (r, &i) in ws.idx.iter().enumerate() {
                lambda[i] += alpha * (ws.z[r] - lambda[i]);
                if lambda[i] <= 0.0 {
                    lambda[i] = 0.0;
                    set[i] = false;
                }
            }
            // guarantee progress: the blocking index (alpha attained) leaves the set
            for (r, &i) in ws.idx.iter().enumerate() {
                let li = lambda[i];
                if ws.z[r] <= 0.0 && li <= f64::EPSILON * (1.0 + li.abs()) {
                    lambda[i] = 0.0;
                    set[i] = false;
                }
            }
        }
    }
}

/// Like [`solve_on_set`] but leaves the solution in `ws.z` (order `ws.idx`).
fn solve_on_set_into_z(lcp: &Lcp<'_>, set: &[bool], ws: &mut LcpWork) -> Result<(), LcpError> {
    let n = lcp.n();
    ws.idx.clear();
    ws.idx.extend((0..n).filter(|&i| set[i]));
    let m = ws.idx.len();
    for (r, &i) in ws.idx.iter().enumerate() {
        for (c, &j) in ws.idx.iter().enumerate().take(r + 1) {
            ws.chol[r * m + c] = lcp.d[i * n + j];
        }
        ws.z[r] = -lcp.q[i];
    }
    cholesky_solve_in_place(&mut ws.chol[..m * m], m, &mut ws.z[..m])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Random SPD `D = M M^T + 0.1 I` and random `q`: both PDAS and the forced fallback reach a
    /// KKT point (`lambda >= 0`, `g >= -tol`, `lambda_i g_i ~ 0`), and the two agree.
    #[test]
    fn lcp_kkt_on_random_spd_problems() {
        let mut rng = Rng::new(42);
        for trial in 0..50 {
            let n = 2 + trial % 17;
            let mut mm = vec![0.0; n * n];
            for v in mm.iter_mut() {
                *v = rng.uniform_in(-1.0, 1.0);
            }
            let mut d = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    d[i * n + j] =
                        (0..n).map(|k| mm[i * n + k] * mm[j * n + k]).sum::<f64>() + if i == j { 0.1 } else { 0.0 };
                }
            }
            let q: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let lcp = Lcp { d: &d, q: &q, c: 1.0, eps: 1e-14 };
            let mut ws = LcpWork::new(n);
            let (mut act, mut lam, mut g) = (vec![false; n], vec![0.0; n], vec![0.0; n]);
            solve_lcp(&lcp, &mut act, &mut lam, &mut g, &mut ws, 500).expect("solvable");
            let (mut act2, mut lam2, mut g2) = (vec![false; n], vec![0.0; n], vec![0.0; n]);
            primal_active_set(&lcp, &mut act2, &mut lam2, &mut g2, &mut ws, 500).expect("solvable");
            for i in 0..n {
                // D has entries O(n) and condition number up to ~1e3 here: KKT within 1e-10.
                assert!(lam[i] >= 0.0 && g[i] >= -1e-10, "trial {trial}: {lam:?} {g:?}");
                assert!((lam[i] * g[i]).abs() <= 1e-10);
                assert!((lam[i] - lam2[i]).abs() <= 1e-8, "PDAS vs fallback differ");
            }
        }
    }
}
