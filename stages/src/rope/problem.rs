//! The discretised rope: grid, obstacle and the H1 norm.

/// Physical and discretisation parameters of the rope (docs/scenes.md#rope).
#[derive(Debug, Clone, PartialEq)]
pub struct RopeParams {
    /// Domain length `L`.
    pub length: f64,
    /// Number of uniform P1 elements (>= 2).
    pub n_elements: usize,
    /// Tension ν (> 0).
    pub nu: f64,
    /// Distributed load f (positive pulls the rope down).
    pub f: f64,
    /// Obstacle sine modes `m_k` of `g = Σ a_k sin(m_k π x) + offset + γ x`.
    pub modes: Vec<f64>,
    /// Obstacle sine amplitudes `a_k`.
    pub amplitudes: Vec<f64>,
    /// Obstacle offset.
    pub offset: f64,
}

impl From<&crom_schemas::scene::RopeSpec> for RopeParams {
    fn from(r: &crom_schemas::scene::RopeSpec) -> Self {
        RopeParams {
            length: r.length,
            n_elements: r.n_elements,
            nu: r.nu,
            f: r.f,
            modes: r.obstacle.modes.clone(),
            amplitudes: r.obstacle.amplitudes.clone(),
            offset: r.obstacle.offset,
        }
    }
}

/// The discretised rope problem (parameter-independent part).
#[derive(Debug, Clone)]
pub struct Rope {
    /// The parameters it was built from.
    pub params: RopeParams,
    /// Node coordinates, `n_elements + 1`.
    pub x: Vec<f64>,
    /// Element size.
    pub h: f64,
    /// Tributary length of each node as a contact node: `h` inside, 0 at the Dirichlet ends.
    pub weights: Vec<f64>,
}

impl Rope {
    /// Build the grid. Panics only on programmer errors (validated scene values are assumed).
    pub fn new(params: RopeParams) -> Self {
        assert!(params.n_elements >= 2, "rope needs at least 2 elements");
        assert_eq!(params.modes.len(), params.amplitudes.len(), "one amplitude per mode");
        let n = params.n_elements;
        let h = params.length / n as f64;
        let x = (0..=n).map(|i| if i == n { params.length } else { i as f64 * h }).collect();
        let weights = (0..=n).map(|i| if i == 0 || i == n { 0.0 } else { h }).collect();
        Self { params, x, h, weights }
    }

    /// Number of nodes (= number of dofs = number of potential-contact nodes).
    pub fn n_nodes(&self) -> usize {
        self.x.len()
    }

    /// Obstacle height at `x` for parameter `gamma` (paper eq. 15).
    pub fn obstacle(&self, x: f64, gamma: f64) -> f64 {
        let p = &self.params;
        let waves: f64 = p.modes.iter().zip(&p.amplitudes).map(|(m, a)| a * (m * std::f64::consts::PI * x).sin()).sum();
        waves + p.offset + gamma * x
    }

    /// Squared H1 norm `∫ u² + u'² dx` of a P1 field given by its nodal values (exact for P1:
    /// consistent mass matrix `h/6 · tridiag(1, 4, 1)` plus the stiffness `1/h · tridiag(-1, 2, -1)`).
    pub fn h1_norm_sq(&self, u: &[f64]) -> f64 {
        assert_eq!(u.len(), self.n_nodes(), "field length");
        let h = self.h;
        u.windows(2)
            .map(|w| {
                let (a, b) = (w[0], w[1]);
                h / 3.0 * (a * a + a * b + b * b) + (b - a) * (b - a) / h
            })
            .sum()
    }

    /// `out = H u`, the Gram matrix of [`Self::h1_norm_sq`]: per element
    /// `[[h/3 + 1/h, h/6 - 1/h], [h/6 - 1/h, h/3 + 1/h]]`.
    pub fn h1_mul(&self, u: &[f64], out: &mut [f64]) {
        assert_eq!(u.len(), self.n_nodes(), "field length");
        let h = self.h;
        let (d, o) = (h / 3.0 + 1.0 / h, h / 6.0 - 1.0 / h);
        out.iter_mut().for_each(|x| *x = 0.0);
        for e in 0..u.len() - 1 {
            out[e] += d * u[e] + o * u[e + 1];
            out[e + 1] += o * u[e] + d * u[e + 1];
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::rope::fixtures::paper_rope;

    #[test]
    fn obstacle_matches_paper_eq_15() {
        let r = paper_rope();
        let (x, g) = (0.3, 0.25);
        let pi = std::f64::consts::PI;
        let expected = -0.2 * ((pi * x).sin() - (3.0 * pi * x).sin()) - 0.5 + g * x;
        // Same formula, different summation order: rounding only (1e-15).
        assert_close!(r.obstacle(x, g), expected, Tol::abs(1e-15));
    }

    #[test]
    fn h1_norm_of_sine_matches_closed_form() {
        // u = sin(pi x) on [0,1]: ∫u² = 1/2, ∫u'² = pi²/2. P1 interpolation error in H1 is O(h):
        // the seminorm of the interpolant differs by ~ pi^4 h^2 / 24 relative ~ 1e-4 at h = 1/200.
        let r = paper_rope();
        let pi = std::f64::consts::PI;
        let u: Vec<f64> = r.x.iter().map(|x| (pi * x).sin()).collect();
        assert_close!(r.h1_norm_sq(&u), 0.5 + pi * pi / 2.0, Tol::rel(2e-4));
    }

    /// `u . (H u)` equals the element-wise norm (1e-12 relative) on a random field.
    #[test]
    fn gram_product_matches_the_norm() {
        let r = paper_rope();
        let mut rng = crate::rng::Rng::new(3);
        let u: Vec<f64> = (0..r.n_nodes()).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let mut hu = vec![0.0; u.len()];
        r.h1_mul(&u, &mut hu);
        let q: f64 = u.iter().zip(&hu).map(|(a, b)| a * b).sum();
        assert_close!(q, r.h1_norm_sq(&u), Tol::rel(1e-12));
    }
}
