//! Dense kernels written so the compiler vectorises them while the result stays a fixed
//! function of the inputs (the same bits on every run and thread count): a dot product with
//! independent accumulators (a single running sum is one dependent add per element) and an
//! axpy. Shared by the online solve and the Gram-free cone projection. And the out-of-span
//! part of a snapshot matrix in one buffer, for the metrics of large sets.

use faer::{Mat, MatRef};

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
    reduce_lanes(acc) + s
}

/// `(x · v, y · v)` in one pass over `v` (equal lengths), each in eight interleaved partial sums
/// reduced pairwise: one fixed order, as [`dot`]'s (two products of one row pair, as the online
/// solve's curvature takes them for a contact node's two rows).
#[inline]
pub fn dot_pair(x: &[f64], y: &[f64], v: &[f64]) -> (f64, f64) {
    const L: usize = 8;
    let (mut ax, mut ay) = ([0.0f64; L], [0.0f64; L]);
    let n = v.len().min(x.len()).min(y.len());
    let main = n / L * L;
    for ((cx, cy), cv) in x[..main].chunks_exact(L).zip(y[..main].chunks_exact(L)).zip(v[..main].chunks_exact(L)) {
        for k in 0..L {
            ax[k] += cx[k] * cv[k];
            ay[k] += cy[k] * cv[k];
        }
    }
    let (mut sx, mut sy) = (0.0, 0.0);
    for i in main..n {
        sx += x[i] * v[i];
        sy += y[i] * v[i];
    }
    (reduce_lanes(ax) + sx, reduce_lanes(ay) + sy)
}

/// `out += Σ_i (f_i0 x_i + f_i1 y_i)` over `N` row pairs `[x_i, y_i]` in one pass over `out`,
/// the pairs added in order: each element gets the same operations in the same order as `N`
/// passes of `*o += f_i0 x_i[j] + f_i1 y_i[j]` (the same bits), with `out` read and written
/// once.
#[inline]
pub fn add_row_pairs<const N: usize>(f: [[f64; 2]; N], rows: [[&[f64]; 2]; N], out: &mut [f64]) {
    let n = rows.iter().fold(out.len(), |n, [x, y]| n.min(x.len()).min(y.len()));
    for (j, o) in out[..n].iter_mut().enumerate() {
        let mut acc = *o;
        for (fi, [x, y]) in f.iter().zip(&rows) {
            acc += fi[0] * x[j] + fi[1] * y[j];
        }
        *o = acc;
    }
}

/// The partial sums of a [`dot`] reduced pairwise (`L` a power of two): one fixed order.
#[inline]
fn reduce_lanes<const L: usize>(mut acc: [f64; L]) -> f64 {
    let mut w = L;
    while w > 1 {
        w /= 2;
        for k in 0..w {
            acc[k] += acc[k + w];
        }
    }
    acc[0]
}

/// [`dot`] of two vectors whose products are `±0` outside `lo..hi` (one of the two is zero
/// there), summed over the chunks that meet `lo..hi` only: the same bits as `dot(a, b)`.
///
/// *Why the same bits:* each of `dot`'s partial sums adds its products in index order, and an
/// exact zero added to a partial sum leaves it unchanged (`s + ±0 = s`, `+0 + −0 = +0`), so
/// skipping the products outside `lo..hi` changes no partial sum; the window is widened to
/// whole chunks so that every product inside it lands in the partial sum `dot` gives it, and
/// the reduction is the same. For sparse columns (a contact pressure is non-zero on the few
/// nodes under the contact patch) this is a dot product over the patch instead of the surface.
#[inline]
pub fn dot_window(a: &[f64], b: &[f64], lo: usize, hi: usize) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (lo, hi) = (lo.min(n), hi.min(n));
    if lo >= hi {
        return 0.0;
    }
    if n < 2 * LANES {
        dot_lanes_window::<4>(a, b, lo, hi)
    } else {
        dot_lanes_window::<LANES>(a, b, lo, hi)
    }
}

/// [`dot_lanes`] restricted to the chunks that meet `lo..hi` and the remainder inside it.
#[inline]
fn dot_lanes_window<const L: usize>(a: &[f64], b: &[f64], lo: usize, hi: usize) -> f64 {
    let main = a.len() / L * L;
    let mut acc = [0.0f64; L];
    let (first, end) = (lo / L * L, hi.min(main).div_ceil(L) * L);
    if first < end {
        for (x, y) in a[first..end].chunks_exact(L).zip(b[first..end].chunks_exact(L)) {
            for k in 0..L {
                acc[k] += x[k] * y[k];
            }
        }
    }
    let mut s = 0.0;
    for i in lo.max(main)..hi {
        s += a[i] * b[i];
    }
    reduce_lanes(acc) + s
}

