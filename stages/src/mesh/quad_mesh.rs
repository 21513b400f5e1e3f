//! The mesh type shared by every 2-D scene: nodes, counter-clockwise Q1 quads and body ids.

use super::Grid;
use crate::q1;

/// Errors of mesh construction.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A geometric or count parameter is out of range (the message names it).
    #[error("bad mesh parameter: {0}")]
    BadParameter(String),
    /// An element is inverted or degenerate: `det J <= 0` at one of its 2x2 Gauss points.
    #[error(
        "element {element} (body {body}) has a non-positive Jacobian det = {det:e} at Gauss point \
         {gauss_point} (xi, eta) = ({xi:.4}, {eta:.4})"
    )]
    NonPositiveJacobian {
        /// Element index in the mesh.
        element: usize,
        /// Body the element belongs to.
        body: usize,
        /// Gauss point index 0..4 (order of [`q1::GAUSS_2X2`]).
        gauss_point: usize,
        /// Reference coordinates of the Gauss point.
        xi: f64,
        /// Reference coordinates of the Gauss point.
        eta: f64,
        /// The Jacobian determinant found there.
        det: f64,
    },
}

/// A 2-D mesh of bilinear quadrilaterals, possibly of several bodies.
///
/// Degrees of freedom are interleaved per node: dof `2 n` is `u_x` and `2 n + 1` is `u_y` of
/// node `n`; nodes of body 0 come first, then body 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh2d {
    /// Node coordinates `[x, y]`; shape `n_nodes`.
    pub nodes: Vec<[f64; 2]>,
    /// Counter-clockwise quads (global node ids); shape `n_elements`.
    pub quads: Vec<[usize; 4]>,
    /// Body id of each element; shape `n_elements`.
    pub element_body: Vec<usize>,
    /// Body id of each node; shape `n_nodes`.
    pub node_body: Vec<usize>,
}

impl Mesh2d {
    /// Concatenate grids, grid `b` becoming body `b`. Returns the mesh and the node offset of
    /// every grid (global id = offset + grid-local id).
    pub fn from_grids(grids: &[&Grid]) -> (Self, Vec<usize>) {
        let mut mesh = Self { nodes: Vec::new(), quads: Vec::new(), element_body: Vec::new(), node_body: Vec::new() };
        let mut offsets = Vec::with_capacity(grids.len());
        for (body, g) in grids.iter().enumerate() {
            let off = mesh.nodes.len();
            offsets.push(off);
            mesh.nodes.extend_from_slice(&g.nodes);
            mesh.node_body.extend(std::iter::repeat_n(body, g.n_nodes()));
            for q in g.quads() {
                mesh.quads.push([q[0] + off, q[1] + off, q[2] + off, q[3] + off]);
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
        self.quads.len()
    }

    /// Number of displacement dofs (`2 n_nodes`).
    pub fn n_dof(&self) -> usize {
        2 * self.nodes.len()
    }

    /// Corner coordinates of element `e`.
    pub fn element_coords(&self, e: usize) -> [[f64; 2]; 4] {
        let q = self.quads[e];
        [self.nodes[q[0]], self.nodes[q[1]], self.nodes[q[2]], self.nodes[q[3]]]
    }

    /// Check that `det J > 0` at every 2x2 Gauss point of every element; returns the smallest
    /// determinant found, or the first offending element.
    pub fn check_jacobians(&self) -> Result<f64, MeshError> {
        let mut min_det = f64::INFINITY;
        for e in 0..self.n_elements() {
            let xe = self.element_coords(e);
            for (gp, &[xi, eta]) in q1::GAUSS_2X2.iter().enumerate() {
                let det = q1::jacobian(&xe, xi, eta).det;
                // NaN coordinates give a NaN determinant: rejected too.
                if det.is_nan() || det <= 0.0 {
                    return Err(MeshError::NonPositiveJacobian {
                        element: e,
                        body: self.element_body[e],
                        gauss_point: gp,
                        xi,
                        eta,
                        det,
                    });
                }
                min_det = min_det.min(det);
            }
        }
        Ok(min_det)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::rectangle;

    #[test]
    fn concatenation_offsets_bodies() {
        let a = rectangle(0.0, 0.0, 1.0, 1.0, 2, 1).expect("valid");
        let b = rectangle(0.0, 1.0, 1.0, 1.0, 1, 1).expect("valid");
        let (m, off) = Mesh2d::from_grids(&[&a, &b]);
        assert_eq!(off, vec![0, 6]);
        assert_eq!(m.n_nodes(), 10);
        assert_eq!(m.n_elements(), 3);
        assert_eq!(m.element_body, vec![0, 0, 1]);
        assert_eq!(m.quads[2], [6, 7, 9, 8]);
        assert!(m.check_jacobians().is_ok());
    }

    #[test]
    fn inverted_element_is_reported() {
        // A "bow-tie" quad: nodes 2 and 3 swapped, so det J changes sign inside the element.
        //   3---2        2   3
        //   |   |  --->   \ /
        //   0---1         / \ (crossed)
        let g = Grid { nx: 1, ny: 1, nodes: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] };
        let (mut m, _) = Mesh2d::from_grids(&[&g]);
        m.quads[0] = [0, 1, 3, 2];
        match m.check_jacobians() {
            Err(MeshError::NonPositiveJacobian { element: 0, body: 0, .. }) => {}
            other => panic!("expected a Jacobian error, got {other:?}"),
        }
        // A clockwise element is negative everywhere.
        m.quads[0] = [0, 3, 2, 1];
        assert!(matches!(m.check_jacobians(), Err(MeshError::NonPositiveJacobian { gauss_point: 0, .. })));
    }
}
