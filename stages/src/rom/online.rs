//! [`OnlineRom`]: offline reduced stiffness, online Algorithm 1 (see the module doc).

use super::operator::{ContactOperator, Linearized};
use super::saddle::{cholesky, solve_saddle};

/// Settings of the online solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RomParams {
    /// Cap on fixed-point iterations (default 100).
    pub max_iter: usize,
    /// A reduced constraint counts as violated when its gap is below `-gap_tol * scale`, with
    /// `scale` the largest `|ĝ0|` at the query (default 1e-12: rounding of the projections).
    pub gap_tol: f64,
    /// Type-2 only: the linearisation (pairing, normals) is frozen during each saddle solve, so
    /// the iterate is converged only once `||û_k - û_{k-1}|| <= u_tol ||û_k||` as well
    /// (default 1e-12).
    pub u_tol: f64,
}

impl Default for RomParams {
    fn default() -> Self {
        Self { max_iter: 100, gap_tol: 1e-12, u_tol: 1e-12 }
    }
}

/// How the online iteration ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RomOutcome {
    /// The active set (and pairing) stopped changing.
    Converged,
    /// An earlier active set came back: the fixed point cycles.
    Cycled,
    /// `max_iter` reached.
    NotConverged,
}

impl RomOutcome {
    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            RomOutcome::Converged => "converged",
            RomOutcome::Cycled => "cycled",
            RomOutcome::NotConverged => "not_converged",
        }
    }
}

/// Result of one online query.
#[derive(Debug, Clone, PartialEq)]
pub struct RomSolution {
    /// Reconstructed displacement `u0 + Phi û` (all dofs).
    pub u: Vec<f64>,
    /// Reconstructed pressure `Theta λ̂`.
    pub pressure: Vec<f64>,
    /// Reduced displacement coordinates.
    pub u_hat: Vec<f64>,
    /// Reduced dual coordinates (>= 0 on the active set, 0 elsewhere).
    pub lambda_hat: Vec<f64>,
    /// Fixed-point iterations.
    pub iterations: usize,
    /// Active reduced constraints at the end (the mask of Algorithm 1).
    pub active: usize,
    /// Reduced dual dofs with a non-negligible multiplier, `λ̂_i > 1e-9 max λ̂`: a weakly
    /// active constraint (zero gap, zero force) carries a rounding-level multiplier and is not
    /// counted (the paper's "number of active dofs of λ̂").
    pub nonzero_dual: usize,
    /// How it ended.
    pub outcome: RomOutcome,
}

/// A reduced model: the bases and the factor of `K̂`, built offline once.
#[derive(Debug, Clone)]
pub struct OnlineRom {
    n_dof: usize,
    n_contact: usize,
    r_u: usize,
    r_l: usize,
    /// Column-major `n_dof x r_u`.
    phi: Vec<f64>,
    /// Column-major `n_contact x r_l`.
    theta: Vec<f64>,
    /// Cholesky factor of `K̂` (column-major `r_u x r_u`).
    khat_l: Vec<f64>,
    /// The dofs the linearisation reads, and `Phi` restricted to them (column-major).
    read_dofs: Vec<usize>,
    phi_read: Vec<f64>,
}

/// Why an [`OnlineRom`] could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RomError {
    /// `Phi^T K Phi` is not positive definite (a basis vector with K-energy 0, e.g. one that does
    /// not vanish on the Dirichlet dofs, or dependent columns).
    #[error("the reduced stiffness Phi^T K Phi is not positive definite (rank-deficient or non-lifted primal basis)")]
    SingularStiffness,
}

impl OnlineRom {
    /// Offline: `phi` (`n_dof x r_u`, column-major, zero on Dirichlet dofs) and `theta`
    /// (`n_contact x r_l`, column-major).
    pub fn new(op: &dyn ContactOperator, phi: &[f64], r_u: usize, theta: &[f64], r_l: usize) -> Result<Self, RomError> {
        let (n_dof, n_contact) = (op.n_dof(), op.n_contact());
        assert_eq!(phi.len(), n_dof * r_u, "phi shape");
        assert_eq!(theta.len(), n_contact * r_l, "theta shape");
        let mut kphi = vec![0.0; n_dof];
        let mut khat = vec![0.0; r_u * r_u];
        for j in 0..r_u {
            op.stiffness_mul(&phi[j * n_dof..(j + 1) * n_dof], &mut kphi);
            for i in 0..r_u {
                khat[i + j * r_u] = phi[i * n_dof..(i + 1) * n_dof].iter().zip(&kphi).map(|(a, b)| a * b).sum();
            }
        }
        // Symmetrise the rounding of the two-sided product before factoring.
        for j in 0..r_u {
            for i in j + 1..r_u {
                let m = 0.5 * (khat[i + j * r_u] + khat[j + i * r_u]);
                khat[i + j * r_u] = m;
                khat[j + i * r_u] = m;
            }
        }
        if !cholesky(&mut khat, r_u) {
            return Err(RomError::SingularStiffness);
        }
        let read_dofs = op.read_dofs();
        let phi_read = (0..r_u).flat_map(|j| read_dofs.iter().map(move |&d| phi[d + j * n_dof])).collect();
        Ok(Self {
            n_dof,
            n_contact,
            r_u,
            r_l,
            phi: phi.to_vec(),
            theta: theta.to_vec(),
            khat_l: khat,
            read_dofs,
            phi_read,
        })
    }

