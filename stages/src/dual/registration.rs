//! Registration: a change of variables of the contact surface that makes the pressure snapshots
//! low rank (the paper's second *Perspective*).
//!
//! # The map
//!
//! A slave node at abscissa `x` (reference configuration) is sent to `xi = (x - c(mu)) / a(mu)`:
//!
//! * [`MapKind::Translate`] (ironing): `c(mu) = mu_1`, the iron's travel `d_x`, `a = 1` — known
//!   from the parameter, exact.
//! * [`MapKind::Moments`] (hertz): `c` and `a` from the pressure's moments. With the
//!   piecewise-constant pressure of the discretisation (value `s_i` on the tributary cell of
//!   width `w_i` around node i), `M0 = sum w_i s_i`, `c = sum w_i s_i x_i / M0` and
//!   `a = 2 sqrt(sum w_i s_i ((x_i - c)^2 + w_i^2 / 12) / M0)` — for the Hertz profile
//!   `p0 sqrt(1 - x^2 / b^2)` the variance is `b^2 / 4`, so `a` is the contact half-width `b`.
//!   Online `(c, a)(mu)` is the piecewise-linear interpolation, in the one parameter, of the
//!   training snapshots' values (clamped beyond the ends): predicted from `mu` alone, with no
//!   full-order information. Scenes with more than one parameter component are refused.
//!
//! The rope has no natural map: its contact set is an interval whose both ends move with the
//! load at rates that are not a translation or a dilation of a fixed profile (the free span's
//! shape changes), so no map is offered for it.
//!
//! # Interpolation
//!
//! * [`Interpolation::Nodes`] (translation only, uniform node spacing `h`): the shift is
//!   rounded to whole nodes, `k(mu) = round(c(mu) / h)`, and the reference grid is the node grid
//!   extended by the training shifts. Pulling back and pushing forward only move values: exact
//!   (round trip 0), non-negative, and the sub-node part of the travel is left to the modes.
//! * [`Interpolation::Linear`]: a uniform reference grid `refine` times finer than the finest
//!   node spacing seen in the reference frame; both directions interpolate linearly (pressure
//!   zero beyond the surface's ends). Linear interpolation is monotone, so mapped pressures stay
//!   non-negative. Pulled back, a snapshot is its nodal piecewise-linear interpolant sampled on
//!   the reference grid; pushed forward again, each node's value is interpolated across the
//!   interpolant's kink at that node, so the round trip errs by about `h_ref` times the kink:
//!   `O(h h_ref |p''|)` where the profile is smooth, `O(h_ref / h)` of the jump at a steep
//!   edge — first order in the reference spacing `h_ref` either way, and much smaller where the
//!   profile is smooth. The round-trip error
//!   `||push(pull(s_j)) - s_j|| / ||s_j||` of every training snapshot is measured and stored
//!   (mean and max).
//!
//! # The basis and the projection
//!
//! POD or CPG is built from the registered snapshots. For a pressure `s` at `mu` the first m
//! reference modes are pushed forward to `mu`'s frame (`m x n` values) and `s` is projected on
//! their span (POD; the pushed modes are not orthonormal, so they are orthonormalised) or their
//! cone (CPG): every error is in the physical frame, against the original snapshot.

mod arrays;
mod neighbours;

use faer::Mat;

pub use arrays::RegisteredArrays;
pub use neighbours::{Neighbours, Second as NeighbourSecond, WEIGHTS as NEIGHBOUR_WEIGHTS};

use super::{cpg_generators, pod_modes, ConePrefix, DualApprox, DualError, Fact, Inner, SpanPrefix, Training};
use crate::cone::norm2;

/// How mapped values are evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Whole-node shifts on the node grid (exact; translation on a uniform grid only).
    Nodes,
    /// Linear interpolation on a reference grid `refine` times finer than the nodes.
    Linear {
        /// Reference cells per (finest) node spacing, >= 1.
        refine: usize,
    },
}

/// The map of the contact surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapKind {
    /// `xi = x - mu_1` (ironing: the iron's travel).
    Translate {
        /// Evaluation of the shifted values.
        interpolation: Interpolation,
    },
    /// `xi = (x - c(mu)) / a(mu)` with centre and half-width from the pressure's moments,
    /// interpolated in the parameter (hertz).
    Moments {
        /// Reference cells per finest node spacing.
        refine: usize,
    },
}

impl MapKind {
    /// Name in tables (`translate-nodes`, `translate-linear`, `moments`).
    pub fn name(&self) -> &'static str {
        match self {
            MapKind::Translate { interpolation: Interpolation::Nodes } => "translate-nodes",
            MapKind::Translate { interpolation: Interpolation::Linear { .. } } => "translate-linear",
            MapKind::Moments { .. } => "moments",
        }
    }
}

/// [`Map::frame`]'s interpolation of `(c, a)` over `points` in the first `dims` components of
/// `mu` (every point agrees with `mu`'s components beyond them).
fn levels(points: &[&(Vec<f64>, f64, f64)], mu: &[f64], dims: usize) -> (f64, f64) {
    let last = dims - 1;
    // a point with fewer components than the map's (refused where a model is loaded) reads
    // the lowest level: never an index out of range
    let t = mu.get(last).copied().unwrap_or(f64::NAN);
    // the distinct values of the last component, ascending
    let mut values: Vec<f64> = points.iter().map(|p| p.0[last]).collect();
    values.sort_by(f64::total_cmp);
    values.dedup_by(|a, b| a.to_bits() == b.to_bits());
    let at = |v: f64| -> (f64, f64) {
        let on: Vec<&(Vec<f64>, f64, f64)> =
            points.iter().copied().filter(|p| p.0[last].to_bits() == v.to_bits()).collect();
        if last == 0 {
            // one point per value on the first axis (duplicates: the first)
            let p = on[0];
            (p.1, p.2)
        } else {
            levels(&on, mu, last)
        }
    };
    let k = values.partition_point(|&v| v <= t);
    if k == 0 {
        at(values[0])
    } else if k >= values.len() {
        at(values[values.len() - 1])
    } else {
        let (p, q) = (values[k - 1], values[k]);
        let (a, b) = (at(p), at(q));
        let th = if q > p { (t - p) / (q - p) } else { 0.0 };
        ((1.0 - th) * a.0 + th * b.0, (1.0 - th) * a.1 + th * b.1)
    }
}

/// Tolerance of the uniform-spacing check of [`Interpolation::Nodes`] (relative to `h`; node
/// coordinates from a structured mesh agree to round-off).
const UNIFORM_REL: f64 = 1e-9;

/// Two slave nodes lie on one line of a contact area when their coordinates across the travel
/// differ by at most this fraction of the across extent (a structured mesh repeats a row's
/// coordinate to round-off).
const LINE_REL: f64 = 1e-9;

/// The surface's nodes, line by line (a contact curve is one line; a contact area, the lines of
/// equal coordinate across the travel), each line sorted by abscissa.
#[derive(Debug, Clone)]
struct Surface {
    /// Node order: by line, then by increasing x.
    order: Vec<usize>,
    /// Abscissae in that order.
    x: Vec<f64>,
    /// Tributary widths along the line (same order).
    w: Vec<f64>,
    /// Where each line starts in that order, and the end (`lines + 1` entries).
    starts: Vec<usize>,
}

