//! Vertex-flip detection and ties (docs/scenes.md#contact-formulation, the vertices of the master
//! polyline).
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
//!
//! **End ties** (enabled by [`VertexTies::set_end_ties`]; the reduced solve only). A slave
//! whose natural pairing flips in the same way between the segment at an end of the polyline
//! and no pairing (its closest point the end vertex) is tied to that end:
//! [`PairKind::End`], gap `(x_s - x_e) . n_k`, `n_k` the end segment's normal, i.e. the end
//! segment's line extended past its end; it equals the segment's gap wherever the projection
//! is valid, so the gap row is continuous across the end. The tie persists while the natural
//! pairing stays that segment or none and is released otherwise. The full-order solver does
//! not need it: a slave whose pairing flips there has an open gap, carries no pressure, and
//! its pairing does not move the solution. In a reduced problem it does: a slave's pressure
//! is not its own unknown but a dual basis vector's value, so a slave with an open gap can
//! carry pressure, and its row enters the reduced constraint only while it is paired; the
//! reduced constraint then jumps with the pairing, and the re-pairing can cycle between two
//! states with no fixed point (measured on ironing-fine, docs/design-notes.md#end-ties).

use super::pairing::{end_pair, vertex_pair, Certificate, MasterIndex, Pair, PairKind};

/// Radius of a vertex's zone, relative to the shorter segment at the vertex: 1 %, five times
/// the 0.2 % within which an independent implementation and crom settled ironing-coarse slaves
/// on different sides of a sole vertex, so that both of those states put the slave in
/// the same zone.
pub const VERTEX_ZONE: f64 = 0.01;

