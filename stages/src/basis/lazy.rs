//! The lazily maintained greedy selection of [`cpg`](super::cpg) and
//! [`cpg_path`](super::cpg_path) (the rule and the refresh band are in the module docs of
//! `cpg`): the candidates' error bounds in a max-heap, each re-projected only when its bound
//! could still win, warm-started from its last coefficients. The cone is held with its Gram
//! matrix ([`ConeProjector`]), or above [`CpgPathParams::wide_above`](super::CpgPathParams::wide_above) snapshots as the
//! generators themselves ([`WideCone`], projected with [`WideNnls`]).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use faer::{Mat, MatRef};

use super::pick::{scan, BAND_ABS, BAND_REL, CPG_FLOOR};
use crate::cone::{copy_column, ColumnIndex, ConeError, ConeProjector, NnlsParams, WideNnls};

/// A candidate's bound in the max-heap (larger error first, then lower index).
#[derive(Debug, Clone, Copy)]
struct Bound {
    err: f64,
    j: usize,
}

impl Ord for Bound {
    fn cmp(&self, other: &Self) -> Ordering {
        self.err.total_cmp(&other.err).then_with(|| other.j.cmp(&self.j))
    }
}

impl PartialOrd for Bound {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Bound {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Bound {}

/// One projection of a candidate in the lazy selection.
#[derive(Debug, Clone)]
pub(crate) struct Refresh {
    /// Cone size it was computed at.
    pub(crate) m: usize,
    /// Relative error.
    pub(crate) err: f64,
    /// Coefficients on the first m generators.
    pub(crate) coeffs: Vec<f64>,
}

/// The non-zero entries of `dense` as `(index, value)`.
pub(super) fn sparse(dense: &[f64]) -> Vec<(usize, f64)> {
    dense.iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(g, v)| (g, *v)).collect()
}

/// Largest Gram matrix [`LazyGreedy`] reserves up front (8 GiB of address space: a path of up
/// to 32 768 generators; the pages are touched only as generators arrive).
const RESERVE_GRAM_BYTES: usize = 8 << 30;

/// The cone of a large selection held without its Gram matrix: the generators themselves
/// (column-major, `n` rows) and one [`WideNnls`] workspace sized for every candidate.
#[derive(Debug)]
struct WideCone {
    n: usize,
    cols: usize,
    data: Vec<f64>,
    /// Each generator's non-zero rows (the projections' dual update visits only the
    /// generators that meet the residual).
    windows: ColumnIndex,
    nnls: WideNnls,
}

impl WideCone {
    fn new(n: usize, most: usize, params: NnlsParams) -> Self {
        Self {
            n,
            cols: 0,
            data: Vec::with_capacity(n.saturating_mul(most)),
            windows: ColumnIndex::new(n),
            nnls: WideNnls::new(n, most, params),
        }
    }

    fn theta(&self) -> MatRef<'_, f64> {
        columns(&self.data, self.n, self.cols)
    }

    fn push(&mut self, column: &[f64]) {
        self.data.extend_from_slice(column);
        self.windows.push(column.iter().copied());
        self.cols += 1;
    }
}

/// The first `cols` columns of `n` rows stored column-major in `data`.
fn columns(data: &[f64], n: usize, cols: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(&data[..n * cols], n, cols)
}

/// A lazily maintained greedy selection; see the module docs.
#[derive(Debug)]
pub(crate) struct LazyGreedy<'a> {
    s: MatRef<'a, f64>,
    norms: &'a [f64],
    /// The cone with its Gram matrix (empty while `wide` holds the cone).
    pub(crate) projector: ConeProjector,
    /// The cone of a selection over more than [`CpgPathParams::wide_above`](super::CpgPathParams::wide_above) snapshots.
    wide: Option<WideCone>,
    heap: BinaryHeap<Bound>,
    /// Cone size at which each candidate's bound was computed.
    stamp: Vec<usize>,
    /// Last coefficients of each candidate as `(generator, value)` over its support (warm
    /// start of its next projection). Sparse: a candidate's support has at most n entries,
    /// while dense vectors of the cone's size would hold ~N^2/2 numbers by the end of a path.
    coeffs: Vec<Vec<(usize, f64)>>,
    /// Dense coefficients of the candidate being projected; all zero between refreshes.
    dense: Vec<f64>,
    /// `Theta^T s_j` of each candidate, extended when it is next projected.
    atb: Vec<Vec<f64>>,
    lambda: Vec<f64>,
    column: Vec<f64>,
    /// Every projection on a cone of fewer than `record_below` generators, per snapshot
    /// (recorded for the leave-one-out continuations, which start below `max_rank`).
    pub(super) history: Option<Vec<Vec<Refresh>>>,
    record_below: usize,
}

