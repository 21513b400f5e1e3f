//! Translates of contact responses along a regular slave body: a primal enrichment without
//! full-order solves.
//!
//! Where the slave body is meshed as a regular grid along `x` with the slave surface's node
//! spacing `h` (columns `c = (x - x_0) / h`, the same heights `y` in every column), a training
//! response `u` translated by `k` columns,
//!
//! ```text
//! (T_k u)(c, y) = u(c - k, y)   on the slave body   (0 where column c - k does not exist),
//! (T_k u) = u                   on every other body,
//! ```
//!
//! is, away from the body's ends, the response the master would cause `k h` further on with the
//! same offset within a node spacing: the registration's argument (a whole-node shift) applied
//! to the displacement. The online solve needs the displacement between two training travels,
//! which the training responses miss (docs/design-notes.md#an-exact-corrected-step); the
//! translates by `±k` give it, at no full-order solve.
//!
//! A slave body that is not such a grid (a curved surface, a graded mesh, slaves on two bodies)
//! is refused with the reason: its translates are not responses of anything.

use crate::mesh::Mesh2d;

/// Relative tolerance (of `h`) on a node's distance from its grid column: the grids are built
/// as `x_0 + c h` in floating point, so a node of a regular grid is off by rounding only.
const ON_GRID: f64 = 1e-9;

/// Why translates could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TranslateError {
    /// The slave body is not a regular grid of the slave surface's spacing.
    #[error("the slave body is not a regular grid along x with the slave surface's node spacing ({0}); translates of its responses need one")]
    NotAGrid(String),
}

/// The slave body's grid: each node as `(node, column, row)`, and the column and row counts.
struct Grid {
    cells: Vec<(usize, usize, usize)>,
    cols: usize,
    rows: usize,
}

/// The slave body's grid, or why it is not one.
fn grid(mesh: &Mesh2d, slaves: &[usize]) -> Result<Grid, TranslateError> {
    let not = |why: String| TranslateError::NotAGrid(why);
    let Some(&first) = slaves.first() else { return Err(not("no slave node".into())) };
    if slaves.len() < 2 {
        return Err(not("a single slave node has no spacing".into()));
    }
    let body = mesh.node_body[first];
    if slaves.iter().any(|&s| mesh.node_body[s] != body) {
        return Err(not("the slaves lie on more than one body".into()));
    }
    let x = |i: usize| mesh.nodes[i][0];
    let (lo, hi) = slaves.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| (a.min(x(i)), b.max(x(i))));
    let h = (hi - lo) / (slaves.len() - 1) as f64;
    if h.is_nan() || h <= 0.0 {
        return Err(not("the slave nodes share one abscissa".into()));
    }
    let nodes: Vec<usize> = (0..mesh.nodes.len()).filter(|&i| mesh.node_body[i] == body).collect();
    let mut heights: Vec<u64> = nodes.iter().map(|&i| mesh.nodes[i][1].to_bits()).collect();
    heights.sort_unstable();
    heights.dedup();
    let mut cells = Vec::with_capacity(nodes.len());
    let mut max_col = 0;
    for &i in &nodes {
        let c = ((x(i) - lo) / h).round();
        if c < 0.0 || (x(i) - (lo + c * h)).abs() > ON_GRID * h {
            return Err(not(format!("node {i} at x = {} is not on a column", x(i))));
        }
        let col = c as usize;
        max_col = max_col.max(col);
        let row = heights.binary_search(&mesh.nodes[i][1].to_bits()).unwrap_or(0);
        cells.push((i, col, row));
    }
    let (cols, rows) = (max_col + 1, heights.len());
    if cols * rows != nodes.len() {
        return Err(not(format!("{} nodes on {cols} columns of {rows} heights", nodes.len())));
    }
    Ok(Grid { cells, cols, rows })
}

