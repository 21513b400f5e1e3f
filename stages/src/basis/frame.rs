//! A small orthonormal frame of a large snapshot matrix, built block by block: `S ~ Q R` with
//! `Q` n x q orthonormal and q about the numerical rank, so the POD and the orthogonal
//! leave-one-out folds of N snapshots cost `O(n q N)` instead of an SVD of the n x N matrix.
//!
//! ```text
//! for each block S_b of B columns (in column order):
//!     C = Q^T S_b,  W = S_b - Q C                  (twice: classical Gram-Schmidt, reorthogonalised)
//!     W P = Q_W R_W                                (column-pivoted QR of the residual block)
//!     keep the t leading directions with |R_W[k, k]| > tau,  Q <- [Q, Q_W[:, :t]]
//!     R[:, b] = [C; Q_W[:, :t]^T W],   dropped^2 += ||W - Q_W[:, :t] Q_W[:, :t]^T W||_F^2
//! ```
//!
//! `tau = eps ||S||_F`. A direction is dropped only where every column of its block has a
//! residual at round-off, so `||S - Q R||_F = dropped` (the stored bound) and by Weyl's
//! inequality each singular value of `R` is within `dropped` of the one of S; the POD's
//! numerical-rank cut, `max(n, N) eps s_max`, lies above any dropped direction as long as
//! `sqrt(N) ||S||_F <= max(n, N) s_max` (true whenever one mode carries a fair share of the
//! energy; the bound is stored so a reader can check it). The frame is deterministic: blocks in
//! column order, each step a fixed sequence of dense kernels.

use faer::{Mat, MatRef};

use crate::blocks::{BlockError, ColumnBlocks};

/// Columns per block: about the rank of the shipped scenes' primal snapshots (180), where the
/// per-block cost `n (q + B)^2` per `B` columns is near its minimum.
pub const FRAME_BLOCK: usize = 256;

/// `S ~ Q R` (see the module docs).
#[derive(Debug, Clone)]
pub struct Frame {
    /// Orthonormal frame, n x q.
    pub q: Mat<f64>,
    /// Coordinates of every snapshot in the frame, q x N.
    pub r: Mat<f64>,
    /// `||S - Q R||_F`: the energy of the directions dropped at round-off.
    pub dropped: f64,
}

/// The blockwise frame of a large set that its POD ([`pod_blocks_framed`](super::pod_blocks_framed))
/// and its orthogonal leave-one-out
/// ([`LooOrth::from_blocks_framed`](crate::metrics::LooOrth::from_blocks_framed))
/// share: above [`POD_FRAME_ABOVE`](super::POD_FRAME_ABOVE) finite snapshots, within
/// [`frame_pays_up_to`]`(N)`, with `||S||_F` from the columns' norms. `None` at or below the
/// switch-over size, for non-finite snapshots, or where the frame does not pay: then both read
/// the whole matrix.
pub fn large_frame(src: &dyn ColumnBlocks, norms: &crate::blocks::ColumnNorms) -> Result<Option<Frame>, BlockError> {
    let count = src.ncols();
    if count <= super::POD_FRAME_ABOVE || !norms.finite {
        return Ok(None);
    }
    frame_within_blocks(src, norms.frobenius(), frame_pays_up_to(count))
}

/// The frame of `s` (n x N), built in blocks of [`FRAME_BLOCK`] columns.
pub fn frame(s: MatRef<'_, f64>) -> Frame {
    frame_within(s, usize::MAX).unwrap_or_else(|| unreachable!("no size limit"))
}

/// The largest frame worth building for N snapshots: the frame costs about
/// `n N (q + B)^2 / B` and a direct SVD of a tall n x N matrix `n N^2`, so the frame pays while
/// `(q + B)^2 < N B`. Measured: ironing-coarse's 6 164 x 2 049 displacements (q = 192) 11 s
/// direct against 2 s framed; ironing-fine-2d's 11 800 x 1 105 on 65 x 17 points (rank 391) the other way.
pub fn frame_pays_up_to(count: usize) -> usize {
    (((count * FRAME_BLOCK) as f64).sqrt() as usize).saturating_sub(FRAME_BLOCK)
}

/// [`frame`], or `None` as soon as it would have more than `max_q` columns.
pub fn frame_within(s: MatRef<'_, f64>, max_q: usize) -> Option<Frame> {
    frame_within_blocks(&s, s.norm_l2(), max_q)
        .unwrap_or_else(|_| unreachable!("a matrix in memory is read without error"))
}

