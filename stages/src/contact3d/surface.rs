//! The master surface and the node-to-surface pairing rule.
//!
//! The master surface is a set of bilinear quadrilateral facets over the master nodes
//! (master-local ids), each listed in the master body's outward orientation. It carries one
//! continuous normal field: each master node's normal is the normalised sum of the unit
//! normals, at that corner, of the facets around it, with the components normal to each
//! symmetry plane the node lies on removed (the mirror image's facets add the reflected
//! normals); at a point of a facet the normal is the bilinear interpolation of its corners'
//! normals (`m = sum_a N_a n_a`, normalised). A slave at `p` (deformed configuration) is paired
//! by one rule:
//!
//! 1. **Locate.** The closest point of the surface ([`super::facet::closest`]: interior by
//!    Newton, edges exactly) over the facets a uniform grid of their `(x, y)` bounding boxes
//!    offers, searched in growing squares until the best distance lies within the square's
//!    half-side (a facet outside the square is farther horizontally, so farther). Ties within
//!    `1e-12` (relative, plus `1e-14` of the facet size): the lowest facet index.
//! 2. **Project.** Along the normal field onto the facets that share a node with that closest
//!    facet: `p = x(xi, eta) + g m(xi, eta)`, three equations in `(xi, eta, g)` by Newton from
//!    the closest point. The lowest-index facet whose projection lands in its square (within
//!    `1e-10`) wins: `Facet(f)`, supported by its four corners with weights `N_a(xi, eta)`, the
//!    normal `m / |m|` there and the gap `n . (p - x)`. At a shared edge or vertex every facet
//!    around it finds the same point, the same weights on the shared nodes and the same
//!    normal, so the tie rule (lowest index) only picks the facet's name.
//! 3. **Past the surface.** Where no facet takes the projection the slave lies beyond the
//!    surface's free boundary (an edge of a single facet on no symmetry plane, or a vertex on
//!    one) or beyond a symmetry edge. A slave whose closest point lies on a symmetry edge is
//!    paired with that `Edge(a, b)` (`a < b`) or `Vertex(v)`, the normal interpolated from the
//!    nodal normals, as the mirror image's facets would continue the surface. On the free
//!    boundary it is paired likewise while its lateral offset past the boundary
//!    (`|d - (d . n) n|`, `d = p - x_c`, `n` the facet's own normal there) is at most half the
//!    facet's mean edge length, and left unpaired (zero pressure) beyond, as a 2-D slave past
//!    the master polyline's end.
//!
//! Why a projection along a continuous normal and not the closest point: the closest point
//! jumps across a convex edge for a slave just inside the master (from one facet's foot to the
//! other's), and a facet's own normal jumps there too, so a slave at a near-zero gap over an
//! edge flipped between the two facets from one pairing to the next, with gaps of opposite
//! signs, and the re-pairing never settled (ironing-3d at 25 000 and 58 000 dofs, d_x = 3,
//! where the die's nodes sit over the block's). Along the continuous field the gap, its normal
//! and its support change continuously over every edge and vertex. The band at the free
//! boundary does the same for a slave under the die's edge (the largest pressure), which
//! rounding and the die's lateral strain put on either side of it.
//!
//! The gap of a pair is `g = n . (p - x_c)` with `x_c = sum_a w_a x_a` on its support nodes
//! (four, two or one); frozen `(w, n)` make it linear in the displacements.

use std::collections::BTreeMap;

use super::facet::{self, Closest, Spot};
use crate::solid::symmetry::Plane;

/// The canonical feature a slave is paired with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Feature {
    /// The interior of facet `f`.
    Facet(usize),
    /// The edge between master nodes `a < b`.
    Edge(usize, usize),
    /// Master node `v`.
    Vertex(usize),
    /// Nothing: the closest point lies on the surface's free boundary.
    Free,
}

impl Feature {
    /// An identifier of the discrete pairing (for re-pairing detection).
    pub fn id(self) -> u64 {
        match self {
            Feature::Facet(f) => (f as u64) << 2,
            Feature::Edge(a, b) => (((a as u64) << 24 | b as u64) << 2) | 1,
            Feature::Vertex(v) => ((v as u64) << 2) | 2,
            Feature::Free => 3,
        }
    }
}

/// A slave's pair: the feature, the closest point's support (master-local node, weight; `len`
/// of them), the normal and the gap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair3 {
    /// The feature.
    pub feature: Feature,
    /// `(master node, weight)`, the first `len` used.
    pub support: [(usize, f64); 4],
    /// Entries of `support` in use (0 when unpaired).
    pub len: usize,
    /// Unit normal (outward of the master).
    pub normal: [f64; 3],
    /// `n . (p - x_c)`.
    pub gap: f64,
}

impl Pair3 {
    /// Whether the slave is paired.
    pub fn is_paired(&self) -> bool {
        self.feature != Feature::Free
    }

    /// Whether re-pairing a slave from `before` to `self` keeps its gap row continuous: the
    /// same feature, or two paired features whose supports share a master node. The normal
    /// projection is continuous across every shared edge and vertex (module docs: each facet
    /// around them finds the same point, weights and normal there), so a slave whose feature
    /// moves to a neighbouring one has had its row renamed and moved, not replaced; a slave
    /// that becomes unpaired or pairs with a facet sharing no node has jumped.
    pub fn continues(&self, before: &Pair3) -> bool {
        self.feature == before.feature
            || (self.is_paired()
                && before.is_paired()
                && self.support[..self.len].iter().any(|a| before.support[..before.len].iter().any(|b| a.0 == b.0)))
    }

    /// On facet `f` (nodes `q`) at reference coordinates `r`: its four nodes with their
    /// shape-function weights (normal and gap still to set).
    fn on_facet(f: usize, q: [usize; 4], r: [f64; 2]) -> Pair3 {
        let w = crate::q1::shape(r[0], r[1]);
        Pair3 {
            feature: Feature::Facet(f),
            support: [(q[0], w[0]), (q[1], w[1]), (q[2], w[2]), (q[3], w[3])],
            len: 4,
            ..Pair3::UNPAIRED
        }
    }

    /// `(contact dof, coefficient)` of the gap row of slave `s` (of `ns`) paired by this pair:
    /// `g = n . (x_s - sum_a w_a x_a)` over the contact dofs `3 c + j` (slaves, then masters).
    pub fn row(&self, s: usize, ns: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let n = self.normal;
        (0..3).map(move |j| (3 * s + j, n[j])).chain(
            self.support[..self.len].iter().flat_map(move |&(m, w)| (0..3).map(move |j| (3 * (ns + m) + j, -w * n[j]))),
        )
    }

    /// No pair: the slave is free of contact.
    pub const UNPAIRED: Pair3 =
        Pair3 { feature: Feature::Free, support: [(0, 0.0); 4], len: 0, normal: [0.0; 3], gap: 0.0 };
}

/// The master surface: facets over master-local node ids, their adjacency, and the symmetry
/// planes (with the tolerance that puts a node on one).
#[derive(Debug, Clone)]
pub struct MasterSurface {
    facets: Vec<[usize; 4]>,
    /// Facets of each edge `(a, b)`, `a < b`.
    edges: BTreeMap<(usize, usize), Vec<usize>>,
    /// Facets of each master node.
    at_node: Vec<Vec<usize>>,
    /// Per facet, the facets that share a node with it (itself included), ascending: where
    /// step 2 of the rule projects.
    around: Vec<Vec<usize>>,
    /// Per master node: the symmetry planes it lies on (bit k: plane k).
    on_plane: Vec<u8>,
    planes: Vec<Plane>,
    /// The distance that puts a node on a plane.
    tol: f64,
    /// Per master node: whether it lies on a free edge.
    free_node: Vec<bool>,
}