/// The interior vertex `v` whose zone holds the slave at `xs`, given its natural closest-point
/// pairing `nat` on the polyline `xm` (the zone's vertex is an end of the closest segment, or
/// the closest vertex): `|xs - x_v| <= zone min(|x_v - x_{v-1}|, |x_{v+1} - x_v|)`, with `zone`
/// [`VERTEX_ZONE`] for the rule.
pub fn zone_vertex(xs: [f64; 2], xm: &[[f64; 2]], nat: PairKind, zone: f64) -> Option<usize> {
    let last = xm.len() - 1;
    let candidates = match nat {
        PairKind::None | PairKind::End(_) => [None, None],
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
    /// End ties are enabled (see the module docs).
    ends: bool,
    /// Ties imposed for the whole solve (the vertex-zone rule).
    forced: Vec<Option<usize>>,
    /// Each slave's flip tie: [`PairKind::Tied`] or [`PairKind::End`].
    tie: Vec<Option<PairKind>>,
    last: Vec<PairKind>,
    before_last: Vec<PairKind>,
}

impl VertexTies {
    /// No history, no ties, for `n` slaves.
    pub fn new(n: usize) -> Self {
        Self {
            enabled: true,
            ends: false,
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

    /// Enable or disable end ties (see the module docs); kept by [`Self::reset`].
    pub fn set_end_ties(&mut self, on: bool) {
        self.ends = on;
    }

    /// The vertex slave `s` is tied to, forced or by a flip.
    pub fn tied(&self, s: usize) -> Option<usize> {
        self.forced[s].or(self.flip_vertex(s))
    }

    /// The interior vertex a flip tied slave `s` to (not an end tie).
    fn flip_vertex(&self, s: usize) -> Option<usize> {
        match self.tie[s] {
            Some(PairKind::Tied(v)) => Some(v),
            _ => None,
        }
    }

    /// Whether flip tie `tie` still holds for the natural pairing `nat`: a vertex tie while
    /// `nat` is around its vertex, an end tie while `nat` is the end segment or none.
    fn holds(tie: PairKind, nat: PairKind) -> bool {
        match tie {
            PairKind::Tied(v) => nat.touches_vertex(v),
            PairKind::End(e) => nat == PairKind::None || nat.touches_vertex(e),
            _ => false,
        }
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
        self.forced.clear();
        self.forced.resize(n, None);
        self.tie.clear();
        self.tie.resize(n, None);
    }

    /// A tracker that never ties (plain closest-point pairing).
    pub fn disabled(n: usize) -> Self {
        Self { enabled: false, ..Self::new(n) }
    }

    /// Record the natural pairing `nat` of slave `s` at re-pairing number `repairing` and return
    /// the pairing to use (`nat`, [`PairKind::Tied`] or [`PairKind::End`]); `last` is the index
    /// of the polyline's last vertex.
    pub fn resolve(&mut self, s: usize, nat: PairKind, repairing: usize, last: usize) -> PairKind {
        if let Some(v) = self.forced[s] {
            return PairKind::Tied(v);
        }
        if !self.enabled {
            return nat;
        }
        let (h1, h2) = (self.last[s], self.before_last[s]);
        self.before_last[s] = h1;
        self.last[s] = nat;
        if let Some(tie) = self.tie[s] {
            if Self::holds(tie, nat) {
                return tie;
            }
            self.tie[s] = None;
            return nat;
        }
        let flipped = nat != h1 && (nat == h2 || repairing >= STALL_REPAIRINGS);
        if flipped {
            // an end flip needs `repairing >= 2`: both earlier pairings were recorded (the
            // history starts unpaired, so a slave paired at the first re-pairing and not at
            // the second is no flip)
            let tie = nat
                .shared_vertex(h1)
                .map(PairKind::Tied)
                .or_else(|| nat.end_vertex(h1, last).filter(|_| self.ends && repairing >= 2).map(PairKind::End));
            if let Some(tie) = tie {
                self.tie[s] = Some(tie);
                return tie;
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
            Some(tie) if self.enabled && Self::holds(tie, nat) => tie,
            _ => nat,
        }
    }

    /// The pair of kind `kind` (from [`Self::resolve`] or [`Self::peek`]) for a slave at `xs`
    /// whose natural pair is `nat`.
    fn realize(kind: PairKind, nat: Pair, xs: [f64; 2], xm: &[[f64; 2]]) -> Pair {
        match kind {
            PairKind::Tied(v) => vertex_pair(xs, xm, v, PairKind::Tied(v)),
            PairKind::End(v) => end_pair(xs, xm, v),
            _ => nat,
        }
    }

    /// The pairing of slave `s` at `xs`: the closest point on the master polyline `xm` (through
    /// its `index`), replaced by a tie to vertex `v` (averaged normal) when [`Self::resolve`]
    /// says so; the natural pairing is recorded as re-pairing number `repairing`.
    pub fn pair(&mut self, s: usize, xs: [f64; 2], xm: &[[f64; 2]], index: &MasterIndex, repairing: usize) -> Pair {
        let nat = index.closest_point(xs, xm);
        Self::realize(self.resolve(s, nat.kind, repairing, xm.len() - 1), nat, xs, xm)
    }

    /// [`Self::pair`] with the radius (0 for a tie) and the certificate of the natural pairing
    /// from [`MasterIndex::closest_point_proved`].
    pub fn pair_proved(
        &mut self,
        s: usize,
        xs: [f64; 2],
        xm: &[[f64; 2]],
        index: &MasterIndex,
        repairing: usize,
    ) -> (Pair, f64, Certificate) {
        let (nat, r, cert) = index.closest_point_proved(xs, xm);
        let kind = self.resolve(s, nat.kind, repairing, xm.len() - 1);
        (Self::realize(kind, nat, xs, xm), if kind == nat.kind { r } else { 0.0 }, cert)
    }

    /// [`Self::pair`] for a slave whose natural pair `nat` is already known (proven unchanged
    /// by a radius of [`MasterIndex::closest_point_proved`]): the same resolution and
    /// history update, no search.
    pub fn pair_known(&mut self, s: usize, nat: Pair, xs: [f64; 2], xm: &[[f64; 2]], repairing: usize) -> Pair {
        Self::realize(self.resolve(s, nat.kind, repairing, xm.len() - 1), nat, xs, xm)
    }

    /// [`Self::pair_peek`] for a slave whose natural pair `nat` is already known (see
    /// [`Self::pair_known`]): no search, no history update.
    pub fn peek_known(&self, s: usize, nat: Pair, xs: [f64; 2], xm: &[[f64; 2]]) -> Pair {
        Self::realize(self.peek(s, nat.kind), nat, xs, xm)
    }

    /// [`Self::pair`] without recording anything (existing ties only, [`Self::peek`]).
    pub fn pair_peek(&self, s: usize, xs: [f64; 2], xm: &[[f64; 2]], index: &MasterIndex) -> Pair {
        let nat = index.closest_point(xs, xm);
        Self::realize(self.peek(s, nat.kind), nat, xs, xm)
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
        zone_vertex(xs, xm, nat.kind, VERTEX_ZONE).or(if self.forced[s].is_none() { self.flip_vertex(s) } else { None })
    }

    /// [`Self::rule_tie`] without the search, for a slave not forced whose natural pairing at
    /// `xs` is the last one recorded ([`Self::pair`], [`Self::pair_known`] or
    /// [`Self::pair_proved`] at this `xs`): reads `xm` around that pairing only.
    pub fn rule_tie_recorded(&self, s: usize, xs: [f64; 2], xm: &[[f64; 2]]) -> Option<usize> {
        zone_vertex(xs, xm, self.last[s], VERTEX_ZONE).or(if self.forced[s].is_none() {
            self.flip_vertex(s)
        } else {
            None
        })
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
        assert_eq!(t.resolve(0, Segment(9), 0, 99), Tied(3));
        assert_eq!(t.resolve(0, PairKind::None, 1, 99), Tied(3));
        assert_eq!(t.peek(0, Segment(1)), Tied(3));
        assert_eq!((t.tied(0), t.forced(0), t.tied(1), t.count()), (Some(3), Some(3), None, 1));
    }

    #[test]
    fn period_two_flip_ties_and_release() {
        let mut t = VertexTies::new(2);
        assert_eq!(t.resolve(0, Segment(4), 0, 99), Segment(4));
        assert_eq!(t.resolve(0, Segment(5), 1, 99), Segment(5));
        // back to segment 4: flip around vertex 5 -> tie
        assert_eq!(t.resolve(0, Segment(4), 2, 99), Tied(5));
        assert_eq!(t.count(), 1);
        // persists while the natural pairing stays around vertex 5
        assert_eq!(t.resolve(0, Vertex(5), 3, 99), Tied(5));
        assert_eq!(t.resolve(0, Segment(5), 4, 99), Tied(5));
        // released when it moves away
        assert_eq!(t.resolve(0, Segment(7), 5, 99), Segment(7));
        assert_eq!(t.count(), 0);
        // monotone sliding is not a flip
        assert_eq!(t.resolve(1, Segment(1), 0, 99), Segment(1));
        assert_eq!(t.resolve(1, Segment(2), 1, 99), Segment(2));
        assert_eq!(t.resolve(1, Segment(3), 2, 99), Segment(3));
        assert_eq!(t.count(), 0);
    }

    /// End ties: only when enabled, only for a period-two flip between no pairing and the
    /// segment at an end (here segments 0..=9, ends 0 and 10), persisting while the natural
    /// pairing stays there, released when it moves inside; an end pair is the end segment's
    /// line extended past the end.
    #[test]
    fn end_flips_tie_to_the_end_only_when_enabled() {
        let mut t = VertexTies::new(3);
        for (r, nat) in [Segment(9), PairKind::None, Segment(9), PairKind::None].into_iter().enumerate() {
            assert_eq!(t.resolve(0, nat, r, 10), nat, "disabled: never tied");
        }
        t.set_end_ties(true);
        t.reset(3);
        assert_eq!(t.resolve(0, Segment(9), 0, 10), Segment(9));
        assert_eq!(t.resolve(0, PairKind::None, 1, 10), PairKind::None);
        assert_eq!(t.resolve(0, Segment(9), 2, 10), PairKind::End(10));
        assert_eq!(t.resolve(0, PairKind::None, 3, 10), PairKind::End(10));
        assert_eq!(t.peek(0, Segment(9)), PairKind::End(10));
        assert_eq!(t.resolve(0, Segment(8), 4, 10), Segment(8), "released inside");
        assert_eq!(t.peek(0, PairKind::None), PairKind::None);
        // the first segment's end is vertex 0; an interior segment has no end
        assert_eq!(t.resolve(1, Segment(0), 0, 10), Segment(0));
        assert_eq!(t.resolve(1, PairKind::None, 1, 10), PairKind::None);
        assert_eq!(t.resolve(1, Segment(0), 2, 10), PairKind::End(0));
        assert_eq!(t.resolve(2, Segment(4), 0, 10), Segment(4));
        assert_eq!(t.resolve(2, PairKind::None, 1, 10), PairKind::None);
        assert_eq!(t.resolve(2, Segment(4), 2, 10), Segment(4));
        // geometry: the end segment [(1,0),(2,0)] of a polyline, its line extended past x = 2
        let m = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        let p = crate::contact::pairing::end_pair([2.5, -0.25], &m, 2);
        assert_eq!((p.kind, p.normal, p.gap), (PairKind::End(2), [0.0, -1.0], 0.25));
    }
}
