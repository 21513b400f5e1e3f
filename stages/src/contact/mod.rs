//! Two-body frictionless node-to-segment contact (paper Secs. 2.1–2.2, eqs. 2, 5–7;
//! docs/scenes.md#contact-formulation).
//!
//! Discrete problem (paper eq. 7) with one Lagrange multiplier (nodal contact force) per slave
//! node and the gap of eq. 2 evaluated with the closest-point projection in the deformed
//! configuration:
//!
//! ```text
//! K u - f - C(u)^T lambda = 0        (equilibrium, free dofs; Dirichlet by elimination)
//! g(u) = (x_s - x_bar(u)) . n(u) >= 0,   lambda >= 0,   lambda_i g_i(u) = 0
//! ```
//!
//! (`C^T lambda` pushes the bodies apart; paper eq. 7 writes the same with `C u - g <= 0`.)
//! Small-strain linear elasticity: `K` is parameter-independent and factored once per scene
//! ([`ContactModel::factor`]); the deformed configuration enters only through the pairing and
//! the normals, frozen within each active-set solve ([`FactoredModel::solve`]).
//!
//! - [`pairing`]: closest-point projection onto the master polyline;
//! - [`delassus`]: the compliance `W = E_c^T K^{-1} E_c` on the contact dofs;
//! - [`active_set`]: the condensed LCP `g = q + B W B^T lambda` (PDAS, fallback primal active set);
//! - [`vertex`]: vertex-flip detection, ties and the vertex-zone rule;
//! - [`check`]: the geometric check of a converged state;
//! - [`anderson`]: acceleration of the re-pairing fixed point;
//! - `model`, `factor`, `solve`: the scenes, the factorisation, the re-pairing loop;
//! - `rom_view`: the factored model as the reduced model sees it
//!   ([`crate::full_order::ContactOperator`]).
//!
//! The stored pressure is `lambda_i / l_i`, `l_i` the slave's tributary length (reference
//! configuration, half of each adjacent slave edge): the nodal contact force divided by the node's
//! tributary length (docs/scenes.md#common-setting).

pub mod active_set;
pub mod anderson;
pub mod check;
pub mod delassus;
mod error;
mod factor;
pub(crate) mod model;
pub mod pairing;
mod rom_view;
pub mod scene;
mod solve;
pub mod vertex;

#[cfg(test)]
mod tests;

pub use crate::fem::Material;
pub use error::{ContactError, ModelError};
pub use factor::FactoredModel;
pub use model::{build_hertz, build_ironing, ContactModel, HertzParams, IroningParams, SceneKind};
pub use solve::{ContactSolveParams, SolveStart, VertexRule};
