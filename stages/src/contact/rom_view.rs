//! The two-body node-to-segment contact model as a [`ContactOperator`] for the online reduced
//! solve (paper Sec. 2.3.2, Algorithm 1; scenes hertz and ironing). Type-2: the pairing is
//! recomputed at every linearisation.
//!
//! - dofs: all displacement dofs of both bodies, interleaved `(u_x, u_y)` per node;
//! - dual field: one pressure per slave node, nodal force = pressure × tributary length
//!   ([`crate::contact::ContactModel::tributary_lengths`], the conversion [`FactoredModel::solve`] uses);
//! - lift `u0(mu)`: the contact-free solution, `u_D(mu)` on the Dirichlet dofs and
//!   `u^(0) + mu u^(1)` on the free ones — bit for bit the unconstrained response the solver
//!   adds its contact correction to, so `u - u0(mu)` vanishes exactly on the Dirichlet dofs;
//! - `stiffness_mul`: the sparse `K` with the Dirichlet rows zeroed;
//! - `linearize`: closest-point pairing of every slave onto the deformed master polyline
//!   ([`closest_point`], the solver's rule and normals), gap
//!   `g_s(v) = n · (x_s + v_s - (1 - ξ)(x_a + v_a) - ξ (x_b + v_b))` with `ξ`, `n` frozen; a
//!   slave whose two dofs are Dirichlet (the Hertz arc's end nodes) or with no master segment
//!   under it is unpaired.
//!
//! **Vertex ties.** The full-order solver ties a slave whose pairing flips around a master
//! vertex to that vertex ([`super::vertex`]); that needs the history of the re-pairing loop. A
//! linearisation here is stateless, so it uses the plain closest-point rule, with one
//! deterministic refinement: a foot point within [`VERTEX_SNAP`] (in the segment coordinate `ξ`)
//! of an interior vertex is paired with that vertex and its averaged normal, exactly what a tie
//! or the blind-spot rule of [`closest_point`] gives there. Without it a slave sitting on a
//! vertex — the Hertz apex, where both arcs have a node at the origin — would take the normal
//! of whichever adjacent segment rounding favours, tilted by half the vertex angle.
//!
//! **Pairing ids.** Segment `k` → `k`; vertex `v` → `u64::MAX - 1 - v`; unpaired → `u64::MAX`.

use super::factor::FactoredModel;
use super::pairing::GapRow;
use super::pairing::{closest_point, vertex_pair, Pair, PairKind};
use crate::fem::h1::{h1_gram, h1_norm_sq};
use crate::full_order::{Compliance, ContactOperator, Linearized, Surface};

/// A segment foot point with `ξ <= VERTEX_SNAP` or `ξ >= 1 - VERTEX_SNAP` next to an interior
/// vertex is paired with the vertex (see the module docs). The rounding of `ξ` for a slave on a
/// vertex is `~1e-16 |x| / h ~ 1e-14`, well inside; snapping moves the foot point by at most
/// `1e-9 h`, far below the solver's tolerances.
pub const VERTEX_SNAP: f64 = 1e-9;

/// Id of a pairing in [`Linearized::pairing`].
fn pairing_id(kind: PairKind) -> u64 {
    match kind {
        PairKind::None => u64::MAX,
        PairKind::Segment(k) => k as u64,
        PairKind::Vertex(v) | PairKind::Tied(v) => u64::MAX - 1 - v as u64,
        PairKind::End(v) => u64::MAX / 2 + v as u64,
    }
}

/// Plain closest-point pairing with the vertex snap.
fn stateless_pair(xs: [f64; 2], xm: &[[f64; 2]]) -> Pair {
    let p = closest_point(xs, xm);
    let last = xm.len() - 1;
    match p.kind {
        PairKind::Segment(k) if p.xi <= VERTEX_SNAP && k >= 1 => vertex_pair(xs, xm, k, PairKind::Vertex(k)),
        PairKind::Segment(k) if p.xi >= 1.0 - VERTEX_SNAP && k + 1 < last => {
            vertex_pair(xs, xm, k + 1, PairKind::Vertex(k + 1))
        }
        _ => p,
    }
}

impl ContactOperator for FactoredModel {
    fn n_dof(&self) -> usize {
        self.model.n_dof()
    }