/// `responses` (column-major, `n_dof = 2 n_nodes` rows, 2 dofs per node) followed by each of
/// them translated by `-shift` and then `+shift` columns of the slave body's grid.
pub fn with_translates(
    mesh: &Mesh2d,
    slaves: &[usize],
    responses: &[f64],
    shift: usize,
) -> Result<Vec<f64>, TranslateError> {
    let Grid { cells, cols, rows } = grid(mesh, slaves)?;
    let n = 2 * mesh.nodes.len();
    // the node at each (column, row)
    let mut at = vec![usize::MAX; cols * rows];
    for &(i, c, r) in &cells {
        if at[c * rows + r] != usize::MAX {
            return Err(TranslateError::NotAGrid(format!("two nodes at column {c}, height {r}")));
        }
        at[c * rows + r] = i;
    }
    let mut out = Vec::with_capacity(3 * responses.len());
    out.extend_from_slice(responses);
    for k in [-(shift as i64), shift as i64] {
        for u in responses.chunks_exact(n) {
            let mut t = u.to_vec();
            for &(i, c, r) in &cells {
                let from = c as i64 - k;
                let src = (0..cols as i64).contains(&from).then(|| at[from as usize * rows + r]);
                for d in 0..2 {
                    t[2 * i + d] = src.map_or(0.0, |j| u[2 * j + d]);
                }
            }
            out.extend(t);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{hertz, ironing_coarse};

    /// On ironing-coarse's slab, a field `f(x, y)` translated by `k` columns is `f(x - k h, y)`
    /// at every slab node whose source column exists and 0 at the others; the iron's values are
    /// unchanged. Exact: the values are copied, and `x - k h` is a node's abscissa to rounding,
    /// which the field (a polynomial in `round((x - x_0) / h)`) does not see.
    #[test]
    fn a_translate_moves_the_slab_by_whole_columns() {
        let fm = ironing_coarse();
        let mesh = fm.model().mesh();
        let slaves = fm.model().slave_nodes();
        let slab = mesh.node_body[slaves[0]];
        let xs: Vec<f64> = slaves.iter().map(|&s| mesh.nodes[s][0]).collect();
        let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let h = (hi - lo) / (slaves.len() - 1) as f64;
        let col = |i: usize| ((mesh.nodes[i][0] - lo) / h).round();
        let f = |c: f64, y: f64, d: usize| (c * c + 3.0 * c + 7.0 * y + d as f64) * 1e-3;
        let n = 2 * mesh.nodes.len();
        let u: Vec<f64> = (0..n).map(|k| f(col(k / 2), mesh.nodes[k / 2][1], k % 2)).collect();
        let k = 3usize;
        let out = with_translates(mesh, slaves, &u, k).expect("a grid");
        assert_eq!(out.len(), 3 * n);
        let cols = (0..mesh.nodes.len()).filter(|&i| mesh.node_body[i] == slab).map(col).fold(0.0, f64::max);
        for (t, sign) in [(&out[n..2 * n], -1.0), (&out[2 * n..], 1.0)] {
            for i in 0..mesh.nodes.len() {
                for d in 0..2 {
                    let want = if mesh.node_body[i] != slab {
                        u[2 * i + d]
                    } else {
                        let from = col(i) - sign * k as f64;
                        if (0.0..=cols).contains(&from) {
                            f(from, mesh.nodes[i][1], d)
                        } else {
                            0.0
                        }
                    };
                    assert_eq!(t[2 * i + d].to_bits(), want.to_bits(), "node {i} dof {d} shift {}", sign * k as f64);
                }
            }
        }
        assert!(out[..n].iter().zip(&u).all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    /// Hertz's slaves lie on a curved surface: refused, naming why.
    #[test]
    fn a_slave_body_that_is_not_a_grid_is_refused() {
        let fm = hertz();
        let mesh = fm.model().mesh();
        let e = with_translates(mesh, fm.model().slave_nodes(), &vec![0.0; 2 * mesh.nodes.len()], 2)
            .expect_err("hertz is not a grid");
        assert!(e.to_string().contains("not a regular grid"), "{e}");
    }
}