/// One greedy step: the pick and the freshly projected candidates it was chosen from.
#[derive(Debug)]
pub(crate) struct Step {
    pub(crate) pick: usize,
    /// `(index, error)` in ascending index order.
    pub(crate) band: Vec<(usize, f64)>,
}

impl<'a> LazyGreedy<'a> {
    /// The empty cone: every non-zero snapshot is a candidate with its exact error
    /// `||s_j|| / ||s_j||`, exactly 1 in floating point (x / x = 1 for finite x != 0).
    /// `wide`: hold the cone without its Gram matrix ([`WideCone`]).
    pub(super) fn new(s: MatRef<'a, f64>, norms: &'a [f64], nnls: NnlsParams, record_below: usize, wide: bool) -> Self {
        let candidates = (0..s.ncols()).filter(|&j| norms[j] > 0.0).map(|j| (j, 1.0, 0, Vec::new()));
        let mut projector = ConeProjector::empty(s.nrows(), nnls);
        // Every generator is a candidate, so the cone never holds more than the non-zero
        // snapshots: reserve that much once (address space; see `Nnls::reserve`), within
        // `RESERVE_GRAM_BYTES`; a larger path grows by doubling.
        let most = norms.iter().filter(|&&v| v > 0.0).count();
        if !wide && most.saturating_mul(most).saturating_mul(std::mem::size_of::<f64>()) <= RESERVE_GRAM_BYTES {
            projector.reserve(most);
        }
        let mut out = Self::resume(s, norms, projector, candidates);
        out.wide = wide.then(|| WideCone::new(s.nrows(), most, nnls));
        out.history = (record_below > 0).then(|| vec![Vec::new(); s.ncols()]);
        out.record_below = record_below;
        out
    }

    /// Continue from a cone (`projector`) with the given candidates
    /// `(index, bound, cone size of the bound, coefficients)`.
    pub(crate) fn resume(
        s: MatRef<'a, f64>,
        norms: &'a [f64],
        projector: ConeProjector,
        candidates: impl IntoIterator<Item = (usize, f64, usize, Vec<f64>)>,
    ) -> Self {
        let count = s.ncols();
        let mut out = Self {
            s,
            norms,
            projector,
            wide: None,
            heap: BinaryHeap::new(),
            stamp: vec![0; count],
            coeffs: vec![Vec::new(); count],
            dense: Vec::new(),
            atb: vec![Vec::new(); count],
            lambda: vec![0.0; s.nrows()],
            column: vec![0.0; s.nrows()],
            history: None,
            record_below: 0,
        };
        for (j, err, m, coeffs) in candidates {
            out.stamp[j] = m;
            out.coeffs[j] = sparse(&coeffs);
            out.heap.push(Bound { err, j });
        }
        out
    }

    /// Number of generators so far.
    pub(crate) fn len(&self) -> usize {
        self.wide.as_ref().map_or_else(|| self.projector.ncols(), |w| w.cols)
    }

    /// The generators selected so far (n x k).
    pub(super) fn basis(&self) -> Mat<f64> {
        match &self.wide {
            Some(w) => w.theta().to_owned(),
            None => self.projector.basis().to_owned(),
        }
    }