    fn n_contact(&self) -> usize {
        self.model.slaves.len()
    }

    fn weights(&self) -> &[f64] {
        &self.model.tributary
    }

    fn lift(&self, mu: &[f64]) -> Vec<f64> {
        // the same expression as the solver's recovery (solve.rs, `finish`) without contact
        self.model.split.contact_free(&self.model.u_d, &self.resp, mu)
    }

    fn lift_terms(&self) -> Vec<Vec<f64>> {
        self.model.split.contact_free_terms(&self.model.u_d, &self.resp)
    }

    fn stiffness_mul(&self, x: &[f64], y: &mut [f64]) {
        self.model.split.mul_zero_fixed(&self.model.k, x, y)
    }

    /// Estimated beside the Delassus operator when the model was factored with it
    /// ([`super::model::ContactModel::factor_with_condition`]), else here on first read
    /// ([`super::factor::stiffness_condition`]).
    fn stiffness_condition(&self) -> Option<crate::condition::Condition> {
        *self.condition.get_or_init(|| super::factor::stiffness_condition(&self.model, &self.llt))
    }

    fn linearize(&self, _mu: &[f64], u: &[f64], out: &mut Linearized) {
        let m = &self.model;
        assert_eq!(u.len(), m.n_dof(), "displacement length");
        let ns = m.slaves.len();
        let global = |cd: usize| 2 * self.cnodes[cd / 2] + cd % 2;
        let xc: Vec<f64> = (0..2 * self.cnodes.len()).map(|cd| self.x_ref[cd / 2][cd % 2] + u[global(cd)]).collect();
        let xm: Vec<[f64; 2]> = (0..m.masters.len()).map(|k| [xc[2 * (ns + k)], xc[2 * (ns + k) + 1]]).collect();
        out.clear();
        out.start.push(0);
        for s in 0..ns {
            // a non-finite position projects nowhere (every comparison fails): unpaired
            let p = if self.slave_fixed[s] { Pair::NONE } else { stateless_pair([xc[2 * s], xc[2 * s + 1]], &xm) };
            let paired = p.kind.is_paired();
            let mut gap0 = 0.0;
            if paired {
                let row = GapRow::new(s, ns, &p);
                for (cd, c) in row.entries() {
                    out.dofs.push(global(cd));
                    out.coeffs.push(c);
                    gap0 += c * self.x_ref[cd / 2][cd % 2];
                }
            }
            out.start.push(out.dofs.len());
            out.gap0.push(gap0);
            out.paired.push(paired);
            out.pairing.push(pairing_id(p.kind));
        }
    }

    fn primal_norm_sq(&self, u: &[f64]) -> f64 {
        h1_norm_sq(&self.model.mesh, u)
    }

    fn primal_gram_mul(&self, u: &[f64], out: &mut [f64]) {
        self.h1.get_or_init(|| h1_gram(&self.model.mesh)).matvec_into(u, out)
    }

    fn surface(&self) -> Surface {
        Surface::NodeToSegment {
            n_slaves: self.model.slaves.len(),
            x_ref: self.x_ref.clone(),
            dofs: self.cnodes.iter().flat_map(|&n| [2 * n, 2 * n + 1]).collect(),
            slave_fixed: self.slave_fixed.clone(),
        }
    }

    fn contact_compliance(&self) -> Compliance {
        Compliance { dofs: self.cnodes.iter().flat_map(|&n| [2 * n, 2 * n + 1]).collect(), w: self.w.clone() }
    }
}

#[cfg(test)]
mod tests {
    use super::super::pairing::{closest_point, vertex_normal};
    use crate::contact::{build_hertz, FactoredModel, HertzParams, Material};
    use crate::float_cmp::Tol;
    use crate::rom::{ContactOperator, Linearized};
    use crate::snapshot::Snapshot;
    use crate::testing::{hertz, ironing_coarse, TOL};
    use crate::{assert_all_close, assert_close};