impl Surface {
    /// `x`: each node's abscissa; `across`: each node's coordinate across the travel, or empty
    /// for a contact curve (one line).
    fn new(x: &[f64], across: &[f64]) -> Self {
        let n = x.len();
        // the line of each node: distinct across-coordinates (to LINE_REL of their extent)
        let mut line = vec![0usize; n];
        if across.len() == n && n > 0 {
            let mut by: Vec<usize> = (0..n).collect();
            by.sort_by(|&a, &b| across[a].total_cmp(&across[b]));
            let extent = across[by[n - 1]] - across[by[0]];
            let tol = crate::float_cmp::Tol { abs: LINE_REL * extent.abs(), rel: 0.0 };
            let mut l = 0;
            for k in 1..n {
                if !crate::float_cmp::close(across[by[k - 1]], across[by[k]], tol) {
                    l += 1;
                }
                line[by[k]] = l;
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| line[a].cmp(&line[b]).then(x[a].total_cmp(&x[b])));
        let xs: Vec<f64> = order.iter().map(|&i| x[i]).collect();
        let mut starts = vec![0];
        starts.extend((1..n).filter(|&k| line[order[k]] != line[order[k - 1]]));
        starts.push(n);
        let mut w = vec![0.0; n];
        for seg in starts.windows(2) {
            let xl = &xs[seg[0]..seg[1]];
            let m = xl.len();
            for (i, wi) in w[seg[0]..seg[1]].iter_mut().enumerate() {
                let lo = if i > 0 { xl[i - 1] } else { xl[i] };
                let hi = if i + 1 < m { xl[i + 1] } else { xl[i] };
                *wi = 0.5 * (hi - lo);
            }
        }
        Self { order, x: xs, w, starts }
    }

    /// Number of lines.
    fn lines(&self) -> usize {
        self.starts.len() - 1
    }

    /// The positions (in [`Surface::order`]) of line `l`.
    fn line(&self, l: usize) -> std::ops::Range<usize> {
        self.starts[l]..self.starts[l + 1]
    }

    /// Smallest positive spacing along a line.
    fn min_spacing(&self) -> f64 {
        (0..self.lines())
            .flat_map(|l| self.x[self.line(l)].windows(2).map(|p| p[1] - p[0]).collect::<Vec<_>>())
            .filter(|d| *d > 0.0)
            .fold(f64::INFINITY, f64::min)
    }

    /// Linear interpolation along line `l` of the nodal values `v` (dual order) at `t` (0
    /// beyond the line's ends).
    fn eval(&self, l: usize, v: &[f64], t: f64) -> f64 {
        let r = self.line(l);
        let (xs, order) = (&self.x[r.clone()], &self.order[r]);
        let n = xs.len();
        if n == 0 || t < xs[0] || t > xs[n - 1] {
            return 0.0;
        }
        let k = xs.partition_point(|&x| x <= t);
        if k == 0 {
            return v[order[0]];
        }
        if k >= n {
            return v[order[n - 1]];
        }
        let (x0, x1) = (xs[k - 1], xs[k]);
        let th = if x1 > x0 { (t - x0) / (x1 - x0) } else { 0.0 };
        (1.0 - th) * v[order[k - 1]] + th * v[order[k]]
    }

    /// `(c, a)` of one snapshot by its moments along the travel, summed over the lines (None
    /// for a zero snapshot).
    fn moments(&self, s: &[f64]) -> Option<(f64, f64)> {
        let m0: f64 = self.order.iter().zip(&self.w).map(|(&i, w)| w * s[i]).sum();
        if m0 <= 0.0 {
            return None;
        }
        let c = self.order.iter().zip(&self.w).zip(&self.x).map(|((&i, w), x)| w * s[i] * x).sum::<f64>() / m0;
        let var = self
            .order
            .iter()
            .zip(&self.w)
            .zip(&self.x)
            .map(|((&i, w), x)| w * s[i] * ((x - c).powi(2) + w * w / 12.0))
            .sum::<f64>()
            / m0;
        Some((c, 2.0 * var.sqrt()))
    }
}

/// The map fitted to a training set.
#[derive(Debug, Clone)]
pub struct Map {
    kind: MapKind,
    surface: Surface,
    /// Training abscissae of the moments map (sorted) and their `(c, a)` (one parameter).
    table: Vec<(f64, f64, f64)>,
    /// With several parameter components: each training point and its `(c, a)`
    /// ([`Map::frame`]'s levels).
    pub(super) points: Vec<(Vec<f64>, f64, f64)>,
    /// Nodes: spacing h and the shift offset; Linear: reference grid start and spacing.
    grid_start: f64,
    grid_step: f64,
    /// Reference grid length: [`Map::line_len`] per line of the surface.
    len: usize,
    /// Reference points per line.
    line_len: usize,
    /// The coordinate across the travel of each node, dual order, as fitted (empty: a curve).
    across: Vec<f64>,
}

impl Map {
    /// Fit the map to the training snapshots.
    pub fn fit(training: &Training<'_>, kind: MapKind) -> Result<Self, DualError> {
        let s = training.snapshots;
        let n = s.nrows();
        if training.surface.len() != n {
            return Err(DualError::NotApplicable(format!(
                "registration needs the abscissa of each of the {n} slave nodes; {} given",
                training.surface.len()
            )));
        }
        if !training.across.is_empty() && training.across.len() != n {
            return Err(DualError::NotApplicable(format!(
                "registration needs the coordinate across the travel of each of the {n} slave nodes; {} given",
                training.across.len()
            )));
        }
        let surface = Surface::new(training.surface, training.across);
        let col = |j: usize| -> Vec<f64> { (0..n).map(|i| s[(i, j)]).collect() };
        let mut map = Self {
            kind,
            surface,
            table: Vec::new(),
            points: Vec::new(),
            grid_start: 0.0,
            grid_step: 1.0,
            len: 0,
            line_len: 0,
            across: training.across.to_vec(),
        };
        if let MapKind::Moments { .. } = kind {
            let Some(dims) = training.dims() else {
                return Err(DualError::NotApplicable(
                    "the training points have different numbers of components".into(),
                ));
            };
            for j in 0..s.ncols() {
                if let Some((c, a)) = map.surface.moments(&col(j)) {
                    if dims == 1 {
                        map.table.push((training.params[j][0], c, a));
                    } else {
                        map.points.push((training.params[j].clone(), c, a));
                    }
                }
            }
            map.table.sort_by(|p, q| p.0.total_cmp(&q.0));
            if map.table.is_empty() && map.points.is_empty() {
                return Err(DualError::NotApplicable(
                    "no training snapshot has contact: the moments map has nothing to fit".into(),
                ));
            }
        }
        let frames: Vec<(f64, f64)> = training.params.iter().map(|p| map.frame(p)).collect();
        match kind {
            MapKind::Translate { interpolation: Interpolation::Nodes } => {
                // One spacing h for every line (the first line's), and each line's nodes at
                // whole multiples of h from the first line's first node.
                let first = &map.surface.x[map.surface.line(0)];
                let h =
                    if first.len() > 1 { (first[first.len() - 1] - first[0]) / (first.len() - 1) as f64 } else { 1.0 };
                let x0 = first.first().copied().unwrap_or(0.0);
                let mut reach = 0usize;
                for l in 0..map.surface.lines() {
                    let xs = &map.surface.x[map.surface.line(l)];
                    let offset = ((xs[0] - x0) / h).round();
                    if offset < 0.0
                        || xs
                            .iter()
                            .enumerate()
                            .any(|(i, x)| (x - (x0 + (offset + i as f64) * h)).abs() > UNIFORM_REL * h)
                    {
                        return Err(DualError::NotApplicable(
                            "whole-node shifts need uniformly spaced slave nodes, one spacing on every line; use interpolation = \"linear\"".into(),
                        ));
                    }
                    reach = reach.max(offset as usize + xs.len());
                }
                let shifts: Vec<i64> = frames.iter().map(|f| (f.0 / h).round() as i64).collect();
                let (lo, hi) = (shifts.iter().copied().min().unwrap_or(0), shifts.iter().copied().max().unwrap_or(0));
                map.grid_step = h;
                // Reference index of node k of a line (counted from the first line's first
                // node) at shift t: k - t + hi, in that line's block of the grid.
                map.grid_start = hi as f64;
                map.line_len = reach + (hi - lo) as usize;
                map.len = map.line_len * map.surface.lines();
            }
            MapKind::Translate { interpolation: Interpolation::Linear { refine } } | MapKind::Moments { refine } => {
                let refine = refine.max(1);
                let h = map.surface.min_spacing();
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                let mut step = f64::INFINITY;
                for (j, &(c, a)) in frames.iter().enumerate() {
                    step = step.min(h / a);
                    let v = col(j);
                    // The support of the snapshot (all nodes for a translation), padded by
                    // two node spacings.
                    let support: Vec<f64> = if matches!(kind, MapKind::Moments { .. }) {
                        map.surface
                            .order
                            .iter()
                            .zip(&map.surface.x)
                            .filter(|(&i, _)| v[i] > 0.0)
                            .map(|(_, &x)| x)
                            .collect()
                    } else {
                        map.surface.x.clone()
                    };
                    if let (Some(&a0), Some(&a1)) = (support.first(), support.last()) {
                        lo = lo.min((a0 - 2.0 * h - c) / a);
                        hi = hi.max((a1 + 2.0 * h - c) / a);
                    }
                }
                if !lo.is_finite() || !hi.is_finite() || !step.is_finite() {
                    return Err(DualError::NotApplicable("no training snapshot to register".into()));
                }
                map.grid_step = step / refine as f64;
                map.grid_start = lo;
                map.line_len = ((hi - lo) / map.grid_step).ceil() as usize + 1;
                map.len = map.line_len * map.surface.lines();
            }
        }
        Ok(map)
    }

