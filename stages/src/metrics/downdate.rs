//! Deleting one column from a matrix whose SVD is known: the singular values of the rest and the
//! squared coefficients of the deleted column on the rest's left singular vectors, in O(p^2)
//! instead of a new O(p^3) SVD. It makes the orthogonal leave-one-out folds of eq. 17 cheap.
//!
//! # The secular equation
//!
//! With `A = U Σ V^T` (p singular values `σ_1 >= ... >= σ_p >= 0`) and `v` the row of V of the
//! deleted column, that column is `a = U z` with `z = Σ v`, and the rest satisfies
//! `A' A'^T = U (Σ^2 - z z^T) U^T`. The squared singular values `ω^2` of `A'` are the
//! eigenvalues of the rank-one downdate `Σ^2 - z z^T`, the roots of
//!
//! ```text
//! f(ω) = 1 - sum_k z_k^2 / ((σ_k - ω)(σ_k + ω)) = 0,
//! ```
//!
//! one in each interval `(σ_{k+1}, σ_k)` and the last in `[0, σ_p)` (interlacing; f decreases
//! from +inf to -inf on each interval, and `f(0) = 1 - ||v||^2 >= 0`). The eigenvector of
//! `ω_l` is `q_l ∝ (Σ^2 - ω_l^2)^-1 z`, so the deleted column's coefficient on it is
//!
//! ```text
//! c_l^2 = (q_l^T z)^2 = 1 / sum_k z_k^2 / (σ_k^2 - ω_l^2)^2       (using f(ω_l) = 0),
//! ```
//!
//! and `sum_l c_l^2 = ||z||^2 = ||a||^2`.
//!
//! # Accuracy
//!
//! An eigen-downdate written on `σ^2` (the Gram) resolves eigenvalues to `eps σ_1^2` only, so it
//! loses every singular value below `sqrt(eps) σ_1`, where the primal curves live
//! (docs/design-notes.md#orthogonal-folds-by-a-column-downdate). Here each root is found relative to its nearer pole `σ_o`: `ω = σ_o + τ`, with
//! `σ_k - ω = (σ_k - σ_o) - τ` and `σ_k + ω = (σ_k + σ_o) + τ` formed separately, so τ is found
//! to relative accuracy and no difference of squares is ever formed (the device of LAPACK's
//! `dlasd4`, which solves the updating case). And f is evaluated relative to its value at 0,
//!
//! ```text
//! f(ω) = f(0) - sum_k z_k^2 ω^2 / (σ_k^2 (σ_k - ω)(σ_k + ω)),
//! ```
//!
//! with `f(0) = 1 - ||v||^2` supplied exactly (`complement`, the squared rest of V's row: 0 for
//! a square V) plus the deflated part of `v`. The textbook `1 - sum` cancels at O(1) and cannot
//! place a root that is small against the poles above it; this form has no such cancellation,
//! so a fold that keeps every direction has its small singular values to `O(eps σ_1)`, and one
//! that loses a direction gets exactly 0.
//!
//! Deflation is exact only: a `z_k` whose square is 0 leaves the eigenpair `(σ_k, 0)`, and equal
//! poles are merged by a rotation in their plane (one eigenpair `σ_k` with weight 0, the kept pole
//! takes the combined weight). Deflating a small but non-zero `z_k`, as the eigenvalue update
//! does, would be a perturbation of `|z_k| ||z||` of the Gram — of `sqrt(|z_k| ||z||)` of a
//! singular value near 0, a spurious direction; the iteration below instead resolves a root
//! within round-off of its pole. So the singular values are those of the fold to `O(eps σ_1)`
//! absolute, like a direct SVD of `A'`.
//!
//! # Root finding
//!
//! The two-pole fixed-weight model (Li; LAPACK's `dlaed4`): at the current τ the terms of the
//! poles above the root are modelled as `a + b / (Δ_l - τ)` and those below as
//! `c + d / (Δ_{l+1} - τ)` (`Δ_k = σ_k - σ_o`), value and slope matched; the model's root in the
//! bracket is the next iterate, and a bisection replaces any step that leaves the bracket, so
//! the iteration always terminates. It stops when `|f|` is at the round-off of its own
//! evaluation, `8 eps (f(0) + sum_k |term_k|)`, or the bracket is at round-off.

