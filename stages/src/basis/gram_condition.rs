//! Conditioning of a greedy cone basis as it grows: at each step t, an estimate of
//! the 1-norm condition number of the Gram matrix `G_t = B_tᵀ B_t` of the first t generators.
//! Every NNLS of a CPG step factors the Gram of a subset of these generators (its passive set),
//! a principal submatrix of `G_t`, whose 2-norm condition is at most `kappa_2(G_t)` (Cauchy
//! interlacing), so this one number per step bounds the conditioning every cone projection of
//! that step saw (up to the factor `t` between the 1- and 2-norm condition numbers).
//!
//! ```text
//! B_t = Q_t R_t  (modified Gram-Schmidt, twice: one column per step, O(n t)),  G_t = R_tᵀ R_t
//! kappa_1(G_t) ~ ||G_t||_1 est(||G_t^{-1}||_1)   (||G_t||_1 from column sums grown by one
//!                                                  Gram column per step, O(n t))
//! ```
//!
//! `est` is Hager's estimator (Higham 1988, LAPACK `xLACON`): at most five pairs of solves with
//! `R_tᵀ R_t` (`O(t^2)` each), a lower bound on `||G_t^{-1}||_1` that is rarely below a third
//! of it. Total cost `O(n N^2 + N^3)` for N generators, so the 1 025-generator stress case
//! stays cheap. A generator in the span of the earlier ones (`R_tt = 0`), or an estimate above
//! `1 / eps` (the Gram singular to working precision: the solves with `R` then return
//! round-off, and once `R_tt` is subnormal, overflow and NaN), gives `f64::INFINITY` from that
//! step on — the condition of `G_t` never decreases with t (`G_t` is a principal submatrix of
//! `G_{t+1}`: by interlacing its extreme eigenvalues are inside those of `G_{t+1}`). The
//! caller stores `1 / kappa`, 0 for those steps. Found by the stress matrix's near-duplicate
//! case, which stored NaN after 19 generators.

use faer::MatRef;

