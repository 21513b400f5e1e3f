//! The high-fidelity contact solve at one parameter value: active set with re-pairing.
//!
//! For the current pairing (frozen `xi`, `n` per slave) the gaps are linear in the contact-dof
//! positions, `g = B x_c`, and the contact dofs respond to the contact forces `B^T lambda` as
//! `u_c = a_c(mu) + W B^T lambda`. Hence `g = q + D lambda` with `q = B (X_c + a_c)` and
//! `D = B W B^T`, an LCP solved by [`super::active_set`]. Then
//!
//! 1. update `u_c` and the deformed positions, re-pair every slave (closest point, deformed
//!    configuration, with vertex ties, [`super::vertex`]);
//! 2. evaluate the KKT residual of `(u, lambda)` for the NEW pairing `B'`:
//!    equilibrium `||(B' - B)^T lambda||_inf / f_ref` (the condensed form of
//!    `K u - f - B'^T lambda` on the free dofs, since `K u - f - B^T lambda = 0` exactly) and
//!    complementarity `||min(lambda, c g')||_inf / max(||lambda||_inf, c ||g'^-||_inf)` with the
//!    actual gaps `g'` and `c = 1 / mean(diag D)` turning lengths into forces;
//! 3. stop when the discrete pairing and the active set did not change and both residuals are
//!    `<= rel_tol`, otherwise go to the LCP with the new pairing (warm-started active set);
//! 4. once pairing kinds and active set have settled, the configuration the next pairing is
//!    computed at is Anderson-mixed ([`super::anderson`]) instead of taken as the last `u_c`
//!    (the re-pairing fixed point is otherwise only linearly convergent); the stopping test of
//!    step 3 is always evaluated on a plain step, so acceleration never changes what counts as
//!    converged.
//!
//! `f_ref = ||B'^T lambda||_inf` (the contact forces, which in every scene balance the
//! reactions) or, without contact, `||K_FD u_D||_inf` (the lifted load; not used with contact
//! because a rigid travel of a stiff body, e.g. the iron, lifts to large self-balanced forces
//! that would make the test lenient). After convergence the full
//! displacement is recovered with one sparse solve, `u_F = u^(0) + mu u^(1) + K_FF^{-1} E_c B^T
//! lambda`, and the reported statistics are recomputed from it with the full sparse `K`. The
//! reported equilibrium residual is the recovered field's backward error (Higham, *Accuracy and
//! Stability of Numerical Algorithms*, sec. 7.1, with the row sums of `|K| |u|` for `||K|| ||u||`):
//! `||K u - f - B^T lambda||_inf / max(||B^T lambda||_inf, max_i (|K| |u| + |f|)_i)` over the free
//! dofs — evaluating `K u` in floating point errs by about `eps (|K| |u|)_i`, so a residual
//! measured against the contact forces alone grows with the stiffness contrast and shrinks
//! with the load without the solution being any worse (the stress matrix found 1e-6 for a
//! 10^6-times stiffer iron and 2e-8 at a grazing 1e-5 indentation). The stopping test above
//! keeps the strict contact-force scale.
//! Every buffer is allocated before the loop.

use super::active_set::{solve_lcp, Lcp, LcpError, LcpWork};
use super::anderson::Anderson;
use super::error::ContactError;
use super::factor::FactoredModel;
use super::pairing::{GapRow as Row, MasterIndex, Pair};
use super::vertex::VertexTies;
use crate::mu::{affine, Mu};
use crate::snapshot::{Snapshot, SolveStats};

/// Settings of the contact solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSolveParams {
    /// Relative KKT tolerance (equilibrium and complementarity), default `1e-10`.
    pub rel_tol: f64,
    /// Budget of active-set iterations (dense solves, summed over re-pairings), default 500.
    pub max_iter: usize,
}

impl Default for ContactSolveParams {
    fn default() -> Self {
        Self { rel_tol: 1e-10, max_iter: 500 }
    }
}

/// Depth of the Anderson mixing of the re-pairing fixed point ([`super::anderson`]).
const ANDERSON_DEPTH: usize = 3;