impl MasterSurface {
    /// The surface of `facets` (master-local ids, `< n_nodes`) whose reference node
    /// positions are `x_ref`; `planes` the model's symmetry planes, `tol` the distance that puts
    /// a node on one.
    pub fn new(facets: Vec<[usize; 4]>, x_ref: &[[f64; 3]], planes: &[Plane], tol: f64) -> Self {
        let n = x_ref.len();
        let mut edges: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
        let mut at_node = vec![Vec::new(); n];
        for (f, q) in facets.iter().enumerate() {
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                edges.entry((a.min(b), a.max(b))).or_default().push(f);
                at_node[q[k]].push(f);
            }
        }
        let on_plane: Vec<u8> = x_ref
            .iter()
            .map(|x| {
                planes
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| (x[p.axis] - p.at).abs() <= tol)
                    .fold(0u8, |m, (k, _)| m | (1 << k))
            })
            .collect();
        let mut free_node = vec![false; n];
        for (&(a, b), fs) in &edges {
            if fs.len() == 1 && on_plane[a] & on_plane[b] == 0 {
                free_node[a] = true;
                free_node[b] = true;
            }
        }
        let around = facets
            .iter()
            .map(|q| {
                let mut near: Vec<usize> = q.iter().flat_map(|&v| at_node[v].iter().copied()).collect();
                near.sort_unstable();
                near.dedup();
                near
            })
            .collect();
        Self { facets, edges, at_node, around, on_plane, planes: planes.to_vec(), tol, free_node }
    }

    /// The symmetry planes and the distance that puts a node on one (as given to [`Self::new`]).
    pub fn planes(&self) -> (&[Plane], f64) {
        (&self.planes, self.tol)
    }

    /// The facets.
    pub fn facets(&self) -> &[[usize; 4]] {
        &self.facets
    }

    fn corners(&self, f: usize, xm: &[[f64; 3]]) -> [[f64; 3]; 4] {
        self.facets[f].map(|v| xm[v])
    }

    /// Each master node's normal at positions `xm` (see the module docs).
    pub fn nodal_normals(&self, xm: &[[f64; 3]]) -> Vec<[f64; 3]> {
        (0..self.at_node.len()).map(|v| self.node_normal(v, xm)).collect()
    }

    /// Master node `v`'s normal at positions `xm` (see the module docs).
    fn node_normal(&self, v: usize, xm: &[[f64; 3]]) -> [f64; 3] {
        let normals = self.at_node[v].iter().map(|&g| {
            let k = self.facets[g].iter().position(|&x| x == v).expect("corner");
            facet::normal(&self.corners(g, xm), facet::corner_ref(k))
        });
        self.averaged(normals, self.on_plane[v])
    }

    /// The normalised sum of `normals`, without the components normal to the planes in `mask`.
    fn averaged(&self, normals: impl Iterator<Item = [f64; 3]>, mask: u8) -> [f64; 3] {
        let mut s = [0.0; 3];
        for n in normals {
            for c in 0..3 {
                s[c] += n[c];
            }
        }
        for (k, p) in self.planes.iter().enumerate() {
            if mask & (1 << k) != 0 {
                s[p.axis] = 0.0;
            }
        }
        facet::unit(s)
    }

    /// Whether the slave at `p`, whose closest point `c` on facet `f` lies on the free
    /// boundary, is past the boundary's band (module docs, rule 4).
    fn past(&self, f: usize, c: &Closest, p: [f64; 3], xm: &[[f64; 3]]) -> bool {
        let xf = self.corners(f, xm);
        let n = facet::normal(&xf, facet::spot_ref(c.spot));
        let d = facet::sub(p, c.x);
        let dn = facet::dot(d, n);
        let lateral = facet::sub(d, [dn * n[0], dn * n[1], dn * n[2]]);
        let size = (0..4)
            .map(|k| facet::dot(facet::sub(xf[(k + 1) % 4], xf[k]), facet::sub(xf[(k + 1) % 4], xf[k])).sqrt())
            .sum::<f64>()
            / 4.0;
        facet::dot(lateral, lateral).sqrt() > 0.5 * size
    }

    /// The canonical pair of the closest point `c` found on facet `f` for the slave at `p`;
    /// `xm` the master positions, `nodal` the master nodes' normals.
    fn pair_of(&self, f: usize, c: &Closest, p: [f64; 3], xm: &[[f64; 3]], nodal: &[[f64; 3]]) -> Pair3 {
        let q = self.facets[f];
        let mut pair = Pair3::UNPAIRED;
        match c.spot {
            Spot::Interior(r) => pair = Pair3::on_facet(f, q, r),
            Spot::Edge(e, t) => {
                let (a, b) = (q[e], q[(e + 1) % 4]);
                let key = (a.min(b), a.max(b));
                if self.edges[&key].len() == 1 && self.on_plane[a] & self.on_plane[b] == 0 && self.past(f, c, p, xm) {
                    return Pair3::UNPAIRED;
                }
                pair.feature = Feature::Edge(key.0, key.1);
                pair.len = 2;
                pair.support[0] = (a, 1.0 - t);
                pair.support[1] = (b, t);
            }
            Spot::Corner(k) => {
                let v = q[k];
                if self.free_node[v] && self.past(f, c, p, xm) {
                    return Pair3::UNPAIRED;
                }
                pair.feature = Feature::Vertex(v);
                pair.len = 1;
                pair.support[0] = (v, 1.0);
            }
        }
        let mut n = [0.0; 3];
        for &(v, w) in &pair.support[..pair.len] {
            for c in 0..3 {
                n[c] += w * nodal[v][c];
            }
        }
        pair.normal = facet::unit(n);
        pair.gap = facet::dot(pair.normal, facet::sub(p, c.x));
        pair
    }
}

/// A uniform grid over the facets' `(x, y)` bounding boxes at one configuration of the master
/// nodes, for the closest-point search; rebuilt whenever the master moves.
#[derive(Debug, Clone)]
pub struct FacetGrid {
    origin: [f64; 2],
    cell: f64,
    dims: [usize; 2],
    /// Facets of cell `(i, j)` at `start[j * dims[0] + i]..start[.. + 1]`.
    start: Vec<usize>,
    items: Vec<usize>,
    /// Mean facet extent (the tie tolerance's length).
    size: f64,
    /// Each facet's bounding box `[x_min, y_min, x_max, y_max, z_min, z_max]` (the grid
    /// indexes the first four).
    boxes: Vec<[f64; 6]>,
    /// Each facet's [`Cone`] (where a normal projection onto it can come from), once asked for.
    cones: Vec<Option<Cone>>,
    /// Whether the search's index (`origin` … `boxes`) is built.
    indexed: bool,
    stamp: Vec<u32>,
    round: u32,
    /// The master nodes' normals at this configuration, those with `have_normal` computed.
    nodal: Vec<[f64; 3]>,
    have_normal: Vec<bool>,
    /// [`Self::pair`]'s scratch: the facets found `(distance, facet, closest point)`.
    found: Vec<(f64, usize, Closest)>,
    /// The facets of the current square by their boxes' horizontal distance.
    boxed: Vec<(f64, usize)>,
}

impl FacetGrid {
    /// The grid of `surface`'s facets at master positions `xm`. Nothing is computed here: the
    /// search's index on the first search ([`Self::pair_located`]), a node's normal and a
    /// facet's cone when a pairing first reads them. A query's later linearisations pair most
    /// slaves without a search ([`Self::pair_at`]) and near a part of the surface only, so
    /// building all of it per linearisation was a fifth of ironing-3d's online solve. Every
    /// method must be called with the positions `xm` given here.
    pub fn new(surface: &MasterSurface, xm: &[[f64; 3]]) -> Self {
        let (nf, nn) = (surface.facets.len(), surface.at_node.len());
        debug_assert_eq!(xm.len(), nn, "a position per master node");
        Self {
            origin: [0.0; 2],
            cell: 1.0,
            dims: [1, 1],
            start: Vec::new(),
            items: Vec::new(),
            size: 1.0,
            boxes: Vec::new(),
            cones: vec![None; nf],
            indexed: false,
            stamp: vec![0; nf],
            round: 0,
            nodal: vec![[0.0; 3]; nn],
            have_normal: vec![false; nn],
            found: Vec::new(),
            boxed: Vec::new(),
        }
    }

