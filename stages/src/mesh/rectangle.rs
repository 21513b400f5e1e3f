//! Structured rectangle `[x0, x0 + lx] x [y0, y0 + ly]` with `nx x ny` equal elements.

use super::{Grid, MeshError};

/// A uniform `nx x ny` grid of the rectangle with lower-left corner `(x0, y0)` and side lengths
/// `lx`, `ly`. Errors if a size is not positive and finite or a count is zero.
pub fn rectangle(x0: f64, y0: f64, lx: f64, ly: f64, nx: usize, ny: usize) -> Result<Grid, MeshError> {
    if !(lx.is_finite() && ly.is_finite() && lx > 0.0 && ly > 0.0) {
        return Err(MeshError::BadParameter(format!(
            "rectangle side lengths must be positive and finite, got {lx} x {ly}"
        )));
    }
    if nx == 0 || ny == 0 {
        return Err(MeshError::BadParameter(format!(
            "rectangle needs at least one element per direction, got {nx} x {ny}"
        )));
    }
    Ok(Grid::from_fn(nx, ny, |i, j| [x0 + lx * i as f64 / nx as f64, y0 + ly * j as f64 / ny as f64]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    #[test]
    fn rectangle_corners_and_counts() {
        let g = rectangle(0.0, -1.0, 5.0, 1.0, 100, 20).expect("valid rectangle");
        assert_eq!(g.n_nodes(), 101 * 21);
        assert_eq!(g.quads().len(), 2000);
        // Corners are computed as x0 + lx * i / nx: exact up to one rounding (1e-15 relative).
        let tr = g.nodes[g.node(100, 20)];
        assert_close!(tr[0], 5.0, Tol::abs(1e-14));
        assert_close!(tr[1], 0.0, Tol::abs(1e-14));
        assert_eq!(g.top().len(), 101);
        assert!(rectangle(0.0, 0.0, -1.0, 1.0, 2, 2).is_err());
        assert!(rectangle(0.0, 0.0, 1.0, 1.0, 0, 2).is_err());
    }
}
