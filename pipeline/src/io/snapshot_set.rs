//! A snapshot set as the stages read it: the primal and dual snapshot matrices and their
//! parameter points. The type lives below `dag` (which writes and loads sets) and `report`
//! (which draws them), so that neither depends on the other for it.

use super::h5::ColMatrix;

/// A loaded snapshot set (training, test or nested level).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TrainingSet {
    /// Primal snapshots, `n_dof x n_snap`.
    pub primal: ColMatrix,
    /// Dual snapshots (pressure), `n_contact x n_snap`.
    pub dual: ColMatrix,
    /// Parameter points, one value per component each.
    pub parameters: Vec<Vec<f64>>,
}

impl TrainingSet {
    /// The columns `cols` of this set, in that order (a copy).
    pub(crate) fn columns(&self, cols: &[usize]) -> TrainingSet {
        let pick = |m: &ColMatrix| {
            let mut data = Vec::with_capacity(m.rows * cols.len());
            for &j in cols {
                data.extend_from_slice(m.col(j));
            }
            ColMatrix { rows: m.rows, cols: cols.len(), data }
        };
        TrainingSet {
            primal: pick(&self.primal),
            dual: pick(&self.dual),
            parameters: cols.iter().map(|&j| self.parameters[j].clone()).collect(),
        }
    }
}