    /// The search's index at `xm`: each facet's `(x, y)` bounding box, the mean facet extent
    /// (the cell size), and the facets of each cell.
    fn index(&mut self, surface: &MasterSurface, xm: &[[f64; 3]]) {
        if self.indexed {
            return;
        }
        self.indexed = true;
        let nf = surface.facets.len();
        let boxes: Vec<[f64; 6]> = (0..nf).map(|f| facet_box(&surface.corners(f, xm))).collect();
        let size =
            if nf > 0 { boxes.iter().map(|b| (b[2] - b[0]).max(b[3] - b[1])).sum::<f64>() / nf as f64 } else { 1.0 };
        let cell = if size > 0.0 && size.is_finite() { size } else { 1.0 };
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for b in &boxes {
            lo = [lo[0].min(b[0]), lo[1].min(b[1])];
            hi = [hi[0].max(b[2]), hi[1].max(b[3])];
        }
        if nf == 0 {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        let dims = [((hi[0] - lo[0]) / cell).floor() as usize + 1, ((hi[1] - lo[1]) / cell).floor() as usize + 1];
        let cell_of = |x: f64, o: f64, d: usize| (((x - o) / cell).floor().max(0.0) as usize).min(d - 1);
        let mut count = vec![0usize; dims[0] * dims[1] + 1];
        let each = |b: &[f64; 6], f: &mut dyn FnMut(usize)| {
            for j in cell_of(b[1], lo[1], dims[1])..=cell_of(b[3], lo[1], dims[1]) {
                for i in cell_of(b[0], lo[0], dims[0])..=cell_of(b[2], lo[0], dims[0]) {
                    f(j * dims[0] + i);
                }
            }
        };
        for b in &boxes {
            each(b, &mut |c| count[c + 1] += 1);
        }
        for c in 0..dims[0] * dims[1] {
            count[c + 1] += count[c];
        }
        let mut fill = count.clone();
        let mut items = vec![0; count[dims[0] * dims[1]]];
        for (f, b) in boxes.iter().enumerate() {
            each(b, &mut |c| {
                items[fill[c]] = f;
                fill[c] += 1;
            });
        }
        (self.origin, self.cell, self.dims, self.start, self.items, self.size, self.boxes) =
            (lo, cell, dims, count, items, size, boxes);
    }

    /// The normals of facet `f`'s corners, computed where not yet.
    fn normals_of(&mut self, surface: &MasterSurface, xm: &[[f64; 3]], f: usize) {
        for v in surface.facets[f] {
            if !self.have_normal[v] {
                self.nodal[v] = surface.node_normal(v, xm);
                self.have_normal[v] = true;
            }
        }
    }

    /// Facet `g`'s cone, computed where not yet (with its corners' normals).
    fn cone(&mut self, surface: &MasterSurface, xm: &[[f64; 3]], g: usize) -> Cone {
        if let Some(c) = self.cones[g] {
            return c;
        }
        self.normals_of(surface, xm, g);
        let c = Cone::of(&surface.corners(g, xm), &surface.facets[g].map(|v| self.nodal[v]));
        self.cones[g] = Some(c);
        c
    }

    /// The pair of the slave at `p` (see the module docs).
    pub fn pair(&mut self, surface: &MasterSurface, xm: &[[f64; 3]], p: [f64; 3]) -> Pair3 {
        self.search(surface, xm, p, None, None).0
    }

    /// The pair of the slave at `p` from the proof `at` of an earlier search, after the slave and
    /// the master nodes moved by at most `moved` in all since (see [`Located`]): the search's
    /// answer without the search, or `None` where the proof does not decide it.
    ///
    /// Every facet of `at`'s near set is measured (the search's arithmetic); every other facet
    /// lies beyond `others - moved`. The search's tie set is every facet within
    /// `best (1 + 1e-12) + 1e-14 size` of the least distance `best`, at the current facet extent
    /// `size`, which lies within `2 moved` of `at.size` (each box's sides move by at most twice
    /// the largest master move). A measured facet within `best (1 + 1e-12)` is in it whatever
    /// the extent; one beyond `hi = best (1 + 1e-9) + 1e-9 (at.size + 2 moved)`, a thousand
    /// times the search's tolerance for the rounding of the distances and of the extent, is
    /// out. So when no measured facet lies between the two and every other facet lies beyond
    /// `hi`, the search's least distance and tie set are these, it locates their lowest index,
    /// and step 2 of the rule from that facet's closest point (the search would have measured
    /// it with the same arithmetic) is the pair [`Self::pair`] returns, bit for bit.
    pub fn pair_near(
        &mut self,
        surface: &MasterSurface,
        xm: &[[f64; 3]],
        p: [f64; 3],
        at: &Located,
        moved: f64,
    ) -> Option<Pair3> {
        if !moved.is_finite() {
            return None;
        }
        self.found.clear();
        let hi_of = |best: f64| best * (1.0 + 1e-9) + 1e-9 * (at.size + 2.0 * moved);
        // the located facet first: its distance bounds the others', which are measured only
        // where their box reaches within `hi` of it (a facet's distance is at least its box's)
        let cl = facet::closest(&surface.corners(at.facet, xm), p);
        let mut best = cl.d2.sqrt();
        self.found.push((best, at.facet, cl));
        for &f in at.near() {
            if f == at.facet {
                continue;
            }
            let xf = surface.corners(f, xm);
            if box_distance(&facet_box(&xf), p) > hi_of(best) {
                continue;
            }
            let cl = facet::closest(&xf, p);
            let d = cl.d2.sqrt();
            if d < best {
                best = d;
            }
            self.found.push((d, f, cl));
        }
        let (lo, hi) = (best * (1.0 + 1e-12), hi_of(best));
        // (a NaN distance or bound is neither clear nor decided: refused)
        let clear = at.others - moved > hi;
        if !clear || self.found.iter().any(|x| !(x.0 <= lo || x.0 > hi)) {
            return None;
        }
        let (_, f, cl) = self.found.iter().filter(|x| x.0 <= lo).min_by_key(|x| x.1).copied()?;
        Some(self.finish(surface, xm, p, f, cl))
    }

    /// [`Self::pair`], and what its search proves ([`Located`]; `None` without facets). `hint`:
    /// a facet likely to be near (the slave's last one), measured first so that its distance
    /// prunes the others; the pair is the same with any hint or none. `reach`: the proof's near
    /// set holds the facets within `reach` facet extents of the least distance (the search
    /// measures them all, and prunes only beyond), so that [`Self::pair_near`] decides after
    /// moves up to about half of that; 0 keeps the search's own measurements.
    pub fn pair_located(
        &mut self,
        surface: &MasterSurface,
        xm: &[[f64; 3]],
        p: [f64; 3],
        hint: Option<usize>,
        reach: f64,
    ) -> (Pair3, Option<Located>) {
        self.search(surface, xm, p, hint, Some(reach))
    }

    /// The search of [`Self::pair_located`]; its proof only with a `reach` (the full-order
    /// solver's pairings, [`Self::pair`], keep none).
    fn search(
        &mut self,
        surface: &MasterSurface,
        xm: &[[f64; 3]],
        p: [f64; 3],
        hint: Option<usize>,
        reach: Option<f64>,
    ) -> (Pair3, Option<Located>) {
        if surface.facets.is_empty() {
            return (Pair3::UNPAIRED, None);
        }
        self.index(surface, xm);
        self.round = self.round.wrapping_add(1);
        if self.round == 0 {
            self.stamp.fill(0);
            self.round = 1;
        }
        self.found.clear();
        // Start from the square that reaches the grid: every facet is at least the horizontal
        // distance to the grid's box away, so a smaller square finds nothing (the search's
        // answer does not depend on where it starts, only on stopping once `best <= r`).
        let hi = [self.origin[0] + self.cell * self.dims[0] as f64, self.origin[1] + self.cell * self.dims[1] as f64];
        let (gx, gy) =
            ((self.origin[0] - p[0]).max(p[0] - hi[0]).max(0.0), (self.origin[1] - p[1]).max(p[1] - hi[1]).max(0.0));
        let mut r = self.cell + (gx * gx + gy * gy).sqrt();
        // The closest point of a facet is no nearer than its bounding box: a facet whose box
        // lies beyond the tie tolerance of the best distance so far cannot be the closest nor
        // tie with it, and is not measured (the same answer, bit for bit: the best distance and
        // the tie set are those of the measured facets either way, whichever facet was measured
        // first).
        let mut best_so_far = f64::INFINITY;
        if let Some(f) = hint.filter(|&f| f < self.stamp.len()) {
            self.stamp[f] = self.round;
            let cl = facet::closest(&surface.corners(f, xm), p);
            best_so_far = cl.d2.sqrt();
            self.found.push((best_so_far, f, cl));
        }
        // the nearest box of a facet left unmeasured, and whether the last square held every cell
        let mut pruned = f64::INFINITY;
        let mut everything;
        let tie_of = |best: f64, size: f64| best * (1.0 + 1e-12) + 1e-14 * size;
        // beyond the tie tolerance by this much a facet is neither measured nor in the near set
        let (proof, reach) = (reach.is_some(), reach.unwrap_or(0.0) * self.size);
        let cell_of =
            |x: f64, o: f64, d: usize, cell: f64| ((x - o) / cell).floor().clamp(0.0, (d - 1) as f64) as usize;
        let best = loop {
            let (i0, i1) = (
                cell_of(p[0] - r, self.origin[0], self.dims[0], self.cell),
                cell_of(p[0] + r, self.origin[0], self.dims[0], self.cell),
            );
            let (j0, j1) = (
                cell_of(p[1] - r, self.origin[1], self.dims[1], self.cell),
                cell_of(p[1] + r, self.origin[1], self.dims[1], self.cell),
            );
            // the square's facets not met before, nearest box first; measured until the next
            // box lies beyond the tie tolerance of the best distance (then so do the rest, now
            // and in any later round, as the best only decreases)
            self.boxed.clear();
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let c = j * self.dims[0] + i;
                    for &f in &self.items[self.start[c]..self.start[c + 1]] {
                        if self.stamp[f] != self.round {
                            self.stamp[f] = self.round;
                            let boxed = box_distance(&self.boxes[f], p);
                            if boxed > tie_of(best_so_far, self.size) + reach {
                                // beyond the best so far already: not measured (see above)
                                pruned = pruned.min(boxed);
                            } else {
                                self.boxed.push((boxed, f));
                            }
                        }
                    }
                }
            }
            self.boxed.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for &(boxed, f) in &self.boxed {
                if boxed > tie_of(best_so_far, self.size) + reach {
                    // this facet and the rest of the square's new ones are not measured: no
                    // nearer than their boxes
                    pruned = pruned.min(boxed);
                    break;
                }
                let cl = facet::closest(&surface.corners(f, xm), p);
                let d = cl.d2.sqrt();
                best_so_far = best_so_far.min(d);
                self.found.push((d, f, cl));
            }
            let best = self.found.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
            everything = i0 == 0 && j0 == 0 && i1 == self.dims[0] - 1 && j1 == self.dims[1] - 1;
            if best + reach <= r || everything {
                break best;
            }
            r *= 2.0;
        };
        let tie = tie_of(best, self.size);
        let (_, f, cl) = self.found.iter().filter(|x| x.0 <= tie).min_by_key(|x| x.1).copied().expect("a facet");
        if !proof {
            return (self.finish(surface, xm, p, f, cl), None);
        }
        // the near set: the measured facets within `reach` of the tie tolerance, nearest first
        // (at most NEAR, the located one among them); every other facet is measured, pruned by
        // its box, or outside the last square (whose boxes lie more than `r` away horizontally)
        let order = &mut self.boxed;
        order.clear();
        order.extend(self.found.iter().map(|x| (x.0, x.1)));
        order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let within = order.iter().take_while(|x| x.0 <= tie + reach).count().clamp(1, NEAR);
        let mut near = [0; NEAR];
        for (k, x) in order[..within].iter().enumerate() {
            near[k] = x.1;
        }
        if !near[..within].contains(&f) {
            near[within - 1] = f;
        }
        let measured =
            order.iter().filter(|x| !near[..within].contains(&x.1)).map(|x| x.0).fold(f64::INFINITY, f64::min);
        let others = measured.min(pruned).min(if everything { f64::INFINITY } else { r });
        let located = Located { facet: f, near, len: within, best, others, size: self.size };
        (self.finish(surface, xm, p, f, cl), Some(located))
    }

    /// Step 2 of the rule (module docs) for the slave at `p` located on facet `f` with closest
    /// point `cl` (`self.found` holding the closest points the search measured).
    fn finish(&mut self, surface: &MasterSurface, xm: &[[f64; 3]], p: [f64; 3], f: usize, cl: Closest) -> Pair3 {
        // the normal projection onto the facets around the closest one, lowest index first
        for &g in &surface.around[f] {
            if !self.cone(surface, xm, g).may_project(p) {
                // no point of the facet has `p` on its normal line (`project` would fail)
                continue;
            }
            // the closest point of a facet the search measured is reused as the projection's
            // start (the same function of the same corners and point: the same bits)
            let start = self.found.iter().find(|x| x.1 == g).map(|x| x.2);
            if let Some(pair) = surface.project(g, p, xm, &self.nodal, start) {
                return pair;
            }
        }
        self.normals_of(surface, xm, f);
        surface.pair_of(f, &cl, p, xm, &self.nodal)
    }
}