/// Reusable buffers of [`ColumnDowndate::solve`]: no allocation after the first call of a size.
#[derive(Debug, Default, Clone)]
pub struct ColumnDowndate {
    /// The poles kept after deflation (descending) and their weights `z_k^2`.
    s: Vec<f64>,
    w: Vec<f64>,
    /// `σ_k - σ_o` and `σ_k + σ_o` for the root being solved.
    delta: Vec<f64>,
    plus: Vec<f64>,
    /// `(ω, c^2)` of every eigenpair, sorted by ω descending.
    pairs: Vec<(f64, f64)>,
}

/// One evaluation of the secular function at τ: `f`, the sums of the terms above and below the
/// root and their slopes, and `sum |term|` (for the round-off test).
#[derive(Debug, Clone, Copy)]
struct Eval {
    f: f64,
    psi: f64,
    dpsi: f64,
    phi: f64,
    dphi: f64,
    abs: f64,
}

impl ColumnDowndate {
    pub fn new() -> Self {
        Self::default()
    }

    /// The eigenpairs of `Σ^2 - z z^T`, `z = Σ v`, as `(ω, c^2)`: `ω` the singular values of
    /// the matrix without the column (descending, p of them; with V square one of them is 0)
    /// and `c^2` the squared coefficients of the deleted column on the matching left singular
    /// vectors. `sigma` (descending, non-negative) and `v` (the deleted column's row of V) have
    /// length p; `complement = 1 - ||v||^2` is the squared norm of the rest of that row of the
    /// full orthogonal V (0 when V is square), passed separately because forming `1 - ||v||^2`
    /// would cancel. All finite.
    pub fn solve(&mut self, sigma: &[f64], v: &[f64], complement: f64) -> &[(f64, f64)] {
        assert_eq!(sigma.len(), v.len(), "ColumnDowndate: σ and v differ in length");
        self.s.clear();
        self.w.clear();
        self.pairs.clear();
        // f(0) = 1 - sum_kept w / s^2 = complement + what deflation takes out of ||v||^2.
        let mut f0 = complement;
        for (&sk, &vk) in sigma.iter().zip(v) {
            debug_assert!(sk >= 0.0, "ColumnDowndate: negative singular value");
            let zk = sk * vk;
            if zk * zk == 0.0 {
                self.pairs.push((sk, 0.0));
                f0 += vk * vk;
            } else if self.s.last() == Some(&sk) {
                *self.w.last_mut().expect("a kept pole") += zk * zk;
                self.pairs.push((sk, 0.0));
            } else {
                self.s.push(sk);
                self.w.push(zk * zk);
            }
        }
        self.delta.resize(self.s.len(), 0.0);
        self.plus.resize(self.s.len(), 0.0);
        for l in 0..self.s.len() {
            let root = self.root(l, f0);
            self.pairs.push(root);
        }
        self.pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
        &self.pairs
    }

