//! The online solve's contact surface in 3-D ([`Nts3`]): node-to-surface pairs between slave
//! nodes and a master surface of bilinear facets, paired at each linearisation with the
//! full-order solver's own rule (`crate::contact3d::surface`, stateless: no ties, no history).
//!
//! A linearisation places the supported slaves and every master at `y`,
//! `x_c = X_c + u0_c(mu) + Psi_c y` (three rows of `Psi_c` per node), indexes the masters' deformed positions in a facet grid, pairs
//! each supported slave and builds its gap row `g = n . (x_s - sum_a w_a x_a)` with the pair's
//! normal and weights frozen: `C Psi` is the row combined with `Psi_c`, the constant part the
//! row applied to `X_c + u0_c(mu)`. Everything after (the rows summed under the dual basis, the
//! QP, the re-pairing loop) is the 2-D node-to-segment path's. A slave whose last search's
//! proof still decides its pair is paired without a search ([`ReducedModel::linearize3`]), the
//! first linearisation with the proofs of the nearest warm-start sample
//! ([`super::WarmStarts::locate3`]), and a search measures the slave's last located facet first
//! (its hint); the 2-D
//! path's vertex-zone rule (3-D has no ties) and Newton correction for the gaps' curvature
//! (first-order re-pairing steps) are not used. Its cost per linearisation: the searches that
//! are not proved, a projection per supported slave, `O((n_s + n_m) r_u)` for the positions.

use super::{ReducedModel, RomWork};
use crate::contact3d::surface::{FacetGrid, MasterSurface, Pair3, ONLINE_REACH};
use crate::rom::la::dot;

/// `|a - b|` (infinite when either is not finite: a slave placed for the first time).
fn norm3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if n.is_finite() {
        n
    } else {
        f64::INFINITY
    }
}

/// The 3-D contact surface's offline data.
#[derive(Debug, Clone)]
pub(super) struct Nts3 {
    pub ns: usize,
    pub nm: usize,
    /// Reference positions of the contact nodes (slaves, then masters).
    pub x_ref: Vec<[f64; 3]>,
    pub slave_fixed: Vec<bool>,
    /// The master surface (facets over master-local ids, normal field, symmetry planes).
    pub master: MasterSurface,
    /// `Psi` on the contact dofs (`3 c + j`), row-major `3 nn x r_u`.
    pub phi_c: Vec<f64>,
    /// Affine terms of the lift on the contact dofs.
    pub a_terms: Vec<Vec<f64>>,
    /// Non-fixed slaves in the support of `Theta[:, :r_l]` (a sampled surface: the
    /// quadrature's slaves only).
    pub supp: Vec<usize>,
    /// A sampled surface's quadrature weights by slave ([`ReducedModel::with_sampled_surface`]);
    /// `None`: every supported slave with its tributary area.
    pub quad: Option<Vec<f64>>,
    /// The compliance on the contact dofs (row-major `(3 nn)²`) for the indicator's
    /// equilibrium residual; `None` when it was too large to keep (the residual is then NaN).
    pub w_c: Option<Vec<f64>>,
}

/// The largest contact-dof compliance a model keeps for its indicator (entries): 4M, 32 MB.
pub(super) const MAX_W_C: usize = 1 << 22;

impl Nts3 {
    /// The slaves in the support of the dual basis whose CSR-by-node row starts are `starts`,
    /// not fixed.
    pub(super) fn support(&self, starts: &[usize]) -> Vec<usize> {
        (0..self.ns).filter(|&s| !self.slave_fixed[s] && starts[s + 1] > starts[s]).collect()
    }

    /// `Psi_c` restricted to the leading `r` of its `r_u` columns.
    pub(super) fn leading(&self, r_u: usize, r: usize, starts: &[usize]) -> Self {
        let rows = self.phi_c.len() / r_u.max(1);
        let phi_c = (0..rows).flat_map(|i| self.phi_c[i * r_u..i * r_u + r].to_vec()).collect();
        let mut out = Self { phi_c, quad: None, ..self.clone() };
        out.supp = out.support(starts);
        out
    }
}

