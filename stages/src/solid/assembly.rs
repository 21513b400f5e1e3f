//! Global assembly of the 3-D stiffness `K = sum_e A_e^T K_e A_e` into a compressed-row matrix
//! over all dofs, without triplets: the pattern comes from the node graph (nodes that share an
//! element), each node pair a dense 3x3 block, so a 10^5-dof mesh needs its `nnz` values and
//! nothing of the `576 n_e` triplets an element-by-element list would hold. Element matrices
//! are formed in parallel in chunks and added in element order, so the sums, and `K`, are the
//! same bits on any number of threads.

use rayon::prelude::*;

use super::hex8;
use super::mesh::Mesh3d;
use crate::fem::{CsrMatrix, Material};

/// Assembly failure: an element with a non-positive Jacobian.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("element {element}: non-positive Jacobian det = {det:e} at Gauss point {gauss_point}")]
pub struct Assembly3dError {
    /// Element index.
    pub element: usize,
    /// Gauss point index ([`hex8::GAUSS`] order; 8 the centre).
    pub gauss_point: usize,
    /// Determinant found.
    pub det: f64,
}

/// A 6x6 matrix in Voigt notation.
type Voigt = [[f64; 6]; 6];

/// Elements whose matrices are formed together before they are added.
const CHUNK: usize = 512;

/// The node graph's sorted adjacency (each node with itself), CSR.
fn node_graph(mesh: &Mesh3d) -> (Vec<usize>, Vec<usize>) {
    let n = mesh.n_nodes();
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
    for h in &mesh.hexes {
        for &a in h {
            adj[a].extend_from_slice(h);
        }
    }
    let mut ptr = Vec::with_capacity(n + 1);
    ptr.push(0);
    let mut idx = Vec::new();
    for mut a in adj {
        a.sort_unstable();
        a.dedup();
        idx.extend_from_slice(&a);
        ptr.push(idx.len());
    }
    (ptr, idx)
}

