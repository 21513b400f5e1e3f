//! Relative primal errors of many reduced solutions against reference snapshots, without
//! reconstructing the full field per query.
//!
//! With `M = Phi^T H Phi = L_M L_M^T` (`H` the Gram matrix of the primal norm) and a reference
//! `u` at `mu` with response `r = u - u0(mu)`, the error of `u0 + Phi[:, :k] û` is
//!
//! ```text
//! ||Phi_k û - r||_H^2 = |L_{M,k}^T û - y_{:k}|^2 + sum_{i >= k} y_i^2 + tail,
//! y = L_M^{-1} Phi^T H r,    tail = ||r - Phi M^{-1} Phi^T H r||_H^2
//! ```
//!
//! (the leading block of `L_M` is the factor of the leading block of `M`, and the projection
//! of `r` onto the first `k` modes has coordinates `y_{:k}` in that factor's basis). `y` and
//! `tail` cost `n_dof r` once per reference point; each query then costs `O(k^2)`, and no term
//! is a difference of large numbers (`tail` is evaluated directly from the residual field).

use super::la::{backward_t, dot, forward};
use super::saddle::cholesky;
use crate::full_order::ContactOperator;
use faer::{Mat, MatRef};
use rayon::prelude::*;

/// Precomputed references for [`PrimalErrors::relative`].
#[derive(Debug, Clone)]
pub struct PrimalErrors {
    r: usize,
    l: Vec<f64>,
    /// Per reference: `y`, `tail`, `||u||_H^2`.
    refs: Vec<(Vec<f64>, f64, f64)>,
}

impl PrimalErrors {
    /// `phi`: `n_dof x r` column-major with independent columns; `refs`: `(mu, u)` pairs.
    /// `None` if `Phi^T H Phi` is not positive definite.
    pub fn new(op: &dyn ContactOperator, phi: &[f64], r: usize, refs: &[(&[f64], &[f64])]) -> Option<Self> {
        let n = op.n_dof();
        let mut hphi = vec![0.0; n * r];
        op.primal_gram_mul_cols(phi, r, &mut hphi);
        let phi_m = MatRef::from_column_major_slice(phi, n, r);
        let hphi_m = MatRef::from_column_major_slice(&hphi, n, r);
        let mg = hphi_m.transpose() * phi_m;
        let mut m = vec![0.0; r * r];
        for j in 0..r {
            for i in 0..r {
                m[i + j * r] = 0.5 * (mg[(i, j)] + mg[(j, i)]);
            }
        }
        if !cholesky(&mut m, r) {
            return None;
        }
        // references in blocks of 64, so the products are matrix-matrix (faer) and memory stays
        // bounded; the blocks in parallel, each computed as alone (the same sizes, so the same
        // products to the bit), two at a time on two cores
        let m_ref = &m;
        let blocks: Vec<Vec<(Vec<f64>, f64, f64)>> = refs
            .par_chunks(64)
            .map(|block| {
                let k = block.len();
                let mut res = Mat::<f64>::zeros(n, k);
                let lifts: Vec<Vec<f64>> = block.par_iter().map(|(mu, _)| op.lift(mu)).collect();
                for (j, ((_, u), lift)) in block.iter().zip(lifts).enumerate() {
                    for (i, (a, b)) in u.iter().zip(lift).enumerate() {
                        res[(i, j)] = a - b;
                    }
                }
                let b = hphi_m.transpose() * &res;
                let mut c = Mat::<f64>::zeros(r, k);
                let mut ys = Vec::with_capacity(k);
                for j in 0..k {
                    // y = L^{-1} b, c = M^{-1} b
                    let mut y: Vec<f64> = (0..r).map(|i| b[(i, j)]).collect();
                    forward(m_ref, r, &mut y);
                    let mut cj = y.clone();
                    backward_t(m_ref, r, &mut cj);
                    for (i, v) in cj.iter().enumerate() {
                        c[(i, j)] = *v;
                    }
                    ys.push(y);
                }
                let e = &res - phi_m * &c;
                // per reference, in parallel: the two products with H and their dots, each the
                // same arithmetic as alone
                let e = &e;
                let norms: Vec<(f64, f64)> = (0..k)
                    .into_par_iter()
                    .map_init(
                        || vec![0.0; n],
                        |he, j| {
                            let ej: Vec<f64> = e.col(j).iter().copied().collect();
                            op.primal_gram_mul(&ej, he);
                            let tail = dot(&ej, he);
                            op.primal_gram_mul(block[j].1, he);
                            (tail, dot(block[j].1, he))
                        },
                    )
                    .collect();
                ys.into_iter().zip(norms).map(|(y, (tail, norm))| (y, tail, norm)).collect()
            })
            .collect();
        let out: Vec<(Vec<f64>, f64, f64)> = blocks.into_iter().flatten().collect();
        Some(Self { r, l: m, refs: out })
    }

    /// `||u0 + Phi[:, :k] û - u_j||_H / ||u_j||_H` for reference `j`, `k = û.len()`; `NaN`
    /// when the reference is zero.
    pub fn relative(&self, j: usize, u_hat: &[f64]) -> f64 {
        let (y, tail, norm) = &self.refs[j];
        let k = u_hat.len();
        assert!(k <= self.r, "rank exceeds the basis");
        let mut e2 = *tail + y[k..].iter().map(|v| v * v).sum::<f64>();
        for (i, yi) in y.iter().enumerate().take(k) {
            // (L_k^T û)_i = sum_{m >= i} L[m, i] û_m
            let lu: f64 = (i..k).map(|m| self.l[m + i * self.r] * u_hat[m]).sum();
            e2 += (lu - yi) * (lu - yi);
        }
        if *norm > 0.0 {
            (e2 / norm).sqrt()
        } else {
            f64::NAN
        }
    }
}
