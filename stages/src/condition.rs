//! Condition estimates of symmetric positive definite operators (conditioning in the
//! artifacts). For the stiffness `K` (free dofs) of a scene:
//!
//! ```text
//! lambda_max ~ x_kᵀ K x_k,           x_{k+1} = K x_k / |K x_k|        (power iteration)
//! lambda_min ~ 1 / (z_kᵀ K^{-1} z_k), z_{k+1} = K^{-1} z_k / |K^{-1} z_k| (inverse iteration,
//!                                                                     with the existing factor)
//! kappa_2(K) ~ lambda_max / lambda_min
//! ```
//!
//! Both Rayleigh quotients lie inside the spectrum, so the estimate is a lower bound on
//! `kappa_2(K)`: `lambda_max` from below, `lambda_min` from above. Inverse iteration converges
//! with the ratio `lambda_1 / lambda_2` (well separated at the bottom of an elastic spectrum);
//! power iteration converges slowly when the top of the spectrum is clustered, but then every
//! eigenvalue of the cluster is close to `lambda_max`, so the Rayleigh quotient is too (the
//! tests bound both against exact spectra). Cost: `iterations` products and solves, `O(nnz(L))`
//! each; no factorisation beyond the one the solver already has. A pivot ratio of the Cholesky
//! factor was the obvious alternative; faer's sparse factor does not expose its pivots, and the
//! two-sided Rayleigh estimate is closer to `kappa_2` than a pivot ratio, which can be off by
//! orders of magnitude in either direction.

/// Extreme eigenvalue estimates of an SPD operator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Condition {
    /// Estimate of the largest eigenvalue (from below).
    pub lambda_max: f64,
    /// Estimate of the smallest eigenvalue (from above).
    pub lambda_min: f64,
}

impl Condition {
    /// `lambda_max / lambda_min`: a lower bound on the 2-norm condition number.
    pub fn ratio(&self) -> f64 {
        self.lambda_max / self.lambda_min
    }
}

/// Iterations of [`estimate`] used by the operators.
pub const ITERATIONS: usize = 60;

/// Power and inverse iteration on an SPD operator of size `n` given by its product `mul(x, y)`
/// (`y = A x`) and its solve `solve(x)` (`x <- A^{-1} x`), from a fixed, non-symmetric start (so
/// the estimate is deterministic and has a component along every eigenvector of a generic
/// operator). The two iterations are independent and run side by side (`rayon::join`); each is
/// sequential, so the estimate is the same whatever the thread count. `None` for `n == 0` or a
/// non-positive or non-finite quotient (not SPD).
pub fn estimate(
    n: usize,
    iterations: usize,
    mul: &(dyn Fn(&[f64], &mut [f64]) + Sync),
    solve: &(dyn Fn(&mut [f64]) + Sync),
) -> Option<Condition> {
    if n == 0 {
        return None;
    }
    let steps = iterations.max(1);
    let (lambda_max, inv) = rayon::join(
        || rayleigh(n, steps, mul),
        || {
            rayleigh(n, steps, |x, y| {
                y.copy_from_slice(x);
                solve(y);
            })
        },
    );
    let c = Condition { lambda_max: lambda_max?, lambda_min: 1.0 / inv? };
    (c.lambda_max > 0.0 && c.lambda_min > 0.0 && c.ratio().is_finite()).then_some(c)
}

/// `steps` normalised applications of `apply(x, y)` (`y = B x`) from the fixed start; the last
/// Rayleigh quotient `xᵀ B x`, or `None` once `|B x|` is zero or not finite.
fn rayleigh(n: usize, steps: usize, apply: impl Fn(&[f64], &mut [f64])) -> Option<f64> {
    let x: Vec<f64> = (0..n).map(|i| 1.0 + ((i * 7919) % 101) as f64 / 101.0).collect();
    let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    let (mut x, mut y): (Vec<f64>, _) = (x.into_iter().map(|v| v / norm).collect(), vec![0.0; n]);
    let mut quotient = 0.0;
    for _ in 0..steps {
        apply(&x, &mut y);
        quotient = x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>();
        let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            return None;
        }
        x.iter_mut().zip(&y).for_each(|(a, b)| *a = b / norm);
    }
    Some(quotient)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonal operator with a known spectrum: a well separated bottom, a clustered top.
    #[test]
    fn bounds_and_accuracy_on_a_known_spectrum() {
        let n = 200;
        let d: Vec<f64> = (0..n).map(|i| 1.0 + 3.0 * i as f64 + if i == n - 1 { 0.5 } else { 0.0 }).collect();
        let (lo, hi) = (d[0], d[n - 1]);
        let mul = |x: &[f64], y: &mut [f64]| y.iter_mut().zip(x).zip(&d).for_each(|((y, x), d)| *y = d * x);
        let solve = |x: &mut [f64]| x.iter_mut().zip(&d).for_each(|(x, d)| *x /= d);
        let c = estimate(n, ITERATIONS, &mul, &solve).expect("SPD");
        // Inside the spectrum, always.
        assert!(c.lambda_max <= hi * (1.0 + 1e-12) && c.lambda_min >= lo * (1.0 - 1e-12));
        // Bottom ratio 1/4: after 60 steps the quotient is exact to round-off (1e-12).
        assert!((c.lambda_min - lo).abs() <= 1e-12 * lo, "{} vs {lo}", c.lambda_min);
        // Top: the j-th eigenvalue below hi is about 0.5 j % lower and keeps a weight of about
        // (1 - 0.005 j)^120 ~ exp(-0.6 j) after 60 steps, so the quotient sits about 0.6 %
        // below hi: within 1 %.
        assert!(c.lambda_max >= 0.99 * hi, "{} vs {hi}", c.lambda_max);
        assert!(estimate(0, 10, &mul, &solve).is_none());
        let neg = |x: &[f64], y: &mut [f64]| y.iter_mut().zip(x).for_each(|(y, x)| *y = -x);
        assert!(estimate(3, 10, &neg, &|_| {}).is_none());
    }
}
