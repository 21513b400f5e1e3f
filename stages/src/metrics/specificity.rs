//! Specificity (paper eq. 18):
//!
//! ```text
//! S(m) = 1/N_s sum_{i=1}^{N_s} min_{s_j in S_tr} ||s_j - Psi[:, :m] alpha_i|| / ||s_j||
//! ```
//!
//! how far random members of the reduced space are from the closest training snapshot.
//!
//! * Reduced coordinates of the training snapshots on the first m basis vectors: for POD modes
//!   (orthonormal) `Gamma = Psi[:, :m]^T S`, which does not depend on m beyond its row count;
//!   for a CPG cone basis the NNLS coefficients (eq. 12) of each snapshot on the first m
//!   generators, which do. Every training snapshot contributes, a zero one with coordinates 0.
//! * Per coordinate k < m, the mean `mu_k` and population standard deviation `sigma_k` over the
//!   N training snapshots; `alpha_ik` uniform in `[mu_k - sigma_k, mu_k + sigma_k]` for POD and
//!   in `[max(0, mu_k - sigma_k), mu_k + sigma_k]` for the cone (the interval is clipped, so
//!   every sample is a non-negative combination of non-negative generators — a pressure field,
//!   docs/scenes.md#study-settings). The POD basis is not centred, so no mean field is added.
//! * `min_j` runs over the training snapshots with `||s_j|| > 0`; zero ones are counted in
//!   [`MetricCurve::n_zero`]. With no non-zero snapshot there is nothing to compare: count 0
//!   and NaN for that m.
//! * Mean and population standard deviation over the `samples` draws, for m = 1..=k (k basis
//!   vectors given). The draws for m come from their own stream `Rng::new(mix(seed, m))`, so
//!   S(m) does not depend on which other m are computed (or on the basis size beyond m), and
//!   the sizes m are computed in parallel (rayon) with the same numbers bit for bit.
//!
//! # Distances without cancellation and without forming `Psi alpha`
//!
//! Let `Q` (n x q) be orthonormal with the basis in its span: `Q = Psi` for POD, and
//! `Theta = Q R` (thin QR, R upper trapezoidal q x k) for a cone basis. With the coordinates
//! `c_j = Q^T s_j` and the explicit residual `s_j - Q c_j`, a member `r = Q beta` whose frame
//! coordinates `beta` vanish beyond the first p (POD: `beta = alpha`, p = m; cone:
//! `beta = R[:, :m] alpha`, p = min(m, q)) has
//!
//! ```text
//! ||s_j - r||^2 = ||s_j - Q c_j||^2 + sum_{l >= p} c_jl^2 + sum_{l < p} (c_jl - beta_l)^2 ,
//! ```
//!
//! a sum of non-negative terms, the first two precomputed per snapshot and p. A sample costs
//! O(N p) instead of O(n (N + m)) — independent of n, which matters for primal fields — and a
//! sample equal to a snapshot gives a round-off-level distance.

use faer::{Mat, MatRef};
use rayon::prelude::*;

use super::stats::{on_rank_grid, MetricCurve, RunningStats};
use crate::basis::CpgPath;
use crate::cone::{copy_column, ConeError, GrowingCone, NnlsParams};
use crate::rng::Rng;

/// Parameters of [`specificity_orth`] and [`specificity_cone`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpecificityParams {
    /// Number `N_s` of random members per basis size m (default 1000, as in the shipped scenes).
    pub samples: usize,
    /// Seed of the sampler (default 0; scenes record their own `study.seed`).
    pub seed: u64,
    /// Evaluate every m up to this, beyond it only the ranks of
    /// [`on_rank_grid`](super::on_rank_grid) (default `usize::MAX`: every m). Each m draws from
    /// its own stream, so an evaluated S(m) is the same number either way.
    pub dense_to: usize,
}

impl Default for SpecificityParams {
    fn default() -> Self {
        Self { samples: 1000, seed: 0, dense_to: usize::MAX }
    }
}

/// S(m) for m = 1..=k on orthonormal `modes` (n x k, POD: "primal orth", "dual orth") of the
/// training snapshots `s` (n x N).
pub fn specificity_orth(s: MatRef<'_, f64>, modes: MatRef<'_, f64>, params: SpecificityParams) -> MetricCurve {
    assert_eq!(s.nrows(), modes.nrows(), "specificity_orth: S and modes have different rows");
    debug_assert!(
        (modes.transpose() * modes - Mat::<f64>::identity(modes.ncols(), modes.ncols())).norm_l2() <= 1e-8,
        "specificity_orth: modes are not orthonormal"
    );
    specificity_on_frame(&Frame::new(s, modes), params)
}