impl ReducedModel {
    /// Positions at `w.u_hat` of the slaves `slaves` and of every master into `w.lin.xc` (3 per
    /// node), and the masters' into `w.lin.xm3`.
    fn place3(&self, d: &Nts3, w: &mut RomWork, slaves: impl Iterator<Item = usize>) {
        let (ru, l) = (self.r_u, &mut w.lin);
        let zero = w.u_hat.iter().all(|&v| v == 0.0);
        for c in slaves.chain(d.ns..d.ns + d.nm) {
            for cd in 3 * c..3 * c + 3 {
                let m = if zero { 0.0 } else { dot(&d.phi_c[cd * ru..(cd + 1) * ru], &w.u_hat) };
                l.xc[cd] = l.base[cd] + m;
            }
        }
        l.xm3.clear();
        l.xm3.extend((d.ns..d.ns + d.nm).map(|c| [l.xc[3 * c], l.xc[3 * c + 1], l.xc[3 * c + 2]]));
    }

    /// Slave `s`'s position in `xc` (3 per contact node), or `None` for a slave that is fixed or
    /// placed at a non-finite position (it is unpaired).
    fn pairable(d: &Nts3, xc: &[f64], s: usize) -> Option<[f64; 3]> {
        let xs = [xc[3 * s], xc[3 * s + 1], xc[3 * s + 2]];
        (!d.slave_fixed[s] && xs.iter().all(|v| v.is_finite())).then_some(xs)
    }

    /// The pair of slave `s` at the positions in `w.lin` ([`Self::pairable`]).
    fn pair3(d: &Nts3, grid: &mut FacetGrid, w: &RomWork, s: usize) -> Pair3 {
        let l = &w.lin;
        Self::pairable(d, &l.xc, s).map_or(Pair3::UNPAIRED, |xs| grid.pair(&d.master, &l.xm3, xs))
    }

    /// Type-2 in 3-D ([`Self::linearize_with`]): place every contact node, re-pair every
    /// supported slave, rebuild the gap rows if `assemble`; whether a pairing changed other
    /// than continuously ([`Pair3::continues`]: a feature renamed across a shared node is not a
    /// change).
    ///
    /// A slave whose last search's proof still decides its pair ([`FacetGrid::pair_near`]: the
    /// facets near the located one measured again, every other one proved farther) is paired
    /// without a search, the search's answer bit for bit: the distance it and the masters moved
    /// since is bounded by the sum, over the linearisations since, of its own displacement and
    /// the largest master displacement. Its searches keep a near set ([`ONLINE_REACH`]).
    pub(super) fn linearize3(&self, d: &Nts3, w: &mut RomWork, assemble: bool) -> bool {
        // the supported slaves only: the others are neither paired nor in a row
        self.place3(d, w, d.supp.iter().copied());
        let mut grid = FacetGrid::new(&d.master, &w.lin.xm3);
        let l = &mut w.lin;
        // the largest master displacement since the last linearisation (none before the first)
        let masters_moved = if l.xm3_prev.len() == l.xm3.len() {
            l.xm3.iter().zip(&l.xm3_prev).map(|(a, b)| norm3(a, b)).fold(0.0, f64::max)
        } else {
            f64::INFINITY
        };
        let mut changed = false;
        for &s in &d.supp {
            let p = match Self::pairable(d, &l.xc, s) {
                None => {
                    // no certificate survives: the next pairing searches
                    l.located3[s] = None;
                    Pair3::UNPAIRED
                }
                Some(xs) => {
                    l.moved3[s] += norm3(&xs, &l.last3[s]) + masters_moved;
                    l.last3[s] = xs;
                    let proved = l.located3[s].and_then(|at| grid.pair_near(&d.master, &l.xm3, xs, &at, l.moved3[s]));
                    match proved {
                        Some(p) => p,
                        None => {
                            // the last located facet (or the sample's) is likely near: measured first
                            let hint = l.located3[s].map(|at| at.facet);
                            let (p, at) = grid.pair_located(&d.master, &l.xm3, xs, hint, ONLINE_REACH);
                            l.located3[s] = at;
                            l.moved3[s] = 0.0;
                            p
                        }
                    }
                }
            };
            // a feature renamed across a shared node moves the row continuously: not a change
            // of the pairing the re-pairing's contraction estimate must restart after
            changed |= !p.continues(&l.pairs3[s]);
            l.pairs3[s] = p;
        }
        l.xm3_prev.clear();
        l.xm3_prev.extend_from_slice(&l.xm3);
        l.count += 1;
        l.fresh = false;
        if assemble {
            self.assemble3(d, w);
        }
        changed
    }