/// Force scale of the equilibrium residual: the contact forces, or the lifted load without
/// contact (see the module docs).
fn residual_scale(contact_inf: f64, lift_inf: f64) -> f64 {
    if contact_inf > 0.0 {
        contact_inf
    } else {
        lift_inf.max(f64::MIN_POSITIVE)
    }
}

/// `u_c = a + V lambda` over the paired rows, and the contact force `f_old = B^T lambda` of the
/// pairing the multipliers were solved for.
fn update_displacement(ws: &mut Work, np: usize, ncd: usize) {
    ws.uc.copy_from_slice(&ws.a);
    ws.f_old.fill(0.0);
    for r in 0..np {
        let l = ws.lam[r];
        if l != 0.0 {
            let col = &ws.v[r * ncd..(r + 1) * ncd];
            for (u, vi) in ws.uc.iter_mut().zip(col) {
                *u += l * vi;
            }
            ws.rows[r].scatter(l, &mut ws.f_old);
        }
    }
}

/// Per-solve buffers.
struct Work {
    a: Vec<f64>,
    xa: Vec<f64>,
    uc: Vec<f64>,
    x: Vec<f64>,
    xm: Vec<[f64; 2]>,
    index: MasterIndex,
    pairs: Vec<Pair>,
    pairs_new: Vec<Pair>,
    rows: Vec<Row>,
    pidx: Vec<usize>,
    q: Vec<f64>,
    v: Vec<f64>,
    d: Vec<f64>,
    lam: Vec<f64>,
    g: Vec<f64>,
    act: Vec<bool>,
    /// First active-set guess per slave ([`SolveStart::active`]).
    act_first: Vec<bool>,
    lam_s: Vec<f64>,
    lam_s_new: Vec<f64>,
    f_old: Vec<f64>,
    f_new: Vec<f64>,
    /// Contact-dof displacement the current pairing was computed at.
    x_pair: Vec<f64>,
    /// Anderson-mixed next configuration.
    x_next: Vec<f64>,
    pairs_acc: Vec<Pair>,
    anderson: Anderson,
    lcp: LcpWork,
}

/// Where a solve starts. Production solves start cold ([`SolveStart::COLD`]); the other starts
/// exist to show that the returned state does not depend on the start (the vertex-zone rule,
/// [`super::vertex`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct SolveStart<'a> {
    /// A full displacement to pair the slaves at first (e.g. a neighbouring point's snapshot);
    /// `None`: the response without contact.
    pub u: Option<&'a [f64]>,
    /// The first active-set guess, one flag per slave; `None`: no slave active.
    pub active: Option<&'a [bool]>,
}

impl SolveStart<'_> {
    /// The cold start: no contact, empty active set.
    pub const COLD: SolveStart<'static> = SolveStart { u: None, active: None };

    fn is_cold(&self) -> bool {
        self.u.is_none() && self.active.is_none()
    }
}

/// How slaves near a master vertex are settled ([`super::vertex`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VertexRule {
    /// The vertex-zone rule on top of flip ties: the returned state does not depend on the
    /// start. What [`FactoredModel::solve`] uses.
    Zone,
    /// Flip ties only (the state depends on the iteration history; kept to measure the rule
    /// against).
    FlipTies,
    /// Plain closest point, no ties (does not converge where a slave flips).
    Off,
}

impl FactoredModel {
    /// Solve the contact problem at parameter `mu` (Hertz: approach `d`; ironing: travel `d_x`)
    /// from the cold start.
    pub fn solve(&self, mu: &[f64], p: &ContactSolveParams) -> Result<Snapshot, ContactError> {
        self.solve_with_rule(mu, p, &SolveStart::COLD, VertexRule::Zone)
    }

    /// [`Self::solve`] from another start; returns the same state (the vertex-zone rule).
    pub fn solve_from(&self, mu: &[f64], p: &ContactSolveParams, start: &SolveStart) -> Result<Snapshot, ContactError> {
        self.solve_with_rule(mu, p, start, VertexRule::Zone)
    }

