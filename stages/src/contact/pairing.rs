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
    /// Tied to the end vertex `v` (`0` or the last) with the normal of the segment at that end
    /// because the pairing kept flipping between that segment and no pairing: the end
    /// segment's line, extended past its end (see [`super::vertex`], end ties; only the
    /// reduced solve ties ends).
    End(usize),
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

    /// The end vertex of a flip between no pairing and the segment at an end of a polyline
    /// whose last vertex is `last`: segment `0` has end `0`, segment `last - 1` has end `last`.
    pub fn end_vertex(self, other: PairKind, last: usize) -> Option<usize> {
        match (self, other) {
            (PairKind::None, PairKind::Segment(k)) | (PairKind::Segment(k), PairKind::None) => {
                if k == 0 {
                    Some(0)
                } else if k + 1 == last {
                    Some(last)
                } else {
                    None
                }
            }
            _ => None,
        }
    }

    /// True when this (natural) pairing is one of those around vertex `v`.
    pub fn touches_vertex(self, v: usize) -> bool {
        match self {
            PairKind::Segment(k) => k == v || k + 1 == v,
            PairKind::Vertex(w) | PairKind::Tied(w) | PairKind::End(w) => w == v,
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

/// `a - b`.
pub(crate) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
/// `a . b`.
pub(crate) fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
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

/// Tie to the end vertex `v` of `m` (`0` or the last) with the normal of the segment at that
/// end: the gap to that segment's line, extended past its end.
pub fn end_pair(xs: [f64; 2], m: &[[f64; 2]], v: usize) -> Pair {
    let n = segment_normal(m, if v == 0 { 0 } else { v - 1 });
    Pair { kind: PairKind::End(v), xi: 0.0, normal: n, gap: dot(sub(xs, m[v]), n) }
}

/// [`MasterIndex::closest_point_proved`]'s radius for a slave at `xs` paired with segment
/// `k` (`p`), `l_minus_d` the margin of every other candidate's distance over its own.
fn segment_radius(xs: [f64; 2], m: &[[f64; 2]], k: usize, p: &Pair, l_minus_d: f64) -> f64 {
    let (a, b) = (m[k], m[k + 1]);
    let t = sub(b, a);
    let h = dot(t, t).sqrt();
    let along = p.xi * h;
    let margin = along.min(h - along);
    let (ra, rb) = (sub(xs, a), sub(xs, b));
    let reach = dot(ra, ra).max(dot(rb, rb)).sqrt();
    positive(0.5 * (l_minus_d / 2.0).min(margin / (3.0 + 4.0 * reach / h)).min(h / 4.0))
}

/// [`MasterIndex::closest_point_proved`]'s radius for a slave at `xs` closest to the end
/// vertex `e` (at distance `d`), `l_minus_d` as in [`segment_radius`].
fn end_radius(xs: [f64; 2], m: &[[f64; 2]], e: usize, d: f64, l_minus_d: f64) -> f64 {
    let last = m.len() - 1;
    let (a, b) = if e == 0 { (m[0], m[1]) } else { (m[last], m[last - 1]) };
    let t = sub(b, a);
    let h = dot(t, t).sqrt();
    // distance beyond the normal line through the end vertex (positive outside)
    let g = -dot(sub(xs, a), t) / h;
    positive(0.5 * (l_minus_d / 2.0).min(g / (1.0 + 4.0 * d / h)).min(h / 4.0))
}

/// `r` if finite and positive, else 0.
fn positive(r: f64) -> f64 {
    if r.is_finite() && r > 0.0 {
        r
    } else {
        0.0
    }
}

/// Orthogonal projection of `xs` onto segment `k` of `m`: `(xi, xs - foot)` when
/// `xi in [0, 1]`, else `None` (the one arithmetic of every closest-point search here).
fn project_on_segment(xs: [f64; 2], m: &[[f64; 2]], k: usize) -> Option<(f64, [f64; 2])> {
    let t = sub(m[k + 1], m[k]);
    let xi = dot(sub(xs, m[k]), t) / dot(t, t);
    (0.0..=1.0).contains(&xi).then(|| (xi, sub(xs, [m[k][0] + xi * t[0], m[k][1] + xi * t[1]])))
}

/// Closest-point projection of `xs` onto the polyline `m` (at least two points), see the
/// module docs. Returns [`Pair::NONE`] when the closest point is an end of the polyline.
pub fn closest_point(xs: [f64; 2], m: &[[f64; 2]]) -> Pair {
    assert!(m.len() >= 2, "a master polyline needs at least one segment");
    let mut best_d2 = f64::INFINITY;
    let mut best = Pair::NONE;
    for k in 0..m.len() - 1 {
        if let Some((xi, r)) = project_on_segment(xs, m, k) {
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

/// The feature closest to a slave: what a [`Certificate`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Feature {
    /// No candidate (never certified).
    #[default]
    Nothing,
    /// Segment `k`, with a valid projection.
    Segment(usize),
    /// Interior vertex `v` (blind spot).
    Vertex(usize),
    /// End vertex `e`: the slave is unpaired.
    End(usize),
}

/// What a search proves about the closest point for a while: see
/// [`MasterIndex::closest_point_proved`] and [`MasterIndex::recheck`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Certificate {
    pub feature: Feature,
    /// Motion (the slave's plus the largest master vertex's) below which the feature's
    /// neighbourhood decides the closest point alone.
    pub radius: f64,
}

/// Relative margin of a certificate's radius (to `L`): the distances it compares are rounded
/// by a few units of 1e-16 relative.
const CERTIFICATE_MARGIN: f64 = 1e-12;

/// Candidates a search keeps, nearest first: enough to see past a segment's neighbourhood
/// (three segments and two vertices, each vertex possibly met twice at a chunk boundary) in
/// [`MasterIndex::closest_point_proved`]'s certificate.
const NEAREST: usize = 8;

type Nearest = [(f64, usize); NEAREST];

/// The outcome of [`MasterIndex`]'s search.
struct Found {
    pair: Pair,
    feature: Feature,
    d2: f64,
    near: Nearest,
    skipped: f64,
}

/// Segments per chunk of a [`MasterIndex`].
const CHUNK: usize = 8;

/// Relative margin of the chunk pruning: a chunk is skipped only when the squared distance to
/// its bounding box exceeds the best squared distance so far by more than this (the box bound
/// and a candidate's distance are rounded differently, by ~1e-16 relative).
const PRUNE_MARGIN: f64 = 1e-12;

/// A bounding-volume hierarchy over a master polyline, rebuilt for every configuration: the
/// leaves are chunks of `CHUNK` consecutive segments (with their vertices), the inner nodes
/// the boxes of consecutive chunk ranges (an implicit binary tree; consecutive segments of a
/// polyline are close, so the boxes are tight). [`MasterIndex::closest_point`] returns exactly
/// what [`closest_point`] returns (same arithmetic per candidate, same tie rule: lowest segment
/// among equal distances, a vertex only when strictly closer, lowest vertex among equal ones)
/// but descends nearest-box-first and skips every box that cannot hold a closer candidate, so a
/// query costs `O(log(m / CHUNK) + CHUNK)` for a slave near the polyline or beyond its ends,
/// instead of `O(m)`.
#[derive(Debug, Clone, Default)]
pub struct MasterIndex {
    /// Number of leaves (a power of two, at least the number of chunks).
    leaves: usize,
    /// `[min_x, min_y, max_x, max_y]` of node `i` (1-based heap order; leaf `c` is node
    /// `leaves + c`, covering vertices `c CHUNK ..= (c + 1) CHUNK`); empty boxes are inverted.
    boxes: Vec<[f64; 4]>,
    n_seg: usize,
}

const EMPTY_BOX: [f64; 4] = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];

fn merge(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [a[0].min(b[0]), a[1].min(b[1]), a[2].max(b[2]), a[3].max(b[3])]
}

impl MasterIndex {
    /// Rebuild for the polyline `m` (at least two points).
    pub fn build(&mut self, m: &[[f64; 2]]) {
        assert!(m.len() >= 2, "a master polyline needs at least one segment");
        self.n_seg = m.len() - 1;
        let chunks = self.n_seg.div_ceil(CHUNK);
        self.leaves = chunks.next_power_of_two();
        assert!(self.leaves <= 1 << 31, "a master polyline of {} segments is beyond the search's node ids", self.n_seg);
        self.boxes.clear();
        self.boxes.resize(2 * self.leaves, EMPTY_BOX);
        for c in 0..chunks {
            let hi = ((c + 1) * CHUNK).min(self.n_seg);
            let mut b = EMPTY_BOX;
            for p in &m[c * CHUNK..=hi] {
                b = merge(b, [p[0], p[1], p[0], p[1]]);
            }
            self.boxes[self.leaves + c] = b;
        }
        for i in (1..self.leaves).rev() {
            self.boxes[i] = merge(self.boxes[2 * i], self.boxes[2 * i + 1]);
        }
    }

    fn lower_bound(&self, node: usize, xs: [f64; 2]) -> f64 {
        let b = self.boxes[node];
        if b[0] > b[2] {
            return f64::INFINITY;
        }
        let dx = (b[0] - xs[0]).max(xs[0] - b[2]).max(0.0);
        let dy = (b[1] - xs[1]).max(xs[1] - b[3]).max(0.0);
        dx * dx + dy * dy
    }

    /// [`closest_point`] of `xs` onto `m` (the polyline this index was built for).
    pub fn closest_point(&self, xs: [f64; 2], m: &[[f64; 2]]) -> Pair {
        self.search(xs, m).pair
    }

    /// [`Self::closest_point`] with two proofs that it holds for a while, from one search.
    ///
    /// **A radius.** When the slave is unpaired (closest to an end vertex `e`), a radius
    /// `R > 0` within which the result cannot change: if afterwards the slave moves
    /// by `d_s` and every master vertex by at most `d_m` with `d_s + d_m <= R`, the closest
    /// point is still `e`. With `D` the distance to `e`, `L` a lower bound of the distance to
    /// every other candidate (the second-best candidate evaluated and the bounds of the skipped
    /// boxes), `h` the length of the end segment and `g` the slave's distance beyond the line
    /// through `e` normal to it (`xi < 0` resp. `> 1`):
    ///
    /// - `e` stays closer than any other candidate while `2 (d_s + d_m) < L - D`;
    /// - the end segment's projection stays invalid (which would pair the slave with it) while
    ///   `(d_s + d_m) + 2 d_m D / (h - 2 d_m) < g`, the line turning by at most
    ///   `2 d_m / (h - 2 d_m)` — implied by `(d_s + d_m)(1 + 4 D / h) < g` when `d_m <= h / 4`;
    ///
    /// `R` is half the smallest of `(L - D) / 2`, `g / (1 + 4 D / h)` and `h / 4`.
    ///
    /// A slave paired with a segment `k` (length `h`, ends `a`, `b`) keeps `k` within `R`: with
    /// `D` its distance to `k`, `L` as above, `s = xi h` its foot's distance from `a`, and
    /// `P = max(|x_s - a|, |x_s - b|)`,
    ///
    /// - `k` stays closer than any other candidate while `2 (d_s + d_m) < L - D` (a distance to
    ///   a point or to a segment changes by at most the motion of the slave plus that of the
    ///   segment's ends, and a segment whose projection is invalid is no closer than one of
    ///   its ends, itself a candidate);
    /// - the projection stays valid, `0 <= s' <= h'`: `s` moves by at most
    ///   `(d_s + d_m) + P |t̂' - t̂|` with `|t̂' - t̂| <= 4 d_m / h`, and `h' >= h - 2 d_m`, so
    ///   `(d_s + d_m)(3 + 4 P / h) < min(s, h - s)` suffices;
    ///
    /// `R` is half the smallest of `(L - D) / 2`, `min(s, h - s) / (3 + 4 P / h)` and `h / 4`.
    /// Slaves paired with an interior vertex get `R = 0`.
    ///
    /// **A [`Certificate`]:** with `D` the distance to the closest feature and `L` a lower bound
    /// of the distance to every candidate outside the feature's neighbourhood (the nearest such
    /// candidate evaluated, and the bounds of the skipped boxes), the radius is `(L - D) / 2`
    /// less a rounding margin. The neighbourhood of a segment `k` is segments `k - 1..=k + 1`
    /// and vertices `k`, `k + 1`; of a vertex, itself (its two segments have no projection, or
    /// they would be at least as close). See [`Self::recheck`] for what it proves.
    pub fn closest_point_proved(&self, xs: [f64; 2], m: &[[f64; 2]]) -> (Pair, f64, Certificate) {
        let f = self.search(xs, m);
        (f.pair, Self::radius(&f, xs, m), Self::certificate(&f, m))
    }

    /// The radius of a search (see [`Self::closest_point_proved`]).
    fn radius(f: &Found, xs: [f64; 2], m: &[[f64; 2]]) -> f64 {
        let n_seg = m.len() - 1;
        let best_id = match f.feature {
            Feature::Segment(k) => k,
            Feature::Vertex(v) | Feature::End(v) => n_seg + v,
            Feature::Nothing => usize::MAX,
        };
        let other = if f.near[0].1 == best_id { f.near[1].0 } else { f.near[0].0 };
        let (p, l2) = (f.pair, other.min(f.skipped));
        match f.feature {
            Feature::End(e) => end_radius(xs, m, e, f.d2.sqrt(), l2.sqrt() - f.d2.sqrt()),
            Feature::Segment(k) => segment_radius(xs, m, k, &p, l2.sqrt() - p.gap.abs()),
            _ => 0.0,
        }
    }

    /// The pair with segment `k` itself (what [`Self::closest_point`] returns when `k` is the
    /// closest feature: the same arithmetic), or `None` when the projection onto `k` is
    /// invalid. For a slave known to stay paired with `k` ([`Self::closest_point_proved`]).
    pub fn segment_pair(xs: [f64; 2], m: &[[f64; 2]], k: usize) -> Option<Pair> {
        let (xi, r) = project_on_segment(xs, m, k)?;
        let n = segment_normal(m, k);
        Some(Pair { kind: PairKind::Segment(k), xi, normal: n, gap: dot(r, n) })
    }

    /// The search: the pair, the closest feature and its squared distance, the smallest
    /// candidate distances met, and the bound of the skipped boxes.
    fn search(&self, xs: [f64; 2], m: &[[f64; 2]]) -> Found {
        let n_seg = m.len() - 1;
        assert_eq!(n_seg, self.n_seg, "index built for another polyline");
        // best segment (d2, k) and best vertex (d2, v), each lowest index among ties
        let mut seg: (f64, usize) = (f64::INFINITY, usize::MAX);
        let mut ver: (f64, usize) = (f64::INFINITY, usize::MAX);
        // the smallest candidate distances (squared) with their feature ids, and the smallest
        // bound of a skipped box
        let mut near: Nearest = [(f64::INFINITY, usize::MAX); NEAREST];
        let mut skipped = f64::INFINITY;
        let note = |near: &mut Nearest, d2: f64, id: usize| {
            if d2 < near[NEAREST - 1].0 {
                let mut i = NEAREST - 1;
                while i > 0 && near[i - 1].0 > d2 {
                    near[i] = near[i - 1];
                    i -= 1;
                }
                near[i] = (d2, id);
            }
        };
        let visit = |c: usize, seg: &mut (f64, usize), ver: &mut (f64, usize), near: &mut Nearest| {
            let hi = ((c + 1) * CHUNK).min(n_seg);
            for k in c * CHUNK..hi {
                if let Some((_, r)) = project_on_segment(xs, m, k) {
                    let d2 = dot(r, r);
                    note(near, d2, k);
                    if d2 < seg.0 || (d2 <= seg.0 && k < seg.1) {
                        *seg = (d2, k);
                    }
                }
            }
            for (v, &xv) in m.iter().enumerate().take(hi + 1).skip(c * CHUNK) {
                let r = sub(xs, xv);
                let d2 = dot(r, r);
                note(near, d2, n_seg + v);
                if d2 < ver.0 || (d2 <= ver.0 && v < ver.1) {
                    *ver = (d2, v);
                }
            }
        };
        // nearest-box-first descent with an explicit stack: each level pops one node and pushes
        // two, so it holds at most depth + 1 <= 33 nodes (leaves <= 2^31, see `build`); node
        // ids as u32 keep the array that is zeroed per search small
        let mut stack = [0u32; 34];
        let mut top = 0;
        stack[top] = 1;
        top += 1;
        while top > 0 {
            top -= 1;
            let node = stack[top] as usize;
            let best = seg.0.min(ver.0);
            let lb = self.lower_bound(node, xs);
            if lb > best * (1.0 + PRUNE_MARGIN) {
                skipped = skipped.min(lb);
                continue;
            }
            if node >= self.leaves {
                visit(node - self.leaves, &mut seg, &mut ver, &mut near);
                continue;
            }
            let (a, b) = (2 * node, 2 * node + 1);
            let (near, far) = if self.lower_bound(b, xs) < self.lower_bound(a, xs) { (b, a) } else { (a, b) };
            stack[top] = far as u32;
            stack[top + 1] = near as u32;
            top += 2;
        }
        let last = m.len() - 1;
        let (pair, feature, d2) = if ver.0 < seg.0 {
            let v = ver.1;
            if v == 0 || v == last {
                (Pair::NONE, Feature::End(v), ver.0)
            } else {
                (vertex_pair(xs, m, v, PairKind::Vertex(v)), Feature::Vertex(v), ver.0)
            }
        } else if seg.1 == usize::MAX {
            (Pair::NONE, Feature::Nothing, f64::INFINITY)
        } else {
            let k = seg.1;
            (Self::segment_pair(xs, m, k).expect("the best segment has a projection"), Feature::Segment(k), seg.0)
        };
        Found { pair, feature, d2, near, skipped }
    }

    /// The certificate of a search (see [`Self::closest_point_proved`]).
    fn certificate(f: &Found, m: &[[f64; 2]]) -> Certificate {
        let n_seg = m.len() - 1;
        let excluded = |id: usize| match f.feature {
            Feature::Segment(k) => (id < n_seg && id + 1 >= k && id <= k + 1) || id == n_seg + k || id == n_seg + k + 1,
            Feature::Vertex(v) | Feature::End(v) => id == n_seg + v,
            Feature::Nothing => false,
        };
        let other = f.near.iter().find(|(_, id)| *id != usize::MAX && !excluded(*id)).map_or(f64::INFINITY, |c| c.0);
        let (l, d) = (other.min(f.skipped).sqrt(), f.d2.sqrt());
        let radius = 0.5 * (l - d) - CERTIFICATE_MARGIN * l;
        let radius = if f.feature != Feature::Nothing && radius > 0.0 { radius } else { 0.0 };
        Certificate { feature: f.feature, radius }
    }

    /// The closest point of `xs` on `m` if `cert` (from [`Self::closest_point_proved`] at
    /// an earlier configuration) proves it, else `None` (search again). `moved` bounds the
    /// slave's displacement since the certificate plus the largest displacement of any master
    /// vertex. Every candidate outside the certified feature's neighbourhood was at least `L`
    /// away, so with `moved < (L - D) / 2` it is still farther than `D + moved`, itself at
    /// least the feature's present distance (a distance to a point or to a segment changes by
    /// at most the motion of the point plus that of the segment's ends). The neighbourhood is
    /// evaluated here with the search's own arithmetic:
    ///
    /// - segment `k`: its projection must be valid, its vertices not strictly closer and its
    ///   neighbours `k ± 1` without a projection or strictly farther;
    /// - interior vertex `v`: neither adjacent segment may have a projection;
    /// - end vertex `e` (unpaired): the end segment may not have a projection.
    ///
    /// What it returns is then what [`closest_point`] returns, bit for bit, with a radius of
    /// further motion (from here) within which the pairing kind cannot change, as
    /// [`Self::closest_point_proved`]'s radius: the certificate's slack `radius - moved`, and
    /// for the neighbourhood the same bounds as there with the neighbours' distances in place
    /// of `L` (a segment's distance: to its projection if it has one, else to its nearer end).
    /// A vertex gets 0.
    pub fn recheck(xs: [f64; 2], m: &[[f64; 2]], cert: &Certificate, moved: f64) -> Option<(Pair, f64)> {
        // a NaN motion proves nothing either
        if moved.is_nan() || moved >= cert.radius {
            return None;
        }
        let slack = cert.radius - moved;
        let n_seg = m.len() - 1;
        let has_projection = |k: usize| project_on_segment(xs, m, k).is_some();
        let to_vertex = |v: usize| {
            let r = sub(xs, m[v]);
            dot(r, r)
        };
        match cert.feature {
            Feature::Segment(k) => {
                let (_, r) = project_on_segment(xs, m, k)?;
                let d2 = dot(r, r);
                if to_vertex(k) < d2 || to_vertex(k + 1) < d2 {
                    return None;
                }
                // each neighbour's distance (squared), which must exceed the segment's
                let mut near = f64::INFINITY;
                for j in [k.wrapping_sub(1), k + 1].into_iter().filter(|&j| j < n_seg) {
                    let dj = match project_on_segment(xs, m, j) {
                        Some((_, rj)) if dot(rj, rj) <= d2 => return None,
                        Some((_, rj)) => dot(rj, rj),
                        None => to_vertex(j).min(to_vertex(j + 1)),
                    };
                    near = near.min(dj);
                }
                let p = Self::segment_pair(xs, m, k)?;
                Some((p, segment_radius(xs, m, k, &p, near.sqrt() - d2.sqrt()).min(slack)))
            }
            Feature::Vertex(v) => (!has_projection(v - 1) && !has_projection(v))
                .then(|| (vertex_pair(xs, m, v, PairKind::Vertex(v)), 0.0)),
            Feature::End(e) => (!has_projection(if e == 0 { 0 } else { n_seg - 1 }))
                .then(|| (Pair::NONE, end_radius(xs, m, e, to_vertex(e).sqrt(), f64::INFINITY).min(slack))),
            Feature::Nothing => None,
        }
    }
}

/// One linearised gap row over the contact dofs — the single implementation of the
/// node-to-segment gap (paper eq. 2) that the full-order solver, its statistics, the operator
/// view and the online reduced solve all use. Contact node `c` has dofs `2 c`, `2 c + 1`; the
/// slaves are nodes `0..ns`, master vertex `k` is node `ns + k`. With the pairing's `ξ` and
/// normal `n` frozen,
///
/// ```text
/// segment k:  g = n · (x_s - (1 - ξ) x_k - ξ x_{k+1})
/// vertex v:   g = n · (x_s - x_v)          (blind spot or tie, averaged normal)
/// ```
///
/// linear in the contact-dof positions `x`; a master weight that is exactly zero (`ξ = 0` or
/// `1`) contributes no entries.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GapRow {
    /// Contact dofs of the entries.
    pub dof: [usize; 6],
    /// Coefficients of the entries.
    pub coef: [f64; 6],
    /// Number of entries used.
    pub len: usize,
}

impl GapRow {
    /// The row of slave `s` (of `ns`) for its pairing `p` (which must be paired).
    pub fn new(s: usize, ns: usize, p: &Pair) -> Self {
        let n = p.normal;
        let mut r = GapRow { len: 2, ..Default::default() };
        r.dof[0] = 2 * s;
        r.dof[1] = 2 * s + 1;
        r.coef[0] = n[0];
        r.coef[1] = n[1];
        let mut push = |node: usize, w: f64| {
            if w != 0.0 {
                r.dof[r.len] = 2 * (ns + node);
                r.coef[r.len] = -w * n[0];
                r.dof[r.len + 1] = 2 * (ns + node) + 1;
                r.coef[r.len + 1] = -w * n[1];
                r.len += 2;
            }
        };
        match p.kind {
            PairKind::Segment(k) => {
                push(k, 1.0 - p.xi);
                push(k + 1, p.xi);
            }
            PairKind::Vertex(v) | PairKind::Tied(v) | PairKind::End(v) => push(v, 1.0),
            PairKind::None => panic!("gap rows are built for paired slaves only"),
        }
        r
    }

    /// The entries `(contact dof, coefficient)`.
    pub fn entries(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.dof[..self.len].iter().copied().zip(self.coef[..self.len].iter().copied())
    }

    /// `sum coef_j x[dof_j]`.
    pub fn apply(&self, x: &[f64]) -> f64 {
        (0..self.len).map(|j| self.coef[j] * x[self.dof[j]]).sum()
    }

    /// `f[dof_j] += coef_j lambda` (the contact force of this constraint).
    pub fn scatter(&self, lambda: f64, f: &mut [f64]) {
        for j in 0..self.len {
            f[self.dof[j]] += self.coef[j] * lambda;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

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

    /// The pruned search returns exactly the brute-force [`closest_point`] (bitwise: same
    /// candidates, same arithmetic, same ties) on random wavy polylines of 1 to 40 segments,
    /// points near and far, and points placed exactly on vertices and segment ends.
    #[test]
    fn indexed_closest_point_equals_brute_force() {
        let mut rng = crate::rng::Rng::new(7);
        let mut index = MasterIndex::default();
        for case in 0..300 {
            let n = 2 + case % 40;
            let m: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    let x = -(i as f64) * 0.1 + rng.uniform_in(-0.03, 0.03);
                    [x, 0.2 * (3.0 * x).sin() + rng.uniform_in(-0.05, 0.05)]
                })
                .collect();
            index.build(&m);
            let mut points: Vec<[f64; 2]> =
                (0..20).map(|_| [rng.uniform_in(-5.0, 1.5), rng.uniform_in(-1.0, 1.0)]).collect();
            points.extend(m.iter().copied());
            for xs in points {
                let (a, b) = (closest_point(xs, &m), index.closest_point(xs, &m));
                assert_eq!(a.kind, b.kind, "case {case} point {xs:?}");
                assert_eq!(a.xi.to_bits(), b.xi.to_bits(), "case {case} point {xs:?}");
                assert_eq!(a.gap.to_bits(), b.gap.to_bits(), "case {case} point {xs:?}");
                assert_eq!(a.normal.map(f64::to_bits), b.normal.map(f64::to_bits), "case {case} point {xs:?}");
            }
        }
    }

    /// The gap row of a segment pairing evaluates the gap `(x_s - x_bar) . n` of the pairing
    /// (1e-15: a handful of roundings of O(1) values); a vertex pairing gets one master node.
    #[test]
    fn gap_row_evaluates_the_pairing_gap() {
        let m = [[1.0, -1.0], [0.0, 0.0], [-1.0, 0.0]];
        let xs = [-0.4, 0.3];
        let p = closest_point(xs, &m);
        let row = GapRow::new(0, 1, &p);
        let x: Vec<f64> = std::iter::once(xs).chain(m).flatten().collect();
        assert_eq!(row.len, 6);
        assert_close!(row.apply(&x), p.gap, Tol::abs(1e-15));
        let v = closest_point([0.1, 0.3], &m);
        let row = GapRow::new(0, 1, &v);
        assert_eq!((row.len, row.dof[2], row.dof[3]), (4, 4, 5));
        let x: Vec<f64> = std::iter::once([0.1, 0.3]).chain(m).flatten().collect();
        assert_close!(row.apply(&x), v.gap, Tol::abs(1e-15));
    }

    /// The slave `xs` and every vertex of `m` moved in random directions by amounts summing to
    /// at most `r` (a random split between the slave and the masters).
    fn random_motion(rng: &mut crate::rng::Rng, xs: [f64; 2], m: &[[f64; 2]], r: f64) -> ([f64; 2], Vec<[f64; 2]>) {
        let split = rng.uniform();
        let mv = |rng: &mut crate::rng::Rng, len: f64| {
            let a = rng.uniform_in(0.0, std::f64::consts::TAU);
            [len * a.cos(), len * a.sin()]
        };
        let ds = mv(rng, r * split);
        let m2 = m
            .iter()
            .map(|p| {
                let len = r * (1.0 - split) * rng.uniform();
                let d = mv(rng, len);
                [p[0] + d[0], p[1] + d[1]]
            })
            .collect();
        ([xs[0] + ds[0], xs[1] + ds[1]], m2)
    }

    /// The radius of an unpaired slave is safe: moving the slave and every master vertex at
    /// random by amounts summing to at most the radius never pairs it (brute-force
    /// [`closest_point`] after the move), over random polylines and far points on both sides.
    #[test]
    fn unpaired_radius_is_safe() {
        let mut rng = crate::rng::Rng::new(17);
        let mut index = MasterIndex::default();
        let mut checked = 0;
        for case in 0..200 {
            let n = 3 + case % 30;
            let m: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    let x = -(i as f64) * 0.1;
                    [x, 0.1 * (4.0 * x).sin() + rng.uniform_in(-0.02, 0.02)]
                })
                .collect();
            index.build(&m);
            for _ in 0..10 {
                let xs = [rng.uniform_in(-(n as f64) * 0.1 - 1.0, 1.0), rng.uniform_in(-0.3, 0.3)];
                let (p, r, _) = index.closest_point_proved(xs, &m);
                if p.kind != PairKind::None || r == 0.0 {
                    continue;
                }
                checked += 1;
                for _ in 0..20 {
                    let (xs2, m2) = random_motion(&mut rng, xs, &m, r);
                    assert_eq!(closest_point(xs2, &m2).kind, PairKind::None, "case {case}: {xs:?} r {r}");
                }
            }
        }
        assert!(checked > 100, "too few unpaired points: {checked}");
    }

    /// `n` points along `y = 0.1 sin(4 x)`, `x = 0.1 i`, each jittered by up to `dx`, `dy`.
    fn wavy(rng: &mut crate::rng::Rng, n: usize, dx: f64, dy: f64) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let x = i as f64 * 0.1;
                [x + rng.uniform_in(-dx, dx), 0.1 * (4.0 * x).sin() + rng.uniform_in(-dy, dy)]
            })
            .collect()
    }

    /// A certificate is safe: after moving the slave and every master vertex at random by
    /// amounts summing to less than its radius, what [`MasterIndex::recheck`] returns (when it
    /// returns) is the brute-force [`closest_point`], bit for bit; and it does return for most
    /// moves, on wavy polylines (convex and concave corners) with slaves near and far, on both
    /// sides, beyond the ends.
    #[test]
    fn certificates_are_safe() {
        let mut rng = crate::rng::Rng::new(29);
        let mut index = MasterIndex::default();
        let (mut checked, mut kept, mut renewed) = (0, 0, 0);
        let mut features = [0usize; 3];
        for case in 0..300 {
            let n = 3 + case % 40;
            let m = wavy(&mut rng, n, 0.02, 0.03);
            index.build(&m);
            for _ in 0..10 {
                let far = if rng.uniform() < 0.3 { 1.0 } else { 0.2 };
                let xs = [rng.uniform_in(-far, n as f64 * 0.1 + far), rng.uniform_in(-far, far)];
                let (p, _, cert) = index.closest_point_proved(xs, &m);
                assert_eq!(p, closest_point(xs, &m), "case {case}: the search itself");
                if cert.radius == 0.0 {
                    continue;
                }
                features[match cert.feature {
                    Feature::Segment(_) => 0,
                    Feature::Vertex(_) => 1,
                    _ => 2,
                }] += 1;
                for _ in 0..20 {
                    let moved = cert.radius * rng.uniform();
                    let (xs2, m2) = random_motion(&mut rng, xs, &m, moved);
                    checked += 1;
                    if let Some((q, r2)) = MasterIndex::recheck(xs2, &m2, &cert, moved) {
                        kept += 1;
                        assert_eq!(q, closest_point(xs2, &m2), "case {case}: {xs:?} {cert:?} moved {moved}");
                        // the renewed radius: the kind holds for any further motion within it
                        if r2 > 0.0 {
                            renewed += 1;
                            let further = r2 * rng.uniform();
                            let (xs3, m3) = random_motion(&mut rng, xs2, &m2, further);
                            assert_eq!(closest_point(xs3, &m3).kind, q.kind, "case {case}: renewed {r2}");
                        }
                    }
                }
            }
        }
        assert!(features.iter().all(|&c| c > 20), "every feature certified: {features:?}");
        assert!(kept * 10 > checked * 8, "rechecks kept {kept} of {checked}");
        assert!(renewed * 2 > kept, "renewed {renewed} of {kept}");
        // beyond the radius a certificate proves nothing
        let flat = [[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]];
        index.build(&flat);
        let (_, _, cert) = index.closest_point_proved([0.05, 0.2], &flat);
        assert!(cert.radius > 0.0 && MasterIndex::recheck([0.05, 0.2], &flat, &cert, 0.0).is_some());
        assert!(MasterIndex::recheck([0.05, 0.2], &flat, &cert, cert.radius).is_none());
    }

    /// The radius of a slave paired with a segment is safe: moving the slave and every master
    /// vertex at random by amounts summing to at most the radius leaves it paired with the same
    /// segment (brute-force [`closest_point`] after the move), and `segment_pair` there equals
    /// the brute force bit for bit.
    #[test]
    fn segment_radius_is_safe() {
        let mut rng = crate::rng::Rng::new(23);
        let mut index = MasterIndex::default();
        let mut checked = 0;
        for case in 0..200 {
            let n = 3 + case % 30;
            let m = wavy(&mut rng, n, 0.01, 0.02);
            index.build(&m);
            for _ in 0..10 {
                let xs = [rng.uniform_in(-0.1, n as f64 * 0.1), rng.uniform_in(-0.2, 0.3)];
                let (p, r, _) = index.closest_point_proved(xs, &m);
                let PairKind::Segment(k) = p.kind else { continue };
                if r == 0.0 {
                    continue;
                }
                checked += 1;
                for _ in 0..20 {
                    let (xs2, m2) = random_motion(&mut rng, xs, &m, r);
                    let brute = closest_point(xs2, &m2);
                    assert_eq!(brute.kind, PairKind::Segment(k), "case {case}: {xs:?} r {r}");
                    assert_eq!(MasterIndex::segment_pair(xs2, &m2, k), Some(brute), "case {case}");
                }
            }
        }
        assert!(checked > 500, "too few paired points: {checked}");
    }
}
