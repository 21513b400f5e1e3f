//! The rope-on-obstacle problem (Type-1, paper Sec. 3, eqs. 14–15; docs/scenes.md#rope).
//!
//! Find `u` on `[0, L]`, `u(0) = u(L) = 0`, minimising `∫ ½ ν u'² + f u dx` subject to
//! `u(x) >= g(x, γ)`. Strong form: `-ν u'' + f = λ`, `λ >= 0`, `u - g >= 0`, `λ (u - g) = 0`.
//!
//! P1 elements on a uniform grid of `n` elements (`h = L / n`), nodes `x_i = i h`. With
//! `K = ν/h · tridiag(-1, 2, -1)` and the consistent load `F_i = f h`, the discrete KKT system
//! (paper eq. 7 with `C = -I` on the interior nodes, contact pairs static) is
//!
//! ```text
//! K u + F - Λ = 0,   Λ >= 0,   u - g >= 0,   Λ_i (u_i - g_i) = 0,
//! ```
//!
//! where `Λ_i` is the nodal contact force; the stored pressure is `λ_i = Λ_i / h` (force per unit
//! length, tributary length `h`). Every node is a potential contact node; the two Dirichlet end
//! nodes carry zero pressure by convention.
//!
//! [`solve()`] uses the primal-dual active set method (a semismooth Newton method on
//! `Λ - max(0, Λ + c (g - u)) = 0`, Hintermüller–Ito–Kunisch 2002): for an M-matrix `K` it
//! terminates in finitely many steps with the exact discrete solution.

mod problem;
mod rom_view;
mod solve;

pub use problem::{Rope, RopeParams};
pub use solve::{solve, unconstrained, RopeError, RopeSolveParams};

/// Test fixtures shared by the rope's test modules.
#[cfg(test)]
pub(crate) mod fixtures {
    use crom_schemas::scene::Model;

    use super::{solve, unconstrained, Rope, RopeParams, RopeSolveParams};
    use crate::shipped::shipped_scene;
    use crate::snapshot::Snapshot;

    /// The paper's rope, from the shipped `data/scenes/rope.toml` (docs/scenes.md#rope).
    pub(crate) fn paper_rope() -> Rope {
        let Model::Rope(r) = shipped_scene("rope").expect("rope.toml").model else {
            panic!("rope.toml is a rope scene")
        };
        Rope::new(RopeParams::from(&r))
    }

    /// The 10 training points and snapshots, the contact responses `u - u0` and the pressures,
    /// both column-major `n x 10`.
    pub(crate) fn training(rope: &Rope) -> (Vec<f64>, Vec<Snapshot>, Vec<f64>, Vec<f64>) {
        let gammas: Vec<f64> = (0..10).map(|k| -0.5 + k as f64 / 9.0).collect();
        let snaps: Vec<Snapshot> =
            gammas.iter().map(|&g| solve(rope, g, &RopeSolveParams::default()).expect("solves")).collect();
        let u0 = unconstrained(rope);
        let responses = snaps.iter().flat_map(|s| s.u.iter().zip(&u0).map(|(a, b)| a - b)).collect();
        let duals = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
        (gammas, snaps, responses, duals)
    }
}