    /// [`Self::solve_from`] with another [`VertexRule`] (to measure the rule against the
    /// alternatives; production solves use [`VertexRule::Zone`]).
    ///
    /// The vertex-zone rule: the first solve (from `start`) gives a state `S_0` and the tie set
    /// `T_1 = Z(S_0)`, where `Z(S)` is the set of slaves with pressure at `S` that are in a
    /// vertex zone or that the solve of `S` flip-tied (a slave without pressure is not
    /// constrained, whatever its pairing). Then `S_n = cold(T_n)` (the cold solve with `T_n` forced) and
    /// `T_{n+1} = T_n ∪ Z(S_n)`, until `T_{n+1} = T_n`; the state returned is that last `S_n`.
    /// The sequence is monotone, so it ends after at most `ns + 1` rounds, and a start enters
    /// only through `Z(S_0)`: the states a start can lead to differ only for slaves near a vertex,
    /// and those are in the zone whichever side they settled on (the zone is five times the
    /// widest such difference seen, see [`super::vertex::VERTEX_ZONE`]).
    pub fn solve_with_rule(
        &self,
        mu: &[f64],
        p: &ContactSolveParams,
        start: &SolveStart,
        rule: VertexRule,
    ) -> Result<Snapshot, ContactError> {
        if mu.len() != self.model.n_params() || mu.iter().any(|m| !m.is_finite()) {
            return Err(ContactError::BadParameter(Mu::of(mu)));
        }
        let ns = self.model.slaves.len();
        if start.u.is_some_and(|u| u.len() != self.model.n_dof()) || start.active.is_some_and(|a| a.len() != ns) {
            return Err(ContactError::BadParameter(Mu::of(mu)));
        }
        let mut ws = self.work(mu);
        let lift_inf =
            (0..self.lift[0].len()).fold(0.0f64, |acc, i| acc.max(affine(&self.lift[0], &self.lift[1..], mu, i).abs()));
        let mut ties = if rule == VertexRule::Off { VertexTies::disabled(ns) } else { VertexTies::new(ns) };
        let (mut iterations, mut c_scale) = self.active_set_loop(mu, p, start, lift_inf, &mut ws, &mut ties)?;
        let mut rounds = 0;
        if rule == VertexRule::Zone {
            let mut forced = vec![None; ns];
            let mut next = vec![None; ns];
            let mut cold = start.is_cold();
            loop {
                self.rule_ties(&mut ws, &ties, &mut next);
                // monotone: a slave once tied stays tied (to its first vertex)
                for (n, f) in next.iter_mut().zip(&forced) {
                    if f.is_some() {
                        *n = *f;
                    }
                }
                if cold && next == forced {
                    break;
                }
                // every round but the first adds a slave: at most ns + 1 rounds
                rounds += 1;
                std::mem::swap(&mut forced, &mut next);
                ties.force(&forced);
                cold = true;
                let (it, c) = self.active_set_loop(mu, p, &SolveStart::COLD, lift_inf, &mut ws, &mut ties)?;
                iterations += it;
                c_scale = c;
            }
        }
        Ok(self.finish(mu, &ws, lift_inf, c_scale, (iterations, rounds), &ties))
    }

    /// The vertex-zone rule's tie set `T(S)` of the state in `ws` (see [`Self::solve_with_rule`]).
    fn rule_ties(&self, ws: &mut Work, ties: &VertexTies, out: &mut [Option<usize>]) {
        self.deformed_positions(&ws.uc, &mut ws.x, &mut ws.xm);
        ws.index.build(&ws.xm);
        for (s, o) in out.iter_mut().enumerate() {
            *o = None;
            if self.slave_fixed[s] {
                continue;
            }
            if ws.lam_s[s] > 0.0 {
                *o = ties.rule_tie(s, [ws.x[2 * s], ws.x[2 * s + 1]], &ws.xm, &ws.index);
            }
        }
    }

