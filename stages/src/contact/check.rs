//! The geometric check of a converged contact state, computed from the recovered
//! displacement alone — not from the pairing the solver used — so that it tests the solver's
//! bookkeeping instead of repeating it.
//!
//! With `x_s` the deformed slave positions and `x_0 .. x_m` the deformed master polyline:
//!
//! - **signed distance** `d_s` of every slave that has the polyline under it (a closest point
//!   that is not an end vertex): `(x_s - x_bar) . n_k` for a foot on segment `k`, and
//!   `sign((x_s - x_v) . n_v) |x_s - x_v|` for a blind-spot vertex `v` (averaged normal `n_v`).
//!   Reported: `min_gap = min_s d_s` (`>= 0` up to the solver's tolerance: no penetration) and
//!   `active_gap = max |d_s|` over slaves with pressure `> 0` (`0` up to tolerance: a pressed node
//!   touches the master);
//! - **normal cone**: the contact force on an active slave is `F_s = (K u)_s` at its two dofs
//!   (no other load acts on a slave node in these scenes; slaves with a Dirichlet dof are
//!   skipped). A frictionless force must lie in the normal cone of the master feature the slave
//!   touches: the ray of `n_k` for a foot inside segment `k`; the cone spanned by `n_{v-1}` and
//!   `n_v` when the slave is within `CHECK_ZONE = 2 VERTEX_ZONE` of interior vertex `v`
//!   ([`super::vertex::zone_vertex`]): twice the rule's zone, because a slave that the rule
//!   tied can drift out of the zone under the tie's own averaged normal (measured: to 1.03 % on
//!   ironing-fine), and is still a vertex contact.
//!   Reported: `cone_angle`, the largest angle (radians) by which an `F_s` lies outside its cone.
//!
//! Tolerances are the caller's (the solver's are stated where the checks are tested).

use super::factor::FactoredModel;
use super::pairing::{segment_normal, vertex_normal, MasterIndex, PairKind};
use super::vertex::{zone_vertex, VERTEX_ZONE};

/// Radius (relative to the shorter segment) within which the check counts a contact as a vertex
/// contact.
pub const CHECK_ZONE: f64 = 2.0 * VERTEX_ZONE;

/// Worst values of the geometric check of one converged state (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeometryCheck {
    /// Smallest signed distance of a slave to the deformed master polyline (negative:
    /// penetration); `+inf` when no slave has the master under it.
    pub min_gap: f64,
    /// Largest `|signed distance|` of a slave with pressure `> 0`; 0 without contact.
    pub active_gap: f64,
    /// Largest angle (rad) by which an active slave's contact force lies outside the normal cone
    /// of the feature it touches; 0 without contact.
    pub cone_angle: f64,
}

fn angle(a: [f64; 2]) -> f64 {
    a[1].atan2(a[0])
}

/// Difference of two angles wrapped into `(-pi, pi]`.
fn wrap(d: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let r = d.rem_euclid(TAU);
    if r > PI {
        r - TAU
    } else {
        r
    }
}

/// Angle by which direction `f` lies outside the cone spanned by unit vectors `a` and `b`
/// (the smaller arc between them; `a == b` gives a ray).
pub fn outside_cone(f: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (pf, pa) = (angle(f), angle(a));
    let width = wrap(angle(b) - pa);
    let (lo, w) = if width >= 0.0 { (pa, width) } else { (pa + width, -width) };
    let t = wrap(pf - lo);
    if (0.0..=w).contains(&t) {
        0.0
    } else {
        t.abs().min(wrap(pf - (lo + w)).abs())
    }
}

impl FactoredModel {
    /// The geometric check of the state `(u, pressure)` (full displacement, one pressure per
    /// slave), see the module docs.
    pub fn check_geometry(&self, u: &[f64], pressure: &[f64]) -> GeometryCheck {
        self.check_geometry_with(u, &self.model.k.matvec(u), pressure)
    }

