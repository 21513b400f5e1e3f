//! Node-to-segment closest-point projection (paper eq. 2) onto the master polyline, in the
//! deformed configuration.
//!
//! The master surface is a polyline `x_0, x_1, ..., x_m` ordered counter-clockwise around the
//! master body (body on the left), so segment `k = [x_k, x_{k+1}]` has the outward unit normal
//! `n_k = (t_y, -t_x) / |t|`, `t = x_{k+1} - x_k`. For a slave point `x_s` the closest point
//! `x_bar` of the polyline is either
//!
//! - on a segment: `xi = (x_s - x_k).t / |t|^2 in [0, 1]`, `x_bar = x_k + xi t`, normal `n_k`;
//! - at an interior vertex `v` (the "blind spot" of a convex corner, where neither adjacent
//!   segment has an orthogonal projection): `x_bar = x_v`, normal the normalised average
//!   `(n_{v-1} + n_v) / |n_{v-1} + n_v|`;
//! - at an end vertex of the polyline: the slave has no master segment under it and is left
//!   unpaired (inactive, zero pressure).
//!
//! The signed gap is `g = (x_s - x_bar) . n` (`> 0` separated, `< 0` penetrating). Ties in
//! distance go to the segment (a foot point exactly at a vertex pairs with the lower segment).

/// The discrete part of a pairing (what must stop changing for the active-set loop to end).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairKind {
    /// No master segment under the slave.
    None,
    /// Orthogonal projection onto segment `k` (`[x_k, x_{k+1}]`).
    Segment(usize),
    /// Closest point is the interior vertex `v` (blind spot of a convex corner).
    Vertex(usize),
    /// Tied to vertex `v` with the averaged normal because the pairing kept flipping between
    /// the segments around `v` (see [`super::vertex`]).
    Tied(usize),
}

impl PairKind {
    /// True when this pairing constrains the slave.
    pub fn is_paired(self) -> bool {
        !matches!(self, PairKind::None)
    }

    /// The master vertex shared by two different pairings around one vertex, if any:
    /// segments `k`/`k+1` share `k+1`; a segment and one of its end vertices share that vertex.
    pub fn shared_vertex(self, other: PairKind) -> Option<usize> {
        use PairKind::{Segment as S, Vertex as V};
        match (self, other) {
            (S(a), S(b)) if b == a + 1 => Some(b),
            (S(a), S(b)) if a == b + 1 => Some(a),
            (S(a), V(v)) | (V(v), S(a)) if v == a || v == a + 1 => Some(v),
            _ => None,
        }
    }

    /// True when this (natural) pairing is one of those around vertex `v`.
    pub fn touches_vertex(self, v: usize) -> bool {
        match self {
            PairKind::Segment(k) => k == v || k + 1 == v,
            PairKind::Vertex(w) | PairKind::Tied(w) => w == v,
            PairKind::None => false,
        }
    }
}

/// A full pairing of one slave: discrete kind plus the frozen geometry of the linearised gap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    /// Discrete pairing.
    pub kind: PairKind,
    /// Local coordinate on the segment (`0` for vertex pairings).
    pub xi: f64,
    /// Outward unit normal of the master surface at `x_bar`.
    pub normal: [f64; 2],
    /// Signed gap `(x_s - x_bar) . n` in the configuration it was computed in.
    pub gap: f64,
}