    /// The operator's view of a solver snapshot: (smallest gap over paired slaves, largest
    /// |gap| over slaves with pressure > 0, equilibrium residual `max_F |K (u - u0) - C^T W λ|`
    /// relative to `max_F |C^T W λ|`), with `C`, `gap0` linearised at the snapshot.
    fn operator_residuals(fm: &FactoredModel, mu: f64, s: &Snapshot) -> (f64, f64, f64) {
        let mut lin = Linearized::default();
        fm.linearize(&[mu], &s.u, &mut lin);
        let w = fm.weights();
        let (mut min_gap, mut active_gap) = (f64::INFINITY, 0.0f64);
        let mut f = vec![0.0; fm.n_dof()];
        for (i, &p) in s.pressure.iter().enumerate() {
            if !lin.paired[i] {
                assert!(p <= 0.0, "mu {mu}: slave {i} carries pressure but is unpaired");
                continue;
            }
            let g = lin.gap(i, &s.u);
            min_gap = min_gap.min(g);
            if p > 0.0 {
                active_gap = active_gap.max(g.abs());
            }
        }
        lin.add_forces(w, &s.pressure, &mut f);
        let v: Vec<f64> = s.u.iter().zip(fm.lift(&[mu])).map(|(a, b)| a - b).collect();
        let mut kv = vec![0.0; fm.n_dof()];
        fm.stiffness_mul(&v, &mut kv);
        let free = fm.model.split.free();
        let scale = free.iter().fold(0.0f64, |m, &d| m.max(f[d].abs()));
        let res = free.iter().fold(0.0f64, |m, &d| m.max((kv[d] - f[d]).abs()));
        (min_gap, active_gap, res / scale)
    }

    /// The lift is the solver's contact-free solution: bit-identical to a separated solve
    /// (hertz at d = -0.01: the recovery adds `K^{-1} 0 = 0` to the same expression), and a
    /// contact snapshot minus the lift vanishes exactly on the Dirichlet dofs (imposed values
    /// are copied), where `stiffness_mul` returns zero rows.
    #[test]
    fn lift_is_the_solvers_contact_free_response() {
        let fm = hertz();
        let s = fm.solve(&[-0.01], &TOL).expect("separated solve");
        assert_all_close!(s.u, fm.lift(&[-0.01]), Tol::abs(0.0));
        for (fm, mu) in [(hertz(), 0.2), (ironing_coarse(), 1.3)] {
            let s = fm.solve(&[mu], &TOL).expect("solve");
            let v: Vec<f64> = s.u.iter().zip(fm.lift(&[mu])).map(|(a, b)| a - b).collect();
            let mut kv = vec![1.0; fm.n_dof()];
            fm.stiffness_mul(&v, &mut kv);
            for &d in fm.model.split.fixed() {
                assert_close!(v[d], 0.0, Tol::abs(0.0));
                assert_close!(kv[d], 0.0, Tol::abs(0.0));
            }
        }
    }

    /// Hertz at d = 0: the lift is zero and both arcs have a node at the origin (the apex), so
    /// the apex slave sits on a master vertex (up to the rounding of cos(pi/2)); it must pair
    /// with that vertex and its averaged normal, here (0, 1) exactly by symmetry (1e-15), with
    /// zero gap, rather than with one of the two adjacent segments (tilted by pi/156).
    #[test]
    fn slave_on_a_master_vertex_gets_the_vertex_normal() {
        let fm = hertz();
        let m = &fm.model;
        let apex = m.slaves.iter().position(|&n| m.mesh.nodes[n][0].abs() < 1e-12).expect("apex slave");
        let v = m.masters.iter().position(|&n| m.mesh.nodes[n][0].abs() < 1e-12).expect("apex vertex");
        let u = fm.lift(&[0.0]);
        let mut lin = Linearized::default();
        fm.linearize(&[0.0], &u, &mut lin);
        assert_eq!(lin.pairing[apex], u64::MAX - 1 - v as u64, "vertex pairing id");
        let r = lin.start[apex]..lin.start[apex + 1];
        let sn = m.slaves[apex];
        assert_eq!(lin.dofs[r.clone()], [2 * sn, 2 * sn + 1, 2 * m.masters[v], 2 * m.masters[v] + 1]);
        assert_all_close!(lin.coeffs[r], [0.0, 1.0, 0.0, -1.0], Tol::abs(1e-15));
        assert_close!(lin.gap0[apex], 0.0, Tol::abs(1e-15));
        // the Hertz arc's end slaves are Dirichlet (on the flat face): unpaired, empty rows
        let last = m.slaves.len() - 1;
        for i in [0, last] {
            assert!(!lin.paired[i] && lin.start[i] == lin.start[i + 1] && lin.pairing[i] == u64::MAX);
        }
    }