    /// The gap rows of the paired supported slaves (`cphi`, `g0`), then, for a small dual
    /// basis, the reduced rows summed ([`Self::sum_rows`]).
    fn assemble3(&self, d: &Nts3, w: &mut RomWork) {
        let ru = self.r_u;
        let l = &mut w.lin;
        l.ps.clear();
        l.g0.clear();
        for &s in &d.supp {
            l.ps_of[s] = usize::MAX;
            let p = l.pairs3[s];
            if !p.is_paired() {
                continue;
            }
            let at = l.ps.len() * ru;
            l.ps_of[s] = l.ps.len();
            l.ps.push(s);
            if l.cphi.len() < at + ru {
                l.cphi.resize(at + ru, 0.0);
            }
            let row = &mut l.cphi[at..at + ru];
            row.iter_mut().for_each(|v| *v = 0.0);
            let mut g0 = 0.0;
            for (cd, c) in p.row(s, d.ns) {
                for (o, v) in row.iter_mut().zip(&d.phi_c[cd * ru..(cd + 1) * ru]) {
                    *o += c * v;
                }
                g0 += c * l.base[cd];
            }
            l.g0.push(g0);
        }
        self.sum_rows(w);
    }

    /// The indicator's surface terms in 3-D: over every non-fixed slave paired at the answer,
    /// (total force, penetration, force-weighted `|g|` sum, unpaired force), `Psi_c^T F` into
    /// `phit_f` and `F^T W F` (NaN without a stored compliance).
    pub(super) fn indicator3(&self, d: &Nts3, w: &mut RomWork, phit_f: &mut [f64]) -> (f64, f64, f64, f64, f64) {
        let ru = self.r_u;
        self.place3(d, w, 0..d.ns);
        let mut grid = FacetGrid::new(&d.master, &w.lin.xm3);
        let ncd = w.lin.xc.len();
        let mut fc = std::mem::take(&mut w.lin.fc);
        fc.clear();
        fc.resize(ncd, 0.0);
        let (mut force, mut pen, mut comp, mut unpaired) = (0.0, 0.0f64, 0.0, 0.0);
        for s in (0..d.ns).filter(|&s| !d.slave_fixed[s]) {
            let p = Self::pair3(d, &mut grid, w, s);
            let f = self.weights[s] * self.pressure_at(s, &w.lam);
            force += f;
            if !p.is_paired() {
                unpaired += f;
                continue;
            }
            let g: f64 = p.row(s, d.ns).map(|(cd, c)| c * w.lin.xc[cd]).sum();
            pen = pen.max(-g);
            comp += f * g.abs();
            if f != 0.0 {
                for (cd, c) in p.row(s, d.ns) {
                    fc[cd] += f * c;
                    for (o, v) in phit_f.iter_mut().zip(&d.phi_c[cd * ru..(cd + 1) * ru]) {
                        *o += f * c * v;
                    }
                }
            }
        }
        let fww = match &d.w_c {
            Some(w_c) => {
                let nz: Vec<usize> = (0..ncd).filter(|&i| fc[i] != 0.0).collect();
                nz.iter().map(|&i| nz.iter().map(|&j| fc[i] * fc[j] * w_c[i * ncd + j]).sum::<f64>()).sum()
            }
            None => f64::NAN,
        };
        w.lin.fc = fc;
        (force, pen, comp, unpaired, fww)
    }

