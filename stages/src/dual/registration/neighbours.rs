//! Registered neighbours: at each parameter point, the dual basis is the training snapshots
//! nearest to it in the registered frame, pushed forward to it.
//!
//! # Why a per-query choice
//!
//! With whole-node shifts ([`Interpolation::Nodes`](super::Interpolation::Nodes)) a pressure at
//! travel `c` is pulled back by `k(c) = round(c / h)` nodes. What the shift leaves is the
//! residual
//!
//! ```text
//! ρ(c) = c / h − k(c)  ∈ [−½, ½]      (in node spacings)
//! ```
//!
//! and on a node-to-segment discretisation the nodal pressure depends on it: the same sole
//! pressed between two slave nodes or onto one gives different nodal values. Two snapshots with
//! the same `ρ` are, after the whole-node shift, the same profile up to the slow effect of where
//! the iron stands on the slab; two with `ρ` half a node apart are not. A basis fixed in the
//! reference frame (POD, CPG) has to hold every residual shift at once; this one picks, at each
//! point, the training snapshots whose residual shift is nearest.
//!
//! # The order
//!
//! At a point with travel `c`, training snapshot `j` (travel `c_j`) scores
//!
//! ```text
//! score_j = h |Δρ_j| + w |c − c_j|,     Δρ_j = ρ(c_j) − ρ(c) wrapped into (−½, ½],
//! ```
//!
//! the misalignment its pushed profile keeps plus `w` times how far it was taken along the
//! surface. The snapshots with `Δρ_j ≤ 0` and those with `Δρ_j > 0` are two sides; each is
//! sorted by `(score, j)`, and the order takes them alternately, starting with the side whose
//! best scores lower (ties: the side `Δρ ≤ 0`). The first two columns bracket the point's
//! residual shift, so their cone interpolates in it; the first `m` are the basis of size `m`.
//! Every column is a training snapshot pulled back and scaled to unit norm, so the basis is
//! non-negative and the cone projection and the online solve take it as they take CPG
//! generators.
//!
//! # A vector parameter
//!
//! Over `μ = (c, μ₂)` (the travel and a second component, such as the press), a column also
//! stands on one side of the point in `μ₂`, and four sides take turns: `Δρ_j ≤ 0` or `> 0`,
//! crossed with `μ₂,j ≤ μ₂` or `> μ₂`. The score adds the distance in `μ₂`, turned into travel
//! by the ratio `s` of the training grid's steps (the smallest positive difference between
//! training travels over that between training `μ₂`):
//!
//! ```text
//! score_j = h |Δρ_j| + w (|c − c_j| + s |μ₂ − μ₂,j|).
//! ```
//!
//! The sides take turns in the order of their best scores (ties: the lower side, counting
//! `Δρ > 0` as 1 and `μ₂,j > μ₂` as 2), each giving its next column by `(score, j)`; a side
//! that has none left is passed over. With one component there are the two sides above and
//! this is their alternation. The first four columns bracket the point's residual shift and its
//! `μ₂`, so their cone interpolates in both: on ironing-fine-2d's press, where a smooth map
//! (centre and width from moments) moves the node-to-node ripple of the node-to-segment
//! pressure with the profile and stops near 1 %, whole-node shifts keep the ripple in place.
//!
//! # The weight
//!
//! `w` trades travel against misalignment. It is chosen from [`WEIGHTS`] by leave-one-out on the
//! training set: for each `w`, every training snapshot is projected on the cone of its first two
//! neighbours among the others (physical frame, Euclidean norm) and the relative residuals are
//! averaged; the smallest mean wins (ties: the smaller `w`). The choice is a function of the
//! training snapshots only, so a study chooses the same `w` every run.

use faer::MatRef;

use super::Map;

/// The candidate weights `w` (travel against misalignment), ascending.
pub const WEIGHTS: [f64; 11] = [0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0];

/// The per-query order of a registered-neighbours basis (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct Neighbours {
    /// Travel `c_j` of each training snapshot (reference column `j`).
    pub(super) centres: Vec<f64>,
    /// The node spacing `h` of the whole-node shifts.
    pub(super) step: f64,
    /// The weight `w`.
    pub(super) weight: f64,
    /// `ρ(c_j)` of each column (computed once).
    pub(super) rho: Vec<f64>,
    /// Over a vector parameter: each column's second component and the scale `s` (module doc).
    second: Option<Second>,
}