/// The most facets a search's proof keeps measured ([`Located`]'s near set).
pub const NEAR: usize = 6;

/// The near set's reach (in facet extents past the least distance) of the searches whose proofs
/// the online solve keeps ([`FacetGrid::pair_located`]): a slave over a vertex of the master
/// (hertz-3d's, where the two meshes match) ties the facets around it, and a slave near an
/// edge nearly ties two, so a proof of the located facet alone fails at the first move. The
/// facets within a hundredth of a facet extent are measured again instead: a proof that
/// survives moves of about half of that (1.3e-4 on hertz-3d, whose queries' first
/// linearisations lay up to 1e-4 from their nearest samples' positions; measured). A reach of 0.1
/// measured more facets per proof (4.9 against 4.3, before the near facets' box test) and was
/// no faster.
pub const ONLINE_REACH: f64 = 0.01;

/// What a search of [`FacetGrid::pair_located`] proves: the facet it located, its distance
/// `best`, the near set (the facets it measured within its reach of `best`, at most [`NEAR`],
/// the located one among them), a lower bound `others` on the distance of every facet outside
/// the near set (measured, pruned by its bounding box, or outside the searched square), at the
/// grid's facet extent `size`.
///
/// A facet's points are convex combinations of its corners (bilinear weights are non-negative
/// and sum to one), so when the slave moves by `a` and every master node by at most `b`, each
/// facet's distance changes by at most `a + b`. After moves adding up to `moved`, every facet
/// outside the near set lies beyond `others - moved`: measuring the near set again decides the
/// search's answer while that stays beyond the near set's least distance by more than a tie
/// tolerance ([`FacetGrid::pair_near`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// The located facet.
    pub facet: usize,
    /// The near set, `near[..len]`.
    near: [usize; NEAR],
    len: usize,
    /// The located facet's distance.
    pub best: f64,
    /// A lower bound on the distance of every facet outside the near set.
    pub others: f64,
    /// The grid's mean facet extent.
    pub size: f64,
}

impl Located {
    /// The near set: the facets the proof measures again.
    pub fn near(&self) -> &[usize] {
        &self.near[..self.len]
    }
}

/// Where the normal projection onto a facet can come from: every point `p = x + g m` with `x`
/// on the facet and `m = sum_a N_a n_a` its interpolated corner normals. Let `nu` be the unit
/// axis (the corners' mean normal), `c` the corners' centroid, `cos theta = min_a n_a . nu` and
/// `P` the projection onto the plane normal to `nu`. For weights `N_a >= 0` summing to 1, `x` is
/// a convex combination of the corners, `m . nu >= cos theta` and `|m| <= 1`, so:
///
/// - `|(x - c) . nu| <= h = max_a |(x_a - c) . nu|`, hence `|g| cos theta <= |(p - c) . nu| + h`;
/// - `|P m| <= sin theta`, hence `|g P m| <= tan theta (|(p - c) . nu| + h)`;
/// - `P (x - c)` lies in the convex hull `Q` of the corners' `P (x_a - c)`.
///
/// So a point with `dist(P (p - c), Q) > tan theta (|(p - c) . nu| + h)` has no projection on the
/// facet. The test first asks the coarser ball form of the same bound (`Q` and `h` replaced by
/// the ball of radius `rho` about `c` that holds the facet, a few operations), then the hull
/// form, which excludes the neighbouring facets of a slave that lies over the facet's interior
/// (the ball admitted them within a third of a facet of their edge: 0.46 failed projections per
/// pairing on ironing-3d). The radii, `h` and the cosine carry a margin of 1e-6 (of `rho`) for
/// the projection's slack outside the square (`PROJECTION_SLACK`, where weights are down to
/// -1e-10) and the rounding of the test: it only skips projections that would fail, it never
/// changes a pair.
#[derive(Debug, Clone, Copy)]
struct Cone {
    centre: [f64; 3],
    rho: f64,
    nu: [f64; 3],
    /// `tan theta`, or infinity when the corners' normals span a half-space or more.
    tan: f64,
    /// An orthonormal basis of the plane normal to `nu`, the corners in it (relative to
    /// `centre`), the height `h` (with its margin) and the margin of the hull distance.
    e1: [f64; 3],
    e2: [f64; 3],
    hull: [[f64; 2]; 4],
    h: f64,
    slack: f64,
}