/// [`specificity_orth`] from one [`modal_pass`](crate::blocks::modal_pass) over snapshots read
/// block by block (the snapshots' coordinates on the modes, their out-of-span and whole
/// squared norms: all the sampling reads of them).
pub fn specificity_orth_modal(modal: crate::blocks::ModalCoordinates, params: SpecificityParams) -> MetricCurve {
    specificity_on_frame(&Frame::from_parts(modal.coords, &modal.perp, &modal.norm2), params)
}

fn specificity_on_frame(frame: &Frame, params: SpecificityParams) -> MetricCurve {
    let (k, count) = frame.coords.shape();
    let ranges: Vec<(f64, f64)> = (0..k)
        .map(|l| {
            let mut st = RunningStats::new();
            (0..count).for_each(|j| st.push(frame.coords[(l, j)]));
            st.interval(false)
        })
        .collect();
    // each m draws from its own stream: the sizes run in parallel, collected in order
    let stats: Vec<RunningStats> = (1..=k)
        .into_par_iter()
        .map(|m| {
            if !on_rank_grid(m, params.dense_to, k) {
                return RunningStats::new();
            }
            sample_stats(frame, &ranges[..m], stream(params.seed, m), params.samples, m, |alpha, beta| {
                beta.copy_from_slice(alpha)
            })
        })
        .collect();
    skip_off_grid(MetricCurve::from_stats(&stats, vec![0; k], frame.n_zero()), params.dense_to)
}

/// S(m) for m = 1..=k on the cone of the first m columns of `cone_basis` (n x k, CPG:
/// "dual cone") of the training snapshots `s` (n x N); coefficients are clipped at 0. Computes
/// the sampling intervals with its own cone pass; [`specificity_cone_path`] reuses the CPG
/// path's.
pub fn specificity_cone(
    s: MatRef<'_, f64>,
    cone_basis: MatRef<'_, f64>,
    params: SpecificityParams,
    nnls: NnlsParams,
) -> Result<MetricCurve, ConeError> {
    assert_eq!(s.nrows(), cone_basis.nrows(), "specificity_cone: S and basis have different rows");
    let ranges = cone_ranges_reference(s, cone_basis, nnls)?;
    Ok(specificity_cone_with(s, cone_basis, &ranges, params, &|| {}))
}

/// S(m) for m = 1..=min(max_m, k, path.max_rank) on the cone of the first m generators of the
/// CPG path of `s` (the path of these snapshots, [`cpg_path`](crate::basis::cpg_path) with
/// `max_rank` set), with the intervals recorded by the path; `tick` is called once per m.
/// With `max_m` = the size of a CPG basis (a prefix of the path) this is
/// [`specificity_cone`] of that basis, bit for bit.
pub fn specificity_cone_path(
    s: MatRef<'_, f64>,
    path: &CpgPath,
    max_m: usize,
    params: SpecificityParams,
    tick: &(dyn Fn() + Sync),
) -> MetricCurve {
    let m = path.cone_ranges.len().min(max_m);
    specificity_cone_with(s, path.basis.subcols(0, m), &path.cone_ranges[..m], params, tick)
}

fn specificity_cone_with(
    s: MatRef<'_, f64>,
    cone_basis: MatRef<'_, f64>,
    ranges: &[Vec<(f64, f64)>],
    params: SpecificityParams,
    tick: &(dyn Fn() + Sync),
) -> MetricCurve {
    assert_eq!(s.nrows(), cone_basis.nrows(), "specificity_cone: S and basis have different rows");
    let (n, k) = cone_basis.shape();
    assert_eq!(ranges.len(), k, "specificity_cone: one set of intervals per basis size");
    let (q, r) = if n.min(k) == 0 {
        (Mat::zeros(n, 0), Mat::zeros(0, k))
    } else {
        let qr = cone_basis.qr();
        (qr.compute_thin_Q(), qr.thin_R().to_owned())
    };
    let frame = Frame::new(s, q.as_ref());
    let qdim = q.ncols();
    let stats: Vec<RunningStats> = (1..=k)
        .into_par_iter()
        .map(|m| {
            if !on_rank_grid(m, params.dense_to, k) {
                tick();
                return RunningStats::new();
            }
            let p = m.min(qdim);
            let st = sample_stats(&frame, &ranges[m - 1], stream(params.seed, m), params.samples, p, |alpha, beta| {
                // beta = R[:p, :m] alpha, R upper trapezoidal: row l starts at column l.
                for (l, b) in beta.iter_mut().enumerate() {
                    *b = (l..alpha.len()).map(|c| r[(l, c)] * alpha[c]).sum();
                }
            });
            tick();
            st
        })
        .collect();
    skip_off_grid(MetricCurve::from_stats(&stats, vec![0; k], frame.n_zero()), params.dense_to)
}

