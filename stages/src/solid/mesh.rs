//! The 3-D mesh: nodes, hexahedra and body ids, concatenated from one [`Block`] per body.

use super::block::Block;
use super::hex8;

/// Errors of 3-D mesh construction.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Mesh3dError {
    /// A geometric or count parameter is out of range (the message names it).
    #[error("bad mesh parameter: {0}")]
    BadParameter(String),
    /// An element is inverted or degenerate: `det J <= 0` at one of its Gauss points or its
    /// centre.
    #[error(
        "element {element} (body {body}) is inverted or degenerate: det J = {det:e} at Gauss point \
         {point} (8: the centre)"
    )]
    NonPositiveJacobian {
        /// Element index in the mesh.
        element: usize,
        /// Body the element belongs to.
        body: usize,
        /// Index into [`hex8::GAUSS`], 8 for the centre.
        point: usize,
        /// The determinant found there.
        det: f64,
    },
}

/// A mesh of trilinear hexahedra, possibly of several bodies. Dof `3 n + c` is component `c` of
/// node `n`'s displacement; nodes of body 0 come first.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh3d {
    /// Node coordinates; shape `n_nodes`.
    pub nodes: Vec<[f64; 3]>,
    /// Hexahedra (global node ids, [`hex8`] order); shape `n_elements`.
    pub hexes: Vec<[usize; 8]>,
    /// Body of each element.
    pub element_body: Vec<usize>,
    /// Body of each node.
    pub node_body: Vec<usize>,
}

impl Mesh3d {
    /// Concatenate blocks, block `b` becoming body `b`; returns the mesh and each block's node
    /// offset (global id = offset + block-local id).
    pub fn from_blocks(blocks: &[&Block]) -> (Self, Vec<usize>) {
        let mut mesh = Self { nodes: Vec::new(), hexes: Vec::new(), element_body: Vec::new(), node_body: Vec::new() };
        let mut offsets = Vec::with_capacity(blocks.len());
        for (body, b) in blocks.iter().enumerate() {
            let off = mesh.nodes.len();
            offsets.push(off);
            mesh.nodes.extend_from_slice(&b.nodes);
            mesh.node_body.extend(std::iter::repeat_n(body, b.n_nodes()));
            for h in b.hexes() {
                mesh.hexes.push(h.map(|n| n + off));
                mesh.element_body.push(body);
            }
        }
        (mesh, offsets)
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        self.hexes.len()
    }

    /// Number of dofs (three per node).
    pub fn n_dof(&self) -> usize {
        3 * self.nodes.len()
    }

    /// Corner coordinates of element `e`.
    pub fn element_coords(&self, e: usize) -> [[f64; 3]; 8] {
        self.hexes[e].map(|n| self.nodes[n])
    }

    /// Every element's Jacobian is positive at its Gauss points and centre; returns the smallest
    /// determinant, or the first element (lowest index) that fails.
    pub fn check_jacobians(&self) -> Result<f64, Mesh3dError> {
        let mut min = f64::INFINITY;
        for e in 0..self.n_elements() {
            let (det, point) = hex8::min_jacobian(&self.element_coords(e));
            if det.is_nan() || det <= 0.0 {
                return Err(Mesh3dError::NonPositiveJacobian { element: e, body: self.element_body[e], point, det });
            }
            min = min.min(det);
        }
        Ok(min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two blocks concatenate with offsets; a block whose map reverses orientation is refused,
    /// naming its first element and body.
    #[test]
    fn blocks_concatenate_and_inverted_elements_are_named() {
        let id = |t: f64| t;
        let a = Block::mapped([2, 2, 2], [&id, &id, &id], |p| p);
        let b = Block::mapped([1, 2, 3], [&id, &id, &id], |p| [p[0] + 2.0, p[1], p[2]]);
        let (m, off) = Mesh3d::from_blocks(&[&a, &b]);
        assert_eq!(off, vec![0, 27]);
        assert_eq!((m.n_nodes(), m.n_elements(), m.n_dof()), (27 + 24, 8 + 6, 3 * 51));
        assert!(m.check_jacobians().is_ok());
        let flipped = Block::mapped([1, 1, 1], [&id, &id, &id], |p| [p[0], p[1], -p[2]]);
        let (m, _) = Mesh3d::from_blocks(&[&a, &flipped]);
        match m.check_jacobians() {
            Err(Mesh3dError::NonPositiveJacobian { element, body, det, .. }) => {
                assert_eq!((element, body), (8, 1));
                assert!(det < 0.0);
            }
            other => panic!("expected an inverted element, got {other:?}"),
        }
    }
}