/// [`frame_within`] of snapshots read block by block ([`ColumnBlocks`]: one block of
/// [`FRAME_BLOCK`] columns in memory at a time), given `total = ||S||_F`.
pub fn frame_within_blocks(src: &dyn ColumnBlocks, total: f64, max_q: usize) -> Result<Option<Frame>, BlockError> {
    let (n, count) = (src.nrows(), src.ncols());
    let tau = f64::EPSILON * total;
    let mut q = Mat::<f64>::zeros(n, 0);
    // Coefficients per block: (rows of the frame at that block, q_b x B).
    let mut blocks: Vec<Mat<f64>> = Vec::new();
    let mut dropped2 = 0.0;
    let mut start = 0;
    while start < count {
        let b = FRAME_BLOCK.min(count - start);
        let block = src.block(start, b)?;
        let sb = block.as_ref();
        let mut c = if q.ncols() > 0 { q.transpose() * sb } else { Mat::zeros(0, b) };
        let mut w = if q.ncols() > 0 { sb - &q * &c } else { sb.to_owned() };
        if q.ncols() > 0 {
            let c2 = q.transpose() * &w;
            w -= &q * &c2;
            c += &c2;
        }
        let keep = if w.norm_l2() > tau { new_directions(q.as_ref(), w.as_ref(), tau) } else { Mat::zeros(n, 0) };
        let new_rows = keep.transpose() * &w;
        let rest = &w - &keep * &new_rows;
        dropped2 += rest.squared_norm_l2();
        let q_old = q.ncols();
        let t = keep.ncols();
        if q_old + t > max_q {
            return Ok(None);
        }
        if t > 0 {
            q.resize_with(n, q_old + t, |i, j| keep[(i, j - q_old)]);
        }
        blocks.push(Mat::from_fn(q_old + t, b, |i, j| if i < q_old { c[(i, j)] } else { new_rows[(i - q_old, j)] }));
        start += b;
    }
    let rows = q.ncols();
    let mut r = Mat::<f64>::zeros(rows, count);
    let mut col = 0;
    for blk in &blocks {
        r.submatrix_mut(0, col, blk.nrows(), blk.ncols()).copy_from(blk);
        col += blk.ncols();
    }
    Ok(Some(Frame { q, r, dropped: dropped2.sqrt() }))
}

