//! The rope as a [`ContactOperator`] for the online reduced solve: static pairs (Type-1), gap
//! `u_i - g(x_i, γ)` at every interior node, nodal force = pressure × `h`.

use super::{unconstrained, Rope};
use crate::full_order::{Compliance, ContactOperator, Linearized, Surface};

impl ContactOperator for Rope {
    fn n_dof(&self) -> usize {
        self.n_nodes()
    }

    fn n_contact(&self) -> usize {
        self.n_nodes()
    }

    fn weights(&self) -> &[f64] {
        &self.weights
    }

    fn lift(&self, _mu: &[f64]) -> Vec<f64> {
        // The load does not depend on γ: the lift is the same at every query.
        unconstrained(self)
    }

    fn stiffness_mul(&self, x: &[f64], y: &mut [f64]) {
        let n = self.n_nodes();
        let k = self.params.nu / self.h;
        y[0] = 0.0;
        y[n - 1] = 0.0;
        for i in 1..n - 1 {
            y[i] = k * (2.0 * x[i] - x[i - 1] - x[i + 1]);
        }
    }

    /// The interior block `(nu / h) tridiag(-1, 2, -1)`, solved by the Thomas algorithm.
    fn stiffness_condition(&self) -> Option<crate::condition::Condition> {
        let m = self.n_nodes().saturating_sub(2);
        let k = self.params.nu / self.h;
        let mul = |x: &[f64], y: &mut [f64]| {
            for i in 0..m {
                let left = if i > 0 { x[i - 1] } else { 0.0 };
                let right = if i + 1 < m { x[i + 1] } else { 0.0 };
                y[i] = k * (2.0 * x[i] - left - right);
            }
        };
        let solve = |x: &mut [f64]| {
            let (sub, sup) = (vec![-k; m], vec![-k; m]);
            let mut diag = vec![2.0 * k; m];
            let mut rhs = x.to_vec();
            super::solve::thomas(&sub, &mut diag, &sup, &mut rhs, x);
        };
        crate::condition::estimate(m, crate::condition::ITERATIONS, &mul, &solve)
    }

    fn linearize(&self, mu: &[f64], _u: &[f64], out: &mut Linearized) {
        let n = self.n_nodes();
        out.clear();
        out.start.push(0);
        for i in 0..n {
            let interior = i > 0 && i < n - 1;
            if interior {
                out.dofs.push(i);
                out.coeffs.push(1.0);
            }
            out.start.push(out.dofs.len());
            out.gap0.push(-self.obstacle(self.x[i], mu[0]));
            out.paired.push(interior);
            out.pairing.push(0);
        }
    }

    fn primal_norm_sq(&self, u: &[f64]) -> f64 {
        self.h1_norm_sq(u)
    }

    fn primal_gram_mul(&self, u: &[f64], out: &mut [f64]) {
        self.h1_mul(u, out)
    }

    fn lift_terms(&self) -> Vec<Vec<f64>> {
        // the contact-free rope does not depend on gamma
        vec![unconstrained(self), vec![0.0; self.n_nodes()]]
    }

    fn surface(&self) -> Surface {
        let mut rows = Linearized::default();
        self.linearize(&[0.0], &[], &mut rows);
        // gap0(gamma) = -obstacle(x, gamma) = -(waves(x) + offset) - gamma x  (paper eq. 15)
        let g0 = self.x.iter().map(|&x| -self.obstacle(x, 0.0)).collect();
        let g1 = self.x.iter().map(|&x| -x).collect();
        Surface::Fixed { rows, gap0_terms: vec![g0, g1] }
    }

    /// `K_FF^{-1}` in closed form: `K_FF = (nu / h) tridiag(-1, 2, -1)` on the interior nodes
    /// `1..N-1` (`N` elements), whose inverse is the discrete Green's function
    /// `(h / nu) min(i, j) (N - max(i, j)) / N`; zero on the two Dirichlet ends.
    fn contact_compliance(&self) -> Compliance {
        let n = self.n_nodes();
        let ne = (n - 1) as f64;
        let c = self.h / self.params.nu;
        let mut w = vec![0.0; n * n];
        for i in 1..n - 1 {
            for j in 1..n - 1 {
                let (lo, hi) = (i.min(j) as f64, i.max(j) as f64);
                w[i * n + j] = c * lo * (ne - hi) / ne;
            }
        }
        Compliance { dofs: (0..n).collect(), w }
    }
}

