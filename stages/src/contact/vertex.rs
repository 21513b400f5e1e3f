//! Vertex-flip detection and ties (SCENES.md → ironing, last paragraph).
//!
//! Closest-point projection is not unique at a vertex of the master polyline: a slave near a
//! vertex `v` can alternate between the two segments around `v` (or between a segment and the
//! vertex's blind spot) from one re-pairing to the next, so the pairing never settles. When a
//! slave's natural pairing returns to the one it had two re-pairings ago, differing from the last
//! one, and the two share a vertex `v` — or, after [`STALL_REPAIRINGS`] re-pairings, whenever it
//! changes between two pairings sharing a vertex — the slave is tied to `v`: `x_bar = x_v`,
//! normal the normalised average of the normals of the two segments around `v`, gap
//! `(x_s - x_v) . n`. The tie persists as long as the natural pairing stays around `v` and is
//! released as soon as it moves elsewhere. The tied constraint is an ordinary node-to-node
//! constraint, so the loop then converges to a KKT point of the tied problem.
//!
//! Flip ties depend on the iteration history. The state a solve returns does not: it is fixed
//! by the **vertex-zone rule** ([`zone_vertex`], applied by the solver's outer rounds, see
//! `super::solve`): a slave is *in the zone* of interior vertex `v` when its deformed position
//! is within `VERTEX_ZONE h_v` of `x_v`, `h_v` the shorter deformed segment at `v`; the
//! returned state is a KKT point, solved from the cold start, in which the slaves with pressure
//! that were in a zone (or that a solve had to flip-tie) are [`PairKind::Tied`] to their
//! vertex; the exact sequence of solves is in `super::solve`. Such slaves are *forced*
//! ([`VertexTies::force`]): tied from the first re-pairing and never released.

use super::pairing::{vertex_pair, MasterIndex, Pair, PairKind};

/// Radius of a vertex's zone, relative to the shorter segment at the vertex: 1 %, five times
/// the 0.2 % within which an independent implementation and crom settled ironing-coarse slaves
/// on different sides of a sole vertex (issue 9), so that both of those states put the slave in
/// the same zone.
pub const VERTEX_ZONE: f64 = 0.01;

/// The interior vertex `v` whose zone holds the slave at `xs`, given its natural closest-point
/// pairing `nat` on the polyline `xm` (the zone's vertex is an end of the closest segment, or
/// the closest vertex): `|xs - x_v| <= zone min(|x_v - x_{v-1}|, |x_{v+1} - x_v|)`, with `zone`
/// [`VERTEX_ZONE`] for the rule.
pub fn zone_vertex(xs: [f64; 2], xm: &[[f64; 2]], nat: PairKind, zone: f64) -> Option<usize> {
    let last = xm.len() - 1;
    let candidates = match nat {
        PairKind::None => [None, None],
        PairKind::Segment(k) => [Some(k), Some(k + 1)],
        PairKind::Vertex(v) | PairKind::Tied(v) => [Some(v), None],
    };
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    candidates.into_iter().flatten().filter(|&v| v >= 1 && v < last).find(|&v| {
        let h = dist(xm[v], xm[v - 1]).min(dist(xm[v + 1], xm[v]));
        dist(xs, xm[v]) <= zone * h
    })
}

/// Re-pairings after which any change between pairings sharing a vertex counts as a flip.
pub const STALL_REPAIRINGS: usize = 12;

/// Per-slave pairing history and ties.
#[derive(Debug, Clone)]
pub struct VertexTies {
    enabled: bool,
    /// Ties imposed for the whole solve (the vertex-zone rule).
    forced: Vec<Option<usize>>,
    tie: Vec<Option<usize>>,
    last: Vec<PairKind>,
    before_last: Vec<PairKind>,
}

impl VertexTies {
    /// No history, no ties, for `n` slaves.
    pub fn new(n: usize) -> Self {
        Self {
            enabled: true,
            forced: vec![None; n],
            tie: vec![None; n],
            last: vec![PairKind::None; n],
            before_last: vec![PairKind::None; n],
        }
    }

    /// Forget all history and flip ties and tie slave `s` to `forced[s]` (when `Some`) for the
    /// whole solve, whatever its natural pairing (enabled or not).
    pub fn force(&mut self, forced: &[Option<usize>]) {
        self.reset(forced.len());
        self.forced.clear();
        self.forced.extend_from_slice(forced);
    }

    /// The vertex slave `s` is tied to, forced or by a flip.
    pub fn tied(&self, s: usize) -> Option<usize> {
        self.forced[s].or(self.tie[s])
    }