    /// `(c, a)` at the parameter point `mu`. The moments map interpolates the training
    /// points' `(c, a)`: piecewise linearly in one parameter (clamped beyond the ends); with
    /// several, level by level along the last component (the training points sharing a value
    /// of it, interpolated in the others the same way), then linearly between the two levels
    /// that bracket `mu`'s last component. On a full tensor grid this is the multilinear
    /// interpolant; a grid with points missing (a leave-one-out fold) interpolates over those
    /// present on each level.
    pub fn frame(&self, mu: &[f64]) -> (f64, f64) {
        match self.kind {
            MapKind::Translate { .. } => (mu.first().copied().unwrap_or(0.0), 1.0),
            MapKind::Moments { .. } if !self.points.is_empty() => {
                let refs: Vec<&(Vec<f64>, f64, f64)> = self.points.iter().collect();
                levels(&refs, mu, self.points[0].0.len())
            }
            MapKind::Moments { .. } => {
                let t = mu.first().copied().unwrap_or(0.0);
                let tab = &self.table;
                let k = tab.partition_point(|p| p.0 <= t);
                if k == 0 {
                    (tab[0].1, tab[0].2)
                } else if k >= tab.len() {
                    (tab[tab.len() - 1].1, tab[tab.len() - 1].2)
                } else {
                    let (p, q) = (tab[k - 1], tab[k]);
                    let th = if q.0 > p.0 { (t - p.0) / (q.0 - p.0) } else { 0.0 };
                    ((1.0 - th) * p.1 + th * q.1, (1.0 - th) * p.2 + th * q.2)
                }
            }
        }
    }

    /// The kind of map.
    pub fn kind(&self) -> MapKind {
        self.kind
    }

    /// Reference grid length.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True for an empty grid.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whole-node offset of line `l`'s first node from the first line's (Nodes only).
    fn offset(&self, l: usize) -> i64 {
        let x0 = self.surface.x.first().copied().unwrap_or(0.0);
        self.surface.x.get(self.surface.starts[l]).map_or(0, |x| ((x - x0) / self.grid_step).round() as i64)
    }

    /// Whole-node shift at `mu` (Nodes only).
    fn shift(&self, mu: &[f64]) -> i64 {
        (self.frame(mu).0 / self.grid_step).round() as i64
    }

    /// Pull the pressure `s` (dual order) at `mu` back to the reference grid.
    pub fn pull(&self, s: &[f64], mu: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        match self.kind {
            MapKind::Translate { interpolation: Interpolation::Nodes } => {
                let t = self.shift(mu);
                for (l, block) in (0..self.surface.lines()).zip(out.chunks_mut(self.line_len.max(1))) {
                    let offset = self.offset(l);
                    for (k, &i) in self.surface.order[self.surface.line(l)].iter().enumerate() {
                        let q = (k as i64 + offset).saturating_sub(t).saturating_add(self.grid_start as i64);
                        if q >= 0 && (q as usize) < self.line_len {
                            block[q as usize] = s[i];
                        }
                    }
                }
            }
            _ => {
                let (c, a) = self.frame(mu);
                for (l, block) in (0..self.surface.lines()).zip(out.chunks_mut(self.line_len.max(1))) {
                    for (k, o) in block.iter_mut().enumerate() {
                        *o = self.surface.eval(l, s, c + a * (self.grid_start + k as f64 * self.grid_step));
                    }
                }
            }
        }
    }

    /// Push the reference vector `r` forward to the nodes (dual order) at `mu`.
    pub fn push(&self, r: &[f64], mu: &[f64], out: &mut [f64]) {
        match self.kind {
            MapKind::Translate { interpolation: Interpolation::Nodes } => {
                let t = self.shift(mu);
                for (l, block) in (0..self.surface.lines()).zip(r.chunks(self.line_len.max(1))) {
                    let offset = self.offset(l);
                    for (k, &i) in self.surface.order[self.surface.line(l)].iter().enumerate() {
                        let q = (k as i64 + offset).saturating_sub(t).saturating_add(self.grid_start as i64);
                        out[i] = if q >= 0 && (q as usize) < self.line_len { block[q as usize] } else { 0.0 };
                    }
                }
            }
            _ => {
                let (c, a) = self.frame(mu);
                let len = self.line_len;
                for (l, block) in (0..self.surface.lines()).zip(r.chunks(len.max(1))) {
                    let line = self.surface.line(l);
                    for (&x, &i) in self.surface.x[line.clone()].iter().zip(&self.surface.order[line]) {
                        let xi = (x - c) / a;
                        let u = (xi - self.grid_start) / self.grid_step;
                        out[i] = if u < 0.0 || u > (len - 1) as f64 {
                            0.0
                        } else {
                            let k0 = (u.floor() as usize).min(len.saturating_sub(2));
                            let th = u - k0 as f64;
                            if k0 + 1 < len {
                                (1.0 - th) * block[k0] + th * block[k0 + 1]
                            } else {
                                block[k0]
                            }
                        };
                    }
                }
            }
        }
    }

