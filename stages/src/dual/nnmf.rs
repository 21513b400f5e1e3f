//! Non-negative matrix factorisation of the pressure snapshots (Lee and Seung 1999; as a dual
//! basis, Balajewicz, Amsallem and Farhat 2016).
//!
//! For a rank m, `min_{W >= 0, H >= 0} f(W, H) = 1/2 ||S - W H||_F^2` (W n x m, H m x N) by
//! hierarchical alternating least squares (HALS, Cichocki and Phan 2009): each sweep updates the
//! rows of H one at a time, then the columns of W, each by the exact minimiser of f over that
//! row (column) alone, clipped at zero,
//!
//! ```text
//! H[k, :] <- max(0, H[k, :] + (W^T S - W^T W H)[k, :] / (W^T W)[k, k])
//! W[:, k] <- max(0, W[:, k] + (S H^T - W H H^T)[:, k] / (H H^T)[k, k])
//! ```
//!
//! with `W^T S`, `S H^T` and the Gram matrices `W^T W`, `H H^T` each summed by fused
//! multiply-adds in ascending index from 0, and the terms of `W^T W H` (`W H H^T`) subtracted
//! in ascending order. The columns of W are scaled to unit norm once, after the last sweep
//! (H's rows take the scale). The updates are equivariant under that scaling (scaling W's
//! column k by `c` and H's row k by `1/c` scales the next iterates the same way), so scaling
//! after every sweep, as HALS is often written, changes only the rounding; it cost a third
//! Gram product and `m (n + N)` divisions and products a sweep. The start is NNDSVD
//! (Boutsidis and Gallopoulos 2008): from the thin SVD of S, the first pair
//! `sqrt(s_1) (|u_1|, |v_1|)` and, for each further singular triple, the dominant one of the
//! positive and negative parts of `(u_j, v_j)`. A family of ranks `m_1 < m_2 < ...`
//! ([`NnmfFamily`]) starts rank `m_1` from NNDSVD and each further rank from the rank before's
//! factors with the further NNDSVD components appended: NNDSVD's start of rank `m_{j+1}` with
//! its first `m_j` components already refined. Everything is deterministic: the start is a
//! function of S, the sweeps are in a fixed order, and the run stops after `iterations` sweeps or
//! once a sweep lowers f by less than [`STALL_REL`] of f (iterations and the final relative
//! residual `||S - W H||_F / ||S||_F` are recorded). The factorisation is not nested in m: each
//! rank of the grid has its own basis.
//!
//! The dual basis of rank m is W; a pressure is approximated on the cone of its columns.

use faer::{Mat, MatRef};

use super::{ConePrefix, DualApprox, DualError, Fact};

/// Stop once a sweep lowers `f` by less than this fraction of it. On ironing-fine's family
/// (ranks 1..=32, warm-started) 3e-4 reads C, the test error and G at m = 16 and 32 within
/// 3 % of 300 sweeps each, and every metric averaged over the ranks within 0.5 % of 1e-4's,
/// at 0.46 s instead of 0.67 s (docs/design-notes.md, "NNMF: rank warm starts and a relative
/// stopping rule").
pub const STALL_REL: f64 = 3e-4;

/// One rank's factorisation.
#[derive(Debug, Clone)]
pub struct Nnmf {
    /// n x m, unit columns (a zero column stays zero).
    pub w: Mat<f64>,
    /// m x N.
    pub h: Mat<f64>,
    /// Sweeps run.
    pub iterations: usize,
    /// `||S - W H||_F / ||S||_F` (0 for a zero S).
    pub relative_residual: f64,
}

/// The thin SVD of S that every rank's NNDSVD start reads (`None` for an empty or zero S, whose
/// start is zero): `U`, the singular values, `V`.
struct Spectrum {
    u: Mat<f64>,
    sv: Vec<f64>,
    v: Mat<f64>,
}

impl Spectrum {
    fn of(s: MatRef<'_, f64>) -> Result<Option<Self>, DualError> {
        if s.nrows() == 0 || s.ncols() == 0 || s.norm_l2() == 0.0 {
            return Ok(None);
        }
        let svd = s.thin_svd().map_err(|_| DualError::Pod(crate::basis::PodError::SvdNoConvergence))?;
        let sv = svd.S().column_vector().iter().copied().collect();
        Ok(Some(Self { u: svd.U().to_owned(), sv, v: svd.V().to_owned() }))
    }
}

/// The NNDSVD start of rank m.
pub fn nndsvd(s: MatRef<'_, f64>, m: usize) -> Result<(Mat<f64>, Mat<f64>), DualError> {
    Ok(nndsvd_from(Spectrum::of(s)?.as_ref(), s.nrows(), s.ncols(), m))
}

/// The NNDSVD start of rank m of an n x count S from its thin SVD.
fn nndsvd_from(spectrum: Option<&Spectrum>, n: usize, count: usize, m: usize) -> (Mat<f64>, Mat<f64>) {
    let mut w = Mat::zeros(n, m);
    let mut h = Mat::zeros(m, count);
    let Some(Spectrum { u, sv, v }) = spectrum else { return (w, h) };
    for j in 0..m.min(sv.len()) {
        if sv[j] <= 0.0 {
            break;
        }
        let x: Vec<f64> = (0..n).map(|i| u[(i, j)]).collect();
        let y: Vec<f64> = (0..count).map(|i| v[(i, j)]).collect();
        let (wx, hy, sigma) = if j == 0 {
            (x.iter().map(|a| a.abs()).collect::<Vec<_>>(), y.iter().map(|a| a.abs()).collect::<Vec<_>>(), 1.0)
        } else {
            let pos = |z: &[f64]| z.iter().map(|a| a.max(0.0)).collect::<Vec<_>>();
            let neg = |z: &[f64]| z.iter().map(|a| (-a).max(0.0)).collect::<Vec<_>>();
            let (xp, xn, yp, yn) = (pos(&x), neg(&x), pos(&y), neg(&y));
            let nrm = |z: &[f64]| z.iter().map(|a| a * a).sum::<f64>().sqrt();
            let (mp, mn) = (nrm(&xp) * nrm(&yp), nrm(&xn) * nrm(&yn));
            let (a, b, mm) = if mp >= mn { (xp, yp, mp) } else { (xn, yn, mn) };
            if mm <= 0.0 {
                continue;
            }
            let (na, nb) = (nrm(&a), nrm(&b));
            (a.iter().map(|t| t / na).collect(), b.iter().map(|t| t / nb).collect(), mm)
        };
        let scale = (sv[j] * sigma).sqrt();
        for i in 0..n {
            w[(i, j)] = scale * wx[i];
        }
        for c in 0..count {
            h[(j, c)] = scale * hy[c];
        }
    }
    (w, h)
}