    /// Primal and dual ranks.
    pub fn ranks(&self) -> (usize, usize) {
        (self.r_u, self.r_l)
    }

    /// The reduced model on the first `r_u` primal and `r_l` dual basis vectors, without
    /// recomputing `K̂`: `Phi[:, :r]^T K Phi[:, :r]` is the leading block of `K̂`, and the
    /// Cholesky factor of a leading block is the leading block of the factor.
    pub fn leading(&self, r_u: usize, r_l: usize) -> Self {
        assert!(r_u <= self.r_u && r_l <= self.r_l, "leading ranks exceed the model's");
        let mut khat_l = vec![0.0; r_u * r_u];
        for j in 0..r_u {
            khat_l[j * r_u..(j + 1) * r_u].copy_from_slice(&self.khat_l[j * self.r_u..j * self.r_u + r_u]);
        }
        let nd = self.read_dofs.len();
        Self {
            n_dof: self.n_dof,
            n_contact: self.n_contact,
            r_u,
            r_l,
            phi: self.phi[..r_u * self.n_dof].to_vec(),
            theta: self.theta[..r_l * self.n_contact].to_vec(),
            khat_l,
            read_dofs: self.read_dofs.clone(),
            phi_read: self.phi_read[..r_u * nd].to_vec(),
        }
    }

    /// Ĉ (row-major `r_l x r_u`) and ĝ0 from a linearisation and the lift.
    fn project(
        &self,
        op: &dyn ContactOperator,
        lin: &Linearized,
        u0: &[f64],
        cphi: &mut [f64],
        chat: &mut [f64],
        ghat: &mut [f64],
    ) {
        let (nc, ru, rl) = (self.n_contact, self.r_u, self.r_l);
        let w = op.weights();
        // cphi (nc x ru, row-major) = W C Phi; g (reuse ghat later) = W (C u0 + gap0).
        let mut wg = vec![0.0; nc];
        for i in 0..nc {
            let row = &mut cphi[i * ru..(i + 1) * ru];
            row.iter_mut().for_each(|x| *x = 0.0);
            if !lin.paired[i] {
                continue;
            }
            for k in lin.start[i]..lin.start[i + 1] {
                let (d, c) = (lin.dofs[k], lin.coeffs[k] * w[i]);
                for (j, x) in row.iter_mut().enumerate() {
                    *x += c * self.phi[d + j * self.n_dof];
                }
            }
            wg[i] = w[i] * lin.gap(i, u0);
        }
        for a in 0..rl {
            let th = &self.theta[a * nc..(a + 1) * nc];
            let out = &mut chat[a * ru..(a + 1) * ru];
            out.iter_mut().for_each(|x| *x = 0.0);
            let mut g = 0.0;
            for i in 0..nc {
                if th[i].abs() > 0.0 {
                    for (x, c) in out.iter_mut().zip(&cphi[i * ru..(i + 1) * ru]) {
                        *x += th[i] * c;
                    }
                    g += th[i] * wg[i];
                }
            }
            ghat[a] = g;
        }
    }