    /// `||push(pull(s)) - s|| / ||s||` (None for a zero s).
    pub fn round_trip_error(&self, s: &[f64], mu: &[f64]) -> Option<f64> {
        let norm = norm2(s);
        if norm == 0.0 {
            return None;
        }
        let mut r = vec![0.0; self.len];
        self.pull(s, mu, &mut r);
        let mut back = vec![0.0; s.len()];
        self.push(&r, mu, &mut back);
        Some(back.iter().zip(s).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / norm)
    }
}

/// POD, CPG or neighbours in the reference frame of a [`Map`].
#[derive(Debug, Clone)]
pub struct Registered {
    map: Map,
    inner: Inner,
    /// Reference modes, `len x k` (neighbours: every training snapshot, unit columns; level
    /// PODs: none, each interval's are in `levels`).
    modes: Mat<f64>,
    round_trip: (f64, f64),
    /// Neighbours: the per-query order ([`neighbours`]) and the most columns an m uses.
    neighbours: Option<(Neighbours, usize)>,
    /// Level PODs: the second component's levels and each interval's modes.
    levels: Option<Levels>,
}

/// One POD per interval between consecutive levels of the second parameter component
/// ([`Inner::LevelPod`]). Over ironing-3d-2d's five press levels, the moments map's single POD
/// of every training pressure holds the contact's width at every press at once (1.06 % at
/// m = 5); the POD of the two levels that bracket a point's press holds only the change between
/// them (docs/design-notes.md, "A registered POD per press interval").
#[derive(Debug, Clone)]
pub struct Levels {
    /// The distinct second components of the training points, ascending.
    pub values: Vec<f64>,
    /// Interval `k`'s modes (`[values[k], values[k + 1]]`; one interval over one level).
    pub modes: Vec<Mat<f64>>,
}

impl Levels {
    /// The interval whose modes a point with second component `v` takes: the one that holds it
    /// (the one above an inner level, the last at the top level, the first or last beyond the
    /// levels; NaN: the first).
    pub fn interval(&self, v: f64) -> usize {
        let below = self.values.partition_point(|&x| x <= v);
        below.saturating_sub(1).min(self.modes.len().saturating_sub(1))
    }
}

/// A count of parameter components for a message ([`Training::dims`]).
fn components(dims: Option<usize>) -> String {
    dims.map_or_else(|| "points with differing numbers of components".into(), |d| d.to_string())
}

impl Registered {
    /// Fit the map, pull every training snapshot back, build the inner basis.
    pub fn build(training: &Training<'_>, kind: MapKind, inner: Inner) -> Result<Self, DualError> {
        let map = Map::fit(training, kind)?;
        let s = training.snapshots;
        let (n, count) = (s.nrows(), s.ncols());
        let mut reg = Mat::zeros(map.len(), count);
        let mut col = vec![0.0; n];
        let mut r = vec![0.0; map.len()];
        let (mut sum, mut max, mut counted) = (0.0f64, 0.0f64, 0usize);
        for j in 0..count {
            (0..n).for_each(|i| col[i] = s[(i, j)]);
            map.pull(&col, &training.params[j], &mut r);
            (0..map.len()).for_each(|k| reg[(k, j)] = r[k]);
            if let Some(e) = map.round_trip_error(&col, &training.params[j]) {
                sum += e;
                max = max.max(e);
                counted += 1;
            }
        }
        let mean = if counted > 0 { sum / counted as f64 } else { 0.0 };
        let round_trip = (mean, max);
        let modes = match inner {
            Inner::LevelPod => {
                let dims = training.dims();
                if dims != Some(2) {
                    return Err(DualError::NotApplicable(format!(
                        "basis = \"level-pod\" takes one POD per interval between the levels of a second \
                         parameter component; this scene has {} (use basis = \"pod\")",
                        components(dims)
                    )));
                }
                let mut values: Vec<f64> = training.params.iter().map(|p| p[1]).collect();
                values.sort_by(f64::total_cmp);
                values.dedup_by(|a, b| a.to_bits() == b.to_bits());
                let intervals: Vec<(f64, f64)> = if values.len() < 2 {
                    let Some(&v) = values.first() else {
                        return Err(DualError::NotApplicable("no training points".into()));
                    };
                    vec![(v, v)]
                } else {
                    values.windows(2).map(|w| (w[0], w[1])).collect()
                };
                let mut modes = Vec::with_capacity(intervals.len());
                for (lo, hi) in intervals {
                    // a level is one of the training values itself: the same bits
                    let on = |j: usize, v: f64| training.params[j][1].to_bits() == v.to_bits();
                    let cols: Vec<usize> = (0..count).filter(|&j| on(j, lo) || on(j, hi)).collect();
                    let sub = Mat::from_fn(reg.nrows(), cols.len(), |i, c| reg[(i, cols[c])]);
                    modes.push(pod_modes(sub.as_ref(), training.max_m())?);
                }
                // every read of the modes goes through `modes_of`, which takes them from `levels`
                let none = Mat::zeros(reg.nrows(), 0);
                let levels = Some(Levels { values, modes });
                return Ok(Self { map, inner, modes: none, round_trip, neighbours: None, levels });
            }
            Inner::Pod => pod_modes(reg.as_ref(), training.max_m())?,
            Inner::Cpg => cpg_generators(reg.as_ref(), training.max_m())?,
            Inner::Neighbours => {
                if kind != (MapKind::Translate { interpolation: Interpolation::Nodes }) {
                    return Err(DualError::NotApplicable(
                        "basis = \"neighbours\" orders the training snapshots by the part of a node the whole-node \
                         shift leaves; use map = \"translate\" with interpolation = \"nodes\""
                            .into(),
                    ));
                }
                let dims = training.dims();
                if !matches!(dims, Some(1 | 2)) {
                    return Err(DualError::NotApplicable(format!(
                        "basis = \"neighbours\" orders the training snapshots by the travel and at most one \
                         more parameter component; this scene has {} (use basis = \"cpg\")",
                        components(dims)
                    )));
                }
                for j in 0..count {
                    let norm = reg.col(j).norm_l2();
                    if norm > 0.0 {
                        (0..map.len()).for_each(|k| reg[(k, j)] /= norm);
                    }
                }
                let travels: Vec<f64> = training.params.iter().map(|p| map.frame(p).0).collect();
                let second = (dims == Some(2))
                    .then(|| neighbours::Second::of(&travels, training.params.iter().map(|p| p[1]).collect()));
                let nb = Neighbours::fit(&map, reg.as_ref(), s, travels, second);
                let neighbours = Some((nb, training.max_m()));
                let registered = Self { map, inner, modes: reg, round_trip, neighbours, levels: None };
                return Ok(registered);
            }
        };
        Ok(Self { map, inner, modes, round_trip, neighbours: None, levels: None })
    }