/// `f = 1/2 ||S - W H||^2` from the explicit residual.
fn objective(s: MatRef<'_, f64>, w: MatRef<'_, f64>, h: MatRef<'_, f64>) -> f64 {
    let r = s - w * h;
    0.5 * r.squared_norm_l2()
}

/// HALS from the NNDSVD start, at most `iterations` sweeps.
pub fn nnmf(s: MatRef<'_, f64>, m: usize, iterations: usize, stall: f64) -> Result<Nnmf, DualError> {
    Ok(nnmf_from(s, &Sparse::of(s), Spectrum::of(s)?.as_ref(), m, (iterations, stall)))
}

/// W's columns scaled to unit norm, H's rows taking the scale (`W H` unchanged; a zero column
/// stays zero).
fn normalise(w: &mut Mat<f64>, h: &mut Mat<f64>) {
    for k in 0..w.ncols() {
        let norm = w.col(k).iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > 0.0 {
            w.col_mut(k).iter_mut().for_each(|x| *x /= norm);
            h.row_mut(k).iter_mut().for_each(|x| *x *= norm);
        }
    }
}

/// [`nnmf`] from S's non-zeros and thin SVD (shared by the ranks of a family).
fn nnmf_from(s: MatRef<'_, f64>, sparse: &Sparse, spectrum: Option<&Spectrum>, m: usize, stop: (usize, f64)) -> Nnmf {
    let (w, h) = nndsvd_from(spectrum, s.nrows(), s.ncols(), m);
    hals(s, sparse, (w.as_ref(), h.as_ref()), stop)
}

/// HALS sweeps from the start `(W, H)` until a sweep lowers `f` by at most `stall` of it or
/// `iterations` sweeps ran (`stop = (iterations, stall)`; the families use [`STALL_REL`], a
/// test that wants a converged factorisation 0); W's columns scaled to unit norm at the end.
fn hals(s: MatRef<'_, f64>, sparse: &Sparse, (w, h): (MatRef<'_, f64>, MatRef<'_, f64>), stop: (usize, f64)) -> Nnmf {
    let (iterations, stall) = stop;
    let total = s.squared_norm_l2();
    let mut f = objective(s, w, h);
    let mut done = 0;
    let mut work = Sweep::new(w, h);
    for _ in 0..iterations {
        let next = work.run(sparse, total);
        done += 1;
        let stalled = f - next <= stall * f;
        f = next;
        if stalled {
            break;
        }
    }
    let relative_residual = if total > 0.0 { (2.0 * f / total).sqrt() } else { 0.0 };
    let (mut w, mut h) = work.factors();
    normalise(&mut w, &mut h);
    Nnmf { w, h, iterations: done, relative_residual }
}

/// Rank `m`'s start from a lower rank's factors: their columns of W and rows of H, and the
/// NNDSVD components beyond them (rank m's NNDSVD start is that of the lower rank with the
/// further components, so this is the NNDSVD start with the first components already
/// refined).
fn extend(lower: &Nnmf, spectrum: Option<&Spectrum>, m: usize) -> (Mat<f64>, Mat<f64>) {
    let (n, count) = (lower.w.nrows(), lower.h.ncols());
    let (mut w, mut h) = nndsvd_from(spectrum, n, count, m);
    let r = lower.w.ncols().min(m);
    for k in 0..r {
        w.col_mut(k).copy_from(lower.w.col(k));
        h.row_mut(k).copy_from(lower.h.row(k));
    }
    (w, h)
}

/// S's non-zero entries by column and by row, each in ascending index order: the two products
/// of S a sweep forms, `Wᵀ S` and `S Hᵀ`, over them alone. A pressure snapshot is zero off its
/// contact zone (ironing-fine: 11 % of S's entries are non-zero), so the products cost
/// `m nnz(S)` instead of `m n N`.
///
/// Each entry is the sum of its products by fused multiply-adds in ascending index, from 0:
/// `acc <- fma(a_i, b_i, acc)`. A zero term leaves such a sum unchanged bit for bit (`acc` never
/// becomes `-0` from a `+0` start, and `acc + (±0) = acc` otherwise), so skipping S's zeros
/// gives the sum over every index; the tests check the sweep against the formula. faer's dense
/// product, used before, sums these shapes the same way but for one: with m = 1 its
/// matrix-vector kernel keeps several partial sums. On ironing-fine every rank's basis but
/// m = 1's is the same, bit for bit, and m = 1's tables moved by at most 2e-15 relative; a
/// family's factorisations take 0.24 s instead of 0.32 s.
struct Sparse {
    n: usize,
    count: usize,
    /// Column c's entries at `col_ptr[c]..col_ptr[c + 1]`: (row, value).
    col_ptr: Vec<usize>,
    by_col: Vec<(usize, f64)>,
    /// Row i's entries at `row_ptr[i]..row_ptr[i + 1]`: (column, value).
    row_ptr: Vec<usize>,
    by_row: Vec<(usize, f64)>,
}

