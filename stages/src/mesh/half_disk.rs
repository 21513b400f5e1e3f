//! Mapped quad mesh of a half-disk (the bodies of the Hertz scenes,
//! docs/scenes.md#hertz-and-hertz-fine).
//!
//! # Scheme: one Coons (transfinite) patch with two corners on the arc
//!
//! In local coordinates (centre at the origin, flat face on `y = 0`, arc above) the four sides of
//! the logical square `(xi, eta) in [0, 1]^2` are
//!
//! ```text
//!                  T: arc, angle pi - th_c .. th_c      (n_x elements)
//!              P01 _.-~~~~~~~~~~~~~~~~~~~~~~-._ P11      th_c = n_side pi / n_arc
//!               .-'                             '-.
//!  L: arc      /                                   \     R: arc, angle 0 .. th_c
//!  pi..pi-th_c|                                     |      (n_side elements)
//!  (n_side)   +-------------------------------------+
//!            P00        B: flat face (n_x)          P10
//!           (-R, 0)                                (R, 0)
//! ```
//!
//! `x(xi, eta) = (1-eta) B(xi) + eta T(xi) + (1-xi) L(eta) + xi R(eta) - bilinear(corners)`,
//! sampled on a uniform `n_x x n_side` lattice with `n_x = n_arc - 2 n_side`. All three arc
//! sides are parametrised by angle with the same step `pi / n_arc`, so the curved edge carries
//! exactly `n_arc` equal elements and the flat face `n_x` equal elements.
//!
//! The corners `(±R, 0)` are the only non-smooth points of the boundary, so a single mapped
//! block must put its two other corners on the smooth arc: the one element at each of `P01`,
//! `P11` has an interior angle of `180° - 180°/n_arc` there (`det J` vanishes at that corner node
//! but stays positive at every Gauss point; [`crate::mesh::Mesh2d::check_jacobians`] verifies it).
//! These two elements sit `th_c` (16° for the defaults) from the flat face, far from the contact
//! zone around the apex. The alternative with no such corner (an O-grid: half-square core plus
//! three blocks) forces all `n_arc` divisions through the interior and gives ~1000 nodes at
//! `n_arc = 78` instead of the paper's ~500.
//!
//! # Node counts
//!
//! `(n_x + 1)(n_side + 1)` nodes and `n_x n_side` elements. Default `n_side = round(7 n_arc / 78)`:
//!
//! | n_arc | n_side | n_x | nodes | elements |
//! |-------|--------|-----|-------|----------|
//! | 78    | 7      | 64  | 520   | 448      |
//! | 312   | 28     | 256 | 7453  | 7168     |
//!
//! (paper, gmsh at n_arc = 78: 513 nodes, 466 elements). Elements near the apex are about
//! `pi R / n_arc` wide and `R / n_side` tall (aspect ratio about 3.6 with the defaults).

use super::{Grid, MeshError};
use std::f64::consts::PI;

/// Parameters of [`half_disk`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfDiskParams {
    /// Centre of the full disk (midpoint of the flat face).
    pub center: [f64; 2],
    /// Radius (> 0).
    pub radius: f64,
    /// Elements on the curved edge (>= 3).
    pub n_arc: usize,
    /// Elements on each of the two short arc sides of the Coons patch, i.e. element layers
    /// between flat face and arc (>= 1, `2 n_side < n_arc`).
    pub n_side: usize,
    /// `true`: arc above the flat face (bottom body of the Hertz scene); `false`: arc below
    /// (the same mesh rotated by 180° about the centre, which keeps the quads counter-clockwise).
    pub arc_up: bool,
}

impl HalfDiskParams {
    /// The default number of side elements, `round(7 n_arc / 78)` (at least 1): 7 at the paper's
    /// `n_arc = 78`, which gives 520 nodes per body (paper: 513).
    pub fn default_n_side(n_arc: usize) -> usize {
        ((7 * n_arc + 39) / 78).max(1)
    }
}

/// A meshed half-disk and its boundary node lists (grid-local ids).
#[derive(Debug, Clone, PartialEq)]
pub struct HalfDisk {
    /// The mapped grid.
    pub grid: Grid,
    /// Curved-edge nodes in counter-clockwise order around the body (body on the left);
    /// `n_arc + 1` nodes, the first and last being the ends of the flat face.
    pub arc: Vec<usize>,
    /// Flat-face nodes; `n_x + 1` nodes.
    pub flat: Vec<usize>,
}

