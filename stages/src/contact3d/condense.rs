//! The stiffness factor with the contact dofs ordered last, and the Delassus operator from its
//! trailing block (static condensation).
//!
//! Order the free dofs as `[interior, contact]` (the interior in the fill-reducing order faer's
//! AMD gives the whole matrix, the contact dofs after it) and factor `P K_FF P^T = L L^T`. The
//! contact dofs' unit loads then stay in the trailing block: forward substitution of `L y = e_j`
//! for a contact dof `j` leaves `y` zero before `j`'s position, and the contact rows of the
//! backward substitution read only the trailing block. So with `L_cc` that block,
//!
//! ```text
//! W = E_c^T K_FF^{-1} E_c = (L_cc L_cc^T)^{-1} = X^T X,   X = L_cc^{-1},
//! ```
//!
//! `n_c^3 / 3 + n_c^3` dense flops (about 1.5 s at 3 609 contact dofs) where `n_c` solves with
//! the whole factor cost about `4 nnz(L) n_c` (27 s at 109 431 dofs). The trailing block is
//! dense (the contact dofs' Schur complement couples them all), so `L` gains at most
//! `n_c^2 / 2` entries.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, simplicial::SimplicialLltRef, supernodal::SupernodalLltRef, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::SparseColMat;
use faer::{Conj, Mat, MatMut, Par, Side};

use crate::contact::ModelError;

/// `K_FF = P^T L L^T P` with the contact dofs last.
#[derive(Debug, Clone)]
pub struct ContactLastFactor {
    symbolic: std::sync::Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl ContactLastFactor {
    /// Factor `kff` (lower triangle given) with the free dofs `contact` (free indices) ordered
    /// last; returns the factor and `W` on `contact` (row-major, in `contact`'s order).
    pub fn factor(kff: &SparseColMat<usize, f64>, contact: &[usize]) -> Result<(Self, Vec<f64>), ModelError> {
        let n = kff.nrows();
        let singular = |e: String| ModelError::Singular(e);
        // the whole matrix's AMD order, then the contact dofs moved to the end (each part in
        // that order)
        let amd = factorize_symbolic_cholesky(kff.symbolic(), Side::Lower, SymmetricOrdering::Amd, Default::default())
            .map_err(|e| ModelError::Sparse(format!("{e:?}")))?;
        let order: Vec<usize> = match amd.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        drop(amd);
        let mut is_contact = vec![false; n];
        for &c in contact {
            is_contact[c] = true;
        }
        let mut fwd: Vec<usize> = order.iter().copied().filter(|&i| !is_contact[i]).collect();
        let first = fwd.len();
        fwd.extend(order.iter().copied().filter(|&i| is_contact[i]));
        let mut inv = vec![0usize; n];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        let perm = faer::perm::PermRef::new_checked(&fwd, &inv, n);
        let symbolic = factorize_symbolic_cholesky(
            kff.symbolic(),
            Side::Lower,
            SymmetricOrdering::Custom(perm),
            Default::default(),
        )
        .map_err(|e| ModelError::Sparse(format!("{e:?}")))?;
        let mut values = vec![0.0; symbolic.len_val()];
        // faer is built without its rayon feature: one thread (the sweeps use both cores)
        let par = Par::Seq;
        let mut mem = MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut values,
                kff.as_ref(),
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|e| singular(format!("{e:?}")))?;
        drop(mem);
        let factor = Self { symbolic: std::sync::Arc::new(symbolic), values };
        // the trailing block L_cc, then W in the permuted order
        let nc = n - first;
        let mut lcc = Mat::<f64>::zeros(nc, nc);
        factor.for_each_entry_from(first, |row, col, v| lcc[(row - first, col - first)] = v);
        let mut x = Mat::<f64>::identity(nc, nc);
        solve_lower_triangular_in_place(lcc.as_ref(), x.as_mut(), par);
        let wp = x.transpose() * x.as_ref();
        // back to `contact`'s order
        let at: Vec<usize> = contact.iter().map(|&c| inv[c] - first).collect();
        let mut w = vec![0.0; contact.len() * contact.len()];
        for (i, &pi) in at.iter().enumerate() {
            for (j, &pj) in at.iter().enumerate() {
                w[i * contact.len() + j] = wp[(pi, pj)];
            }
        }
        Ok((factor, w))
    }

