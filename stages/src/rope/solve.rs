//! Primal-dual active set solve of the discrete rope obstacle problem (see the module doc).

use super::Rope;
use crate::snapshot::{Snapshot, SolveStats};

/// Settings of the active-set loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RopeSolveParams {
    /// Relative complementarity residual to reach (default 1e-10).
    pub rel_tol: f64,
    /// Cap on active-set iterations (default 100; PDAS needs a handful).
    pub max_iter: usize,
}

impl Default for RopeSolveParams {
    fn default() -> Self {
        Self { rel_tol: 1e-10, max_iter: 100 }
    }
}

/// Numerical failure of the rope solve.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RopeError {
    /// The obstacle lies above a Dirichlet end (`g > 0` there): no admissible `u` exists.
    #[error("infeasible: the obstacle is above the fixed end x = {x} (g = {g}) at parameter {gamma}")]
    Infeasible {
        /// Node position.
        x: f64,
        /// Obstacle value there.
        g: f64,
        /// Parameter value.
        gamma: f64,
    },
    /// The active set did not settle within `max_iter` iterations.
    #[error("no convergence after {iterations} active-set iterations (complementarity residual {residual:e})")]
    NoConvergence {
        /// Iterations done.
        iterations: usize,
        /// Last relative complementarity residual.
        residual: f64,
    },
}

/// Solve the rope at parameter `gamma`: the snapshot `(u, λ)` and its convergence evidence.
pub fn solve(rope: &Rope, gamma: f64, params: &RopeSolveParams) -> Result<Snapshot, RopeError> {
    let n = rope.n_nodes();
    let (h, nu, f) = (rope.h, rope.params.nu, rope.params.f);
    let g: Vec<f64> = rope.x.iter().map(|&x| rope.obstacle(x, gamma)).collect();
    // An end may touch the obstacle (g = 0 up to rounding, e.g. gamma = 0.5 at x = 1): allow the
    // rounding of the obstacle's terms, 1e-12 relative to their magnitude.
    let g_scale = 1.0
        + rope.params.amplitudes.iter().map(|a| a.abs()).sum::<f64>()
        + rope.params.offset.abs()
        + (gamma * rope.params.length).abs();
    for &i in &[0, n - 1] {
        if g[i] > 1e-12 * g_scale {
            return Err(RopeError::Infeasible { x: rope.x[i], g: g[i], gamma });
        }
    }
    let k_diag = 2.0 * nu / h;
    let k_off = -nu / h;
    let load = f * h; // F_i: nodal load of the distributed f
    let c = k_diag; // complementarity scaling: force per unit length of gap
                    // Workspaces, allocated once per solve.
    let mut u = vec![0.0; n];
    let mut force = vec![0.0; n]; // Λ, nodal contact force
    let mut active = vec![false; n];
    let mut sub = vec![0.0; n];
    let mut diag = vec![0.0; n];
    let mut sup = vec![0.0; n];
    let mut rhs = vec![0.0; n];
    let mut iterations = 0;
    let scale = (load * load * (n - 2) as f64).sqrt().max(f64::MIN_POSITIVE);
    loop {
        iterations += 1;
        // Newton step: u_i = g_i on the active set, equilibrium (K u + F)_i = 0 elsewhere.
        for i in 0..n {
            let interior = i > 0 && i < n - 1;
            if !interior || active[i] {
                (sub[i], diag[i], sup[i]) = (0.0, 1.0, 0.0);
                rhs[i] = if interior { g[i] } else { 0.0 };
            } else {
                (sub[i], diag[i], sup[i]) = (k_off, k_diag, k_off);
                rhs[i] = -load;
            }
        }
        thomas(&sub, &mut diag, &sup, &mut rhs, &mut u);
        // Multipliers: Λ = K u + F on the active set, 0 elsewhere.
        let mut changed = false;
        for i in 1..n - 1 {
            let ku = k_off * u[i - 1] + k_diag * u[i] + k_off * u[i + 1];
            force[i] = if active[i] { ku + load } else { 0.0 };
            let now = force[i] + c * (g[i] - u[i]) > 0.0;
            changed |= now != active[i];
            active[i] = now;
        }
        let residual = complementarity(&force, &u, &g, c) / scale;
        if !changed && residual <= params.rel_tol {
            return Ok(finish(rope, u, &force, &g, &active, iterations, residual, scale, k_diag, k_off, load));
        }
        if iterations >= params.max_iter {
            return Err(RopeError::NoConvergence { iterations, residual });
        }
    }
}

