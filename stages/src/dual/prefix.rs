//! The two projections of an ordered basis, for every prefix size m at once.
//!
//! * [`SpanPrefix`]: the orthogonal projection onto `span(B[:, :m])`. The columns are
//!   orthonormalised in order by modified Gram–Schmidt applied twice ("twice is enough",
//!   Giraud et al. 2005), so `Q[:, :r(m)]` spans the same space as `B[:, :m]`; a column whose
//!   part outside the previous ones is below `DEPENDENT_REL` of its norm adds nothing and is
//!   skipped (`r(m)` counts the kept ones). With `c = Q^T s` and `s_perp = s - Q c`,
//!   `||s - P_m s||^2 = ||s_perp||^2 + sum_{l >= r(m)} c_l^2` (non-negative terms, no
//!   cancellation).
//! * [`ConePrefix`]: the projection onto `cone(B[:, :m])` (eq. 12), an NNLS per m, each warm
//!   started from the previous m's coefficients.

use faer::{Mat, MatRef};

use super::{DualApprox, DualError};
use crate::cone::{norm2, ConeProjector, NnlsParams};

/// A column whose part outside the span of the previous ones is at most this fraction of its
/// norm is numerically dependent (sin of its angle to that span; 1e-10 is far above the
/// round-off of two Gram–Schmidt passes, ~1e-15, and far below any angle a snapshot set
/// resolves).
const DEPENDENT_REL: f64 = 1e-10;

/// Orthogonal projections onto the spans of the prefixes of an ordered basis.
#[derive(Debug, Clone)]
pub struct SpanPrefix {
    q: Mat<f64>,
    /// `kept[m]` = orthonormal columns spanning the first m basis vectors (m = 0..=k).
    kept: Vec<usize>,
}

impl SpanPrefix {
    /// Orthonormalise the columns of `b` (n x k) in order.
    pub fn new(b: MatRef<'_, f64>) -> Self {
        let (n, k) = (b.nrows(), b.ncols());
        let mut cols: Vec<Vec<f64>> = Vec::with_capacity(k);
        let mut kept = Vec::with_capacity(k + 1);
        kept.push(0);
        let mut v = vec![0.0; n];
        for j in 0..k {
            v.copy_from_slice(b.col(j).try_as_col_major().expect("contiguous column").as_slice());
            let norm0 = norm2(&v);
            for _pass in 0..2 {
                for q in &cols {
                    let c: f64 = q.iter().zip(&v).map(|(a, b)| a * b).sum();
                    v.iter_mut().zip(q).for_each(|(x, qi)| *x -= c * qi);
                }
            }
            let norm = norm2(&v);
            if norm0 > 0.0 && norm > DEPENDENT_REL * norm0 {
                cols.push(v.iter().map(|x| x / norm).collect());
            }
            kept.push(cols.len());
        }
        let q = Mat::from_fn(n, cols.len(), |i, j| cols[j][i]);
        Self { q, kept }
    }

    /// Coordinates `Q[:, :r(m)]^T s` of `s` on the orthonormal basis of the first m vectors.
    pub fn coords(&self, s: &[f64], m: usize) -> Vec<f64> {
        let r = self.kept[m.min(self.kept.len() - 1)];
        (0..r).map(|l| self.q.col(l).iter().zip(s).map(|(a, b)| a * b).sum()).collect()
    }

    /// `Q[:, :len(alpha)] alpha` into `out`.
    pub fn combine(&self, alpha: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (l, &a) in alpha.iter().enumerate() {
            out.iter_mut().zip(self.q.col(l).iter()).for_each(|(o, q)| *o += a * q);
        }
    }

    /// Residual norms of `s` on the spans of the first `ms[k]` basis vectors.
    pub fn residuals_of(&self, s: &[f64], ms: &[usize], out: &mut [f64]) {
        let r = self.q.ncols();
        let mut c = vec![0.0; r];
        let mut perp = s.to_vec();
        for (l, cl) in c.iter_mut().enumerate() {
            let q = self.q.col(l).try_as_col_major().expect("contiguous column").as_slice();
            *cl = q.iter().zip(s).map(|(a, b)| a * b).sum();
            perp.iter_mut().zip(q).for_each(|(x, qi)| *x -= *cl * qi);
        }
        // tails[l] = sum_{i >= l} c_i^2, accumulated from the last term up.
        let mut tails = vec![0.0; r + 1];
        for l in (0..r).rev() {
            tails[l] = tails[l + 1] + c[l] * c[l];
        }
        let perp2: f64 = perp.iter().map(|x| x * x).sum();
        for (o, &m) in out.iter_mut().zip(ms) {
            let used = self.kept[m.min(self.kept.len() - 1)];
            *o = (perp2 + tails[used]).sqrt();
        }
    }
}

impl DualApprox for SpanPrefix {
    fn residuals(&self, s: &[f64], _mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        self.residuals_of(s, ms, out);
        Ok(())
    }

    fn size(&self) -> usize {
        self.kept.len() - 1
    }

    fn coefficients(&self, s: &[f64], _mu: &[f64], m: usize) -> Result<Option<(usize, Vec<f64>)>, DualError> {
        Ok(Some((0, self.coords(s, m))))
    }

    fn member(&self, _group: usize, alpha: &[f64], _mu: &[f64], _m: usize, out: &mut [f64]) {
        self.combine(alpha, out);
    }

    fn nonnegative(&self) -> bool {
        false
    }
}

/// Cone projections onto the prefixes of an ordered set of generators.
#[derive(Debug)]
pub struct ConePrefix {
    full: ConeProjector,
}