/// The second parameter component `μ₂,j` of every column and the scale `s` that turns its
/// distances into travel (module doc, "A vector parameter").
#[derive(Debug, Clone, PartialEq)]
pub struct Second {
    /// `μ₂,j` of each column.
    pub values: Vec<f64>,
    /// `s`.
    pub scale: f64,
}

impl Second {
    /// The second components `values` of the training points with travels `travels`, scaled by
    /// the ratio of their grids' steps (1 where either has no two distinct values).
    pub fn of(travels: &[f64], values: Vec<f64>) -> Self {
        let step = |v: &[f64]| {
            let mut v = v.to_vec();
            v.sort_by(f64::total_cmp);
            v.windows(2).map(|p| p[1] - p[0]).filter(|&d| d > 0.0).fold(f64::INFINITY, f64::min)
        };
        let (a, b) = (step(travels), step(&values));
        let scale = if a.is_finite() && b.is_finite() { a / b } else { 1.0 };
        Self { values, scale }
    }
}

/// Where a column stands from the point: its side (module doc: bit 0 `Δρ > 0`, bit 1
/// `μ₂,j > μ₂`) and its score.
fn side_and_score(nb: &Neighbours, (c, second): (f64, f64), rho: f64, w: f64, j: usize) -> (u8, f64) {
    let h = nb.step;
    let d = wrapped(nb.rho[j], rho);
    let cj = nb.centres[j];
    match &nb.second {
        None => (u8::from(d > 0.0), h * d.abs() + w * (c - cj).abs()),
        Some(sec) => {
            let e = sec.values[j] - second;
            (u8::from(d > 0.0) | (u8::from(e > 0.0) << 1), h * d.abs() + w * ((c - cj).abs() + sec.scale * e.abs()))
        }
    }
}

/// `ρ(c)`: the part of the travel `c` that whole-node shifts leave, in node spacings.
fn residual_shift(c: f64, h: f64) -> f64 {
    let t = c / h;
    t - t.round()
}

/// `a − b` wrapped into `(−½, ½]`.
fn wrapped(a: f64, b: f64) -> f64 {
    let mut d = a - b;
    d -= d.round();
    if d <= -0.5 {
        d += 1.0;
    }
    d
}

impl Neighbours {
    /// With the weight given (a stored basis).
    pub(super) fn with_weight(centres: Vec<f64>, step: f64, weight: f64) -> Self {
        let rho = centres.iter().map(|&c| residual_shift(c, step)).collect();
        Self { centres, step, weight, rho, second: None }
    }

    /// Over a vector parameter: the columns' second components (module doc).
    pub(super) fn with_second(mut self, second: Second) -> Self {
        self.second = Some(second);
        self
    }

    /// The columns' second components, over a vector parameter.
    pub fn second(&self) -> Option<&Second> {
        self.second.as_ref()
    }

    /// The weight `w`.
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// The travels `c_j` of the training snapshots.
    pub fn centres(&self) -> &[f64] {
        &self.centres
    }