impl Sparse {
    fn of(s: MatRef<'_, f64>) -> Self {
        let (n, count) = (s.nrows(), s.ncols());
        let (mut col_ptr, mut by_col) = (vec![0], Vec::new());
        for c in 0..count {
            by_col.extend((0..n).filter(|&i| s[(i, c)] != 0.0).map(|i| (i, s[(i, c)])));
            col_ptr.push(by_col.len());
        }
        let (mut row_ptr, mut by_row) = (vec![0], Vec::new());
        for i in 0..n {
            by_row.extend((0..count).filter(|&c| s[(i, c)] != 0.0).map(|c| (c, s[(i, c)])));
            row_ptr.push(by_row.len());
        }
        Self { n, count, col_ptr, by_col, row_ptr, by_row }
    }

    /// `Wᵀ S` into `out` (m x N, `[c * m + k]`) from W row by row, each row padded with zeros
    /// to `stride` entries (`w_rows[i * stride + k]`, `stride` a multiple of [`BLOCK`]).
    fn wt_s(&self, w_rows: &[f64], m: usize, stride: usize, out: &mut [f64]) {
        let col = |c: usize| &self.by_col[self.col_ptr[c]..self.col_ptr[c + 1]];
        products(self.count, col, w_rows, m, stride, out);
    }

    /// `S Hᵀ` into `out` (n x m, `[i * m + k]`) from H column by column, each padded with zeros
    /// to `stride` entries (`h_cols[c * stride + k]`).
    fn s_ht(&self, h_cols: &[f64], m: usize, stride: usize, out: &mut [f64]) {
        let row = |i: usize| &self.by_row[self.row_ptr[i]..self.row_ptr[i + 1]];
        products(self.n, row, h_cols, m, stride, out);
    }
}

/// Lanes of the products' partial sums ([`products`]): one 512-bit register of doubles.
const BLOCK: usize = 8;

/// `m` rounded up to whole [`BLOCK`]s: the stride of the padded copies of W and H.
fn padded(m: usize) -> usize {
    m.div_ceil(BLOCK) * BLOCK
}

/// `out[o * m + k] = sum over (j, v) in nz(o) of v * rows[j * stride + k]` for `o < outputs`,
/// `k < m`, each by fused multiply-adds in the order of `nz(o)` from 0. One, two or four blocks of
/// [`BLOCK`] entries at a time, their sums held in registers over the pass through `nz(o)`
/// (each block one chain of dependent adds, so up to four for the core to overlap).
fn products<'a>(
    outputs: usize,
    nz: impl Fn(usize) -> &'a [(usize, f64)],
    rows: &[f64],
    m: usize,
    stride: usize,
    out: &mut [f64],
) {
    for o in 0..outputs {
        let out = &mut out[o * m..(o + 1) * m];
        let mut kb = 0;
        while kb < m {
            // three blocks as two and one: LLVM compiles three 8-wide accumulators into
            // shuffles (ironing-fine's factorisations at m = 20 and 24 took longer than at 32)
            let blocks = match (m - kb).div_ceil(BLOCK) {
                1 => 1,
                2 | 3 => 2,
                _ => 4,
            };
            match blocks {
                1 => block_sums::<1>(nz(o), rows, stride, kb, out),
                2 => block_sums::<2>(nz(o), rows, stride, kb, out),
                _ => block_sums::<4>(nz(o), rows, stride, kb, out),
            }
            kb += blocks * BLOCK;
        }
    }
}

/// `acc <- fma(x, v, acc)` for the `NB` blocks `x` of `rows` from `at`.
#[inline(always)]
fn accumulate<const NB: usize>(acc: &mut [[f64; BLOCK]; NB], rows: &[f64], at: usize, v: f64) {
    let row: &[f64] = &rows[at..at + NB * BLOCK];
    for (b, acc) in acc.iter_mut().enumerate() {
        let x: &[f64; BLOCK] = row[b * BLOCK..(b + 1) * BLOCK].try_into().expect("a block");
        for t in 0..BLOCK {
            acc[t] = x[t].mul_add(v, acc[t]);
        }
    }
}

/// The first `out.len() - kb` (at most `NB` blocks) sums into `out` from entry `kb`.
#[inline(always)]
fn store<const NB: usize>(acc: &[[f64; BLOCK]; NB], kb: usize, out: &mut [f64]) {
    for (b, acc) in acc.iter().enumerate() {
        for (t, &a) in acc.iter().enumerate() {
            if let Some(o) = out.get_mut(kb + b * BLOCK + t) {
                *o = a;
            }
        }
    }
}

/// [`products`] of one output for the `NB` blocks from entry `kb`.
#[inline(always)]
fn block_sums<const NB: usize>(nz: &[(usize, f64)], rows: &[f64], stride: usize, kb: usize, out: &mut [f64]) {
    let mut acc = [[0.0f64; BLOCK]; NB];
    for &(j, v) in nz {
        accumulate(&mut acc, rows, j * stride + kb, v);
    }
    store(&acc, kb, out);
}

/// Lanes updated together by [`gauss_seidel`]: independent rows (of W) or columns (of H) whose
/// serial sums interleave, so their latency chains overlap (16 doubles: two 512-bit registers;
/// on ironing-fine's factorisations 8 % faster than one register, and 32 lanes slower again).
const LANES: usize = 16;