    /// Buffers of one solve at `mu`.
    fn work(&self, mu: &[f64]) -> Work {
        let m = &self.model;
        let ns = m.slaves.len();
        let nm = m.masters.len();
        let ncd = 2 * (ns + nm);
        let mut ws = Work {
            a: (0..ncd).map(|i| affine(&self.a[0], &self.a[1..], mu, i)).collect(),
            xa: vec![0.0; ncd],
            uc: vec![0.0; ncd],
            x: vec![0.0; ncd],
            xm: vec![[0.0; 2]; nm],
            index: MasterIndex::default(),
            pairs: vec![Pair::NONE; ns],
            pairs_new: vec![Pair::NONE; ns],
            rows: vec![Row::default(); ns],
            pidx: Vec::with_capacity(ns),
            q: vec![0.0; ns],
            v: vec![0.0; ncd * ns],
            d: vec![0.0; ns * ns],
            lam: vec![0.0; ns],
            g: vec![0.0; ns],
            act: vec![false; ns],
            act_first: vec![false; ns],
            lam_s: vec![0.0; ns],
            lam_s_new: vec![0.0; ns],
            f_old: vec![0.0; ncd],
            f_new: vec![0.0; ncd],
            x_pair: vec![0.0; ncd],
            x_next: vec![0.0; ncd],
            pairs_acc: vec![Pair::NONE; ns],
            anderson: Anderson::new(ANDERSON_DEPTH, ncd),
            lcp: LcpWork::new(ns),
        };
        for (i, xa) in ws.xa.iter_mut().enumerate() {
            *xa = self.x_ref[i / 2][i % 2] + ws.a[i];
        }
        ws
    }

    /// The active-set loop with re-pairing (module docs) from `start`, with the ties `ties`
    /// (forced ones included); leaves the converged state in `ws` and returns the iterations and
    /// the complementarity scale.
    fn active_set_loop(
        &self,
        mu: &[f64],
        p: &ContactSolveParams,
        start: &SolveStart,
        lift_inf: f64,
        ws: &mut Work,
        ties: &mut VertexTies,
    ) -> Result<(usize, f64), ContactError> {
        let ns = self.model.slaves.len();
        let ncd = ws.uc.len();
        let tol = p.rel_tol;
        match start.u {
            Some(u) => {
                for (i, uc) in ws.uc.iter_mut().enumerate() {
                    *uc = u[2 * self.cnodes[i / 2] + i % 2];
                }
            }
            None => ws.uc.copy_from_slice(&ws.a),
        }
        ws.x_pair.copy_from_slice(&ws.uc);
        ws.lam_s.fill(0.0);
        ws.act_first.fill(false);
        if let Some(a) = start.active {
            ws.act_first.copy_from_slice(a);
        }
        ws.anderson.reset();
        let mut repairings = 0;
        self.pair_slaves(mu, &ws.uc, &mut ws.x, &mut ws.xm, &mut ws.index, ties, Some(repairings), &mut ws.pairs)?;
        repairings += 1;
        let mut iterations = 0;
        let mut first = true;
        let mut c_scale = 1.0;
        let mut last_eq = f64::INFINITY;
        loop {
            let (np, diag_sum) = self.condense(ws, ns, ncd);
            if np > 0 && diag_sum > 0.0 {
                c_scale = np as f64 / diag_sum;
            }
            let mut f_scale = 0.0f64;
            for (r, &s) in ws.pidx.iter().enumerate() {
                ws.act[r] = if first { ws.act_first[s] } else { ws.lam_s[s] > 0.0 };
                f_scale = f_scale.max(ws.lam_s[s]).max(-c_scale * ws.q[r]);
            }
            let lcp = Lcp { d: &ws.d[..np * np], q: &ws.q[..np], c: c_scale, eps: 0.01 * tol * f_scale };
            let budget = p.max_iter.saturating_sub(iterations).max(1);
            let out = solve_lcp(&lcp, &mut ws.act[..np], &mut ws.lam[..np], &mut ws.g[..np], &mut ws.lcp, budget)
                .map_err(|e| match e {
                    LcpError::NotPositiveDefinite(pivot) => ContactError::Singular { param: Mu::of(mu), pivot },
                    LcpError::Budget => ContactError::NoConvergence {
                        param: Mu::of(mu),
                        iterations: p.max_iter,
                        repairings,
                        residual: f64::INFINITY,
                    },
                })?;
            iterations += out.iterations;
            // new multipliers per slave; did the active set change?
            ws.lam_s_new.fill(0.0);
            let mut lam_new_inf = 0.0f64;
            for (r, &s) in ws.pidx.iter().enumerate() {
                ws.lam_s_new[s] = ws.lam[r];
                lam_new_inf = lam_new_inf.max(ws.lam[r]);
            }
            let active_same = !first && ws.lam_s.iter().zip(&ws.lam_s_new).all(|(a, b)| (*a > 0.0) == (*b > 0.0));
            std::mem::swap(&mut ws.lam_s, &mut ws.lam_s_new);
            update_displacement(ws, np, ncd);
            // --- re-pair in the deformed configuration ---
            self.pair_slaves(
                mu,
                &ws.uc,
                &mut ws.x,
                &mut ws.xm,
                &mut ws.index,
                ties,
                Some(repairings),
                &mut ws.pairs_new,
            )?;
            repairings += 1;
            let (eq, comp) = self.residuals(ws, ns, c_scale, (lam_new_inf, lift_inf));
            let same_pairing = ws.pairs.iter().zip(&ws.pairs_new).all(|(a, b)| a.kind == b.kind);
            if same_pairing && active_same && eq <= tol && comp <= tol {
                break;
            }
            if iterations >= p.max_iter {
                return Err(ContactError::NoConvergence {
                    param: Mu::of(mu),
                    iterations,
                    repairings,
                    residual: eq.max(comp),
                });
            }
            let smooth = same_pairing && active_same && eq < last_eq;
            last_eq = eq;
            self.next_pairing(mu, ws, ties, smooth)?;
            first = false;
        }
        Ok((iterations, c_scale))
    }

