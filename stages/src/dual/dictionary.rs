//! Dictionary-sparse approximation (the paper's first *Perspective*; Kollepara et al. 2024):
//! every non-zero training snapshot, scaled to unit norm, is an atom `d_j`, and a pressure `s`
//! is approximated by a non-negative combination of at most m atoms, chosen greedily by the
//! Lawson–Hanson rule:
//!
//! ```text
//! r_0 = s;  t = 1, 2, ..: j_t = argmax_{j not chosen} d_j^T r_{t-1}  (stop if <= 0),
//!           alpha = argmin_{a >= 0} ||s - D_{j_1..j_t} a||,  r_t = s - D_{j_1..j_t} alpha
//! ```
//!
//! The error with at most m atoms is `||r_m||` (atoms whose coefficient the NNLS sets to zero
//! stay chosen and count). Without a limit the loop ends when no atom correlates positively
//! with the residual: the KKT conditions of the NNLS over all atoms, so `||r||` is the
//! distance from s to the cone of the whole dictionary. Each step costs one correlation per
//! atom (`O(N n)` here; `O(N)` online with the atoms' Gram rows precomputed) and one NNLS on the
//! chosen atoms.

use faer::{Mat, MatRef};

use super::{DualApprox, DualError, Fact};
use crate::cone::{norm2, ConeProjector, NnlsParams};

/// A correlation at most this fraction of `||s||` is no ascent direction (round-off of the
/// residual's inner products).
const ASCENT_REL: f64 = 1e-12;

/// The training snapshots as atoms.
#[derive(Debug, Clone)]
pub struct Dictionary {
    atoms: Mat<f64>,
}

/// The non-zero columns of `s` scaled to unit norm: their indices, and the atoms column-major.
pub(crate) fn unit_atoms(s: MatRef<'_, f64>) -> (Vec<usize>, Vec<f64>) {
    let mut kept = Vec::new();
    let mut atoms = Vec::new();
    for j in 0..s.ncols() {
        let norm = s.col(j).iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm > 0.0 {
            kept.push(j);
            atoms.extend(s.col(j).iter().map(|v| v / norm));
        }
    }
    (kept, atoms)
}

/// One greedy approximation.
#[derive(Debug, Clone, PartialEq)]
pub struct Sparse {
    /// Atoms in the order they entered.
    pub chosen: Vec<usize>,
    /// Their coefficients (>= 0).
    pub coeffs: Vec<f64>,
    /// `||r_t||` after each step t = 1..
    pub residuals: Vec<f64>,
}

impl Dictionary {
    /// Atoms from the non-zero columns of `s` (n x N), each scaled to unit norm.
    pub fn new(s: MatRef<'_, f64>) -> Self {
        let (kept, atoms) = unit_atoms(s);
        Self { atoms: MatRef::from_column_major_slice(&atoms, s.nrows(), kept.len()).to_owned() }
    }

    /// Number of atoms.
    pub fn len(&self) -> usize {
        self.atoms.ncols()
    }

    /// True without atoms.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The greedy approximation of `s` with at most `max_atoms` atoms.
    pub fn approximate(&self, s: &[f64], max_atoms: usize) -> Result<Sparse, DualError> {
        let n = self.atoms.nrows();
        let mut cone = ConeProjector::empty(n, NnlsParams::default());
        let mut out = Sparse { chosen: Vec::new(), coeffs: Vec::new(), residuals: Vec::new() };
        let mut r = s.to_vec();
        let scale = norm2(s);
        let mut chosen = vec![false; self.len()];
        while out.chosen.len() < max_atoms {
            let mut best: Option<(usize, f64)> = None;
            for j in (0..self.len()).filter(|&j| !chosen[j]) {
                let d = self.atoms.col(j).try_as_col_major().expect("contiguous column").as_slice();
                let c: f64 = d.iter().zip(&r).map(|(a, b)| a * b).sum();
                if best.is_none_or(|(_, b)| c > b) {
                    best = Some((j, c));
                }
            }
            let Some((j, c)) = best else { break };
            if c <= ASCENT_REL * scale {
                break;
            }
            chosen[j] = true;
            out.chosen.push(j);
            let d = self.atoms.col(j).try_as_col_major().expect("contiguous column").as_slice();
            cone.push_column(d);
            out.coeffs.push(0.0);
            let norm = cone.project_warm(s, &mut out.coeffs)?;
            r.copy_from_slice(s);
            for (k, &a) in out.chosen.iter().enumerate() {
                let col = self.atoms.col(a).try_as_col_major().expect("contiguous column").as_slice();
                r.iter_mut().zip(col).for_each(|(x, v)| *x -= out.coeffs[k] * v);
            }
            out.residuals.push(norm);
        }
        Ok(out)
    }
}

