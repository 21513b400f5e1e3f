//! Structured and mapped quadrilateral meshes for the 2-D contact scenes (docs/scenes.md).
//!
//! Every mesh here is built from one or more [`Grid`]s: an `(nx + 1) x (ny + 1)` lattice of nodes
//! `node(i, j) = j (nx + 1) + i` mapped into the plane, with counter-clockwise bilinear quads
//! `[(i, j), (i+1, j), (i+1, j+1), (i, j+1)]`. Grids of different bodies are concatenated into one
//! [`Mesh2d`] (nodes of body 0 first, then body 1, ...), which records the body of every node and
//! element and checks that every element's Jacobian is positive at every 2x2 Gauss point.
//!
//! - [`rectangle`]: the slab of the ironing scenes.
//! - [`half_disk`]: the bodies of the Hertz scenes (a Coons patch, see its docs for the scheme and
//!   the node counts it gives).
//! - [`iron`]: the iron of the ironing scenes, exactly the mapping of
//!   docs/scenes.md#ironing-coarse-and-ironing-fine.

mod grid;
mod half_disk;
mod iron;
mod quad_mesh;
mod rectangle;

pub use grid::Grid;
pub use half_disk::{half_disk, HalfDisk, HalfDiskParams};
pub use iron::{iron, IronGeometry};
pub use quad_mesh::{Mesh2d, MeshError};
pub use rectangle::rectangle;