/// Mesh a half-disk with the Coons scheme described in the module docs.
pub fn half_disk(p: &HalfDiskParams) -> Result<HalfDisk, MeshError> {
    let r = p.radius;
    if !(r.is_finite() && r > 0.0) {
        return Err(MeshError::BadParameter(format!("half-disk radius must be > 0, got {r}")));
    }
    if p.n_arc < 3 {
        return Err(MeshError::BadParameter(format!(
            "half-disk needs n_arc >= 3 elements on the curved edge, got {}",
            p.n_arc
        )));
    }
    if p.n_side == 0 || 2 * p.n_side >= p.n_arc {
        return Err(MeshError::BadParameter(format!(
            "half-disk needs 1 <= n_side and 2 n_side < n_arc, got n_side = {} with n_arc = {}",
            p.n_side, p.n_arc
        )));
    }
    let n_side = p.n_side;
    let n_x = p.n_arc - 2 * n_side;
    let dth = PI / p.n_arc as f64;
    let th_c = n_side as f64 * dth;
    let arc = |phi: f64| [r * phi.cos(), r * phi.sin()];
    // Sides of the logical square, by lattice index so that arc nodes land exactly on the
    // angles k * dth (no accumulated rounding).
    let bottom = |i: usize| [-r + 2.0 * r * i as f64 / n_x as f64, 0.0];
    let top = |i: usize| arc(PI - th_c - (i as f64) * dth);
    let left = |j: usize| arc(PI - (j as f64) * dth);
    let right = |j: usize| arc((j as f64) * dth);
    let (p00, p10, p01, p11) = (bottom(0), bottom(n_x), top(0), top(n_x));
    let (cx, cy) = (p.center[0], p.center[1]);
    let grid = Grid::from_fn(n_x, n_side, |i, j| {
        let (xi, eta) = (i as f64 / n_x as f64, j as f64 / n_side as f64);
        let (b, t, l, rr) = (bottom(i), top(i), left(j), right(j));
        let mut x = [0.0; 2];
        for c in 0..2 {
            x[c] = (1.0 - eta) * b[c] + eta * t[c] + (1.0 - xi) * l[c] + xi * rr[c]
                - ((1.0 - xi) * (1.0 - eta) * p00[c]
                    + xi * (1.0 - eta) * p10[c]
                    + (1.0 - xi) * eta * p01[c]
                    + xi * eta * p11[c]);
        }
        // Boundary nodes exactly on the boundary curves (the formula reproduces them up to
        // rounding; set them exactly so arc nodes are at radius r to the last bit).
        if j == 0 {
            x = b;
        } else if j == n_side {
            x = t;
        } else if i == 0 {
            x = l;
        } else if i == n_x {
            x = rr;
        }
        if p.arc_up {
            [cx + x[0], cy + x[1]]
        } else {
            [cx - x[0], cy - x[1]]
        }
    });
    let mut arc_nodes = Vec::with_capacity(p.n_arc + 1);
    arc_nodes.extend((0..=n_side).map(|j| grid.node(n_x, j)));
    arc_nodes.extend((0..n_x).rev().map(|i| grid.node(i, n_side)));
    arc_nodes.extend((0..n_side).rev().map(|j| grid.node(0, j)));
    let flat = grid.bottom();
    Ok(HalfDisk { grid, arc: arc_nodes, flat })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::mesh::Mesh2d;

    fn params(n_arc: usize, arc_up: bool) -> HalfDiskParams {
        HalfDiskParams {
            center: [0.0, if arc_up { -1.0 } else { 1.0 }],
            radius: 1.0,
            n_arc,
            n_side: HalfDiskParams::default_n_side(n_arc),
            arc_up,
        }
    }

    /// Node and element counts of the documented table, arc nodes on the circle at equal angles,
    /// and positive Jacobians everywhere.
    #[test]
    fn half_disk_counts_arc_and_jacobians() {
        for (n_arc, nodes, elems) in [(78, 520, 448), (312, 7453, 7168)] {
            for up in [true, false] {
                let hd = half_disk(&params(n_arc, up)).expect("valid half-disk");
                assert_eq!(hd.grid.n_nodes(), nodes);
                assert_eq!(hd.grid.quads().len(), elems);
                assert_eq!(hd.arc.len(), n_arc + 1);
                let c = params(n_arc, up).center;
                // Chord lengths of equal-angle arc steps: 2 sin(pi / (2 n_arc)); arc nodes come
                // from cos/sin of exact multiples, so 1e-12 covers rounding.
                let chord = 2.0 * (PI / (2.0 * n_arc as f64)).sin();
                for w in hd.arc.windows(2) {
                    let (a, b) = (hd.grid.nodes[w[0]], hd.grid.nodes[w[1]]);
                    let ra = ((a[0] - c[0]).powi(2) + (a[1] - c[1]).powi(2)).sqrt();
                    assert_close!(ra, 1.0, Tol::abs(1e-12));
                    let len = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
                    assert_close!(len, chord, Tol::rel(1e-10));
                    // Counter-clockwise around the body: the centre is on the left of each
                    // arc segment (cross product > 0).
                    let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                    assert!(cross > 0.0, "arc not counter-clockwise");
                }
                let (m, _) = Mesh2d::from_grids(&[&hd.grid]);
                let min_det = m.check_jacobians().expect("positive Jacobians");
                assert!(min_det > 0.0);
            }
        }
    }

    /// The apex of the bottom body (arc up, centre (0,-1)) is at the origin and is the middle
    /// arc node.
    #[test]
    fn apex_at_origin() {
        let hd = half_disk(&params(78, true)).expect("valid");
        let apex = hd.grid.nodes[hd.arc[39]];
        // sin/cos of pi/2 computed as 39 * (pi/78): rounding only.
        assert_close!(apex[0], 0.0, Tol::abs(1e-14));
        assert_close!(apex[1], 0.0, Tol::abs(1e-14));
    }

    #[test]
    fn half_disk_rejects_bad_parameters() {
        let mut p = params(78, true);
        p.n_arc = 2;
        p.n_side = 1;
        assert!(half_disk(&p).is_err());
        let mut p = params(78, true);
        p.n_side = 39;
        assert!(half_disk(&p).is_err());
        let mut p = params(78, true);
        p.radius = 0.0;
        assert!(half_disk(&p).is_err());
    }
}