/// Assemble the stiffness of every element of `mesh`, element `e` with
/// `materials[mesh.element_body[e]]` (selective integration where the material asks for it).
pub fn assemble_stiffness(mesh: &Mesh3d, materials: &[Material]) -> Result<CsrMatrix, Assembly3dError> {
    let ds: Vec<(Voigt, Voigt)> = materials
        .iter()
        .map(|m| {
            let (l, mu) = m.lame();
            hex8::elasticity(l, mu)
        })
        .collect();
    let (gptr, gidx) = node_graph(mesh);
    let n_dof = mesh.n_dof();
    // row 3 a + c holds, for each neighbour b of a (ascending), the columns 3 b, 3 b + 1, 3 b + 2
    let mut row_ptr = Vec::with_capacity(n_dof + 1);
    row_ptr.push(0);
    let mut col = Vec::new();
    for a in 0..mesh.n_nodes() {
        for _ in 0..3 {
            for &b in &gidx[gptr[a]..gptr[a + 1]] {
                col.extend_from_slice(&[3 * b, 3 * b + 1, 3 * b + 2]);
            }
            row_ptr.push(col.len());
        }
    }
    let mut val = vec![0.0; col.len()];
    let element = |e: usize| -> Result<Box<[[f64; 24]; 24]>, Assembly3dError> {
        let body = mesh.element_body[e];
        assert!(body < ds.len(), "no material for body {body}");
        let xe = mesh.element_coords(e);
        let (dev, vol) = &ds[body];
        let k = if materials[body].selective {
            hex8::stiffness_selective(&xe, dev, vol)
        } else {
            hex8::stiffness(&xe, &hex8::sum(dev, vol))
        };
        k.map_err(|b| Assembly3dError { element: e, gauss_point: b.gauss_point, det: b.det })
    };
    for first in (0..mesh.n_elements()).step_by(CHUNK) {
        let last = (first + CHUNK).min(mesh.n_elements());
        let kes: Vec<_> = (first..last).into_par_iter().map(element).collect::<Result<_, _>>()?;
        for (e, ke) in (first..last).zip(kes) {
            let h = &mesh.hexes[e];
            for (i, &a) in h.iter().enumerate() {
                let nbrs = &gidx[gptr[a]..gptr[a + 1]];
                for (j, &b) in h.iter().enumerate() {
                    let pos = nbrs.binary_search(&b).expect("b shares an element with a");
                    for r in 0..3 {
                        let start = row_ptr[3 * a + r] + 3 * pos;
                        for c in 0..3 {
                            val[start + c] += ke[3 * i + r][3 * j + c];
                        }
                    }
                }
            }
        }
    }
    Ok(CsrMatrix { n: n_dof, row_ptr, col, val })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::fem::DofSplit;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;
    use crate::solid::block::Block;

    /// Patch test (Zienkiewicz & Taylor, vol. 1, ch. 10; MacNeal & Harder 1985): on a block of
    /// 3 x 3 x 3 hexahedra whose interior nodes are moved randomly by up to 0.25 h, imposing a
    /// linear displacement on the boundary nodes reproduces it exactly inside, with both
    /// integrations (every linear field is in the trilinear space and 2x2x2 Gauss integrates
    /// constant-strain energy exactly):
    ///
    /// ```text
    ///   boundary nodes: u = a + G x (12 random coefficients)
    ///   interior:       K_FF u_F = -K_FD u_D
    /// ```
    ///
    /// Tolerance 1e-10: the solve's rounding on a 64-node K of condition number ~1e2.
    #[test]
    fn patch_test_on_a_distorted_block_reproduces_a_linear_field() {
        let id = |t: f64| t;
        let mut b = Block::mapped([3, 3, 3], [&id, &id, &id], |p| [2.0 * p[0], 1.5 * p[1], p[2]]);
        let mut rng = Rng::new(20261129);
        for k in 1..3 {
            for j in 1..3 {
                for i in 1..3 {
                    let n = b.node(i, j, k);
                    let h = [2.0 / 3.0, 0.5, 1.0 / 3.0];
                    for (x, hc) in b.nodes[n].iter_mut().zip(h) {
                        *x += rng.uniform_in(-0.25, 0.25) * hc;
                    }
                }
            }
        }
        let (mesh, _) = Mesh3d::from_blocks(&[&b]);
        mesh.check_jacobians().expect("distorted but valid");
        let coeff: Vec<f64> = (0..12).map(|_| rng.uniform_in(-0.1, 0.1)).collect();
        let field = |x: [f64; 3]| -> [f64; 3] {
            let mut u = [0.0; 3];
            for c in 0..3 {
                u[c] = coeff[4 * c] + coeff[4 * c + 1] * x[0] + coeff[4 * c + 2] * x[1] + coeff[4 * c + 3] * x[2];
            }
            u
        };
        for selective in [false, true] {
            let mat = Material { young: 3.0, poisson: 0.3, selective };
            let k = assemble_stiffness(&mesh, &[mat]).expect("assembly");
            let boundary = |n: usize| {
                let (i, rest) = (n % 4, n / 4);
                let (j, kk) = (rest % 4, rest / 4);
                [i, j, kk].iter().any(|&x| x == 0 || x == 3)
            };
            let fixed: Vec<usize> =
                (0..mesh.n_nodes()).filter(|&n| boundary(n)).flat_map(|n| [3 * n, 3 * n + 1, 3 * n + 2]).collect();
            let split = DofSplit::new(mesh.n_dof(), &fixed);
            let mut u = vec![0.0; mesh.n_dof()];
            for (n, &x) in mesh.nodes.iter().enumerate() {
                u[3 * n..3 * n + 3].copy_from_slice(&field(x));
            }
            let exact = u.clone();
            for &d in split.free() {
                u[d] = 0.0;
            }
            split.solve_unloaded(&k, &mut u);
            for (a, e) in u.iter().zip(&exact) {
                assert_close!(*a, *e, Tol::abs(1e-10));
            }
        }
    }

    /// `K` is symmetric and the same bits whatever the thread count.
    #[test]
    fn the_stiffness_is_symmetric_and_thread_independent() {
        let id = |t: f64| t;
        let b =
            Block::mapped([9, 8, 9], [&id, &id, &id], |p| [p[0] + 0.1 * p[1] * p[2], p[1], p[2] * (1.0 + 0.2 * p[0])]);
        let (mesh, _) = Mesh3d::from_blocks(&[&b]);
        let on = |t: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().expect("pool");
            pool.install(|| assemble_stiffness(&mesh, &[Material::new(1.0, 0.3)]).expect("assembly"))
        };
        let (one, two) = (on(1), on(2));
        assert_eq!(one, two);
        for r in 0..one.n {
            let (cols, vals) = one.row(r);
            for (&c, &v) in cols.iter().zip(vals) {
                let (cc, vv) = one.row(c);
                let at = cc.binary_search(&r).expect("symmetric pattern");
                assert_close!(v, vv[at], Tol::abs(1e-14));
            }
        }
    }
}