impl Clone for ConePrefix {
    fn clone(&self) -> Self {
        Self { full: self.full.prefix(self.full.ncols()) }
    }
}

impl ConePrefix {
    /// The generators `b` (n x k), in order.
    pub fn new(b: MatRef<'_, f64>) -> Self {
        Self { full: ConeProjector::new(b, NnlsParams::default()) }
    }

    /// The generators.
    pub fn basis(&self) -> MatRef<'_, f64> {
        self.full.basis()
    }

    /// NNLS coefficients of `s` on the first `m` generators.
    pub fn coords(&self, s: &[f64], m: usize) -> Result<Vec<f64>, DualError> {
        let m = m.min(self.full.ncols());
        if m == 0 {
            return Ok(Vec::new());
        }
        Ok(self.full.prefix(m).project(s)?.coeffs)
    }

    /// `B[:, :len(alpha)] alpha` into `out`.
    pub fn combine(&self, alpha: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        let b = self.full.basis();
        for (l, &a) in alpha.iter().enumerate() {
            out.iter_mut().zip(b.col(l).iter()).for_each(|(o, q)| *o += a * q);
        }
    }

    /// Residual norms of `s` on the cones of the first `ms[k]` generators.
    pub fn residuals_of(&self, s: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        let k = self.full.ncols();
        let mut coeffs: Vec<f64> = Vec::new();
        for (o, &m) in out.iter_mut().zip(ms) {
            let m = m.min(k);
            if m == 0 {
                *o = norm2(s);
                continue;
            }
            let mut p = self.full.prefix(m);
            coeffs.resize(m, 0.0);
            *o = p.project_warm(s, &mut coeffs)?;
        }
        Ok(())
    }
}

impl DualApprox for ConePrefix {
    fn residuals(&self, s: &[f64], _mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        self.residuals_of(s, ms, out)
    }

    fn size(&self) -> usize {
        self.full.ncols()
    }

    fn cone_basis(&self, _mu: &[f64], m: usize) -> Option<Mat<f64>> {
        Some(super::nonzero_prefix(self.full.basis(), m))
    }

    fn coefficients(&self, s: &[f64], _mu: &[f64], m: usize) -> Result<Option<(usize, Vec<f64>)>, DualError> {
        Ok(Some((0, self.coords(s, m)?)))
    }

    fn member(&self, _group: usize, alpha: &[f64], _mu: &[f64], _m: usize, out: &mut [f64]) {
        self.combine(alpha, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_all_close;
    use crate::cone::nnls_reference;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;

    /// Span residuals against a least-squares solve by a fresh SVD of each prefix.
    #[test]
    fn span_residuals_match_a_least_squares_solve_per_prefix() {
        let mut rng = Rng::new(3);
        let (n, k) = (25, 6);
        let mut b = Mat::from_fn(n, k, |_, _| rng.uniform_in(-1.0, 1.0));
        // Column 3 depends on columns 0 and 1: it adds nothing to the span.
        for i in 0..n {
            b[(i, 3)] = 2.0 * b[(i, 0)] - b[(i, 1)];
        }
        let s: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let ms: Vec<usize> = (0..=k + 2).collect();
        let mut out = vec![0.0; ms.len()];
        let p = SpanPrefix::new(b.as_ref());
        p.residuals_of(&s, &ms, &mut out);
        assert_eq!(p.size(), k);
        let reference: Vec<f64> = ms
            .iter()
            .map(|&m| {
                let m = m.min(k);
                if m == 0 {
                    return norm2(&s);
                }
                let u = b.subcols(0, m).thin_svd().expect("svd");
                let sv: Vec<f64> = u.S().column_vector().iter().copied().collect();
                let rank = sv.iter().filter(|&&x| x > 1e-12 * sv[0]).count();
                let uu = u.U().subcols(0, rank);
                let mut r = s.clone();
                for l in 0..rank {
                    let c: f64 = (0..n).map(|i| uu[(i, l)] * s[i]).sum();
                    (0..n).for_each(|i| r[i] -= c * uu[(i, l)]);
                }
                norm2(&r)
            })
            .collect();
        // 1e-12 relative: both are backward-stable orthogonal projections of an O(1) vector.
        assert_all_close!(out, reference, Tol { abs: 1e-13, rel: 1e-12 });
        // The dependent column changes nothing.
        assert_eq!(out[3].to_bits(), out[4].to_bits());
    }

    /// Cone residuals against the textbook Lawson–Hanson reference on each prefix.
    #[test]
    fn cone_residuals_match_the_reference_nnls_per_prefix() {
        let mut rng = Rng::new(5);
        let (n, k) = (30, 8);
        let b = Mat::from_fn(n, k, |_, _| rng.uniform());
        let s: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
        let ms: Vec<usize> = (1..=k).collect();
        let mut out = vec![0.0; k];
        ConePrefix::new(b.as_ref()).residuals_of(&s, &ms, &mut out).expect("nnls");
        let reference: Vec<f64> = ms
            .iter()
            .map(|&m| nnls_reference(b.subcols(0, m), &s, NnlsParams::default()).expect("ref").residual_norm)
            .collect();
        // 1e-10 relative: two NNLS solvers (Cholesky updates vs SVD per passive set) on a
        // well-conditioned random cone.
        assert_all_close!(out, reference, Tol { abs: 1e-12, rel: 1e-10 });
        // Residuals cannot grow as the cone grows.
        assert!(out.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-12)));
    }
}
