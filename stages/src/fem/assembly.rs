//! Global sparse assembly `K = sum_e A_e^T K_e A_e` into a compressed-row matrix over all dofs.

use super::Material;
use crate::mesh::Mesh2d;
use crate::q1;

/// A square sparse matrix in compressed-row form (sorted column indices, no duplicates).
#[derive(Debug, Clone, PartialEq)]
pub struct CsrMatrix {
    /// Dimension.
    pub n: usize,
    /// Row pointers; shape `n + 1`.
    pub row_ptr: Vec<usize>,
    /// Column indices; shape `nnz`.
    pub col: Vec<usize>,
    /// Values; shape `nnz`.
    pub val: Vec<f64>,
}

impl CsrMatrix {
    /// Build from `(row, col, value)` triplets, summing duplicates.
    pub fn from_triplets(n: usize, mut t: Vec<(usize, usize, f64)>) -> Self {
        t.sort_unstable_by_key(|a| (a.0, a.1));
        let mut row_ptr = vec![0usize; n + 1];
        let mut col = Vec::with_capacity(t.len() / 2);
        let mut val: Vec<f64> = Vec::with_capacity(t.len() / 2);
        let mut last: Option<(usize, usize)> = None;
        for (r, c, v) in t {
            assert!(r < n && c < n, "triplet ({r}, {c}) out of range {n}");
            if last == Some((r, c)) {
                if let Some(x) = val.last_mut() {
                    *x += v;
                }
            } else {
                col.push(c);
                val.push(v);
                row_ptr[r + 1] += 1;
                last = Some((r, c));
            }
        }
        for r in 0..n {
            row_ptr[r + 1] += row_ptr[r];
        }
        Self { n, row_ptr, col, val }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.val.len()
    }

    /// `y = A x`.
    pub fn matvec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        self.matvec_into(x, &mut y);
        y
    }

    /// `y = A x` into a preallocated `y`.
    pub fn matvec_into(&self, x: &[f64], y: &mut [f64]) {
        assert!(x.len() == self.n && y.len() == self.n, "matvec shape mismatch");
        for (r, yr) in y.iter_mut().enumerate() {
            let (a, b) = (self.row_ptr[r], self.row_ptr[r + 1]);
            *yr = self.col[a..b].iter().zip(&self.val[a..b]).map(|(&c, &v)| v * x[c]).sum();
        }
    }

    /// Row `r` as `(columns, values)`.
    pub fn row(&self, r: usize) -> (&[usize], &[f64]) {
        let (a, b) = (self.row_ptr[r], self.row_ptr[r + 1]);
        (&self.col[a..b], &self.val[a..b])
    }
}

/// Assembly failure: an element with a non-positive Jacobian.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("element {element}: non-positive Jacobian det = {det:e} at Gauss point {gauss_point}")]
pub struct AssemblyError {
    /// Element index.
    pub element: usize,
    /// Gauss point index (order of [`q1::GAUSS_2X2`]).
    pub gauss_point: usize,
    /// Determinant found.
    pub det: f64,
}

/// Assemble the plane-strain stiffness of every element of `mesh`, element `e` using
/// `materials[mesh.element_body[e]]`.
pub fn assemble_stiffness(mesh: &Mesh2d, materials: &[Material]) -> Result<CsrMatrix, AssemblyError> {
    let ds: Vec<[[f64; 3]; 3]> = materials.iter().map(Material::plane_strain).collect();
    let split: Vec<_> = materials.iter().map(Material::plane_strain_split).collect();
    let mut t = Vec::with_capacity(64 * mesh.n_elements());
    for e in 0..mesh.n_elements() {
        let body = mesh.element_body[e];
        assert!(body < ds.len(), "no material for body {body}");
        let xe = mesh.element_coords(e);
        let ke = if materials[body].selective {
            q1::stiffness_selective(&xe, &split[body].0, &split[body].1)
        } else {
            q1::stiffness(&xe, &ds[body])
        };
        let ke = ke.map_err(|b| AssemblyError { element: e, gauss_point: b.gauss_point, det: b.det })?;
        let q = mesh.quads[e];
        let dofs = [2 * q[0], 2 * q[0] + 1, 2 * q[1], 2 * q[1] + 1, 2 * q[2], 2 * q[2] + 1, 2 * q[3], 2 * q[3] + 1];
        for (r, &dr) in dofs.iter().enumerate() {
            for (c, &dc) in dofs.iter().enumerate() {
                t.push((dr, dc, ke[r][c]));
            }
        }
    }
    Ok(CsrMatrix::from_triplets(mesh.n_dof(), t))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csr_sums_duplicates_and_multiplies() {
        let a = CsrMatrix::from_triplets(3, vec![(0, 0, 1.0), (2, 1, 4.0), (0, 0, 2.0), (1, 2, -1.0), (0, 2, 5.0)]);
        assert_eq!(a.nnz(), 4);
        assert_eq!(a.row_ptr, vec![0, 2, 3, 4]);
        let y = a.matvec(&[1.0, 2.0, 3.0]);
        // small integers: exact in floating point
        crate::assert_all_close!(y, [18.0, -3.0, 8.0], crate::float_cmp::Tol::abs(0.0));
    }
}
