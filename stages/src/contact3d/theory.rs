//! Hertz theory for two equal elastic spheres (Johnson, *Contact Mechanics*, sec. 4.2): the
//! reference `hertz-3d` is measured against (its test, `just example hertz3d_theory` and the
//! report's figure).
//!
//! ```text
//!   R* = R / 2,  E* = E / (2 (1 - nu^2)),  d the approach of the two spheres' centres
//!   a = sqrt(R* d),  p0 = (2 E* / pi) sqrt(d / R*),  F = (4/3) E* sqrt(R*) d^(3/2)
//!   p(r) = p0 sqrt(1 - r^2 / a^2)  for r <= a,  0 beyond
//! ```

use super::model::Model3d;
use crate::snapshot::Snapshot;

/// The Hertz solution of two equal spheres at one approach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HertzSpheres {
    /// Contact radius `a`.
    pub a: f64,
    /// Peak pressure `p0`.
    pub p0: f64,
    /// Total force `F`.
    pub force: f64,
}

impl HertzSpheres {
    /// Two spheres of radius `radius`, Young's modulus `young` and Poisson's ratio `poisson`,
    /// pressed together by the approach `d`.
    pub fn at(radius: f64, young: f64, poisson: f64, d: f64) -> Self {
        let (es, rs) = (young / (2.0 * (1.0 - poisson * poisson)), radius / 2.0);
        Self {
            a: (rs * d).sqrt(),
            p0: 2.0 * es / std::f64::consts::PI * (d / rs).sqrt(),
            force: 4.0 / 3.0 * es * rs.sqrt() * d.powf(1.5),
        }
    }

    /// The pressure at distance `r` from the axis.
    pub fn pressure(&self, r: f64) -> f64 {
        self.p0 * (1.0 - (r / self.a).powi(2)).max(0.0).sqrt()
    }

    /// The same three quantities as a solve `s` of the quarter model `hertz-3d` (`model`) reads
    /// them, the one definition its test and `just example hertz3d_theory` compare with theory:
    /// `force` = 4 x the reaction on the top face, `p0` = the pressure of the slave on the axis
    /// (its force over its tributary area), `a` from `F = (2/3) pi a^2 p0` (the Hertz
    /// distribution's resultant). `None` when no slave lies on the axis.
    pub fn measured(model: &Model3d, s: &Snapshot) -> Option<Self> {
        let nodes = &model.mesh().nodes;
        let apex = model.slave_nodes().iter().position(|&k| nodes[k][0].hypot(nodes[k][1]) < 1e-12)?;
        let force = -4.0 * model.resultant(&s.u, model.driven_nodes())[2];
        let p0 = s.pressure[apex];
        Some(Self { a: (3.0 * force / (2.0 * std::f64::consts::PI * p0)).sqrt(), p0, force })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::float_cmp::Tol;

    /// The three quantities are one solution: the force is the pressure's resultant,
    /// `F = int_0^a p(r) 2 pi r dr = (2/3) pi a^2 p0` (here also by a 4 000-interval midpoint
    /// sum of `pressure`, whose error at the square-root edge is 1.0e-6 relative), and
    /// `a^2 = R* d` (Johnson's eq. 4.23). Tolerances: 1e-14 for the closed forms (rounding),
    /// 1e-5 for the quadrature; exactly 0 beyond `a` (the formula clamps).
    #[test]
    fn the_force_is_the_pressures_resultant() {
        for (r, e, nu, d) in [(1.0, 1.0, 0.3, 0.01), (2.5, 210.0, 0.25, 0.003)] {
            let h = HertzSpheres::at(r, e, nu, d);
            assert_close!(h.force, 2.0 / 3.0 * std::f64::consts::PI * h.a * h.a * h.p0, Tol::rel(1e-14));
            assert_close!(h.a * h.a, r / 2.0 * d, Tol::rel(1e-14));
            let n = 4000;
            let dr = h.a / n as f64;
            let sum: f64 = (0..n)
                .map(|k| (k as f64 + 0.5) * dr)
                .map(|x| h.pressure(x) * 2.0 * std::f64::consts::PI * x * dr)
                .sum();
            assert_close!(sum, h.force, Tol::rel(1e-5));
            assert_close!(h.pressure(1.01 * h.a), 0.0, Tol::abs(0.0));
        }
    }
}
