//! Three-dimensional small-strain elasticity: the trilinear hexahedron ([`hex8`]), hex meshes
//! of several bodies built from structured blocks ([`mesh`], [`block`], [`shapes`]), global
//! assembly ([`assembly`]) and roller conditions on symmetry planes ([`symmetry`]).
//!
//! Equilibrium `K u = f`, `K = sum_e A_e^T K_e A_e`, dofs interleaved per node (`3 n + c`).
//! Dirichlet conditions by elimination ([`crate::fem::DofSplit`]), as in 2-D.

pub mod assembly;
pub mod block;
pub mod h1;
pub mod hex8;
pub mod mesh;
pub mod shapes;
pub mod symmetry;
