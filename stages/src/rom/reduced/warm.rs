//! The warm-start library of the exact solve: sample parameters with their active sets (and,
//! Type-2, their answers), and how a query starts from the nearest of them.

use super::nts3::Nts3;
use super::{Algorithm, ReducedModel, RomOutcome, RomParams, RomWork, SurfaceData};
use crate::contact3d::surface::{FacetGrid, Located, ONLINE_REACH};
use crate::dual::DualApprox;
use crate::rom::la::dot;

/// Sample parameters (row-major, `dim` per point) and the active sets of the exact solve there:
/// a Type-1 query starts the QP from the set of the nearest sample.
#[derive(Debug, Clone, Default)]
pub(super) struct WarmStarts {
    pub(super) dim: usize,
    pub(super) points: Vec<f64>,
    pub(super) sets: Vec<Vec<usize>>,
    /// Type-2: the answers `y` at the samples (`r_u` each), where a query's re-pairing starts.
    pub(super) ys: Vec<Vec<f64>>,
    /// Type-2: the contact dofs' displacements `Psi_c y` at the samples (`2 n_contact` each,
    /// [`WarmStarts::place`]): the first linearisation of a query takes its positions from
    /// them instead of from a row product per contact dof. Derived, not stored in the model
    /// file; empty (or stale in length) means the positions are computed.
    pub(super) moves: Vec<f64>,
    /// Type-2 in 3-D: per sample, the contact nodes' positions at its answer (slaves, then
    /// masters) and what a search of each non-fixed slave there proves
    /// ([`crate::contact3d::surface::Located`]): a query's first linearisation carries these
    /// proofs over from its nearest sample ([`ReducedModel::seed_warm`]). Derived, not stored
    /// in the model file ([`WarmStarts::locate3`]); empty means every slave is searched.
    pub(super) at3: Vec<Vec<[f64; 3]>>,
    pub(super) located3: Vec<Vec<Option<Located>>>,
}

impl WarmStarts {
    /// Fill [`WarmStarts::moves`] from the answers and `phi_c` (row-major, `r` columns): each
    /// entry the same [`dot`] the positions would take at the sample itself.
    pub(super) fn place(&mut self, phi_c: &[f64], r: usize) {
        self.moves.clear();
        if r == 0 {
            return;
        }
        for y in &self.ys {
            self.moves.extend(phi_c.chunks_exact(r).map(|row| dot(row, y)));
        }
    }

    /// Fill [`WarmStarts::at3`] and [`WarmStarts::located3`] for the 3-D surface `d` (`r`
    /// primal columns): at each sample `(mu_k, y_k)` the contact nodes at
    /// `X_c + u0_c(mu_k) + Psi_c y_k` and a search ([`FacetGrid::pair_located`]) of every
    /// non-fixed slave with finite coordinates there. Any positions would do: a proof holds at
    /// the positions it was found at, and a query adds how far its start lies from them.
    pub(super) fn locate3(&mut self, d: &Nts3, r: usize) {
        self.at3.clear();
        self.located3.clear();
        let dim = self.dim.max(1);
        if r == 0 || self.ys.len() * dim != self.points.len() {
            return;
        }
        let ncd = 3 * (d.ns + d.nm);
        let mut base = vec![0.0; ncd];
        for (k, y) in self.ys.iter().enumerate() {
            // the positions a query at the sample would place there (`RomWork::prepare`, `place3`)
            super::work::affine_into(&d.a_terms, &self.points[k * dim..(k + 1) * dim], &mut base);
            let at: Vec<[f64; 3]> = (0..d.ns + d.nm)
                .map(|c| {
                    std::array::from_fn(|j| {
                        let cd = 3 * c + j;
                        (base[cd] + d.x_ref[c][j]) + dot(&d.phi_c[cd * r..(cd + 1) * r], y)
                    })
                })
                .collect();
            let xm = &at[d.ns..];
            let mut grid = FacetGrid::new(&d.master, xm);
            let located = (0..d.ns)
                .map(|s| {
                    let xs = at[s];
                    if d.slave_fixed[s] || xs.iter().any(|v| !v.is_finite()) {
                        None
                    } else {
                        grid.pair_located(&d.master, xm, xs, None, ONLINE_REACH).1
                    }
                })
                .collect();
            self.at3.push(at);
            self.located3.push(located);
        }
    }
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
        self.warm_starts = sample(&self, points, p, true, None);
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
    /// with [`Self::with_warm_starts`]. Type-2 only, node-to-segment and node-to-surface (a
    /// Type-1 query does not re-pair: the model is returned unchanged), and the exact algorithm
    /// only. The model's own dual basis is left as it is.
    pub fn with_primal_starts(mut self, approx: &dyn DualApprox, m: usize, points: &[Vec<f64>], p: &RomParams) -> Self {
        self.warm_starts = WarmStarts::default();
        let repairs = matches!(self.surf, SurfaceData::Nts { .. } | SurfaceData::Nts3(_));
        if p.algorithm != Algorithm::Exact || points.is_empty() || !repairs {
            return self;
        }
        let prepare = |model: &mut ReducedModel, mu: &[f64]| model.set_dual_of(approx, mu, m);
        self.warm_starts = sample(&self, points, p, false, Some(&prepare));
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
    ///
    /// Where the library holds the samples' displacements ([`WarmStarts::place`]), the contact
    /// positions at that start are placed too, `base + m_k + t (m_o - m_k)` with `m = Psi_c y`
    /// at the samples: the first linearisation then needs no row product (on ironing-fine the
    /// positions of every supported slave and every master, a tenth of a query).
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
        let mut other = None;
        if let Some((_, o, t)) = toward {
            for (u, (a, b)) in w.u_hat.iter_mut().zip(yk.iter().zip(&lib.ys[o])) {
                *u = a + t * (b - a);
            }
            other = Some((o, t));
        }
        // the positions at this start, moved as `y` was (the same line between the two samples)
        let l = &mut w.lin;
        let ncd = l.base.len();
        if ncd > 0 && lib.moves.len() == lib.ys.len() * ncd {
            let at = |k: usize| &lib.moves[k * ncd..(k + 1) * ncd];
            let mk = at(k);
            match other {
                Some((o, t)) => {
                    for (((x, b), a), c) in l.xc.iter_mut().zip(&l.base).zip(mk).zip(at(o)) {
                        *x = b + (a + t * (c - a));
                    }
                }
                None => {
                    for ((x, b), a) in l.xc.iter_mut().zip(&l.base).zip(mk) {
                        *x = b + a;
                    }
                }
            }
            l.placed_at_start = true;
        }
        // 3-D: the nearest sample's proofs, found at its positions; the first linearisation
        // adds how far each slave and the masters lie from those (`linearize3`)
        if let (SurfaceData::Nts3(d), Some(located), Some(at)) = (&self.surf, lib.located3.get(k), lib.at3.get(k)) {
            if located.len() == d.ns && at.len() == d.ns + d.nm && l.located3.len() == d.ns {
                l.located3.copy_from_slice(located);
                l.last3.copy_from_slice(&at[..d.ns]);
                l.moved3.iter_mut().for_each(|m| *m = 0.0);
                l.xm3_prev.clear();
                l.xm3_prev.extend_from_slice(&at[d.ns..]);
            }
        }
    }
}