    /// The next pairing: the one at `u_c` (`pairs_new`), or, once the discrete state has
    /// settled (`smooth`: same pairing and active set, the equilibrium residual falling), the
    /// Anderson-mixed configuration's when it pairs every slave the same way.
    fn next_pairing(&self, mu: &[f64], ws: &mut Work, ties: &mut VertexTies, smooth: bool) -> Result<(), ContactError> {
        if smooth && ws.anderson.step(&ws.x_pair, &ws.uc, &mut ws.x_next) {
            self.pair_slaves(mu, &ws.x_next, &mut ws.x, &mut ws.xm, &mut ws.index, ties, None, &mut ws.pairs_acc)?;
            if ws.pairs_acc.iter().zip(&ws.pairs_new).all(|(a, b)| a.kind == b.kind) {
                std::mem::swap(&mut ws.pairs, &mut ws.pairs_acc);
                std::mem::swap(&mut ws.x_pair, &mut ws.x_next);
                return Ok(());
            }
        }
        if !smooth {
            ws.anderson.reset();
        }
        std::mem::swap(&mut ws.pairs, &mut ws.pairs_new);
        ws.x_pair.copy_from_slice(&ws.uc);
        Ok(())
    }

    /// The condensed LCP of the current pairing: the paired slaves (`pidx`), their rows `B_r`,
    /// `q_r = B_r x_a`, `V[:, r] = W B_r^T` and `D = B V` (rounding symmetrised). Returns the
    /// number of paired slaves and the trace of `D`.
    fn condense(&self, ws: &mut Work, ns: usize, ncd: usize) -> (usize, f64) {
        ws.pidx.clear();
        ws.pidx.extend((0..ns).filter(|&s| ws.pairs[s].kind.is_paired()));
        let np = ws.pidx.len();
        for (r, &s) in ws.pidx.iter().enumerate() {
            let row = Row::new(s, ns, &ws.pairs[s]);
            ws.rows[r] = row;
            ws.q[r] = row.apply(&ws.xa);
            // V[:, r] = W B_r^T
            let col = &mut ws.v[r * ncd..(r + 1) * ncd];
            col.fill(0.0);
            for j in 0..row.len {
                let wrow = &self.w[row.dof[j] * ncd..(row.dof[j] + 1) * ncd];
                let cj = row.coef[j];
                for (vi, wi) in col.iter_mut().zip(wrow) {
                    *vi += cj * wi;
                }
            }
        }
        let mut diag_sum = 0.0;
        for r in 0..np {
            for t in 0..np {
                ws.d[r * np + t] = ws.rows[r].apply(&ws.v[t * ncd..(t + 1) * ncd]);
            }
            diag_sum += ws.d[r * np + r];
        }
        // symmetrise rounding
        for r in 0..np {
            for t in 0..r {
                let s = 0.5 * (ws.d[r * np + t] + ws.d[t * np + r]);
                ws.d[r * np + t] = s;
                ws.d[t * np + r] = s;
            }
        }
        (np, diag_sum)
    }

