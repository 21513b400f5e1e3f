//! The exact corrected re-pairing step: GMRES on the SQP step's equation.
//!
//! The first-order corrected step ([`ReducedModel::curvature_step`]) takes `z = P H d` for the
//! solution of
//!
//! ```text
//! (I + P H P) z = P H d,     x <- x - z,
//! ```
//!
//! (`d = x - y_k` the QP's step, `H` the gaps' curvature over the slaves with pressure,
//! [`crate::rom::curvature`], `P = I - P_A` the projector onto the active constraints' null
//! space), which leaves an error of order `|H|²` per linearisation. Where `|H|` is not small —
//! a primal space that holds the slaves' slip along the master, such as training responses
//! with their translates — the re-pairing then needs half as many linearisations again
//! (docs/design-notes.md#an-exact-corrected-step). Here the equation is solved by `k` steps of
//! GMRES from `z = 0` (Arnoldi with modified Gram–Schmidt, the small least-squares problem by
//! Givens rotations). `P H d` lies in the range of `P`, and `I + P H P` maps that range into
//! itself, so every Krylov vector stays in it and `P` is applied once per product. `H` is
//! applied through each term's two rows ([`CurvatureOp`]): formed once per step from four or six
//! rows of `Psi_c` each, then two row products and two row updates per term and product.
//!
//! At a fixed point `d = 0`, so `z = 0`: the answers are the QP's own, as with the first-order
//! step; only the path to them changes.

use super::{ReducedModel, RomWork, SurfaceData};
use crate::rom::curvature::CurvatureOp;
use crate::rom::la::{axpy, dot};

/// The largest number of Krylov iterations (the size of the small least-squares problem).
pub const MAX_EXACT_STEP: usize = 8;

/// Buffers of the exact step.
#[derive(Debug, Clone, Default)]
pub(crate) struct ExactStepWork {
    /// The terms of `H` at the corrected step (filled by [`ReducedModel::curvature_step`]).
    pub(super) op: CurvatureOp,
    /// The Krylov basis, `r_u` per vector.
    basis: Vec<f64>,
    /// The next vector.
    next: Vec<f64>,
}

impl ReducedModel {
    /// The exact corrected step with `k` (1..=[`MAX_EXACT_STEP`]) GMRES iterations, after
    /// [`Self::curvature_step`] has put the QP's step into `w.lin.step` and the terms of `H`
    /// into `w.exact.op`.
    pub(super) fn exact_step(&self, w: &mut RomWork, k: usize) {
        let SurfaceData::Nts { phi_c, .. } = &self.surf else { return };
        let (ru, k) = (self.r_u, k.min(MAX_EXACT_STEP));
        let RomWork { lin: l, qp, x, exact: e, .. } = w;
        if e.op.is_empty() {
            return;
        }
        // b = P H d
        l.hv.clear();
        l.hv.resize(ru, 0.0);
        e.op.apply(phi_c, ru, &l.step, &mut l.hv);
        qp.remove_active_span(ru, &mut l.hv);
        let ExactStepWork { op, basis, next } = e;
        gmres_sub(
            |v, out| {
                op.apply(phi_c, ru, v, out);
                qp.remove_active_span(ru, out);
                axpy(1.0, v, out);
            },
            &l.hv,
            k,
            (basis, next),
            x,
        );
    }
}