/// Readies a copy of the model at a sample's point ([`sample`]).
type Prepare<'a> = &'a (dyn Fn(&mut ReducedModel, &[f64]) + Sync);

/// A converged sample of [`sample`]: its point, active set and answer `y`.
type Solved<'a> = (&'a [f64], Vec<usize>, Vec<f64>);

/// A library from the exact solve (cold, `model` holding no library) at up to
/// [`WARM_START_SAMPLES`] of `points`, evenly spaced: `prepare` readies a copy of the model at
/// each point (its dual basis there, for a basis set per query; `None`: the model as it is);
/// every converged point is kept with its active set (empty unless `sets`) and, Type-2, its
/// answer `y`.
///
/// The samples are solved in parallel, one contiguous run of them per thread, each run with its
/// own work buffers (and, with `prepare`, its own copy of the model). A cold solve reads only
/// the model, its point and buffers it overwrites (as the timed queries rely on,
/// `pipeline::dag::timing`), so the library is the one a loop over the samples in order
/// builds, whatever the thread count; on ironing-fine's whole run the 100-odd libraries, 64
/// cold solves each, were 0.3 s on one core.
fn sample(
    model: &ReducedModel,
    points: &[Vec<f64>],
    p: &RomParams,
    sets: bool,
    prepare: Option<Prepare<'_>>,
) -> WarmStarts {
    use rayon::prelude::*;
    let repairs = matches!(model.surf, SurfaceData::Nts { .. } | SurfaceData::Nts3(_));
    let n = points.len();
    let take = n.min(WARM_START_SAMPLES);
    let mut lib = WarmStarts { dim: points[0].len(), ..WarmStarts::default() };
    let picked: Vec<&[f64]> = (0..take)
        .map(|k| points[if take == n { k } else { k * (n - 1) / (take - 1).max(1) }].as_slice())
        .filter(|mu| mu.len() == lib.dim)
        .collect();
    let chunk = picked.len().div_ceil(rayon::current_num_threads().max(1)).max(1);
    // per sample: (point, active set, y) of a converged solve
    let solved: Vec<Vec<Option<Solved<'_>>>> = picked
        .par_chunks(chunk)
        .map(|run| {
            let mut w = RomWork::default();
            let mut own = prepare.map(|_| model.clone());
            run.iter()
                .map(|&mu| {
                    let m = match (own.as_mut(), prepare) {
                        (Some(o), Some(f)) => {
                            f(o, mu);
                            &*o
                        }
                        _ => model,
                    };
                    let info = m.solve_in(mu, p, &mut w);
                    (info.outcome == RomOutcome::Converged).then(|| {
                        let set = if sets { w.qp.active.clone() } else { Vec::new() };
                        (mu, set, if repairs { w.u_hat.clone() } else { Vec::new() })
                    })
                })
                .collect()
        })
        .collect();
    for (mu, set, y) in solved.into_iter().flatten().flatten() {
        lib.points.extend_from_slice(mu);
        lib.sets.push(set);
        if repairs {
            lib.ys.push(y);
        }
    }
    match &model.surf {
        SurfaceData::Nts { phi_c, .. } => lib.place(phi_c, model.r_u),
        SurfaceData::Nts3(d) => lib.locate3(d, model.r_u),
        _ => {}
    }
    lib
}