    /// The operator describes the solver's discrete problem at its converged snapshots:
    /// linearised at the snapshot, every gap is >= -1e-10 and the gaps of slaves with
    /// pressure are zero within 1e-9 (the solver's penetration and complementarity are at its
    /// 1e-10 tolerance in length units ~1), and `K (u - u0) = C^T W λ` holds on the free dofs
    /// to 1e-8 relative (the solver's KKT residual is <= 2e-10 relative to the same force scale;
    /// measured 1e-11 .. 8e-11).
    ///
    /// Points: every ironing-coarse point of the 8-point sweep (the solver needs no vertex tie
    /// there), and hertz at d = 0.025 (no tie) and d = 0.05, where the solver ties exactly one
    /// slave — the apex, which sits on the master's apex vertex and gets the same averaged
    /// normal from the vertex snap. (Larger hertz approaches: see the next test.) The snapshots
    /// are solved with flip ties only: the vertex-zone rule ties slaves near a sole vertex at
    /// many more points, and a tie is exactly where the stateless linearisation differs (next
    /// test; the tied states are checked by `contact::tests::geometric_check_on_every_training_point`).
    #[test]
    fn linearisation_at_a_snapshot_matches_the_solver() {
        let cases: Vec<(&FactoredModel, f64)> = (0..8)
            .map(|k| (ironing_coarse(), 3.0 * k as f64 / 7.0))
            .chain([(hertz(), 0.025), (hertz(), 0.05)])
            .collect();
        for (fm, mu) in cases {
            let s = fm
                .solve_with_rule(&[mu], &TOL, &crate::contact::SolveStart::COLD, crate::contact::VertexRule::FlipTies)
                .expect("solve");
            assert!(s.stats.vertex_ties <= 1, "mu {mu}: {:?}", s.stats);
            let (min_gap, active_gap, eq) = operator_residuals(fm, mu, &s);
            assert!(min_gap >= -1e-10, "mu {mu}: gap {min_gap:e}");
            assert!(active_gap <= 1e-9, "mu {mu}: active gap {active_gap:e}");
            assert!(eq <= 1e-8, "mu {mu}: equilibrium residual {eq:e}");
        }
    }

    /// Hertz at larger approaches: both arcs carry the same 78 equal elements, so under load
    /// every active slave sits within ξ ~ 1e-3 .. 1e-2 of a master vertex and the solver ties
    /// several of them (at least 3 over d in 0.1 .. 0.3; without ties it does not converge at all
    /// from d = 0.05 on, see below). A tie uses the averaged normal where the stateless
    /// closest-point rule uses the segment's, so the operator's linearisation at such a snapshot
    /// differs from the solver's — and only there: at every slave with pressure the solver's
    /// contact force (`K u` at the slave's free dofs, which no other constraint touches) points
    /// along the operator's normal or along the averaged normal of the vertex nearest to the
    /// operator's foot point, within 1e-7 rad (KKT tolerance 1e-10 of the largest force over the
    /// smallest active force ~0.1 of it, plus rounding), and at least one slave is of the
    /// second kind.
    #[test]
    fn hertz_ties_are_the_only_difference_from_the_solver() {
        let fm = hertz();
        let m = &fm.model;
        for d in [0.1, 0.2, 0.3] {
            let s = fm.solve(&[d], &TOL).expect("solve");
            assert!(s.stats.vertex_ties >= 3, "{:?}", s.stats);
            let ku = m.k.matvec(&s.u);
            let xm: Vec<[f64; 2]> = m
                .masters
                .iter()
                .map(|&n| [m.mesh.nodes[n][0] + s.u[2 * n], m.mesh.nodes[n][1] + s.u[2 * n + 1]])
                .collect();
            let mut lin = Linearized::default();
            fm.linearize(&[d], &s.u, &mut lin);
            let mut tied = 0;
            for (i, &sn) in m.slaves.iter().enumerate() {
                if s.pressure[i] <= 0.0 {
                    continue;
                }
                let f_angle = ku[2 * sn].atan2(ku[2 * sn + 1]);
                let a = lin.start[i];
                let own = lin.coeffs[a].atan2(lin.coeffs[a + 1]);
                let xs = [m.mesh.nodes[sn][0] + s.u[2 * sn], m.mesh.nodes[sn][1] + s.u[2 * sn + 1]];
                let p = closest_point(xs, &xm);
                let v = match p.kind {
                    super::PairKind::Segment(k) => k + usize::from(p.xi > 0.5),
                    super::PairKind::Vertex(v) | super::PairKind::Tied(v) => v,
                    super::PairKind::None | super::PairKind::End(_) => panic!("active slave {i} unpaired"),
                };
                let nv = vertex_normal(&xm, v);
                let vertex = nv[0].atan2(nv[1]);
                if (f_angle - own).abs() > 1e-7 {
                    assert!((f_angle - vertex).abs() <= 1e-7, "d {d} slave {i}: {f_angle} vs {own} / {vertex}");
                    tied += 1;
                }
            }
            assert!(tied >= 1, "d {d}: expected tied slaves");
            assert!(
                fm.solve_with_rule(&[d], &TOL, &crate::contact::SolveStart::COLD, crate::contact::VertexRule::Off)
                    .is_err(),
                "d {d}: plain closest point converged in the solver"
            );
        }
    }