/// Mark the ranks off the grid as skipped.
fn skip_off_grid(mut curve: MetricCurve, dense_to: usize) -> MetricCurve {
    let k = curve.len();
    curve.skipped = (1..=k).map(|m| !on_rank_grid(m, dense_to, k)).collect();
    curve
}

/// Coordinates per snapshot in the screen of [`Frame::min_relative_distance`].
const HEAD: usize = 8;

/// Row length of [`Heads`]: the head, the tail, `1 / ||s_j||^2`.
const HEAD_STRIDE: usize = HEAD + 2;

/// Relative margin of the screen: far above the rounding between two summation orders of
/// nine non-negative terms (`~10 * 1.1e-16`); only decides how early a sum is abandoned.
const SCREEN_MARGIN: f64 = 1e-9;

/// Per non-zero snapshot at frame size p, one contiguous row: `c_j0 .. c_j7` (zero beyond p),
/// `tails[(p, j)]`, `1 / ||s_j||^2`. A scan reads 80 bytes per snapshot in order instead of
/// two scattered cache lines.
struct Heads {
    p: usize,
    data: Vec<f64>,
}

/// The training snapshots in an orthonormal frame `Q` (n x q).
struct Frame {
    /// `c_j = Q^T s_j`, q x N.
    coords: Mat<f64>,
    /// `tails[(p, j)] = ||s_j - Q c_j||^2 + sum_{l >= p} c_jl^2`, (q + 1) x N.
    tails: Mat<f64>,
    /// `1 / ||s_j||^2` of the non-zero snapshots, with their index.
    nonzero: Vec<(usize, f64)>,
}

impl Frame {
    fn new(s: MatRef<'_, f64>, q: MatRef<'_, f64>) -> Self {
        let coords: Mat<f64> = q.transpose() * s;
        let perp = crate::kernels::out_of_span_norms(s, q, coords.as_ref());
        let norm2: Vec<f64> = (0..s.ncols()).map(|j| s.col(j).squared_norm_l2()).collect();
        Self::from_parts(coords, &perp, &norm2)
    }

    /// From the coordinates `c_j`, `||s_j - Q c_j||^2` and `||s_j||^2` of every snapshot.
    fn from_parts(coords: Mat<f64>, perp: &[f64], norm2: &[f64]) -> Self {
        let (qdim, count) = coords.shape();
        let mut tails = Mat::zeros(qdim + 1, count);
        for j in 0..count {
            tails[(qdim, j)] = perp[j];
            for l in (0..qdim).rev() {
                tails[(l, j)] = tails[(l + 1, j)] + coords[(l, j)] * coords[(l, j)];
            }
        }
        let nonzero = (0..count).filter(|&j| norm2[j] > 0.0).map(|j| (j, 1.0 / norm2[j])).collect();
        Self { coords, tails, nonzero }
    }

    fn n_zero(&self) -> usize {
        self.coords.ncols() - self.nonzero.len()
    }

    /// The first [`HEAD`] coordinates, the tail and `1 / ||s_j||^2` of every non-zero
    /// snapshot at frame size p, packed contiguously in scan order (see [`Heads`]).
    fn heads(&self, p: usize) -> Heads {
        let mut data = Vec::with_capacity(self.nonzero.len() * HEAD_STRIDE);
        for &(j, inv_norm2) in &self.nonzero {
            let c = &self.coords.col_as_slice(j)[..p];
            let mut head = [0.0; HEAD];
            head.iter_mut().zip(c).for_each(|(h, v)| *h = *v);
            data.extend_from_slice(&head);
            data.push(self.tails[(p, j)]);
            data.push(inv_norm2);
        }
        Heads { p, data }
    }

