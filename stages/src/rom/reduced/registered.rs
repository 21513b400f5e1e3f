//! A dual basis rebuilt at each query point: a registered CPG basis
//! ([`crate::dual::registration`]) whose reference generators are pushed forward to the query's
//! frame, `Θ(μ) = push_μ(G)`, then set as the model's dual basis ([`ReducedModel::set_dual`]).
//!
//! The online comparison measures such a basis with exactly these steps
//! ([`ReducedModel::set_dual_of`]: the approximation's cone basis at μ — its first `m` pushed
//! generators that are not zero — then `set_dual`, then the exact solve); a stored model that
//! carries the basis ([`ReducedModel::with_registered_dual`]) repeats them before each query
//! ([`ReducedModel::dual_at`], or through a [`QueryModel`]), so it answers every point with the
//! bits the online comparison measured there. The work per query reads contact-surface data
//! only (`O(n_contact m)` for the push and the sparse layouts), never `n_dof`.
//!
//! Between queries such a model holds the basis of its last query; its warm-start library holds
//! primal starts only ([`ReducedModel::with_primal_starts`]: the answers at the training points,
//! no active sets, which would index one point's basis), as the online comparison's does.

use std::sync::Arc;

use super::{ReducedModel, RomError};
use crate::dual::registration::Registered;
use crate::dual::DualApprox;

/// The registered basis of a model, the most generators a query uses, and a reduced quadrature
/// of the contact constraints in the reference frame ([`ReducedModel::with_registered_quadrature`]).
#[derive(Debug, Clone)]
pub(super) struct PerQueryDual {
    pub(super) basis: Arc<Registered>,
    pub(super) m: usize,
    /// Quadrature weights on the reference grid (`None`: every supported slave).
    pub(super) quad: Option<Arc<Vec<f64>>>,
}

/// The online solve's dual basis of `approx` at `mu`: its cone basis with at most `m` columns
/// ([`DualApprox::cone_basis`]; none for signed modes), column-major, and its column count.
pub fn cone_basis_columns(approx: &dyn DualApprox, mu: &[f64], m: usize) -> (Vec<f64>, usize) {
    approx.cone_columns(mu, m).unwrap_or_default()
}

impl ReducedModel {
    /// Set the dual basis to `approx`'s at `mu` with at most `m` columns
    /// ([`cone_basis_columns`], then [`Self::set_dual`]): the step the online comparison takes
    /// before each query with a basis that depends on the parameter.
    pub fn set_dual_of(&mut self, approx: &dyn DualApprox, mu: &[f64], m: usize) {
        let (theta, k) = cone_basis_columns(approx, mu, m);
        self.set_dual(&theta, k);
    }

    /// The model with the registered CPG basis `basis` as its dual basis, rebuilt at each query
    /// point with at most `m` generators ([`Self::dual_at`]); the dual basis at rest is empty.
    /// Refused: a basis that is not a cone basis (a registered POD) or whose surface is not
    /// the model's contact surface.
    pub fn with_registered_dual(mut self, basis: Registered, m: usize) -> Result<Self, RomError> {
        let arrays = basis.arrays().ok_or_else(|| {
            RomError::Parts("a registered dual basis must have non-negative generators (CPG), not POD modes".into())
        })?;
        if arrays.surface.len() != self.n_contact {
            return Err(RomError::Parts(format!(
                "the registered basis has {} surface nodes, the model {} contact nodes",
                arrays.surface.len(),
                self.n_contact
            )));
        }
        self.set_dual(&[], 0);
        self.per_query = Some(PerQueryDual { basis: Arc::new(basis), m, quad: None });
        Ok(self)
    }

    /// Before a query at `mu`: a model with a registered dual basis sets it to the basis at `mu`
    /// ([`Self::set_dual_of`]), and, with a quadrature in the reference frame, sums its
    /// constraints over the quadrature's slaves pushed forward to `mu`'s frame with their
    /// weights; a model with a fixed one is left as it is.
    pub fn dual_at(&mut self, mu: &[f64]) {
        if let Some(d) = self.per_query.take() {
            self.set_dual_of(d.basis.as_ref(), mu, d.m);
            let n = self.n_contact;
            if let (Some(q), Some((supp, quad))) = (&d.quad, self.surf.quadrature_mut()) {
                // the weights pushed forward to `mu`'s frame (the basis set above dropped the last
                // query's), and the support cut to the slaves they reach
                let mut at = vec![0.0; n];
                d.basis.map().push(q, mu, &mut at);
                supp.retain(|&s| at[s] > 0.0);
                *quad = Some(at);
            }
            self.per_query = Some(d);
        }
    }