    /// The reference modes a point takes: a level POD's interval's (group `k`), else the one set.
    fn modes_of(&self, group: usize) -> &Mat<f64> {
        match &self.levels {
            Some(lv) => &lv.modes[group.min(lv.modes.len() - 1)],
            None => &self.modes,
        }
    }

    /// The group of modes a point takes ([`Self::modes_of`]): its interval for level PODs, else 0.
    fn group_at(&self, mu: &[f64]) -> usize {
        self.levels.as_ref().map_or(0, |lv| lv.interval(mu.get(1).copied().unwrap_or(f64::NAN)))
    }

    /// The level PODs' levels and modes, if this is one.
    pub fn levels(&self) -> Option<&Levels> {
        self.levels.as_ref()
    }

    /// The reference columns in the order used at `mu` (the first [`DualApprox::size`]): the
    /// modes' own order, or the neighbours' order at `mu`, picked lazily.
    fn order_at(&self, mu: &[f64]) -> Box<dyn Iterator<Item = usize> + '_> {
        match &self.neighbours {
            None => Box::new(0..self.size()),
            Some((nb, _)) => {
                // a vector parameter's second component (a point of one component has none)
                let second = mu.get(1).copied().unwrap_or(0.0);
                Box::new(nb.order(self.map.frame(mu).0, second).take(self.size()))
            }
        }
    }

    /// The reference modes pushed forward to `mu` (n x k), in the order used at `mu`.
    pub fn modes_at(&self, mu: &[f64], n: usize) -> Mat<f64> {
        let order: Vec<usize> = self.order_at(mu).collect();
        let mut out = Mat::zeros(n, order.len());
        let mut v = vec![0.0; n];
        let group = self.group_at(mu);
        for (c, &j) in order.iter().enumerate() {
            self.map.push(self.reference_column(group, j), mu, &mut v);
            (0..n).for_each(|i| out[(i, c)] = v[i]);
        }
        out
    }

    /// Reference column `j` of the modes of `group` ([`Self::modes_of`]).
    fn reference_column(&self, group: usize, j: usize) -> &[f64] {
        self.modes_of(group).col(j).try_as_col_major().expect("contiguous column").as_slice()
    }

    /// The per-query order of a neighbours basis (`None` for POD or CPG).
    pub fn neighbours(&self) -> Option<&Neighbours> {
        self.neighbours.as_ref().map(|(nb, _)| nb)
    }

    /// The fitted map.
    pub fn map(&self) -> &Map {
        &self.map
    }
}

impl DualApprox for Registered {
    fn residuals(&self, s: &[f64], mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        let pushed = self.modes_at(mu, s.len());
        match self.inner {
            Inner::Pod | Inner::LevelPod => SpanPrefix::new(pushed.as_ref()).residuals_of(s, ms, out),
            Inner::Cpg | Inner::Neighbours => ConePrefix::new(pushed.as_ref()).residuals_of(s, ms, out)?,
        }
        Ok(())
    }

    fn size(&self) -> usize {
        if let Some(lv) = &self.levels {
            // every interval holds at least this many
            return lv.modes.iter().map(|m| m.ncols()).min().unwrap_or(0);
        }
        match &self.neighbours {
            None => self.modes.ncols(),
            Some((_, most)) => self.modes.ncols().min(*most),
        }
    }

    fn cone_basis(&self, mu: &[f64], m: usize) -> Option<Mat<f64>> {
        let (cols, k) = self.cone_columns(mu, m)?;
        let n = self.map.surface.x.len();
        Some(Mat::from_fn(n, k, |i, c| cols[i + c * n]))
    }

    /// The first `m` pushed columns that are not zero, pushing no more than it needs.
    fn cone_columns(&self, mu: &[f64], m: usize) -> Option<(Vec<f64>, usize)> {
        if matches!(self.inner, Inner::Pod | Inner::LevelPod) {
            return None;
        }
        let n = self.map.surface.x.len();
        let mut cols: Vec<f64> = Vec::with_capacity(n * m.min(self.size()));
        let mut v = vec![0.0; n];
        let (mut k, group) = (0, self.group_at(mu));
        // only as far as the m-th non-zero column
        for j in self.order_at(mu) {
            if k == m {
                break;
            }
            self.map.push(self.reference_column(group, j), mu, &mut v);
            if v.iter().any(|&x| x != 0.0) {
                cols.extend_from_slice(&v);
                k += 1;
            }
        }
        Some((cols, k))
    }

    fn depends_on_mu(&self) -> bool {
        true
    }

    /// In the reference frame: the pulled-back snapshot's coordinates on the reference modes.
    /// Neighbours: none (no modes fixed across points, as for the dictionary).
    fn coefficients(&self, s: &[f64], mu: &[f64], m: usize) -> Result<Option<(usize, Vec<f64>)>, DualError> {
        if self.neighbours.is_some() {
            return Ok(None);
        }
        let mut r = vec![0.0; self.map.len()];
        self.map.pull(s, mu, &mut r);
        let group = self.group_at(mu);
        let modes = self.modes_of(group);
        let k = m.min(modes.ncols());
        let coords = match self.inner {
            Inner::Pod | Inner::LevelPod => {
                (0..k).map(|l| modes.col(l).iter().zip(&r).map(|(a, b)| a * b).sum()).collect()
            }
            Inner::Cpg | Inner::Neighbours if k == 0 => Vec::new(),
            Inner::Cpg | Inner::Neighbours => {
                let mut p =
                    crate::cone::ConeProjector::new(self.modes.subcols(0, k), crate::cone::NnlsParams::default());
                p.project(&r)?.coeffs
            }
        };
        Ok(Some((group, coords)))
    }

    /// The reference member `modes alpha` (a level POD: group `group`'s modes), pushed forward
    /// to `mu`.
    fn member(&self, group: usize, alpha: &[f64], mu: &[f64], _m: usize, out: &mut [f64]) {
        let mut r = vec![0.0; self.map.len()];
        let modes = self.modes_of(group);
        for (l, &a) in alpha.iter().enumerate() {
            r.iter_mut().zip(modes.col(l).iter()).for_each(|(o, q)| *o += a * q);
        }
        self.map.push(&r, mu, out);
    }

    fn nonnegative(&self) -> bool {
        !matches!(self.inner, Inner::Pod | Inner::LevelPod)
    }

    fn facts(&self) -> Vec<Fact> {
        let mut facts = vec![
            Fact::new("reference_points", None, self.map.len() as f64),
            Fact::new("round_trip_error_mean", None, self.round_trip.0),
            Fact::new("round_trip_error_max", None, self.round_trip.1),
        ];
        if let Some((nb, _)) = &self.neighbours {
            facts.push(Fact::new("neighbour_weight", None, nb.weight()));
            if let Some(sec) = nb.second() {
                facts.push(Fact::new("neighbour_second_scale", None, sec.scale));
            }
        }
        if let Some(lv) = &self.levels {
            facts.push(Fact::new("level_intervals", None, lv.modes.len() as f64));
        }
        facts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dual::DualApprox;

    fn grid(n: usize, h: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 * h).collect()
    }

