//! Replacing the dual basis of a model per query ([`ReducedModel::set_dual`]), and the gaps over
//! the whole surface that a growing dual basis checks its candidates against
//! ([`ReducedModel::node_gaps`]).

use super::build::{csr_into, reduce_fixed};
use super::linearise::set_positions;
use super::{ReducedModel, RomWork, SurfaceData, WarmStarts};
use crate::contact::pairing::GapRow;
use crate::mu::affine;
use crate::rom::la::dot;

impl ReducedModel {
    /// Replace the dual basis by `theta` (`n_contact x r_l`, column-major, non-negative) and
    /// keep the primal part: what a dual basis that depends on the parameter (a registered or a
    /// local one, `crom_stages::dual`) needs per query. Costs `O(n_contact r_l)` for a Type-2
    /// problem (the sparse layouts and the supported slaves), `O(nnz(theta) r_u)` for Type-1
    /// (`Ĉ` and `ĝ0`'s terms); no `n_dof` work. A sampled surface's quadrature, fitted to the old
    /// basis, is dropped (2-D and 3-D alike): the constraints sum over the new basis's support.
    pub fn set_dual(&mut self, theta: &[f64], r_l: usize) {
        let nc = self.n_contact;
        assert_eq!(theta.len(), nc * r_l, "theta shape");
        csr_into(theta, nc, r_l, &mut self.by_node, &mut self.by_col);
        let (r_u, by_node) = (self.r_u, &self.by_node);
        match &mut self.surf {
            SurfaceData::Fixed { cphi, cu0, chat, ghat, .. } => {
                chat.clear();
                chat.resize(r_l * r_u, 0.0);
                *ghat = vec![vec![0.0; r_l]; cu0.len()];
                reduce_fixed(by_node, &self.weights, r_u, cphi, cu0, chat, ghat);
            }
            SurfaceData::Nts3(d) => {
                // as in 2-D: a quadrature was fitted to the old basis, and the support is new
                d.supp = d.support(&by_node.0);
                d.quad = None;
            }
            SurfaceData::Nts { ns, slave_fixed, supp, quad, .. } => {
                supp.clear();
                supp.extend((0..*ns).filter(|&s| !slave_fixed[s] && by_node.0[s + 1] > by_node.0[s]));
                *quad = None;
            }
        }
        self.r_l = r_l;
        // the samples' active sets index the old dual basis; their answers `y` are still
        // starting points of a re-pairing (a Type-1 library keeps nothing)
        if self.warm_starts.ys.is_empty() {
            self.warm_starts = WarmStarts::default();
        } else {
            self.warm_starts.sets.iter_mut().for_each(Vec::clear);
        }
    }