    /// A projector (with its Gram matrix) onto the cone of the first `m` generators.
    pub(super) fn prefix(&self, m: usize) -> ConeProjector {
        match &self.wide {
            Some(w) => ConeProjector::new(w.theta().subcols(0, m), self.projector.params()),
            None => self.projector.prefix(m),
        }
    }

    /// Re-project candidate j on the current cone without its Gram matrix, warm-started from
    /// its last support.
    fn refresh_wide(&mut self, j: usize) -> Result<f64, ConeError> {
        let Some(wide) = self.wide.as_mut() else { unreachable!("refresh_wide on a Gram cone") };
        let m = wide.cols;
        copy_column(self.s, j, &mut self.lambda);
        // `wide.theta()` would borrow the workspace `wide.nnls` projects with.
        let theta = columns(&wide.data, wide.n, m);
        let err = wide
            .nnls
            .project_windowed(theta, Some(&wide.windows), &self.lambda, &mut self.coeffs[j])
            .map(|r| r / self.norms[j]);
        if let (Ok(err), Some(h)) = (&err, self.history.as_mut().filter(|_| m < self.record_below)) {
            let mut coeffs = vec![0.0; m];
            for &(g, v) in &self.coeffs[j] {
                coeffs[g] = v;
            }
            h[j].push(Refresh { m, err: *err, coeffs });
        }
        self.stamp[j] = m;
        err
    }

    /// Re-project candidate j on the current cone, warm-started from its last coefficients.
    fn refresh(&mut self, j: usize) -> Result<f64, ConeError> {
        if self.wide.is_some() {
            return self.refresh_wide(j);
        }
        let m = self.projector.ncols();
        self.dense.resize(m, 0.0);
        for &(g, v) in &self.coeffs[j] {
            self.dense[g] = v;
        }
        copy_column(self.s, j, &mut self.lambda);
        let atb = &mut self.atb[j];
        for g in atb.len()..m {
            atb.push(self.projector.dot_column(g, &self.lambda));
        }
        let err = self.projector.project_warm_atb(&self.lambda, atb, &mut self.dense).map(|r| r / self.norms[j]);
        if let (Ok(err), Some(h)) = (&err, self.history.as_mut().filter(|_| m < self.record_below)) {
            h[j].push(Refresh { m, err: *err, coeffs: self.dense.clone() });
        }
        let support = &mut self.coeffs[j];
        support.clear();
        for (g, v) in self.dense.iter_mut().enumerate().filter(|(_, v)| **v != 0.0) {
            support.push((g, *v));
            *v = 0.0;
        }
        self.stamp[j] = m;
        err
    }

    /// Select the next generator and add it to the cone; `None` when every candidate is in
    /// the cone.
    pub(crate) fn step(&mut self) -> Result<Option<Step>, ConeError> {
        let m = self.len();
        let mut band = Vec::new();
        let mut best = f64::NEG_INFINITY;
        while let Some(&top) = self.heap.peek() {
            if !band.is_empty() && top.err < best * (1.0 - BAND_REL) - BAND_ABS {
                break;
            }
            self.heap.pop();
            let err = if self.stamp[top.j] == m { top.err } else { self.refresh(top.j)? };
            if err <= CPG_FLOOR {
                self.coeffs[top.j] = Vec::new(); // represented: never a candidate again
                self.atb[top.j] = Vec::new();
                continue;
            }
            band.push((top.j, err));
            best = best.max(err);
        }
        band.sort_unstable_by_key(|b| b.0);
        let Some(pick) = scan(band.iter().copied(), self.norms, None) else {
            return Ok(None);
        };
        for &(j, err) in band.iter().filter(|b| b.0 != pick) {
            self.heap.push(Bound { err, j });
        }
        self.coeffs[pick] = Vec::new();
        self.atb[pick] = Vec::new();
        copy_column(self.s, pick, &mut self.column);
        let norm = self.norms[pick];
        self.column.iter_mut().for_each(|v| *v /= norm);
        match self.wide.as_mut() {
            Some(w) => w.push(&self.column),
            None => self.projector.push_column(&self.column),
        }
        Ok(Some(Step { pick, band }))
    }
}
