//! Linear isotropic material in plane strain.

/// Young's modulus and Poisson's ratio of a linear isotropic material, and how its Q1 elements
/// integrate the stiffness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Young's modulus `E > 0`.
    pub young: f64,
    /// Poisson's ratio, `-1 < nu < 0.5`.
    pub poisson: f64,
    /// Selective reduced integration of the volumetric part ([`crate::q1::stiffness_selective`]).
    pub selective: bool,
}

impl Material {
    /// A fully integrated material.
    pub const fn new(young: f64, poisson: f64) -> Self {
        Self { young, poisson, selective: false }
    }

    /// Lamé's `(lambda, mu)`: `lambda = E nu / ((1 + nu)(1 - 2 nu))`, `mu = E / (2 (1 + nu))`.
    pub fn lame(&self) -> (f64, f64) {
        let (e, nu) = (self.young, self.poisson);
        (e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu)))
    }

    /// The plane-strain `D` split as `D = D_vol + D_dev`: `D_vol = lambda m m^T` (`m = [1, 1, 0]`)
    /// and `D_dev = mu diag(2, 2, 1)`; returns `(D_dev, D_vol)`.
    pub fn plane_strain_split(&self) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
        let (l, m) = self.lame();
        ([[2.0 * m, 0.0, 0.0], [0.0, 2.0 * m, 0.0], [0.0, 0.0, m]], [[l, l, 0.0], [l, l, 0.0], [0.0, 0.0, 0.0]])
    }

    /// `Ok` if `E > 0` and `-1 < nu < 0.5` (both finite), otherwise a message naming the field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.young.is_finite() && self.young > 0.0) {
            return Err(format!("young must be > 0, got {}", self.young));
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(format!("poisson must be in (-1, 0.5), got {}", self.poisson));
        }
        Ok(())
    }

    /// Plane-strain constitutive matrix `D` (Voigt order `xx, yy, xy` with engineering shear):
    /// `E / ((1+nu)(1-2nu)) [[1-nu, nu, 0], [nu, 1-nu, 0], [0, 0, (1-2nu)/2]]`.
    pub fn plane_strain(&self) -> [[f64; 3]; 3] {
        let (e, nu) = (self.young, self.poisson);
        let c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
        [[c * (1.0 - nu), c * nu, 0.0], [c * nu, c * (1.0 - nu), 0.0], [0.0, 0.0, c * (1.0 - 2.0 * nu) / 2.0]]
    }

    /// Plane-strain modulus `E / (1 - nu^2)` (Hertz theory uses `1/E* = sum (1 - nu_i^2)/E_i`).
    pub fn plane_strain_modulus(&self) -> f64 {
        self.young / (1.0 - self.poisson * self.poisson)
    }
}