/// The directions of the residual block `w` (already orthogonal to `q` up to round-off of
/// `||S_b||`) with a pivoted-QR diagonal above `tau`. A direction found at a pivot near `tau`
/// is `W P R^{-1}`: the round-off components of W along Q are amplified by `1 / |R_kk|`, up to
/// O(1) (measured: a frame of ironing-coarse displacements whose second singular value came
/// out at 61 instead of 28). So the directions are orthogonalised against Q twice more and
/// factored again; one that keeps less than half its length was mostly in span(Q) and is
/// dropped (its part of the block is counted in the dropped energy).
fn new_directions(q: MatRef<'_, f64>, w: MatRef<'_, f64>, tau: f64) -> Mat<f64> {
    let qr = w.col_piv_qr();
    let rr = qr.thin_R();
    let t = (0..rr.nrows().min(rr.ncols())).take_while(|&k| rr[(k, k)].abs() > tau).count();
    let mut k = qr.compute_thin_Q().subcols(0, t).to_owned();
    if t == 0 || q.ncols() == 0 {
        return k;
    }
    for _ in 0..2 {
        let c = q.transpose() * &k;
        k -= q * &c;
    }
    let qr2 = k.col_piv_qr();
    let r2 = qr2.thin_R();
    let t2 = (0..r2.nrows().min(r2.ncols())).take_while(|&j| r2[(j, j)].abs() > 0.5).count();
    qr2.compute_thin_Q().subcols(0, t2).to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A rank-r matrix with decaying spectrum, n x N.
    fn low_rank(rng: &mut Rng, n: usize, count: usize, r: usize) -> Mat<f64> {
        let a = Mat::from_fn(n, r, |_, _| rng.uniform_in(-1.0, 1.0));
        let b = Mat::from_fn(r, count, |i, _| rng.uniform_in(-1.0, 1.0) * 0.5f64.powi(i as i32));
        &a * &b
    }

    /// The frame reproduces S to round-off, is orthonormal, has about the rank's size, and its
    /// singular values are the direct SVD's within the stored bound plus round-off (Weyl).
    #[test]
    fn frame_reproduces_the_snapshots() {
        let mut rng = Rng::new(81);
        let s = low_rank(&mut rng, 120, 700, 30);
        let f = frame(s.as_ref());
        assert!(f.q.ncols() >= 30 && f.q.ncols() <= 40, "frame size {}", f.q.ncols());
        let total = s.norm_l2();
        let err = (&s - &f.q * &f.r).norm_l2();
        // 1e-13 relative: a few reorthogonalised Gram-Schmidt steps on a 30-dimensional span.
        assert!(err <= 1e-13 * total, "||S - QR|| = {err:e}");
        let qtq = f.q.transpose() * &f.q - Mat::<f64>::identity(f.q.ncols(), f.q.ncols());
        assert!(qtq.norm_l2() <= 1e-13, "Q not orthonormal: {:e}", qtq.norm_l2());
        let direct: Vec<f64> = s.thin_svd().expect("svd").S().column_vector().iter().copied().collect();
        let framed: Vec<f64> = f.r.thin_svd().expect("svd").S().column_vector().iter().copied().collect();
        for k in 0..30 {
            assert!((direct[k] - framed[k]).abs() <= f.dropped + 1e-12 * direct[0], "sigma {k}");
        }
    }

    /// A spectrum graded from 1 to 1e-15 (down to the frame's threshold) over several blocks (the case that lost orthogonality
    /// without the second orthogonalisation of new directions): every singular value above
    /// 1e-10 matches the direct SVD to 1e-12 of s_max.
    #[test]
    fn graded_spectrum_keeps_every_singular_value() {
        let mut rng = Rng::new(83);
        let (n, count, r) = (200, 900, 40);
        let a =
            crate::basis::pod_direct(Mat::from_fn(n, r, |_, _| rng.uniform_in(-1.0, 1.0)).as_ref(), Default::default())
                .expect("svd")
                .modes;
        let b = Mat::from_fn(r, count, |i, _| rng.uniform_in(-1.0, 1.0) * 10f64.powf(-15.0 * i as f64 / r as f64));
        let s = &a * &b;
        let f = frame(s.as_ref());
        let direct: Vec<f64> = s.thin_svd().expect("svd").S().column_vector().iter().copied().collect();
        let framed: Vec<f64> = f.r.thin_svd().expect("svd").S().column_vector().iter().copied().collect();
        let smax = direct[0];
        for k in (0..r).filter(|&k| direct[k] > 1e-10 * smax) {
            assert!((direct[k] - framed[k]).abs() <= 1e-12 * smax, "sigma {k}: {} vs {}", direct[k], framed[k]);
        }
    }

    /// A direction that appears in a later block at a few times the threshold, beside a large
    /// one already in the frame: found from the residual at pivot ~tau, it carries the
    /// residual's round-off along the old direction amplified to O(1) unless orthogonalised
    /// again. The frame stays orthonormal to 1e-12 and the new direction is kept.
    #[test]
    fn a_new_direction_near_the_threshold_stays_orthogonal() {
        let mut rng = Rng::new(84);
        let n = 50;
        let v1: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let v2: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let count = 2 * FRAME_BLOCK;
        let big: Vec<f64> = (0..count).map(|_| 1e3 * rng.uniform_in(0.5, 1.5)).collect();
        // ||S||_F ~ 1e3 sqrt(count) |v1|, so tau ~ 2e-16 * 1e3 * 23 * 4 ~ 2e-11.
        let s0 = Mat::from_fn(n, count, |i, j| big[j] * v1[i]);
        let tau = f64::EPSILON * s0.norm_l2();
        let small: Vec<f64> =
            (0..count).map(|j| if j < FRAME_BLOCK { 0.0 } else { 3.0 * tau * rng.uniform_in(0.5, 1.5) }).collect();
        let s = Mat::from_fn(n, count, |i, j| big[j] * v1[i] + small[j] * v2[i]);
        let f = frame(s.as_ref());
        let qtq = f.q.transpose() * &f.q - Mat::<f64>::identity(f.q.ncols(), f.q.ncols());
        assert!(qtq.norm_l2() <= 1e-12, "Q not orthonormal: {:e} ({} columns)", qtq.norm_l2(), f.q.ncols());
        assert!(f.q.ncols() >= 1);
    }

    #[test]
    fn zero_and_single_block_matrices() {
        let f = frame(Mat::<f64>::zeros(10, 5).as_ref());
        assert_eq!((f.q.ncols(), f.r.nrows(), f.r.ncols()), (0, 0, 5));
        let mut rng = Rng::new(82);
        let s = low_rank(&mut rng, 10, 5, 3);
        let f = frame(s.as_ref());
        assert!((&s - &f.q * &f.r).norm_l2() <= 1e-13 * s.norm_l2());
    }
}
