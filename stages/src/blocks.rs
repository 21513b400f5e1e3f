//! Snapshot matrices read block by block: what the primal metrics of a large training set need
//! from its snapshots, in passes that hold one block of columns at a time.
//!
//! A training set of N displacement snapshots of n dofs is `8 n N` bytes (3.2 GB for 65 537
//! ironing-coarse snapshots). The POD of a large set goes through a frame built block by block
//! ([`frame`](crate::basis::frame)), and every primal metric needs, per snapshot, only a few
//! numbers:
//!
//! ```text
//! ||s_j||^2                                   (norms; ||S||_F = sqrt(sum_j ||s_j||^2))
//! c_j = Psi^T s_j,  ||s_j - Psi c_j||^2       (coordinates on the POD modes and the rest)
//! ```
//!
//! so a [`ColumnBlocks`] source (the store's columns, or a matrix in memory) is read in blocks
//! and each pass keeps `O(N k)` numbers, never the `n x N` matrix. The results are a fixed
//! function of the source's columns: the blocks are fixed-size and in column order, and each
//! column's numbers are computed from that column alone (tested against the whole-matrix
//! computations).

use faer::{Mat, MatRef};

/// Columns per block of a [`modal_pass`]: 512 columns of 23 924 dofs (ironing-fine) are 98 MB.
pub const MODAL_BLOCK: usize = 512;

/// A block of columns could not be read (the store's message: file, column, fix).
#[derive(Debug, Clone, thiserror::Error)]
#[error("{0}")]
pub struct BlockError(pub String);

/// A matrix of `nrows x ncols` read by blocks of consecutive columns.
pub trait ColumnBlocks: Sync {
    /// Rows (entries per snapshot).
    fn nrows(&self) -> usize;
    /// Columns (snapshots).
    fn ncols(&self) -> usize;
    /// Columns `start..start + count` as an `nrows x count` matrix.
    fn block(&self, start: usize, count: usize) -> Result<Mat<f64>, BlockError>;

    /// The whole matrix (for the algorithms that need it: small sets, or a frame that does
    /// not pay).
    fn whole(&self) -> Result<Mat<f64>, BlockError> {
        self.block(0, self.ncols())
    }
}

impl ColumnBlocks for MatRef<'_, f64> {
    fn nrows(&self) -> usize {
        MatRef::nrows(self)
    }
    fn ncols(&self) -> usize {
        MatRef::ncols(self)
    }
    fn block(&self, start: usize, count: usize) -> Result<Mat<f64>, BlockError> {
        Ok(self.subcols(start, count).to_owned())
    }
}

/// Each column's squared norm, and whether every entry is finite: one pass.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnNorms {
    /// `||s_j||^2` (faer's `squared_norm_l2` of the column).
    pub norm2: Vec<f64>,
    /// False when some entry is NaN or infinite.
    pub finite: bool,
}

impl ColumnNorms {
    /// `||S||_F` as `sqrt(sum_j ||s_j||^2)`, summed in column order.
    pub fn frobenius(&self) -> f64 {
        frobenius(&self.norm2)
    }
}

/// `||S||_F = sqrt(sum_j ||s_j||^2)` from the columns' squared norms, summed in column order.
pub fn frobenius(norm2: &[f64]) -> f64 {
    norm2.iter().sum::<f64>().sqrt()
}

/// [`ColumnNorms`] of `src`, read in blocks of `block` columns.
pub fn column_norms(src: &dyn ColumnBlocks, block: usize) -> Result<ColumnNorms, BlockError> {
    let count = src.ncols();
    let mut out = ColumnNorms { norm2: Vec::with_capacity(count), finite: true };
    for start in (0..count).step_by(block.max(1)) {
        let b = src.block(start, block.min(count - start))?;
        for j in 0..b.ncols() {
            out.finite &= b.col(j).iter().all(|v| v.is_finite());
            out.norm2.push(b.col(j).squared_norm_l2());
        }
    }
    Ok(out)
}