/// `x -= z` for the GMRES iterate `z` after `k` (1..=[`MAX_EXACT_STEP`]) iterations on
/// `A z = b` from `z = 0`, with `apply(v, out)` overwriting `out` (zeros on entry) with `A v`.
/// Arnoldi by modified Gram–Schmidt; the small
/// least-squares problem `min |β e_1 - H̄ y|` by Givens rotations. Stops early on an invariant
/// subspace (the solve is then exact in it). `b = 0` leaves `x` as it is.
fn gmres_sub(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    k: usize,
    (basis, next): (&mut Vec<f64>, &mut Vec<f64>),
    x: &mut [f64],
) {
    let (r, k) = (b.len(), k.clamp(1, MAX_EXACT_STEP));
    let beta = dot(b, b).sqrt();
    if beta == 0.0 {
        return;
    }
    basis.clear();
    basis.extend(b.iter().map(|v| v / beta));
    // the Hessenberg matrix, column j in h[..=j + 1][j]
    let mut h = [[0.0f64; MAX_EXACT_STEP]; MAX_EXACT_STEP + 1];
    let mut used = 0;
    for j in 0..k {
        next.clear();
        next.resize(r, 0.0);
        apply(&basis[j * r..(j + 1) * r], next);
        for (i, row) in h.iter_mut().enumerate().take(j + 1) {
            let v = &basis[i * r..(i + 1) * r];
            row[j] = dot(next, v);
            axpy(-row[j], v, next);
        }
        let norm = dot(next, next).sqrt();
        h[j + 1][j] = norm;
        used = j + 1;
        if norm <= 1e-14 * beta || used == k {
            break;
        }
        basis.extend(next.iter().map(|v| v / norm));
    }
    let mut g = [0.0f64; MAX_EXACT_STEP + 1];
    g[0] = beta;
    for j in 0..used {
        let (a, c0) = (h[j][j], h[j + 1][j]);
        let rr = a.hypot(c0);
        if rr == 0.0 {
            return;
        }
        let (c, s) = (a / rr, c0 / rr);
        let (top, bottom) = h.split_at_mut(j + 1);
        for (u, v) in top[j][j..used].iter_mut().zip(&mut bottom[0][j..used]) {
            (*u, *v) = (c * *u + s * *v, -s * *u + c * *v);
        }
        let (u, v) = (g[j], g[j + 1]);
        g[j] = c * u + s * v;
        g[j + 1] = -s * u + c * v;
    }
    let mut y = [0.0f64; MAX_EXACT_STEP];
    for i in (0..used).rev() {
        let mut v = g[i];
        for col in i + 1..used {
            v -= h[i][col] * y[col];
        }
        y[i] = v / h[i][i];
    }
    for (i, &yi) in y.iter().enumerate().take(used) {
        axpy(-yi, &basis[i * r..(i + 1) * r], x);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::pod_full;
    use crate::rom::reduced::test_support::{coarse_mus, coarse_tests, columns};
    use crate::rom::translates::with_translates;
    use crate::rom::{ContactOperator, RomOutcome, RomParams};
    use crate::testing::{ironing_coarse, TOL};
    use faer::MatRef;

    /// Ironing-coarse, 17 training points; the primal space the POD of their responses and
    /// their translates by ±2 slab columns (truncated at 17), the dual basis the first 4
    /// training pressures. At the 48 test points between them the exact step (2 GMRES
    /// iterations) converges at every point and gives the first-order step's answers to 1e-8
    /// relative: each solve stops within `u_tol` = 1e-10 of its fixed point, and the step
    /// vanishes at a fixed point (measured 3.0e-12). The linearisations are the same here
    /// (94): on this mesh `|H|` is small; on ironing-fine, where it is not, the exact step
    /// takes them from 6.5 to 4.3 per query (`cargo run --release -p crom-stages --example
    /// exact_step`, docs/design-notes.md#an-exact-corrected-step); here they may not grow.
    /// With the step's sign flipped the answers still agree but it takes 99 (the test fails).
    #[test]
    fn the_exact_step_changes_the_path_not_the_answer() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let snaps: Vec<_> = mus.iter().map(|&d| fm.solve(&[d], &TOL).expect("solve")).collect();
        let n = fm.n_dof();
        let responses: Vec<f64> = mus
            .iter()
            .zip(&snaps)
            .flat_map(|(&d, s)| s.u.iter().zip(fm.lift(&[d])).map(|(a, b)| a - b).collect::<Vec<_>>())
            .collect();
        let all = with_translates(fm.model().mesh(), fm.model().slave_nodes(), &responses, 2).expect("a grid");
        let pod = pod_full(MatRef::from_column_major_slice(&all, n, 3 * mus.len())).expect("pod");
        let r = mus.len().min(pod.modes.ncols());
        let phi: Vec<f64> = columns(pod.modes.as_ref())[..n * r].to_vec();
        let theta: Vec<f64> = snaps
            .iter()
            .flat_map(|s| {
                let norm = s.pressure.iter().map(|p| p * p).sum::<f64>().sqrt();
                s.pressure.iter().map(move |p| if norm > 0.0 { p / norm } else { 0.0 }).collect::<Vec<_>>()
            })
            .collect();
        let model = ReducedModel::new(fm, &phi, r, &theta, mus.len()).expect("K̂ SPD");
        let model = model.leading(r, 4);
        let first = RomParams::default();
        let exact = RomParams { exact_step: 2, ..RomParams::default() };
        let (mut wa, mut wb) = (RomWork::default(), RomWork::default());
        let (mut worst, mut lin_first, mut lin_exact) = (0.0f64, 0, 0);
        for d in coarse_tests() {
            let a = model.solve(&[d], &first, &mut wa);
            let b = model.solve(&[d], &exact, &mut wb);
            assert!(a.outcome == RomOutcome::Converged && b.outcome == RomOutcome::Converged, "d_x {d}");
            let diff = a.u_hat.iter().zip(&b.u_hat).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
            let norm = a.u_hat.iter().map(|x| x * x).sum::<f64>().sqrt();
            worst = worst.max(diff / norm);
            lin_first += a.linearizations;
            lin_exact += b.linearizations;
        }
        assert!(worst <= 1e-8, "exact vs first-order step: {worst:e}");
        assert!(lin_exact <= lin_first, "linearisations exact {lin_exact} vs first-order {lin_first}");
    }

    /// A dense `A = I + M` (6 x 6, `|M|` about 0.5, not symmetric): GMRES with 6 iterations
    /// solves `A z = b` to rounding (residual <= 1e-12 |b|: six orthogonalisations of
    /// 6-vectors), and with 2 its residual is at most that of the first-order step `z = b`
    /// (GMRES minimises the residual over a space that holds `b`) and below half of it here
    /// (measured 0.080 against 0.27 of |b|).
    #[test]
    fn gmres_minimises_the_residual_and_solves_in_full_dimension() {
        let n = 6;
        let m: Vec<f64> = (0..n * n).map(|k| (((k * 7 + 3) % 11) as f64 - 5.0) / 25.0).collect();
        let a = |v: &[f64], out: &mut [f64]| {
            for i in 0..n {
                out[i] = v[i] + (0..n).map(|j| m[i * n + j] * v[j]).sum::<f64>();
            }
        };
        let b: Vec<f64> = (0..n).map(|i| (i as f64 - 2.5) / 3.0).collect();
        let residual = |z: &[f64]| {
            let mut az = vec![0.0; n];
            a(z, &mut az);
            az.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
        };
        let nb = dot(&b, &b).sqrt();
        let (mut basis, mut next) = (Vec::new(), Vec::new());
        let solve = |k: usize, basis: &mut Vec<f64>, next: &mut Vec<f64>| {
            let mut x = vec![0.0; n];
            gmres_sub(a, &b, k, (basis, next), &mut x);
            x.iter().map(|v| -v).collect::<Vec<_>>()
        };
        let full = solve(n, &mut basis, &mut next);
        assert!(residual(&full) <= 1e-12 * nb, "{}", residual(&full));
        let two = residual(&solve(2, &mut basis, &mut next));
        let first_order = residual(&b);
        assert!(two <= 0.5 * first_order, "{two} vs {first_order}");
        // b = 0: nothing moves
        let mut x = vec![1.0; n];
        gmres_sub(a, &vec![0.0; n], 2, (&mut basis, &mut next), &mut x);
        assert_eq!(x, vec![1.0; n]);
    }
}
