//! Cone-Projected Greedy (CPG) dual basis (paper Sec. 2.3.1, eq. 12; rule in SCENES.md).
//!
//! Start from the empty cone. At each step compute, for every training snapshot `s_j` with
//! `||s_j|| > 0`, its relative cone-projection error `e_j = ||s_j - Pi_m(s_j)|| / ||s_j||` onto
//! the cone of the generators selected so far (zero snapshots are in every cone and are
//! skipped); add the snapshot with the largest `e_j` (ties within a relative 1e-12: larger
//! norm, then lower index), normalised to unit Euclidean norm. After each addition record
//! `C(m) = ||S - Pi_m(S)||_F / ||S||_F` (eq. 16). Stop when `C(m) <= tol`, or when every
//! snapshot has `e_j <= IN_CONE_REL_TOL` (already in the cone — so a duplicate or a positive
//! multiple of a selected snapshot is never added). Tolerance 0 keeps every snapshot that is
//! not already in the cone.

use faer::{Mat, MatRef};

use crate::approx::{close, Tol};
use crate::cone::{copy_column, ConeError, GrowingCone, NnlsParams, IN_CONE_REL_TOL};

/// Parameters of [`cpg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpgParams {
    /// Stop once the compactness `C(m)` (eq. 16) is at most this (default 0: keep every
    /// snapshot not already in the cone).
    pub tol: f64,
    /// Parameters of the cone projections (default [`NnlsParams::default`]).
    pub nnls: NnlsParams,
}

impl Default for CpgParams {
    fn default() -> Self {
        Self { tol: 0.0, nnls: NnlsParams::default() }
    }
}

/// A CPG basis.
#[derive(Debug, Clone)]
pub struct Cpg {
    /// Unit-norm generators in order of selection, n x m.
    pub basis: Mat<f64>,
    /// Column index in the snapshot matrix of each generator (length m).
    pub selected: Vec<usize>,
    /// `C(0..=m)`: `C(0) = 1` for a nonzero S. An all-zero S gives an empty basis and
    /// `compactness = [0.0]` (nothing to compress: `||S - Pi(S)||_F = 0`).
    pub compactness: Vec<f64>,
}

/// Relative tie tolerance between two candidates' errors (and norms).
const TIE_REL_TOL: f64 = 1e-12;

/// Greedy cone basis of the snapshots `s` (n x N, one per column).
pub fn cpg(s: MatRef<'_, f64>, params: CpgParams) -> Result<Cpg, ConeError> {
    let total = s.norm_l2();
    let mut cone = GrowingCone::new(s, params.nnls);
    let mut selected = Vec::new();
    if total <= 0.0 {
        return Ok(Cpg { basis: Mat::zeros(s.nrows(), 0), selected, compactness: vec![0.0] });
    }
    let mut compactness = vec![1.0];
    let mut column = vec![0.0; s.nrows()];
    while compactness.last().is_some_and(|&c| c > params.tol) {
        let Some(j) = next_snapshot(&cone, &selected) else {
            break;
        };
        copy_column(s, j, &mut column);
        let norm = cone.norms()[j];
        column.iter_mut().for_each(|v| *v /= norm);
        cone.push(&column)?;
        selected.push(j);
        compactness.push(cone.frobenius_residual() / total);
    }
    Ok(Cpg { basis: cone.basis().to_owned(), selected, compactness })
}

