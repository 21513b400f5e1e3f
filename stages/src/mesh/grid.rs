//! A structured `(nx + 1) x (ny + 1)` lattice of nodes mapped into the plane.

/// A mapped structured grid: node `(i, j)`, `0 <= i <= nx`, `0 <= j <= ny`, has index
/// `j (nx + 1) + i`. `i` runs along the logical "bottom" edge, `j` from bottom to top; the
/// mapping must keep the lattice counter-clockwise so the quads below have positive Jacobians.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Elements along `i`.
    pub nx: usize,
    /// Elements along `j`.
    pub ny: usize,
    /// Node coordinates `[x, y]`; shape `(nx + 1) (ny + 1)`.
    pub nodes: Vec<[f64; 2]>,
}

impl Grid {
    /// Build a grid from a mapping of the lattice indices `(i, j)` to coordinates.
    pub fn from_fn(nx: usize, ny: usize, mut map: impl FnMut(usize, usize) -> [f64; 2]) -> Self {
        assert!(nx >= 1 && ny >= 1, "a grid needs at least one element per direction");
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push(map(i, j));
            }
        }
        Self { nx, ny, nodes }
    }

    /// Index of node `(i, j)`.
    pub fn node(&self, i: usize, j: usize) -> usize {
        assert!(i <= self.nx && j <= self.ny, "grid node ({i}, {j}) out of range");
        j * (self.nx + 1) + i
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Counter-clockwise quads `[(i, j), (i+1, j), (i+1, j+1), (i, j+1)]`, row by row.
    pub fn quads(&self) -> Vec<[usize; 4]> {
        let mut q = Vec::with_capacity(self.nx * self.ny);
        for j in 0..self.ny {
            for i in 0..self.nx {
                q.push([self.node(i, j), self.node(i + 1, j), self.node(i + 1, j + 1), self.node(i, j + 1)]);
            }
        }
        q
    }

    /// Nodes of the edge `j = 0`, `i` increasing.
    pub fn bottom(&self) -> Vec<usize> {
        (0..=self.nx).map(|i| self.node(i, 0)).collect()
    }

    /// Nodes of the edge `j = ny`, `i` increasing.
    pub fn top(&self) -> Vec<usize> {
        (0..=self.nx).map(|i| self.node(i, self.ny)).collect()
    }

    /// Nodes of the edge `i = 0`, `j` increasing.
    pub fn left(&self) -> Vec<usize> {
        (0..=self.ny).map(|j| self.node(0, j)).collect()
    }

    /// Nodes of the edge `i = nx`, `j` increasing.
    pub fn right(&self) -> Vec<usize> {
        (0..=self.ny).map(|j| self.node(self.nx, j)).collect()
    }
}
