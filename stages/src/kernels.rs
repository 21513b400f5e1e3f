//! Dense kernels written so the compiler vectorises them while the result stays a fixed
//! function of the inputs (the same bits on every run and thread count): a dot product with
//! independent accumulators (a single running sum is one dependent add per element) and an
//! axpy. Shared by the online solve and the Gram-free cone projection.

/// `a . b` (equal lengths). A long product is summed in sixteen interleaved partial sums: four
/// vectors of four lanes, so the adds of consecutive chunks do not wait on each other (one
/// accumulator vector makes every add wait for the previous one's latency); a short one (the
/// rope's ranks) in four, whose reduction is cheaper.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    if n < 2 * LANES {
        dot_lanes::<4>(a, b)
    } else {
        dot_lanes::<LANES>(a, b)
    }
}

/// Partial sums of a long [`dot`].
const LANES: usize = 16;

/// `a . b` in `L` interleaved partial sums, reduced pairwise (`L` a power of two).
#[inline]
fn dot_lanes<const L: usize>(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; L];
    let (ca, cb) = (a.chunks_exact(L), b.chunks_exact(L));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..L {
            acc[k] += x[k] * y[k];
        }
    }
    let mut s = 0.0;
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    let mut w = L;
    while w > 1 {
        w /= 2;
        for k in 0..w {
            acc[k] += acc[k + w];
        }
    }
    acc[0] + s
}

/// `y += alpha x`.
#[inline]
pub fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Against the naive sum (1e-13 relative: reordered sums of O(1) products), at lengths
    /// around both lane counts.
    #[test]
    fn dot_and_axpy_match_naive_loops() {
        let mut rng = Rng::new(1);
        for n in [0, 1, 3, 4, 7, 15, 16, 17, 31, 32, 33, 130] {
            let a: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let b: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let naive: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            assert!((dot(&a, &b) - naive).abs() <= 1e-13 * (1.0 + naive.abs()), "n = {n}");
            let mut y = b.clone();
            axpy(0.5, &a, &mut y);
            assert!(y.iter().zip(&a).zip(&b).all(|((y, a), b)| y.to_bits() == (b + 0.5 * a).to_bits()), "n = {n}");
        }
    }
}