impl Pair {
    /// The unpaired state.
    pub const NONE: Pair = Pair { kind: PairKind::None, xi: 0.0, normal: [0.0, 0.0], gap: f64::INFINITY };
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// Outward unit normal of segment `k` of the polyline `m`.
pub fn segment_normal(m: &[[f64; 2]], k: usize) -> [f64; 2] {
    let t = sub(m[k + 1], m[k]);
    let l = dot(t, t).sqrt();
    [t[1] / l, -t[0] / l]
}

/// Averaged unit normal at interior vertex `v`.
pub fn vertex_normal(m: &[[f64; 2]], v: usize) -> [f64; 2] {
    assert!(v >= 1 && v + 1 < m.len(), "vertex normal needs an interior vertex, got {v}");
    let (a, b) = (segment_normal(m, v - 1), segment_normal(m, v));
    let s = [a[0] + b[0], a[1] + b[1]];
    let l = dot(s, s).sqrt();
    [s[0] / l, s[1] / l]
}

/// Pair with vertex `v` using the averaged normal (also used for ties).
pub fn vertex_pair(xs: [f64; 2], m: &[[f64; 2]], v: usize, kind: PairKind) -> Pair {
    let n = vertex_normal(m, v);
    Pair { kind, xi: 0.0, normal: n, gap: dot(sub(xs, m[v]), n) }
}

/// Closest-point projection of `xs` onto the polyline `m` (at least two points), see the
/// module docs. Returns [`Pair::NONE`] when the closest point is an end of the polyline.
pub fn closest_point(xs: [f64; 2], m: &[[f64; 2]]) -> Pair {
    assert!(m.len() >= 2, "a master polyline needs at least one segment");
    let mut best_d2 = f64::INFINITY;
    let mut best = Pair::NONE;
    for k in 0..m.len() - 1 {
        let t = sub(m[k + 1], m[k]);
        let xi = dot(sub(xs, m[k]), t) / dot(t, t);
        if (0.0..=1.0).contains(&xi) {
            let foot = [m[k][0] + xi * t[0], m[k][1] + xi * t[1]];
            let r = sub(xs, foot);
            let d2 = dot(r, r);
            if d2 < best_d2 {
                best_d2 = d2;
                let n = segment_normal(m, k);
                best = Pair { kind: PairKind::Segment(k), xi, normal: n, gap: dot(r, n) };
            }
        }
    }
    // Vertices win only when strictly closer (blind spots); end vertices mean "nothing under".
    let last = m.len() - 1;
    for (v, &xv) in m.iter().enumerate() {
        let r = sub(xs, xv);
        let d2 = dot(r, r);
        if d2 < best_d2 {
            best_d2 = d2;
            best = if v == 0 || v == last { Pair::NONE } else { vertex_pair(xs, m, v, PairKind::Vertex(v)) };
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::Tol;
    use crate::assert_close;

    /// Convex "roof" master, listed counter-clockwise around a body below it (right to left
    /// along its top), so outward normals point up:
    ///
    /// ```text
    ///            * (-0.4, 0.3)   * (0.1, 0.3): blind spot above the corner x1
    ///   x2 ------------------ x1
    ///  (-1,0)               (0,0) \     * (-0.05,-0.3) penetrating: projects on both
    ///                              \ x0 (1,-1)
    /// ```
    #[test]
    fn segment_vertex_and_end_pairings() {
        let m = [[1.0, -1.0], [0.0, 0.0], [-1.0, 0.0]];
        let p = closest_point([-0.4, 0.3], &m);
        assert_eq!(p.kind, PairKind::Segment(1));
        // small binary fractions, exact up to one rounding: 1e-15
        assert_close!(p.xi, 0.4, Tol::abs(1e-15));
        assert_close!(p.gap, 0.3, Tol::abs(1e-15));
        assert_close!(p.normal[1], 1.0, Tol::abs(1e-15));
        // blind spot of the convex corner: vertex pairing with the averaged normal
        let p = closest_point([0.1, 0.3], &m);
        assert_eq!(p.kind, PairKind::Vertex(1));
        let n = vertex_normal(&m, 1);
        assert_close!(n[0] * n[0] + n[1] * n[1], 1.0, Tol::abs(1e-15));
        // bisector of (0, 1) and (1, 1)/sqrt(2): angle 22.5 deg from vertical
        assert_close!(n[0].atan2(n[1]), std::f64::consts::PI / 8.0, Tol::abs(1e-15));
        assert!(p.gap > 0.0);
        // penetrating point below the corner projects onto both segments; the closer wins
        let p = closest_point([-0.05, -0.3], &m);
        assert_eq!(p.kind, PairKind::Segment(0));
        assert!(p.gap < 0.0);
        // beyond the left end: nothing under it
        assert_eq!(closest_point([-1.5, 0.2], &m).kind, PairKind::None);
    }

    #[test]
    fn shared_vertices() {
        use PairKind::*;
        assert_eq!(Segment(3).shared_vertex(Segment(4)), Some(4));
        assert_eq!(Segment(4).shared_vertex(Segment(3)), Some(4));
        assert_eq!(Segment(3).shared_vertex(Vertex(4)), Some(4));
        assert_eq!(Vertex(3).shared_vertex(Segment(3)), Some(3));
        assert_eq!(Segment(3).shared_vertex(Segment(5)), Option::None);
        assert_eq!(Segment(3).shared_vertex(None), Option::None);
        assert!(Segment(3).touches_vertex(4) && Segment(4).touches_vertex(4));
        assert!(!Segment(5).touches_vertex(4));
    }
}