    /// The vertex slave `s` was forced to.
    pub fn forced(&self, s: usize) -> Option<usize> {
        self.forced[s]
    }

    /// Forget every tie and all history, for `n` slaves (keeps the capacity and `enabled`).
    pub fn reset(&mut self, n: usize) {
        for v in [&mut self.last, &mut self.before_last] {
            v.clear();
            v.resize(n, PairKind::None);
        }
        for v in [&mut self.tie, &mut self.forced] {
            v.clear();
            v.resize(n, None);
        }
    }

    /// A tracker that never ties (plain closest-point pairing).
    pub fn disabled(n: usize) -> Self {
        Self { enabled: false, ..Self::new(n) }
    }

    /// Record the natural pairing `nat` of slave `s` at re-pairing number `repairing` and return
    /// the pairing to use (`nat` or [`PairKind::Tied`]).
    pub fn resolve(&mut self, s: usize, nat: PairKind, repairing: usize) -> PairKind {
        if let Some(v) = self.forced[s] {
            return PairKind::Tied(v);
        }
        if !self.enabled {
            return nat;
        }
        let (h1, h2) = (self.last[s], self.before_last[s]);
        self.before_last[s] = h1;
        self.last[s] = nat;
        if let Some(v) = self.tie[s] {
            if nat.touches_vertex(v) {
                return PairKind::Tied(v);
            }
            self.tie[s] = None;
            return nat;
        }
        let flipped = nat != h1 && (nat == h2 || repairing >= STALL_REPAIRINGS);
        if flipped {
            if let Some(v) = nat.shared_vertex(h1) {
                self.tie[s] = Some(v);
                return PairKind::Tied(v);
            }
        }
        nat
    }

    /// The pairing [`Self::resolve`] would keep for an existing tie, without recording
    /// anything: `Tied(v)` if slave `s` is tied to `v` and `nat` is around `v`, else `nat`.
    pub fn peek(&self, s: usize, nat: PairKind) -> PairKind {
        if let Some(v) = self.forced[s] {
            return PairKind::Tied(v);
        }
        match self.tie[s] {
            Some(v) if self.enabled && nat.touches_vertex(v) => PairKind::Tied(v),
            _ => nat,
        }
    }

    /// The pairing of slave `s` at `xs`: the closest point on the master polyline `xm` (through
    /// its `index`), replaced by a tie to vertex `v` (averaged normal) when [`Self::resolve`]
    /// says so; the natural pairing is recorded as re-pairing number `repairing`.
    pub fn pair(&mut self, s: usize, xs: [f64; 2], xm: &[[f64; 2]], index: &MasterIndex, repairing: usize) -> Pair {
        let nat = index.closest_point(xs, xm);
        match self.resolve(s, nat.kind, repairing) {
            PairKind::Tied(v) => vertex_pair(xs, xm, v, PairKind::Tied(v)),
            _ => nat,
        }
    }

    /// [`Self::pair`] with the radius of [`MasterIndex::closest_point_with_radius`] for an
    /// unpaired result (0 otherwise, and 0 for a tie).
    pub fn pair_with_radius(
        &mut self,
        s: usize,
        xs: [f64; 2],
        xm: &[[f64; 2]],
        index: &MasterIndex,
        repairing: usize,
    ) -> (Pair, f64) {
        let (nat, r) = index.closest_point_with_radius(xs, xm);
        match self.resolve(s, nat.kind, repairing) {
            PairKind::Tied(v) => (vertex_pair(xs, xm, v, PairKind::Tied(v)), 0.0),
            _ => (nat, r),
        }
    }

    /// [`Self::pair`] for a slave whose natural pair `nat` is already known (proven unchanged
    /// by a radius of [`MasterIndex::closest_point_with_radius`]): the same resolution and
    /// history update, no search.
    pub fn pair_known(&mut self, s: usize, nat: Pair, xs: [f64; 2], xm: &[[f64; 2]], repairing: usize) -> Pair {
        match self.resolve(s, nat.kind, repairing) {
            PairKind::Tied(v) => vertex_pair(xs, xm, v, PairKind::Tied(v)),
            _ => nat,
        }
    }

    /// [`Self::pair_peek`] for a slave whose natural pair `nat` is already known (see
    /// [`Self::pair_known`]): no search, no history update.
    pub fn peek_known(&self, s: usize, nat: Pair, xs: [f64; 2], xm: &[[f64; 2]]) -> Pair {
        match self.peek(s, nat.kind) {
            PairKind::Tied(v) => vertex_pair(xs, xm, v, PairKind::Tied(v)),
            _ => nat,
        }
    }

