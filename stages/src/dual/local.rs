//! Local bases: the range `[a, b]` of the first parameter component over the training points is
//! cut into K cells of width `w = (b - a) / K`; cell c trains a CPG basis (tolerance 0) on every
//! training point with `mu_1` in `[a + c w - overlap w, a + (c + 1) w + overlap w]`, and a
//! pressure at `mu` is projected on the cone of the cell holding `mu_1` (points outside `[a, b]`
//! use the nearest cell; a point on an inner edge belongs to the cell above it). With several
//! parameter components only the first one is cut (the cells are slabs). A cell without a
//! training point is refused when built: K too large for the training set.

use faer::Mat;

use super::{cpg_generators, ConePrefix, DualApprox, DualError, Fact, Training};

/// One CPG basis per cell.
#[derive(Debug)]
pub struct LocalBases {
    lo: f64,
    width: f64,
    cells: Vec<ConePrefix>,
    members: Vec<usize>,
}

impl LocalBases {
    /// Cut the training range into `cells` cells with `overlap` (in cell widths, >= 0).
    pub fn build(training: &Training<'_>, cells: usize, overlap: f64) -> Result<Self, DualError> {
        let s = training.snapshots;
        let first: Vec<f64> = training.params.iter().map(|p| p.first().copied().unwrap_or(0.0)).collect();
        let lo = first.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = first.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if cells == 0 || first.is_empty() {
            return Err(DualError::NotApplicable("local bases need at least one cell and one training point".into()));
        }
        let width = if hi > lo { (hi - lo) / cells as f64 } else { 1.0 };
        let mut out = Self { lo, width, cells: Vec::new(), members: Vec::new() };
        for c in 0..cells {
            let a = lo + (c as f64 - overlap) * width;
            let b = lo + (c as f64 + 1.0 + overlap) * width;
            let keep: Vec<usize> = (0..first.len()).filter(|&j| first[j] >= a && first[j] <= b).collect();
            if keep.is_empty() {
                return Err(DualError::NotApplicable(format!(
                    "cell {c} of {cells} ([{a}, {b}]) holds no training point: use fewer cells or more training points"
                )));
            }
            let sub = Mat::from_fn(s.nrows(), keep.len(), |i, k| s[(i, keep[k])]);
            out.cells.push(ConePrefix::new(cpg_generators(sub.as_ref(), training.max_m())?.as_ref()));
            out.members.push(keep.len());
        }
        Ok(out)
    }

    /// The cell of the parameter point `mu`.
    pub fn cell_of(&self, mu: &[f64]) -> usize {
        let x = mu.first().copied().unwrap_or(0.0);
        let c = ((x - self.lo) / self.width).floor();
        if c.is_nan() || c < 0.0 {
            0
        } else {
            (c as usize).min(self.cells.len() - 1)
        }
    }
}

impl DualApprox for LocalBases {
    fn residuals(&self, s: &[f64], mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        self.cells[self.cell_of(mu)].residuals_of(s, ms, out)
    }

    fn size(&self) -> usize {
        self.cells.iter().map(DualApprox::size).max().unwrap_or(0)
    }

    fn cone_basis(&self, mu: &[f64], m: usize) -> Option<Mat<f64>> {
        self.cells[self.cell_of(mu)].cone_basis(mu, m)
    }

    /// The group is the cell of `mu`.
    fn coefficients(&self, s: &[f64], mu: &[f64], m: usize) -> Result<Option<(usize, Vec<f64>)>, DualError> {
        let c = self.cell_of(mu);
        Ok(Some((c, self.cells[c].coords(s, m)?)))
    }

    fn member(&self, group: usize, alpha: &[f64], _mu: &[f64], _m: usize, out: &mut [f64]) {
        self.cells[group].combine(alpha, out);
    }

    fn depends_on_mu(&self) -> bool {
        true
    }

    fn cell_of(&self, mu: &[f64]) -> Option<usize> {
        Some(LocalBases::cell_of(self, mu))
    }

    fn facts(&self) -> Vec<Fact> {
        let mut f = Vec::new();
        for (c, (cone, &n)) in self.cells.iter().zip(&self.members).enumerate() {
            f.push(Fact::new(&format!("cell_{c}_snapshots"), None, n as f64));
            f.push(Fact::new(&format!("cell_{c}_generators"), None, cone.size() as f64));
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Two families of pressures on disjoint supports: with two cells each cell's cone holds
    /// its own family only, so one generator per cell reproduces a rank-one family exactly,
    /// while the global cone needs both.
    #[test]
    fn each_cell_sees_its_own_snapshots() {
        let mut rng = Rng::new(21);
        let n = 10;
        let params: Vec<Vec<f64>> = (0..8).map(|j| vec![j as f64]).collect();
        let s = Mat::from_fn(n, 8, |i, j| {
            let left = j < 4;
            if left == (i < 5) {
                (1.0 + i as f64) * (1.0 + j as f64)
            } else {
                0.0
            }
        });
        let _ = rng.uniform();
        let ms = [1usize, 2];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &[], across: &[], ms: &ms };
        let local = LocalBases::build(&t, 2, 0.0).expect("build");
        assert_eq!(local.cell_of(&[1.0]), 0);
        assert_eq!(local.cell_of(&[6.0]), 1);
        assert_eq!(local.cell_of(&[-3.0]), 0);
        assert_eq!(local.cell_of(&[99.0]), 1);
        for j in 0..8 {
            let col: Vec<f64> = (0..n).map(|i| s[(i, j)]).collect();
            let mut out = [0.0; 2];
            local.residuals(&col, &params[j], &ms, &mut out).expect("project");
            assert!(out[0] <= 1e-12 * crate::cone::norm2(&col), "snapshot {j}: {out:?}");
        }
        assert!(LocalBases::build(&t, 20, 0.0).is_err(), "empty cells are refused");
    }
}
