//! Mean, standard deviation and count of a metric per basis size, shared by the
//! generalization G(m) (eq. 17) and the specificity S(m) (eq. 18).
//!
//! The standard deviation is the population one, `sqrt(sum (x - mean)^2 / count)` (numpy's
//! default `ddof = 0`): the paper's ±1σ bars (Figs. 10 and 16) describe the spread of the
//! per-snapshot (or per-sample) values themselves ([`RunningStats`], Welford's update).

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
}

impl MetricCurve {
    /// Curve from per-m accumulators.
    pub fn from_stats(stats: &[RunningStats], padded: Vec<usize>, n_zero: usize) -> Self {
        assert_eq!(stats.len(), padded.len(), "MetricCurve: one padded count per m");
        Self {
            mean: stats.iter().map(RunningStats::mean).collect(),
            std: stats.iter().map(RunningStats::std).collect(),
            count: stats.iter().map(RunningStats::count).collect(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::Tol;
    use crate::assert_close;

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
}