    /// The root in `(s_{l+1}, s_l)` (`[0, s_l)` for the last, with `f(0) = f0`) and its weight.
    fn root(&mut self, l: usize, f0: f64) -> (f64, f64) {
        let k_len = self.s.len();
        let hi = self.s[l];
        let lower_pole = l + 1 < k_len;
        let lo = if lower_pole { self.s[l + 1] } else { 0.0 };
        if !lower_pole && f0 <= 0.0 {
            // The fold lost a direction: ω = 0 exactly (V square and nothing deflated).
            return (0.0, weight(self.s.iter().zip(&self.w).map(|(s, w)| w / (s * s * s * s)).sum()));
        }
        let mid = 0.5 * (lo + hi);
        self.shift(lo);
        // f decreases: f(mid) >= 0 puts the root in [mid, hi), nearer the upper pole.
        let f_mid = self.eval(l, lo, mid - lo, f0).f;
        let (origin, mut t_lo, mut t_hi) = if f_mid >= 0.0 { (hi, mid - hi, 0.0) } else { (lo, 0.0, mid - lo) };
        self.shift(origin);
        // Distances of the bracketing poles from the origin (the last root has no lower pole:
        // the model keeps only the upper one).
        let d_up = self.delta[l];
        let d_low = if lower_pole { self.delta[l + 1] } else { f64::NAN };
        let mut tau = 0.5 * (t_lo + t_hi);
        for _ in 0..200 {
            let e = self.eval(l, origin, tau, f0);
            if e.f.abs() <= 8.0 * f64::EPSILON * (f0 + e.abs) {
                break;
            }
            if e.f > 0.0 {
                t_lo = tau;
            } else {
                t_hi = tau;
            }
            let next = model_step(&e, d_up - tau, lower_pole.then_some(d_low - tau))
                .map(|eta| tau + eta)
                .filter(|&t| t > t_lo && t < t_hi)
                .unwrap_or(0.5 * (t_lo + t_hi));
            if t_hi - t_lo <= 2.0 * f64::EPSILON * t_lo.abs().max(t_hi.abs()) {
                break;
            }
            tau = next;
        }
        let inv = self
            .delta
            .iter()
            .zip(&self.plus)
            .zip(&self.w)
            .map(|((d, p), w)| {
                let den = (d - tau) * (p + tau);
                w / (den * den)
            })
            .sum();
        (origin + tau, weight(inv))
    }

    /// Pole distances `σ_k - origin` and sums `σ_k + origin` for roots measured from `origin`.
    fn shift(&mut self, origin: f64) {
        for ((d, p), s) in self.delta.iter_mut().zip(self.plus.iter_mut()).zip(&self.s) {
            *d = s - origin;
            *p = s + origin;
        }
    }

    /// f at `ω = origin + τ` (deltas and pluses relative to `origin`), as
    /// `f(0) - sum_k w_k ω^2 / (s_k^2 (s_k - ω)(s_k + ω))`: each term is the k-th term of
    /// `1 - f` less its value at 0, so no O(1) quantities cancel when the root is small against
    /// the poles above it.
    fn eval(&self, l: usize, origin: f64, tau: f64, f0: f64) -> Eval {
        let mut e = Eval { f: 0.0, psi: 0.0, dpsi: 0.0, phi: 0.0, dphi: 0.0, abs: 0.0 };
        let omega = origin + tau;
        let o2 = omega * omega;
        for (k, (((d, p), w), s)) in self.delta.iter().zip(&self.plus).zip(&self.w).zip(&self.s).enumerate() {
            let (dk, pk) = (d - tau, p + tau);
            let den = dk * pk;
            let term = w * o2 / (s * s * den);
            // d/dτ of w / ((Δ - τ)(σ + σ_o + τ)) = w (pk - dk) / den^2 = 2 w ω / den^2 > 0.
            let slope = w * (pk - dk) / (den * den);
            if k <= l {
                e.psi += term;
                e.dpsi += slope;
            } else {
                e.phi += term;
                e.dphi += slope;
            }
            e.abs += term.abs();
        }
        e.f = f0 - e.psi - e.phi;
        e
    }

    /// Number of poles kept after the deflation of the last [`ColumnDowndate::solve`] (tests).
    #[cfg(test)]
    fn kept(&self) -> usize {
        self.s.len()
    }
}

/// The weight `c^2 = 1 / inv` of a root from `inv = sum_k z_k^2 / (σ_k^2 - ω^2)^2`; 0 when `inv`
/// overflowed (a root on a pole carries no weight).
fn weight(inv: f64) -> f64 {
    if inv.is_finite() && inv > 0.0 {
        1.0 / inv
    } else {
        0.0
    }
}