    /// The residuals of the multipliers `lam_s` under the new pairing `pairs_new`: the
    /// equilibrium change `|f_new - f_old|_inf` on the free contact dofs over the force scale,
    /// and the complementarity `|min(lambda, c g)|_inf` over the larger of the largest new
    /// multiplier and the deepest scaled penetration (`scales`: that multiplier and the lift's
    /// force norm). A slave that lost its pairing but carries force shows up in `f_new - f_old`.
    fn residuals(&self, ws: &mut Work, ns: usize, c_scale: f64, (lam_new_inf, lift_inf): (f64, f64)) -> (f64, f64) {
        ws.f_new.fill(0.0);
        let mut comp = 0.0f64;
        let mut neg_gap = 0.0f64;
        for s in 0..ns {
            let pn = &ws.pairs_new[s];
            if pn.kind.is_paired() {
                let l = ws.lam_s[s];
                if l != 0.0 {
                    Row::new(s, ns, pn).scatter(l, &mut ws.f_new);
                }
                comp = comp.max(l.min(c_scale * pn.gap).abs());
                neg_gap = neg_gap.max(-c_scale * pn.gap);
            }
        }
        let mut eq = 0.0f64;
        let mut fnew_inf = 0.0f64;
        for (cd, free) in self.cfree.iter().enumerate() {
            if free.is_some() {
                eq = eq.max((ws.f_new[cd] - ws.f_old[cd]).abs());
                fnew_inf = fnew_inf.max(ws.f_new[cd].abs());
            }
        }
        let f_ref = residual_scale(fnew_inf, lift_inf);
        (eq / f_ref, comp / lam_new_inf.max(neg_gap).max(f64::MIN_POSITIVE))
    }

    /// Pair every slave at the contact-dof displacement `uc`. With `repairing = Some(k)` the
    /// natural pairings are recorded as re-pairing `k` (ties may form or be released) and a
    /// non-finite slave position is an error; with `None` only the existing ties are applied
    /// and nothing is recorded (the Anderson-mixed configuration).
    #[allow(clippy::too_many_arguments)]
    fn pair_slaves(
        &self,
        mu: &[f64],
        uc: &[f64],
        x: &mut [f64],
        xm: &mut [[f64; 2]],
        index: &mut MasterIndex,
        ties: &mut VertexTies,
        repairing: Option<usize>,
        out: &mut [Pair],
    ) -> Result<(), ContactError> {
        let ns = self.model.slaves.len();
        self.deformed_positions(uc, x, xm);
        index.build(xm);
        for s in 0..ns {
            if self.slave_fixed[s] {
                out[s] = Pair::NONE;
                continue;
            }
            let xs = [x[2 * s], x[2 * s + 1]];
            out[s] = match repairing {
                Some(k) => {
                    if !(xs[0].is_finite() && xs[1].is_finite()) {
                        return Err(ContactError::Pairing { param: Mu::of(mu), slave: s });
                    }
                    ties.pair(s, xs, xm, index, k)
                }
                None => ties.pair_peek(s, xs, xm, index),
            };
        }
        Ok(())
    }

    /// Deformed positions of the contact nodes (`x`, interleaved) and of the master nodes (`xm`)
    /// for the contact-dof displacement `uc`.
    fn deformed_positions(&self, uc: &[f64], x: &mut [f64], xm: &mut [[f64; 2]]) {
        let ns = self.model.slaves.len();
        for (i, xi) in x.iter_mut().enumerate() {
            *xi = self.x_ref[i / 2][i % 2] + uc[i];
        }
        for (k, xk) in xm.iter_mut().enumerate() {
            *xk = [x[2 * (ns + k)], x[2 * (ns + k) + 1]];
        }
    }

