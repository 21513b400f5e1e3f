//! Test data shared by the unit tests of several modules.

use faer::Mat;

use crate::rng::Rng;

/// `count` non-negative "pressure-like" snapshots on `n` points: parabolic bumps
/// `h (1 - ((i - c)/w)^2)_+` with random centre `c` in `[0, n)`, width `w` in `widths` and height
/// `h` in `[0.5, 2)`.
pub(crate) fn bumps(rng: &mut Rng, n: usize, count: usize, widths: (f64, f64)) -> Mat<f64> {
    let mut s = Mat::zeros(n, count);
    for j in 0..count {
        let centre = rng.uniform_in(0.0, n as f64);
        let width = rng.uniform_in(widths.0, widths.1);
        let height = rng.uniform_in(0.5, 2.0);
        for i in 0..n {
            let d = (i as f64 - centre) / width;
            s[(i, j)] = height * (1.0 - d * d).max(0.0);
        }
    }
    s
}
