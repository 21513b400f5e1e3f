//! The closest point of a bilinear quadrilateral facet to a point.
//!
//! A facet `x(xi, eta) = sum_a N_a(xi, eta) x_a` over `[-1, 1]^2` (corners in the order of
//! [`crate::q1`]: `(-1,-1), (1,-1), (1,1), (-1,1)`) is minimised in `f = |x(xi, eta) - p|^2 / 2`:
//!
//! - inside: Newton on `grad f = [r . x_xi, r . x_eta] = 0` (`r = x - p`) with the exact
//!   Hessian `[[x_xi . x_xi, x_xi . x_eta + r . x_xieta], [., x_eta . x_eta]]`, from the
//!   centre; accepted when it converges inside the square with a positive definite Hessian (a
//!   local minimum);
//! - on the boundary: the four edges are straight segments, so the closest point of each is
//!   exact (`t` clamped to `[0, 1]`).
//!
//! The closest of these candidates wins; the interior one on a tie (same distance), then the
//! lower edge. A boundary point with `t` at 0 or 1 is a corner.

use crate::q1;

/// Where on the facet the closest point lies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Spot {
    /// Inside, at reference coordinates `(xi, eta)`.
    Interior([f64; 2]),
    /// On edge `e` (corners `e`, `e + 1 mod 4`) at `t in (0, 1)` from corner `e`.
    Edge(usize, f64),
    /// At corner `c`.
    Corner(usize),
}

/// The closest point: where, the point itself and its squared distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// Where on the facet.
    pub spot: Spot,
    /// The point.
    pub x: [f64; 3],
    /// `|x - p|^2`.
    pub d2: f64,
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub(crate) fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    if n > 0.0 {
        [a[0] / n, a[1] / n, a[2] / n]
    } else {
        a
    }
}

/// The reference coordinates of corner `c`.
pub fn corner_ref(c: usize) -> [f64; 2] {
    [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]][c]
}

/// The point `x(xi, eta)`.
pub fn point(xf: &[[f64; 3]; 4], r: [f64; 2]) -> [f64; 3] {
    let n = q1::shape(r[0], r[1]);
    let mut x = [0.0; 3];
    for (a, xa) in xf.iter().enumerate() {
        for c in 0..3 {
            x[c] += n[a] * xa[c];
        }
    }
    x
}

/// The tangents `(x_xi, x_eta)` at `r`.
pub fn tangents(xf: &[[f64; 3]; 4], r: [f64; 2]) -> ([f64; 3], [f64; 3]) {
    let dn = q1::shape_derivatives(r[0], r[1]);
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    for (k, xa) in xf.iter().enumerate() {
        for c in 0..3 {
            a[c] += dn[k][0] * xa[c];
            b[c] += dn[k][1] * xa[c];
        }
    }
    (a, b)
}

/// The unit normal `x_xi x x_eta / |.|` at `r` (outward for a facet listed in a body's outward
/// orientation).
pub fn normal(xf: &[[f64; 3]; 4], r: [f64; 2]) -> [f64; 3] {
    let (a, b) = tangents(xf, r);
    unit(cross(a, b))
}