    /// A bump translated with the parameter, sampled at the nodes.
    fn translated(x: &[f64], params: &[Vec<f64>], f: impl Fn(f64) -> f64) -> Mat<f64> {
        Mat::from_fn(x.len(), params.len(), |i, j| f(x[i] - params[j][0]))
    }

    /// Whole-node shifts of a profile moving by whole nodes: the registered matrix has rank one
    /// and one mode reproduces every snapshot, at training and at new shifts; the round trip
    /// is exact.
    #[test]
    fn a_translated_bump_registers_to_rank_one() {
        let h = 0.1;
        let x = grid(60, h);
        let params: Vec<Vec<f64>> = (0..12).map(|j| vec![j as f64 * 2.0 * h]).collect();
        let bump = |t: f64| (1.0 - ((t - 1.0) / 0.5).powi(2)).max(0.0);
        let s = translated(&x, &params, bump);
        let ms = [1usize, 2];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let kind = MapKind::Translate { interpolation: Interpolation::Nodes };
        let reg = Registered::build(&t, kind, Inner::Pod).expect("build");
        assert_eq!(reg.size(), 1, "registered rank");
        assert_eq!(reg.round_trip.1.to_bits(), 0.0f64.to_bits(), "exact round trip");
        let mu = vec![7.0 * h];
        let q: Vec<f64> = x.iter().map(|&xi| bump(xi - mu[0])).collect();
        let mut out = [0.0; 2];
        reg.residuals(&q, &mu, &ms, &mut out).expect("project");
        assert!(out[0] <= 1e-12 * norm2(&q), "new shift: {out:?}");
        // Without registration the same snapshots need many modes.
        let pod = SpanPrefix::new(pod_modes(s.as_ref(), 12).expect("pod").as_ref());
        assert!(pod.size() > 5);
    }