impl Cone {
    fn of(xf: &[[f64; 3]; 4], nf: &[[f64; 3]; 4]) -> Self {
        let centre = std::array::from_fn(|k| 0.25 * (xf[0][k] + xf[1][k] + xf[2][k] + xf[3][k]));
        let rho =
            xf.iter().map(|x| facet::dot(facet::sub(*x, centre), facet::sub(*x, centre)).sqrt()).fold(0.0, f64::max);
        let sum: [f64; 3] = std::array::from_fn(|k| nf[0][k] + nf[1][k] + nf[2][k] + nf[3][k]);
        let len = facet::dot(sum, sum).sqrt();
        let nu = if len > 0.0 { sum.map(|v| v / len) } else { [0.0; 3] };
        // the bound needs unit corner normals (normalised averages; a degenerate one, none)
        let units = nf.iter().all(|n| (facet::dot(*n, *n) - 1.0).abs() <= 1e-9);
        let cos = nf.iter().map(|n| facet::dot(*n, nu)).fold(f64::INFINITY, f64::min) - 1e-6;
        let tan = if units && cos > 0.0 && len > 0.0 { (1.0 - cos * cos).max(0.0).sqrt() / cos } else { f64::INFINITY };
        // the plane normal to nu: e1 across nu's smallest component, e2 = nu x e1
        let k = (0..3).min_by(|&a, &b| nu[a].abs().total_cmp(&nu[b].abs())).unwrap_or(0);
        let mut axis = [0.0; 3];
        axis[k] = 1.0;
        let e1 = facet::unit(facet::cross(nu, axis));
        let e2 = facet::cross(nu, e1);
        let rel = xf.map(|x| facet::sub(x, centre));
        let hull = rel.map(|r| [facet::dot(r, e1), facet::dot(r, e2)]);
        let slack = 1e-6 * rho;
        let h = rel.iter().map(|r| facet::dot(*r, nu).abs()).fold(0.0, f64::max) + slack;
        Self { centre, rho: rho * (1.0 + 1e-6), nu, tan, e1, e2, hull, h, slack }
    }

    /// Whether a normal projection of `p` onto the facet may exist: the ball form, then the hull
    /// form of the bound.
    fn may_project(&self, p: [f64; 3]) -> bool {
        if !self.ball_admits(p) {
            return false;
        }
        if !self.tan.is_finite() {
            return true;
        }
        let d = facet::sub(p, self.centre);
        let along = facet::dot(d, self.nu);
        let q = [facet::dot(d, self.e1), facet::dot(d, self.e2)];
        hull_distance(q, &self.hull) <= self.tan * (along.abs() + self.h) + self.slack
    }

    /// The ball form of the bound alone: whether `p` lies within the double cone about the ball of
    /// radius `rho` (always, when the normals' spread has no finite bound).
    fn ball_admits(&self, p: [f64; 3]) -> bool {
        if !self.tan.is_finite() {
            return true;
        }
        let d = facet::sub(p, self.centre);
        let along = facet::dot(d, self.nu);
        let perp = (facet::dot(d, d) - along * along).max(0.0).sqrt();
        perp - self.rho <= self.tan * (along.abs() + self.rho)
    }
}

/// The bounding box `[x_min, y_min, x_max, y_max, z_min, z_max]` of a facet's corners `xf`
/// (the search's index keeps the first four per facet).
fn facet_box(xf: &[[f64; 3]; 4]) -> [f64; 6] {
    let (inf, ninf) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut b = [inf, inf, ninf, ninf, inf, ninf];
    for x in xf {
        b = [b[0].min(x[0]), b[1].min(x[1]), b[2].max(x[0]), b[3].max(x[1]), b[4].min(x[2]), b[5].max(x[2])];
    }
    b
}

/// The distance from `p` to the box `b` ([`facet_box`]): no more than the distance to any point
/// of the facet (its points are convex combinations of the corners).
fn box_distance(b: &[f64; 6], p: [f64; 3]) -> f64 {
    let (dx, dy, dz) = (
        (b[0] - p[0]).max(p[0] - b[2]).max(0.0),
        (b[1] - p[1]).max(p[1] - b[3]).max(0.0),
        (b[4] - p[2]).max(p[2] - b[5]).max(0.0),
    );
    (dx * dx + dy * dy + dz * dz).sqrt()
}

/// The distance from `q` to the convex hull of the four points `pts` (0 inside): inside when in
/// one of the four triangles of three of them (a degenerate triangle counts the points on its
/// line), else the nearest of the six segments between them (the hull's edges are among them,
/// and the others lie inside it).
fn hull_distance(q: [f64; 2], pts: &[[f64; 2]; 4]) -> f64 {
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    for t in [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] {
        let (a, b, c) = (pts[t[0]], pts[t[1]], pts[t[2]]);
        let s = [cross(a, b, q), cross(b, c, q), cross(c, a, q)];
        if s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0) {
            return 0.0;
        }
    }
    let mut best = f64::INFINITY;
    for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        let (a, b) = (pts[i], pts[j]);
        let ab = [b[0] - a[0], b[1] - a[1]];
        let l2 = ab[0] * ab[0] + ab[1] * ab[1];
        let t = if l2 > 0.0 { (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0) } else { 0.0 };
        let (dx, dy) = (a[0] + t * ab[0] - q[0], a[1] + t * ab[1] - q[1]);
        best = best.min((dx * dx + dy * dy).sqrt());
    }
    best
}

/// Newton steps of the normal projection.
const PROJECTION_STEPS: usize = 25;

/// A projection whose last Newton step is at most this (reference units) has converged: the
/// steps stall at the rounding of the residual, about 1e-16 of the facet's size over the
/// Jacobian's smallest singular value.
const PROJECTION_CONVERGED: f64 = 1e-11;

/// How far outside its square a facet's normal projection may land and still count (reference
/// units): rounding at a shared edge, where the neighbouring facet gives the same point.
const PROJECTION_SLACK: f64 = 1e-10;