/// The contact-free solution `K u + F = 0`, `u(0) = u(L) = 0` (the lift of the online solve).
pub fn unconstrained(rope: &Rope) -> Vec<f64> {
    let n = rope.n_nodes();
    let (h, nu, f) = (rope.h, rope.params.nu, rope.params.f);
    let (k_diag, k_off) = (2.0 * nu / h, -nu / h);
    let mut sub = vec![k_off; n];
    let mut diag = vec![k_diag; n];
    let mut sup = vec![k_off; n];
    let mut rhs = vec![-f * h; n];
    for i in [0, n - 1] {
        (sub[i], diag[i], sup[i], rhs[i]) = (0.0, 1.0, 0.0, 0.0);
    }
    let mut u = vec![0.0; n];
    thomas(&sub, &mut diag, &sup, &mut rhs, &mut u);
    u
}

/// `|| min(Λ, c (u - g)) ||_2` over interior nodes (zero exactly at a KKT point).
fn complementarity(force: &[f64], u: &[f64], g: &[f64], c: f64) -> f64 {
    let n = u.len();
    (1..n - 1).map(|i| force[i].min(c * (u[i] - g[i])).powi(2)).sum::<f64>().sqrt()
}

#[allow(clippy::too_many_arguments)]
fn finish(
    rope: &Rope,
    u: Vec<f64>,
    force: &[f64],
    g: &[f64],
    active: &[bool],
    iterations: usize,
    complementarity: f64,
    scale: f64,
    k_diag: f64,
    k_off: f64,
    load: f64,
) -> Snapshot {
    let n = u.len();
    let pressure: Vec<f64> = force.iter().map(|l| l / rope.h).collect();
    let kkt = (1..n - 1)
        .map(|i| (k_off * u[i - 1] + k_diag * u[i] + k_off * u[i + 1] + load - force[i]).powi(2))
        .sum::<f64>()
        .sqrt()
        / scale;
    let max_penetration = (0..n).map(|i| (g[i] - u[i]).max(0.0)).fold(0.0, f64::max);
    let min_lambda = pressure.iter().copied().fold(f64::INFINITY, f64::min);
    let stats = SolveStats {
        iterations,
        active: active.iter().filter(|a| **a).count(),
        max_penetration,
        min_lambda,
        complementarity,
        kkt_residual: kkt,
        vertex_ties: 0,
        vertex_nodes: String::new(),
        vertex_rounds: 0,
        min_gap: (0..n).map(|i| u[i] - g[i]).fold(f64::INFINITY, f64::min),
        active_gap: (0..n).filter(|&i| force[i] > 0.0).map(|i| (u[i] - g[i]).abs()).fold(0.0, f64::max),
        cone_angle: 0.0,
    };
    Snapshot { u, pressure, stats }
}

