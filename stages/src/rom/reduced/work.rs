//! The buffers of online queries ([`RomWork`]): one per thread, reused across queries, so a
//! query allocates nothing once they have grown.

use super::linearise::LinState;
use super::{ReducedModel, ReducedSolution, SolveInfo, SurfaceData};
use crate::contact::pairing::{Certificate, Pair};
use crate::mu::affine;
use crate::rom::qp::QpWork;

/// Buffers of online queries; one per thread, reused across queries.
#[derive(Debug, Clone, Default)]
pub struct RomWork {
    pub(super) lin: LinState,
    pub(super) qp: QpWork,
    pub(super) warm: Vec<usize>,
    /// Hashes of the pairings reached by a change (cycle detection).
    pub(super) seen: Vec<u64>,
    pub(super) x: Vec<f64>,
    /// The iterate in the K-orthonormal coordinates `y` (see [`ReducedModel`]).
    pub(super) u_hat: Vec<f64>,
    /// The answer `û = L^{-T} y` in the caller's primal basis.
    pub(super) coords: Vec<f64>,
    pub(super) lam: Vec<f64>,
    pub(super) s: Vec<f64>,
    pub(super) zero: Vec<f64>,
    pub(super) phit_f: Vec<f64>,
    pub(super) fnode: Vec<(usize, f64)>,
    /// Slaves forced to a vertex by the vertex-zone rule in the current query.
    pub(super) forced: Vec<Option<usize>>,
    /// Pressure per slave (the vertex-zone rule).
    pub(super) pressures: Vec<f64>,
    /// The exact corrected step's buffers ([`super::exact_step`]).
    pub(super) exact: super::exact_step::ExactStepWork,
}

impl RomWork {
    /// The solution of the last [`ReducedModel::solve_in`] with these buffers.
    pub fn solution(&self, info: &SolveInfo) -> ReducedSolution {
        let max = self.lam.iter().fold(0.0f64, |m, l| m.max(*l));
        ReducedSolution {
            u_hat: self.coords.clone(),
            lambda_hat: self.lam.clone(),
            iterations: info.iterations,
            linearizations: info.linearizations,
            active: info.active,
            nonzero_dual: self.lam.iter().filter(|l| **l > 1e-9 * max).count(),
            outcome: info.outcome,
        }
    }

    /// Size the buffers for a query of `m` at `mu` and reset the linearisation state.
    pub(super) fn prepare(&mut self, m: &ReducedModel, mu: &[f64]) {
        let (ru, rl) = (m.r_u, m.r_l);
        for (v, n) in
            [(&mut self.x, ru), (&mut self.u_hat, ru), (&mut self.zero, ru), (&mut self.lam, rl), (&mut self.s, rl)]
        {
            v.clear();
            v.resize(n, 0.0);
        }
        self.lin.count = 0;
        if let SurfaceData::Fixed { ghat, .. } = &m.surf {
            self.lin.g_mu.resize(rl, 0.0);
            affine_into(ghat, mu, &mut self.lin.g_mu);
        }
        if let SurfaceData::Nts3(d) = &m.surf {
            let ncd = 3 * d.x_ref.len();
            let l = &mut self.lin;
            l.base.resize(ncd, 0.0);
            affine_into(&d.a_terms, mu, &mut l.base);
            for (cd, b) in l.base.iter_mut().enumerate() {
                *b += d.x_ref[cd / 3][cd % 3];
            }
            l.xc.clear();
            l.xc.resize(ncd, f64::NAN);
            l.pairs3.clear();
            l.pairs3.resize(d.ns, crate::contact3d::surface::Pair3::UNPAIRED);
            l.located3.clear();
            l.located3.resize(d.ns, None);
            l.moved3.clear();
            l.moved3.resize(d.ns, 0.0);
            l.last3.clear();
            l.last3.resize(d.ns, [f64::NAN; 3]);
            l.xm3_prev.clear();
            l.ps_of.clear();
            l.ps_of.resize(d.ns, usize::MAX);
            l.fresh = true;
        }
        if let SurfaceData::Nts { ns, nm, x_ref, a_terms, .. } = &m.surf {
            let ncd = 2 * x_ref.len();
            let l = &mut self.lin;
            l.base.resize(ncd, 0.0);
            affine_into(a_terms, mu, &mut l.base);
            for (cd, b) in l.base.iter_mut().enumerate() {
                *b += x_ref[cd / 2][cd % 2];
            }
            l.xc.clear();
            l.xc.resize(ncd, f64::NAN);
            l.xm.clear();
            l.xm.resize(*nm, [0.0; 2]);
            l.placed.resize(*nm, 0);
            l.masters_all = false;
            l.pairs.clear();
            l.pairs.resize(*ns, Pair::NONE);
            l.ps_of.clear();
            l.ps_of.resize(*ns, usize::MAX);
            l.budget.clear();
            l.budget.resize(*ns, 0.0);
            l.cert.clear();
            l.cert.resize(*ns, Certificate::default());
            l.cert_x.clear();
            l.cert_x.resize(*ns, [0.0; 2]);
            l.cert_path.clear();
            l.cert_path.resize(*ns, 0.0);
            l.master_path = 0.0;
            l.prev_full = false;
            l.travel = 0.0;
            l.fresh = true;
            l.placed_at_start = false;
            l.ties.set_end_ties(true);
            l.ties.reset(*ns);
        }
    }
}

/// `out[i] = terms[0][i] + sum_k mu_k terms[1 + k][i]`: affine terms evaluated at `mu`.
pub(super) fn affine_into(terms: &[Vec<f64>], mu: &[f64], out: &mut [f64]) {
    for (i, o) in out.iter_mut().enumerate() {
        *o = affine(&terms[0], &terms[1..], mu, i);
    }
}