/// The step η to the root of the two-pole model at τ: `a = Δ_l - τ > 0` and `b = Δ_{l+1} - τ < 0`
/// the distances to the bracketing poles. The model `E - B / (a - η) - D / (b - η)` matches f's
/// value and slope, with `B = ψ' a^2`, `D = φ' b^2`, `E = f + B / a + D / b`. `None` when the
/// model has no real root.
fn model_step(e: &Eval, a: f64, b: Option<f64>) -> Option<f64> {
    let big_b = e.dpsi * a * a;
    match b {
        None => {
            // One pole: E - B / (a - η) = 0, η = a - B / E.
            let big_e = e.f + big_b / a;
            (big_e > 0.0).then(|| a - big_b / big_e)
        }
        Some(b) => {
            let big_d = e.dphi * b * b;
            let big_e = e.f + big_b / a + big_d / b;
            // E (a - η)(b - η) - B (b - η) - D (a - η) = 0:
            // E η^2 - (E (a + b) - B - D) η + f a b = 0 (the constant is the model at η = 0).
            let beta = -(big_e * (a + b) - big_b - big_d);
            let gamma = e.f * a * b;
            let disc = beta * beta - 4.0 * big_e * gamma;
            if disc.is_nan() || disc < 0.0 {
                return None;
            }
            let q = -0.5 * (beta + beta.signum() * disc.sqrt());
            // The root nearer zero is γ / q (the step from τ); the other is q / E.
            let near = if q != 0.0 { Some(gamma / q) } else { None };
            let far = if big_e != 0.0 { Some(q / big_e) } else { None };
            let inside = |eta: &f64| *eta > b && *eta < a;
            near.filter(inside).or(far.filter(inside))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use faer::Mat;

    /// The singular values of A without column i by a direct SVD, descending.
    fn direct(a: &Mat<f64>, i: usize) -> Vec<f64> {
        let rest = Mat::from_fn(a.nrows(), a.ncols() - 1, |r, c| a[(r, if c < i { c } else { c + 1 })]);
        rest.thin_svd().expect("svd").S().column_vector().iter().copied().collect()
    }

    /// (σ, v, 1 - ||v||^2) of A's full SVD for column i.
    fn inputs(a: &Mat<f64>, i: usize) -> (Vec<f64>, Vec<f64>, f64) {
        let svd = a.svd().expect("svd");
        let sigma: Vec<f64> = svd.S().column_vector().iter().copied().collect();
        let v = (0..sigma.len()).map(|k| svd.V()[(i, k)]).collect();
        let complement = (sigma.len()..a.ncols()).map(|k| svd.V()[(i, k)] * svd.V()[(i, k)]).sum();
        (sigma, v, complement)
    }

    #[test]
    fn singular_values_and_weights_match_a_direct_svd() {
        // Random matrices, square and wide and tall, with graded singular values down to
        // 1e-12 σ_1 (where an eigen-downdate of the Gram would lose them).
        let mut rng = Rng::new(5);
        for &(n, count, grade) in &[(12, 12, 1.0_f64), (20, 9, 1e-3), (7, 15, 1.0), (30, 30, 1e-12)] {
            let raw = Mat::from_fn(n, count, |_, _| rng.uniform_in(-1.0, 1.0));
            let svd = raw.thin_svd().expect("svd");
            let p = n.min(count);
            let scale = Mat::from_fn(p, p, |r, c| if r == c { grade.powf(r as f64 / (p - 1) as f64) } else { 0.0 });
            let a = svd.U() * &scale * svd.V().transpose();
            let mut dd = ColumnDowndate::new();
            for i in 0..count {
                let (sigma, v, complement) = inputs(&a, i);
                let pairs = dd.solve(&sigma, &v, complement).to_vec();
                assert_eq!(pairs.len(), p);
                let reference = direct(&a, i);
                // Both are backward stable at O(eps σ_1) (σ_1 = 1 here): 1e-13 absolute.
                for (k, r) in reference.iter().enumerate() {
                    assert_close!(pairs[k].0, *r, Tol::abs(1e-13));
                }
                // The weights sum to ||a_i||^2 (round-off of p terms of size <= 1: 1e-13).
                let norm2: f64 = (0..n).map(|r| a[(r, i)] * a[(r, i)]).sum();
                assert_close!(pairs.iter().map(|p| p.1).sum::<f64>(), norm2, Tol::abs(1e-13));
            }
        }
    }

    #[test]
    fn weights_are_the_squared_coefficients_on_the_left_vectors() {
        // c_l^2 = (u'_l^T a_i)^2 with u'_l the direct SVD's left vectors of A without column i,
        // for well separated singular values (so each u'_l is well defined).
        let mut rng = Rng::new(6);
        let (n, count) = (10, 6);
        let a = Mat::from_fn(n, count, |_, _| rng.uniform_in(-1.0, 1.0));
        let mut dd = ColumnDowndate::new();
        for i in 0..count {
            let (sigma, v, complement) = inputs(&a, i);
            let pairs = dd.solve(&sigma, &v, complement).to_vec();
            let rest = Mat::from_fn(n, count - 1, |r, c| a[(r, if c < i { c } else { c + 1 })]);
            let svd = rest.thin_svd().expect("svd");
            let values: Vec<f64> = svd.S().column_vector().iter().copied().collect();
            assert!(values.windows(2).all(|w| w[0] - w[1] > 1e-2), "the premise: separated values {values:?}");
            for (l, pair) in pairs.iter().take(count - 1).enumerate() {
                let c: f64 = (0..n).map(|r| svd.U()[(r, l)] * a[(r, i)]).sum();
                // O(1) data, gaps above 1e-2: the modes are determined to eps / gap, 1e-12
                // absolute on the squared coefficient.
                assert_close!(pair.1, c * c, Tol::abs(1e-12));
            }
        }
    }

    #[test]
    fn deflation_handles_zero_weights_and_repeated_poles() {
        // z_2 = 0: σ_2 is an eigenvalue with weight 0. σ_3 = σ_4: one of them deflates.
        let sigma = [4.0, 3.0, 2.0, 1.0, 1.0, 0.5];
        let v = [0.125, 0.4 / 3.0, 0.0, 0.3, 0.2, 0.2];
        let z: Vec<f64> = sigma.iter().zip(&v).map(|(s, v)| s * v).collect();
        let complement = 1.0 - v.iter().map(|x| x * x).sum::<f64>();
        let mut dd = ColumnDowndate::new();
        let pairs = dd.solve(&sigma, &v, complement).to_vec();
        assert_eq!(dd.kept(), 4);
        // The eigenvalues of diag(σ^2) - z z^T by a dense symmetric eigen-solver.
        let g = Mat::from_fn(6, 6, |r, c| if r == c { sigma[r] * sigma[r] } else { 0.0 } - z[r] * z[c]);
        let mut ev: Vec<f64> =
            g.self_adjoint_eigenvalues(faer::Side::Lower).expect("eigen").iter().map(|v| v.max(0.0).sqrt()).collect();
        ev.sort_by(|a, b| b.total_cmp(a));
        for (p, e) in pairs.iter().zip(&ev) {
            // O(1) data, well conditioned eigenvalues: 1e-13 absolute on ω.
            assert_close!(p.0, *e, Tol::abs(1e-13));
        }
        // σ = 2 with z = 0 is an eigenpair with weight exactly 0.
        assert!(
            pairs.iter().any(|p| p.0.to_bits() == 2.0f64.to_bits() && p.1.to_bits() == 0.0f64.to_bits()),
            "{pairs:?}"
        );
        assert_close!(pairs.iter().map(|p| p.1).sum::<f64>(), z.iter().map(|v| v * v).sum::<f64>(), Tol::abs(1e-15));
    }
}