#[cfg(test)]
mod tests {
    use faer::{Mat, MatRef};

    use crate::assert_close;
    use crate::float_cmp::Tol;

    use crate::basis::{cpg, pod, CpgParams, PodParams};
    use crate::rom::{Algorithm, ContactOperator, ReducedModel, RomOutcome, RomParams, RomWork};
    use crate::rope::fixtures::{paper_rope, training};
    use crate::rope::{Rope, RopeParams};

    fn columns(m: &Mat<f64>, r: usize) -> Vec<f64> {
        (0..r).flat_map(|j| m.col(j).iter().copied().collect::<Vec<_>>()).collect()
    }

    fn full_bases(rope: &Rope) -> (Mat<f64>, Mat<f64>) {
        let n = rope.n_nodes();
        let (_, _, responses, duals) = training(rope);
        let phi = pod(MatRef::from_column_major_slice(&responses, n, 10), PodParams::default()).expect("pod");
        let theta = cpg(MatRef::from_column_major_slice(&duals, n, 10), CpgParams::default()).expect("cpg");
        (phi.modes, theta.basis)
    }

    /// The reduced model of the full bases and the primal basis (column-major, for
    /// reconstruction).
    fn full_model(rope: &Rope) -> (ReducedModel, Vec<f64>) {
        let (phi, theta) = full_bases(rope);
        let (ru, rl) = (phi.ncols(), theta.ncols());
        let phi_c = columns(&phi, ru);
        (ReducedModel::new(rope, &phi_c, ru, &columns(&theta, rl), rl).expect("K̂ SPD"), phi_c)
    }

    /// Relative H1 error of the displacement and relative Euclidean error of the pressure.
    fn errors(rope: &Rope, u: &[f64], p: &[f64], s: &crate::snapshot::Snapshot) -> (f64, f64) {
        let diff: Vec<f64> = u.iter().zip(&s.u).map(|(a, b)| a - b).collect();
        let err = (rope.primal_norm_sq(&diff) / rope.primal_norm_sq(&s.u)).sqrt();
        let dnorm = s.pressure.iter().map(|x| x * x).sum::<f64>().sqrt();
        let derr = p.iter().zip(&s.pressure).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / dnorm;
        (err, derr)
    }

    /// With full bases (POD at numerical rank, CPG at tolerance 0) both online algorithms
    /// reproduce every training snapshot to 1e-8 (the rope solver's tolerance is 1e-10 on the
    /// KKT residual; the reduced operators add rounding of the projections), with one active
    /// reduced dual dof (paper Sec. 3). The error indicator is at rounding level there: no
    /// penetration or misplaced force beyond 1e-10 (lengths ~0.1), and an equilibrium residual
    /// below 1e-6 (it is the square root of a difference of energies, so rounding `~1e-15` of
    /// the energies shows as `~3e-8`).
    #[test]
    fn full_bases_reproduce_every_training_snapshot() {
        let rope = paper_rope();
        let (gammas, snaps, _, _) = training(&rope);
        let (rom, phi_c) = full_model(&rope);
        let mut w = RomWork::default();
        for algorithm in [Algorithm::Exact, Algorithm::Paper] {
            let p = RomParams { algorithm, ..RomParams::default() };
            for (g, s) in gammas.iter().zip(&snaps) {
                let r = rom.solve(&[*g], &p, &mut w);
                assert_eq!(r.outcome, RomOutcome::Converged, "{algorithm:?} gamma {g}");
                let u = ReducedModel::displacement(&rope, &phi_c, &[*g], &r.u_hat);
                let (eu, ep) = errors(&rope, &u, &rom.pressure(&r.lambda_hat), s);
                assert!(eu <= 1e-8 && ep <= 1e-8, "{algorithm:?} gamma {g}: errors {eu:e} {ep:e}");
                assert_eq!(r.nonzero_dual, 1, "gamma {g}: {:?}", r.lambda_hat);
                let ind = rom.indicator(&[*g], &mut w);
                assert!(ind.penetration <= 1e-10 && ind.complementarity <= 1e-10, "gamma {g}: {ind:?}");
                assert!(ind.residual <= 1e-6 && ind.unpaired_force == 0.0, "gamma {g}: {ind:?}");
            }
        }
    }

