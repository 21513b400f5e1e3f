//! The bodies of the 3-D scenes as structured blocks: a cuboid, the octant of a ball (a quarter
//! hemisphere) and a die whose sole is a cylinder.
//!
//! **Ball octant** (the quarter hemisphere of `hertz-3d`). The unit cube `p in [0, 1]^3` is
//! mapped radially onto the octant of the unit ball, `q(p) = p ||p||_inf / ||p||_2`: the faces
//! `p_c = 0` stay on the coordinate planes (the symmetry planes and the flat face), the three
//! faces `p_c = 1` become the spherical surface, and the face `p_2 = 1` is the cap around the
//! pole, polar angle at most `atan(sqrt 2) = 54.7°` (at its corner; 45° on its edges), where
//! contact happens. `q` is homogeneous of degree one and one-to-one, so the elements are
//! well-shaped down to the centre; the worst sit at the corner `(1, 1, 1)` (angles of 120°).
//! The lattice is graded toward the pole (`p_0, p_1 -> 0`, `p_2 -> 1`) to resolve the contact
//! zone, radius `a << R`.

use super::block::{toward_one, toward_zero, Block};

/// Whether a hemisphere's curved face points up (`+z`) or down (`-z`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Facing {
    /// Curved face up, flat face below (the bottom body).
    Up,
    /// Curved face down, flat face above (the top body).
    Down,
}

/// A quarter hemisphere (`x >= cx`, `y >= cy`) of radius `radius` whose flat face lies in the
/// plane `z = centre[2]`, as a block of `n` elements along each lattice direction, graded toward
/// the pole with exponent `grading` (1: uniform). Lattice face `KMax` is the cap around the pole,
/// `KMin` the flat face, `IMin` the plane `x = cx` and `JMin` the plane `y = cy` (facing down,
/// the other way round: there lattice `i` runs along y and `j` along x).
pub fn ball_octant(centre: [f64; 3], radius: f64, n: usize, grading: f64, facing: Facing) -> Block {
    let g0 = toward_zero(grading);
    let g2 = toward_one(grading);
    Block::mapped([n, n, n], [&g0, &g0, &g2], |p| {
        let inf = p[0].max(p[1]).max(p[2]);
        let two = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        let s = if two > 0.0 { radius * inf / two } else { 0.0 };
        let q = [s * p[0], s * p[1], s * p[2]];
        match facing {
            Facing::Up => [centre[0] + q[0], centre[1] + q[1], centre[2] + q[2]],
            // (x, y, z) -> (y, x, -z) keeps the orientation (two sign changes)
            Facing::Down => [centre[0] + q[1], centre[1] + q[0], centre[2] - q[2]],
        }
    })
}

/// The cuboid `[x0, x0 + size_x] x [y0, y0 + size_y] x [z0, z0 + size_z]` with `n` elements
/// along x, y, z; `KMax` is its top `z = z0 + size_z`.
pub fn cuboid(origin: [f64; 3], size: [f64; 3], n: [usize; 3]) -> Block {
    let id = |t: f64| t;
    Block::mapped(n, [&id, &id, &id], |p| {
        [origin[0] + size[0] * p[0], origin[1] + size[1] * p[1], origin[2] + size[2] * p[2]]
    })
}

/// A die: `x in [cx - width / 2, cx + width / 2]`, `y in [y0, y0 + depth]`, its sole the
/// cylinder of radius `sole_radius` whose axis is parallel to y through `(cx, ., z_low +
/// sole_radius)`, lowest point at height `z_low`, and its top the plane `z = z_low + height`.
/// Node `(i, j, k)` sits at `x = cx - width / 2 + width i / nx`, `z = s(x) + (height - s(x)) k /
/// nz` above `z_low`, with `s(x) = R - sqrt(R^2 - (x - cx)^2)` (the 2-D iron's mapping swept
/// along y). `KMin` is the sole, `KMax` the top.
pub fn cylinder_die(centre_x: f64, y0: f64, z_low: f64, dims: [f64; 3], sole_radius: f64, n: [usize; 3]) -> Block {
    let [width, depth, height] = dims;
    let id = |t: f64| t;
    Block::mapped(n, [&id, &id, &id], |p| {
        let x = centre_x - 0.5 * width + width * p[0];
        let dx = x - centre_x;
        let s = sole_radius - (sole_radius * sole_radius - dx * dx).max(0.0).sqrt();
        [x, y0 + depth * p[1], z_low + s + (height - s) * p[2]]
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::solid::block::Face;
    use crate::solid::mesh::Mesh3d;

    /// The octant's faces land where the module doc says: the cap and the other two curved
    /// faces on the sphere, the flat face and the symmetry planes on their planes; every
    /// element is valid, and the volumes add up to an eighth of the ball's, `pi R^3 / 6`, to
    /// the error of the faceted sphere (second order in h: 2 % at 12 elements a side).
    #[test]
    fn the_ball_octant_fills_an_eighth_of_the_ball() {
        let (r, c) = (1.5, [0.2, -0.1, 3.0]);
        for facing in [Facing::Up, Facing::Down] {
            let b = ball_octant(c, r, 12, 1.6, facing);
            let (m, _) = Mesh3d::from_blocks(&[&b]);
            m.check_jacobians().expect("valid elements");
            let dist = |n: usize| {
                let x = b.nodes[n];
                ((x[0] - c[0]).powi(2) + (x[1] - c[1]).powi(2) + (x[2] - c[2]).powi(2)).sqrt()
            };
            for face in [Face::IMax, Face::JMax, Face::KMax] {
                for n in b.face_nodes(face) {
                    assert_close!(dist(n), r, Tol::rel(1e-14));
                }
            }
            for n in b.face_nodes(Face::KMin) {
                assert_close!(b.nodes[n][2], c[2], Tol::abs(1e-14));
            }
            let sign = if facing == Facing::Up { 1.0 } else { -1.0 };
            let pole = b.node(0, 0, 12);
            assert_close!(b.nodes[pole][2], c[2] + sign * r, Tol::abs(1e-14));
            assert!(b.nodes.iter().all(|x| x[0] >= c[0] - 1e-15 && x[1] >= c[1] - 1e-15));
            let volume: f64 = (0..m.n_elements())
                .map(|e| {
                    let xe = m.element_coords(e);
                    crate::solid::hex8::GAUSS.iter().map(|&p| crate::solid::hex8::jacobian(&xe, p).det).sum::<f64>()
                })
                .sum();
            assert_close!(volume, std::f64::consts::PI * r.powi(3) / 6.0, Tol::rel(0.02));
        }
    }

    /// The die's sole is the cylinder and its top the plane.
    #[test]
    fn the_die_sole_is_a_cylinder() {
        let b = cylinder_die(1.0, 0.0, 0.0, [1.0, 0.5, 1.0], 2.0, [8, 3, 4]);
        let (m, _) = Mesh3d::from_blocks(&[&b]);
        m.check_jacobians().expect("valid");
        for n in b.face_nodes(Face::KMin) {
            let x = b.nodes[n];
            assert_close!(((x[0] - 1.0).powi(2) + (x[2] - 2.0).powi(2)).sqrt(), 2.0, Tol::rel(1e-14));
        }
        for n in b.face_nodes(Face::KMax) {
            assert_close!(b.nodes[n][2], 1.0, Tol::abs(1e-14));
        }
    }
}