/// The factors and one HALS sweep's scratch, allocated once per factorisation.
///
/// - H is held by rows (`h[l * np + c]`) and W by columns (`w[l * nw + i]`), each padded with
///   zero columns (rows) to `np` (`nw`), a whole number of [`LANES`]: the Gauss-Seidel passes
///   update [`LANES`] columns of H (rows of W) in place, each unknown's lanes contiguous. A
///   zero lane stays zero.
/// - `w_rows` (W by rows) and `h_cols` (H by columns), each padded to a whole number of
///   [`BLOCK`]s, are the copies the products with S ([`Sparse`]) and the Gram matrices read.
/// - `system` holds the Gauss-Seidel passes' coefficients and right-hand sides ([`Lanes`]).
/// - `wtw` is W's Gram matrix at the W the next sweep starts from: the sweep that updates W
///   forms it for its objective, and W is not rescaled between sweeps.
struct Sweep {
    m: usize,
    n: usize,
    count: usize,
    np: usize,
    nw: usize,
    h: Vec<f64>,
    w: Vec<f64>,
    system: Lanes,
    w_rows: Vec<f64>,
    h_cols: Vec<f64>,
    wts: Vec<f64>,
    sht: Vec<f64>,
    wtw: Vec<f64>,
    hht: Vec<f64>,
    /// Per column of W: `sum_i W[i, k] (S Hᵀ)[i, k]`.
    dots: Vec<f64>,
}

impl Sweep {
    /// The sweeps from W (n x m) and H (m x N), with W's Gram matrix formed for the first one.
    fn new(w: MatRef<'_, f64>, h: MatRef<'_, f64>) -> Self {
        let (n, m, count) = (w.nrows(), w.ncols(), h.ncols());
        let (np, nw) = (count.div_ceil(LANES) * LANES, n.div_ceil(LANES) * LANES);
        let mut sweep = Self {
            m,
            n,
            count,
            np,
            nw,
            h: vec![0.0; m * np],
            w: vec![0.0; m * nw],
            system: Lanes { m, nz: Vec::with_capacity(m * m), nz_ptr: vec![0; m + 1], b: vec![0.0; m * LANES] },
            w_rows: vec![0.0; n * padded(m)],
            h_cols: vec![0.0; padded(m) * count],
            wts: vec![0.0; m * count],
            sht: vec![0.0; n * m],
            wtw: vec![0.0; m * m],
            hht: vec![0.0; m * m],
            dots: vec![0.0; m],
        };
        for l in 0..m {
            sweep.w[l * nw..l * nw + n].iter_mut().zip(w.col(l).iter()).for_each(|(o, &x)| *o = x);
            sweep.h[l * np..l * np + count].iter_mut().zip(h.row(l).iter()).for_each(|(o, &x)| *o = x);
        }
        sweep.copy_w();
        gram(&sweep.w_rows, n, m, padded(m), &mut sweep.wtw);
        sweep
    }

    /// The factors (W, H).
    fn factors(&self) -> (Mat<f64>, Mat<f64>) {
        let (m, n, count) = (self.m, self.n, self.count);
        let w = Mat::from_fn(n, m, |i, l| self.w[l * self.nw + i]);
        let h = Mat::from_fn(m, count, |l, c| self.h[l * self.np + c]);
        (w, h)
    }

    /// W by rows into `w_rows`.
    fn copy_w(&mut self) {
        let stride = padded(self.m);
        for k in 0..self.m {
            for (i, &x) in self.w[k * self.nw..k * self.nw + self.n].iter().enumerate() {
                self.w_rows[i * stride + k] = x;
            }
        }
    }

    /// H by columns into `h_cols`.
    fn copy_h(&mut self) {
        let stride = padded(self.m);
        for k in 0..self.m {
            for (c, &x) in self.h[k * self.np..k * self.np + self.count].iter().enumerate() {
                self.h_cols[c * stride + k] = x;
            }
        }
    }

    /// One HALS sweep (H rows, then W columns). Each update is, for k ascending,
    /// `x[k] <- max(0, x[k] + (b[k] - sum_l a[k, l] x[l]) / a[k, k])` over one column of H
    /// (`a = W^T W`, `b` its column of `W^T S`) or one row of W (`a = H H^T`, `b` its row of
    /// `S H^T`); H's column c depends only on column c and W's row i only on row i, so the
    /// sums and operations are those of the formulas in the module docs in the same order
    /// ([`sweep_reference`](tests) checks it bit for bit), [`LANES`] columns or rows at a
    /// time. A Gram entry that is zero (W and H are non-negative and sparse: on ironing-fine
    /// 12-15 % of W's entries and 17-19 % of H's are non-zero, and about half the Gram entries
    /// are zero) is skipped: its term `0 x[l]` is `±0`, and `g - (±0)` is `g` bit for bit, since
    /// `g` is never `-0` (it starts from a sum of fused multiply-adds from `+0`, and an exact
    /// cancellation rounds to `+0`).
    ///
    /// Returns the objective after the sweep from the products the W update has already formed
    /// (`S Hᵀ` and `H Hᵀ` at the new H, `Wᵀ W` at the new W), with `total = ||S||²`:
    ///
    /// ```text
    /// 2 f = ||S||² - 2 <W, S Hᵀ> + <Wᵀ W, H Hᵀ>
    /// ```
    ///
    /// This costs `m² n` where the explicit residual `S - W H` costs `m n N` and an `n x N`
    /// matrix; the cancellation against `||S||²` leaves `f` within about 1e-15 `||S||²` of the
    /// explicit value (tested), far below the [`STALL_REL`] `f` the stopping test reads at the
    /// residuals reached here.
    fn run(&mut self, s: &Sparse, total: f64) -> f64 {
        let (n, m, count) = (self.n, self.m, self.count);
        let stride = padded(m);
        s.wt_s(&self.w_rows, m, stride, &mut self.wts);
        self.system.update(&self.wtw, &self.wts, count, (&mut self.h, self.np));
        self.copy_h();
        gram(&self.h_cols, count, m, stride, &mut self.hht);
        s.s_ht(&self.h_cols, m, stride, &mut self.sht);
        self.system.update(&self.hht, &self.sht, n, (&mut self.w, self.nw));
        self.copy_w();
        gram(&self.w_rows, n, m, stride, &mut self.wtw);
        // per column k of W, `sum_i W[i, k] (S Hᵀ)[i, k]`, summed over i ascending from -0 as
        // `Iterator::sum` does, all m columns side by side
        self.dots.fill(-0.0);
        for (w, sht) in self.w_rows.chunks_exact(stride).zip(self.sht.chunks_exact(m)) {
            for ((d, &x), &y) in self.dots.iter_mut().zip(w).zip(sht) {
                *d += x * y;
            }
        }
        let mut cross = 0.0;
        let mut quad = 0.0;
        for k in 0..m {
            cross += self.dots[k];
            quad += (0..m).map(|l| self.wtw[l * m + k] * self.hht[l * m + k]).sum::<f64>();
        }
        (0.5 * (total - 2.0 * cross + quad)).max(0.0)
    }
}