    /// [`Self::check_geometry`] with `ku = K u` already computed (the solver has it from its
    /// KKT residual).
    pub(crate) fn check_geometry_with(&self, u: &[f64], ku: &[f64], pressure: &[f64]) -> GeometryCheck {
        let m = &self.model;
        let pos = |n: usize| [m.mesh.nodes[n][0] + u[2 * n], m.mesh.nodes[n][1] + u[2 * n + 1]];
        let xm: Vec<[f64; 2]> = m.masters.iter().map(|&n| pos(n)).collect();
        let mut index = MasterIndex::default();
        index.build(&xm);
        let mut out = GeometryCheck { min_gap: f64::INFINITY, active_gap: 0.0, cone_angle: 0.0 };
        for (s, &sn) in m.slaves.iter().enumerate() {
            if self.slave_fixed[s] {
                continue;
            }
            let xs = pos(sn);
            let p = index.closest_point(xs, &xm);
            let d = match p.kind {
                PairKind::None => continue,
                PairKind::Segment(_) | PairKind::End(_) => p.gap,
                PairKind::Vertex(v) | PairKind::Tied(v) => {
                    let r = [xs[0] - xm[v][0], xs[1] - xm[v][1]];
                    (r[0] * r[0] + r[1] * r[1]).sqrt().copysign(p.gap)
                }
            };
            out.min_gap = out.min_gap.min(d);
            if pressure[s] <= 0.0 {
                continue;
            }
            out.active_gap = out.active_gap.max(d.abs());
            let both_free = self.cfree[2 * s].is_some() && self.cfree[2 * s + 1].is_some();
            if !both_free {
                continue;
            }
            let f = [ku[2 * sn], ku[2 * sn + 1]];
            let (a, b) = match (zone_vertex(xs, &xm, p.kind, CHECK_ZONE), p.kind) {
                (Some(v), _) => (segment_normal(&xm, v - 1), segment_normal(&xm, v)),
                (None, PairKind::Segment(k)) => (segment_normal(&xm, k), segment_normal(&xm, k)),
                (None, PairKind::Vertex(v) | PairKind::Tied(v)) => (vertex_normal(&xm, v), vertex_normal(&xm, v)),
                (None, PairKind::None | PairKind::End(_)) => {
                    unreachable!("unpaired slaves were skipped; a closest point is never an end tie")
                }
            };
            out.cone_angle = out.cone_angle.max(outside_cone(f, a, b));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use std::f64::consts::PI;

    /// Angles outside a cone, from plane geometry: inside gives 0, outside the distance to the
    /// nearer edge, a ray the angle to it; exact up to the rounding of `atan2` (1e-15 rad).
    #[test]
    fn angles_outside_a_cone() {
        let dir = |deg: f64| [(deg * PI / 180.0).cos(), (deg * PI / 180.0).sin()];
        let rad = |deg: f64| deg * PI / 180.0;
        let (a, b) = (dir(80.0), dir(100.0));
        assert_close!(outside_cone(dir(90.0), a, b), 0.0, Tol::abs(0.0));
        assert_close!(outside_cone(dir(90.0), b, a), 0.0, Tol::abs(0.0));
        assert_close!(outside_cone(dir(70.0), a, b), rad(10.0), Tol::abs(1e-15));
        assert_close!(outside_cone(dir(130.0), b, a), rad(30.0), Tol::abs(1e-15));
        assert_close!(outside_cone(dir(-90.0), a, b), rad(170.0), Tol::abs(1e-14));
        // across the branch cut of atan2
        let (c, d) = (dir(170.0), dir(-170.0));
        assert_close!(outside_cone(dir(180.0), c, d), 0.0, Tol::abs(0.0));
        assert_close!(outside_cone(dir(150.0), c, d), rad(20.0), Tol::abs(1e-14));
        // a ray
        assert_close!(outside_cone(dir(93.0), dir(90.0), dir(90.0)), rad(3.0), Tol::abs(1e-15));
    }
}
