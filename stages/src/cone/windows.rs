//! Which generators can meet a residual: each column's non-zero rows, indexed by where they
//! start.
//!
//! A contact-pressure snapshot is non-zero only under its contact patch (on ironing-coarse 12
//! of 101 surface nodes). In the dual update `w = Theta^T r` of a Gram-free cone projection a
//! column whose non-zero rows `lo_j..hi_j` miss the residual's `a..b` has `w_j = 0` exactly,
//! so it cannot enter the passive set; the others' `w_j` are summed over the rows they share
//! with the residual ([`dot_window`](crate::kernels::dot_window), the same bits as the whole
//! dot product). The columns that can meet `a..b` start in `a - (widest - 1) .. b`, where
//! `widest` is the largest `hi_j - lo_j`: one bucket per starting row, each holding its columns
//! in ascending order, so a cone's prefix of `m` generators is each bucket's leading part.
//!
//! Cost of finding them: the buckets in that range plus the columns in them, against `n m`
//! products for the whole update.

/// Each column's non-zero rows, and the columns by their first non-zero row.
#[derive(Debug, Clone, Default)]
pub struct ColumnIndex {
    windows: Vec<(usize, usize)>,
    /// `by_start[i]`: the non-zero columns whose first non-zero row is i, ascending.
    by_start: Vec<Vec<usize>>,
    /// Largest `hi - lo` of a column.
    widest: usize,
}

impl ColumnIndex {
    /// An empty index for columns of `n` rows.
    pub fn new(n: usize) -> Self {
        Self { windows: Vec::new(), by_start: vec![Vec::new(); n], widest: 0 }
    }

    /// The index of the columns of an `n x m` matrix.
    pub fn of(theta: faer::MatRef<'_, f64>) -> Self {
        let mut index = Self::new(theta.nrows());
        for j in 0..theta.ncols() {
            index.push(theta.col(j).iter().copied());
        }
        index
    }

    /// Append the next column, given by its entries in row order.
    pub fn push(&mut self, column: impl Iterator<Item = f64>) {
        let j = self.windows.len();
        let (mut lo, mut hi) = (None, 0usize);
        for (i, v) in column.enumerate() {
            if v != 0.0 {
                lo.get_or_insert(i);
                hi = i + 1;
            }
        }
        match lo {
            Some(lo) if lo < self.by_start.len() => {
                self.by_start[lo].push(j);
                self.widest = self.widest.max(hi - lo);
                self.windows.push((lo, hi));
            }
            _ => self.windows.push((0, 0)),
        }
    }

    /// Number of columns indexed.
    pub fn len(&self) -> usize {
        self.windows.len()
    }

    /// True when no column is indexed.
    pub fn is_empty(&self) -> bool {
        self.windows.is_empty()
    }

    /// Column j's non-zero rows `lo..hi` (`0..0` for a zero column).
    pub fn window(&self, j: usize) -> (usize, usize) {
        self.windows[j]
    }

    /// Call `f(j, lo, hi)` for every column `j < m` whose non-zero rows meet `a..b`, with
    /// `lo..hi` the rows they share (in bucket order, not column order).
    pub fn for_each_meeting(&self, m: usize, a: usize, b: usize, mut f: impl FnMut(usize, usize, usize)) {
        if a >= b || self.widest == 0 {
            return;
        }
        let first = a.saturating_sub(self.widest - 1);
        for bucket in &self.by_start[first..b.min(self.by_start.len())] {
            let end = bucket.partition_point(|&j| j < m);
            for &j in &bucket[..end] {
                let (lo, hi) = self.windows[j];
                let (lo, hi) = (lo.max(a), hi.min(b));
                if lo < hi {
                    f(j, lo, hi);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Against the direct check of every column: the same set of columns and shared rows, for
    /// prefixes and windows at both ends, with zero columns and full-height ones.
    #[test]
    fn meeting_columns_are_those_of_a_full_scan() {
        let mut rng = Rng::new(3);
        let n = 40;
        let columns: Vec<Vec<f64>> = (0..300)
            .map(|j| {
                let lo = (rng.uniform_in(0.0, 1.0) * n as f64) as usize;
                let width = if j % 50 == 0 { n } else { 1 + (rng.uniform_in(0.0, 1.0) * 8.0) as usize };
                (0..n).map(|i| if j % 37 != 0 && i >= lo && i < lo + width { 1.0 + i as f64 } else { 0.0 }).collect()
            })
            .collect();
        let mut index = ColumnIndex::new(n);
        columns.iter().for_each(|c| index.push(c.iter().copied()));
        assert_eq!(index.len(), 300);
        for _ in 0..200 {
            let a = (rng.uniform_in(0.0, 1.0) * n as f64) as usize;
            let b = (a + (rng.uniform_in(0.0, 1.0) * 10.0) as usize).min(n);
            let m = (rng.uniform_in(0.0, 1.0) * 301.0) as usize;
            let mut found = Vec::new();
            index.for_each_meeting(m, a, b, |j, lo, hi| found.push((j, lo, hi)));
            found.sort_unstable();
            let expected: Vec<(usize, usize, usize)> = (0..m)
                .filter_map(|j| {
                    let rows: Vec<usize> = (a..b).filter(|&i| columns[j][i] != 0.0).collect();
                    let nz: Vec<usize> = (0..n).filter(|&i| columns[j][i] != 0.0).collect();
                    (!rows.is_empty()).then(|| (j, a.max(nz[0]), b.min(nz[nz.len() - 1] + 1)))
                })
                .collect();
            assert_eq!(found, expected, "window {a}..{b}, prefix {m}");
        }
    }
}