/// The not-yet-selected snapshot with the largest relative error above `IN_CONE_REL_TOL`.
fn next_snapshot(cone: &GrowingCone<'_>, selected: &[usize]) -> Option<usize> {
    let norms = cone.norms();
    let mut best: Option<(usize, f64)> = None;
    for j in 0..norms.len() {
        let Some(err) = cone.relative_error(j) else {
            continue;
        };
        if err <= IN_CONE_REL_TOL || selected.contains(&j) {
            continue;
        }
        let better = match best {
            None => true,
            Some((b, berr)) if close(err, berr, Tol::rel(TIE_REL_TOL)) => {
                !close(norms[j], norms[b], Tol::rel(TIE_REL_TOL)) && norms[j] > norms[b]
            }
            Some((_, berr)) => err > berr,
        };
        if better {
            best = Some((j, err));
        }
    }
    best.map(|(j, _)| j)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::Tol;
    use crate::assert_close;
    use crate::cone::ConeProjector;
    use crate::rng::Rng;
    use crate::testing::bumps;

    fn relative_cone_errors(basis: MatRef<'_, f64>, s: MatRef<'_, f64>) -> Vec<f64> {
        let mut proj = ConeProjector::new(basis, NnlsParams::default());
        let (_, res) = proj.project_many(s).expect("converges");
        (0..s.ncols()).map(|j| res[j] / s.col(j).norm_l2().max(f64::MIN_POSITIVE)).collect()
    }

    #[test]
    fn tolerance_zero_spans_every_snapshot() {
        let mut rng = Rng::new(51);
        let s = bumps(&mut rng, 40, 25, (1.0, 4.0));
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        for (j, e) in relative_cone_errors(out.basis.as_ref(), s.as_ref()).iter().enumerate() {
            // Every training snapshot is in the final cone: 1e-10 relative (round-off of a
            // Gram-matrix NNLS on unit generators).
            assert!(*e <= 1e-10, "snapshot {j} has relative cone error {e:e}");
        }
        // Compactness ends at ~0 (same 1e-10) and the basis has unit columns.
        assert_close!(*out.compactness.last().expect("nonempty"), 0.0, Tol::abs(1e-10));
        for m in 0..out.basis.ncols() {
            assert_close!(out.basis.col(m).norm_l2(), 1.0, Tol::abs(1e-14)); // one division
        }
    }

    #[test]
    fn duplicates_multiples_and_zeros_are_not_selected() {
        let mut rng = Rng::new(52);
        let base = bumps(&mut rng, 30, 8, (1.0, 4.0));
        // Columns: 0..8 base, 8 = copy of 2, 9 = 3 * column 5, 10 = zero, 11 = copy of 0.
        let s = Mat::from_fn(30, 12, |i, j| match j {
            0..=7 => base[(i, j)],
            8 => base[(i, 2)],
            9 => 3.0 * base[(i, 5)],
            10 => 0.0,
            _ => base[(i, 0)],
        });
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        assert!(!out.selected.contains(&10), "zero snapshot selected: {:?}", out.selected);
        for (a, b) in [(2, 8), (5, 9), (0, 11)] {
            let both = out.selected.contains(&a) && out.selected.contains(&b);
            assert!(!both, "rays {a} and {b} both selected: {:?}", out.selected);
        }
        let mut sorted = out.selected.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), out.selected.len(), "an index selected twice");
        assert!(out.selected.len() <= 8, "at most the 8 distinct rays: {:?}", out.selected);
    }

    #[test]
    fn compactness_is_non_increasing_and_stops_at_tolerance() {
        let mut rng = Rng::new(53);
        let s = bumps(&mut rng, 50, 40, (1.0, 4.0));
        let full = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        assert_close!(full.compactness[0], 1.0, Tol::abs(0.0)); // set exactly
        for w in full.compactness.windows(2) {
            // The cone only grows: C can only decrease, up to NNLS round-off (1e-12).
            assert!(w[1] <= w[0] + 1e-12, "compactness increased: {w:?}");
        }
        let tol = 0.2;
        let cut = cpg(s.as_ref(), CpgParams { tol, ..CpgParams::default() }).expect("converges");
        let m = cut.selected.len();
        assert!(cut.compactness[m] <= tol && cut.compactness[m - 1] > tol);
        // Greedy and deterministic: the truncated run is a prefix of the full one.
        assert_eq!(cut.selected[..], full.selected[..m]);
    }

    #[test]
    fn ties_prefer_larger_norm_then_lower_index() {
        // Empty cone: every relative error is 1, so the first pick is the largest norm.
        let s = Mat::from_fn(3, 4, |i, j| match (i, j) {
            (0, 0) => 1.0,
            (1, 1) | (2, 2) => 3.0,
            (0, 3) => 2.0,
            _ => 0.0,
        });
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        // Columns 1 and 2 tie (error 1, norm 3): lower index first; column 3 is a multiple of
        // column 0, and column 0 (err 1, norm 1) loses to column 3 (err 1, norm 2).
        assert_eq!(out.selected, vec![1, 2, 3]);
    }

    #[test]
    fn all_zero_snapshots_give_an_empty_basis() {
        let out = cpg(Mat::<f64>::zeros(5, 3).as_ref(), CpgParams::default()).expect("trivial");
        assert_eq!((out.basis.nrows(), out.basis.ncols()), (5, 0));
        assert!(out.selected.is_empty());
        assert_eq!(out.compactness.len(), 1);
        assert_close!(out.compactness[0], 0.0, Tol::abs(0.0));
    }

    #[test]
    fn cone_of_the_snapshots_reproduces_them() {
        let mut rng = Rng::new(54);
        let s = bumps(&mut rng, 30, 10, (1.0, 4.0));
        for (j, e) in relative_cone_errors(s.as_ref(), s.as_ref()).iter().enumerate() {
            // s_j = Theta e_j exactly: the residual is round-off, 1e-12 relative.
            assert!(*e <= 1e-12, "snapshot {j}: relative error {e:e}");
        }
    }

    #[test]
    fn tolerance_zero_on_an_ill_conditioned_family_reaches_zero() {
        // Hertz-like pressures sqrt(1 - ((x - c)/a)^2)_+ with slowly moving centre and width:
        // neighbouring snapshots are nearly parallel, the cone is badly conditioned. Every
        // snapshot is selected (each is an extreme ray), so C(m) must end at round-off;
        // warm-started projections alone stalled at ~1e-6 here (KKT test resolution).
        let (n, count) = (60, 64);
        let s = Mat::from_fn(n, count, |i, j| {
            let x = i as f64 / n as f64;
            let mu = j as f64 / (count - 1) as f64;
            let d = (x - 0.3 - 0.4 * mu) / (0.05 + 0.4 * mu);
            (1.0 - d * d).max(0.0).sqrt() * (1.0 + mu)
        });
        let out = cpg(s.as_ref(), CpgParams::default()).expect("converges");
        // 1e-10: round-off of unit generators is ~1e-14; the stalled value was ~1e-7.
        assert_close!(*out.compactness.last().expect("nonempty"), 0.0, Tol::abs(1e-10));
    }
}