    /// Online: Algorithm 1 at parameter `mu`.
    pub fn solve(&self, op: &dyn ContactOperator, mu: &[f64], p: &RomParams) -> RomSolution {
        let (ru, rl) = (self.r_u, self.r_l);
        let u0 = op.lift(mu);
        let mut u = u0.clone();
        let mut lin = Linearized::default();
        op.linearize(mu, &u, &mut lin);
        let mut cphi = vec![0.0; self.n_contact * ru];
        let mut chat = vec![0.0; rl * ru];
        let mut ghat = vec![0.0; rl];
        self.project(op, &lin, &u0, &mut cphi, &mut chat, &mut ghat);
        let mut u_hat = vec![0.0; ru];
        let mut lam = vec![0.0; rl];
        let mut mask = vec![false; rl];
        let scale = ghat.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        let violated = |g: f64| g < -p.gap_tol * scale;
        // Deterministic start: the most violated reduced constraint at û = 0.
        let start = (0..rl).filter(|&a| violated(ghat[a])).min_by(|&a, &b| ghat[a].total_cmp(&ghat[b]));
        let Some(first) = start else {
            return self.finish(u, u_hat, lam, 0, 0, RomOutcome::Converged);
        };
        mask[first] = true;
        let mut history: Vec<(Vec<bool>, Vec<u64>)> = Vec::new();
        let (mut c_a, mut g_a, mut lam_a, mut work) =
            (Vec::with_capacity(rl * ru), Vec::with_capacity(rl), vec![0.0; rl], Vec::new());
        let mut gap = vec![0.0; rl];
        let mut prev_u_hat = vec![0.0; ru];
        for it in 1..=p.max_iter {
            prev_u_hat.copy_from_slice(&u_hat);
            c_a.clear();
            g_a.clear();
            let idx: Vec<usize> = (0..rl).filter(|&a| mask[a]).collect();
            for &a in &idx {
                c_a.extend_from_slice(&chat[a * ru..(a + 1) * ru]);
                g_a.push(ghat[a]);
            }
            lam_a.resize(idx.len(), 0.0);
            solve_saddle(&self.khat_l, ru, &c_a, &g_a, &mut u_hat, &mut lam_a, &mut work);
            lam.iter_mut().for_each(|x| *x = 0.0);
            for (k, &a) in idx.iter().enumerate() {
                lam[a] = lam_a[k];
            }
            let mut pairing_changed = false;
            if op.repairs() {
                self.reconstruct_read_dofs(&u0, &u_hat, &mut u);
                let old = std::mem::take(&mut lin.pairing);
                op.linearize(mu, &u, &mut lin);
                pairing_changed = old != lin.pairing;
                self.project(op, &lin, &u0, &mut cphi, &mut chat, &mut ghat);
            }
            for a in 0..rl {
                gap[a] = chat[a * ru..(a + 1) * ru].iter().zip(&u_hat).map(|(c, x)| c * x).sum::<f64>() + ghat[a];
            }
            let new: Vec<bool> = (0..rl).map(|a| if mask[a] { lam[a] >= 0.0 } else { violated(gap[a]) }).collect();
            let settled = new == mask && !pairing_changed;
            let moved = {
                let du: f64 = u_hat.iter().zip(&prev_u_hat).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
                let un: f64 = u_hat.iter().map(|a| a * a).sum::<f64>().sqrt();
                op.repairs() && du > p.u_tol * un
            };
            if settled && !moved {
                let active = mask.iter().filter(|m| **m).count();
                self.reconstruct_into(&u0, &u_hat, &mut u);
                return self.finish(u, u_hat, lam, it, active, RomOutcome::Converged);
            }
            if settled {
                // Same discrete state, geometry still moving: keep iterating on the normals.
                continue;
            }
            let state = (new.clone(), lin.pairing.clone());
            if history.contains(&state) {
                self.reconstruct_into(&u0, &u_hat, &mut u);
                let active = mask.iter().filter(|m| **m).count();
                return self.finish(u, u_hat, lam, it, active, RomOutcome::Cycled);
            }
            history.push(state);
            mask = new;
        }
        self.reconstruct_into(&u0, &u_hat, &mut u);
        let active = mask.iter().filter(|m| **m).count();
        self.finish(u, u_hat, lam, p.max_iter, active, RomOutcome::NotConverged)
    }

    /// `u = u0 + Phi û` on the dofs the linearisation reads only (the rest of `u` is stale).
    fn reconstruct_read_dofs(&self, u0: &[f64], u_hat: &[f64], u: &mut [f64]) {
        let nd = self.read_dofs.len();
        for (k, &d) in self.read_dofs.iter().enumerate() {
            u[d] = u0[d] + u_hat.iter().enumerate().map(|(j, c)| c * self.phi_read[k + j * nd]).sum::<f64>();
        }
    }

    fn reconstruct_into(&self, u0: &[f64], u_hat: &[f64], u: &mut [f64]) {
        u.copy_from_slice(u0);
        for (j, c) in u_hat.iter().enumerate() {
            for (x, p) in u.iter_mut().zip(&self.phi[j * self.n_dof..(j + 1) * self.n_dof]) {
                *x += c * p;
            }
        }
    }

    fn finish(
        &self,
        u: Vec<f64>,
        u_hat: Vec<f64>,
        lambda_hat: Vec<f64>,
        iterations: usize,
        active: usize,
        outcome: RomOutcome,
    ) -> RomSolution {
        let nc = self.n_contact;
        let mut pressure = vec![0.0; nc];
        for (a, l) in lambda_hat.iter().enumerate() {
            for (x, t) in pressure.iter_mut().zip(&self.theta[a * nc..(a + 1) * nc]) {
                *x += l * t;
            }
        }
        let max = lambda_hat.iter().fold(0.0f64, |m, l| m.max(*l));
        let nonzero_dual = lambda_hat.iter().filter(|l| **l > 1e-9 * max).count();
        RomSolution { u, pressure, u_hat, lambda_hat, iterations, active, nonzero_dual, outcome }
    }
}