/// The Gauss-Seidel passes' systems: the non-zeros by row of the coefficient matrix of the
/// factor being updated (row k at `nz[nz_ptr[k]..nz_ptr[k + 1]]`), and the right-hand sides of
/// one group of [`LANES`] outputs, interleaved by lane (`[l * LANES + lane]`).
struct Lanes {
    m: usize,
    nz: Vec<(usize, f64)>,
    nz_ptr: Vec<usize>,
    b: Vec<f64>,
}

impl Lanes {
    /// One factor's update: the coefficients from the symmetric Gram matrix `g`, then a pass
    /// over each group of [`LANES`] of the `outputs` columns of H (rows of W), whose
    /// right-hand sides are `prod[o * m + k]` (zero beyond the last output) and whose
    /// unknowns are `x[k * stride + o]`.
    fn update(&mut self, g: &[f64], prod: &[f64], outputs: usize, (x, stride): (&mut [f64], usize)) {
        let m = self.m;
        self.nz.clear();
        for k in 0..m {
            let row = g[k * m..(k + 1) * m].iter().enumerate();
            self.nz.extend(row.filter(|(_, &v)| v != 0.0).map(|(l, &v)| (l, v)));
            self.nz_ptr[k + 1] = self.nz.len();
        }
        for first in (0..stride).step_by(LANES) {
            for j in 0..LANES {
                let o = first + j;
                for l in 0..m {
                    self.b[l * LANES + j] = if o < outputs { prod[o * m + l] } else { 0.0 };
                }
            }
            gauss_seidel(g, (&self.nz, &self.nz_ptr), m, &self.b, (x, stride, first));
        }
    }
}

/// `out[k * m + l] = sum over r ascending of rows[r][k] rows[r][l]` (a Gram matrix: W's from
/// its rows, H's from its columns; `rows[r * stride + k]`), each entry by fused multiply-adds
/// from `+0`, the rows whose entry k is zero skipped (their term is `±0`, which leaves such a
/// sum unchanged bit for bit: see [`Sparse`]). The result is symmetric bit for bit (`fma(a, b,
/// c) = fma(b, a, c)`).
fn gram(rows: &[f64], count: usize, m: usize, stride: usize, out: &mut [f64]) {
    out[..m * m].fill(0.0);
    for r in 0..count {
        let row = &rows[r * stride..r * stride + m];
        for (k, &v) in row.iter().enumerate() {
            if v != 0.0 {
                for (o, &x) in out[k * m..(k + 1) * m].iter_mut().zip(row) {
                    *o = v.mul_add(x, *o);
                }
            }
        }
    }
}

/// One projected Gauss-Seidel pass over [`LANES`] independent systems sharing `a` (m x m,
/// row-major, its non-zeros by row in `nz`, row k at `nz[ptr[k]..ptr[k + 1]]`): for k ascending
/// with `a[k, k] > 0`, each lane's `x[k] <- max(0, x[k] + (b[k] - sum_{l ascending, a[k, l] !=
/// 0} a[k, l] x[l]) / a[k, k])`. `b` is interleaved by lane; the unknowns are updated in place,
/// unknown l's lanes at `x[l * stride + first..][..LANES]`. A lane of zeros stays zero.
fn gauss_seidel(
    a: &[f64],
    (nz, ptr): (&[(usize, f64)], &[usize]),
    m: usize,
    b: &[f64],
    (x, stride, first): (&mut [f64], usize, usize),
) {
    for k in 0..m {
        let d = a[k * m + k];
        if d <= 0.0 {
            continue;
        }
        let mut g = [0.0; LANES];
        g.copy_from_slice(&b[k * LANES..(k + 1) * LANES]);
        for &(l, akl) in &nz[ptr[k]..ptr[k + 1]] {
            let at = l * stride + first;
            let xl: &[f64; LANES] = x[at..at + LANES].try_into().expect("a lane block");
            for (gj, xj) in g.iter_mut().zip(xl) {
                *gj -= akl * xj;
            }
        }
        let at = k * stride + first;
        for (xj, gj) in x[at..at + LANES].iter_mut().zip(&g) {
            *xj = (*xj + gj / d).max(0.0);
        }
    }
}

/// The NNMF dual bases of every rank of the m grid.
#[derive(Debug)]
pub struct NnmfFamily {
    ranks: Vec<usize>,
    cones: Vec<ConePrefix>,
    runs: Vec<(usize, f64)>,
}