    /// Type-1: the full model, a truncated one with warm starts each survive a round trip
    /// through their parts (`ReducedModel::parts`) bit for bit, at the training points and 20
    /// points between and beyond them, with both algorithms.
    #[test]
    fn models_round_trip_bit_for_bit() {
        let rope = paper_rope();
        let (gammas, _, _, _) = training(&rope);
        let (full, _) = full_model(&rope);
        let samples: Vec<Vec<f64>> = gammas.iter().map(|&g| vec![g]).collect();
        let (lo, hi) = (gammas[0], gammas[gammas.len() - 1]);
        let mut at: Vec<Vec<f64>> = (0..20).map(|k| vec![lo + (hi - lo) * (k as f64 - 1.5) / 16.0]).collect();
        at.extend(samples.iter().cloned());
        let warm = full.leading(4, 3).with_warm_starts(&samples, &RomParams::default());
        for model in [&full, &warm] {
            crate::rom::test_support::assert_round_trip(model, &at);
        }
    }

    /// Truncating the primal basis makes the indicator grow: at rank 2 of 10 its residual is
    /// above 1e-3 at every training point whose true H1 error is above 1e-3 (a residual of
    /// the size of the error, not a rounding artefact).
    #[test]
    fn indicator_grows_with_truncation() {
        let rope = paper_rope();
        let (gammas, snaps, _, _) = training(&rope);
        let (full, phi_c) = full_model(&rope);
        let rom = full.leading(2, 2);
        let mut w = RomWork::default();
        let mut checked = 0;
        for (g, s) in gammas.iter().zip(&snaps) {
            let r = rom.solve(&[*g], &RomParams::default(), &mut w);
            if r.outcome != RomOutcome::Converged {
                continue;
            }
            let u = ReducedModel::displacement(&rope, &phi_c, &[*g], &r.u_hat);
            let (eu, _) = errors(&rope, &u, &rom.pressure(&r.lambda_hat), s);
            let ind = rom.indicator(&[*g], &mut w);
            if eu > 1e-3 {
                checked += 1;
                assert!(ind.residual > 1e-3 || ind.penetration > 1e-4, "gamma {g}: error {eu:e}, {ind:?}");
            }
        }
        assert!(checked >= 3, "too few truncated points with a visible error: {checked}");
    }

    /// Warm starts from the nearest training point's active set change the path of the
    /// Type-1 QP, not its answer: at 37 parameters between and beyond the training points, for
    /// the full model and two truncations, û and λ̂ equal the cold start's to 1e-12 relative
    /// (the QP is strictly convex: one minimiser, reached by different active-set steps; the
    /// difference is rounding of the equality-constrained solves), and the warm start never
    /// takes more QP steps than the cold one and takes fewer in total.
    #[test]
    fn warm_starts_change_the_steps_not_the_answer() {
        let rope = paper_rope();
        let (gammas, _, _, _) = training(&rope);
        let (full, _) = full_model(&rope);
        let samples: Vec<Vec<f64>> = gammas.iter().map(|&g| vec![g]).collect();
        let p = RomParams::default();
        let (mut w, mut v) = (RomWork::default(), RomWork::default());
        for (ru, rl) in [full.ranks(), (6, 10), (10, 4)] {
            let cold = full.leading(ru, rl);
            let warm = cold.clone().with_warm_starts(&samples, &p);
            let (mut steps_cold, mut steps_warm) = (0, 0);
            for k in 0..37 {
                let g = -0.6 + 1.2 * k as f64 / 36.0;
                let (a, b) = (cold.solve(&[g], &p, &mut w), warm.solve(&[g], &p, &mut v));
                assert_eq!((a.outcome, b.outcome), (RomOutcome::Converged, RomOutcome::Converged), "gamma {g}");
                let scale = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let (su, sl) = (scale(&a.u_hat), scale(&a.lambda_hat));
                for (x, y) in a.u_hat.iter().zip(&b.u_hat) {
                    assert!((x - y).abs() <= 1e-12 * su.max(1e-300), "ranks ({ru}, {rl}) gamma {g}: û {x} vs {y}");
                }
                for (x, y) in a.lambda_hat.iter().zip(&b.lambda_hat) {
                    assert!((x - y).abs() <= 1e-12 * sl.max(1e-300), "ranks ({ru}, {rl}) gamma {g}: λ̂ {x} vs {y}");
                }
                assert!(b.iterations <= a.iterations, "gamma {g}: {} warm steps, {} cold", b.iterations, a.iterations);
                steps_cold += a.iterations;
                steps_warm += b.iterations;
            }
            assert!(steps_warm < steps_cold, "ranks ({ru}, {rl}): {steps_warm} warm steps, {steps_cold} cold");
        }
    }

