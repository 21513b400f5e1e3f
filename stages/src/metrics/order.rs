//! Order statistics for reports: nearest-rank quantiles and Spearman's rank correlation.

/// Nearest-rank quantile `q in [0, 1]` of the finite values of `v` (`NaN` if there are none):
/// the smallest value with at least `q n` values at or below it.
pub fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    let k = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len());
    s[k - 1]
}

/// Ranks `1..=n` with ties given their average rank.
fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]].total_cmp(&v[idx[i]]).is_eq() {
            j += 1;
        }
        let avg = (i + j) as f64 / 2.0 + 1.0;
        for &k in &idx[i..=j] {
            r[k] = avg;
        }
        i = j + 1;
    }
    r
}

/// Spearman's rank correlation of the pairs where both values are finite (`NaN` with fewer
/// than 3 such pairs or a constant side): the Pearson correlation of the (tie-averaged) ranks.
pub fn spearman(x: &[f64], y: &[f64]) -> f64 {
    let (x, y): (Vec<f64>, Vec<f64>) =
        x.iter().zip(y).filter(|(a, b)| a.is_finite() && b.is_finite()).map(|(a, b)| (*a, *b)).unzip();
    if x.len() < 3 {
        return f64::NAN;
    }
    let (rx, ry) = (ranks(&x), ranks(&y));
    let n = rx.len() as f64;
    let (mx, my) = (rx.iter().sum::<f64>() / n, ry.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in rx.iter().zip(&ry) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    if sxx == 0.0 || syy == 0.0 {
        return f64::NAN;
    }
    sxy / (sxx * syy).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    #[test]
    fn nearest_rank_quantiles() {
        let v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        // exact: the quantile is one of the (integer-valued) inputs
        assert_close!(quantile(&v, 0.95), 95.0, Tol::abs(0.0));
        assert_close!(quantile(&v, 0.5), 50.0, Tol::abs(0.0));
        assert_close!(quantile(&v, 1.0), 100.0, Tol::abs(0.0));
        assert_close!(quantile(&[3.0, f64::NAN, 1.0], 0.5), 1.0, Tol::abs(0.0));
        assert!(quantile(&[f64::NAN], 0.5).is_nan());
    }

    /// Hand-computed: x = 1..5, y = (5, 6, 7, 8, 7) has ranks (1, 2, 3.5, 5, 3.5), so
    /// rho = 8 / sqrt(10 * 9.5); a monotone transform gives 1, a reversal -1 (1e-15).
    #[test]
    fn spearman_by_hand() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_close!(spearman(&x, &[5.0, 6.0, 7.0, 8.0, 7.0]), 8.0 / 95f64.sqrt(), Tol::abs(1e-15));
        assert_close!(spearman(&x, &x.map(|v: f64| v.exp())), 1.0, Tol::abs(1e-15));
        assert_close!(spearman(&x, &x.map(|v| -v)), -1.0, Tol::abs(1e-15));
        assert!(spearman(&x[..2], &x[..2]).is_nan());
    }
}
