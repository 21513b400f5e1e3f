//! A structured block: an `(nx + 1) x (ny + 1) x (nz + 1)` lattice of nodes mapped into space,
//! `node(i, j, k) = (k (ny + 1) + j) (nx + 1) + i`, with the hexahedra
//! `[(i, j, k), (i+1, j, k), (i+1, j+1, k), (i, j+1, k)]` and the same four at `k + 1` (the
//! node order of [`super::hex8`]). A map that preserves orientation gives positive Jacobians.
//!
//! Its six faces are named by the lattice coordinate they fix ([`Face`]); [`Block::face_quads`]
//! lists a face's quads with corners ordered so that `(x_1 - x_0) x (x_3 - x_0)` points out of
//! the block (for an orientation-preserving map).

/// One of a block's six faces: the lattice coordinate `i`, `j` or `k` at its least or greatest
/// value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Face {
    /// `i = 0`.
    IMin,
    /// `i = nx`.
    IMax,
    /// `j = 0`.
    JMin,
    /// `j = ny`.
    JMax,
    /// `k = 0`.
    KMin,
    /// `k = nz`.
    KMax,
}

/// A face's lattice point `(s, t)` to its node id.
type FaceMap<'a> = Box<dyn Fn(usize, usize) -> usize + 'a>;

/// A structured hexahedral block.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// Elements along each lattice direction.
    pub n: [usize; 3],
    /// Node coordinates, `node(i, j, k)` order.
    pub nodes: Vec<[f64; 3]>,
}

impl Block {
    /// The block whose node `(i, j, k)` sits at `map(s_0(i / nx), s_1(j / ny), s_2(k / nz))`:
    /// `grading[c]` maps `[0, 1]` onto itself (increasing, ends fixed) to cluster nodes.
    pub fn mapped(n: [usize; 3], grading: [&dyn Fn(f64) -> f64; 3], map: impl Fn([f64; 3]) -> [f64; 3]) -> Self {
        let mut nodes = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
        for k in 0..=n[2] {
            for j in 0..=n[1] {
                for i in 0..=n[0] {
                    let t = [i as f64 / n[0] as f64, j as f64 / n[1] as f64, k as f64 / n[2] as f64];
                    nodes.push(map([grading[0](t[0]), grading[1](t[1]), grading[2](t[2])]));
                }
            }
        }
        Self { n, nodes }
    }

    /// Node id of lattice point `(i, j, k)`.
    pub fn node(&self, i: usize, j: usize, k: usize) -> usize {
        (k * (self.n[1] + 1) + j) * (self.n[0] + 1) + i
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// The hexahedra, node ids in [`super::hex8`] order, `i` fastest.
    pub fn hexes(&self) -> Vec<[usize; 8]> {
        let [nx, ny, nz] = self.n;
        let mut out = Vec::with_capacity(nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let n = |a: usize, b: usize, c: usize| self.node(i + a, j + b, k + c);
                    out.push([
                        n(0, 0, 0),
                        n(1, 0, 0),
                        n(1, 1, 0),
                        n(0, 1, 0),
                        n(0, 0, 1),
                        n(1, 0, 1),
                        n(1, 1, 1),
                        n(0, 1, 1),
                    ]);
                }
            }
        }
        out
    }

    /// The face's lattice as `(s, t) -> node`, with `(s, t)` ordered so that `ds x dt` points out.
    fn face_lattice(&self, face: Face) -> (usize, usize, FaceMap<'_>) {
        let [nx, ny, nz] = self.n;
        match face {
            Face::KMax => (nx, ny, Box::new(move |s, t| self.node(s, t, nz))),
            Face::KMin => (ny, nx, Box::new(move |s, t| self.node(t, s, 0))),
            Face::IMax => (ny, nz, Box::new(move |s, t| self.node(nx, s, t))),
            Face::IMin => (nz, ny, Box::new(move |s, t| self.node(0, t, s))),
            Face::JMax => (nz, nx, Box::new(move |s, t| self.node(t, ny, s))),
            Face::JMin => (nx, nz, Box::new(move |s, t| self.node(s, 0, t))),
        }
    }

    /// The face's nodes, `s` fastest (see [`Self::face_quads`]).
    pub fn face_nodes(&self, face: Face) -> Vec<usize> {
        let (ns, nt, at) = self.face_lattice(face);
        (0..=nt).flat_map(|t| (0..=ns).map(move |s| (s, t))).map(|(s, t)| at(s, t)).collect()
    }

    /// The face's quads, corners `(s, t), (s+1, t), (s+1, t+1), (s, t+1)` in the face's
    /// outward orientation, `s` fastest.
    pub fn face_quads(&self, face: Face) -> Vec<[usize; 4]> {
        let (ns, nt, at) = self.face_lattice(face);
        let mut out = Vec::with_capacity(ns * nt);
        for t in 0..nt {
            for s in 0..ns {
                out.push([at(s, t), at(s + 1, t), at(s + 1, t + 1), at(s, t + 1)]);
            }
        }
        out
    }
}

/// Grading toward 0: `t^p` (`p >= 1`; 1 is uniform).
pub fn toward_zero(p: f64) -> impl Fn(f64) -> f64 {
    move |t| t.powf(p)
}

/// Grading toward 1: `1 - (1 - t)^p`.
pub fn toward_one(p: f64) -> impl Fn(f64) -> f64 {
    move |t| 1.0 - (1.0 - t).powf(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(n: [usize; 3]) -> Block {
        let id = |t: f64| t;
        Block::mapped(n, [&id, &id, &id], |p| p)
    }

    /// Node and element counts, and every face's quads point out of the unit cube: the
    /// normal `(x_1 - x_0) x (x_3 - x_0)` is the face's outward axis direction.
    #[test]
    fn faces_are_oriented_outward() {
        let b = unit([3, 2, 4]);
        assert_eq!(b.n_nodes(), 4 * 3 * 5);
        assert_eq!(b.hexes().len(), 24);
        let cases = [
            (Face::IMin, [-1.0, 0.0, 0.0], 8),
            (Face::IMax, [1.0, 0.0, 0.0], 8),
            (Face::JMin, [0.0, -1.0, 0.0], 12),
            (Face::JMax, [0.0, 1.0, 0.0], 12),
            (Face::KMin, [0.0, 0.0, -1.0], 6),
            (Face::KMax, [0.0, 0.0, 1.0], 6),
        ];
        for (face, out, count) in cases {
            let quads = b.face_quads(face);
            assert_eq!(quads.len(), count, "{face:?}");
            for q in quads {
                let [a, p, _, r] = q.map(|n| b.nodes[n]);
                let (e1, e2) = ([p[0] - a[0], p[1] - a[1], p[2] - a[2]], [r[0] - a[0], r[1] - a[1], r[2] - a[2]]);
                let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
                let d: f64 = n.iter().zip(&out).map(|(x, y)| x * y).sum();
                assert!(d > 0.0, "{face:?}: normal {n:?}");
            }
            let nodes = b.face_nodes(face);
            let axis = out.iter().position(|&x| x != 0.0).expect("axis");
            let at = if out[axis] > 0.0 { 1.0 } else { 0.0 };
            assert!(nodes.iter().all(|&n| crate::float_cmp::is_zero(b.nodes[n][axis] - at, 0.0)), "{face:?}");
        }
    }
}