    /// The order of the columns at the point `(c, μ₂)` with weight `w`, without column `skip`,
    /// by sorting every side: the definition, kept for the tests of [`Picks`].
    #[cfg(test)]
    fn order_with(&self, at: (f64, f64), w: f64, skip: Option<usize>) -> Vec<usize> {
        let rho = residual_shift(at.0, self.step);
        let mut sides: [Vec<(f64, usize)>; 4] = Default::default();
        for j in 0..self.centres.len() {
            if Some(j) == skip {
                continue;
            }
            let (side, score) = side_and_score(self, at, rho, w, j);
            sides[usize::from(side)].push((score, j));
        }
        for side in &mut sides {
            side.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        let mut turns: Vec<usize> = (0..4).filter(|&k| !sides[k].is_empty()).collect();
        turns.sort_by(|&a, &b| sides[a][0].0.total_cmp(&sides[b][0].0).then(a.cmp(&b)));
        let longest = sides.iter().map(Vec::len).max().unwrap_or(0);
        let mut order = Vec::new();
        for k in 0..longest {
            for &t in &turns {
                order.extend(sides[t].get(k).map(|p| p.1));
            }
        }
        order
    }

    /// The columns at the point of travel `c` (and second component `second`, read over a
    /// vector parameter) in the module doc's order, picked one at a time.
    pub(super) fn order(&self, c: f64, second: f64) -> Picks {
        Picks::new(self, (c, second), self.weight, None)
    }

    /// Choose `w` from [`WEIGHTS`] by leave-one-out on the training set: `reference` holds the
    /// pulled-back unit columns, `snapshots` the physical ones (`n x N`), `travels` the `c_j`.
    pub(super) fn fit(
        map: &Map,
        reference: MatRef<'_, f64>,
        snapshots: MatRef<'_, f64>,
        travels: Vec<f64>,
        second: Option<Second>,
    ) -> Self {
        let mut me = Self::with_weight(travels, map.grid_step, 0.0);
        me.second = second;
        let count = me.centres.len();
        if count < 3 {
            return me;
        }
        let n = snapshots.nrows();
        let column = |j: usize| reference.col(j).try_as_col_major().expect("contiguous column").as_slice();
        // each training snapshot with its norm, read once for every weight
        let physical: Vec<(Vec<f64>, f64)> = (0..count)
            .map(|j| {
                let s: Vec<f64> = snapshots.col(j).iter().copied().collect();
                let norm = crate::cone::norm2(&s);
                (s, norm)
            })
            .collect();
        let mut best = (f64::INFINITY, 0.0);
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        for &w in &WEIGHTS {
            let mut sum = 0.0;
            for (j, (s, norm)) in physical.iter().enumerate() {
                if *norm == 0.0 {
                    continue;
                }
                let at = (me.centres[j], me.second.as_ref().map_or(0.0, |sec| sec.values[j]));
                let mut order = Picks::new(&me, at, w, Some(j));
                let (first, second) = (order.next().expect("3 columns or more"), order.next().expect("a second"));
                let mu = [me.centres[j]];
                map.push(column(first), &mu, &mut a);
                map.push(column(second), &mu, &mut b);
                sum += cone2_residual(s, &a, &b) / norm;
            }
            let mean = sum / count as f64;
            if mean < best.0 {
                best = (mean, w);
            }
        }
        me.weight = best.1;
        me
    }
}

/// The columns of a [`Neighbours`] order at one point, best first, without sorting: each pick
/// scans the remaining columns of the side whose turn it is for the least `(score, j)`, so the
/// first `k` cost `O(N k)` — a query needs a few.
pub(super) struct Picks {
    /// Per column: its side (module doc), its score, whether it is still to pick.
    keys: Vec<(u8, f64, bool)>,
    /// The sides that had columns, in the order they take turns.
    turns: Vec<u8>,
    /// The position in `turns` whose turn it is.
    turn: usize,
}

impl Picks {
    fn new(nb: &Neighbours, at: (f64, f64), w: f64, skip: Option<usize>) -> Self {
        let rho = residual_shift(at.0, nb.step);
        let keys = (0..nb.centres.len())
            .map(|j| {
                let (side, score) = side_and_score(nb, at, rho, w, j);
                (side, score, Some(j) != skip)
            })
            .collect();
        let mut me = Self { keys, turns: Vec::new(), turn: 0 };
        let mut firsts: Vec<(u8, usize)> = (0..4u8).filter_map(|side| me.best(side).map(|j| (side, j))).collect();
        firsts.sort_by(|a, b| me.keys[a.1].1.total_cmp(&me.keys[b.1].1).then(a.0.cmp(&b.0)));
        me.turns = firsts.into_iter().map(|(side, _)| side).collect();
        me
    }

    /// The remaining column of `side` with the least `(score, j)`.
    fn best(&self, side: u8) -> Option<usize> {
        let mut best: Option<usize> = None;
        for (j, &(sd, score, open)) in self.keys.iter().enumerate() {
            if open && sd == side && best.is_none_or(|b| score < self.keys[b].1) {
                best = Some(j);
            }
        }
        best
    }
}

impl Iterator for Picks {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        let n = self.turns.len();
        for k in 0..n {
            let at = (self.turn + k) % n;
            if let Some(j) = self.best(self.turns[at]) {
                self.keys[j].2 = false;
                self.turn = (at + 1) % n;
                return Some(j);
            }
        }
        None
    }
}