/// The snapshots on orthonormal modes `Psi` (n x k), from one pass of [`MODAL_BLOCK`] columns.
#[derive(Debug, Clone)]
pub struct ModalCoordinates {
    /// `c_j = Psi^T s_j`, k x N.
    pub coords: Mat<f64>,
    /// `||s_j - Psi c_j||^2`, length N.
    pub perp: Vec<f64>,
    /// `||s_j||^2`, length N.
    pub norm2: Vec<f64>,
}

/// [`ModalCoordinates`] of `src` on `modes`: per block `C_b = Psi^T S_b` and the block's
/// out-of-span norms ([`out_of_span`](crate::kernels::out_of_span)).
pub fn modal_pass(src: &dyn ColumnBlocks, modes: MatRef<'_, f64>) -> Result<ModalCoordinates, BlockError> {
    assert_eq!(src.nrows(), modes.nrows(), "modal_pass: snapshots and modes have different rows");
    let (k, count) = (modes.ncols(), src.ncols());
    let mut out = ModalCoordinates {
        coords: Mat::zeros(k, count),
        perp: Vec::with_capacity(count),
        norm2: Vec::with_capacity(count),
    };
    for start in (0..count).step_by(MODAL_BLOCK) {
        let w = MODAL_BLOCK.min(count - start);
        let s = src.block(start, w)?;
        let c: Mat<f64> = modes.transpose() * &s;
        let perp = crate::kernels::out_of_span(s.as_ref(), modes, c.as_ref());
        out.coords.subcols_mut(start, w).copy_from(&c);
        for j in 0..w {
            out.perp.push(perp.col(j).squared_norm_l2());
            out.norm2.push(s.col(j).squared_norm_l2());
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A source that serves each block by copying from a matrix and counts what it serves:
    /// the passes read every column once, in blocks, and never the whole matrix.
    struct Counting<'a> {
        s: MatRef<'a, f64>,
        widest: std::sync::atomic::AtomicUsize,
        served: std::sync::atomic::AtomicUsize,
    }

    impl ColumnBlocks for Counting<'_> {
        fn nrows(&self) -> usize {
            self.s.nrows()
        }
        fn ncols(&self) -> usize {
            self.s.ncols()
        }
        fn block(&self, start: usize, count: usize) -> Result<Mat<f64>, BlockError> {
            use std::sync::atomic::Ordering::Relaxed;
            self.widest.fetch_max(count, Relaxed);
            self.served.fetch_add(count, Relaxed);
            Ok(self.s.subcols(start, count).to_owned())
        }
    }

    /// Against the whole-matrix computations (an independent path: one product `Psi^T S` and
    /// the per-column norms of `S - Psi Psi^T S`): the norms bit for bit (the same function of
    /// the same column), the coordinates to 1e-13 and the out-of-span norms to 1e-12 relative
    /// of `||s_j||^2` (the same sums under another blocking of the product may round
    /// differently), over three blocks with a partial last one; every column is read once, in
    /// blocks of at most [`MODAL_BLOCK`].
    #[test]
    fn the_modal_pass_is_the_whole_matrix_computation() {
        let mut rng = Rng::new(21);
        let (n, count) = (50, 2 * MODAL_BLOCK + 77);
        let s = Mat::from_fn(n, count, |_, _| rng.uniform_in(-1.0, 1.0));
        let modes = crate::basis::pod_full(s.subcols(0, 40)).expect("pod").modes;
        let k = modes.ncols().min(12);
        let modes = modes.subcols(0, k).to_owned();
        let src = Counting { s: s.as_ref(), widest: 0.into(), served: 0.into() };
        let pass = modal_pass(&src, modes.as_ref()).expect("in memory");
        assert_eq!(src.widest.into_inner(), MODAL_BLOCK);
        assert_eq!(src.served.into_inner(), count);
        let whole: Mat<f64> = modes.transpose() * &s;
        let perp = &s - &modes * &whole;
        for j in 0..count {
            assert_eq!(pass.norm2[j].to_bits(), s.col(j).squared_norm_l2().to_bits(), "column {j}");
            let expected = perp.col(j).squared_norm_l2();
            assert!(
                (pass.perp[j] - expected).abs() <= 1e-12 * pass.norm2[j],
                "column {j}: {} vs {expected}",
                pass.perp[j]
            );
            for l in 0..k {
                assert!((pass.coords[(l, j)] - whole[(l, j)]).abs() <= 1e-13 * (1.0 + whole[(l, j)].abs()));
            }
        }
        let norms = column_norms(&s.as_ref(), 100).expect("in memory");
        assert!(norms.finite);
        assert_eq!(norms.norm2, pass.norm2);
        let f = norms.frobenius();
        assert!((f - s.norm_l2()).abs() <= 1e-13 * f, "{f} vs {}", s.norm_l2());
        let mut bad = s.clone();
        bad[(3, count - 1)] = f64::NAN;
        assert!(!column_norms(&bad.as_ref(), 100).expect("in memory").finite);
    }

    /// The block-by-block POD, compactness, specificity and orthogonal leave-one-out of a
    /// set above the frame's switch-over size against the in-memory ones (an independent
    /// entry: the whole matrix's norm from faer, one product for the coordinates): singular
    /// values to 1e-12 of the largest, C(m) to 1e-12, S(m) and G(m) to 1e-10 relative (the
    /// same sampled draws and folds from numbers that differ by rounding), and no read wider
    /// than a block.
    #[test]
    fn block_passes_match_the_in_memory_metrics() {
        use crate::basis::{pod, pod_blocks, PodParams, FRAME_BLOCK, POD_FRAME_ABOVE};
        use crate::metrics::{compactness_orth, compactness_orth_modal, specificity_orth, specificity_orth_modal};
        use crate::metrics::{LooOrth, SpecificityParams};
        let mut rng = Rng::new(5);
        let (n, count, rank) = (40, POD_FRAME_ABOVE + 75, 6);
        let left = Mat::from_fn(n, rank, |_, _| rng.uniform_in(-1.0, 1.0));
        let right = Mat::from_fn(rank, count, |_, _| rng.uniform_in(-1.0, 1.0));
        let s: Mat<f64> = &left * &right;
        let src = Counting { s: s.as_ref(), widest: 0.into(), served: 0.into() };
        let norms = column_norms(&src, FRAME_BLOCK).expect("in memory");
        let streamed = pod_blocks(&src, &norms, PodParams::default()).expect("pod");
        let direct = pod(s.as_ref(), PodParams::default()).expect("pod");
        assert_eq!(streamed.rank, rank);
        assert_eq!(streamed.modes.ncols(), direct.modes.ncols());
        let s1 = direct.singular_values[0];
        for (a, b) in streamed.singular_values.iter().zip(&direct.singular_values) {
            assert!((a - b).abs() <= 1e-12 * s1, "{a} vs {b}");
        }
        let modal = modal_pass(&src, streamed.modes.as_ref()).expect("in memory");
        let c_streamed = compactness_orth_modal(&modal);
        let c_direct = compactness_orth(s.as_ref(), streamed.modes.as_ref());
        for (a, b) in c_streamed.iter().zip(&c_direct) {
            assert!((a - b).abs() <= 1e-12, "C: {a} vs {b}");
        }
        let params = SpecificityParams { samples: 50, seed: 3, dense_to: usize::MAX };
        let sp_streamed = specificity_orth_modal(modal, params);
        let sp_direct = specificity_orth(s.as_ref(), streamed.modes.as_ref(), params);
        for (a, b) in sp_streamed.mean.iter().zip(&sp_direct.mean) {
            assert!((a - b).abs() <= 1e-10 * b.abs().max(1e-3), "S: {a} vs {b}");
        }
        let loo_streamed = LooOrth::from_blocks(&src, &norms).expect("factor");
        let loo_direct = LooOrth::new(s.as_ref()).expect("factor");
        for i in [0, 7, count / 2, count - 1] {
            let a = loo_streamed.fold(i, rank + 2).expect("fold").expect("non-zero");
            let b = loo_direct.fold(i, rank + 2).expect("fold").expect("non-zero");
            for (x, y) in a.errors.iter().zip(&b.errors) {
                assert!((x - y).abs() <= 1e-10 * y.abs().max(1e-6), "fold {i}: {x} vs {y}");
            }
        }
        assert!(src.widest.into_inner() <= FRAME_BLOCK.max(MODAL_BLOCK), "a read wider than a block");
    }
}
