//! Small dense kernels of the online solve, written so the compiler vectorises them: a dot
//! product with independent accumulators (a single running sum is one dependent add per
//! element), triangular solves with a column-major Cholesky factor.

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

/// The metric of a reduced space: the lower Cholesky factor `L` (column-major `r x r`) of its
/// Gram matrix `G = L L^T`, or the identity — coordinates in which `G = I` need no triangular
/// solve (the online solve works in them, see [`crate::rom`]).
#[derive(Debug, Clone, Copy)]
pub enum Factor<'a> {
    /// `G = I`.
    Identity,
    /// `G = L L^T`, `L` column-major `r x r`.
    Lower(&'a [f64]),
}

impl Factor<'_> {
    /// `b <- L^{-1} b` (nothing for the identity).
    pub fn forward(self, r: usize, b: &mut [f64]) {
        if let Factor::Lower(l) = self {
            forward(l, r, b);
        }
    }

    /// `b <- L^{-T} b` (nothing for the identity).
    pub fn backward_t(self, r: usize, b: &mut [f64]) {
        if let Factor::Lower(l) = self {
            backward_t(l, r, b);
        }
    }
}

/// `b <- L^{-1} b` with the lower factor `L` stored column-major (`r x r`): column sweeps, so the
/// inner loop is an `axpy` over contiguous memory.
pub fn forward(l: &[f64], r: usize, b: &mut [f64]) {
    for j in 0..r {
        let v = b[j] / l[j + j * r];
        b[j] = v;
        if v != 0.0 {
            axpy(-v, &l[j * r + j + 1..(j + 1) * r], &mut b[j + 1..r]);
        }
    }
}

/// `b <- L^{-T} b` with the same factor: row `i` of `L^T` is column `i` of `L`, a dot product.
pub fn backward_t(l: &[f64], r: usize, b: &mut [f64]) {
    for i in (0..r).rev() {
        let s = dot(&l[i * r + i + 1..(i + 1) * r], &b[i + 1..r]);
        b[i] = (b[i] - s) / l[i + i * r];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Against the naive sum and naive triangular solves (1e-13 relative: reordered sums of
    /// O(1) products).
    #[test]
    fn kernels_match_naive_loops() {
        let mut rng = Rng::new(1);
        for n in [0, 1, 3, 4, 7, 15, 16, 17, 33, 130] {
            let a: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let b: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let naive: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            assert!((dot(&a, &b) - naive).abs() <= 1e-13 * (1.0 + naive.abs()));
        }
        let r = 9;
        let mut l = vec![0.0; r * r];
        for j in 0..r {
            for i in j..r {
                l[i + j * r] = if i == j { 2.0 + rng.uniform() } else { rng.uniform_in(-1.0, 1.0) };
            }
        }
        let b: Vec<f64> = (0..r).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let mut y = b.clone();
        forward(&l, r, &mut y);
        for i in 0..r {
            let ly: f64 = (0..=i).map(|k| l[i + k * r] * y[k]).sum();
            assert!((ly - b[i]).abs() <= 1e-13, "forward row {i}");
        }
        let mut z = b.clone();
        backward_t(&l, r, &mut z);
        for i in 0..r {
            let ltz: f64 = (i..r).map(|k| l[k + i * r] * z[k]).sum();
            assert!((ltz - b[i]).abs() <= 1e-13, "backward row {i}");
        }
    }
}
