//! The reduced saddle-point system of eq. 13 by its Schur complement.
//!
//! With `K̂ = L L^T` SPD (`r x r`) and the active rows `Ĉ_A` (`a x r`):
//! `û = K̂^{-1} Ĉ_A^T λ̂_A`, `(Ĉ_A K̂^{-1} Ĉ_A^T) λ̂_A = -ĝ0_A`, evaluated in the range space
//! `W = L^{-1} Ĉ_A^T`: Schur matrix `W^T W`, `û = L^{-T} W λ̂_A`. The Schur matrix is only
//! positive semi-definite when active constraints are dependent (several dual generators can be
//! nearly parallel); a pivoted Cholesky that drops pivots below `1e-12` of the largest diagonal
//! gives a solution with the dependent multipliers set to zero (pivots below
//! [`SCHUR_PIVOT_TOL`] of the largest diagonal).

use super::la::Factor;

/// Relative pivot below which an active row of the Schur complement counts as dependent. The
/// Schur matrix squares the conditioning of `Ĉ_A`: a pivot `1e-10` of the largest means rows
/// dependent to ~1e-5, whose multipliers would otherwise be amplified ~1e10 (seen when the dual
/// basis is richer than the primal one).
pub const SCHUR_PIVOT_TOL: f64 = 1e-10;

/// Dense column-major Cholesky `a = L L^T` in place (lower triangle); `false` if not SPD.
pub fn cholesky(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j + j * n];
        for k in 0..j {
            d -= a[j + k * n] * a[j + k * n];
        }
        if d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j + j * n] = d;
        for i in j + 1..n {
            let mut s = a[i + j * n];
            for k in 0..j {
                s -= a[i + k * n] * a[j + k * n];
            }
            a[i + j * n] = s / d;
        }
    }
    true
}

/// Solve eq. 13 on the active rows. `khat_l`: Cholesky factor of `K̂` (`r x r`, or the
/// identity in coordinates where `K̂ = I`); `c_a`: active
/// rows of `Ĉ`, row-major `a x r`; `g_a`: `ĝ0_A`. Writes `û` (length r) and `λ̂_A` (length a).
/// `work` must hold at least `a * r + a * a` values.
pub fn solve_saddle(
    khat_l: Factor<'_>,
    r: usize,
    c_a: &[f64],
    g_a: &[f64],
    u: &mut [f64],
    lam: &mut [f64],
    work: &mut Vec<f64>,
) {
    let a = g_a.len();
    work.clear();
    work.resize(a * r + a * a, 0.0);
    let (y, s) = work.split_at_mut(a * r);
    // Range space of K̂ = L L^T: W = L^{-1} Ĉ_A^T (column i of W, length r, contiguous), so that
    // the Schur matrix is S = Ĉ_A K̂^{-1} Ĉ_A^T = W^T W and û = L^{-T} W λ (one triangular solve
    // per active row instead of two).
    for i in 0..a {
        let col = &mut y[i * r..(i + 1) * r];
        col.copy_from_slice(&c_a[i * r..(i + 1) * r]);
        khat_l.forward(r, col);
    }
    // S = W^T W is symmetric: the factorisation below reads its lower triangle only
    for j in 0..a {
        for i in j..a {
            s[i + j * a] = super::la::dot(&y[i * r..(i + 1) * r], &y[j * r..(j + 1) * r]);
        }
    }
    // Pivoted Cholesky with dropping of dependent rows.
    let max_diag = (0..a).map(|i| s[i + i * a]).fold(0.0f64, f64::max);
    let tol = SCHUR_PIVOT_TOL * max_diag.max(f64::MIN_POSITIVE);
    let mut keep = vec![true; a];
    for j in 0..a {
        let mut d = s[j + j * a];
        for k in 0..j {
            if keep[k] {
                d -= s[j + k * a] * s[j + k * a];
            }
        }
        if d <= tol {
            keep[j] = false;
            continue;
        }
        let d = d.sqrt();
        s[j + j * a] = d;
        for i in j + 1..a {
            let mut v = s[i + j * a];
            for k in 0..j {
                if keep[k] {
                    v -= s[i + k * a] * s[j + k * a];
                }
            }
            s[i + j * a] = v / d;
        }
    }
    // Solve S λ = -g on the kept rows (forward, then backward substitution).
    for i in 0..a {
        lam[i] = -g_a[i];
    }
    for i in 0..a {
        if !keep[i] {
            lam[i] = 0.0;
            continue;
        }
        let mut v = lam[i];
        for k in 0..i {
            if keep[k] {
                v -= s[i + k * a] * lam[k];
            }
        }
        lam[i] = v / s[i + i * a];
    }
    for i in (0..a).rev() {
        if !keep[i] {
            continue;
        }
        let mut v = lam[i];
        for k in i + 1..a {
            if keep[k] {
                v -= s[k + i * a] * lam[k];
            }
        }
        lam[i] = v / s[i + i * a];
    }
    u.iter_mut().for_each(|x| *x = 0.0);
    for i in 0..a {
        super::la::axpy(lam[i], &y[i * r..(i + 1) * r], u);
    }
    khat_l.backward_t(r, u);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::rom::la::Factor;
    use crate::testing::spd;
    use crate::{assert_all_close, assert_close};

    /// The solution satisfies both block rows of eq. 13 (residuals at rounding, 1e-10 relative
    /// to O(1) data), including with a duplicated (dependent) active row.
    #[test]
    fn saddle_solution_satisfies_both_block_rows() {
        let mut rng = Rng::new(3);
        let r = 6;
        let k = spd(r, r as f64, &mut rng);
        let mut l = k.clone();
        assert!(cholesky(&mut l, r));
        for dup in [false, true] {
            let a = 3;
            let mut c: Vec<f64> = (0..a * r).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let mut g: Vec<f64> = (0..a).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            if dup {
                let row0: Vec<f64> = c[..r].to_vec();
                c.extend_from_slice(&row0);
                g.push(g[0]);
            }
            let a = g.len();
            let (mut u, mut lam, mut w) = (vec![0.0; r], vec![0.0; a], Vec::new());
            solve_saddle(Factor::Lower(&l), r, &c, &g, &mut u, &mut lam, &mut w);
            for i in 0..a {
                let cu: f64 = (0..r).map(|k2| c[i * r + k2] * u[k2]).sum();
                assert_close!(cu, -g[i], Tol { abs: 1e-10, rel: 1e-10 });
            }
            let ku: Vec<f64> = (0..r).map(|i| (0..r).map(|j| k[i + j * r] * u[j]).sum()).collect();
            let ctl: Vec<f64> = (0..r).map(|k2| (0..a).map(|i| c[i * r + k2] * lam[i]).sum()).collect();
            assert_all_close!(ku, ctl, Tol { abs: 1e-10, rel: 1e-10 });
        }
    }
}