/// The smallest `lo..hi` outside which `v` is zero (`0..0` for a zero vector).
#[inline]
pub fn nonzero_window(v: &[f64]) -> (usize, usize) {
    match v.iter().position(|x| *x != 0.0) {
        Some(lo) => (lo, v.iter().rposition(|x| *x != 0.0).map_or(lo, |h| h) + 1),
        None => (0, 0),
    }
}

/// `y += alpha x`.
#[inline]
pub fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

/// `s - basis * coords` (n x N; `basis` n x q, `coords` q x N) in one n x N buffer: the
/// product, overwritten column by column with the difference. `s - basis * &coords` holds the
/// product and the difference at once: 0.8 GB instead of 0.4 GB for 8 193 primal snapshots of
/// 6 164 dofs. Each entry is the same subtraction of the same product entry, so the same bits.
pub fn out_of_span(s: MatRef<'_, f64>, basis: MatRef<'_, f64>, coords: MatRef<'_, f64>) -> Mat<f64> {
    assert_eq!(s.shape(), (basis.nrows(), coords.ncols()), "out_of_span: shapes differ");
    let mut out = basis * coords;
    for j in 0..s.ncols() {
        for (o, v) in out.col_mut(j).iter_mut().zip(s.col(j).iter()) {
            *o = *v - *o;
        }
    }
    out
}

/// Columns per block of [`out_of_span_norms`]: 2 048 columns of 6 164 dofs are 0.1 GB.
pub const SPAN_BLOCK: usize = 2048;

