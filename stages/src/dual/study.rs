//! The metrics of every dual approximation, by one code path:
//!
//! * compactness `C(m) = sqrt(sum_j ||s_j - Pi_m(s_j; mu_j)||^2) / ||S||_F` over the training
//!   set (eq. 16; for a parameter-dependent approximation each snapshot at its own `mu_j`);
//! * generalization `G(m)`, leave-one-out (eq. 17): for each fold i the approximation is built
//!   again from the other snapshots and `s_i` is projected at `mu_i`; mean, population standard
//!   deviation and count of `||s_i - Pi_m(s_i)|| / ||s_i||` over the folds;
//! * the test error `T(m)`: the same relative error for each test snapshot at its own `mu`,
//!   with the approximation built from the whole training set (the comparison's headline measure);
//! * the nested error `H(n)` (eq. 19): built from level n, the relative Frobenius error of
//!   level n + 1's snapshots, at the largest m of the grid (the same budget for every
//!   approach: the paper's H uses the whole span or cone of level n, the same where level n
//!   has at most that many snapshots);
//! * the specificity `S(m)` (eq. 18, [`specificity`]).
//!
//! Zero snapshots have no relative error: they are skipped and counted, never divided by.
//! Snapshots and folds are evaluated in parallel; each result lands in its own slot and the
//! statistics are accumulated in index order, so the numbers do not depend on the thread
//! count.

use faer::MatRef;
use rayon::prelude::*;

use super::{build, Approach, DualApprox, DualError, Training};
use crate::cone::norm2;
use crate::running_stats::RunningStats;

/// Relative errors of each column of `s` at its parameter, per m (`None` for a zero column).
pub fn relative_errors(
    model: &dyn DualApprox,
    s: MatRef<'_, f64>,
    params: &[Vec<f64>],
    ms: &[usize],
) -> Result<Vec<Option<Vec<f64>>>, DualError> {
    let n = s.nrows();
    (0..s.ncols())
        .into_par_iter()
        .map(|j| {
            let col: Vec<f64> = (0..n).map(|i| s[(i, j)]).collect();
            let norm = norm2(&col);
            if norm == 0.0 {
                return Ok(None);
            }
            let mut out = vec![0.0; ms.len()];
            model.residuals(&col, &params[j], ms, &mut out)?;
            out.iter_mut().for_each(|e| *e /= norm);
            Ok(Some(out))
        })
        .collect()
}

/// Mean and spread per m of per-snapshot errors, and the count of zero snapshots skipped.
pub fn stats(errors: &[Option<Vec<f64>>], ms: &[usize]) -> (Vec<RunningStats>, usize) {
    let mut st = vec![RunningStats::new(); ms.len()];
    let mut zero = 0;
    for e in errors {
        match e {
            Some(v) => st.iter_mut().zip(v).for_each(|(s, x)| s.push(*x)),
            None => zero += 1,
        }
    }
    (st, zero)
}

/// `C(m)` over the training set (eq. 16 with each snapshot at its own parameter).
pub fn compactness(model: &dyn DualApprox, training: &Training<'_>) -> Result<Vec<f64>, DualError> {
    let s = training.snapshots;
    let total = s.squared_norm_l2();
    let n = s.nrows();
    let rows: Vec<Vec<f64>> = (0..s.ncols())
        .into_par_iter()
        .map(|j| {
            let col: Vec<f64> = (0..n).map(|i| s[(i, j)]).collect();
            let mut out = vec![0.0; training.ms.len()];
            if norm2(&col) > 0.0 {
                model.residuals(&col, &training.params[j], training.ms, &mut out)?;
            }
            Ok(out)
        })
        .collect::<Result<_, DualError>>()?;
    let mut sums = vec![0.0; training.ms.len()];
    for r in &rows {
        sums.iter_mut().zip(r).for_each(|(a, e)| *a += e * e);
    }
    Ok(sums.iter().map(|&a| if total > 0.0 { (a / total).sqrt() } else { 0.0 }).collect())
}