impl NnmfFamily {
    /// One factorisation per rank in `ms` (ascending), each warm-started from the one before:
    /// rank `m_{j+1}` starts from rank `m_j`'s factors and the further NNDSVD components
    /// ([`extend`]); the first from NNDSVD.
    pub fn build(s: MatRef<'_, f64>, ms: &[usize], iterations: usize) -> Result<Self, DualError> {
        let (spectrum, sparse) = (Spectrum::of(s)?, Sparse::of(s));
        let mut factors: Vec<Nnmf> = Vec::with_capacity(ms.len());
        for &m in ms {
            let f = match factors.last() {
                None => nnmf_from(s, &sparse, spectrum.as_ref(), m, (iterations, STALL_REL)),
                Some(lower) => {
                    let (w, h) = extend(lower, spectrum.as_ref(), m);
                    hals(s, &sparse, (w.as_ref(), h.as_ref()), (iterations, STALL_REL))
                }
            };
            factors.push(f);
        }
        let mut out = Self { ranks: Vec::new(), cones: Vec::new(), runs: Vec::new() };
        for (&m, f) in ms.iter().zip(factors) {
            out.cones.push(ConePrefix::new(f.w.as_ref()));
            out.runs.push((f.iterations, f.relative_residual));
            out.ranks.push(m);
        }
        Ok(out)
    }
}

impl DualApprox for NnmfFamily {
    fn residuals(&self, s: &[f64], _mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        for (o, &m) in out.iter_mut().zip(ms) {
            // The factorisation of the largest grid rank not above m.
            let k = self.ranks.iter().rposition(|&r| r <= m).ok_or_else(|| {
                DualError::NotApplicable(format!("NNMF was not factored at rank {m} (ranks: {:?})", self.ranks))
            })?;
            let mut one = [0.0];
            self.cones[k].residuals_of(s, &[self.ranks[k]], &mut one)?;
            *o = one[0];
        }
        Ok(())
    }

    fn size(&self) -> usize {
        self.ranks.last().copied().unwrap_or(0)
    }

    fn cone_basis(&self, mu: &[f64], m: usize) -> Option<Mat<f64>> {
        let k = self.ranks.iter().rposition(|&r| r <= m)?;
        self.cones[k].cone_basis(mu, m)
    }

    /// The group is the factorisation (rank index) used for m.
    fn coefficients(&self, s: &[f64], _mu: &[f64], m: usize) -> Result<Option<(usize, Vec<f64>)>, DualError> {
        let Some(k) = self.ranks.iter().rposition(|&r| r <= m) else { return Ok(None) };
        Ok(Some((k, self.cones[k].coords(s, self.ranks[k])?)))
    }

    fn member(&self, group: usize, alpha: &[f64], _mu: &[f64], _m: usize, out: &mut [f64]) {
        self.cones[group].combine(alpha, out);
    }

    fn facts(&self) -> Vec<Fact> {
        let mut f = Vec::new();
        for (&m, &(it, res)) in self.ranks.iter().zip(&self.runs) {
            f.push(Fact::new("iterations", Some(m), it as f64));
            f.push(Fact::new("relative_residual", Some(m), res));
        }
        f
    }
}

