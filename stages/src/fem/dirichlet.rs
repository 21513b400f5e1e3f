//! Dirichlet conditions by elimination: split dofs into free `F` and fixed `D`, solve
//! `K_FF u_F = f_F - K_FD u_D`.

use super::CsrMatrix;
use faer::sparse::Triplet;

/// The partition of the dofs into free and fixed ones.
#[derive(Debug, Clone, PartialEq)]
pub struct DofSplit {
    free_index: Vec<usize>,
    free: Vec<usize>,
    fixed: Vec<usize>,
}

impl DofSplit {
    /// Marker in `free_index` for a fixed dof.
    pub const FIXED: usize = usize::MAX;

    /// Split `0..n_dof` given the fixed dofs (duplicates allowed).
    pub fn new(n_dof: usize, fixed_dofs: &[usize]) -> Self {
        let mut is_fixed = vec![false; n_dof];
        for &d in fixed_dofs {
            assert!(d < n_dof, "fixed dof {d} out of range {n_dof}");
            is_fixed[d] = true;
        }
        let mut free_index = vec![Self::FIXED; n_dof];
        let (mut free, mut fixed) = (Vec::new(), Vec::new());
        for (d, &f) in is_fixed.iter().enumerate() {
            if f {
                fixed.push(d);
            } else {
                free_index[d] = free.len();
                free.push(d);
            }
        }
        Self { free_index, free, fixed }
    }

    /// Number of dofs.
    pub fn n_dof(&self) -> usize {
        self.free_index.len()
    }
    /// Number of free dofs.
    pub fn n_free(&self) -> usize {
        self.free.len()
    }
    /// Free dofs (global ids, increasing); position = free index.
    pub fn free(&self) -> &[usize] {
        &self.free
    }
    /// Fixed dofs (global ids, increasing).
    pub fn fixed(&self) -> &[usize] {
        &self.fixed
    }
    /// Free index of global dof `d`, `None` if fixed.
    pub fn free_index(&self, d: usize) -> Option<usize> {
        let i = self.free_index[d];
        (i != Self::FIXED).then_some(i)
    }

    /// Lower triangle of `K_FF` as faer triplets (free indices).
    pub fn free_block_lower_triplets(&self, k: &CsrMatrix) -> Vec<Triplet<usize, usize, f64>> {
        assert_eq!(k.n, self.n_dof(), "matrix/dof-split size mismatch");
        let mut t = Vec::with_capacity(k.nnz() / 2 + k.n);
        for (fr, &r) in self.free.iter().enumerate() {
            let (cols, vals) = k.row(r);
            for (&c, &v) in cols.iter().zip(vals) {
                let fc = self.free_index[c];
                if fc != Self::FIXED && fc >= fr {
                    // row fc >= column fr: lower triangle in (row, col) = (fc, fr)
                    t.push(Triplet::new(fc, fr, v));
                }
            }
        }
        t
    }

    /// The lifted load `-K_FD u_D` over the free dofs, reading `u_D` from the fixed entries of
    /// the full vector `u_full` (its free entries are ignored).
    pub fn lift(&self, k: &CsrMatrix, u_full: &[f64]) -> Vec<f64> {
        assert_eq!(u_full.len(), self.n_dof(), "vector/dof-split size mismatch");
        self.free
            .iter()
            .map(|&r| {
                let (cols, vals) = k.row(r);
                -cols
                    .iter()
                    .zip(vals)
                    .filter(|(&c, _)| self.free_index[c] == Self::FIXED)
                    .map(|(&c, &v)| v * u_full[c])
                    .sum::<f64>()
            })
            .collect()
    }

