//! Mean, standard deviation and count of a metric per basis size, shared by the
//! generalization G(m) (eq. 17) and the specificity S(m) (eq. 18).
//!
//! The standard deviation is the population one, `sqrt(sum (x - mean)^2 / count)` (numpy's
//! default `ddof = 0`): the paper's ±1σ bars (Figs. 10 and 16) describe the spread of the
//! per-snapshot (or per-sample) values themselves ([`RunningStats`], Welford's update).
//!
//! **A mean from a sample of folds.** Leave-one-out over `f` of the `N` training snapshots
//! estimates the mean over all `N` folds. [`mean_interval95`] is the half-width of its 95 %
//! interval under simple random sampling without replacement,
//! `h = z s / sqrt(f) * sqrt(1 - f / N)`, `z = 1.959964` (the normal 97.5 % quantile), `s` the
//! sample standard deviation (`ddof = 1`, from the population one as `σ sqrt(f / (f - 1))`) and
//! `sqrt(1 - f / N)` the finite-population correction (`h = 0` when every fold is in). The folds
//! are evenly spaced over the parameter-ordered training set (systematic sampling): for an error
//! that varies smoothly with the parameter, that is a stratified sample whose variance is at most
//! the random sample's, so the interval is conservative.

pub use crate::running_stats::RunningStats;

/// Statistics of a metric for basis sizes m = 1..=len (entry `k` is m = k + 1).
///
/// For the generalization G(m) the contributors are the left-out snapshots, for the
/// specificity S(m) the random samples.
#[derive(Debug, Clone, PartialEq)]
pub struct MetricCurve {
    /// Mean of the contributors' values at m = k + 1 (NaN where `count[k] == 0`).
    pub mean: Vec<f64>,
    /// Population standard deviation at m = k + 1 (NaN where `count[k] == 0`).
    pub std: Vec<f64>,
    /// Number of values averaged at m = k + 1.
    pub count: Vec<usize>,
    /// Contributors at m = k + 1 whose basis had fewer than m vectors, so their value is the
    /// one of their whole basis (python slicing `Psi[:m]`, as in the paper's notation). Always
    /// 0 for the specificity, which is evaluated for m up to the given basis size.
    pub padded: Vec<usize>,
    /// Zero-norm snapshots skipped (reported, never divided by): left-out snapshots for G,
    /// training snapshots left out of the minimum for S.
    pub n_zero: usize,
    /// m = k + 1 was not evaluated (the rank grid of a large training set, see
    /// [`on_rank_grid`]): its entries are NaN and 0, and tables have no row for it.
    pub skipped: Vec<bool>,
}

impl MetricCurve {
    /// Curve from per-m accumulators.
    pub fn from_stats(stats: &[RunningStats], padded: Vec<usize>, n_zero: usize) -> Self {
        assert_eq!(stats.len(), padded.len(), "MetricCurve: one padded count per m");
        Self {
            mean: stats.iter().map(RunningStats::mean).collect(),
            std: stats.iter().map(RunningStats::std).collect(),
            count: stats.iter().map(RunningStats::count).collect(),
            skipped: vec![false; padded.len()],
            padded,
            n_zero,
        }
    }

    /// Number of basis sizes m (the curve covers m = 1..=len).
    pub fn len(&self) -> usize {
        self.mean.len()
    }

    /// True when the curve covers no basis size.
    pub fn is_empty(&self) -> bool {
        self.mean.is_empty()
    }
}

/// The normal distribution's 97.5 % quantile (two-sided 95 % interval).
const Z_95: f64 = 1.959_963_984_540_054;

/// Half-width of the 95 % interval of a population mean estimated from `count` of its
/// `population` values whose population standard deviation (`ddof = 0`) is `std` (module docs):
/// 0 when the whole population is in, NaN below two values.
pub fn mean_interval95(std: f64, count: usize, population: usize) -> f64 {
    if count >= population {
        return 0.0;
    }
    if count < 2 {
        return f64::NAN;
    }
    let f = count as f64;
    let sample_std = std * (f / (f - 1.0)).sqrt();
    Z_95 * sample_std / f.sqrt() * (1.0 - f / population as f64).sqrt()
}

/// Whether rank m (1-based) of a curve over m = 1..=k is evaluated when every rank up to
/// `dense_to` is and, beyond, only the quarter-octave grid `round(dense_to * 2^(i/4))`, i >= 1,
/// and k itself (about 4 ranks per doubling: a log-scale plot's resolution). A metric whose cost
/// grows with m then costs ~`dense_to^2 / 2 + 6 k` rank-units instead of `k^2 / 2`.
pub fn on_rank_grid(m: usize, dense_to: usize, k: usize) -> bool {
    if m <= dense_to || m == k {
        return true;
    }
    let mut i = 1;
    loop {
        let g = (dense_to as f64 * 2f64.powf(i as f64 / 4.0)).round() as usize;
        if g >= m {
            return g == m;
        }
        i += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    #[test]
    fn running_stats_by_hand() {
        // 2, 4, 4, 4, 5, 5, 7, 9: mean 5, population std 2 (the textbook example).
        let mut s = RunningStats::new();
        for x in [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0] {
            s.push(x);
        }
        assert_eq!(s.count(), 8);
        assert_close!(s.mean(), 5.0, Tol::abs(1e-15)); // a few roundings of small integers
        assert_close!(s.std(), 2.0, Tol::abs(1e-15));
    }

    #[test]
    fn running_stats_of_nothing_and_of_constants() {
        let empty = RunningStats::new();
        assert!(empty.mean().is_nan() && empty.std().is_nan());
        let mut same = RunningStats::new();
        for _ in 0..1000 {
            same.push(0.1);
        }
        // Welford on equal values: delta is exactly 0 after the first push, so std is exactly 0.
        assert_close!(same.std(), 0.0, Tol::abs(0.0));
        assert_close!(same.mean(), 0.1, Tol::abs(0.0));
    }

    #[test]
    fn interval_of_a_sampled_mean_by_hand() {
        // Values 2, 4, 4, 4, 5, 5, 7, 9 (population std 2, sample std 2 sqrt(8/7)) drawn from a
        // population of 80: h = 1.959964 * 2 sqrt(8/7) / sqrt(8) * sqrt(1 - 8/80).
        let h = 1.959_963_984_540_054 * 2.0 * (8.0f64 / 7.0).sqrt() / 8f64.sqrt() * 0.9f64.sqrt();
        assert_close!(mean_interval95(2.0, 8, 80), h, Tol::rel(1e-15)); // same operations, reordered
        assert_close!(mean_interval95(2.0, 80, 80), 0.0, Tol::abs(0.0)); // the whole population: the mean is exact
        assert!(mean_interval95(2.0, 1, 80).is_nan(), "one value has no spread estimate");
        // The correction shrinks the interval as the sample covers more of the population.
        assert!(mean_interval95(2.0, 40, 80) < mean_interval95(2.0, 40, 8000));
    }

    #[test]
    fn rank_grid_is_dense_then_quarter_octaves() {
        let on: Vec<usize> = (1..=256).filter(|&m| on_rank_grid(m, 32, 256)).collect();
        // 32 * 2^(i/4) rounded: 38, 45, 54, 64, 76, 91, 108, 128, 152, 181, 215, 256.
        let tail = [38, 45, 54, 64, 76, 91, 108, 128, 152, 181, 215, 256];
        assert_eq!(on, (1..=32).chain(tail).collect::<Vec<_>>());
        assert!(on_rank_grid(100, 32, 100), "the last rank is always on the grid");
        assert!((1..=50).all(|m| on_rank_grid(m, usize::MAX, 50)));
    }
}
