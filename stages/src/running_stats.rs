//! Running count, mean and population standard deviation, accumulated with Welford's update
//! (no `E[x^2] - E[x]^2` cancellation when every value is nearly the same). Below `cone`,
//! `basis` and `metrics`, which all summarise coefficients or errors with it.

/// Running count, mean and population standard deviation (Welford).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunningStats {
    count: usize,
    mean: f64,
    m2: f64,
}

impl RunningStats {
    /// No values yet.
    pub const fn new() -> Self {
        Self { count: 0, mean: 0.0, m2: 0.0 }
    }

    /// Add one value.
    pub fn push(&mut self, x: f64) {
        self.count += 1;
        let delta = x - self.mean;
        self.mean += delta / self.count as f64;
        self.m2 += delta * (x - self.mean);
    }

    /// Number of values pushed.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Mean, NaN when no value was pushed.
    pub fn mean(&self) -> f64 {
        if self.count == 0 {
            f64::NAN
        } else {
            self.mean
        }
    }

    /// Population standard deviation, NaN when no value was pushed (0 for one value).
    pub fn std(&self) -> f64 {
        if self.count == 0 {
            f64::NAN
        } else {
            (self.m2.max(0.0) / self.count as f64).sqrt()
        }
    }

    /// `[mean - std, mean + std]`, the lower end clipped at 0 when `clip` (cone coefficients).
    pub fn interval(&self, clip: bool) -> (f64, f64) {
        let (mu, sigma) = (self.mean(), self.std());
        let lo = if clip { (mu - sigma).max(0.0) } else { mu - sigma };
        (lo, mu + sigma)
    }
}
