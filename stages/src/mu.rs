//! A parameter point `μ`: one value per parameter component (the paper's `μ` may be a vector;
//! every scene's imposed displacement is affine in it, `u_D(μ) = u_D0 + Σ_k μ_k u_Dk`).

/// A parameter point, displayed as `0.5` (one component) or `(0.5, 0.04)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Mu(pub Vec<f64>);

impl Mu {
    /// From a slice.
    pub fn of(mu: &[f64]) -> Self {
        Self(mu.to_vec())
    }
}

impl std::fmt::Display for Mu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0.as_slice() {
            [x] => write!(f, "{x}"),
            xs => {
                let parts: Vec<String> = xs.iter().map(|x| x.to_string()).collect();
                write!(f, "({})", parts.join(", "))
            }
        }
    }
}

/// `base + Σ_k mu_k terms[k]`, elementwise (the affine parameter dependence of lifts and
/// responses); `terms.len() == mu.len()`.
pub fn affine(base: &[f64], terms: &[Vec<f64>], mu: &[f64], i: usize) -> f64 {
    debug_assert_eq!(terms.len(), mu.len(), "one term per parameter component");
    terms.iter().zip(mu).fold(base[i], |acc, (t, m)| acc + m * t[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displays_scalars_plainly_and_vectors_in_parentheses() {
        assert_eq!(Mu(vec![0.5]).to_string(), "0.5");
        assert_eq!(Mu(vec![1.5, 0.04]).to_string(), "(1.5, 0.04)");
    }

    #[test]
    fn affine_adds_each_component_times_its_term() {
        let v = affine(&[1.0, 2.0], &[vec![10.0, 20.0], vec![100.0, 200.0]], &[0.5, 2.0], 1);
        // 2 + 0.5 * 20 + 2 * 200, exact in binary.
        assert_eq!(v.to_bits(), 412.0f64.to_bits());
    }
}