#[cfg(test)]
mod tests {
    use crate::rom::reduced::linearise::set_positions;
    use crate::rom::reduced::test_support::{coarse_mus, coarse_tests, compare_solves, full_rom, points};
    use crate::rom::reduced::SurfaceData;
    use crate::rom::{RomParams, RomWork};
    use crate::testing::ironing_coarse;

    /// The positions a query's first linearisation takes from the samples' displacements are
    /// the positions at its warm start: ironing-coarse, 17 training points, full bases with
    /// warm starts; at each of the 48 test points (between two samples, so the start is
    /// interpolated) every contact dof of `xc` after `seed_warm` against `base + Psi_c y` by
    /// row products at the seeded `y`. Tolerance 1e-12 of the largest displacement: the same
    /// products summed before or after the interpolation (a few ulps of the displacements).
    /// Without the interpolation the gap is the distance between the start and the nearest
    /// sample (the test fails).
    #[test]
    fn warm_positions_are_the_positions_at_the_start() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (cold, _, _) = full_rom(fm, &mus);
        let warm = cold.with_warm_starts(&points(&mus), &RomParams::default());
        let SurfaceData::Nts { phi_c, .. } = &warm.surf else { panic!("ironing is node-to-segment") };
        assert!(!warm.warm_starts.moves.is_empty());
        let mut w = RomWork::default();
        for d in coarse_tests() {
            w.prepare(&warm, &[d]);
            warm.seed_warm(&[d], &mut w);
            assert!(w.lin.placed_at_start, "d_x {d}");
            let l = &w.lin;
            let ncd = l.base.len();
            let mut want = vec![f64::NAN; ncd];
            set_positions(phi_c, warm.r_u, &w.u_hat, &l.base, &mut want, 0..ncd / 2);
            let scale = want.iter().zip(&l.base).fold(0.0f64, |m, (x, b)| m.max((x - b).abs()));
            assert!(scale > 0.0, "d_x {d}: a start that moves the surface");
            for (cd, (got, want)) in l.xc.iter().zip(&want).enumerate() {
                assert!((got - want).abs() <= 1e-12 * scale, "d_x {d} dof {cd}: {got} vs {want}");
            }
        }
    }

    /// The library is solved in parallel runs ([`super::sample`]) and is, bit for bit, the one
    /// the loop it replaced builds: every sample solved in order with one work buffer carried
    /// from each solve to the next (the reference kept here). Ironing-coarse, full bases, the 48
    /// test points as samples (so each thread's run is several solves long), on pools of 1, 2
    /// and 3 threads, with the model as it is and with a copy readied per sample (`prepare`);
    /// points, active sets, answers and the placed displacements are compared as bits.
    #[test]
    fn the_parallel_library_is_the_sequential_loops() {
        use super::{sample, WarmStarts};
        use crate::rom::RomOutcome;
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (model, _, _) = full_rom(fm, &mus);
        let p = RomParams::default();
        let samples = points(&coarse_tests());
        let mut want = WarmStarts { dim: 1, ..WarmStarts::default() };
        let mut w = RomWork::default();
        for mu in &samples {
            if model.solve_in(mu, &p, &mut w).outcome == RomOutcome::Converged {
                want.points.extend_from_slice(mu);
                want.sets.push(w.qp.active.clone());
                want.ys.push(w.u_hat.clone());
            }
        }
        let SurfaceData::Nts { phi_c, .. } = &model.surf else { panic!("ironing is node-to-segment") };
        want.place(phi_c, model.r_u);
        assert!(want.sets.len() > 40, "most samples converge: {}", want.sets.len());
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let no_op = |_: &mut crate::rom::ReducedModel, _: &[f64]| {};
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            for prepare in [None, Some(&no_op as super::Prepare<'_>)] {
                let got = pool.install(|| sample(&model, &samples, &p, true, prepare));
                let case = format!("{threads} threads, prepare {}", prepare.is_some());
                assert_eq!(bits(&got.points), bits(&want.points), "{case}");
                assert_eq!(got.sets, want.sets, "{case}");
                assert_eq!(got.ys.len(), want.ys.len(), "{case}");
                for (a, b) in got.ys.iter().zip(&want.ys) {
                    assert_eq!(bits(a), bits(b), "{case}");
                }
                assert_eq!(bits(&got.moves), bits(&want.moves), "{case}");
            }
        }
    }

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