    /// `min_j ||s_j - Q[:, :p] beta|| / ||s_j||` over non-zero snapshots (p = beta.len() =
    /// `heads.p`).
    ///
    /// Exact pruning in two stages, neither of which changes the result:
    ///
    /// * A screen on the packed heads: `(tail + sum_{l < 8} (c_jl - beta_l)^2) / ||s_j||^2`,
    ///   the first eight terms summed in independent lanes (vectorised, from one contiguous
    ///   row), is a lower bound of snapshot j's value up to rounding: the full sum in coordinate
    ///   order is at least its own first eight partial terms (non-negative terms), which differ
    ///   from the lane sum by a relative `8 eps`, plus one rounding for the tail. A snapshot
    ///   whose screen exceeds the best value by `SCREEN_MARGIN` = 1e-9 (relative) cannot be
    ///   the minimum.
    /// * The survivors are summed in coordinate order; floating-point addition of non-negative
    ///   terms never decreases a partial sum, so a partial sum above the best value stops the
    ///   sum.
    ///
    /// The minimum itself is summed in full in the same order, so the result is bit for bit
    /// that of the full scan. `hint` (an index into the non-zero snapshots, updated to the
    /// winner) is tried first: consecutive samples tend to share their nearest snapshot.
    fn min_relative_distance(&self, heads: &Heads, beta: &[f64], hint: &mut usize) -> Option<f64> {
        if self.nonzero.is_empty() {
            return None;
        }
        let p = beta.len();
        assert_eq!(p, heads.p, "min_relative_distance: heads packed for another frame size");
        let mut b = [0.0; HEAD];
        b.iter_mut().zip(beta).for_each(|(h, v)| *h = *v);
        let first = (*hint).min(self.nonzero.len() - 1);
        let mut best = f64::INFINITY;
        let mut screen_at = f64::INFINITY;
        for q in std::iter::once(first).chain((0..self.nonzero.len()).filter(|&q| q != first)) {
            let row = &heads.data[q * HEAD_STRIDE..(q + 1) * HEAD_STRIDE];
            let (tail, inv_norm2) = (row[HEAD], row[HEAD + 1]);
            let mut lanes = [0.0; HEAD];
            for l in 0..HEAD {
                lanes[l] = (row[l] - b[l]) * (row[l] - b[l]);
            }
            let head =
                ((lanes[0] + lanes[4]) + (lanes[1] + lanes[5])) + ((lanes[2] + lanes[6]) + (lanes[3] + lanes[7]));
            if (tail + head) * inv_norm2 > screen_at {
                continue;
            }
            let (j, _) = self.nonzero[q];
            let c = &self.coords.col_as_slice(j)[..p];
            let mut sum = 0.0;
            let mut pruned = false;
            for (l, (a, b)) in c.iter().zip(beta).enumerate() {
                sum += (a - b) * (a - b);
                if l % 8 == 7 && (tail + sum) * inv_norm2 > best {
                    pruned = true;
                    break;
                }
            }
            if !pruned {
                let value = (tail + sum) * inv_norm2;
                if value < best {
                    best = value;
                    screen_at = best * (1.0 + SCREEN_MARGIN);
                    *hint = q;
                }
            }
        }
        Some(best.sqrt())
    }

    /// The full scan (kept as the reference of the pruned one).
    #[cfg(test)]
    fn min_relative_distance_reference(&self, beta: &[f64]) -> Option<f64> {
        let p = beta.len();
        let mut best = f64::INFINITY;
        for &(j, inv_norm2) in &self.nonzero {
            let c = &self.coords.col_as_slice(j)[..p];
            let d2 = self.tails[(p, j)] + c.iter().zip(beta).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            best = best.min(d2 * inv_norm2);
        }
        (!self.nonzero.is_empty()).then(|| best.sqrt())
    }
}

/// The sampling intervals of the cone coordinates for every m: `ranges[m - 1]` has m entries,
/// from the NNLS coefficients of every training snapshot on the first m generators. Kept as
/// the reference: [`CpgPath::cone_ranges`] holds the same numbers from the basis' own pass.
pub fn cone_ranges_reference(
    s: MatRef<'_, f64>,
    cone_basis: MatRef<'_, f64>,
    nnls: NnlsParams,
) -> Result<Vec<Vec<(f64, f64)>>, ConeError> {
    let k = cone_basis.ncols();
    let mut cone = GrowingCone::new(s, nnls);
    let mut column = vec![0.0; s.nrows()];
    let mut all = Vec::with_capacity(k);
    for m in 1..=k {
        copy_column(cone_basis, m - 1, &mut column);
        cone.push(&column)?;
        all.push(cone.coefficient_intervals(m));
    }
    Ok(all)
}

