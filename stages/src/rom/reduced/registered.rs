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

/// The registered basis of a model and the most generators a query uses.
#[derive(Debug, Clone)]
pub(super) struct PerQueryDual {
    pub(super) basis: Arc<Registered>,
    pub(super) m: usize,
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
        self.per_query = Some(PerQueryDual { basis: Arc::new(basis), m });
        Ok(self)
    }

    /// Before a query at `mu`: a model with a registered dual basis sets it to the basis at `mu`
    /// ([`Self::set_dual_of`]); a model with a fixed one is left as it is.
    pub fn dual_at(&mut self, mu: &[f64]) {
        if let Some(d) = self.per_query.take() {
            self.set_dual_of(d.basis.as_ref(), mu, d.m);
            self.per_query = Some(d);
        }
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