    /// `leading(r_u, r_l)` answers exactly like a model built from the truncated bases (1e-12:
    /// the leading blocks of K̂ and its factor equal the fresh ones up to summation order).
    #[test]
    fn leading_block_equals_a_fresh_model() {
        let rope = paper_rope();
        let (phi, theta) = full_bases(&rope);
        let (ru, rl) = (phi.ncols(), theta.ncols());
        let full = ReducedModel::new(&rope, &columns(&phi, ru), ru, &columns(&theta, rl), rl).expect("SPD");
        let (ru, rl) = (4, 6);
        let fresh = ReducedModel::new(&rope, &columns(&phi, ru), ru, &columns(&theta, rl), rl).expect("SPD");
        let lead = full.leading(ru, rl);
        let mut w = RomWork::default();
        for algorithm in [Algorithm::Exact, Algorithm::Paper] {
            let p = RomParams { algorithm, ..RomParams::default() };
            for g in [-0.45, 0.05, 0.4] {
                let (a, b) = (lead.solve(&[g], &p, &mut w), fresh.solve(&[g], &p, &mut w));
                assert_eq!(a.outcome, b.outcome);
                for (x, y) in a.u_hat.iter().zip(&b.u_hat) {
                    assert!((x - y).abs() <= 1e-12 * (1.0 + y.abs()), "gamma {g}: {x} vs {y}");
                }
            }
        }
    }

    /// `set_dual` on a Type-1 model rebuilds `Ĉ` and `ĝ0` as a fresh model does (1e-12: the
    /// same sums in the same order up to the factor's leading block).
    #[test]
    fn set_dual_equals_a_fresh_model_on_the_rope() {
        let rope = paper_rope();
        let (phi, theta) = full_bases(&rope);
        let (ru, rl) = (phi.ncols(), theta.ncols());
        let full = ReducedModel::new(&rope, &columns(&phi, ru), ru, &columns(&theta, rl), rl).expect("SPD");
        let sub = theta.subcols(2, rl - 3).to_owned();
        let fresh = ReducedModel::new(&rope, &columns(&phi, ru), ru, &columns(&sub, rl - 3), rl - 3).expect("SPD");
        let mut swapped = full.clone();
        swapped.set_dual(&columns(&sub, rl - 3), rl - 3);
        let mut w = RomWork::default();
        for g in [-0.45, 0.05, 0.4] {
            let (a, b) =
                (swapped.solve(&[g], &RomParams::default(), &mut w), fresh.solve(&[g], &RomParams::default(), &mut w));
            assert_eq!(a.outcome, b.outcome);
            for (x, y) in a.u_hat.iter().zip(&b.u_hat).chain(a.lambda_hat.iter().zip(&b.lambda_hat)) {
                assert!((x - y).abs() <= 1e-12 * (1.0 + y.abs()), "gamma {g}: {x} vs {y}");
            }
        }
    }

    /// A query whose obstacle is far below is answered with û = 0, λ̂ = 0 (the lift), without
    /// iterating.
    #[test]
    fn no_contact_query_returns_the_lift() {
        let rope = paper_rope();
        let far = Rope::new(RopeParams { offset: -10.0, ..rope.params.clone() });
        let phi = vec![0.0, 1.0].into_iter().chain(std::iter::repeat_n(0.0, far.n_nodes() - 2)).collect::<Vec<_>>();
        let theta = vec![1.0; far.n_nodes()];
        let rom = ReducedModel::new(&far, &phi, 1, &theta, 1).expect("K̂ SPD");
        let mut w = RomWork::default();
        for algorithm in [Algorithm::Exact, Algorithm::Paper] {
            let r = rom.solve(&[0.0], &RomParams { algorithm, ..RomParams::default() }, &mut w);
            assert_eq!((r.outcome, r.iterations, r.active), (RomOutcome::Converged, 0, 0));
            assert_eq!(r.u_hat, vec![0.0]);
        }
    }