/// The random stream of basis size m: a SplitMix64 hash of m mixed into the seed.
pub fn stream(seed: u64, m: usize) -> Rng {
    let mut z = (m as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    Rng::new(seed ^ z ^ (z >> 31))
}

/// One coefficient vector: `alpha_l` uniform in `ranges[l]`.
pub(crate) fn draw(rng: &mut Rng, ranges: &[(f64, f64)], alpha: &mut [f64]) {
    for (a, (lo, hi)) in alpha.iter_mut().zip(ranges) {
        *a = rng.uniform_in(*lo, *hi);
    }
}

/// Statistics of `samples` draws for one m (`ranges.len() == m`), `to_frame` mapping the
/// coefficients alpha (length m) to the p frame coordinates beta.
fn sample_stats<F>(
    frame: &Frame,
    ranges: &[(f64, f64)],
    mut rng: Rng,
    samples: usize,
    p: usize,
    mut to_frame: F,
) -> RunningStats
where
    F: FnMut(&[f64], &mut [f64]),
{
    let mut alpha = vec![0.0; ranges.len()];
    let mut beta = vec![0.0; p];
    let mut stats = RunningStats::new();
    let mut hint = 0;
    let heads = frame.heads(p);
    for _ in 0..samples {
        draw(&mut rng, ranges, &mut alpha);
        to_frame(&alpha, &mut beta);
        if let Some(value) = frame.min_relative_distance(&heads, &beta, &mut hint) {
            stats.push(value);
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{cpg, pod_full, CpgParams};
    use crate::basis::{cpg_path, CpgPathParams};
    use crate::cone::nnls_reference;
    use crate::float_cmp::Tol;
    use crate::testing::{bumps, hertz_family};
    use crate::{assert_all_close, assert_close};

    fn params(seed: u64) -> SpecificityParams {
        SpecificityParams { samples: 200, seed, ..SpecificityParams::default() }
    }

    /// S(m) by definition: r = Theta[:, :m] alpha formed explicitly, explicit distances.
    fn brute_force(
        s: MatRef<'_, f64>,
        basis: MatRef<'_, f64>,
        ranges: &[(f64, f64)],
        m: usize,
        p: SpecificityParams,
    ) -> (f64, f64) {
        let mut rng = stream(p.seed, m);
        let mut alpha = vec![0.0; m];
        let mut stats = RunningStats::new();
        for _ in 0..p.samples {
            draw(&mut rng, ranges, &mut alpha);
            let r = Mat::from_fn(s.nrows(), 1, |i, _| (0..m).map(|l| basis[(i, l)] * alpha[l]).sum::<f64>());
            let best = (0..s.ncols())
                .filter(|&j| s.col(j).norm_l2() > 0.0)
                .map(|j| (s.subcols(j, 1) - &r).norm_l2() / s.col(j).norm_l2())
                .fold(f64::INFINITY, f64::min);
            stats.push(best);
        }
        (stats.mean(), stats.std())
    }

    #[test]
    fn orth_matches_the_definition() {
        let mut rng = Rng::new(81);
        let s = bumps(&mut rng, 30, 12, (2.0, 6.0));
        let full = pod_full(s.as_ref()).expect("svd").modes;
        // Truncated to 6 of 12 modes, so the snapshots have a part outside the span (the
        // ||s_j - Q c_j||^2 term of the frame identity matters).
        let modes = full.subcols(0, 6);
        let p = params(5);
        let curve = specificity_orth(s.as_ref(), modes, p);
        assert_eq!((curve.len(), curve.n_zero), (modes.ncols(), 0));
        assert_eq!(curve.count, vec![p.samples; modes.ncols()]);
        // Independent intervals: two-pass mean and population std of Gamma = Psi^T S.
        let gamma = modes.transpose() * &s;
        let ranges: Vec<(f64, f64)> = (0..modes.ncols())
            .map(|l| {
                let row: Vec<f64> = (0..s.ncols()).map(|j| gamma[(l, j)]).collect();
                let mu = row.iter().sum::<f64>() / row.len() as f64;
                let sigma = (row.iter().map(|x| (x - mu) * (x - mu)).sum::<f64>() / row.len() as f64).sqrt();
                (mu - sigma, mu + sigma)
            })
            .collect();
        for m in [1, 2, 5, modes.ncols()] {
            let (mean, std) = brute_force(s.as_ref(), modes, &ranges[..m], m, p);
            // Frame identity vs explicit residuals, and Welford vs two-pass intervals: both
            // round-off on O(1) relative distances; 1e-12.
            assert_close!(curve.mean[m - 1], mean, Tol::abs(1e-12));
            assert_close!(curve.std[m - 1], std, Tol::abs(1e-12));
        }
    }

    #[test]
    fn cone_matches_the_definition() {
        let mut rng = Rng::new(82);
        let s = bumps(&mut rng, 30, 12, (2.0, 6.0));
        let full = cpg(s.as_ref(), CpgParams::default()).expect("ok").basis;
        // Truncated to 7 generators: the snapshots stick out of span(Theta) (the residual
        // term of the frame identity matters), and the last m equals the QR width.
        let basis = full.subcols(0, 7);
        let p = params(6);
        let curve = specificity_cone(s.as_ref(), basis, p, NnlsParams::default()).expect("ok");
        let ranges = cone_ranges_reference(s.as_ref(), basis, NnlsParams::default()).expect("ok");
        for m in 1..=basis.ncols() {
            let (mean, std) = brute_force(s.as_ref(), basis, &ranges[m - 1], m, p);
            // QR frame vs explicit Theta alpha: round-off (cond(Theta) ~ 10 for bumps); 1e-12.
            assert_close!(curve.mean[m - 1], mean, Tol::abs(1e-12));
            assert_close!(curve.std[m - 1], std, Tol::abs(1e-12));
        }
    }

    #[test]
    fn cone_with_more_generators_than_rows_matches_the_definition() {
        // n = 8 nodes, 16 bumps: CPG keeps more generators than n (a cone needs them), so the
        // QR frame is square and R is wide (m > q uses p = q rows).
        let mut rng = Rng::new(88);
        let s = bumps(&mut rng, 8, 16, (2.0, 6.0));
        let basis = cpg(s.as_ref(), CpgParams::default()).expect("ok").basis;
        assert!(basis.ncols() > 8, "only {} generators", basis.ncols());
        let p = params(8);
        let curve = specificity_cone(s.as_ref(), basis.as_ref(), p, NnlsParams::default()).expect("ok");
        let ranges = cone_ranges_reference(s.as_ref(), basis.as_ref(), NnlsParams::default()).expect("ok");
        for m in 1..=basis.ncols() {
            let (mean, std) = brute_force(s.as_ref(), basis.as_ref(), &ranges[m - 1], m, p);
            // As above; cond(Theta) of overlapping bumps on 8 nodes is larger, still 1e-12
            // of O(1) relative distances.
            assert_close!(curve.mean[m - 1], mean, Tol::abs(1e-12));
            assert_close!(curve.std[m - 1], std, Tol::abs(1e-12));
        }
    }

    #[test]
    fn cone_ranges_match_reference_coefficients() {
        // Independent generators (n = 30 > k): the NNLS coefficients are unique, so the
        // incremental warm-started ones must equal a cold textbook Lawson–Hanson's.
        let mut rng = Rng::new(83);
        let s = bumps(&mut rng, 30, 10, (2.0, 6.0));
        let basis = cpg(s.as_ref(), CpgParams::default()).expect("ok").basis;
        let ranges = cone_ranges_reference(s.as_ref(), basis.as_ref(), NnlsParams::default()).expect("ok");
        for m in [1, 3, basis.ncols()] {
            let mut stats = vec![RunningStats::new(); m];
            for j in 0..s.ncols() {
                let b: Vec<f64> = s.col(j).iter().copied().collect();
                let x = nnls_reference(basis.subcols(0, m), &b, NnlsParams::default()).expect("ok").x;
                x.iter().zip(stats.iter_mut()).for_each(|(a, st)| st.push(*a));
            }
            let expected: Vec<(f64, f64)> = stats.iter().map(|st| st.interval(true)).collect();
            for ((lo, hi), (elo, ehi)) in ranges[m - 1].iter().zip(&expected) {
                // Coefficients of O(1) snapshots on unit generators, round-off apart: 1e-10.
                assert_close!(*lo, *elo, Tol::abs(1e-10));
                assert_close!(*hi, *ehi, Tol::abs(1e-10));
            }
        }
    }

    #[test]
    fn reproducible_for_a_seed_and_different_for_another() {
        let mut rng = Rng::new(84);
        let s = bumps(&mut rng, 30, 12, (2.0, 6.0));
        let modes = pod_full(s.as_ref()).expect("svd").modes;
        let basis = cpg(s.as_ref(), CpgParams::default()).expect("ok").basis;
        let nnls = NnlsParams::default();
        let a = specificity_orth(s.as_ref(), modes.as_ref(), params(1));
        let b = specificity_orth(s.as_ref(), modes.as_ref(), params(1));
        let c = specificity_orth(s.as_ref(), modes.as_ref(), params(2));
        assert_all_close!(a.mean, b.mean, Tol::abs(0.0)); // same arithmetic, bit for bit
        assert!(a.mean.iter().zip(&c.mean).any(|(x, y)| (x - y).abs() > 1e-6), "seed ignored");
        let a = specificity_cone(s.as_ref(), basis.as_ref(), params(1), nnls).expect("ok");
        let b = specificity_cone(s.as_ref(), basis.as_ref(), params(1), nnls).expect("ok");
        let c = specificity_cone(s.as_ref(), basis.as_ref(), params(2), nnls).expect("ok");
        assert_all_close!(a.mean, b.mean, Tol::abs(0.0));
        assert!(a.mean.iter().zip(&c.mean).any(|(x, y)| (x - y).abs() > 1e-6), "seed ignored");
    }

    #[test]
    fn identical_snapshots_have_zero_specificity() {
        // sigma = 0: every sample is mu = the common coordinate, i.e. the snapshot itself.
        let mut rng = Rng::new(85);
        let v = bumps(&mut rng, 25, 1, (2.0, 6.0));
        let s = Mat::from_fn(25, 5, |i, _| v[(i, 0)]);
        let modes = pod_full(s.as_ref()).expect("svd").modes;
        let basis = cpg(s.as_ref(), CpgParams::default()).expect("ok").basis;
        assert_eq!((modes.ncols(), basis.ncols()), (1, 1));
        let orth = specificity_orth(s.as_ref(), modes.as_ref(), params(3));
        let cone = specificity_cone(s.as_ref(), basis.as_ref(), params(3), NnlsParams::default()).expect("ok");
        for curve in [&orth, &cone] {
            // Mean of 5 equal coordinates and one rounding per entry: 1e-12 as required.
            assert_close!(curve.mean[0], 0.0, Tol::abs(1e-12));
            assert_close!(curve.std[0], 0.0, Tol::abs(1e-12));
        }
    }

    #[test]
    fn cone_samples_are_non_negative_fields() {
        // Generators with disjoint supports; the coefficient of the second is 0 for four
        // snapshots and 1 for one: mu = 0.2, sigma = 0.4, so an unclipped interval would give
        // negative coefficients and negative pressures on the second support.
        let theta = Mat::from_fn(6, 2, |i, j| if i / 3 == j { 1.0 / 3f64.sqrt() } else { 0.0 });
        let s = Mat::from_fn(6, 5, |i, j| {
            let first = if i < 3 { 1.0 + 0.1 * j as f64 } else { 0.0 };
            let second = if i >= 3 && j == 4 { 1.0 } else { 0.0 };
            first + second
        });
        let ranges = cone_ranges_reference(s.as_ref(), theta.as_ref(), NnlsParams::default()).expect("ok");
        assert_close!(ranges[1][1].0, 0.0, Tol::abs(0.0)); // clipped from 0.2 - 0.4 < 0
        let mut alpha = vec![0.0; 2];
        let mut rng = stream(9, 2);
        for _ in 0..500 {
            draw(&mut rng, &ranges[1], &mut alpha);
            let r = &theta * Mat::from_fn(2, 1, |l, _| alpha[l]);
            assert!(r.col(0).iter().all(|v| *v >= 0.0), "negative field {alpha:?}");
        }
        let curve = specificity_cone(s.as_ref(), theta.as_ref(), params(9), NnlsParams::default()).expect("ok");
        assert!(curve.mean.iter().all(|v| v.is_finite() && *v >= 0.0));
    }

    /// Computing m together with other m gives the same values; computing m alone is the
    /// brute force of `orth_matches_the_definition` / `cone_matches_the_definition`, which
    /// draws from a fresh `stream(seed, m)` (a stream shared across m fails those).
    #[test]
    fn value_for_m_does_not_depend_on_other_m() {
        let mut rng = Rng::new(86);
        let s = bumps(&mut rng, 30, 12, (2.0, 6.0));
        let modes = pod_full(s.as_ref()).expect("svd").modes;
        let basis = cpg(s.as_ref(), CpgParams::default()).expect("ok").basis;
        let nnls = NnlsParams::default();
        let all = specificity_orth(s.as_ref(), modes.as_ref(), params(4));
        let few = specificity_orth(s.as_ref(), modes.subcols(0, 3), params(4));
        // Same draws; the frame of 3 vs all modes changes only the round-off of the tails: 1e-12.
        assert_all_close!(few.mean, all.mean[..3], Tol::abs(1e-12));
        assert_all_close!(few.std, all.std[..3], Tol::abs(1e-12));
        let all = specificity_cone(s.as_ref(), basis.as_ref(), params(4), nnls).expect("ok");
        let few = specificity_cone(s.as_ref(), basis.subcols(0, 3), params(4), nnls).expect("ok");
        assert_all_close!(few.mean, all.mean[..3], Tol::abs(1e-12));
        assert_all_close!(few.std, all.std[..3], Tol::abs(1e-12));
    }

    #[test]
    fn zero_training_snapshots_are_skipped_and_counted() {
        let mut rng = Rng::new(87);
        let mut s = bumps(&mut rng, 20, 6, (2.0, 6.0));
        s.col_mut(2).fill(0.0);
        let modes = pod_full(s.as_ref()).expect("svd").modes;
        let curve = specificity_orth(s.as_ref(), modes.as_ref(), params(7));
        assert_eq!(curve.n_zero, 1);
        assert!(curve.mean.iter().all(|v| v.is_finite()));
        let none = specificity_orth(Mat::<f64>::zeros(4, 3).as_ref(), Mat::<f64>::identity(4, 1).as_ref(), params(7));
        assert_eq!((none.n_zero, none.count[0]), (3, 0));
        assert!(none.mean[0].is_nan());
    }

    #[test]
    fn path_intervals_and_curve_equal_the_reference() {
        let s = hertz_family(&mut Rng::new(89), 101, 64);
        let path = cpg_path(s.as_ref(), CpgPathParams { max_rank: 64, ..CpgPathParams::default() }, &|| {})
            .expect("converges");
        let reference = cone_ranges_reference(s.as_ref(), path.basis.as_ref(), NnlsParams::default()).expect("ok");
        assert_eq!(path.cone_ranges.len(), reference.len());
        for (a, b) in path.cone_ranges.iter().zip(&reference) {
            let flat = |r: &[(f64, f64)]| r.iter().flat_map(|(lo, hi)| [*lo, *hi]).collect::<Vec<_>>();
            // The same pushes and warm-started projections: bit for bit.
            assert_all_close!(flat(a), flat(b), Tol::abs(0.0));
        }
        let p = params(3);
        let fast = specificity_cone_path(s.as_ref(), &path, usize::MAX, p, &|| {});
        let slow = specificity_cone(s.as_ref(), path.basis.as_ref(), p, NnlsParams::default()).expect("ok");
        assert_all_close!(fast.mean, slow.mean, Tol::abs(0.0)); // same intervals, same frame
        assert_all_close!(fast.std, slow.std, Tol::abs(0.0));
        // A smaller max rank gives the prefix of the curve (a frame of fewer generators: the
        // round-off of the tails only, 1e-12).
        let short =
            cpg_path(s.as_ref(), CpgPathParams { max_rank: 9, ..CpgPathParams::default() }, &|| {}).expect("converges");
        let few = specificity_cone_path(s.as_ref(), &short, usize::MAX, p, &|| {});
        assert_eq!(few.len(), 9);
        assert_all_close!(few.mean, fast.mean[..9], Tol::abs(1e-12));
    }

    #[test]
    fn pruned_nearest_snapshot_equals_the_full_scan() {
        // Ironing-like snapshots in their POD frame; samples around the snapshots (where the
        // pruning bites) and far away, for p = 1..q.
        let mut rng = Rng::new(90);
        let s = hertz_family(&mut rng, 60, 40);
        let modes = pod_full(s.as_ref()).expect("svd").modes;
        let frame = Frame::new(s.as_ref(), modes.as_ref());
        let q = modes.ncols();
        let mut hint = 0;
        for trial in 0..400 {
            let p = 1 + trial % q;
            let j = trial % s.ncols();
            let scale = if trial % 3 == 0 { 1.0 } else { 1e-3 };
            let beta: Vec<f64> = (0..p).map(|l| frame.coords[(l, j)] + scale * rng.uniform_in(-1.0, 1.0)).collect();
            let fast = frame.min_relative_distance(&frame.heads(p), &beta, &mut hint).expect("non-zero snapshots");
            let slow = frame.min_relative_distance_reference(&beta).expect("non-zero snapshots");
            // The same sum for the winner, pruned ones provably larger: bit for bit.
            assert_close!(fast, slow, Tol::abs(0.0));
        }
    }

    /// On a rank grid the evaluated S(m) are the same bits as on the whole curve (each m has
    /// its own random stream) and the others are marked skipped.
    #[test]
    fn rank_grid_evaluates_the_same_numbers() {
        let mut rng = Rng::new(71);
        let s = crate::testing::bumps(&mut rng, 30, 50, (2.0, 6.0));
        let modes = crate::basis::pod(s.as_ref(), crate::basis::PodParams::default()).expect("svd").modes;
        let k = modes.ncols().min(20);
        let whole = specificity_orth(s.as_ref(), modes.subcols(0, k), params(5));
        let grid = specificity_orth(s.as_ref(), modes.subcols(0, k), SpecificityParams { dense_to: 4, ..params(5) });
        for m in 1..=k {
            let on = crate::metrics::on_rank_grid(m, 4, k);
            assert_eq!(grid.skipped[m - 1], !on, "m = {m}");
            if on {
                assert_eq!(grid.mean[m - 1].to_bits(), whole.mean[m - 1].to_bits(), "m = {m}");
            } else {
                assert!(grid.mean[m - 1].is_nan() && grid.count[m - 1] == 0);
            }
        }
        assert!(grid.skipped.iter().any(|&x| x) && whole.skipped.iter().all(|&x| !x));
    }
}