/// Thomas algorithm for a tridiagonal system; overwrites `diag` and `rhs`, writes `x`.
/// Stable here: every row is diagonally dominant (identity rows or `2ν/h` against `ν/h`).
pub(super) fn thomas(sub: &[f64], diag: &mut [f64], sup: &[f64], rhs: &mut [f64], x: &mut [f64]) {
    let n = diag.len();
    for i in 1..n {
        let w = sub[i] / diag[i - 1];
        diag[i] -= w * sup[i - 1];
        rhs[i] -= w * rhs[i - 1];
    }
    x[n - 1] = rhs[n - 1] / diag[n - 1];
    for i in (0..n - 1).rev() {
        x[i] = (rhs[i] - sup[i] * x[i + 1]) / diag[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::rope::RopeParams;

    fn rope(offset: f64, n_elements: usize) -> Rope {
        Rope::new(RopeParams {
            length: 1.0,
            n_elements,
            nu: 30.0,
            f: 250.0,
            modes: vec![1.0, 3.0],
            amplitudes: vec![-0.2, 0.2],
            offset,
        })
    }

    /// Complementarity at every node of every training point of the paper's sweep.
    #[test]
    fn kkt_conditions_hold_across_the_sweep() {
        let r = rope(-0.5, 200);
        let p = RopeSolveParams::default();
        for k in 0..10 {
            let gamma = -0.5 + k as f64 / 9.0;
            let s = solve(&r, gamma, &p).expect("converges");
            assert!(s.stats.active > 0, "the paper's rope touches the obstacle at gamma {gamma}");
            for (i, &x) in r.x.iter().enumerate() {
                let gap = s.u[i] - r.obstacle(x, gamma);
                // Feasibility to rounding of the O(1) solution values (1e-12).
                assert!(gap >= -1e-12, "penetration {gap} at node {i}");
                assert!(s.pressure[i] >= 0.0, "negative pressure at node {i}");
                // λ (u - g) = 0 up to rounding: pressure O(1e3) times gap rounding O(1e-15).
                assert!((s.pressure[i] * gap).abs() <= 1e-9, "complementarity at node {i}");
            }
            assert!(s.stats.complementarity <= p.rel_tol);
            assert!(s.stats.kkt_residual <= 1e-12, "kkt {}", s.stats.kkt_residual);
        }
    }

    /// Obstacle far below: the solution is the unconstrained closed form
    /// `u = f/(2ν) x (x - 1)`, which P1 reproduces exactly at the nodes (1-D Poisson with
    /// constant load is nodally exact). Tolerance: rounding of a 200-row Thomas solve, 1e-12.
    ///
    /// ```text
    ///  0 ___________________________ 1
    ///     \_____ u = f/2ν x(x-1) __/     (min -f/8ν ≈ -1.04)
    ///
    ///  ------- obstacle at -10 -------
    /// ```
    #[test]
    fn far_obstacle_gives_unconstrained_closed_form() {
        let r = rope(-10.0, 200);
        let s = solve(&r, 0.0, &RopeSolveParams::default()).expect("converges");
        assert_eq!(s.stats.active, 0);
        assert_eq!(s.stats.iterations, 1);
        for (i, &x) in r.x.iter().enumerate() {
            assert_close!(s.u[i], 250.0 / 60.0 * x * (x - 1.0), Tol::abs(1e-12));
            assert_close!(s.pressure[i], 0.0, Tol::abs(0.0));
        }
    }

    /// Total contact force balances the total load minus the end reactions:
    /// Σ Λ_i = f L - (R_0 + R_L), with the reactions from the first and last element.
    #[test]
    fn global_equilibrium() {
        let r = rope(-0.5, 200);
        let s = solve(&r, 0.1, &RopeSolveParams::default()).expect("converges");
        let (h, nu, f) = (r.h, 30.0, 250.0);
        let n = r.n_nodes();
        let contact: f64 = s.pressure.iter().map(|p| p * h).sum();
        // Reactions at the fixed ends: half-element load plus the element's spring force.
        let r0 = nu / h * (s.u[1] - s.u[0]) - f * h / 2.0;
        let rl = nu / h * (s.u[n - 2] - s.u[n - 1]) - f * h / 2.0;
        // Load f·L is ~250: rounding of a few hundred terms, 1e-10 relative.
        assert_close!(contact - r0 - rl, f * 1.0, Tol::rel(1e-10));
    }

    #[test]
    fn obstacle_above_an_end_is_infeasible() {
        let r = rope(0.1, 20);
        assert!(matches!(solve(&r, 0.0, &RopeSolveParams::default()), Err(RopeError::Infeasible { .. })));
    }

    #[test]
    fn iteration_cap_is_a_typed_error() {
        let r = rope(-0.5, 200);
        let p = RopeSolveParams { rel_tol: 1e-10, max_iter: 1 };
        assert!(matches!(solve(&r, 0.0, &p), Err(RopeError::NoConvergence { iterations: 1, .. })));
    }
}