/// `min_{x, y >= 0} ||s − x a − y b||` (Euclidean), in closed form: the two-column least
/// squares where both coefficients are non-negative, else the better single column, else `s`.
fn cone2_residual(s: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(x, y)| x * y).sum::<f64>();
    let (aa, ab, bb, sa, sb, ss) = (dot(a, a), dot(a, b), dot(b, b), dot(s, a), dot(s, b), dot(s, s));
    // each single column (0 where the column is zero or points away from s)
    let single = |cc: f64, sc: f64| if cc > 0.0 && sc > 0.0 { sc * sc / cc } else { 0.0 };
    let mut explained = single(aa, sa).max(single(bb, sb));
    let det = aa * bb - ab * ab;
    if det > 1e-14 * aa * bb {
        let (x, y) = ((bb * sa - ab * sb) / det, (aa * sb - ab * sa) / det);
        if x >= 0.0 && y >= 0.0 {
            explained = explained.max(x * sa + y * sb);
        }
    }
    (ss - explained).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    /// `ρ` and the wrap, by hand: 2.3 spacings leave 0.3, 2.7 leave −0.3; 0.4 − (−0.4) wraps to
    /// −0.2.
    #[test]
    fn residual_shifts_wrap_into_half_a_node() {
        // 1e-12: one division and one rounding of numbers of order 1
        let tol = Tol::abs(1e-12);
        assert_close!(residual_shift(0.23, 0.1), 0.3, tol);
        assert_close!(residual_shift(0.27, 0.1), -0.3, tol);
        assert_close!(wrapped(0.4, -0.4), -0.2, tol);
        assert_close!(wrapped(-0.4, 0.4), 0.2, tol);
        // half a node either way is +½ (the interval is (−½, ½]), exactly
        assert_eq!(wrapped(0.5, 0.0).to_bits(), 0.5f64.to_bits());
        assert_eq!(wrapped(-0.5, 0.0).to_bits(), 0.5f64.to_bits());
    }

    /// The order brackets the residual shift and interleaves the sides by score, worked by
    /// hand. h = 1, travels 0.0, 0.1, 0.2, 1.05, 2.95, 3.5 at c = 2.1 (ρ = 0.1): ρ_j = 0, 0.1,
    /// 0.2, 0.05, −0.05, −0.5, so Δρ_j = −0.1, 0, 0.1, −0.05, −0.15 and −0.6, which wraps to 0.4.
    /// Sides: Δρ ≤ 0 {0, 1, 3, 4}, Δρ > 0 {2, 5}.
    #[test]
    fn the_order_brackets_and_interleaves() {
        let nb = Neighbours::with_weight(vec![0.0, 0.1, 0.2, 1.05, 2.95, 3.5], 1.0, 0.0);
        // w = 0: side ≤ 0 by |Δρ|: 1 (0), 3 (0.05), 0 (0.1), 4 (0.15); side > 0: 2 (0.1),
        // 5 (0.4). Side ≤ 0 starts (0 < 0.1).
        assert_eq!(nb.order_with((2.1, 0.0), 0.0, None), vec![1, 2, 3, 5, 0, 4]);
        // w = 1: scores |Δρ| + |c − c_j| = 2.2, 2.0, 2.0, 1.1, 1.0, 1.8; side ≤ 0: 4, 3, 1, 0;
        // side > 0: 5, 2. Side ≤ 0 starts (1.0 < 1.8).
        assert_eq!(nb.order_with((2.1, 0.0), 1.0, None), vec![4, 5, 3, 2, 1, 0]);
        // without column 1: side ≤ 0: 3, 0, 4; side > 0: 2, 5; side ≤ 0 starts (0.05 < 0.1)
        assert_eq!(nb.order_with((2.1, 0.0), 0.0, Some(1)), vec![3, 2, 0, 5, 4]);
    }

    /// The lazy picks give the sorted order, on scattered travels (ties in score included:
    /// travels symmetric about the point) for several weights and a skipped column.
    #[test]
    fn picks_are_the_sorted_order() {
        let mut centres: Vec<f64> = (0..60).map(|j| ((j * 37) % 61) as f64 * 0.0473).collect();
        centres.extend([1.0, 1.2, 0.8, 1.1, 0.9]);
        let nb = Neighbours::with_weight(centres, 0.025, 0.0);
        for &w in &[0.0, 0.001, 0.05, 1.0] {
            for &c in &[1.0, 0.013, 2.7, 1.4125] {
                for skip in [None, Some(3), Some(61)] {
                    let lazy: Vec<usize> = Picks::new(&nb, (c, 0.0), w, skip).collect();
                    assert_eq!(lazy, nb.order_with((c, 0.0), w, skip), "w {w}, c {c}, skip {skip:?}");
                }
            }
        }
    }

    /// Over a vector parameter four sides take turns, worked by hand. h = 1, s = 1, w = 1, the
    /// point (c, μ₂) = (2.1, 0.5) (ρ = 0.1). Columns (c_j, μ₂,j): 0 (2.0, 0.4), 1 (2.2, 0.38),
    /// 2 (2.0, 0.7), 3 (2.3, 0.6), 4 (1.9, 0.45), 5 (4.0, 0.5). Δρ_j = −0.1, 0.1, −0.1, 0.2,
    /// −0.2, −0.1 (ρ_j = 0, 0.2, 0, 0.3, −0.1, 0); sides (bit 0 Δρ > 0, bit 1 μ₂,j > μ₂):
    /// 0 → 0, 1 → 1, 2 → 2, 3 → 3, 4 → 0, 5 → 0. Scores |Δρ| + |Δc| + |Δμ₂|: 0.3, 0.32, 0.4,
    /// 0.5, 0.45, 2.0. Sides by their best: 0 (0.3, column 0), 1 (0.32), 2 (0.4), 3 (0.5); then
    /// side 0's next (4, then 5).
    #[test]
    fn over_a_vector_parameter_four_sides_take_turns() {
        let centres = vec![2.0, 2.2, 2.0, 2.3, 1.9, 4.0];
        let second = Second { values: vec![0.4, 0.38, 0.7, 0.6, 0.45, 0.5], scale: 1.0 };
        let nb = Neighbours::with_weight(centres, 1.0, 1.0).with_second(second);
        assert_eq!(nb.order_with((2.1, 0.5), 1.0, None), vec![0, 1, 2, 3, 4, 5]);
        let lazy: Vec<usize> = nb.order(2.1, 0.5).collect();
        assert_eq!(lazy, vec![0, 1, 2, 3, 4, 5]);
        // without column 1 side 1 is empty: 0, 2, 3, then side 0's 4 and 5
        assert_eq!(nb.order_with((2.1, 0.5), 1.0, Some(1)), vec![0, 2, 3, 4, 5]);
        // the scale of the grids' steps: travels 0.5 apart, second components 0.01 apart
        let sec = Second::of(&[0.0, 0.5, 1.0, 0.5], vec![0.02, 0.03, 0.05, 0.02]);
        assert_close!(sec.scale, 50.0, Tol::rel(1e-12));
        assert_eq!(Second::of(&[1.0, 1.0], vec![0.0, 0.1]).scale.to_bits(), 1.0f64.to_bits(), "one travel: no step");
    }

    /// The lazy picks give the sorted order over a vector parameter too: a 9 x 5 grid of
    /// points with scattered travels, several weights, points and a skipped column.
    #[test]
    fn picks_are_the_sorted_order_over_a_vector_parameter() {
        let (mut centres, mut values) = (Vec::new(), Vec::new());
        for j in 0..45 {
            centres.push(((j * 37) % 61) as f64 * 0.0473);
            values.push(0.02 + 0.01 * (j % 5) as f64);
        }
        let nb = Neighbours::with_weight(centres.clone(), 0.025, 0.0).with_second(Second::of(&centres, values));
        for &w in &[0.0, 0.01, 1.0] {
            for &at in &[(1.0, 0.03), (0.013, 0.02), (2.7, 0.065), (1.4125, 0.041)] {
                for skip in [None, Some(3), Some(44)] {
                    let lazy: Vec<usize> = Picks::new(&nb, at, w, skip).collect();
                    assert_eq!(lazy, nb.order_with(at, w, skip), "w {w}, at {at:?}, skip {skip:?}");
                }
            }
        }
    }

    /// The two-column cone residual against a brute-force scan of the coefficients.
    #[test]
    fn cone2_residual_is_the_cone_projection() {
        let cases: [([f64; 3], [f64; 3], [f64; 3]); 4] = [
            ([1.0, 2.0, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([1.0, -2.0, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([-1.0, -2.0, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([1.0, 1.0, 1.0], [1.0, 0.2, 0.0], [1.0, 0.3, 0.1]),
        ];
        for (s, a, b) in cases {
            let mut best = f64::INFINITY;
            for i in 0..=400 {
                for k in 0..=400 {
                    let (x, y) = (i as f64 * 0.01, k as f64 * 0.01);
                    let r: f64 = (0..3).map(|t| (s[t] - x * a[t] - y * b[t]).powi(2)).sum::<f64>().sqrt();
                    best = best.min(r);
                }
            }
            // the scan's step (0.01) bounds how far its best can be above the true minimum
            let got = cone2_residual(&s, &a, &b);
            assert!(got <= best + 1e-12 && best - got < 0.03, "{s:?}: {got} against a scan's {best}");
        }
    }
}
