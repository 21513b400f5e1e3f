//! The warm-start library of the exact solve: sample parameters with their active sets (and,
//! Type-2, their answers), and how a query starts from the nearest of them.

use super::{Algorithm, ReducedModel, RomOutcome, RomParams, RomWork, SurfaceData};
use crate::dual::DualApprox;

/// Sample parameters (row-major, `dim` per point) and the active sets of the exact solve there:
/// a Type-1 query starts the QP from the set of the nearest sample.
#[derive(Debug, Clone, Default)]
pub(super) struct WarmStarts {
    pub(super) dim: usize,
    pub(super) points: Vec<f64>,
    pub(super) sets: Vec<Vec<usize>>,
    /// Type-2: the answers `y` at the samples (`r_u` each), where a query's re-pairing starts.
    pub(super) ys: Vec<Vec<f64>>,
}

/// At most this many samples in a warm-start library (evenly spaced among those offered), so
/// the nearest-sample scan in the query stays a few dozen distance evaluations.
pub const WARM_START_SAMPLES: usize = 64;

impl ReducedModel {
    /// The model with a warm-start library for queries of [`Algorithm::Exact`]: the exact
    /// solve (cold) at up to [`WARM_START_SAMPLES`] of `points` (evenly spaced, typically the
    /// training parameters), its active set and, Type-2, its answer `y`. A query starts from
    /// the nearest sample (Euclidean distance in the parameter): the QP from the sample's
    /// active set instead of the unconstrained minimiser, and Type-2 the re-pairing from the
    /// sample's `y`, interpolated toward a neighbouring sample's (`seed_warm`), instead of
    /// `y = 0`. The Type-1 QP is strictly convex, so the answer is the
    /// same (to round-off) from any start; only the number of active-set steps changes — from
    /// the 4–8 a cold start needs to reach the rope's 1–2 active constraints, to about one
    /// when the nearest sample's set is right. A Type-2 re-pairing converges to the same fixed
    /// point from either start wherever it has one (full bases: the full-order solution;
    /// measured on ironing-fine with 128 training points, before the interpolated starts and
    /// Newton-corrected steps (docs/design-notes.md#newton-corrected-re-pairing-steps): cold and warm agree to 1e-10 at
    /// every test point for ranks from (16, 60) to (128, 128)); where a truncated reduced
    /// problem has several, the start picks one (there: 1 of 127 points at (128, 16) and 4 at
    /// (8, 8) moved, by at most 2.7e-5 relative, against median model errors of 4.7e-3 and
    /// 1.2e-2).
    /// The paper algorithm is returned unchanged. Offline work: one solve per sample.
    pub fn with_warm_starts(mut self, points: &[Vec<f64>], p: &RomParams) -> Self {
        self.warm_starts = WarmStarts::default();
        if p.algorithm != Algorithm::Exact || points.is_empty() {
            return self;
        }
        self.warm_starts = sample(&mut self, points, p, true, |_, _| {});
        self
    }

    /// The model with a library of primal starts for a dual basis that changes per query
    /// (`approx`'s cone basis at each point, at most `m` columns: a registered or a local basis):
    /// at up to [`WARM_START_SAMPLES`] of `points` (evenly spaced; all 128 training points of
    /// ironing-fine instead of 64 start no closer: the same times to 2 %) the exact solve (cold)
    /// with the basis at that
    /// point, and its answer `y`, with an empty active set — the active sets would index one
    /// point's basis, the answers `y` do not. A query then starts its re-pairing from the
    /// nearest samples' `y` (`seed_warm`) and its QP cold, so only the path changes, as
    /// with [`Self::with_warm_starts`]. Type-2 only (a Type-1 query does not re-pair: the model
    /// is returned unchanged), and the exact algorithm only. The model's own dual basis is left
    /// as it is.
    pub fn with_primal_starts(mut self, approx: &dyn DualApprox, m: usize, points: &[Vec<f64>], p: &RomParams) -> Self {
        self.warm_starts = WarmStarts::default();
        if p.algorithm != Algorithm::Exact || points.is_empty() || !matches!(self.surf, SurfaceData::Nts { .. }) {
            return self;
        }
        let mut probe = self.clone();
        self.warm_starts = sample(&mut probe, points, p, false, |model, mu| model.set_dual_of(approx, mu, m));
        self
    }