/// The estimate of `kappa_1(G_t)` for t = 1..=k, k = `b.ncols()`.
pub fn gram_condition_path(b: MatRef<'_, f64>) -> Vec<f64> {
    let (n, k) = (b.nrows(), b.ncols());
    // At most n generators in R^n are independent: the Gram of n + 1 of them is singular, so
    // R never needs more than n + 1 columns (a 16 385-generator path would otherwise
    // allocate 2 GB for it).
    let ld = k.min(n + 1);
    let mut q: Vec<f64> = Vec::with_capacity(n * ld);
    // R column-major, ld x ld upper triangular.
    let mut r = vec![0.0; ld * ld];
    let mut out = Vec::with_capacity(k);
    // Column sums of |G_t|, grown by one Gram column per step: ||G_t||_1 in O(n t).
    let mut col_sums: Vec<f64> = Vec::with_capacity(k);
    for t in 0..k {
        if t == ld {
            // t = n + 1 generators in R^n: singular (see `ld`).
            out.resize(k, f64::INFINITY);
            break;
        }
        let bt = b.col(t);
        let mut own = 0.0;
        for (i, sum) in col_sums.iter_mut().enumerate() {
            let g = b.col(i).iter().zip(bt.iter()).map(|(x, y)| x * y).sum::<f64>().abs();
            *sum += g;
            own += g;
        }
        col_sums.push(own + bt.iter().map(|x| x * x).sum::<f64>());
        let mut v: Vec<f64> = b.col(t).iter().copied().collect();
        for _ in 0..2 {
            for i in 0..t {
                let qi = &q[i * n..(i + 1) * n];
                let c: f64 = qi.iter().zip(&v).map(|(a, b)| a * b).sum();
                r[i + t * ld] += c;
                v.iter_mut().zip(qi).for_each(|(x, a)| *x -= c * a);
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        r[t + t * ld] = norm;
        let kappa = if norm > 0.0 {
            q.extend(v.iter().map(|x| x / norm));
            let m = t + 1;
            let g_norm = col_sums.iter().copied().fold(0.0, f64::max);
            g_norm * hager(m, &|x: &mut [f64]| solve_gram(&r, ld, m, x))
        } else {
            f64::INFINITY
        };
        if !(kappa.is_finite() && kappa <= 1.0 / f64::EPSILON) {
            // singular to working precision, and so is every longer prefix (module docs)
            out.resize(k, f64::INFINITY);
            break;
        }
        out.push(kappa);
    }
    out
}

/// `x <- (Rᵀ R)^{-1} x` on the leading `m x m` block of `r` (column-major, leading dimension `k`).
fn solve_gram(r: &[f64], k: usize, m: usize, x: &mut [f64]) {
    // Rᵀ y = x (forward), then R z = y (backward).
    for i in 0..m {
        let s: f64 = (0..i).map(|l| r[l + i * k] * x[l]).sum();
        x[i] = (x[i] - s) / r[i + i * k];
    }
    for i in (0..m).rev() {
        let s: f64 = (i + 1..m).map(|l| r[i + l * k] * x[l]).sum();
        x[i] = (x[i] - s) / r[i + i * k];
    }
}

/// Hager's lower estimate of `||A^{-1}||_1` for a symmetric A given by its solve.
fn hager(m: usize, solve: &dyn Fn(&mut [f64])) -> f64 {
    let mut x = vec![1.0 / m as f64; m];
    let mut est = 0.0;
    for _ in 0..5 {
        let mut y = x.clone();
        solve(&mut y);
        est = y.iter().map(|v| v.abs()).sum::<f64>();
        let mut z: Vec<f64> = y.iter().map(|v| if *v >= 0.0 { 1.0 } else { -1.0 }).collect();
        solve(&mut z);
        let (j, zmax) = z
            .iter()
            .enumerate()
            .fold((0, 0.0f64), |(bj, bv), (j, v)| if v.abs() > bv { (j, v.abs()) } else { (bj, bv) });
        let ztx: f64 = z.iter().zip(&x).map(|(a, b)| a * b).sum();
        if zmax <= ztx {
            break;
        }
        x.iter_mut().for_each(|v| *v = 0.0);
        x[j] = 1.0;
    }
    est
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use faer::Mat;

    /// Against the exact `kappa_1(G_t)` of every prefix (G and its inverse formed densely with
    /// faer's LU): never above it (a lower bound, to round-off 1e-8 relative on inverses of
    /// condition up to ~1e8), never below a third of it (Higham's observed bound; the test
    /// family, unit bumps drifting apart, is the CPG's own kind of basis), and infinite once a
    /// generator repeats.
    #[test]
    fn estimate_brackets_the_exact_condition_of_every_prefix() {
        let mut rng = Rng::new(16);
        let (n, k) = (60, 14);
        let mut b = Mat::from_fn(n, k, |i, j| {
            let c = 10.0 + 2.5 * j as f64 + rng.uniform();
            (-((i as f64 - c) / 4.0).powi(2)).exp()
        });
        for j in 0..k {
            let norm = b.col(j).norm_l2();
            for i in 0..n {
                b[(i, j)] /= norm;
            }
        }
        let est = gram_condition_path(b.as_ref());
        assert_eq!(est.len(), k);
        for t in 1..=k {
            let bt = b.subcols(0, t);
            let g = bt.transpose() * bt;
            let inv = faer::linalg::solvers::Solve::solve(&g.as_ref().partial_piv_lu(), Mat::<f64>::identity(t, t));
            let one = |a: &Mat<f64>| (0..t).map(|j| (0..t).map(|i| a[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max);
            let exact = one(&g) * one(&inv);
            let e = est[t - 1];
            assert!(e <= exact * (1.0 + 1e-8), "t {t}: estimate {e} above {exact}");
            assert!(e >= exact / 3.0, "t {t}: estimate {e} below a third of {exact}");
        }
        let mut dup = b.clone();
        for i in 0..n {
            dup[(i, 3)] = b[(i, 2)];
        }
        let d = gram_condition_path(dup.as_ref());
        // Nearly parallel generators (each a 1e-6-relative perturbation of the first, the
        // near-duplicate snapshots' kind): the Gram is singular to working precision after a
        // few steps; every later step is infinite, none NaN.
        let first: Vec<f64> = b.col(0).iter().copied().collect();
        let near = Mat::from_fn(n, 30, |i, j| first[i] * (1.0 + 1e-6 * ((i * (j + 1)) % 7) as f64 / 7.0));
        let e = gram_condition_path(near.as_ref());
        let at = e.iter().position(|v| v.is_infinite()).expect("singular to working precision");
        assert!(at >= 1 && e[..at].iter().all(|v| v.is_finite() && *v <= 1.0 / f64::EPSILON), "{e:?}");
        assert!(e[at..].iter().all(|v| v.is_infinite()), "{e:?}");
        assert!(d[2].is_finite() && d[3..].iter().all(|v| v.is_infinite() || *v > 1e12), "{d:?}");
    }
}
