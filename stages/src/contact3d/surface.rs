//! The master surface and the node-to-surface pairing rule.
//!
//! The master surface is a set of bilinear quadrilateral facets over the master nodes
//! (master-local ids), each listed in the master body's outward orientation. A slave at `p` is
//! paired with the closest point of the surface (deformed configuration):
//!
//! 1. **Closest facet.** Every facet that can hold the closest point is searched
//!    ([`super::facet::closest`]: interior by Newton, edges exactly). Candidates come from a
//!    uniform grid over the facets' `(x, y)` bounding boxes, searched in growing squares until
//!    the best distance is within the square's half-side (a facet outside the square is farther
//!    horizontally, so farther).
//! 2. **Tie rule.** Among facets within `1e-12` (relative, plus `1e-14` of the facet size) of
//!    the smallest distance, the lowest facet index wins. Every facet that meets a vertex or an
//!    edge computes the same point from the same corners, so the rule only decides which
//!    facet's description of the same point is kept; the feature is then made canonical:
//! 3. **Feature.** An interior point is `Facet(f)`, with the facet's normal there. A point on an
//!    edge is `Edge(a, b)` (`a < b`), a corner `Vertex(v)`: their normal is the normalised sum of
//!    the unit normals, at that point, of every facet containing the edge or vertex, with the
//!    components normal to each symmetry plane the edge or vertex lies on removed (the mirror
//!    image's facets add the reflected normals). This is the 2-D rule's averaged normal at a
//!    vertex, generalised to edges and vertices; it makes the normal continuous across an edge
//!    for a slave sliding over it.
//! 4. **Free boundary.** An edge of a single facet that lies on no symmetry plane, and a vertex
//!    on such an edge, bound the master surface: a slave whose closest point lies there is past
//!    the surface and is left unpaired (zero pressure), as a 2-D slave past the master
//!    polyline's end.
//!
//! The gap of a pair is `g = n . (p - x_c)` with `x_c = sum_a w_a x_a` the closest point on its
//! support nodes (four, two or one); frozen `(w, n)` make it linear in the displacements.

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

    const UNPAIRED: Pair3 =
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
    /// Per master node: the symmetry planes it lies on (bit k: plane k).
    on_plane: Vec<u8>,
    planes: Vec<Plane>,
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
        Self { facets, edges, at_node, on_plane, planes: planes.to_vec(), free_node }
    }

    /// The facets.
    pub fn facets(&self) -> &[[usize; 4]] {
        &self.facets
    }

    fn corners(&self, f: usize, xm: &[[f64; 3]]) -> [[f64; 3]; 4] {
        self.facets[f].map(|v| xm[v])
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

    /// The canonical pair of the closest point `c` found on facet `f` for the slave at `p`.
    fn pair_of(&self, f: usize, c: &Closest, p: [f64; 3], xm: &[[f64; 3]]) -> Pair3 {
        let q = self.facets[f];
        let mut pair = Pair3::UNPAIRED;
        match c.spot {
            Spot::Interior(r) => {
                let w = crate::q1::shape(r[0], r[1]);
                pair.feature = Feature::Facet(f);
                pair.len = 4;
                for k in 0..4 {
                    pair.support[k] = (q[k], w[k]);
                }
                pair.normal = facet::normal(&self.corners(f, xm), r);
            }
            Spot::Edge(e, t) => {
                let (a, b) = (q[e], q[(e + 1) % 4]);
                let key = (a.min(b), a.max(b));
                let fs = &self.edges[&key];
                let mask = self.on_plane[a] & self.on_plane[b];
                if fs.len() == 1 && mask == 0 {
                    return Pair3::UNPAIRED;
                }
                let normals = fs.iter().map(|&g| {
                    let k = self.facets[g].iter().position(|&v| v == a).expect("edge corner a");
                    let l = self.facets[g].iter().position(|&v| v == b).expect("edge corner b");
                    let (ra, rb) = (facet::corner_ref(k), facet::corner_ref(l));
                    let r = [ra[0] + t * (rb[0] - ra[0]), ra[1] + t * (rb[1] - ra[1])];
                    facet::normal(&self.corners(g, xm), r)
                });
                pair.normal = self.averaged(normals, mask);
                pair.feature = Feature::Edge(key.0, key.1);
                pair.len = 2;
                pair.support[0] = (a, 1.0 - t);
                pair.support[1] = (b, t);
            }
            Spot::Corner(k) => {
                let v = q[k];
                if self.free_node[v] {
                    return Pair3::UNPAIRED;
                }
                let normals = self.at_node[v].iter().map(|&g| {
                    let k = self.facets[g].iter().position(|&x| x == v).expect("corner");
                    facet::normal(&self.corners(g, xm), facet::corner_ref(k))
                });
                pair.normal = self.averaged(normals, self.on_plane[v]);
                pair.feature = Feature::Vertex(v);
                pair.len = 1;
                pair.support[0] = (v, 1.0);
            }
        }
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
    stamp: Vec<u32>,
    round: u32,
}

impl FacetGrid {
    /// The grid of `surface`'s facets at master positions `xm`.
    pub fn new(surface: &MasterSurface, xm: &[[f64; 3]]) -> Self {
        let nf = surface.facets.len();
        let boxes: Vec<[f64; 4]> = (0..nf)
            .map(|f| {
                let c = surface.corners(f, xm);
                let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
                for x in c {
                    b = [b[0].min(x[0]), b[1].min(x[1]), b[2].max(x[0]), b[3].max(x[1])];
                }
                b
            })
            .collect();
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
        let each = |b: &[f64; 4], f: &mut dyn FnMut(usize)| {
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
        Self { origin: lo, cell, dims, start: count, items, size, stamp: vec![0; nf], round: 0 }
    }

    /// The pair of the slave at `p` (see the module docs).
    pub fn pair(&mut self, surface: &MasterSurface, xm: &[[f64; 3]], p: [f64; 3]) -> Pair3 {
        if surface.facets.is_empty() {
            return Pair3::UNPAIRED;
        }
        self.round = self.round.wrapping_add(1);
        if self.round == 0 {
            self.stamp.fill(0);
            self.round = 1;
        }
        let mut found: Vec<(f64, usize, Closest)> = Vec::new();
        let mut r = self.cell;
        let cell_of =
            |x: f64, o: f64, d: usize, cell: f64| ((x - o) / cell).floor().clamp(0.0, (d - 1) as f64) as usize;
        loop {
            let (i0, i1) = (
                cell_of(p[0] - r, self.origin[0], self.dims[0], self.cell),
                cell_of(p[0] + r, self.origin[0], self.dims[0], self.cell),
            );
            let (j0, j1) = (
                cell_of(p[1] - r, self.origin[1], self.dims[1], self.cell),
                cell_of(p[1] + r, self.origin[1], self.dims[1], self.cell),
            );
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let c = j * self.dims[0] + i;
                    for &f in &self.items[self.start[c]..self.start[c + 1]] {
                        if self.stamp[f] != self.round {
                            self.stamp[f] = self.round;
                            let cl = facet::closest(&surface.corners(f, xm), p);
                            found.push((cl.d2.sqrt(), f, cl));
                        }
                    }
                }
            }
            let best = found.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
            let everything = i0 == 0 && j0 == 0 && i1 == self.dims[0] - 1 && j1 == self.dims[1] - 1;
            if best <= r || everything {
                break;
            }
            r *= 2.0;
        }
        let best = found.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
        let tie = best * (1.0 + 1e-12) + 1e-14 * self.size;
        let (_, f, cl) = found.iter().filter(|x| x.0 <= tie).min_by_key(|x| x.1).copied().expect("a facet");
        surface.pair_of(f, &cl, p, xm)
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

    /// The feature cases of the rule, each with its gap and normal:
    /// - above a facet's interior: `Facet`, the facet's normal, gap = height;
    /// - above an interior edge of a bent patch (two facets with different normals): `Edge`, the
    ///   averaged normal (symmetric in x about the edge x = 1);
    /// - straight below an interior vertex of the flat patch: `Vertex` (every facet at it finds
    ///   its corner), normal +z, the signed gap;
    /// - a tie (a slave exactly above the vertex 5, met by four facets): the feature is the
    ///   vertex whichever facet is scanned first;
    /// - beyond the free edge x = 3: unpaired; beyond the symmetry edge y = 0 (row j = 0): paired,
    ///   its normal without a y component.
    #[test]
    fn pairing_rule_facet_edge_vertex_tie_free_and_symmetry() {
        let (s, x) = patch(0.0);
        let mut g = FacetGrid::new(&s, &x);
        let p = g.pair(&s, &x, [1.5, 1.5, 0.25]);
        assert_eq!(p.feature, Feature::Facet(4));
        assert_close!(p.gap, 0.25, Tol::abs(1e-15));
        assert_close!(p.normal[2], 1.0, Tol::abs(1e-15));
        let v = g.pair(&s, &x, [1.0, 1.0, -0.1]);
        assert_eq!(v.feature, Feature::Vertex(5));
        assert_close!(v.normal[2], 1.0, Tol::abs(1e-15));
        assert_close!(v.gap, -0.1, Tol::abs(1e-15));
        let free = g.pair(&s, &x, [3.5, 1.5, 0.1]);
        assert_eq!(free.feature, Feature::Free);
        let sym = g.pair(&s, &x, [1.5, -0.4, 0.2]);
        assert_eq!(sym.feature, Feature::Edge(1, 2));
        assert_close!(sym.normal[1], 0.0, Tol::abs(0.0));
        assert_close!(sym.normal[2], 1.0, Tol::abs(1e-15));
        // a bent patch: z = bend (x - 1.5)^2 at the nodes; the edge x = 1 between facets 3 and 4
        let (s, x) = patch(0.2);
        let mut g = FacetGrid::new(&s, &x);
        let e = g.pair(&s, &x, [0.95, 1.5, -0.5]);
        match e.feature {
            Feature::Edge(a, b) => assert_eq!((a, b), (5, 9)),
            other => panic!("edge expected, got {other:?}"),
        }
        let n3 = facet::normal(&[x[4], x[5], x[9], x[8]], [1.0, 0.0]);
        let n4 = facet::normal(&[x[5], x[6], x[10], x[9]], [-1.0, 0.0]);
        let avg = facet::unit([n3[0] + n4[0], n3[1] + n4[1], n3[2] + n4[2]]);
        for (x, y) in e.normal.iter().zip(avg) {
            assert_close!(*x, y, Tol::abs(1e-14));
        }
        // a tie: straight above vertex 5 of the bent patch, below it: every facet at 5 meets it
        let t = g.pair(&s, &x, [1.0, 1.0, -1.0]);
        assert_eq!(t.feature, Feature::Vertex(5));
        assert_close!(t.gap, facet::dot(t.normal, facet::sub([1.0, 1.0, -1.0], x[5])), Tol::abs(1e-15));
    }
}