    /// The closed-form compliance inverts the rope's stiffness on the interior: `K W = I` there
    /// (1e-9: entries ~h/nu = 5e-3 times stiffness ~2 nu/h, summed over 3 terms).
    #[test]
    fn compliance_inverts_the_stiffness() {
        let rope = paper_rope();
        let c = rope.contact_compliance();
        let n = rope.n_nodes();
        let mut y = vec![0.0; n];
        for j in 1..n - 1 {
            let col: Vec<f64> = (0..n).map(|i| c.w[i * n + j]).collect();
            rope.stiffness_mul(&col, &mut y);
            for (i, yi) in y.iter().enumerate().take(n - 1).skip(1) {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((yi - e).abs() <= 1e-9, "({i},{j}): {yi}");
            }
        }
    }

    /// The precomputed error evaluation equals reconstructing `u0 + Phi_k û` and taking the H1
    /// norm directly, at every rank k and training point (1e-7 relative to the error, 1e-12
    /// absolute: the direct evaluation itself cancels to ~1e-16 of |u|^2).
    #[test]
    fn precomputed_errors_equal_direct_reconstruction() {
        let rope = paper_rope();
        let (gammas, snaps, _, _) = training(&rope);
        let (full, phi_c) = full_model(&rope);
        let refs: Vec<(Vec<f64>, &[f64])> =
            gammas.iter().zip(&snaps).map(|(g, s)| (vec![*g], s.u.as_slice())).collect();
        let refs: Vec<(&[f64], &[f64])> = refs.iter().map(|(m, u)| (m.as_slice(), *u)).collect();
        let (ru, rl) = full.ranks();
        let pe = crate::rom::PrimalErrors::new(&rope, &phi_c, ru, &refs).expect("M SPD");
        let mut w = RomWork::default();
        for k in [1, 3, ru] {
            let rom = full.leading(k, rl);
            for (j, (g, s)) in gammas.iter().zip(&snaps).enumerate() {
                let r = rom.solve(&[*g], &RomParams::default(), &mut w);
                let u = ReducedModel::displacement(&rope, &phi_c[..k * rope.n_nodes()], &[*g], &r.u_hat);
                let (direct, _) = errors(&rope, &u, &s.pressure, s);
                let fast = pe.relative(j, &r.u_hat);
                assert!((fast - direct).abs() <= 1e-12 + 1e-7 * direct, "k {k} gamma {g}: {fast:e} vs {direct:e}");
            }
        }
    }

    /// The rope's stiffness `(nu / h) tridiag(-1, 2, -1)` on its `n - 1` interior nodes has the
    /// closed-form spectrum `lambda_k = (4 nu / h) sin^2(k pi / (2 n))`, `k = 1..n-1` (`n`
    /// elements): the estimate's smallest eigenvalue to 1e-10 (inverse iteration, bottom ratio
    /// 1/4), its largest within 1 % (the top of the spectrum clusters, so the quotient sits just
    /// below it), both inside the spectrum.
    #[test]
    fn stiffness_condition_matches_the_closed_form() {
        let n = 200;
        let rope = Rope::new(RopeParams {
            length: 1.0,
            n_elements: n,
            nu: 30.0,
            f: 250.0,
            modes: vec![1.0],
            amplitudes: vec![0.1],
            offset: 0.0,
        });
        let h = 1.0 / n as f64;
        let lambda = |k: usize| 4.0 * 30.0 / h * (k as f64 * std::f64::consts::PI / (2.0 * n as f64)).sin().powi(2);
        let c = rope.stiffness_condition().expect("SPD");
        let (lo, hi) = (lambda(1), lambda(n - 1));
        assert_close!(c.lambda_min, lo, Tol::rel(1e-10));
        assert!(c.lambda_min >= lo * (1.0 - 1e-12) && c.lambda_max <= hi * (1.0 + 1e-12));
        assert!(c.lambda_max >= 0.99 * hi, "{} vs {hi}", c.lambda_max);
    }
}