/// Leave-one-out errors of `approach` for the folds `folds` (each fold rebuilds it without
/// that snapshot), per fold (`None`: a zero snapshot); `tick` is called once per fold.
pub fn leave_one_out(
    approach: &Approach,
    training: &Training<'_>,
    folds: &[usize],
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<Option<Vec<f64>>>, DualError> {
    let n = training.snapshots.nrows();
    folds
        .par_iter()
        .map(|&i| {
            let col: Vec<f64> = (0..n).map(|r| training.snapshots[(r, i)]).collect();
            let norm = norm2(&col);
            tick();
            if norm == 0.0 {
                return Ok(None);
            }
            let (s, params) = training.without(i);
            let fold = Training { snapshots: s.as_ref(), params: &params, ..*training };
            let model = build(approach, &fold)?;
            let mut out = vec![0.0; training.ms.len()];
            model.residuals(&col, &training.params[i], training.ms, &mut out)?;
            out.iter_mut().for_each(|e| *e /= norm);
            Ok(Some(out))
        })
        .collect()
}

/// Specificity `S(m)` (eq. 18) for each m of the training's grid: `samples` random members per
/// m, each drawn at the parameter of a random training snapshot t (uniform index) with
/// coefficients uniform in `mean +- std` of the training snapshots' coordinates of t's group
/// (a local basis' cell; clipped at 0 for non-negative coefficients), compared with the closest
/// training snapshot (`min_j ||s_j - member|| / ||s_j||` over the non-zero ones). The draws
/// for m come from their own stream (`metrics::specificity`'s, `seed` mixed with m).
/// `None` for an approximation without modes (the dictionary).
pub fn specificity(
    model: &dyn DualApprox,
    training: &Training<'_>,
    samples: usize,
    seed: u64,
) -> Result<Option<Vec<RunningStats>>, DualError> {
    let s = training.snapshots;
    let (n, count) = (s.nrows(), s.ncols());
    let cols: Vec<Vec<f64>> = (0..count).map(|j| (0..n).map(|i| s[(i, j)]).collect()).collect();
    let norms: Vec<f64> = cols.iter().map(|c| norm2(c)).collect();
    let clip = model.nonnegative();
    let per_m: Vec<Option<RunningStats>> = training
        .ms
        .par_iter()
        .map(|&m| -> Result<Option<RunningStats>, DualError> {
            // Coordinates of every non-zero training snapshot, by group.
            let mut coords: Vec<Option<(usize, Vec<f64>)>> = Vec::with_capacity(count);
            for (j, c) in cols.iter().enumerate() {
                if norms[j] == 0.0 {
                    coords.push(None);
                    continue;
                }
                match model.coefficients(c, &training.params[j], m)? {
                    Some(x) => coords.push(Some(x)),
                    None => return Ok(None),
                }
            }
            let mut ranges: std::collections::BTreeMap<usize, Vec<RunningStats>> = Default::default();
            for (g, a) in coords.iter().flatten() {
                let st = ranges.entry(*g).or_insert_with(|| vec![RunningStats::new(); a.len()]);
                st.iter_mut().zip(a).for_each(|(r, x)| r.push(*x));
            }
            let owners: Vec<usize> = (0..count).filter(|&j| coords[j].is_some()).collect();
            let nearest = Nearest::new(&cols, &norms, &owners);
            let mut rng = crate::metrics::specificity_stream(seed, m);
            let mut out = RunningStats::new();
            let mut member = vec![0.0; n];
            let mut hint = 0;
            for _ in 0..samples {
                if owners.is_empty() {
                    break;
                }
                let t = owners[rng.below(owners.len())];
                let Some((g, _)) = &coords[t] else { continue };
                let alpha: Vec<f64> = ranges[g]
                    .iter()
                    .map(|r| {
                        let (lo, hi) = r.interval(clip);
                        rng.uniform_in(lo, hi)
                    })
                    .collect();
                model.member(*g, &alpha, &training.params[t], m, &mut member);
                out.push(nearest.min_relative(&member, &mut hint));
            }
            Ok(Some(out))
        })
        .collect::<Result<_, DualError>>()?;
    Ok(per_m.into_iter().collect())
}

/// Snapshots compared [`LANES`] at a time by [`Nearest::min_relative`].
const LANES: usize = 8;

/// The training snapshots a specificity sample is compared with, interleaved by lane: block
/// `k` holds snapshots `owners[LANES k ..]`, coordinate `i` of lane `l` at
/// `packed[(k n + i) LANES + l]` (a missing lane of the last block is zero and not read).
struct Nearest {
    n: usize,
    owners: usize,
    packed: Vec<f64>,
    norms: Vec<f64>,
}

impl Nearest {
    fn new(cols: &[Vec<f64>], norms: &[f64], owners: &[usize]) -> Self {
        let n = cols.first().map_or(0, Vec::len);
        let blocks = owners.len().div_ceil(LANES);
        let mut packed = vec![0.0; blocks * n * LANES];
        for (o, &j) in owners.iter().enumerate() {
            let (k, l) = (o / LANES, o % LANES);
            for (i, &v) in cols[j].iter().enumerate() {
                packed[(k * n + i) * LANES + l] = v;
            }
        }
        Self { n, owners: owners.len(), packed, norms: owners.iter().map(|&j| norms[j]).collect() }
    }

    /// `min_j ||s_j - member|| / ||s_j||` over the owners (infinite without any): each
    /// distance is the sum of `(s_ij - member_i)^2` over `i` ascending from 0, as
    /// `iter().sum()` adds them, so every value and the minimum have the bits of the plain scan
    /// ([`nearest_reference`](tests) checks it); [`LANES`] snapshots at a time, so that their
    /// sums' latency chains overlap.
    ///
    /// Exact pruning: a block of lanes is dropped once, after a multiple of [`CHECK_ROWS`]
    /// rows, every one of its partial values `sqrt(partial) / ||s_j||` exceeds the best value
    /// so far. Adding non-negative terms never decreases a floating-point sum, and `sqrt` and
    /// the division are monotone, so a dropped lane's full value exceeds the best too and the
    /// minimum keeps its bits. `hint` (a block index, updated to the winner's) is scanned
    /// first: consecutive samples tend to share their nearest snapshot.
    fn min_relative(&self, member: &[f64], hint: &mut usize) -> f64 {
        self.scan(member, hint).0
    }

    /// [`Self::min_relative`] and the number of blocks dropped before their last row.
    fn scan(&self, member: &[f64], hint: &mut usize) -> (f64, usize) {
        let n = self.n;
        let blocks = if n == 0 { 0 } else { self.packed.len() / (n * LANES) };
        let mut best = f64::INFINITY;
        let mut dropped_blocks = 0;
        if blocks == 0 {
            return (best, 0);
        }
        let first = (*hint).min(blocks - 1);
        for k in std::iter::once(first).chain((0..blocks).filter(|&k| k != first)) {
            let block = &self.packed[k * n * LANES..(k + 1) * n * LANES];
            let lanes = LANES.min(self.owners - k * LANES);
            let norms = &self.norms[k * LANES..k * LANES + lanes];
            let mut acc = [0.0f64; LANES];
            let mut dropped = false;
            for (rows, part) in block.chunks(LANES * CHECK_ROWS).zip(member.chunks(CHECK_ROWS)) {
                for (row, &b) in rows.chunks_exact(LANES).zip(part) {
                    for (a, &x) in acc.iter_mut().zip(row) {
                        *a += (x - b) * (x - b);
                    }
                }
                if best < f64::INFINITY && acc.iter().zip(norms).all(|(a, norm)| a.sqrt() / norm > best) {
                    dropped = true;
                    break;
                }
            }
            if dropped {
                dropped_blocks += 1;
                continue;
            }
            for (a, norm) in acc.iter().zip(norms) {
                let value = a.sqrt() / norm;
                if value < best {
                    best = value;
                    *hint = k;
                }
            }
        }
        (best, dropped_blocks)
    }
}

/// Rows between two pruning checks of [`Nearest::min_relative`].
const CHECK_ROWS: usize = 32;

/// The nested-set error H(n) (eq. 19) of `approach`: built from the coarser level `lower` (at
/// the largest m of its grid), the relative Frobenius error of the finer level's snapshots
/// `upper` (each at its own parameter, `upper_params`).
pub fn nested_error(
    approach: &Approach,
    lower: &Training<'_>,
    upper: MatRef<'_, f64>,
    upper_params: &[Vec<f64>],
) -> Result<f64, DualError> {
    let model = build(approach, lower)?;
    let m = [lower.max_m()];
    let n = upper.nrows();
    let sums: Vec<f64> = (0..upper.ncols())
        .into_par_iter()
        .map(|j| {
            let col: Vec<f64> = (0..n).map(|i| upper[(i, j)]).collect();
            let mut out = [0.0];
            if norm2(&col) > 0.0 {
                model.residuals(&col, &upper_params[j], &m, &mut out)?;
            }
            Ok(out[0] * out[0])
        })
        .collect::<Result<_, DualError>>()?;
    let total = upper.squared_norm_l2();
    Ok(if total > 0.0 { (sums.iter().sum::<f64>() / total).sqrt() } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_all_close;
    use crate::cone::NnlsParams;
    use crate::float_cmp::Tol;
    use crate::metrics::{compactness_orth, generalization_cone, generalization_orth};
    use crate::rng::Rng;
    use faer::Mat;

    /// The plain scan [`Nearest`] replaces.
    fn nearest_reference(cols: &[Vec<f64>], norms: &[f64], owners: &[usize], member: &[f64]) -> f64 {
        owners
            .iter()
            .map(|&j| cols[j].iter().zip(member).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt() / norms[j])
            .fold(f64::INFINITY, f64::min)
    }

    /// The lane scan gives the plain scan's bits: random snapshots and members, owner counts
    /// that fill whole blocks, leave a partial one, or are empty.
    #[test]
    fn the_lane_scan_is_the_plain_scan_bit_for_bit() {
        let mut rng = crate::rng::Rng::new(41);
        let (n, count) = (37, 21);
        let cols: Vec<Vec<f64>> = (0..count).map(|_| (0..n).map(|_| rng.uniform() - 0.3).collect()).collect();
        let norms: Vec<f64> = cols.iter().map(|c| norm2(c)).collect();
        for owners in [(0..count).collect::<Vec<_>>(), (0..16).collect(), vec![3, 5, 19], vec![]] {
            let nearest = Nearest::new(&cols, &norms, &owners);
            let mut hint = 0;
            for _ in 0..50 {
                let member: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
                let (a, b) =
                    (nearest.min_relative(&member, &mut hint), nearest_reference(&cols, &norms, &owners, &member));
                assert_eq!(a.to_bits(), b.to_bits(), "{owners:?}: {a} vs {b}");
            }
        }
    }

    /// The pruned scan gives the plain scan's bits where it prunes: moving bumps over 200 rows
    /// (six pruning checks), members near one snapshot or between two, the hint carried over
    /// from sample to sample as in [`specificity`]; and it does prune (a block dropped by the
    /// first check of a sample whose nearest snapshot lies in another block).
    #[test]
    fn the_pruned_scan_is_the_plain_scan_bit_for_bit() {
        let (n, count) = (200, 45);
        let (s, _) = bumps(n, count, 7);
        let cols: Vec<Vec<f64>> = (0..count).map(|j| (0..n).map(|i| s[(i, j)]).collect()).collect();
        let norms: Vec<f64> = cols.iter().map(|c| norm2(c)).collect();
        let mut rng = Rng::new(43);
        for owners in [(0..count).collect::<Vec<_>>(), (0..count).step_by(3).collect(), vec![40, 2, 17]] {
            let nearest = Nearest::new(&cols, &norms, &owners);
            let mut hint = 0;
            for t in 0..200 {
                let (j, k) = (rng.below(count), rng.below(count));
                let w = if t % 2 == 0 { 0.0 } else { rng.uniform() };
                let member: Vec<f64> =
                    (0..n).map(|i| (1.0 - w) * cols[j][i] + w * cols[k][i] + 1e-3 * rng.uniform()).collect();
                let (a, b) =
                    (nearest.min_relative(&member, &mut hint), nearest_reference(&cols, &norms, &owners, &member));
                assert_eq!(a.to_bits(), b.to_bits(), "{owners:?}, sample {t}: {a} vs {b}");
            }
        }
        // a member equal to snapshot 44 (the last block), its block scanned first: every other
        // block's bumps lie away from it and exceed a best value of 0 before their last row
        let nearest = Nearest::new(&cols, &norms, &(0..count).collect::<Vec<_>>());
        let mut hint = 44 / LANES;
        let (value, dropped) = nearest.scan(&cols[44], &mut hint);
        assert_eq!((value, hint), (0.0, 44 / LANES));
        assert_eq!(dropped, count.div_ceil(LANES) - 1);
    }

    /// Non-negative bumps moving along a line (a small contact-like set).
    fn bumps(n: usize, count: usize, seed: u64) -> (Mat<f64>, Vec<Vec<f64>>) {
        let mut rng = Rng::new(seed);
        let params: Vec<Vec<f64>> = (0..count).map(|j| vec![j as f64 / (count - 1) as f64]).collect();
        let s = Mat::from_fn(n, count, |i, j| {
            let c = 5.0 + params[j][0] * (n as f64 - 10.0);
            ((1.0 - ((i as f64 - c) / 3.0).powi(2)).max(0.0)) * (1.0 + 0.1 * rng.uniform())
        });
        (s, params)
    }

    /// The generic path reproduces the paper's metrics as the dedicated stages compute them:
    /// POD compactness and leave-one-out (orthogonal), CPG leave-one-out (cone, shared greedy
    /// path), on every m. Independent algorithms: SVD tails / reduced-coordinate folds / the
    /// lazy path against a rebuild per fold with Gram–Schmidt and warm NNLS prefixes.
    #[test]
    fn pod_and_cpg_through_the_interface_match_the_dedicated_metrics() {
        let (s, params) = bumps(30, 14, 1);
        let ms: Vec<usize> = (1..=13).collect();
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &[], across: &[], ms: &ms };
        let folds: Vec<usize> = (0..14).collect();
        let pod = build(&Approach::Pod, &t).expect("pod");
        let c = compactness(pod.as_ref(), &t).expect("c");
        let reference = compactness_orth(s.as_ref(), crate::dual::pod_modes(s.as_ref(), 14).expect("modes").as_ref());
        // 1e-10 absolute: both are square roots of sums of squared projections of O(1) data.
        assert_all_close!(c, reference[1..14], Tol { abs: 1e-10, rel: 1e-10 });
        let (g, _) = stats(&leave_one_out(&Approach::Pod, &t, &folds, &|| {}).expect("loo"), &ms);
        let reference = generalization_orth(s.as_ref(), 13).expect("g");
        let means: Vec<f64> = g.iter().map(RunningStats::mean).collect();
        assert_all_close!(means, reference.mean, Tol { abs: 1e-10, rel: 1e-9 });
        let (g, _) = stats(&leave_one_out(&Approach::Cpg, &t, &folds, &|| {}).expect("loo"), &ms);
        let reference = generalization_cone(s.as_ref(), 13, NnlsParams::default()).expect("g");
        let means: Vec<f64> = g.iter().map(RunningStats::mean).collect();
        // 1e-8: NNLS solutions warm-started along different chains (shared path vs fresh
        // prefixes) agree to the solver's KKT tolerance (1e-12) times the cone's condition.
        assert_all_close!(means, reference.mean, Tol { abs: 1e-8, rel: 1e-8 });
    }

    /// H(n) through the interface equals the dedicated nested metric for POD and CPG (eq. 19:
    /// the span / cone of the whole coarser level).
    #[test]
    fn nested_error_matches_the_dedicated_metric() {
        let (lo, lo_p) = bumps(30, 9, 3);
        let (hi, hi_p) = bumps(30, 17, 4);
        let ms: Vec<usize> = (1..=9).collect();
        let t = Training { snapshots: lo.as_ref(), params: &lo_p, surface: &[], across: &[], ms: &ms };
        let pod = nested_error(&Approach::Pod, &t, hi.as_ref(), &hi_p).expect("pod");
        let reference = crate::metrics::nested_error_orth(lo.as_ref(), hi.as_ref()).expect("orth");
        assert!(crate::float_cmp::close(pod, reference, Tol { abs: 1e-12, rel: 1e-10 }), "{pod} vs {reference}");
        let cpg = nested_error(&Approach::Cpg, &t, hi.as_ref(), &hi_p).expect("cpg");
        let reference =
            crate::metrics::nested_error_cone(lo.as_ref(), hi.as_ref(), NnlsParams::default()).expect("cone");
        // 1e-8: NNLS on the CPG generators (a subset of the level's snapshots spanning the same
        // cone) against NNLS on all of them; both at the solver's KKT tolerance.
        assert!(crate::float_cmp::close(cpg, reference, Tol { abs: 1e-10, rel: 1e-8 }), "{cpg} vs {reference}");
    }

    /// Specificity through the interface follows eq. 18 on POD: against a direct evaluation of
    /// the definition with the same draws (the same stream, the same interval, the same member
    /// and minimum), computed here from the SVD modes.
    #[test]
    fn pod_specificity_follows_the_definition() {
        let (s, params) = bumps(20, 10, 5);
        let ms = [1usize, 2, 4];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &[], across: &[], ms: &ms };
        let pod = build(&Approach::Pod, &t).expect("pod");
        let got = specificity(pod.as_ref(), &t, 50, 7).expect("s").expect("pod has modes");
        let modes = crate::dual::pod_modes(s.as_ref(), 10).expect("modes");
        let cols: Vec<Vec<f64>> = (0..10).map(|j| (0..20).map(|i| s[(i, j)]).collect()).collect();
        for (k, &m) in ms.iter().enumerate() {
            let coef = |c: &[f64], l: usize| -> f64 { (0..20).map(|i| modes[(i, l)] * c[i]).sum() };
            let mut st = vec![RunningStats::new(); m];
            for c in &cols {
                (0..m).for_each(|l| st[l].push(coef(c, l)));
            }
            let mut rng = crate::metrics::specificity_stream(7, m);
            let mut want = RunningStats::new();
            for _ in 0..50 {
                let _t = rng.below(10);
                let alpha: Vec<f64> = st
                    .iter()
                    .map(|r| {
                        let (lo, hi) = r.interval(false);
                        rng.uniform_in(lo, hi)
                    })
                    .collect();
                let member: Vec<f64> = (0..20).map(|i| (0..m).map(|l| alpha[l] * modes[(i, l)]).sum()).collect();
                let best = cols
                    .iter()
                    .map(|c| norm2(&c.iter().zip(&member).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm2(c))
                    .fold(f64::INFINITY, f64::min);
                want.push(best);
            }
            // 1e-9: SVD modes against their Gram-Schmidt re-orthonormalisation (signs and
            // rounding identical up to ~1e-14; the minimum over snapshots is continuous).
            assert!(crate::float_cmp::close(got[k].mean(), want.mean(), Tol { abs: 1e-12, rel: 1e-9 }), "m {m}");
        }
        let dict = build(&Approach::Dictionary, &t).expect("dictionary");
        assert!(specificity(dict.as_ref(), &t, 5, 1).expect("s").is_none());
    }

    /// Every approach builds and gives errors in [0, 1] that do not grow with m where the
    /// approximation is nested (all but NNMF, which is refactored per rank).
    #[test]
    fn every_approach_gives_bounded_errors() {
        let (s, params) = bumps(40, 16, 2);
        let x: Vec<f64> = (0..40).map(|i| i as f64).collect();
        let ms: Vec<usize> = (1..=6).collect();
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        use crate::dual::{Inner, Interpolation, MapKind};
        let approaches = [
            Approach::Pod,
            Approach::Cpg,
            Approach::AngleGreedy,
            Approach::Nnmf { iterations: 100 },
            Approach::Local { cells: 2, overlap: 0.1 },
            Approach::Dictionary,
            Approach::Registered { map: MapKind::Moments { refine: 2 }, inner: Inner::Cpg },
            Approach::Registered {
                map: MapKind::Translate { interpolation: Interpolation::Linear { refine: 2 } },
                inner: Inner::Pod,
            },
        ];
        for a in &approaches {
            let model = build(a, &t).unwrap_or_else(|e| panic!("{}: {e}", a.name()));
            // The online basis: none for signed modes, else non-negative, no zero column, at
            // most m columns (the dictionary: all its atoms).
            let signed = matches!(a, Approach::Pod | Approach::Registered { inner: Inner::Pod, .. });
            match model.cone_basis(&params[3], 3) {
                None => assert!(signed, "{} has no online basis", a.name()),
                Some(b) => {
                    assert!(!signed, "{} has signed modes", a.name());
                    let cap = if matches!(a, Approach::Dictionary) { 16 } else { 3 };
                    assert!(b.ncols() >= 1 && b.ncols() <= cap, "{}: {} columns", a.name(), b.ncols());
                    for j in 0..b.ncols() {
                        assert!(b.col(j).iter().all(|&v| v >= 0.0), "{}: negative entry", a.name());
                        assert!(b.col(j).iter().any(|&v| v > 0.0), "{}: zero column", a.name());
                    }
                }
            }
            let errs = relative_errors(model.as_ref(), s.as_ref(), &params, &ms).expect("errors");
            for e in errs.iter().flatten() {
                assert!(e.iter().all(|v| (0.0..=1.0 + 1e-12).contains(v)), "{}: {e:?}", a.name());
                if !matches!(a, Approach::Nnmf { .. }) {
                    assert!(e.windows(2).all(|w| w[1] <= w[0] + 1e-12), "{}: {e:?}", a.name());
                }
            }
        }
    }
}
