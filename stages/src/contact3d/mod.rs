//! Three-dimensional frictionless node-to-surface contact between two hexahedral bodies.
//!
//! The discrete problem is the 2-D one ([`crate::contact`]) with a surface in place of the
//! polyline: one Lagrange multiplier per slave node, the gap to the closest point of the master
//! surface in the deformed configuration ([`surface`]: facet interiors, edges and vertices by
//! one rule), small-strain elasticity with a parameter-independent `K` factored once, the
//! contact problem condensed on the potential-contact dofs (Delassus operator) and solved by
//! the same active-set LCP ([`crate::contact::active_set`]) with re-pairing.

mod condense;
pub mod facet;
pub mod model;
pub mod rom_view;
mod scene;
pub mod solve;
pub mod surface;
pub mod theory;

pub use model::{
    build_hertz3d, build_ironing3d, check_hertz3d, check_ironing3d, Hertz3dParams, Ironing3dParams, Model3d, Scene3d,
};
pub use solve::Factored3d;
pub use theory::HertzSpheres;
#[cfg(test)]
pub(crate) mod tests;