/// `||s_j - basis * coords_j||^2` for every column j (`basis` n x q, `coords` q x N), formed in
/// blocks of [`SPAN_BLOCK`] columns: memory n x SPAN_BLOCK instead of n x N (0.8 GB for 16 385
/// primal snapshots of 6 164 dofs). Each block's product has the same inner dimension q as the
/// whole one, so each entry is the same dot product and each column's norm the same bits as
/// from [`out_of_span`] of the whole matrix (tested).
pub fn out_of_span_norms(s: MatRef<'_, f64>, basis: MatRef<'_, f64>, coords: MatRef<'_, f64>) -> Vec<f64> {
    let count = s.ncols();
    let mut out = Vec::with_capacity(count);
    for start in (0..count).step_by(SPAN_BLOCK) {
        let w = SPAN_BLOCK.min(count - start);
        let perp = out_of_span(s.subcols(start, w), basis, coords.subcols(start, w));
        out.extend((0..w).map(|j| perp.col(j).squared_norm_l2()));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// `add_row_pairs` over four pairs is, bit for bit, four passes of one pair each in order
    /// (exact equality: the same operations in the same order), at lengths 0 to 20; with the
    /// pairs summed first and added to `out` once, the bits differ (checked below, so the test
    /// can tell the two orders apart).
    #[test]
    fn add_row_pairs_adds_the_pairs_in_order() {
        let mut rng = Rng::new(3);
        let mut orders_differ = false;
        for n in 0..=20 {
            let rows: Vec<Vec<f64>> = (0..8).map(|_| (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect()).collect();
            let f: [[f64; 2]; 4] = std::array::from_fn(|_| [rng.uniform_in(-3.0, 3.0), rng.uniform_in(-3.0, 3.0)]);
            let out0: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let pair = |i: usize| [&rows[2 * i][..], &rows[2 * i + 1][..]];
            let mut one_pass = out0.clone();
            add_row_pairs(f, [pair(0), pair(1), pair(2), pair(3)], &mut one_pass);
            let mut four_passes = out0.clone();
            for (i, fi) in f.iter().enumerate() {
                add_row_pairs([*fi], [pair(i)], &mut four_passes);
            }
            assert_eq!(
                one_pass.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                four_passes.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                "n = {n}"
            );
            let summed_first: Vec<f64> = (0..n)
                .map(|j| out0[j] + (0..4).map(|i| f[i][0] * rows[2 * i][j] + f[i][1] * rows[2 * i + 1][j]).sum::<f64>())
                .collect();
            orders_differ |= summed_first.iter().zip(&one_pass).any(|(a, b)| a.to_bits() != b.to_bits());
        }
        assert!(orders_differ, "the two summation orders agreed everywhere: the test cannot tell them apart");
    }

    /// `dot_pair` is the two products: against a plain sum at every length from 0 to 40 (the
    /// remainder and the lanes), tolerance 1e-14 of `Σ |x_i v_i|` (another summation order of
    /// at most 40 terms: a few ulps of the sum of magnitudes).
    #[test]
    fn dot_pair_is_the_two_products() {
        let mut rng = Rng::new(9);
        for n in 0..=40 {
            let x: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let y: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let v: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            let (px, py) = dot_pair(&x, &y, &v);
            for (p, a) in [(px, &x), (py, &y)] {
                let exact: f64 = a.iter().zip(&v).map(|(a, b)| a * b).sum();
                let scale: f64 = a.iter().zip(&v).map(|(a, b)| (a * b).abs()).sum();
                assert!((p - exact).abs() <= 1e-14 * scale.max(f64::MIN_POSITIVE), "n = {n}: {p} vs {exact}");
            }
        }
    }

    #[test]
    fn out_of_span_is_the_two_buffer_difference_bit_for_bit() {
        let mut rng = Rng::new(5);
        let s = Mat::from_fn(37, 23, |_, _| rng.uniform_in(-1.0, 1.0));
        let basis = Mat::from_fn(37, 6, |_, _| rng.uniform_in(-1.0, 1.0));
        let coords: Mat<f64> = basis.transpose() * &s;
        let two = &s - &basis * &coords;
        let one = out_of_span(s.as_ref(), basis.as_ref(), coords.as_ref());
        for j in 0..23 {
            for i in 0..37 {
                assert_eq!(one[(i, j)].to_bits(), two[(i, j)].to_bits(), "entry ({i}, {j})");
            }
        }
    }

    /// Blockwise norms against the whole matrix's, bit for bit, across three blocks (the last
    /// one partial) with a frame of 40 columns.
    #[test]
    fn out_of_span_norms_are_the_whole_matrix_columns_norms() {
        let mut rng = Rng::new(6);
        let (n, q, count) = (70, 40, 2 * SPAN_BLOCK + 37);
        let s = Mat::from_fn(n, count, |_, _| rng.uniform_in(-1.0, 1.0));
        let basis = Mat::from_fn(n, q, |_, _| rng.uniform_in(-1.0, 1.0));
        let coords: Mat<f64> = basis.transpose() * &s;
        let whole = out_of_span(s.as_ref(), basis.as_ref(), coords.as_ref());
        let norms = out_of_span_norms(s.as_ref(), basis.as_ref(), coords.as_ref());
        assert_eq!(norms.len(), count);
        for (j, v) in norms.iter().enumerate() {
            assert_eq!(v.to_bits(), whole.col(j).squared_norm_l2().to_bits(), "column {j}");
        }
    }

    /// `dot_window` against `dot`, bit for bit, on vectors zero outside random windows (one
    /// vector's window or the other's; cancellations included), at lengths around both lane
    /// counts and with windows in the remainder, across chunk boundaries and empty.
    #[test]
    fn dot_window_is_dot_bit_for_bit() {
        let mut rng = Rng::new(9);
        for n in [1, 3, 4, 5, 17, 31, 32, 33, 47, 64, 101, 130] {
            for trial in 0..200 {
                let lo = (rng.uniform_in(0.0, 1.0) * n as f64) as usize;
                let hi = (lo + (rng.uniform_in(0.0, 1.0) * (n - lo + 1) as f64) as usize).min(n);
                let mut a: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
                let mut b: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
                let zeroed = if trial % 2 == 0 { &mut a } else { &mut b };
                for (i, v) in zeroed.iter_mut().enumerate() {
                    if i < lo || i >= hi {
                        *v = if i % 3 == 0 { -0.0 } else { 0.0 };
                    }
                }
                if trial % 7 == 0 && hi > lo + 1 {
                    // An exact cancellation inside the window.
                    a[lo] = 1.0;
                    b[lo] = 1.0;
                    a[lo + 1] = -1.0;
                    b[lo + 1] = 1.0;
                }
                let whole = dot(&a, &b);
                assert_eq!(dot_window(&a, &b, lo, hi).to_bits(), whole.to_bits(), "n = {n}, window {lo}..{hi}");
                let (wlo, whi) = nonzero_window(if trial % 2 == 0 { &a } else { &b });
                assert!(
                    (wlo, whi) == (0, 0) || (wlo >= lo && whi <= hi),
                    "nonzero_window {wlo}..{whi} outside {lo}..{hi}"
                );
                assert_eq!(dot_window(&a, &b, wlo, whi).to_bits(), whole.to_bits(), "n = {n}, tight {wlo}..{whi}");
            }
        }
        assert_eq!(nonzero_window(&[0.0, -0.0, 0.0]), (0, 0));
        assert_eq!(nonzero_window(&[0.0, 2.0, 0.0, 3.0, 0.0]), (1, 4));
    }

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
