//! The iron of the ironing scenes (docs/scenes.md#ironing-coarse-and-ironing-fine): a block with
//! a flat top and a convex circular sole, meshed by exactly the mapping given there.
//!
//! ```text
//!   y = h  +----------------------------+   flat top (Dirichlet in the scenes)
//!          |   |   |   |   |   |   |    |   columns vertical, x = cx - w/2 + w i / nx
//!          |   |   |   |   |   |   |    |   rows evenly spread between sole and top:
//!          |   |   |   |   |   |   |    |   y = s(x) + (h - s(x)) j / ny
//!  s(x_0)   '-.__|___|___|___|___|__.-'     sole s(x) = R - sqrt(R^2 - (x - cx)^2)
//!   y = 0              (cx, 0)              lowest point
//! ```

use super::{Grid, MeshError};

/// Geometry of the iron block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IronGeometry {
    /// x of the sole's lowest point (shipped scenes: 1.0).
    pub contact_x: f64,
    /// y of the sole's lowest point (shipped scenes: 0.0, the slab's top).
    pub contact_y: f64,
    /// Block width `w` (shipped scenes: 1).
    pub width: f64,
    /// Height `h` from the sole's lowest point to the flat top (shipped scenes: 1).
    pub height: f64,
    /// Sole radius `R` (shipped scenes: 2); must exceed `w / 2`, and the sole must stay below the top.
    pub sole_radius: f64,
}

impl IronGeometry {
    /// Height of the sole above its lowest point at abscissa `x`.
    pub fn sole_height(&self, x: f64) -> f64 {
        let dx = x - self.contact_x;
        self.sole_radius - (self.sole_radius * self.sole_radius - dx * dx).sqrt()
    }
}

/// Mesh the iron: `nx x ny` elements, node `(i, j)` at `x = cx - w/2 + w i / nx`,
/// `y = cy + s(x) + (h - s(x)) j / ny`. The sole is the grid's bottom edge (left to right, which
/// is counter-clockwise around the block) and the flat top its top edge.
pub fn iron(g: &IronGeometry, nx: usize, ny: usize) -> Result<Grid, MeshError> {
    let ok = |v: f64| v.is_finite() && v > 0.0;
    if !(ok(g.width) && ok(g.height) && ok(g.sole_radius)) {
        return Err(MeshError::BadParameter(format!(
            "iron width, height and sole_radius must be > 0, got {}, {}, {}",
            g.width, g.height, g.sole_radius
        )));
    }
    if g.sole_radius <= 0.5 * g.width {
        return Err(MeshError::BadParameter(format!(
            "iron sole_radius {} must exceed half the width {}",
            g.sole_radius,
            0.5 * g.width
        )));
    }
    let edge = g.sole_height(g.contact_x + 0.5 * g.width);
    if edge >= g.height {
        return Err(MeshError::BadParameter(format!(
            "iron sole rises {edge} at its ends, not below the top at height {}",
            g.height
        )));
    }
    if nx == 0 || ny == 0 {
        return Err(MeshError::BadParameter(format!("iron needs at least one element per direction, got {nx} x {ny}")));
    }
    Ok(Grid::from_fn(nx, ny, |i, j| {
        let x = g.contact_x - 0.5 * g.width + g.width * i as f64 / nx as f64;
        let s = g.sole_height(x);
        [x, g.contact_y + s + (g.height - s) * j as f64 / ny as f64]
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::mesh::Mesh2d;

    fn scene() -> IronGeometry {
        IronGeometry { contact_x: 1.0, contact_y: 0.0, width: 1.0, height: 1.0, sole_radius: 2.0 }
    }

    #[test]
    fn iron_follows_the_scenes_mapping() {
        let g = iron(&scene(), 30, 30).expect("valid iron");
        // Middle sole node is the lowest point (1, 0); exact arithmetic up to one rounding.
        let mid = g.nodes[g.node(15, 0)];
        assert_close!(mid[0], 1.0, Tol::abs(1e-14));
        assert_close!(mid[1], 0.0, Tol::abs(1e-14));
        // Sole end at x = 0.5: s = 2 - sqrt(4 - 0.25).
        let end = g.nodes[g.node(0, 0)];
        assert_close!(end[1], 2.0 - 3.75f64.sqrt(), Tol::abs(1e-14));
        // Top row flat at y = 1.
        for n in g.top() {
            assert_close!(g.nodes[n][1], 1.0, Tol::abs(1e-14));
        }
        let (m, _) = Mesh2d::from_grids(&[&g]);
        assert!(m.check_jacobians().is_ok());
        assert!(iron(&IronGeometry { sole_radius: 0.4, ..scene() }, 4, 4).is_err());
    }
}