    /// The model with a reduced quadrature of its contact constraints fitted in its registered
    /// basis's reference frame (docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints):
    /// the fit of [`Self::with_sampled_surface`] with a column per reference node instead of per
    /// slave. At each of `samples` the basis is set there ([`Self::dual_at`]) and every paired
    /// supported slave's contributions go to the reference node its whole-node shift pulls it
    /// back to; the full sums weigh each slave by its tributary measure. The kept reference
    /// nodes and weights, pushed forward to each query's frame, replace the supported slaves
    /// and their measures there: under a die that moves with the parameter the slaves under it
    /// are, in the reference frame, the same ones at every point. Refused
    /// ([`RomError::Sampling`]): a model without a registered basis, a map other than the
    /// whole-node translation (`translate-nodes`, whose pull and push move values exactly), or
    /// the fit's refusals. The answers change: measure them.
    pub fn with_registered_quadrature(
        mut self,
        samples: &[Vec<f64>],
        p: &super::RomParams,
        tol: f64,
    ) -> Result<(Self, crate::rom::sampling::Selection), RomError> {
        use crate::dual::registration::{Interpolation, MapKind};
        let Some(d) = self.per_query.clone() else {
            return Err(RomError::Sampling("the model has no registered dual basis to sample in".into()));
        };
        let map = d.basis.map();
        if map.kind() != (MapKind::Translate { interpolation: Interpolation::Nodes }) {
            return Err(RomError::Sampling(format!(
                "the registered map is {}: a quadrature in the reference frame needs whole-node shifts (translate-nodes)",
                map.kind().name()
            )));
        }
        super::surface::check_fit(samples, tol)?;
        let (len, rl) = (map.len(), d.m);
        let dirs = super::surface::sampling_directions(self.r_u);
        let (mut values, mut sums, mut row) = (Vec::new(), Vec::new(), Vec::new());
        let (mut w, mut at) = (super::RomWork::default(), self.clone());
        let (code, mut pulled) = ((1..=self.n_contact).map(|s| s as f64).collect::<Vec<f64>>(), vec![0.0; len]);
        for mu in samples {
            at.dual_at(mu);
            // the reference node of each slave at `mu`: its (1-based) index pulled back
            map.pull(&code, mu, &mut pulled);
            let mut col_of = vec![usize::MAX; self.n_contact];
            for (r, &v) in pulled.iter().enumerate().filter(|(_, &v)| v > 0.0) {
                col_of[v as usize - 1] = r;
            }
            at.fit_states(mu, p, &mut w, |w| {
                at.record_state(w, (&col_of, len, rl), &dirs, (&mut values, &mut sums), &mut row)
            });
        }
        // the reference nodes some state reached, as the fit's columns
        let rows = sums.len();
        let cols: Vec<usize> = (0..len).filter(|&c| (0..rows).any(|r| values[r * len + c] != 0.0)).collect();
        let compact: Vec<f64> =
            (0..rows).flat_map(|r| cols.iter().map(move |&c| (r, c))).map(|(r, c)| values[r * len + c]).collect();
        drop(values);
        let sel = super::surface::fit_quadrature(compact, sums, cols.len(), rl, tol)?;
        let mut q = vec![0.0; len];
        for (&c, &xi) in sel.columns.iter().zip(&sel.weights) {
            q[cols[c]] = xi;
        }
        if let Some(pq) = &mut self.per_query {
            pq.quad = Some(Arc::new(q));
        }
        Ok((self, sel))
    }

    /// The registered dual basis and its most generators per query, if the dual basis is
    /// rebuilt at each query point.
    pub fn registered_dual(&self) -> Option<(&Registered, usize)> {
        self.per_query.as_ref().map(|d| (d.basis.as_ref(), d.m))
    }

    /// The ranks the model was stored with: [`Self::ranks`], except that a registered dual
    /// basis counts its most generators per query.
    pub fn stored_ranks(&self) -> (usize, usize) {
        (self.r_u, self.per_query.as_ref().map_or(self.r_l, |d| d.m))
    }
}