    /// [`Self::node_gaps`] in 3-D: the gap of every non-fixed slave paired at the answer.
    pub(super) fn node_gaps3(&self, d: &Nts3, w: &mut RomWork, out: &mut Vec<(usize, f64)>) {
        self.place3(d, w, 0..d.ns);
        let mut grid = FacetGrid::new(&d.master, &w.lin.xm3);
        for s in (0..d.ns).filter(|&s| !d.slave_fixed[s]) {
            let p = Self::pair3(d, &mut grid, w, s);
            if p.is_paired() {
                out.push((s, p.row(s, d.ns).map(|(cd, c)| c * w.lin.xc[cd]).sum()));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use faer::MatRef;

    use crate::basis::pod_full;
    use crate::contact::ContactSolveParams;
    use crate::contact3d::tests::{hertz_params, ironing_params};
    use crate::contact3d::{build_hertz3d, build_ironing3d, Factored3d};
    use crate::rom::reduced::test_support::{assert_round_trip, columns};
    use crate::rom::reduced::SurfaceData;
    use crate::rom::{Algorithm, ContactOperator, ReducedModel, RomOutcome, RomParams, RomWork};
    use crate::snapshot::Snapshot;

    /// Full bases of the training points `mus`: the POD of the contact responses `u - u0(mu)`
    /// and the training pressures themselves as the dual basis (non-negative); the model, the
    /// primal basis and the snapshots.
    fn full_rom3(f: &Factored3d, mus: &[f64]) -> (ReducedModel, Vec<f64>, Vec<Snapshot>) {
        let snaps: Vec<Snapshot> =
            mus.iter().map(|&d| f.solve(&[d], &ContactSolveParams::default()).expect("solve")).collect();
        let n = f.n_dof();
        let responses: Vec<f64> = mus
            .iter()
            .zip(&snaps)
            .flat_map(|(&d, s)| s.u.iter().zip(f.lift(&[d])).map(|(a, b)| a - b).collect::<Vec<_>>())
            .collect();
        let phi = pod_full(MatRef::from_column_major_slice(&responses, n, mus.len())).expect("pod");
        let theta: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
        let ru = phi.modes.ncols();
        assert_eq!(ru, mus.len(), "independent training responses");
        let phi = columns(phi.modes.as_ref());
        let rom = ReducedModel::new(f, &phi, ru, &theta, mus.len()).expect("K̂ SPD");
        (rom, phi, snaps)
    }

    /// The reduced solve with full bases at a training point has the full-order solution as its
    /// solution: `u - u0` is in the primal span and the pressure is a dual basis vector, the
    /// full-order KKT conditions (equilibrium, gaps >= 0, complementarity under non-negative
    /// `Theta`) are the reduced ones at the same pairing, and the reduced QP is strictly convex.
    /// So on a small hertz-3d (8 elements a side) and a small ironing-3d (the die sliding over
    /// 0.1 .. 0.5), at every training point the exact solve converges and its displacement and
    /// pressure equal the full-order ones to 1e-9 relative (H1 and Euclidean): both solves stop
    /// at re-linearisation tolerances of 1e-10 (measured: at most 1.5e-10). The paper's
    /// Algorithm 1 reaches the same answer where it converges, which it does at 3 of the 5
    /// hertz points and at every ironing point (measured), and cycles between active sets
    /// elsewhere (it adds and drops one constraint per iteration; a cycle is reported, never a
    /// wrong answer). The stored model reads back with the same bits, and the indicator sees no
    /// penetration beyond 1e-9 of the approach.
    #[test]
    fn full_bases_reproduce_the_training_solves_in_3d() {
        let hertz = build_hertz3d(&hertz_params(8, 3.0)).expect("hertz").factor().expect("factor");
        let ironing = build_ironing3d(&ironing_params()).expect("ironing").factor().expect("factor");
        let cases: [(&Factored3d, Vec<f64>); 2] =
            [(&hertz, vec![0.004, 0.008, 0.012, 0.016, 0.02]), (&ironing, vec![0.1, 0.2, 0.3, 0.4, 0.5])];
        for (f, mus) in cases {
            let (rom, phi, snaps) = full_rom3(f, &mus);
            let mut w = RomWork::default();
            let mut paper_converged = 0;
            for algorithm in [Algorithm::Exact, Algorithm::Paper] {
                let p = RomParams { algorithm, ..RomParams::default() };
                for (&mu, s) in mus.iter().zip(&snaps) {
                    let r = rom.solve(&[mu], &p, &mut w);
                    match (algorithm, r.outcome) {
                        (_, RomOutcome::Converged) => paper_converged += usize::from(algorithm == Algorithm::Paper),
                        (Algorithm::Paper, RomOutcome::Cycled) => continue,
                        (_, other) => panic!("{algorithm:?} at {mu}: {other:?}"),
                    }
                    let u = ReducedModel::displacement(f, &phi, &[mu], &r.u_hat);
                    let diff: Vec<f64> = u.iter().zip(&s.u).map(|(a, b)| a - b).collect();
                    let eu = (f.primal_norm_sq(&diff) / f.primal_norm_sq(&s.u)).sqrt();
                    let p_rom = rom.pressure(&r.lambda_hat);
                    let norm = s.pressure.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let ep = p_rom.iter().zip(&s.pressure).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / norm;
                    assert!(eu <= 1e-9 && ep <= 1e-9, "{algorithm:?} at {mu}: H1 {eu:e}, pressure {ep:e}");
                    let ind = rom.indicator(&[mu], &mut w);
                    assert!(ind.penetration <= 1e-9 * mu, "{algorithm:?} at {mu}: {ind:?}");
                }
            }
            assert!(2 * paper_converged > mus.len(), "Algorithm 1 converged at {paper_converged} points");
            let at: Vec<Vec<f64>> = mus.iter().map(|&m| vec![m]).collect();
            assert_round_trip(&rom, &at);
        }
    }

    /// A small hertz-3d (8 elements a side) and a small ironing-3d, factored, each with 5
    /// training points and 4 points between them.
    fn small_models() -> [(Factored3d, [f64; 5], [f64; 4]); 2] {
        let hertz = build_hertz3d(&hertz_params(8, 3.0)).expect("hertz").factor().expect("factor");
        let ironing = build_ironing3d(&ironing_params()).expect("ironing").factor().expect("factor");
        [
            (hertz, [0.004, 0.008, 0.012, 0.016, 0.02], [0.005, 0.009, 0.013, 0.019]),
            (ironing, [0.1, 0.2, 0.3, 0.4, 0.5], [0.15, 0.25, 0.33, 0.45]),
        ]
    }

    /// In 3-D the exact solve answers with its linearisation point once that point's pairing is
    /// verified (the linearisation at it changed none) and its distance to the fixed point is
    /// estimated within `u_tol` (`point_within`), instead of checking the pairing at the next
    /// QP's answer. On the small hertz-3d and ironing-3d with full bases at 5 training points,
    /// at 4 points between them and `u_tol` of 1e-4 and 1e-6, every query converges and its
    /// coordinates lie within `u_tol` (relative) of the answer at `u_tol` = 1e-13, the
    /// estimate's promise (measured at most 0.52 `u_tol`). The point is accepted at 9 of the 16
    /// queries, one linearisation sooner than the check at the next iterate (counted with the
    /// check forced: 3 against 4 on ironing, 4 against 5 once on hertz). The multipliers,
    /// which `u_tol` does not bound, lie within 12.8 `u_tol`, as with the check (measured).
    #[test]
    fn the_verified_point_is_within_the_tolerance_of_the_fixed_point() {
        let rel = |x: &[f64], y: &[f64]| {
            let n = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            x.iter().zip(y).map(|(s, t)| (s - t).powi(2)).sum::<f64>().sqrt() / n
        };
        for (f, mus, tests) in &small_models() {
            let (rom, _, _) = full_rom3(f, mus);
            let mut w = RomWork::default();
            for &d in tests {
                let tight = rom.solve(&[d], &RomParams { u_tol: 1e-13, ..RomParams::default() }, &mut w);
                assert_eq!(tight.outcome, RomOutcome::Converged, "{d}");
                for u_tol in [1e-4, 1e-6] {
                    let r = rom.solve(&[d], &RomParams { u_tol, ..RomParams::default() }, &mut w);
                    assert_eq!(r.outcome, RomOutcome::Converged, "{d} at {u_tol}");
                    let (eu, el) = (rel(&r.u_hat, &tight.u_hat), rel(&r.lambda_hat, &tight.lambda_hat));
                    assert!(eu <= u_tol && el.is_finite(), "{d} at {u_tol}: {eu:e} (multipliers {el:e})");
                }
            }
        }
    }

    /// A query's first linearisation carries its nearest sample's search proofs
    /// (`WarmStarts::locate3`, docs/design-notes.md#certificates-instead-of-searches) and its
    /// located facets as the searches' hints: a small hertz-3d and a small ironing-3d, full bases
    /// at 5 training points, the warm library at the first and the last (the die 0.4 apart, 4
    /// facets). At 4 points between them the seeded start holds a proof for every supported
    /// slave, and the answers (coordinates and multipliers, as bits), outcomes and
    /// linearisation counts equal those of the same model with the proofs dropped, where every
    /// slave is searched. A proof carried too far, or a hint that changed a search, changes a
    /// pair and so the answer: pairing on every carried proof's facet without measuring its
    /// near set again fails the test (checked). (Ignoring the distance alone does not: across
    /// four facets the near set's own distances refuse the proof.)
    #[test]
    fn a_query_starts_from_its_samples_proofs_and_keeps_its_answer() {
        let p = RomParams::default();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for (f, mus, tests) in &small_models() {
            let (rom, _, _) = full_rom3(f, mus);
            // the library at the two ends only: most queries lie farther than a facet from it
            let points = [vec![mus[0]], vec![mus[4]]];
            let seeded = rom.with_warm_starts(&points, &p);
            let lib = &seeded.warm_starts;
            assert_eq!(lib.located3.len(), 2, "proofs per sample");
            assert_eq!(lib.at3.len(), 2, "positions per sample");
            let mut bare = seeded.clone();
            bare.warm_starts.located3.clear();
            bare.warm_starts.at3.clear();
            let (mut ws, mut wb) = (RomWork::default(), RomWork::default());
            for &d in tests {
                ws.prepare(&seeded, &[d]);
                seeded.seed_warm(&[d], &mut ws);
                let SurfaceData::Nts3(n3) = &seeded.surf else { panic!("node-to-surface") };
                assert!(n3.supp.iter().all(|&s| ws.lin.located3[s].is_some()), "{d}: a proof per supported slave");
                let (a, b) = (seeded.solve(&[d], &p, &mut ws), bare.solve(&[d], &p, &mut wb));
                assert_eq!(a.outcome, RomOutcome::Converged, "{d}");
                assert_eq!((a.outcome, a.linearizations), (b.outcome, b.linearizations), "{d}");
                assert_eq!(bits(&a.u_hat), bits(&b.u_hat), "{d}");
                assert_eq!(bits(&a.lambda_hat), bits(&b.lambda_hat), "{d}");
            }
        }
    }

    /// A reduced quadrature of the 3-D contact constraints ([`ReducedModel::with_sampled_surface`],
    /// docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints): the small hertz-3d
    /// and ironing-3d with full bases at 5 training points, fitted at those points, answered at
    /// the 4 points between and compared with the full surface (coordinates and pressure,
    /// relative).
    ///
    /// * Fitted at 0, the fit reproduces the sums to its residual, at most 1e-7 (hertz-3d: 9 of
    ///   its 16 supported slaves, whose columns span the others', leave 3.4e-8; ironing-3d keeps
    ///   all 35, to rounding), and the answers are the full surface's to 1e-6 (measured 1.8e-7
    ///   and 1.2e-15: the residual, amplified by the QP's conditioning).
    /// * Fitted at 1e-2 it keeps fewer slaves (measured 5 and 10), converges at every point, and
    ///   its coordinates lie within 5e-2 of the full surface's (a regression bound: measured
    ///   1.7e-3 and 1.7e-2).
    /// * The sampled model reads back from its parts with the same bits (its weights are
    ///   stored), and a sampled model's leading ranks are the full surface again, as in 2-D.
    #[test]
    fn a_sampled_node_to_surface_model_is_exact_at_zero_tolerance_and_trades_above() {
        let p = RomParams::default();
        let rel = |x: &[f64], y: &[f64]| {
            let n = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            x.iter().zip(y).map(|(s, t)| (s - t).powi(2)).sum::<f64>().sqrt() / n
        };
        for (f, mus, tests) in &small_models() {
            let (rom, _, _) = full_rom3(f, mus);
            let points: Vec<Vec<f64>> = mus.iter().map(|&m| vec![m]).collect();
            let SurfaceData::Nts3(full) = &rom.surf else { panic!("node-to-surface") };
            let (exact, sel) = rom.with_sampled_surface(&points, &p, 0.0).expect("fit");
            assert!(sel.residual <= 1e-7, "fit residual {:e}", sel.residual);
            let (loose, _) = rom.with_sampled_surface(&points, &p, 1e-2).expect("fit");
            let kept = exact.sampled_slaves().expect("sampled");
            assert!(kept <= full.supp.len(), "{kept} of {}", full.supp.len());
            assert!(loose.sampled_slaves().expect("sampled") < kept, "the loose fit keeps fewer slaves");
            let (mut w, mut v) = (RomWork::default(), RomWork::default());
            for &d in tests {
                let a = rom.solve(&[d], &p, &mut w);
                for (model, bound) in [(&exact, 1e-6), (&loose, 5e-2)] {
                    let b = model.solve(&[d], &p, &mut v);
                    assert_eq!((a.outcome, b.outcome), (RomOutcome::Converged, RomOutcome::Converged), "{d}");
                    let eu = rel(&b.u_hat, &a.u_hat);
                    assert!(eu <= bound, "{d}: coordinates {eu:e} from the full surface's (bound {bound:e})");
                    if bound < 1e-2 {
                        let ep = rel(&model.pressure(&b.lambda_hat), &rom.pressure(&a.lambda_hat));
                        assert!(ep <= bound, "{d}: pressure {ep:e} from the full surface's");
                    }
                }
            }
            assert_round_trip(&loose, &points);
            let SurfaceData::Nts3(again) = &loose.leading(rom.ranks().0, rom.ranks().1).surf else { panic!() };
            assert!(again.quad.is_none() && again.supp == full.supp, "leading ranks restore the full surface");
        }
    }

    /// A dual basis set per query starts its re-pairing from the training points' answers in
    /// 3-D as in 2-D (`with_primal_starts`, docs/design-notes.md#warm-starts): a small
    /// ironing-3d, 5 training points, their pressures as a cone basis set before each query
    /// ([`crate::dual::ConePrefix`], every column at every point). The library holds every
    /// training point's answer (before, a node-to-surface model got none and every query started
    /// at `y = 0`), and at 4 points between them the started answers equal the cold ones to 1e-8
    /// relative (each solve stops within `u_tol` = 1e-10 of the fixed point, as in the 2-D
    /// test). On this small model both take 4–5 linearisations; on ironing-3d's stored model the
    /// starts take 4.9 on average instead of 5.9 (docs/results.md#contact-in-3-d).
    #[test]
    fn primal_starts_reach_node_to_surface_models_and_keep_the_answer() {
        let ironing = build_ironing3d(&ironing_params()).expect("ironing").factor().expect("factor");
        let mus = [0.1, 0.2, 0.3, 0.4, 0.5];
        let (rom, _, snaps) = full_rom3(&ironing, &mus);
        let nc = snaps[0].pressure.len();
        let theta = faer::Mat::from_fn(nc, mus.len(), |i, j| snaps[j].pressure[i]);
        let approx = crate::dual::ConePrefix::new(theta.as_ref());
        let p = RomParams::default();
        let points: Vec<Vec<f64>> = mus.iter().map(|&d| vec![d]).collect();
        let started = rom.clone().with_primal_starts(&approx, mus.len(), &points, &p);
        assert_eq!(started.warm_starts.ys.len(), mus.len(), "an answer per training point");
        let (mut wa, mut wb) = (RomWork::default(), RomWork::default());
        for d in [0.15, 0.25, 0.33, 0.45] {
            let (mut a, mut b) = (rom.clone(), started.clone());
            a.set_dual_of(&approx, &[d], mus.len());
            b.set_dual_of(&approx, &[d], mus.len());
            let (ra, rb) = (a.solve(&[d], &p, &mut wa), b.solve(&[d], &p, &mut wb));
            assert_eq!((ra.outcome, rb.outcome), (RomOutcome::Converged, RomOutcome::Converged), "d_x {d}");
            let rel = |x: &[f64], y: &[f64]| {
                let n = y.iter().map(|v| v * v).sum::<f64>().sqrt();
                x.iter().zip(y).map(|(s, t)| (s - t).powi(2)).sum::<f64>().sqrt() / n
            };
            let (eu, el) = (rel(&rb.u_hat, &ra.u_hat), rel(&rb.lambda_hat, &ra.lambda_hat));
            assert!(eu <= 1e-8 && el <= 1e-8, "d_x {d}: started vs cold {eu:e}, {el:e}");
        }
    }
}