impl DualApprox for Dictionary {
    fn residuals(&self, s: &[f64], _mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        let max = ms.iter().copied().max().unwrap_or(0);
        let sparse = self.approximate(s, max)?;
        let norm = norm2(s);
        for (o, &m) in out.iter_mut().zip(ms) {
            *o = match m.min(sparse.residuals.len()) {
                0 => norm,
                k => sparse.residuals[k - 1],
            };
        }
        Ok(())
    }

    fn size(&self) -> usize {
        self.len()
    }

    fn facts(&self) -> Vec<Fact> {
        vec![Fact::new("atoms", None, self.len() as f64)]
    }

    fn cone_basis(&self, _mu: &[f64], _m: usize) -> Option<Mat<f64>> {
        Some(self.atoms.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::cone::nnls_reference;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;

    /// Unlimited, the greedy loop ends at the NNLS over every atom (dense Lawson–Hanson
    /// reference); limited, its error is never below that and never grows with m.
    #[test]
    fn unlimited_it_is_the_nnls_over_all_atoms() {
        let mut rng = Rng::new(31);
        let (n, count) = (40, 25);
        let s = Mat::from_fn(n, count, |i, j| {
            let c = 1.0 + j as f64;
            (-((i as f64 - c) / 3.0).powi(2)).exp() * rng.uniform_in(0.5, 1.5)
        });
        let dict = Dictionary::new(s.as_ref());
        for trial in 0..5 {
            let b: Vec<f64> = (0..n).map(|i| (-((i as f64 - 10.0 - 3.3 * trial as f64) / 4.0).powi(2)).exp()).collect();
            let full = dict.approximate(&b, count).expect("greedy");
            let reference = nnls_reference(dict.atoms.as_ref(), &b, NnlsParams::default()).expect("reference");
            // 1e-9 relative: two NNLS solvers on a cone of 25 overlapping bumps (condition
            // ~1e3); the residuals agree to round-off times the condition.
            assert_close!(
                *full.residuals.last().expect("steps"),
                reference.residual_norm,
                Tol { abs: 1e-12, rel: 1e-9 }
            );
            assert!(full.residuals.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-12)));
            assert!(full.coeffs.iter().all(|&c| c >= 0.0));
            let few = dict.approximate(&b, 2).expect("two atoms");
            assert!(few.chosen.len() <= 2);
            assert!(few.residuals.last().copied().unwrap_or(norm2(&b)) >= reference.residual_norm * (1.0 - 1e-12));
        }
    }

    /// A snapshot of the dictionary is reproduced by one atom; zero snapshots are no atoms.
    #[test]
    fn a_training_snapshot_is_one_atom() {
        let mut rng = Rng::new(32);
        let mut s = Mat::from_fn(12, 6, |_, _| rng.uniform());
        for i in 0..12 {
            s[(i, 5)] = 0.0;
        }
        let dict = Dictionary::new(s.as_ref());
        assert_eq!(dict.len(), 5);
        let col: Vec<f64> = (0..12).map(|i| 3.0 * s[(i, 2)]).collect();
        let a = dict.approximate(&col, 3).expect("approximate");
        assert_eq!(a.chosen[0], 2);
        assert!(a.residuals[0] <= 1e-12 * norm2(&col));
    }
}