/// A model to answer queries with from one thread: the model itself where its dual basis is
/// fixed, a copy of its own where the dual basis is rebuilt at each query point (the copy's
/// dual part changes per query; the registered basis is shared, not copied).
#[derive(Debug)]
pub enum QueryModel<'a> {
    /// A fixed dual basis: the model, borrowed.
    Shared(&'a ReducedModel),
    /// A registered dual basis: this thread's copy.
    Own(Box<ReducedModel>),
}

impl<'a> QueryModel<'a> {
    /// For queries of `model` from one thread.
    pub fn new(model: &'a ReducedModel) -> Self {
        if model.per_query.is_some() {
            Self::Own(Box::new(model.clone()))
        } else {
            Self::Shared(model)
        }
    }

    /// The model ready for a query at `mu` ([`ReducedModel::dual_at`]).
    pub fn at(&mut self, mu: &[f64]) -> &ReducedModel {
        match self {
            Self::Shared(m) => m,
            Self::Own(m) => {
                m.dual_at(mu);
                m
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use faer::MatRef;

    use super::QueryModel;
    use crate::dual::registration::{Interpolation, MapKind, Registered};
    use crate::dual::{Inner, Training};
    use crate::rom::reduced::test_support::{coarse_mus, coarse_tests, full_rom};
    use crate::rom::{ContactOperator, ModelParts, ReducedModel, RomOutcome, RomParams, RomWork};
    use crate::testing::ironing_coarse;

    /// A model carrying a registered cone basis (ironing-coarse, 17 training points, whole-node
    /// translation; CPG with at most 5 generators, and neighbours with 2) and its primal starts,
    /// written as parts and read back, answers every test point with the bits of the online
    /// comparison's steps (a fresh copy of the model with the primal starts and no dual basis,
    /// `set_dual_of` the basis at the point, the exact solve): the same solution and the same pressure, through a [`QueryModel`] whose
    /// copy keeps the previous query's basis in between; damaged registered parts are refused.
    #[test]
    fn a_stored_registered_model_answers_as_the_online_comparison() {
        for (inner, m) in [(Inner::Cpg, 5), (Inner::Neighbours, 2)] {
            stored_registered_model_answers(inner, m);
        }
    }

    /// ironing-coarse with 17 training points: the model of the primal POD without a dual
    /// basis, the registered (whole-node translation) basis `inner` of the training pressures,
    /// and the training points.
    fn coarse_registered(inner: Inner) -> (ReducedModel, Registered, Vec<Vec<f64>>) {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (full, phi, snaps) = full_rom(fm, &mus);
        let (ru, nc) = (full.ranks().0, fm.n_contact());
        let base = ReducedModel::new(fm, &phi, ru, &[], 0).expect("K̂ SPD");
        let mesh = fm.model().mesh();
        let x: Vec<f64> = fm.contact_nodes()[..nc].iter().map(|&i| mesh.nodes[i][0]).collect();
        let pressures: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
        let params: Vec<Vec<f64>> = mus.iter().map(|&d| vec![d]).collect();
        let ms: Vec<usize> = (1..=16).collect();
        let training = Training {
            snapshots: MatRef::from_column_major_slice(&pressures, nc, mus.len()),
            params: &params,
            surface: &x,
            across: &[],
            ms: &ms,
        };
        let kind = MapKind::Translate { interpolation: Interpolation::Nodes };
        let reg = Registered::build(&training, kind, inner).expect("registered cone basis");
        (base, reg, params)
    }

    /// Primal starts change the steps, not the answer: with a registered basis set per query
    /// (CPG at m = 5, neighbours at m = 2; ironing-coarse, 48 test points between the 17
    /// training points), the answers from the training answers' `y` equal the cold ones to
    /// 1e-8 relative (each solve stops within `u_tol` = 1e-10 of the fixed point), and take
    /// fewer linearisations in all.
    #[test]
    fn primal_starts_change_the_steps_not_the_answer() {
        for (inner, m) in [(Inner::Cpg, 5), (Inner::Neighbours, 2)] {
            let (base, reg, params) = coarse_registered(inner);
            let p = RomParams::default();
            let started = base.clone().with_primal_starts(&reg, m, &params, &p);
            let (mut cold, mut warm) = (base.clone(), started.clone());
            let (mut wc, mut ww) = (RomWork::default(), RomWork::default());
            let (mut worst, mut lin_cold, mut lin_warm) = (0.0f64, 0, 0);
            for d in coarse_tests() {
                cold.set_dual_of(&reg, &[d], m);
                warm.set_dual_of(&reg, &[d], m);
                let (a, b) = (cold.solve(&[d], &p, &mut wc), warm.solve(&[d], &p, &mut ww));
                assert_eq!((a.outcome, b.outcome), (RomOutcome::Converged, RomOutcome::Converged), "d_x {d}");
                let diff = a.u_hat.iter().zip(&b.u_hat).map(|(s, t)| (s - t) * (s - t)).sum::<f64>().sqrt();
                worst = worst.max(diff / a.u_hat.iter().map(|s| s * s).sum::<f64>().sqrt());
                lin_cold += a.linearizations;
                lin_warm += b.linearizations;
            }
            assert!(worst <= 1e-8, "{inner:?}: started vs cold {worst:e}");
            assert!(lin_warm < lin_cold, "{inner:?}: linearisations started {lin_warm} vs cold {lin_cold}");
        }
    }

    /// A reduced quadrature in the registered basis's reference frame
    /// ([`ReducedModel::with_registered_quadrature`]): ironing-coarse, 17 training points, the
    /// registered neighbours (m = 2) with their primal starts, fitted at the training points.
    ///
    /// * Fitted at 0 it keeps the sums to a residual of at most 1e-8 and answers the 48 test
    ///   points as the model without it, to 1e-8 relative (coordinates; both stop at
    ///   `u_tol` = 1e-10, and the weights it finds are the tributary lengths to the fit's
    ///   rounding);
    /// * fitted at 3e-2 it keeps fewer reference nodes, is applied at every point (the sampled
    ///   slaves replace the support, and answers move) and converges at every test point;
    /// * the weights are stored (`reg_quad`) and read back with the same bits, and the model
    ///   read back answers with the same bits; a weight count that is not the grid's is refused
    ///   naming the array; a model without a registered basis, or a tolerance outside [0, 1), is
    ///   refused.
    #[test]
    fn a_quadrature_in_the_reference_frame_is_exact_at_zero_and_stored() {
        let (base, reg, params) = coarse_registered(Inner::Neighbours);
        let p = RomParams::default();
        let m = 2;
        let copy = Registered::from_arrays(&reg.arrays().expect("cone basis")).expect("copy");
        let model = base.clone().with_primal_starts(&reg, m, &params, &p).with_registered_dual(copy, m).expect("model");
        let (exact, sel) = model.clone().with_registered_quadrature(&params, &p, 0.0).expect("fit");
        assert!(sel.residual <= 1e-8, "fit residual {:e}", sel.residual);
        let (loose, loose_sel) = model.clone().with_registered_quadrature(&params, &p, 3e-2).expect("fit");
        assert!(loose_sel.columns.len() < sel.columns.len(), "{} of {}", loose_sel.columns.len(), sel.columns.len());
        let (mut q0, mut q1, mut q2) = (QueryModel::new(&model), QueryModel::new(&exact), QueryModel::new(&loose));
        let (mut w0, mut w1, mut w2) = (RomWork::default(), RomWork::default(), RomWork::default());
        let mut moved = 0;
        for d in coarse_tests() {
            // the quadrature is applied at each point: its slaves, not the whole support
            assert!(q2.at(&[d]).sampled_slaves().is_some() && q0.at(&[d]).sampled_slaves().is_none(), "d_x {d}");
            let a = q0.at(&[d]).solve(&[d], &p, &mut w0);
            let b = q1.at(&[d]).solve(&[d], &p, &mut w1);
            let c = q2.at(&[d]).solve(&[d], &p, &mut w2);
            assert_eq!(
                (a.outcome, b.outcome, c.outcome),
                (RomOutcome::Converged, RomOutcome::Converged, RomOutcome::Converged),
                "d_x {d}"
            );
            let n = a.u_hat.iter().map(|x| x * x).sum::<f64>().sqrt();
            let e = a.u_hat.iter().zip(&b.u_hat).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt();
            assert!(e <= 1e-8 * n, "d_x {d}: {:e}", e / n);
            moved += usize::from(a.u_hat != c.u_hat);
        }
        assert!(moved > 0, "the loose quadrature changes answers");
        let parts = loose.parts();
        assert_eq!(parts.float("reg_quad").len(), reg.map().len(), "the weights are stored");
        let loaded = ReducedModel::from_parts(&parts).expect("parts make a model");
        assert_eq!(loaded.parts(), parts, "parts differ after a round trip");
        let mut q3 = QueryModel::new(&loaded);
        let mut w3 = RomWork::default();
        for d in coarse_tests() {
            let (a, b) = (q2.at(&[d]).solve(&[d], &p, &mut w2), q3.at(&[d]).solve(&[d], &p, &mut w3));
            assert_eq!(a, b, "d_x {d}");
        }
        let mut bad = parts.clone();
        bad.floats.iter_mut().filter(|(n, _)| *n == "reg_quad").for_each(|(_, v)| v.push(1.0));
        assert!(ReducedModel::from_parts(&bad).err().is_some_and(|e| e.to_string().contains("reg_quad")));
        assert!(matches!(base.with_registered_quadrature(&params, &p, 0.0), Err(crate::rom::RomError::Sampling(_))));
        assert!(matches!(
            model.with_registered_quadrature(&params, &p, f64::NAN),
            Err(crate::rom::RomError::Sampling(_))
        ));
    }

    fn stored_registered_model_answers(inner: Inner, m: usize) {
        let (base, reg, params) = coarse_registered(inner);
        let ru = base.ranks().0;
        let mus = coarse_mus();
        let copy = Registered::from_arrays(&reg.arrays().expect("cone basis")).expect("copy");
        // both start their re-pairings from the answers at the training points (the online
        // comparison's and the model stage's step)
        let p = RomParams::default();
        let base = base.with_primal_starts(&reg, m, &params, &p);
        let stored = base.clone().with_registered_dual(copy, m).expect("registered model");
        assert_eq!(stored.stored_ranks(), (ru, m));
        let parts = stored.parts();
        let loaded = ReducedModel::from_parts(&parts).expect("parts make a model");
        assert_eq!(loaded.parts(), parts, "parts differ after a round trip");
        // every array is listed (a file reader reads the listed names only)
        assert!(parts.scalars.iter().all(|(n, _)| ModelParts::SCALARS.contains(n)));
        assert!(parts.floats.iter().all(|(n, _)| ModelParts::FLOATS.contains(n)));
        // all but `reg_dims`, written for a moments map over several parameter components only
        assert_eq!(parts.scalars.len(), ModelParts::SCALARS.len() - 1);
        assert_eq!(parts.float("reg_travels").len(), if inner == Inner::Neighbours { mus.len() } else { 0 });
        let mut query = QueryModel::new(&loaded);
        let (mut wa, mut wb) = (RomWork::default(), RomWork::default());
        for d in coarse_tests() {
            let mu = [d];
            let mut online = base.clone();
            online.set_dual_of(&reg, &mu, m);
            let a = online.solve(&mu, &p, &mut wa);
            let model = query.at(&mu);
            let b = model.solve(&mu, &p, &mut wb);
            assert_eq!(a.outcome, RomOutcome::Converged, "{inner:?}: d_x {d}");
            assert_eq!(a, b, "{inner:?}: d_x {d}");
            let (pa, pb) = (online.pressure(&a.lambda_hat), model.pressure(&b.lambda_hat));
            assert!(pa.iter().zip(&pb).all(|(s, t)| s.to_bits() == t.to_bits()), "{inner:?}: pressure at d_x {d}");
            assert!(pa.iter().any(|&v| v > 0.0), "{inner:?}: no contact at d_x {d}");
        }
        let damaged = |name: &'static str, value: u64| {
            let mut q: ModelParts = parts.clone();
            q.scalars.iter_mut().filter(|(n, _)| *n == name).for_each(|(_, v)| *v = value);
            ReducedModel::from_parts(&q).err().map(|e| e.to_string())
        };
        assert!(damaged("reg_map", 9).is_some_and(|e| e.contains("reg_map")));
        assert!(damaged("reg_len", 3).is_some_and(|e| e.contains("reg_modes")));
        if inner == Inner::Neighbours {
            let mut q: ModelParts = parts.clone();
            q.floats.iter_mut().filter(|(n, _)| *n == "reg_weight").for_each(|(_, v)| v.push(1.0));
            assert!(ReducedModel::from_parts(&q).err().is_some_and(|e| e.to_string().contains("reg_weight")));
        }
    }
}
