//! The paper's Algorithm 1: one saddle-point solve per iteration on the active reduced
//! constraints, drop negative multipliers, add violated constraints, re-linearise.

use super::oracle::Oracle;
use super::{ReducedModel, RomOutcome, RomParams, RomWork, SurfaceData};
use crate::contact::pairing::PairKind;
use crate::rom::la::Factor;
use crate::rom::qp::QpConstraints;
use crate::rom::saddle::solve_saddle;

/// A discrete state of the paper's algorithm: the active-set mask and every slave's pairing.
type PaperState = (Vec<bool>, Vec<PairKind>);

/// FNV-1a of an active-set mask, continued from a pairing hash.
fn state_hash(mask: &[bool], pairing: u64) -> u64 {
    mask.iter().fold(pairing, |h, &m| (h ^ u64::from(m)).wrapping_mul(0x0000_0100_0000_01b3))
}

/// Relative size below which a negative multiplier of the paper's algorithm counts as zero: the
/// full-order snapshots the bases come from are KKT points to 1e-10 relative
/// (`ContactSolveParams::rel_tol`), so smaller multipliers carry no information.
const PAPER_LAM_TOL: f64 = 1e-10;

impl ReducedModel {
    /// Algorithm 1 from `y = 0`: returns the iterations, the active reduced constraints at the
    /// end and how it ended.
    pub(super) fn solve_paper(&self, p: &RomParams, w: &mut RomWork) -> (usize, usize, RomOutcome) {
        let (ru, rl) = (self.r_u, self.r_l);
        self.linearize(w);
        let scale = self.offset_scale(w);
        let violated = |g: f64| g < -p.gap_tol * scale;
        // deterministic start: the most violated reduced constraint at û = 0
        let start = (0..rl).filter(|&a| violated(w.s[a])).min_by(|&a, &b| w.s[a].total_cmp(&w.s[b]));
        let Some(first) = start else {
            return (0, 0, RomOutcome::Converged);
        };
        let mut mask = vec![false; rl];
        mask[first] = true;
        let mut history: Vec<(u64, PaperState)> = Vec::new();
        let (mut c_a, mut g_a, mut lam_a, mut work, mut row) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), vec![0.0; ru]);
        // the active constraints' indices and the next mask, refilled each iteration
        let (mut idx, mut new): (Vec<usize>, Vec<bool>) = (Vec::with_capacity(rl), Vec::with_capacity(rl));
        let mut prev = vec![0.0; ru];
        let repairs = matches!(self.surf, SurfaceData::Nts { .. } | SurfaceData::Nts3(_));
        for it in 1..=p.max_iter {
            prev.copy_from_slice(&w.u_hat);
            // offsets ĝ0 at the current linearisation, rows of the active constraints
            self.offsets(w);
            c_a.clear();
            g_a.clear();
            idx.clear();
            idx.extend((0..rl).filter(|&a| mask[a]));
            for &a in &idx {
                let RomWork { lin, .. } = w;
                Oracle { m: self, lin }.row(a, &mut row);
                c_a.extend_from_slice(&row);
                g_a.push(w.s[a]);
            }
            lam_a.clear();
            lam_a.resize(idx.len(), 0.0);
            solve_saddle(Factor::Identity, ru, &c_a, &g_a, &mut w.u_hat, &mut lam_a, &mut work);
            w.lam.iter_mut().for_each(|x| *x = 0.0);
            for (k, &a) in idx.iter().enumerate() {
                w.lam[a] = lam_a[k];
            }
            let changed = self.linearize(w);
            {
                let RomWork { lin, s, u_hat, .. } = w;
                Oracle { m: self, lin }.values(u_hat, s);
            }
            // a multiplier counts as negative below -PAPER_LAM_TOL of the largest one: an exact
            // sign test cycles on degenerate constraints (zero gap, multiplier zero up to
            // rounding; measured -6e-12 relative on hertz with full bases)
            let lam_tol = PAPER_LAM_TOL * w.lam.iter().fold(0.0f64, |m, l| m.max(l.abs()));
            new.clear();
            new.extend((0..rl).map(|a| if mask[a] { w.lam[a] >= -lam_tol } else { violated(w.s[a]) }));
            let settled = new == mask && !changed;
            let du = w.u_hat.iter().zip(&prev).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
            let un = w.u_hat.iter().map(|a| a * a).sum::<f64>().sqrt();
            let moved = repairs && du > p.u_tol * un;
            let active = mask.iter().filter(|m| **m).count();
            if settled && !moved {
                return (it, active, RomOutcome::Converged);
            }
            if settled {
                continue;
            }
            // a repeated (active set, pairing) state cycles; states are compared through their
            // hash first (O(1) per earlier state instead of O(r_l + n_s)), then in full
            let state = (new.clone(), w.lin.pairs.iter().map(|p| p.kind).collect::<Vec<_>>());
            let h = state_hash(&state.0, w.lin.pairing_hash());
            if history.iter().any(|(hh, st)| *hh == h && *st == state) {
                return (it, active, RomOutcome::Cycled);
            }
            history.push((h, state));
            std::mem::swap(&mut mask, &mut new);
        }
        (p.max_iter, mask.iter().filter(|m| **m).count(), RomOutcome::NotConverged)
    }
}