    /// The contact-free solution `u0(mu)` of affine Dirichlet data `u_d` (full-length terms,
    /// zero at the free dofs) and the free dofs' responses `resp` to each term:
    /// `u_D(mu)` on the Dirichlet dofs, `resp_0 + sum_k mu_k resp_{k+1}` on the free ones.
    pub fn contact_free(&self, u_d: &[Vec<f64>], resp: &[Vec<f64>], mu: &[f64]) -> Vec<f64> {
        let mut u: Vec<f64> = (0..self.n_dof()).map(|d| crate::mu::affine(&u_d[0], &u_d[1..], mu, d)).collect();
        for (k, &d) in self.free.iter().enumerate() {
            u[d] = crate::mu::affine(&resp[0], &resp[1..], mu, k);
        }
        u
    }

    /// The affine terms of [`Self::contact_free`], full length: `u_d[k]` with its free entries
    /// replaced by `resp[k]`.
    pub fn contact_free_terms(&self, u_d: &[Vec<f64>], resp: &[Vec<f64>]) -> Vec<Vec<f64>> {
        (0..resp.len())
            .map(|k| {
                let mut t = u_d[k].clone();
                for (fi, &d) in self.free.iter().enumerate() {
                    t[d] = resp[k][fi];
                }
                t
            })
            .collect()
    }

    /// `y = K x` with the Dirichlet rows zeroed.
    pub fn mul_zero_fixed(&self, k: &CsrMatrix, x: &[f64], y: &mut [f64]) {
        k.matvec_into(x, y);
        for &d in &self.fixed {
            y[d] = 0.0;
        }
    }

    /// `K_FF`'s lower triangle as faer's sparse matrix (the message of faer's error otherwise).
    pub fn free_block(&self, k: &CsrMatrix) -> Result<faer::sparse::SparseColMat<usize, f64>, String> {
        let nf = self.n_free();
        faer::sparse::SparseColMat::try_new_from_triplets(nf, nf, &self.free_block_lower_triplets(k))
            .map_err(|e| format!("{e:?}"))
    }

    /// The lifted loads `-K_FD u_Dk` of the affine terms `u_d` and their free-dof responses
    /// `K_FF^{-1} (-K_FD u_Dk)`, all terms solved together by `solve` (in place, `n_free x
    /// terms`); the responses are `None` if one is not finite (a singular `K_FF`).
    pub fn responses(
        &self,
        k: &CsrMatrix,
        u_d: &[Vec<f64>],
        solve: impl FnOnce(faer::MatMut<'_, f64>),
    ) -> (Vec<Vec<f64>>, Option<Vec<Vec<f64>>>) {
        let nf = self.n_free();
        let lift: Vec<Vec<f64>> = u_d.iter().map(|ud| self.lift(k, ud)).collect();
        let terms = lift.len();
        let mut r2: Vec<f64> = lift.iter().flatten().copied().collect();
        solve(faer::MatMut::from_column_major_slice_mut(&mut r2, nf, terms));
        let resp: Vec<Vec<f64>> = r2.chunks(nf.max(1)).take(terms).map(<[f64]>::to_vec).collect();
        let finite = resp.iter().flatten().all(|v| v.is_finite());
        (lift, finite.then_some(resp))
    }

    /// Write free values `u_free` into their places in `u_full`.
    pub fn scatter_free(&self, u_free: &[f64], u_full: &mut [f64]) {
        assert!(u_free.len() == self.n_free() && u_full.len() == self.n_dof(), "size mismatch");
        for (&d, &v) in self.free.iter().zip(u_free) {
            u_full[d] = v;
        }
    }
}

#[cfg(test)]
impl DofSplit {
    /// The tests' reference solve: `u_full`'s free entries from `K_FF u_F = -K_FD u_D` (no load;
    /// `u_D` read from its fixed entries), by faer's sparse Cholesky.
    pub(crate) fn solve_unloaded(&self, k: &CsrMatrix, u_full: &mut [f64]) {
        use faer::linalg::solvers::Solve;
        let mut rhs = self.lift(k, u_full);
        let llt = self.free_block(k).expect("K_FF").sp_cholesky(faer::Side::Lower).expect("SPD");
        llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(&mut rhs, self.n_free(), 1));
        self.scatter_free(&rhs, u_full);
    }
}