    /// [`Self::pair`] without recording anything (existing ties only, [`Self::peek`]).
    pub fn pair_peek(&self, s: usize, xs: [f64; 2], xm: &[[f64; 2]], index: &MasterIndex) -> Pair {
        let nat = index.closest_point(xs, xm);
        match self.peek(s, nat.kind) {
            PairKind::Tied(v) => vertex_pair(xs, xm, v, PairKind::Tied(v)),
            _ => nat,
        }
    }

    /// Number of slaves currently tied.
    pub fn count(&self) -> usize {
        (0..self.tie.len()).filter(|&s| self.tied(s).is_some()).count()
    }

    /// The vertex-zone rule's tie for slave `s` at `xs` on the polyline `xm` (with its
    /// `index`): the vertex whose zone holds the slave, from its natural closest point, else
    /// the vertex a flip tied it to in this solve (a forced tie is not a flip). The solver and
    /// the online solve both ask this of every slave with pressure.
    pub fn rule_tie(&self, s: usize, xs: [f64; 2], xm: &[[f64; 2]], index: &MasterIndex) -> Option<usize> {
        let nat = index.closest_point(xs, xm);
        zone_vertex(xs, xm, nat.kind, VERTEX_ZONE).or(if self.forced[s].is_none() { self.tie[s] } else { None })
    }
}

impl Default for VertexTies {
    fn default() -> Self {
        Self::new(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use PairKind::{Segment, Tied, Vertex};

    /// The zone is a disc of radius `VERTEX_ZONE` times the shorter adjacent segment around an
    /// interior vertex (here `h = 1`, the shorter of 1 and sqrt(1.01)): points at distance
    /// 0.00707 and 0.0103 from `x_1` fall inside and outside; end vertices have no zone.
    #[test]
    fn zones_are_discs_around_interior_vertices() {
        let m = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.1]];
        assert_eq!(zone_vertex([1.005, -0.005], &m, Segment(1), VERTEX_ZONE), Some(1));
        assert_eq!(zone_vertex([0.995, -0.005], &m, Segment(0), VERTEX_ZONE), Some(1));
        assert_eq!(zone_vertex([1.009, -0.005], &m, Segment(1), VERTEX_ZONE), None);
        assert_eq!(zone_vertex([1.009, -0.005], &m, Segment(1), 2.0 * VERTEX_ZONE), Some(1));
        assert_eq!(zone_vertex([1.0, 0.001], &m, Vertex(1), VERTEX_ZONE), Some(1));
        assert_eq!(zone_vertex([0.001, -0.001], &m, Segment(0), VERTEX_ZONE), None);
        assert_eq!(zone_vertex([1.0, 0.0], &m, PairKind::None, VERTEX_ZONE), None);
    }

    /// Forced ties hold whatever the natural pairing, and `force` clears the history.
    #[test]
    fn forced_ties_hold() {
        let mut t = VertexTies::new(2);
        t.force(&[Some(3), None]);
        assert_eq!(t.resolve(0, Segment(9), 0), Tied(3));
        assert_eq!(t.resolve(0, PairKind::None, 1), Tied(3));
        assert_eq!(t.peek(0, Segment(1)), Tied(3));
        assert_eq!((t.tied(0), t.forced(0), t.tied(1), t.count()), (Some(3), Some(3), None, 1));
    }

    #[test]
    fn period_two_flip_ties_and_release() {
        let mut t = VertexTies::new(2);
        assert_eq!(t.resolve(0, Segment(4), 0), Segment(4));
        assert_eq!(t.resolve(0, Segment(5), 1), Segment(5));
        // back to segment 4: flip around vertex 5 -> tie
        assert_eq!(t.resolve(0, Segment(4), 2), Tied(5));
        assert_eq!(t.count(), 1);
        // persists while the natural pairing stays around vertex 5
        assert_eq!(t.resolve(0, Vertex(5), 3), Tied(5));
        assert_eq!(t.resolve(0, Segment(5), 4), Tied(5));
        // released when it moves away
        assert_eq!(t.resolve(0, Segment(7), 5), Segment(7));
        assert_eq!(t.count(), 0);
        // monotone sliding is not a flip
        assert_eq!(t.resolve(1, Segment(1), 0), Segment(1));
        assert_eq!(t.resolve(1, Segment(2), 1), Segment(2));
        assert_eq!(t.resolve(1, Segment(3), 2), Segment(3));
        assert_eq!(t.count(), 0);
    }
}
