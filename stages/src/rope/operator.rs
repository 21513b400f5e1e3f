//! The rope as a [`ContactOperator`] for the online reduced solve: static pairs (Type-1), gap
//! `u_i - g(x_i, γ)` at every interior node, nodal force = pressure × `h`.

use super::{unconstrained, Rope};
use crate::rom::{ContactOperator, Linearized};

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

    fn repairs(&self) -> bool {
        false
    }

    fn read_dofs(&self) -> Vec<usize> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use faer::{Mat, MatRef};

    use crate::basis::{cpg, pod, CpgParams, PodParams};
    use crate::rom::{ContactOperator, OnlineRom, RomOutcome, RomParams};
    use crate::rope::fixtures::{paper_rope, training};
    use crate::rope::{Rope, RopeParams};

    /// The first `r` columns of `m`, column-major.
    fn columns(m: &Mat<f64>, r: usize) -> Vec<f64> {
        (0..r).flat_map(|j| m.col(j).iter().copied().collect::<Vec<_>>()).collect()
    }

    /// Primal POD of the training contact responses and CPG (tolerance 0) of the pressures.
    fn full_bases(rope: &Rope) -> (Mat<f64>, Mat<f64>) {
        let n = rope.n_nodes();
        let (_, _, responses, duals) = training(rope);
        let phi = pod(MatRef::from_column_major_slice(&responses, n, 10), PodParams::default()).expect("pod");
        let theta = cpg(MatRef::from_column_major_slice(&duals, n, 10), CpgParams::default()).expect("cpg");
        (phi.modes, theta.basis)
    }

    /// With the full bases (primal POD of the 10 contact responses at numerical rank, CPG at
    /// tolerance 0), the training snapshot is a KKT point of the reduced problem and the reduced
    /// QP is strictly convex, so Algorithm 1 must return it: relative H1 error at the level of
    /// the full-order solver tolerance and the rounding of the projections (1e-8), and — as the
    /// paper observes (Sec. 3) — exactly one active reduced dual dof.
    #[test]
    fn full_bases_reproduce_every_training_snapshot() {
        let rope = paper_rope();
        let (gammas, snaps, _, _) = training(&rope);
        let (phi, theta) = full_bases(&rope);
        let (ru, rl) = (phi.ncols(), theta.ncols());
        let rom = OnlineRom::new(&rope, &columns(&phi, ru), ru, &columns(&theta, rl), rl).expect("K̂ SPD");
        for (g, s) in gammas.iter().zip(&snaps) {
            let r = rom.solve(&rope, &[*g], &RomParams::default());
            assert_eq!(r.outcome, RomOutcome::Converged, "gamma {g}");
            let diff: Vec<f64> = r.u.iter().zip(&s.u).map(|(a, b)| a - b).collect();
            let err = (rope.primal_norm_sq(&diff) / rope.primal_norm_sq(&s.u)).sqrt();
            assert!(err <= 1e-8, "gamma {g}: relative H1 error {err:e}");
            let dnorm = s.pressure.iter().map(|x| x * x).sum::<f64>().sqrt();
            let derr = r.pressure.iter().zip(&s.pressure).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / dnorm;
            assert!(derr <= 1e-8, "gamma {g}: relative dual error {derr:e}");
            assert_eq!(r.nonzero_dual, 1, "gamma {g}: one active reduced dual dof (paper Sec. 3): {:?}", r.lambda_hat);
        }
    }

    /// `leading(r_u, r_l)` is the model built from the leading basis vectors: same answers as
    /// building it from scratch (rounding of a different summation order, 1e-12 relative).
    #[test]
    fn leading_block_equals_a_fresh_model() {
        let rope = paper_rope();
        let (phi, theta) = full_bases(&rope);
        let (ru, rl) = (phi.ncols(), theta.ncols());
        let full = OnlineRom::new(&rope, &columns(&phi, ru), ru, &columns(&theta, rl), rl).expect("SPD");
        let (ru, rl) = (4, 6);
        let fresh = OnlineRom::new(&rope, &columns(&phi, ru), ru, &columns(&theta, rl), rl).expect("SPD");
        let lead = full.leading(ru, rl);
        for g in [-0.45, 0.05, 0.4] {
            let (a, b) =
                (lead.solve(&rope, &[g], &RomParams::default()), fresh.solve(&rope, &[g], &RomParams::default()));
            assert_eq!(a.outcome, b.outcome);
            for (x, y) in a.u.iter().zip(&b.u) {
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
        let rom = OnlineRom::new(&far, &phi, 1, &theta, 1).expect("K̂ SPD");
        let r = rom.solve(&far, &[0.0], &RomParams::default());
        assert_eq!((r.outcome, r.iterations, r.active), (RomOutcome::Converged, 0, 0));
        assert_eq!(r.u, far.lift(&[0.0]));
    }
}