impl MasterSurface {
    /// The normal projection of `p` onto facet `f` (module docs, rule 1): `(xi, eta, g)` with
    /// `p = x(xi, eta) + g m(xi, eta)`, `m = sum_a N_a n_a` the interpolated nodal normals, by
    /// Newton on the three equations from the closest point's coordinates; `None` unless it
    /// converges inside the square (within [`PROJECTION_SLACK`]).
    /// `start`: the facet's closest point to `p` if the caller has it (else it is computed).
    fn project(
        &self,
        f: usize,
        p: [f64; 3],
        xm: &[[f64; 3]],
        nodal: &[[f64; 3]],
        start: Option<Closest>,
    ) -> Option<Pair3> {
        let q = self.facets[f];
        let xf = self.corners(f, xm);
        let nf = q.map(|v| nodal[v]);
        let c = start.unwrap_or_else(|| facet::closest(&xf, p));
        let mut r = facet::spot_ref(c.spot);
        let interp = |r: [f64; 2]| -> ([f64; 3], [f64; 3], [f64; 3], [f64; 3]) {
            let dn = crate::q1::shape_derivatives(r[0], r[1]);
            let (mut m, mut mx, mut my) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            let w = crate::q1::shape(r[0], r[1]);
            for a in 0..4 {
                for k in 0..3 {
                    m[k] += w[a] * nf[a][k];
                    mx[k] += dn[a][0] * nf[a][k];
                    my[k] += dn[a][1] * nf[a][k];
                }
            }
            (m, mx, my, facet::point(&xf, r))
        };
        let (m0, _, _, x0) = interp(r);
        let mut g = facet::dot(facet::sub(p, x0), m0) / facet::dot(m0, m0).max(f64::MIN_POSITIVE);
        let mut last_step = f64::INFINITY;
        for _ in 0..PROJECTION_STEPS {
            let previous = last_step;
            let (m, mx, my, x) = interp(r);
            let (tx, ty) = facet::tangents(&xf, r);
            // residual G = p - x - g m; Jacobian columns dG/dxi, dG/deta, dG/dg
            let res = [p[0] - x[0] - g * m[0], p[1] - x[1] - g * m[1], p[2] - x[2] - g * m[2]];
            let cols = [
                [-tx[0] - g * mx[0], -tx[1] - g * mx[1], -tx[2] - g * mx[2]],
                [-ty[0] - g * my[0], -ty[1] - g * my[1], -ty[2] - g * my[2]],
                [-m[0], -m[1], -m[2]],
            ];
            // solve J d = -res by Cramer's rule (3 x 3)
            let det = facet::dot(cols[0], facet::cross(cols[1], cols[2]));
            if det == 0.0 || !det.is_finite() {
                return None;
            }
            let neg = [-res[0], -res[1], -res[2]];
            let d = [
                facet::dot(neg, facet::cross(cols[1], cols[2])) / det,
                facet::dot(cols[0], facet::cross(neg, cols[2])) / det,
                facet::dot(cols[0], facet::cross(cols[1], neg)) / det,
            ];
            r = [r[0] + d[0], r[1] + d[1]];
            g += d[2];
            if !(r[0].abs() <= 3.0 && r[1].abs() <= 3.0 && g.is_finite()) {
                return None;
            }
            last_step = d[0].abs().max(d[1].abs());
            // converged: below 1e-15, or at the rounding floor (a step of at most
            // `PROJECTION_CONVERGED` that no longer shrinks; more steps only move `(xi, eta)`
            // about the root by rounding: measured, 84 % of the projections of 2 000 ironing-3d
            // queries ran out all 25 steps there)
            if last_step <= 1e-15 || (last_step <= PROJECTION_CONVERGED && last_step >= previous) {
                break;
            }
        }
        // Newton's steps stall at the rounding of the residual (about 1e-16 of the facet's size
        // over the Jacobian's smallest singular value): a last step of 1e-11 is converged
        let inside = r[0].abs() <= 1.0 + PROJECTION_SLACK && r[1].abs() <= 1.0 + PROJECTION_SLACK;
        if !(last_step <= PROJECTION_CONVERGED && inside) {
            return None;
        }
        let r = [r[0].clamp(-1.0, 1.0), r[1].clamp(-1.0, 1.0)];
        let (m, _, _, x) = interp(r);
        let mut pair = Pair3::on_facet(f, q, r);
        pair.normal = facet::unit(m);
        pair.gap = facet::dot(pair.normal, facet::sub(p, x));
        Some(pair)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    /// A 3 x 3 patch of unit facets in the plane z = 0 (outward +z), nodes `j * 4 + i` at
    /// `(i, j, 0)`, with a symmetry plane `y = 0` (the row j = 0):
    ///
    /// ```text
    ///   12--13--14--15
    ///   | 6  | 7  | 8 |
    ///   8---9---10--11      facets f = 3 j + i
    ///   | 3  | 4  | 5 |
    ///   4---5---6---7
    ///   | 0  | 1  | 2 |
    ///   0---1---2---3   <- y = 0, symmetry plane
    /// ```
    fn patch(bend: f64) -> (MasterSurface, Vec<[f64; 3]>) {
        let x: Vec<[f64; 3]> =
            (0..16).map(|n| [(n % 4) as f64, (n / 4) as f64, bend * ((n % 4) as f64 - 1.5).powi(2)]).collect();
        let facets = (0..9).map(|f| {
            let (i, j) = (f % 3, f / 3);
            [4 * j + i, 4 * j + i + 1, 4 * j + i + 5, 4 * j + i + 4]
        });
        (MasterSurface::new(facets.collect(), &x, &[Plane { axis: 1, at: 0.0 }], 1e-12), x)
    }

    /// A search's proof is sound and its shortcut exact ([`FacetGrid::pair_near`]): on the bent
    /// patch, 4 000 slaves at random above, below and beside it, half of them within 1e-3
    /// (horizontally) of one of its interior vertices, are searched with the online reach and
    /// with none; then the slave and every master node move by random amounts up to 1e-4 ...
    /// 0.3 (each a random direction and length) and, wherever the proof decides for the sum of
    /// the two largest moves, its pair is the search's at the new positions bit for bit
    /// (`Pair3`'s `==` on every float). Both branches are counted for both reaches (measured:
    /// 1 454 / 2 546 with none, 3 628 / 372 with the online reach), and so are
    /// the slaves near a vertex decided with the online reach: a proof of the located facet
    /// alone (the reach 0) decides none of them once the move exceeds their distance to the
    /// edges there (counted too: at most a tenth as many; measured 1 against 1 977), which is why the online searches
    /// keep a near set. A proof that ignored the facets outside its near set fails the
    /// comparison (checked).
    #[test]
    fn a_searchs_proof_decides_where_it_says_and_its_shortcut_is_the_search() {
        let (s, x) = patch(0.2);
        let mut rng = crate::rng::Rng::new(7);
        let dir = |rng: &mut crate::rng::Rng, len: f64| {
            let v = [rng.uniform_in(-1.0, 1.0), rng.uniform_in(-1.0, 1.0), rng.uniform_in(-1.0, 1.0)];
            let n = facet::dot(v, v).sqrt().max(1e-300);
            v.map(|c| c / n * len)
        };
        // [reach][decided, refused, decided near a vertex]
        let mut count = [[0usize; 3]; 2];
        for k in 0..4000 {
            let p0 = if k % 2 == 0 {
                [rng.uniform_in(-0.5, 3.5), rng.uniform_in(-0.5, 3.5), rng.uniform_in(-0.6, 1.2)]
            } else {
                let (i, j) = (1 + rng.below(2), 1 + rng.below(2));
                let v = x[4 * j + i];
                [
                    v[0] + rng.uniform_in(-1e-3, 1e-3),
                    v[1] + rng.uniform_in(-1e-3, 1e-3),
                    v[2] + rng.uniform_in(-0.3, 0.3),
                ]
            };
            let scale = [1e-4, 1e-3, 1e-2, 0.3][k / 2 % 4];
            let len = rng.uniform() * scale;
            let step = dir(&mut rng, len);
            let p1 = [p0[0] + step[0], p0[1] + step[1], p0[2] + step[2]];
            let mut largest = 0.0f64;
            let x1: Vec<[f64; 3]> = x
                .iter()
                .map(|xa| {
                    let len = rng.uniform() * scale;
                    let d = dir(&mut rng, len);
                    largest = largest.max(facet::dot(d, d).sqrt());
                    [xa[0] + d[0], xa[1] + d[1], xa[2] + d[2]]
                })
                .collect();
            let moved = facet::dot(step, step).sqrt() + largest;
            let want = FacetGrid::new(&s, &x1).pair(&s, &x1, p1);
            for (r, reach) in [0.0, ONLINE_REACH].into_iter().enumerate() {
                let (_, at) = FacetGrid::new(&s, &x).pair_located(&s, &x, p0, None, reach);
                let at = at.expect("facets");
                match FacetGrid::new(&s, &x1).pair_near(&s, &x1, p1, &at, moved) {
                    Some(pair) => {
                        assert_eq!(pair, want, "case {k}, reach {reach}");
                        count[r][0] += 1;
                        count[r][2] += k % 2;
                    }
                    None => count[r][1] += 1,
                }
            }
        }
        let [plain, online] = count;
        assert!(plain[0] > 500 && plain[1] > 500 && online[0] > 500 && online[1] > 200, "{count:?}");
        assert!(online[2] > 300 && 10 * plain[2] <= online[2], "{count:?}");
    }

    /// The least of `values`, by a plain loop: rustc 1.95 (LLVM 22) compiled
    /// `fold(f64::INFINITY, f64::min)` over the brute-force test's nine distances into a vector
    /// minimum of the first eight that skipped the ninth
    /// (docs/design-notes.md#a-miscompiled-minimum).
    fn least(values: impl Iterator<Item = f64>) -> f64 {
        let mut best = f64::INFINITY;
        for v in values {
            if v < best {
                best = v;
            }
        }
        best
    }

    /// The search is the brute-force rule with any hint and reach: on the bent patch and on a
    /// patch of random heights (so that the boxes' heights prune), 3 000 slaves at random above,
    /// below, beside and far above it (up to 3 facets away, where the squares grow) are located
    /// by measuring every facet: the least distance, ties within the search's tolerance (1e-12
    /// relative plus 1e-14 of the grid's facet extent) to the lowest index. The search without
    /// a hint, with a random facet and with the answer as the hint, each with no reach and with
    /// 0.3 facets, locates that facet and returns the same pair bit for bit (`Pair3`'s `==`),
    /// as does the full-order solver's pairing, which keeps no proof;
    /// its proof's near set holds the located facet and every facet within the reach (short of
    /// [`NEAR`]), and its bound lies below every other facet's distance, to 1e-12 relative for
    /// the rounding (it fails if a box pruned a facet nearer than its bound, if the hint or the
    /// reach changed the answer, or if the near set missed a facet it reached).
    #[test]
    fn the_search_is_the_brute_force_rule_with_any_hint() {
        let mut rng = crate::rng::Rng::new(11);
        let (bent, xb) = patch(0.2);
        let (rough, mut xr) = patch(0.0);
        for x in xr.iter_mut() {
            x[2] = rng.uniform_in(-0.4, 0.4);
        }
        for (s, x) in [(&bent, &xb), (&rough, &xr)] {
            let mut g = FacetGrid::new(s, x);
            for k in 0..1500 {
                let top = [1.2, 3.0][k % 2];
                let p = [rng.uniform_in(-1.0, 4.0), rng.uniform_in(-1.0, 4.0), rng.uniform_in(-0.8, top)];
                let d: Vec<f64> = (0..9).map(|f| facet::closest(&s.corners(f, x), p).d2.sqrt()).collect();
                let best = least(d.iter().copied());
                let (want, _) = g.pair_located(s, x, p, None, 0.0);
                assert_eq!(g.pair(s, x, p), want, "case {k}: the pairing without a proof");
                let tie = best * (1.0 + 1e-12) + 1e-14 * g.size;
                let winner = (0..9).find(|&f| d[f] <= tie).expect("a facet");
                for (hint, reach) in
                    [None, Some(rng.below(9)), Some(winner)].into_iter().flat_map(|h| [(h, 0.0), (h, 0.3)])
                {
                    let (pair, at) = g.pair_located(s, x, p, hint, reach);
                    let at = at.expect("facets");
                    assert_eq!(at.facet, winner, "case {k}, hint {hint:?}: {d:?}");
                    assert!(at.near().contains(&winner), "case {k}, hint {hint:?}, reach {reach}");
                    assert_eq!(pair, want, "case {k}, hint {hint:?}, reach {reach}");
                    // every facet outside the near set lies beyond the bound; a box's distance
                    // and a closest point's are rounded differently (an ulp apart at a box
                    // corner, measured), and `pair_near` keeps a margin of 1e-9
                    let outside = least((0..9).filter(|f| !at.near().contains(f)).map(|f| d[f]));
                    assert!(
                        at.others <= outside * (1.0 + 1e-12),
                        "case {k}, hint {hint:?}, reach {reach}: bound {} above {outside}",
                        at.others
                    );
                    // and the near set holds every facet within the reach (short of NEAR)
                    let reached = (0..9).filter(|&f| d[f] <= tie + reach * g.size).count();
                    assert!(
                        at.near().len() >= reached.min(NEAR),
                        "case {k}, reach {reach}: {:?} of {reached}",
                        at.near()
                    );
                }
            }
        }
    }

    /// [`hull_distance`] against the distance computed by hand: the square `[-1, 1]^2` listed in
    /// order and listed crossed (0, 2, 1, 3: the same hull), a point inside (0), beside an edge
    /// (1 from `(2, 0)`), past a corner (`sqrt 2` from `(2, 2)`), and a triangle with a repeated
    /// corner.
    #[test]
    fn the_hull_distance_is_the_distance_to_the_convex_hull() {
        let square = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        let crossed = [square[0], square[2], square[1], square[3]];
        for pts in [square, crossed] {
            assert_eq!(hull_distance([0.3, -0.2], &pts).to_bits(), 0f64.to_bits(), "inside");
            assert_close!(hull_distance([2.0, 0.0], &pts), 1.0, Tol::abs(1e-15));
            assert_close!(hull_distance([2.0, 2.0], &pts), 2f64.sqrt(), Tol::abs(1e-15));
        }
        let triangle = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 0.0]];
        assert_eq!(hull_distance([0.5, 0.5], &triangle).to_bits(), 0f64.to_bits(), "inside");
        assert_close!(hull_distance([2.0, 2.0], &triangle), 2f64.sqrt(), Tol::abs(1e-15));
    }

    /// The projection cone only skips projections that would fail: on the flat, bent and
    /// randomly distorted patch (nodes moved by up to 0.2 in each direction), 6 000 points at
    /// random above, below and beside it (a third within 0.05 of its height), every facet whose
    /// normal projection of the point succeeds ([`MasterSurface::project`] from its own closest
    /// point) is admitted by its [`Cone`]. The hull form is exercised: some failing projections
    /// the ball form admits are excluded by it (counted; without them the test fails, so a hull
    /// test that never excludes is caught), as are projections both admit.
    #[test]
    fn a_projection_cone_never_refuses_a_projection_that_succeeds() {
        let mut rng = crate::rng::Rng::new(11);
        let (mut succeeded, mut hull_only) = (0, 0);
        for case in 0..4 {
            let (s, mut x) = patch([0.0, 0.2, 0.8, 0.3][case]);
            if case == 3 {
                for xa in &mut x {
                    for c in xa.iter_mut() {
                        *c += rng.uniform_in(-0.2, 0.2);
                    }
                }
            }
            let nodal = s.nodal_normals(&x);
            let cones: Vec<Cone> =
                (0..s.facets.len()).map(|g| Cone::of(&s.corners(g, &x), &s.facets[g].map(|v| nodal[v]))).collect();
            for k in 0..1500 {
                let (px, py) = (rng.uniform_in(-0.5, 3.5), rng.uniform_in(-0.5, 3.5));
                let z = if k % 3 == 0 {
                    0.2 * (px - 1.5).powi(2) * [0.0, 1.0, 4.0, 1.5][case] + rng.uniform_in(-0.05, 0.05)
                } else {
                    rng.uniform_in(-0.6, 1.2)
                };
                let p = [px, py, z];
                for (g, cone) in cones.iter().enumerate() {
                    let projects = s.project(g, p, &x, &nodal, None).is_some();
                    if projects {
                        succeeded += 1;
                        assert!(cone.may_project(p), "case {case}, point {p:?}: facet {g} projects it");
                    } else if !cone.may_project(p) {
                        hull_only += usize::from(cone.ball_admits(p));
                    }
                }
            }
        }
        assert!(succeeded > 2000 && hull_only > 100, "succeeded {succeeded}, excluded by the hull only {hull_only}");
    }

    /// [`Pair3::continues`] says what the rule's continuity makes true: on the bent patch, slaves
    /// 0.1 above the surface stepped by 1e-3 across the edge x = 2 (facets 4 to 5), across the
    /// vertex (2, 2) along the diagonal (facets 4 to 8, which share node 10 only) and across the
    /// edge y = 2, re-pair to other facets somewhere on each line (counted), and every such
    /// rename continues the row: the gap rows of consecutive slaves (the slave's `n`, each
    /// support node's `-w n`; the sum over nodes of the terms' differences) differ by at most
    /// 1e-2, twice the step times the rows' largest rate (each of four bilinear weights changes
    /// by at most 1 per unit length on unit facets, the normal by the bend's curvature 0.4:
    /// 4.4 + 0.4 per unit length). A slave over facet 0 and one over facet 8 (no shared node) do
    /// not continue, nor a paired slave and one past the free edge; their rows differ by at
    /// least 1 (weights summing to 1 on other nodes, or no row).
    #[test]
    fn a_rename_across_a_shared_node_continues_the_row_and_a_jump_does_not() {
        let (s, x) = patch(0.2);
        let mut g = FacetGrid::new(&s, &x);
        let height = |px: f64| 0.2 * (px - 1.5).powi(2) + 0.1;
        // the row as (node or slave, 3-vector): the slave's own term under usize::MAX
        let row = |p: &Pair3| -> Vec<(usize, [f64; 3])> {
            let mut r = vec![(usize::MAX, p.normal)];
            r.extend(p.support[..p.len].iter().map(|&(v, w)| (v, p.normal.map(|c| -w * c))));
            r
        };
        let distance = |a: &Pair3, b: &Pair3| {
            let (ra, rb) = (row(a), row(b));
            let mut nodes: Vec<usize> = ra.iter().chain(&rb).map(|e| e.0).collect();
            nodes.sort_unstable();
            nodes.dedup();
            let at = |r: &[(usize, [f64; 3])], v: usize| r.iter().find(|e| e.0 == v).map_or([0.0; 3], |e| e.1);
            nodes
                .iter()
                .map(|&v| facet::dot(facet::sub(at(&ra, v), at(&rb, v)), facet::sub(at(&ra, v), at(&rb, v))).sqrt())
                .sum::<f64>()
        };
        let mut renames = 0;
        for (start, dir) in [([1.5, 1.5], [1.0, 0.0]), ([1.5, 1.5], [1.0, 1.0]), ([1.5, 1.5], [0.0, 1.0])] {
            let at = |t: f64| {
                let (px, py) = (start[0] + t * dir[0], start[1] + t * dir[1]);
                [px, py, height(px)]
            };
            let mut last = g.pair(&s, &x, at(0.0));
            for k in 1..=1000 {
                let p = g.pair(&s, &x, at(1e-3 * k as f64));
                assert!(p.is_paired(), "{start:?} + {k}e-3 {dir:?}");
                if p.feature != last.feature {
                    renames += 1;
                    assert!(p.continues(&last), "{:?} -> {:?}", last.feature, p.feature);
                }
                assert!(distance(&p, &last) <= 1e-2, "{:?} -> {:?}: {}", last.feature, p.feature, distance(&p, &last));
                last = p;
            }
        }
        assert!(renames >= 3, "renames {renames}");
        let (a, b) = (g.pair(&s, &x, [0.5, 0.5, height(0.5)]), g.pair(&s, &x, [2.5, 2.5, height(2.5)]));
        assert_eq!((a.feature, b.feature), (Feature::Facet(0), Feature::Facet(8)));
        assert!(!b.continues(&a) && !a.continues(&b) && distance(&a, &b) >= 1.0);
        let free = g.pair(&s, &x, [3.8, 1.5, 0.0]);
        let inside = g.pair(&s, &x, [2.5, 1.5, height(2.5)]);
        assert_eq!(free, Pair3::UNPAIRED);
        assert!(!free.continues(&inside) && !inside.continues(&free) && distance(&free, &inside) >= 1.0);
        assert!(free.continues(&free) && inside.continues(&inside));
    }

    /// The cases of the rule, each with its gap and normal:
    /// - above a facet's interior: `Facet`, normal +z, gap = height;
    /// - a tie: straight below the interior vertex 5 of the flat patch, every facet around it
    ///   (0, 1, 3, 4) finds the vertex: the lowest index, facet 0, all weight on node 5;
    /// - an edge of a bent patch: the projection lands on the edge x = 1, its normal the
    ///   interpolation of nodes 5 and 9's normals, and the gap is continuous across the edge
    ///   (two slaves 1e-9 apart on either side differ by about 1e-9 in gap);
    /// - beyond the free edge x = 3 by more than half a facet: unpaired; by less: `Edge(7, 11)`;
    /// - beyond the symmetry edge y = 0: `Edge(1, 2)`, its normal without a y component.
    #[test]
    fn pairing_rule_facet_edge_vertex_tie_free_and_symmetry() {
        let (s, x) = patch(0.0);
        let mut g = FacetGrid::new(&s, &x);
        let p = g.pair(&s, &x, [1.5, 1.5, 0.25]);
        assert_eq!(p.feature, Feature::Facet(4));
        assert_close!(p.gap, 0.25, Tol::abs(1e-15));
        assert_close!(p.normal[2], 1.0, Tol::abs(1e-15));
        let v = g.pair(&s, &x, [1.0, 1.0, -0.1]);
        assert_eq!(v.feature, Feature::Facet(0));
        let weight5: f64 = v.support[..v.len].iter().filter(|(n, _)| *n == 5).map(|(_, w)| w).sum();
        assert_close!(weight5, 1.0, Tol::abs(1e-12));
        assert_close!(v.normal[2], 1.0, Tol::abs(1e-15));
        assert_close!(v.gap, -0.1, Tol::abs(1e-12));
        let free = g.pair(&s, &x, [3.7, 1.5, 0.1]);
        assert_eq!(free.feature, Feature::Free);
        // within half a facet of the free edge x = 3: paired with the edge
        let band = g.pair(&s, &x, [3.3, 1.5, 0.1]);
        assert_eq!(band.feature, Feature::Edge(7, 11));
        assert_close!(band.gap, 0.1, Tol::abs(1e-15));
        let sym = g.pair(&s, &x, [1.5, -0.4, 0.2]);
        assert_eq!(sym.feature, Feature::Edge(1, 2));
        assert_close!(sym.normal[1], 0.0, Tol::abs(0.0));
        assert_close!(sym.normal[2], 1.0, Tol::abs(1e-15));
        // a bent patch: z = bend (x - 1.5)^2 at the nodes; the edge x = 1 between facets 3 and 4
        let (s, x) = patch(0.2);
        let mut g = FacetGrid::new(&s, &x);
        // the point on the edge x = 1 at y = 1.5, raised along the edge's normal: it projects
        // back onto the edge
        let on_edge = [1.0, 1.5, x[5][2]];
        let n5 = s.nodal_normals(&x)[5];
        let p_edge = [on_edge[0] + 0.3 * n5[0], on_edge[1] + 0.3 * n5[1], on_edge[2] + 0.3 * n5[2]];
        let e = g.pair(&s, &x, p_edge);
        assert_eq!(e.feature, Feature::Facet(3), "the lower index of the edge's two facets");
        assert_close!(e.gap, 0.3, Tol::abs(1e-12));
        let w: f64 = e.support[..e.len].iter().filter(|(n, _)| *n == 5 || *n == 9).map(|(_, w)| w).sum();
        assert_close!(w, 1.0, Tol::abs(1e-12));
        let (left, right) =
            (g.pair(&s, &x, [p_edge[0] - 1e-9, 1.5, p_edge[2]]), g.pair(&s, &x, [p_edge[0] + 1e-9, 1.5, p_edge[2]]));
        assert_ne!(left.feature, right.feature, "the two sides are different facets");
        assert_close!(left.gap, right.gap, Tol::abs(1e-8));
        // the edge's normal interpolates its nodes' normals, each the sum of its facets' normals
        // at that corner: node 5 (x = 1, y = 1) has facets 0, 1, 3, 4; node 9 (x = 1, y = 2)
        // has 3, 4, 6, 7; by the bend's symmetry in y both are the sum of the two facet normals
        // at x = 1 from the left and the right, the same vector
        let left = facet::normal(&[x[4], x[5], x[9], x[8]], [1.0, 0.0]);
        let right = facet::normal(&[x[5], x[6], x[10], x[9]], [-1.0, 0.0]);
        let avg = facet::unit([left[0] + right[0], left[1] + right[1], left[2] + right[2]]);
        for (x, y) in e.normal.iter().zip(avg) {
            assert_close!(*x, y, Tol::abs(1e-14));
        }
        // a tie on the bent patch: below vertex 5 along its normal, every facet at 5 meets it;
        // facet 0 names it
        let below = [x[5][0] - n5[0], x[5][1] - n5[1], x[5][2] - n5[2]];
        let t = g.pair(&s, &x, below);
        assert_eq!(t.feature, Feature::Facet(0));
        assert_close!(t.gap, -1.0, Tol::abs(1e-12));
    }
}