    /// The abscissae and across coordinates of a staggered contact area: `ny` lines 0.2 apart
    /// of nodes `h` apart up to `(nx - 1) h`, line `l` starting `l % 3` nodes later, in a dual
    /// order scrambled by a fixed permutation.
    fn staggered_area(h: f64, nx: usize, ny: usize) -> (Vec<f64>, Vec<f64>) {
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for l in 0..ny {
            for i in (l % 3)..nx {
                pts.push((i as f64 * h, 0.2 * l as f64));
            }
        }
        let n = pts.len();
        let perm: Vec<usize> = (0..n).map(|k| (k * 37) % n).collect();
        let mut sorted = perm.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>(), "37 is prime to n");
        (perm.iter().map(|&k| pts[k].0).collect(), perm.iter().map(|&k| pts[k].1).collect())
    }

    /// A contact area: lines of slave nodes across the travel, in a scrambled dual order, some
    /// lines starting a few nodes later than others (a staggered structured patch). A profile
    /// `f(x - mu) g(y)` translates along every line at once, so whole-node shifts register it
    /// to rank one (`g(y) f(xi)` for every `mu`), with an exact round trip and a new shift
    /// reproduced to round-off; the moments map (summed over the lines) and linear
    /// interpolation reproduce it to the interpolation's order. On one line the area's maps
    /// give the curve's bits.
    #[test]
    fn a_contact_area_registers_line_by_line() {
        let h = 0.1;
        let (nx, ny) = (40usize, 5usize);
        let (x, y) = staggered_area(h, nx, ny);
        let n = x.len();
        let bump = |t: f64| (1.0 - ((t - 1.0) / 0.5).powi(2)).max(0.0);
        let g = |y: f64| 1.0 + y * y;
        let params: Vec<Vec<f64>> = (0..10).map(|j| vec![j as f64 * 2.0 * h]).collect();
        let s = Mat::from_fn(n, params.len(), |i, j| bump(x[i] - params[j][0]) * g(y[i]));
        let ms = [1usize, 2];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &y, ms: &ms };
        let nodes = MapKind::Translate { interpolation: Interpolation::Nodes };
        let reg = Registered::build(&t, nodes, Inner::Pod).expect("build");
        assert_eq!(reg.map().surface.lines(), ny);
        assert_eq!(reg.size(), 1, "registered rank");
        assert_eq!(reg.round_trip.1.to_bits(), 0.0f64.to_bits(), "exact round trip");
        let mu = vec![7.0 * h];
        let q: Vec<f64> = (0..n).map(|i| bump(x[i] - mu[0]) * g(y[i])).collect();
        let mut out = [0.0; 2];
        reg.residuals(&q, &mu, &ms, &mut out).expect("project");
        // one mode spans the pushed profile: round-off of the projection (1e-12 of the norm)
        assert!(out[0] <= 1e-12 * norm2(&q), "new shift: {out:?}");
        // Linear interpolation (refine 8) on a smooth profile: the round trip of every training
        // snapshot within 1e-2 (first order in the reference spacing, O(h h_ref |p''|) here:
        // h = 0.1, h_ref = h / 8, |p''| = 8, relative to a unit profile: about 1e-2 at most).
        for kind in
            [MapKind::Translate { interpolation: Interpolation::Linear { refine: 8 } }, MapKind::Moments { refine: 8 }]
        {
            let reg = Registered::build(&t, kind, Inner::Pod).expect("build");
            assert!(reg.round_trip.1 < 1e-2, "{}: round trip {:?}", kind.name(), reg.round_trip);
            assert!(reg.map().len().is_multiple_of(ny), "one block per line");
        }
        // The moments map's centre is the profile's: bump centred at 1 + mu (g weights lines,
        // not abscissae), to the tributary quadrature's error (exact for a symmetric bump away
        // from the ends: 1e-12).
        let map = Map::fit(&t, MapKind::Moments { refine: 8 }).expect("fit");
        for p in &params {
            let (c, _) = map.frame(p);
            assert!((c - (1.0 + p[0])).abs() < 1e-12, "centre {c} at {p:?}");
        }
        // One line: the same bits as the curve (no across coordinates).
        let x1 = grid(nx, h);
        let s1 = translated(&x1, &params, bump);
        let flat = vec![0.5; nx];
        for kind in [
            nodes,
            MapKind::Translate { interpolation: Interpolation::Linear { refine: 4 } },
            MapKind::Moments { refine: 4 },
        ] {
            let a = Training { snapshots: s1.as_ref(), params: &params, surface: &x1, across: &[], ms: &ms };
            let b = Training { across: &flat, ..a };
            let (ra, rb) = (
                Registered::build(&a, kind, Inner::Cpg).expect("a"),
                Registered::build(&b, kind, Inner::Cpg).expect("b"),
            );
            let bits = |r: &Registered| {
                r.modes.col_iter().flat_map(|c| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>()
            };
            assert_eq!(bits(&ra), bits(&rb), "{}", kind.name());
        }
    }

    /// Registered neighbours on a contact area (the staggered lines of
    /// [`a_contact_area_registers_line_by_line`], in a scrambled order): a profile
    /// `f(x - c) g(y)` at travels off the node grid (0.137 j, node spacing 0.1, so every
    /// training point leaves its own part of a node). The whole-node shifts keep the area's node
    /// spacing as their step, and at every training point the first neighbour is that snapshot,
    /// pushed back onto itself: the profile stays on every line, so the shifts lose nothing and
    /// the column is the unit snapshot to the rounding of its norm (1e-14 absolute on entries of
    /// at most 1). A second column brackets the point's part of a node from the other side.
    #[test]
    fn a_contact_area_takes_registered_neighbours() {
        let (h, ny) = (0.1, 5usize);
        let (x, y) = staggered_area(h, 40, ny);
        let n = x.len();
        let bump = |t: f64| (1.0 - ((t - 1.0) / 0.5).powi(2)).max(0.0);
        let g = |y: f64| 1.0 + y * y;
        let params: Vec<Vec<f64>> = (0..12).map(|j| vec![0.137 * j as f64]).collect();
        let s = Mat::from_fn(n, params.len(), |i, j| bump(x[i] - params[j][0]) * g(y[i]));
        let ms = [1usize, 2];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &y, ms: &ms };
        let reg = Registered::build(&t, MapKind::Translate { interpolation: Interpolation::Nodes }, Inner::Neighbours)
            .expect("build");
        assert_eq!(reg.map().surface.lines(), ny);
        let nb = reg.neighbours().expect("a neighbours basis");
        assert_eq!(nb.step.to_bits(), h.to_bits(), "the step is the lines' node spacing");
        for (j, mu) in params.iter().enumerate() {
            let (cols, k) = reg.cone_columns(mu, 2).expect("a cone basis");
            assert_eq!(k, 2, "two non-zero columns at {mu:?}");
            let norm = s.col(j).norm_l2();
            for i in 0..n {
                let want = s[(i, j)] / norm;
                assert!((cols[i] - want).abs() <= 1e-14, "training point {j}, node {i}: {} against {want}", cols[i]);
            }
            let second = reg.order_at(mu).nth(1).expect("a second column");
            // Δρ of the second column wrapped into (−½, ½]: on the side Δρ > 0 (the first, the
            // point itself, has Δρ = 0, the side Δρ ≤ 0)
            let mut d = nb.rho[second] - nb.rho[j];
            d -= d.round();
            assert!(
                d > 0.0 || d.to_bits() == (-0.5f64).to_bits(),
                "the second column at {mu:?} is on the side Δρ ≤ 0: {d}"
            );
        }
    }

    /// Linear interpolation: the round trip is first order in the reference spacing (halving
    /// it halves the error) for a smooth profile and for a jump, and the smooth profile's
    /// error is far smaller (the orders of the module doc). The mapped values stay
    /// non-negative.
    #[test]
    fn linear_round_trip_has_the_stated_orders() {
        let h = 0.05;
        let x = grid(121, h);
        let params: Vec<Vec<f64>> = (0..9).map(|j| vec![0.137 * j as f64]).collect();
        let smooth = |t: f64| (-((t - 2.0) / 0.6).powi(2)).exp();
        let steep = |t: f64| if (1.5..2.5).contains(&t) { 1.0 } else { 0.0 };
        let mut ratios = Vec::new();
        for f in [&smooth as &dyn Fn(f64) -> f64, &steep] {
            let s = translated(&x, &params, f);
            let ms = [1usize];
            let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
            // The node-to-reference-to-node round trip of one snapshot at a fractional shift,
            // for reference grids 2 and 4 times finer than the nodes.
            let err = |refine: usize| {
                let map =
                    Map::fit(&t, MapKind::Translate { interpolation: Interpolation::Linear { refine } }).expect("fit");
                let mut worst = 0.0f64;
                for j in 0..params.len() {
                    let col: Vec<f64> = (0..x.len()).map(|i| s[(i, j)]).collect();
                    worst = worst.max(map.round_trip_error(&col, &params[j]).expect("nonzero"));
                    let mut r = vec![0.0; map.len()];
                    map.pull(&col, &params[j], &mut r);
                    assert!(r.iter().all(|&v| v >= 0.0));
                }
                worst
            };
            ratios.push((err(2) / err(4), err(4)));
        }
        // First order: ratio ~2 (1.6 to 2.6: the grids' offsets against the nodes vary with
        // the shift); the smooth error is O(h^2 |p''|) relative to the jump's O(1): with
        // h = 0.05 and a 0.6-wide Gaussian, over 20 times smaller.
        for (what, (ratio, _)) in ["smooth", "steep"].iter().zip(&ratios) {
            assert!((1.6..2.6).contains(ratio), "{what} ratio {ratio}");
        }
        assert!(ratios[0].1 * 20.0 < ratios[1].1, "smooth {} vs steep {}", ratios[0].1, ratios[1].1);
    }

    /// The moments map recovers the half-width of Hertz profiles `sqrt(1 - x^2 / b^2)` (to the
    /// node spacing: the piecewise-constant moments of a sampled profile) and the registered
    /// matrix of dilated Hertz profiles is nearly rank one.
    #[test]
    fn moments_recover_the_hertz_half_width() {
        let x: Vec<f64> = (0..201).map(|i| -1.0 + i as f64 * 0.01).collect();
        let widths: Vec<f64> = (0..10).map(|j| 0.1 + 0.05 * j as f64).collect();
        let params: Vec<Vec<f64>> = widths.iter().map(|b| vec![b * b]).collect();
        let s = Mat::from_fn(x.len(), widths.len(), |i, j| {
            let b = widths[j];
            b * (1.0 - (x[i] / b).powi(2)).max(0.0).sqrt()
        });
        let ms = [1usize, 2, 3];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let map = Map::fit(&t, MapKind::Moments { refine: 4 }).expect("fit");
        for (j, b) in widths.iter().enumerate() {
            let (c, a) = map.frame(&params[j]);
            // 0.01 (one node spacing): the sampled profile's moments differ from the
            // continuous ones by the quadrature error at the square-root edges.
            // c: 1e-9, the asymmetry of the grid -1 + 0.01 i computed in floating point.
            assert!(c.abs() < 1e-9 && (a - b).abs() < 0.01, "b = {b}: c = {c}, a = {a}");
        }
        let reg = Registered::build(&t, MapKind::Moments { refine: 4 }, Inner::Pod).expect("build");
        let mid = vec![0.325f64.powi(2)];
        let q: Vec<f64> = x.iter().map(|&xi| 0.325 * (1.0 - (xi / 0.325).powi(2)).max(0.0).sqrt()).collect();
        let mut out = [0.0; 3];
        reg.residuals(&q, &mid, &ms, &mut out).expect("project");
        // Three registered modes reproduce an unseen width to 2 % (the edge cells of the
        // square-root profile are not a dilation of each other on the discrete grid).
        assert!(out[2] / norm2(&q) < 0.02, "{:?}", out.map(|e| e / norm2(&q)));
    }

    /// With two parameter components the moments map interpolates `(c, a)` level by level:
    /// on a 4 x 3 tensor grid whose training profiles are semi-ellipses centred at
    /// `c = 0.3 mu_1 - 0.1 mu_2` of half-width `a = 0.2 + 0.1 mu_2` (both affine in `mu`), the frame
    /// at points between the grid's is `(c, a)` to the moments' own error (0.01, one node
    /// spacing, as in the one-parameter test); with a grid point left out (a leave-one-out fold)
    /// the frame there is still interpolated (from its level's other points) to that accuracy.
    #[test]
    fn the_moments_map_interpolates_over_a_tensor_grid_with_points_missing() {
        let x: Vec<f64> = (0..301).map(|i| -1.5 + i as f64 * 0.01).collect();
        let (c_of, a_of) = (|m: &[f64]| 0.3 * m[0] - 0.1 * m[1], |m: &[f64]| 0.2 + 0.1 * m[1]);
        let mut params: Vec<Vec<f64>> = Vec::new();
        for j in 0..3 {
            for i in 0..4 {
                params.push(vec![i as f64, j as f64]);
            }
        }
        let profile = |m: &[f64]| -> Vec<f64> {
            let (c, a) = (c_of(m), a_of(m));
            x.iter().map(|&xi| (1.0 - ((xi - c) / a).powi(2)).max(0.0).sqrt()).collect()
        };
        let cols: Vec<Vec<f64>> = params.iter().map(|m| profile(m)).collect();
        let fit = |keep: &[usize]| {
            let s = Mat::from_fn(x.len(), keep.len(), |i, j| cols[keep[j]][i]);
            let ps: Vec<Vec<f64>> = keep.iter().map(|&j| params[j].clone()).collect();
            let ms = [1usize];
            let t = Training { snapshots: s.as_ref(), params: &ps, surface: &x, across: &[], ms: &ms };
            Map::fit(&t, MapKind::Moments { refine: 4 }).expect("fit")
        };
        let all: Vec<usize> = (0..params.len()).collect();
        let map = fit(&all);
        for mu in [[0.5, 0.5], [2.25, 1.75], [1.0, 0.3]] {
            let (c, a) = map.frame(&mu);
            assert!((c - c_of(&mu)).abs() < 0.01 && (a - a_of(&mu)).abs() < 0.01, "{mu:?}: ({c}, {a})");
        }
        // point (1, 1) left out: interpolated along its level mu_2 = 1 from (0, 1) and (2, 1)
        let fold: Vec<usize> = all.iter().copied().filter(|&j| params[j] != vec![1.0, 1.0]).collect();
        let (c, a) = fit(&fold).frame(&[1.0, 1.0]);
        assert!((c - c_of(&[1.0, 1.0])).abs() < 0.01 && (a - a_of(&[1.0, 1.0])).abs() < 0.01, "({c}, {a})");
    }

    #[test]
    fn whole_node_shifts_refuse_a_non_uniform_surface() {
        let x = vec![0.0, 0.1, 0.25, 0.3];
        let s = Mat::from_fn(4, 2, |i, j| (i + j) as f64);
        let params = vec![vec![0.0], vec![0.1]];
        let ms = [1usize];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let Err(e) = Map::fit(&t, MapKind::Translate { interpolation: Interpolation::Nodes }) else {
            panic!("a non-uniform surface was accepted");
        };
        assert!(e.to_string().contains("linear"), "{e}");
    }

    /// Level PODs over two components: at each of three levels of the second component the
    /// profile is its own shape (three independent bumps), moved by whole nodes with the first
    /// component, and between two levels it is the linear blend of theirs. So an interval's POD
    /// of its two levels' snapshots spans every profile between them with two modes, and
    /// reproduces points off the grid to rounding, while one POD of all three levels needs
    /// three. Its groups are the intervals, and a point one component short is refused.
    #[test]
    fn a_pod_per_interval_spans_the_blend_between_two_levels() {
        let (n, h) = (80, 0.05);
        let x = grid(n, h);
        let shapes = [
            |t: f64| (1.0 - (t / 0.3).powi(2)).max(0.0),
            |t: f64| (1.0 - (t / 0.5).powi(2)).max(0.0).powi(2),
            |t: f64| (1.0 - (t / 0.4).abs()).max(0.0),
        ];
        let levels = [1.0, 2.0, 3.0];
        let profile = |xi: f64, mu: &[f64]| {
            let t = (mu[1] - 1.0).clamp(0.0, 2.0);
            let (k, th) = if t >= 1.0 { (1, t - 1.0) } else { (0, t) };
            (1.0 - th) * shapes[k](xi - 1.5 - mu[0]) + th * shapes[k + 1](xi - 1.5 - mu[0])
        };
        // travels on whole nodes, so the shifts are exact
        let params: Vec<Vec<f64>> =
            levels.iter().flat_map(|&v| (0..6).map(move |j| vec![4.0 * h * j as f64, v])).collect();
        let s = Mat::from_fn(n, params.len(), |i, j| profile(x[i], &params[j]));
        let ms = [1usize, 2, 3];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let nodes = MapKind::Translate { interpolation: Interpolation::Nodes };
        let reg = Registered::build(&t, nodes, Inner::LevelPod).expect("level PODs");
        let lv = reg.levels().expect("levels");
        assert_eq!(lv.values, levels.to_vec());
        assert_eq!(lv.modes.len(), 2, "two intervals between three levels");
        // the interval above an inner level, the last at the top, the end ones beyond
        let at: Vec<usize> = [0.0, 1.0, 1.5, 2.0, 2.5, 3.0, 9.0, f64::NAN].iter().map(|&v| lv.interval(v)).collect();
        assert_eq!(at, vec![0, 0, 0, 1, 1, 1, 1, 0]);
        let pod = Registered::build(&t, nodes, Inner::Pod).expect("one POD");
        let mut out = [0.0; 3];
        for mu in [[0.2, 1.3], [0.6, 1.9], [0.35, 2.5], [0.8, 2.05]] {
            let col: Vec<f64> = x.iter().map(|&xi| profile(xi, &mu)).collect();
            let norm = norm2(&col);
            reg.residuals(&col, &mu, &ms, &mut out).expect("residuals");
            // 1e-12: two modes span the blend exactly; what is left is the rounding of the SVD
            assert!(out[1] / norm < 1e-12, "level PODs at {mu:?}: {:e}", out[1] / norm);
            let (group, _) = reg.coefficients(&col, &mu, 2).expect("coefficients").expect("some");
            assert_eq!(group, usize::from(mu[1] > 2.0), "the interval of {mu:?}");
            pod.residuals(&col, &mu, &ms, &mut out).expect("residuals");
            assert!(out[1] / norm > 1e-3, "one POD of all levels needs a third mode at {mu:?}");
        }
        assert!(!reg.nonnegative() && reg.arrays().is_none(), "signed modes: no online solve");
        let one: Vec<Vec<f64>> = params.iter().map(|p| vec![p[0]]).collect();
        let t1 = Training { snapshots: s.as_ref(), params: &one, surface: &x, across: &[], ms: &ms };
        let err = Registered::build(&t1, nodes, Inner::LevelPod).expect_err("one component");
        assert!(err.to_string().contains("level-pod"), "{err}");
    }
}