    /// Recover the full displacement with one sparse solve and compute the statistics.
    fn finish(
        &self,
        mu: &[f64],
        ws: &Work,
        lift_inf: f64,
        c_scale: f64,
        (iterations, vertex_rounds): (usize, usize),
        ties: &VertexTies,
    ) -> Snapshot {
        let m = &self.model;
        let ns = m.slaves.len();
        let nf = m.split.n_free();
        // u_F = u0 + sum_k mu_k u_k + K^{-1} E_c B^T lambda (B of the pairing u_c was computed with)
        let mut rhs = vec![0.0; nf];
        for (cd, free) in self.cfree.iter().enumerate() {
            if let Some(fi) = free {
                rhs[*fi] = ws.f_old[cd];
            }
        }
        self.solve_free_in_place(&mut rhs);
        let mut u = m.split.contact_free(&m.u_d, &self.resp, mu);
        for (fi, &d) in m.split.free().iter().enumerate() {
            u[d] += rhs[fi];
        }
        // gaps of the final pairing from the recovered displacement (contact-dof positions)
        let xc: Vec<f64> =
            (0..self.cnodes.len() * 2).map(|i| self.x_ref[i / 2][i % 2] + u[2 * self.cnodes[i / 2] + i % 2]).collect();
        let mut fc = vec![0.0; xc.len()];
        let (mut max_pen, mut comp, mut neg_gap, mut lam_inf) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut active = 0;
        for s in 0..ns {
            let pr = &ws.pairs_new[s];
            let l = ws.lam_s[s];
            lam_inf = lam_inf.max(l);
            if l > 0.0 {
                active += 1;
            }
            if !pr.kind.is_paired() {
                continue;
            }
            let row = Row::new(s, ns, pr);
            let gap = row.apply(&xc);
            max_pen = max_pen.max(-gap);
            comp = comp.max(l.min(c_scale * gap).abs());
            neg_gap = neg_gap.max(-c_scale * gap);
            row.scatter(l, &mut fc);
        }
        let mut f_new = vec![0.0; m.n_dof()];
        for (i, f) in fc.iter().enumerate() {
            f_new[2 * self.cnodes[i / 2] + i % 2] += f;
        }
        let ku = m.k.matvec(&u);
        // Backward error of the recovered displacement: the residual against the forces it is
        // made of, the contact forces and the row sums |K| |u| (the size of the round-off in
        // evaluating K u at all; a stiff body's rigid travel makes it large, module docs).
        let (mut res, mut f_inf, mut ku_abs) = (0.0f64, 0.0f64, 0.0f64);
        for &d in m.split.free() {
            res = res.max((ku[d] - f_new[d]).abs());
            f_inf = f_inf.max(f_new[d].abs());
            let (cols, vals) = m.k.row(d);
            let row: f64 = cols.iter().zip(vals).map(|(&c, &v)| (v * u[c]).abs()).sum();
            ku_abs = ku_abs.max(row + f_new[d].abs());
        }
        let kkt = res / residual_scale(f_inf, lift_inf).max(ku_abs);
        let pressure: Vec<f64> = ws.lam_s.iter().zip(&m.tributary).map(|(l, t)| l / t).collect();
        let min_lambda = pressure.iter().copied().fold(f64::INFINITY, f64::min);
        let geo = self.check_geometry_with(&u, &ku, &pressure);
        let vertex_nodes: Vec<String> = (0..ns).filter_map(|s| ties.tied(s).map(|v| format!("{s}:{v}"))).collect();
        Snapshot {
            u,
            stats: SolveStats {
                iterations,
                active,
                max_penetration: max_pen.max(0.0),
                min_lambda: if ns == 0 { 0.0 } else { min_lambda },
                complementarity: comp / lam_inf.max(neg_gap).max(f64::MIN_POSITIVE),
                kkt_residual: kkt,
                vertex_ties: vertex_nodes.len(),
                vertex_nodes: vertex_nodes.join(" "),
                vertex_rounds,
                min_gap: geo.min_gap,
                active_gap: geo.active_gap,
                cone_angle: geo.cone_angle,
            },
            pressure,
        }
    }
}
