//! Small dense kernels of the online solve: the shared vectorised dot product and axpy
//! ([`crate::kernels`]), rows of `Phi_c` combined, triangular solves with a column-major
//! Cholesky factor.

use crate::contact::pairing::GapRow;
pub use crate::kernels::{axpy, dot};

/// `out = sum_j coef_j Phi_c[dof_j, :]` over the entries of a gap row (or of any row of
/// at most six contact-dof entries), in one pass over `out`
/// (each element written once, not read back per entry).
pub fn combine_rows(row: &GapRow, phi_c: &[f64], r: usize, out: &mut [f64]) {
    let rows: [&[f64]; 6] = std::array::from_fn(|j| {
        let cd = row.dof[j.min(row.len - 1)];
        &phi_c[cd * r..(cd + 1) * r]
    });
    let c = row.coef;
    match row.len {
        6 => {
            for (j, o) in out.iter_mut().enumerate() {
                *o = c[0] * rows[0][j]
                    + c[1] * rows[1][j]
                    + c[2] * rows[2][j]
                    + c[3] * rows[3][j]
                    + c[4] * rows[4][j]
                    + c[5] * rows[5][j];
            }
        }
        4 => {
            for (j, o) in out.iter_mut().enumerate() {
                *o = c[0] * rows[0][j] + c[1] * rows[1][j] + c[2] * rows[2][j] + c[3] * rows[3][j];
            }
        }
        _ => {
            out.iter_mut().for_each(|o| *o = 0.0);
            for k in 0..row.len {
                axpy(c[k], rows[k], out);
            }
        }
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

    /// Against naive triangular solves (1e-13: reordered sums of O(1) products).
    #[test]
    fn triangular_solves_match_naive_loops() {
        let mut rng = Rng::new(1);
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