    /// The stiffness condition estimate of a small hertz model against the dense spectrum of
    /// `K_FF` (assembled column by column from `stiffness_mul`): inside the spectrum, the
    /// smallest eigenvalue to 1e-8 (inverse iteration; bottom ratio well below 1), the largest
    /// within 10 % (60 power steps on a clustered top).
    #[test]
    fn stiffness_condition_matches_the_dense_spectrum() {
        let p = HertzParams { radius: 1.0, material: Material::new(1.0, 0.3), n_arc: 12, n_side: None };
        let fm = build_hertz(&p).expect("hertz").factor().expect("factor");
        let free = fm.model.split.free().to_vec();
        let n = fm.n_dof();
        let mut cols = vec![0.0; free.len() * free.len()];
        for (j, &dj) in free.iter().enumerate() {
            let (mut e, mut y) = (vec![0.0; n], vec![0.0; n]);
            e[dj] = 1.0;
            fm.stiffness_mul(&e, &mut y);
            for (i, &di) in free.iter().enumerate() {
                cols[i + j * free.len()] = y[di];
            }
        }
        let k = faer::MatRef::from_column_major_slice(&cols, free.len(), free.len());
        let sym = faer::Mat::from_fn(free.len(), free.len(), |i, j| 0.5 * (k[(i, j)] + k[(j, i)]));
        let eig = sym.as_ref().self_adjoint_eigenvalues(faer::Side::Lower).expect("eigenvalues");
        let lo = eig.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = eig.iter().copied().fold(0.0, f64::max);
        let c = fm.stiffness_condition().expect("SPD");
        assert!(c.lambda_min >= lo * (1.0 - 1e-10) && c.lambda_max <= hi * (1.0 + 1e-10), "{c:?} vs [{lo}, {hi}]");
        assert_close!(c.lambda_min, lo, Tol::rel(1e-8));
        assert!(c.lambda_max >= 0.9 * hi, "{} vs {hi}", c.lambda_max);
    }

    /// The estimate computed beside the Delassus operator (`factor_with_condition`) is the one
    /// a model factored without it computes on first read, to the bit, and the rest of the
    /// factorisation is the same too (the operator's entries).
    #[test]
    fn the_condition_beside_the_operator_is_the_condition_read_later() {
        let p = HertzParams { radius: 1.0, material: Material::new(1.0, 0.3), n_arc: 12, n_side: None };
        let model = build_hertz(&p).expect("hertz");
        let (eager, lazy) = (model.factor_with_condition().expect("factor"), model.factor().expect("factor"));
        assert!(eager.condition.get().is_some() && lazy.condition.get().is_none(), "when each is computed");
        let (a, b) = (eager.stiffness_condition().expect("SPD"), lazy.stiffness_condition().expect("SPD"));
        assert_eq!((a.lambda_min.to_bits(), a.lambda_max.to_bits()), (b.lambda_min.to_bits(), b.lambda_max.to_bits()));
        let bits = |w: &[f64]| w.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&eager.w), bits(&lazy.w), "the Delassus operator");
    }
}
