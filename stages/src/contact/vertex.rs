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

use super::pairing::{vertex_pair, MasterIndex, Pair, PairKind};

/// Re-pairings after which any change between pairings sharing a vertex counts as a flip.
pub const STALL_REPAIRINGS: usize = 12;

/// Per-slave pairing history and ties.
#[derive(Debug, Clone)]
pub struct VertexTies {
    enabled: bool,
    tie: Vec<Option<usize>>,
    last: Vec<PairKind>,
    before_last: Vec<PairKind>,
}

impl VertexTies {
    /// No history, no ties, for `n` slaves.
    pub fn new(n: usize) -> Self {
        Self { enabled: true, tie: vec![None; n], last: vec![PairKind::None; n], before_last: vec![PairKind::None; n] }
    }

    /// Forget every tie and all history, for `n` slaves (keeps the capacity and `enabled`).
    pub fn reset(&mut self, n: usize) {
        for v in [&mut self.last, &mut self.before_last] {
            v.clear();
            v.resize(n, PairKind::None);
        }
        self.tie.clear();
        self.tie.resize(n, None);
    }

    /// A tracker that never ties (plain closest-point pairing).
    pub fn disabled(n: usize) -> Self {
        Self { enabled: false, ..Self::new(n) }
    }

    /// Record the natural pairing `nat` of slave `s` at re-pairing number `repairing` and return
    /// the pairing to use (`nat` or [`PairKind::Tied`]).
    pub fn resolve(&mut self, s: usize, nat: PairKind, repairing: usize) -> PairKind {
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
        self.tie.iter().filter(|t| t.is_some()).count()
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