    /// Every stored entry `(row, col, value)` of `L` (permuted indices) with `col >= from`.
    fn for_each_entry_from(&self, from: usize, mut f: impl FnMut(usize, usize, f64)) {
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(sn) => {
                let l = SupernodalLltRef::new(sn, &self.values);
                for s in 0..sn.n_supernodes() {
                    let node = l.supernode(s);
                    let (start, val) = (node.start(), node.val());
                    let ncols = val.ncols();
                    if start + ncols <= from {
                        continue;
                    }
                    let pattern = node.pattern();
                    for c in 0..ncols {
                        let col = start + c;
                        if col < from {
                            continue;
                        }
                        for r in c..ncols {
                            f(start + r, col, val[(r, c)]);
                        }
                        for (k, &row) in pattern.iter().enumerate() {
                            f(row, col, val[(ncols + k, c)]);
                        }
                    }
                }
            }
            SymbolicCholeskyRaw::Simplicial(sym) => {
                let l = SimplicialLltRef::new(sym, &self.values);
                let (ptr, idx) = (sym.col_ptr(), sym.row_idx());
                let values = l.values();
                for col in from..sym.ncols() {
                    for k in ptr[col]..ptr[col + 1] {
                        f(idx[k], col, values[k]);
                    }
                }
            }
        }
    }

    /// Solve `K_FF X = B` in place (`B`: `n x k`).
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        let par = Par::Seq;
        let mut mem = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(rhs.ncols(), par));
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(Conj::No, rhs, par, MemStack::new(&mut mem));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::contact::delassus::compliance;
    use crate::float_cmp::Tol;

    /// The condensed `W` is the blocked solves' `W` (faer's own AMD factor, every contact dof a
    /// right-hand side: `contact::delassus::compliance`, the 2-D path), and a solve with the
    /// contact-last factor has a small residual against `K_FF` itself. On the small ironing-3-D
    /// model of `contact3d::tests` (7 000 free dofs, 630 contact dofs): both compute the same
    /// inverse by different eliminations, so they agree to rounding amplified by `K`'s
    /// condition (~1e5 here): 1e-9 of W's largest entry.
    #[test]
    fn the_trailing_block_gives_the_blocked_solves_w() {
        let p = crate::contact3d::tests::ironing_params();
        let m = crate::contact3d::build_ironing3d(&p).expect("model");
        let split = &m.split;
        let nf = split.n_free();
        let kff = split.free_block(&m.k).expect("K_FF");
        let cnodes: Vec<usize> = m.slaves.iter().chain(&m.masters).copied().collect();
        let cfree: Vec<Option<usize>> =
            cnodes.iter().flat_map(|&n| [3 * n, 3 * n + 1, 3 * n + 2]).map(|d| split.free_index(d)).collect();
        let contact: Vec<usize> = cfree.iter().flatten().copied().collect();
        let (factor, w) = ContactLastFactor::factor(&kff, &contact).expect("factor");
        let llt = kff.sp_cholesky(Side::Lower).expect("llt");
        let reference = compliance(&llt, nf, &cfree, 1);
        let ncd = cfree.len();
        let scale = reference.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let at: Vec<usize> = (0..ncd).filter(|&i| cfree[i].is_some()).collect();
        assert_eq!(at.len(), contact.len());
        for (i, &ci) in at.iter().enumerate() {
            for (j, &cj) in at.iter().enumerate() {
                assert_close!(w[i * at.len() + j], reference[ci * ncd + cj], Tol::abs(1e-9 * scale));
            }
        }
        // a solve: K_FF x = b to a backward error of rounding
        let mut rng = crate::rng::Rng::new(3);
        let b: Vec<f64> = (0..nf).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let mut x = b.clone();
        factor.solve_in_place(MatMut::from_column_major_slice_mut(&mut x, nf, 1));
        let mut full = vec![0.0; m.n_dof()];
        split.scatter_free(&x, &mut full);
        let kx = m.k.matvec(&full);
        let resid = split.free().iter().zip(&b).map(|(&d, bi)| (kx[d] - bi).abs()).fold(0.0, f64::max);
        assert!(resid < 1e-10, "residual {resid}");
    }
}