/// The same objective by alternating projected gradient with a fixed step `1 / L` per block
/// (`L` the block's Lipschitz constant, `||W^T W||_F` resp. `||H H^T||_F`), from the same
/// start. Slow; for the tests only.
pub fn nnmf_reference_pg(s: MatRef<'_, f64>, m: usize, iterations: usize) -> Result<(Mat<f64>, Mat<f64>), DualError> {
    let (mut w, mut h) = nndsvd(s, m)?;
    for _ in 0..iterations {
        let wtw = w.transpose() * w.as_ref();
        let l = wtw.norm_l2().max(f64::MIN_POSITIVE);
        let g = &wtw * h.as_ref() - w.transpose() * s;
        h = Mat::from_fn(h.nrows(), h.ncols(), |i, j| (h[(i, j)] - g[(i, j)] / l).max(0.0));
        let hht = h.as_ref() * h.transpose();
        let l = hht.norm_l2().max(f64::MIN_POSITIVE);
        let g = w.as_ref() * &hht - s * h.transpose();
        w = Mat::from_fn(w.nrows(), w.ncols(), |i, j| (w[(i, j)] - g[(i, j)] / l).max(0.0));
    }
    Ok((w, h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn exact(seed: u64, n: usize, count: usize, r: usize) -> Mat<f64> {
        let mut rng = Rng::new(seed);
        let w0 = Mat::from_fn(n, r, |_, _| rng.uniform());
        let h0 = Mat::from_fn(r, count, |_, _| rng.uniform());
        w0 * h0
    }

    /// On an exactly factorable non-negative matrix of rank 3 both HALS and the
    /// projected-gradient reference reach a residual far below what rank 2 can (the exact
    /// factorisation has residual 0; 1e-3 relative is two orders below the rank-2 optimum
    /// here and within reach of both linear-rate methods in the given sweeps).
    #[test]
    fn an_exact_factorisation_is_found_by_hals_and_by_the_reference() {
        let s = exact(11, 30, 20, 3);
        let total = s.norm_l2();
        let hals = nnmf(s.as_ref(), 3, 5000, 0.0).expect("hals");
        assert!(hals.relative_residual < 1e-3, "HALS residual {}", hals.relative_residual);
        let (w, h) = nnmf_reference_pg(s.as_ref(), 3, 20000).expect("pg");
        let pg = (s.as_ref() - &w * &h).norm_l2() / total;
        assert!(pg < 1e-3, "projected-gradient residual {pg}");
        let rank2 = nnmf(s.as_ref(), 2, 5000, 0.0).expect("rank 2").relative_residual;
        assert!(rank2 > 10.0 * hals.relative_residual, "rank 2 {rank2} vs rank 3 {}", hals.relative_residual);
        assert!(w.col_iter().all(|c| c.iter().all(|&x| x >= 0.0)));
    }

    /// On a random non-negative matrix, HALS run to its cap (no stall rule) ends at a
    /// stationary point: the projected gradient
    /// (KKT of the bound constraints) is small against the gradient at the start, and its
    /// objective is no worse than the projected-gradient reference's from the same start
    /// (1e-6 relative: both descend monotonically from NNDSVD; HALS takes exact block steps).
    #[test]
    fn hals_is_stationary_and_no_worse_than_projected_gradient() {
        let mut rng = Rng::new(13);
        let s = Mat::from_fn(25, 18, |_, _| rng.uniform());
        let f = nnmf(s.as_ref(), 4, 3000, 0.0).expect("hals");
        let grad_h = f.w.transpose() * (&f.w * &f.h - s.as_ref());
        let grad_w = (&f.w * &f.h - s.as_ref()) * f.h.transpose();
        let proj = |g: &Mat<f64>, x: &Mat<f64>| {
            let mut t = 0.0f64;
            for j in 0..g.ncols() {
                for i in 0..g.nrows() {
                    let v = if x[(i, j)] > 0.0 { g[(i, j)] } else { g[(i, j)].min(0.0) };
                    t += v * v;
                }
            }
            t.sqrt()
        };
        let (w0, h0) = nndsvd(s.as_ref(), 4).expect("start");
        let g0 = (w0.transpose() * (&w0 * &h0 - s.as_ref())).norm_l2()
            + ((&w0 * &h0 - s.as_ref()) * h0.transpose()).norm_l2();
        let pg = proj(&grad_h, &f.h) + proj(&grad_w, &f.w);
        assert!(pg < 1e-4 * g0, "projected gradient {pg} vs start {g0}");
        let (w, h) = nnmf_reference_pg(s.as_ref(), 4, 3000).expect("pg");
        let f_ref = 0.5 * (s.as_ref() - &w * &h).squared_norm_l2();
        let f_hals = 0.5 * f.relative_residual.powi(2) * s.squared_norm_l2();
        assert!(f_hals <= f_ref * (1.0 + 1e-6), "HALS {f_hals} vs reference {f_ref}");
    }

    /// `A B` (p x q times q x r) by the formula, every entry `sum_l A[i, l] B[l, j]` by fused
    /// multiply-adds in ascending l from 0, zeros included: the products of S and the Gram
    /// matrices that a sweep forms ([`Sparse`], [`gram`]), written independently of it.
    fn fma_product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
        Mat::from_fn(a.nrows(), b.ncols(), |i, j| (0..a.ncols()).fold(0.0, |acc, l| a[(i, l)].mul_add(b[(l, j)], acc)))
    }

    /// The sweep as the update formulas read, element by element through the matrices (rows of
    /// H with k outer, then columns of W with k outer); kept to check [`Sweep::run`] against.
    fn sweep_reference(s: MatRef<'_, f64>, w: &mut Mat<f64>, h: &mut Mat<f64>) {
        let (n, m, count) = (w.nrows(), w.ncols(), h.ncols());
        let wtw = fma_product(w.transpose(), w.as_ref());
        let wts = fma_product(w.transpose(), s);
        for k in 0..m {
            let d = wtw[(k, k)];
            if d <= 0.0 {
                continue;
            }
            for c in 0..count {
                let mut g = wts[(k, c)];
                for l in 0..m {
                    g -= wtw[(k, l)] * h[(l, c)];
                }
                h[(k, c)] = (h[(k, c)] + g / d).max(0.0);
            }
        }
        let hht = fma_product(h.as_ref(), h.transpose());
        let sht = fma_product(s, h.transpose());
        for k in 0..m {
            let d = hht[(k, k)];
            if d <= 0.0 {
                continue;
            }
            for i in 0..n {
                let mut g = sht[(i, k)];
                for l in 0..m {
                    g -= w[(i, l)] * hht[(l, k)];
                }
                w[(i, k)] = (w[(i, k)] + g / d).max(0.0);
            }
        }
    }

    /// The contiguous sweep gives the reference sweep's bits, sweep after sweep: on a random
    /// matrix, on a sparse one shaped like pressure snapshots (each column non-zero on a band
    /// of rows, some rows zero throughout: the products skip the zeros), at a rank above S's
    /// column count (the NNDSVD start then has zero columns, whose zero diagonal skips their
    /// updates), and at ranks whose products take two and three blocks.
    #[test]
    fn the_sweep_is_the_reference_sweep_bit_for_bit() {
        let mut rng = Rng::new(29);
        let random = Mat::from_fn(23, 17, |_, _| rng.uniform());
        let banded = Mat::from_fn(40, 19, |i, c| if i >= 2 * c / 3 && i < 2 * c / 3 + 6 { rng.uniform() } else { 0.0 });
        assert!((0..40).any(|i| (0..19).all(|c| banded[(i, c)] == 0.0)), "a zero row");
        // ranks 12 and 20: products of two 8-wide blocks, and of three taken as two and one
        // ([`products`])
        let wide = Mat::from_fn(45, 33, |i, c| if i >= c && i < c + 14 { rng.uniform() } else { 0.0 });
        let cases = [(random, 6), (banded, 5), (exact(31, 12, 3, 2), 5), (wide.clone(), 12), (wide, 20)];
        for (case, (s, m)) in cases.into_iter().enumerate() {
            let (w, h) = nndsvd(s.as_ref(), m).expect("start");
            let (mut wr, mut hr) = (w.clone(), h.clone());
            let sparse = Sparse::of(s.as_ref());
            let mut work = Sweep::new(w.as_ref(), h.as_ref());
            let zero_columns = w.col_iter().filter(|c| c.iter().all(|&x| x == 0.0)).count();
            assert!(zero_columns >= m.saturating_sub(s.ncols()), "{zero_columns} zero columns at rank {m}");
            let mut skipped = 0;
            for sweep in 0..40 {
                work.run(&sparse, s.squared_norm_l2());
                skipped += m * m - work.system.nz.len();
                sweep_reference(s.as_ref(), &mut wr, &mut hr);
                assert!(work.factors() == (wr.clone(), hr.clone()), "sweep {sweep} of rank {m} differs");
            }
            let w = work.factors().0;
            // the banded S's factors have disjoint supports: zero Gram entries are skipped
            assert!(case != 1 || skipped > 0, "no zero Gram entry met");
            assert!(w.col_iter().any(|c| c.iter().any(|&x| x > 0.0)), "a trivial run checks nothing");
        }
    }

    /// The objective a sweep returns (from its Gram products) is the explicit residual's to
    /// rounding. Its three terms are each at most `4 ||S||²` (the sweeps descend from NNDSVD,
    /// so `||W H|| <= 2 ||S||`) and are sums of at most `n m` = 138 products, so each is
    /// within `138 eps 4 ||S||²` of its exact value: the three within 4e-13 `||S||²`
    /// (measured: 3.6e-16).
    #[test]
    fn the_sweep_objective_is_the_explicit_residual() {
        let mut rng = Rng::new(37);
        let s = Mat::from_fn(23, 17, |_, _| rng.uniform());
        let total = s.squared_norm_l2();
        let (w, h) = nndsvd(s.as_ref(), 6).expect("start");
        let (sparse, mut work) = (Sparse::of(s.as_ref()), Sweep::new(w.as_ref(), h.as_ref()));
        for sweep in 0..60 {
            let f = work.run(&sparse, total);
            let (w, h) = work.factors();
            let explicit = objective(s.as_ref(), w.as_ref(), h.as_ref());
            assert!((f - explicit).abs() <= 4e-13 * total, "sweep {sweep}: {f} vs {explicit}");
            assert!(explicit > 1e-4 * total, "a residual this small would not test the cancellation");
        }
    }

    /// A family's ranks are warm-started as the module doc says: rank `m_1` is the single
    /// factorisation from NNDSVD, and rank `m_{j+1}` is HALS from rank `m_j`'s factors with the
    /// further NNDSVD components, which the test forms itself from `nndsvd` and `nnmf`'s
    /// outputs; the same on one and four threads.
    #[test]
    fn a_familys_ranks_are_warm_started_from_the_rank_below() {
        let mut rng = Rng::new(41);
        let s = Mat::from_fn(30, 21, |i, c| if i >= c && i < c + 8 { rng.uniform() } else { 0.0 });
        let ms = [2, 3, 5];
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| NnmfFamily::build(s.as_ref(), &ms, 80).expect("family"))
        };
        let (one, four) = (on(1), on(4));
        assert_eq!(one.runs, four.runs);
        let first = nnmf(s.as_ref(), 2, 80, STALL_REL).expect("rank 2");
        assert_eq!(one.cones[0].basis().to_owned(), first.w);
        // rank 3 from rank 2's (normalised) factors and NNDSVD's third component
        let (w3, h3) = nndsvd(s.as_ref(), 3).expect("start");
        let w0 = Mat::from_fn(30, 3, |i, k| if k < 2 { first.w[(i, k)] } else { w3[(i, k)] });
        let h0 = Mat::from_fn(3, 21, |k, c| if k < 2 { first.h[(k, c)] } else { h3[(k, c)] });
        let third = hals(s.as_ref(), &Sparse::of(s.as_ref()), (w0.as_ref(), h0.as_ref()), (80, STALL_REL));
        assert_eq!(one.cones[1].basis().to_owned(), third.w);
        assert_eq!(four.cones[1].basis().to_owned(), third.w);
        assert_eq!(one.runs[1], (third.iterations, third.relative_residual));
    }

    /// The stopping rule: the last sweep lowered `f = ||S - W H||^2 / 2` by at most
    /// [`STALL_REL`] of it and the sweep before by more (the factorisation is deterministic, so
    /// capping the sweeps at k gives its first k sweeps; `f` from the recorded residual).
    #[test]
    fn the_run_stops_at_the_first_sweep_that_gains_less_than_the_stall_fraction() {
        let mut rng = Rng::new(5);
        let s = Mat::from_fn(40, 30, |i, c| if (i + 40 - c) % 40 < 9 { rng.uniform() } else { 0.0 });
        let f = |k: usize| nnmf(s.as_ref(), 6, k, STALL_REL).expect("nnmf").relative_residual.powi(2);
        let full = nnmf(s.as_ref(), 6, 100_000, STALL_REL).expect("nnmf");
        let k = full.iterations;
        assert!(k > 2 && k < 100_000, "stopped by the rule, after {k} sweeps");
        let (last, before, earlier) = (f(k), f(k - 1), f(k - 2));
        assert!(before - last <= STALL_REL * before, "last sweep: {before} -> {last}");
        assert!(earlier - before > STALL_REL * earlier, "the sweep before: {earlier} -> {before}");
    }

    /// An S without rows or without columns factors to zeros, at any rank, without a sweep
    /// reading past its (empty) factors.
    #[test]
    fn empty_snapshot_matrices_factor_to_zeros() {
        for (n, count) in [(0, 5), (7, 0), (0, 0)] {
            let s = Mat::<f64>::zeros(n, count);
            for m in [1, 3, 12] {
                let f = nnmf(s.as_ref(), m, 10, STALL_REL).expect("an empty S");
                assert_eq!((f.w.nrows(), f.w.ncols(), f.h.nrows(), f.h.ncols()), (n, m, m, count));
                assert!(f.w.col_iter().chain(f.h.col_iter()).all(|c| c.iter().all(|&x| x == 0.0)));
                assert!(f.relative_residual == 0.0, "residual {}", f.relative_residual);
            }
        }
    }

    /// Deterministic: the same input gives the same bits.
    #[test]
    fn the_factorisation_is_deterministic() {
        let s = exact(17, 20, 15, 4);
        let a = nnmf(s.as_ref(), 3, 50, STALL_REL).expect("a");
        let b = nnmf(s.as_ref(), 3, 50, STALL_REL).expect("b");
        assert_eq!(a.w, b.w);
        assert_eq!(a.iterations, b.iterations);
    }
}