    /// The gap of every paired potential-contact node at the solution in `w` (after
    /// [`Self::solve_in`] with the same `w` and `mu`), as `(node, gap)`, over every node of the
    /// surface — not only the support of the dual basis: Type-2 positions and pairs every
    /// non-fixed slave with the solver's rule (as [`Self::indicator`] does). Unpaired nodes carry
    /// no constraint and are left out. What a dual basis that grows (the dictionary's working
    /// set, `crom_stages::rom::working_set`) checks its candidates against.
    pub fn node_gaps(&self, mu: &[f64], w: &mut RomWork, out: &mut Vec<(usize, f64)>) {
        out.clear();
        let ru = self.r_u;
        match &self.surf {
            SurfaceData::Nts3(d) => self.node_gaps3(d, w, out),
            SurfaceData::Fixed { cphi, cu0, paired, .. } => {
                for (i, &p) in paired.iter().enumerate() {
                    if p {
                        out.push((i, dot(&cphi[i * ru..(i + 1) * ru], &w.u_hat) + affine(&cu0[0], &cu0[1..], mu, i)));
                    }
                }
            }
            SurfaceData::Nts { ns, nm, slave_fixed, phi_c, .. } => {
                let (ns, nm) = (*ns, *nm);
                let l = &mut w.lin;
                let slaves = || (0..ns).filter(|&s| !slave_fixed[s]);
                set_positions(phi_c, ru, &w.u_hat, &l.base, &mut l.xc, slaves().chain(ns..ns + nm));
                l.index_masters(ns, nm);
                for s in slaves() {
                    let xs = [l.xc[2 * s], l.xc[2 * s + 1]];
                    let pr = l.ties.pair_peek(s, xs, &l.xm, &l.index);
                    if pr.kind.is_paired() {
                        out.push((s, GapRow::new(s, ns, &pr).apply(&l.xc)));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use faer::MatRef;

    use crate::rom::reduced::test_support::{coarse_mus, full_rom, points};
    use crate::rom::{ContactOperator, ReducedModel, RomOutcome, RomParams, RomWork};
    use crate::testing::{hertz, ironing_coarse};

    /// The dictionary's working set reaches the solution of the reduced problem over all atoms
    /// (ironing-coarse, 17 training pressures as atoms, a working set starting from 1): the
    /// same û at every test point to 1e-8 relative (both stop at the re-linearisation's
    /// tolerance, 1e-10, and û is unique: the reduced QP is strictly convex in û), and the
    /// check adds atoms at some point (it is exercised, not vacuous).
    #[test]
    fn dictionary_working_set_equals_all_atoms() {
        use crate::rom::working_set::{WorkingSet, WorkingSetScratch};
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (all, phi, snaps) = full_rom(fm, &mus);
        let nc = fm.n_contact();
        let ru = all.ranks().0;
        let duals: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
        let params = points(&mus);
        let ws = WorkingSet::new(MatRef::from_column_major_slice(&duals, nc, mus.len()), &params, fm.weights(), 1);
        let atoms: Vec<f64> = snaps
            .iter()
            .flat_map(|s| {
                let n = s.pressure.iter().map(|v| v * v).sum::<f64>().sqrt();
                s.pressure.iter().map(move |v| v / n).collect::<Vec<_>>()
            })
            .collect();
        let mut every = ReducedModel::new(fm, &phi, ru, &atoms, mus.len()).expect("all atoms");
        let mut small = every.clone();
        every.set_dual(&atoms, mus.len());
        let (mut w, mut sc) = (RomWork::default(), WorkingSetScratch::default());
        let mut grew = 0;
        for k in 0..16 {
            let d = 3.0 * (k as f64 + 0.5) / 16.0;
            let full = every.solve(&[d], &RomParams::default(), &mut w);
            let out = ws.solve(&mut small, &[d], &RomParams::default(), &mut w, &mut sc);
            assert_eq!(out.info.outcome, RomOutcome::Converged, "d {d}");
            let got = w.solution(&out.info);
            let norm = full.u_hat.iter().map(|v| v * v).sum::<f64>().sqrt();
            for (a, b) in got.u_hat.iter().zip(&full.u_hat) {
                assert!((a - b).abs() <= 1e-8 * norm, "d {d}: {a} vs {b}");
            }
            grew += usize::from(out.rounds > 1);
        }
        assert!(grew > 0, "the check never added an atom");
    }

    /// `set_dual` with another dual basis answers exactly like a model built with it from
    /// scratch (hertz, Type-2; the same arithmetic on the same rows, so bit for bit).
    #[test]
    fn set_dual_equals_a_fresh_model_on_hertz() {
        let fm = hertz();
        let mus = [0.05, 0.1, 0.15, 0.2, 0.25];
        let (rom, phi, _) = full_rom(fm, &mus);
        let (ru, rl) = rom.ranks();
        let nc = fm.n_contact();
        // The generators in reverse order, the last one dropped.
        let mut cols: Vec<f64> = Vec::new();
        for a in (1..rl).rev() {
            let mut unit = vec![0.0; rl];
            unit[a] = 1.0;
            cols.extend(rom.pressure(&unit));
        }
        let fresh = ReducedModel::new(fm, &phi, ru, &cols, rl - 1).expect("fresh");
        let mut swapped = rom.clone();
        swapped.set_dual(&cols, rl - 1);
        assert_eq!(swapped.ranks(), (ru, rl - 1));
        assert_eq!(cols.len(), nc * (rl - 1));
        let mut w = RomWork::default();
        for d in [0.07, 0.18, 0.3] {
            let (a, b) =
                (swapped.solve(&[d], &RomParams::default(), &mut w), fresh.solve(&[d], &RomParams::default(), &mut w));
            assert_eq!(a.outcome, b.outcome, "d {d}");
            assert_eq!(a.u_hat, b.u_hat, "d {d}");
            assert_eq!(a.lambda_hat, b.lambda_hat, "d {d}");
        }
    }
}
