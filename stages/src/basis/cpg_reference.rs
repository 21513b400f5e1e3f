//! The direct CPG (kept as the slow reference for tests and benchmarks): after every addition
//! every snapshot not yet in the cone is re-projected ([`GrowingCone::push`]) and the next
//! generator is chosen by one scan over all of them. O(N) projections per step.
//!
//! [`cpg`](super::cpg) selects the same generators lazily; `cpg_path` computes the same
//! compactness curve with one [`GrowingCone`] pass over that selection.

use faer::{Mat, MatRef};

use super::cpg::{Cpg, CpgParams};
use super::pick::{scan, CPG_FLOOR};
use crate::cone::{copy_column, ConeError, GrowingCone};

/// Greedy cone basis of the snapshots `s` (n x N), by definition (see [`cpg`](super::cpg)).
pub fn cpg_reference(s: MatRef<'_, f64>, params: CpgParams) -> Result<Cpg, ConeError> {
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

/// The not-yet-selected snapshot with the largest relative error above [`CPG_FLOOR`].
fn next_snapshot(cone: &GrowingCone<'_>, selected: &[usize]) -> Option<usize> {
    let candidates = (0..cone.norms().len())
        .filter_map(|j| cone.relative_error(j).map(|e| (j, e)))
        .filter(|(j, e)| *e > CPG_FLOOR && !selected.contains(j));
    scan(candidates, cone.norms(), None)
}