/// The reference coordinates of a [`Spot`].
pub fn spot_ref(spot: Spot) -> [f64; 2] {
    match spot {
        Spot::Interior(r) => r,
        Spot::Corner(c) => corner_ref(c),
        Spot::Edge(e, t) => {
            let (a, b) = (corner_ref(e), corner_ref((e + 1) % 4));
            [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
        }
    }
}

/// Newton iterations of the interior search.
const NEWTON_STEPS: usize = 30;

/// The closest point of the facet `xf` to `p`.
pub fn closest(xf: &[[f64; 3]; 4], p: [f64; 3]) -> Closest {
    let mut best: Option<Closest> = None;
    // boundary: the four straight edges
    for e in 0..4 {
        let (a, b) = (xf[e], xf[(e + 1) % 4]);
        let ab = sub(b, a);
        let l2 = dot(ab, ab);
        let t = if l2 > 0.0 { (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
        let x = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
        let r = sub(x, p);
        let d2 = dot(r, r);
        let spot = if t <= 0.0 {
            Spot::Corner(e)
        } else if t >= 1.0 {
            Spot::Corner((e + 1) % 4)
        } else {
            Spot::Edge(e, t)
        };
        if best.is_none_or(|b| d2 < b.d2) {
            best = Some(Closest { spot, x, d2 });
        }
    }
    // interior: Newton from the centre
    let twist = {
        let mut t = [0.0; 3];
        for c in 0..3 {
            t[c] = 0.25 * (xf[0][c] - xf[1][c] + xf[2][c] - xf[3][c]);
        }
        t
    };
    let mut r = [0.0, 0.0];
    for _ in 0..NEWTON_STEPS {
        let x = point(xf, r);
        let res = sub(x, p);
        let (a, b) = tangents(xf, r);
        let g = [dot(res, a), dot(res, b)];
        let h = [[dot(a, a), dot(a, b) + dot(res, twist)], [0.0, dot(b, b)]];
        let det = h[0][0] * h[1][1] - h[0][1] * h[0][1];
        if !(det > 0.0 && h[0][0] > 0.0) {
            break;
        }
        let step = [(h[1][1] * g[0] - h[0][1] * g[1]) / det, (h[0][0] * g[1] - h[0][1] * g[0]) / det];
        r = [r[0] - step[0], r[1] - step[1]];
        if !(r[0].abs() <= 2.0 && r[1].abs() <= 2.0) {
            break;
        }
        if step[0].abs().max(step[1].abs()) <= 1e-14 {
            if r[0].abs() < 1.0 && r[1].abs() < 1.0 {
                let x = point(xf, r);
                let d = sub(x, p);
                let d2 = dot(d, d);
                if best.is_none_or(|b| d2 <= b.d2) {
                    best = Some(Closest { spot: Spot::Interior(r), x, d2 });
                }
            }
            break;
        }
    }
    best.unwrap_or(Closest { spot: Spot::Corner(0), x: xf[0], d2: dot(sub(xf[0], p), sub(xf[0], p)) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    /// A warped facet (corner 2 raised): the interior answer is a stationary point of `f`
    /// (its gradient vanishes), no farther than a brute-force scan of a 401 x 401 grid of the
    /// square (to the grid's resolution, 1e-5 in distance); points beyond an edge and beyond a
    /// corner land on that edge and corner.
    #[test]
    fn closest_points_inside_on_an_edge_and_at_a_corner() {
        let xf = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.1], [2.1, 1.8, 0.5], [0.0, 2.0, 0.0]];
        let p = [1.1, 0.9, 0.7];
        let c = closest(&xf, p);
        let Spot::Interior(r) = c.spot else { panic!("interior expected, got {:?}", c.spot) };
        let (a, b) = tangents(&xf, r);
        let res = sub(c.x, p);
        assert_close!(dot(res, a), 0.0, Tol::abs(1e-12));
        assert_close!(dot(res, b), 0.0, Tol::abs(1e-12));
        let mut scan = f64::INFINITY;
        for i in 0..=400 {
            for j in 0..=400 {
                let x = point(&xf, [-1.0 + i as f64 / 200.0, -1.0 + j as f64 / 200.0]);
                scan = scan.min(dot(sub(x, p), sub(x, p)).sqrt());
            }
        }
        assert!(c.d2.sqrt() <= scan + 1e-12, "{} vs scan {scan}", c.d2.sqrt());
        assert_close!(c.d2.sqrt(), scan, Tol::abs(1e-4));
        // beyond edge 0 (y < 0), in the middle: on edge 0
        let c = closest(&xf, [1.0, -0.5, 0.0]);
        assert!(matches!(c.spot, Spot::Edge(0, t) if t > 0.0 && t < 1.0), "{:?}", c.spot);
        // beyond corner 0
        let c = closest(&xf, [-0.5, -0.5, 0.2]);
        assert_eq!(c.spot, Spot::Corner(0));
        assert_close!(c.d2, 0.25 + 0.25 + 0.04, Tol::rel(1e-15));
    }

    /// The normal of a facet listed counter-clockwise seen from +z points to +z.
    #[test]
    fn the_normal_follows_the_corner_order() {
        let xf = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let n = normal(&xf, [0.3, -0.2]);
        assert_close!(n[2], 1.0, Tol::abs(1e-15));
    }
}