    /// Start `w.warm` for a cold query at `mu`: the nearest warm-start sample's active set, if
    /// any, and (Type-2) the re-pairing's first point `y`: the nearest sample's `y`, moved
    /// linearly toward a second sample's when `mu` projects inside the segment between the two
    /// (of those, the sample nearest to `mu`; between neighbouring training points of a single
    /// parameter, the neighbour on the other side): `y = y_k + t (y_o - y_k)`,
    /// `t = (mu - mu_k)·(mu_o - mu_k) / |mu_o - mu_k|²` in `(0, 1]`. Between two neighbouring
    /// training points of ironing-fine this starts 2.5x closer to the answer than the nearest
    /// sample (relative distance 1.7e-2 against 4.3e-2; docs/design-notes.md#newton-corrected-re-pairing-steps). Only the path
    /// changes: the re-pairing converges to the same fixed point wherever it has one.
    pub(super) fn seed_warm(&self, mu: &[f64], w: &mut RomWork) {
        w.warm.clear();
        let lib = &self.warm_starts;
        if lib.sets.is_empty() || mu.len() != lib.dim {
            return;
        }
        let dim = lib.dim.max(1);
        let point = |k: usize| &lib.points[k * dim..(k + 1) * dim];
        let d2 = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
        let mut best = (f64::INFINITY, 0);
        for k in 0..lib.sets.len() {
            let d = d2(point(k), mu);
            if d < best.0 {
                best = (d, k);
            }
        }
        let k = best.1;
        w.warm.extend_from_slice(&lib.sets[k]);
        let Some(yk) = lib.ys.get(k) else { return };
        w.u_hat.copy_from_slice(yk);
        let pk = point(k);
        let mut toward: Option<(f64, usize, f64)> = None;
        for o in (0..lib.ys.len()).filter(|&o| o != k) {
            let po = point(o);
            let len2 = d2(po, pk);
            let t = pk.iter().zip(po).zip(mu).map(|((a, b), m)| (m - a) * (b - a)).sum::<f64>() / len2;
            let d = d2(po, mu);
            if len2 > 0.0 && t > 0.0 && t <= 1.0 && toward.is_none_or(|(best, _, _)| d < best) {
                toward = Some((d, o, t));
            }
        }
        if let Some((_, o, t)) = toward {
            for (u, (a, b)) in w.u_hat.iter_mut().zip(yk.iter().zip(&lib.ys[o])) {
                *u = a + t * (b - a);
            }
        }
    }
}

/// A library from the exact solve (cold, `model` holding no library) at up to
/// [`WARM_START_SAMPLES`] of `points`, evenly spaced: `prepare` readies the model at each point
/// (its dual basis there, for a basis set per query); every converged point is kept with its
/// active set (empty unless `sets`) and, Type-2, its answer `y`.
fn sample(
    model: &mut ReducedModel,
    points: &[Vec<f64>],
    p: &RomParams,
    sets: bool,
    mut prepare: impl FnMut(&mut ReducedModel, &[f64]),
) -> WarmStarts {
    let repairs = matches!(model.surf, SurfaceData::Nts { .. });
    let n = points.len();
    let take = n.min(WARM_START_SAMPLES);
    let mut lib = WarmStarts { dim: points[0].len(), ..WarmStarts::default() };
    let mut w = RomWork::default();
    for k in 0..take {
        let mu = &points[if take == n { k } else { k * (n - 1) / (take - 1).max(1) }];
        if mu.len() != lib.dim {
            continue;
        }
        prepare(model, mu);
        let info = model.solve_in(mu, p, &mut w);
        if info.outcome == RomOutcome::Converged {
            lib.points.extend_from_slice(mu);
            lib.sets.push(if sets { w.qp.active.clone() } else { Vec::new() });
            if repairs {
                lib.ys.push(w.u_hat.clone());
            }
        }
    }
    lib
}

#[cfg(test)]
mod tests {
    use crate::rom::reduced::test_support::{coarse_mus, compare_solves, full_rom, points};
    use crate::rom::{RomParams, RomWork};
    use crate::testing::ironing_coarse;

    /// Type-2 warm starts (docs/design-notes.md#warm-starts) change the steps, not the answer, where the
    /// re-pairing has one fixed point: ironing-coarse, 17 training points, full bases, 48 test
    /// points between them: warm-started answers equal the cold ones to 1e-8 relative (each
    /// solve stops within `u_tol` = 1e-10 of the fixed point; measured 6.7e-11), and the warm
    /// starts take fewer linearisations in all (measured 152 against 194).
    #[test]
    fn type2_warm_starts_change_the_steps_not_the_answer() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (cold, _, _) = full_rom(fm, &mus);
        let p = RomParams::default();
        let samples = points(&mus);
        let warm = cold.clone().with_warm_starts(&samples, &p);
        let (mut wc, mut ww) = (RomWork::default(), RomWork::default());
        let (worst, lin_cold, lin_warm) = compare_solves((&cold, &mut wc), (&warm, &mut ww), &p);
        assert!(worst <= 1e-8, "warm vs cold: {worst:e}");
        assert!(lin_warm < lin_cold, "linearisations warm {lin_warm} vs cold {lin_cold}");
    }
}
