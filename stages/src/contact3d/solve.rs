//! Factoring a 3-D model once and solving it at a parameter: active set with re-pairing, as in
//! 2-D ([`crate::contact`], module `solve`).
//!
//! Once per scene: `K_FF = L L^T` (faer's sparse Cholesky), the responses to the imposed
//! displacement's affine terms, and the Delassus operator `W = E_c^T K_FF^{-1} E_c` on the
//! contact dofs (slaves, then master nodes; three each). Per parameter, for the current pairing
//! (frozen support weights and normal per slave, [`super::surface`]) the gaps are linear in the
//! contact-dof positions, `g = B x_c`, and `u_c = a_c(mu) + W B^T lambda`, so
//! `g = q + D lambda` with `q = B (X_c + a_c)` and `D = B W B^T`: the LCP of
//! [`crate::contact::active_set`]. Then
//!
//! 1. update `u_c`, re-pair every slave at the deformed positions;
//! 2. the KKT residual of `(u_c, lambda)` for the new pairing `B'`: equilibrium
//!    `||(B' - B)^T lambda||_inf / ||B'^T lambda||_inf` and complementarity
//!    `||min(lambda, c g')||_inf / max(||lambda||_inf, c ||g'^-||_inf)` (`c = 1 / mean diag D`);
//! 3. stop when the features did not change and both are `<= rel_tol`; otherwise solve the LCP
//!    with `B'` (warm-started active set).
//!
//! The full displacement is then recovered with one sparse solve, and the statistics are those
//! of the recovered field with the full `K` (the equilibrium residual a backward error, as in
//! 2-D). The pressure is `lambda_s / A_s`, `A_s` the slave's tributary area.

use faer::MatMut;

use super::condense::ContactLastFactor;
use super::model::Model3d;
use super::surface::{FacetGrid, Feature, Pair3};
use crate::contact::active_set::{solve_lcp, Lcp, LcpError, LcpWork};
use crate::contact::{ContactError, ContactSolveParams, ModelError};
use crate::mu::{affine, Mu};
use crate::snapshot::{Snapshot, SolveStats};

/// Re-pairings at most per solve.
const MAX_PAIRINGS: usize = 200;

/// A factored 3-D model: solve it at any parameter with [`Factored3d::solve`]; `Sync`, so many
/// threads may solve different parameters at once.
#[derive(Debug, Clone)]
pub struct Factored3d {
    pub(crate) model: Model3d,
    llt: ContactLastFactor,
    pub(super) resp: Vec<Vec<f64>>,
    cnodes: Vec<usize>,
    pub(super) x_ref: Vec<[f64; 3]>,
    a: Vec<Vec<f64>>,
    pub(super) w: Vec<f64>,
    pub(super) slave_fixed: Vec<bool>,
    /// The H1 Gram matrix of the primal norm, assembled on first use (the online reduced
    /// model's error evaluation, `rom_view`).
    pub(super) h1: std::sync::OnceLock<crate::fem::CsrMatrix>,
}

impl Model3d {
    /// Factor `K_FF`, the responses to the imposed displacement's terms and the Delassus
    /// operator on the contact dofs.
    pub fn factor(&self) -> Result<Factored3d, ModelError> {
        let split = &self.split;
        let kff = split.free_block(&self.k).map_err(ModelError::Sparse)?;
        let cnodes: Vec<usize> = self.slaves.iter().chain(&self.masters).copied().collect();
        let dofs: Vec<usize> = cnodes.iter().flat_map(|&n| [3 * n, 3 * n + 1, 3 * n + 2]).collect();
        let cfree: Vec<Option<usize>> = dofs.iter().map(|&d| split.free_index(d)).collect();
        let contact_free: Vec<usize> = cfree.iter().flatten().copied().collect();
        let (llt, w_free) = ContactLastFactor::factor(&kff, &contact_free)?;
        let (_, resp) = split.responses(&self.k, &self.u_d, |rhs| llt.solve_in_place(rhs));
        let resp = resp.ok_or_else(|| ModelError::Singular("non-finite unconstrained response".into()))?;
        let x_ref: Vec<[f64; 3]> = cnodes.iter().map(|&n| self.mesh.nodes[n]).collect();
        let a: Vec<Vec<f64>> = (0..self.u_d.len())
            .map(|k| dofs.iter().zip(&cfree).map(|(&d, f)| f.map_or(self.u_d[k][d], |fi| resp[k][fi])).collect())
            .collect();
        // W on every contact dof: `w_free` on the free ones (the contact dofs of its rows, in
        // order), zero rows and columns on Dirichlet ones
        let ncd = cfree.len();
        let at: Vec<usize> = (0..ncd).filter(|&i| cfree[i].is_some()).collect();
        let mut w = vec![0.0; ncd * ncd];
        for (fi, &i) in at.iter().enumerate() {
            for (fj, &j) in at.iter().enumerate() {
                w[i * ncd + j] = w_free[fi * at.len() + fj];
            }
        }
        let slave_fixed = (0..self.slaves.len()).map(|s| (0..3).all(|c| cfree[3 * s + c].is_none())).collect();
        Ok(Factored3d { model: self.clone(), llt, resp, cnodes, x_ref, a, w, slave_fixed, h1: Default::default() })
    }
}

/// The rows of the current pairing: per paired slave (row `r`), its contact-dof entries.
#[derive(Debug, Default)]
struct Rows {
    /// Slave of each row.
    slave: Vec<usize>,
    /// Entries of row r at `start[r]..start[r + 1]`: (contact dof, coefficient).
    start: Vec<usize>,
    entries: Vec<(usize, f64)>,
}

impl Rows {
    fn build(pairs: &[Pair3], ns: usize) -> Self {
        let mut rows = Rows { start: vec![0], ..Rows::default() };
        for (s, p) in pairs.iter().enumerate() {
            if !p.is_paired() {
                continue;
            }
            rows.slave.push(s);
            rows.entries.extend(p.row(s, ns));
            rows.start.push(rows.entries.len());
        }
        rows
    }

    fn len(&self) -> usize {
        self.slave.len()
    }

    fn row(&self, r: usize) -> &[(usize, f64)] {
        &self.entries[self.start[r]..self.start[r + 1]]
    }

    /// `out += B^T lambda` (contact dofs), `lambda` per row.
    fn scatter(&self, lam: &[f64], out: &mut [f64]) {
        for (r, &l) in lam.iter().enumerate() {
            if l != 0.0 {
                for &(d, c) in self.row(r) {
                    out[d] += c * l;
                }
            }
        }
    }
}

impl Factored3d {
    /// The model.
    pub fn model(&self) -> &Model3d {
        &self.model
    }

    /// Contact nodes: slaves, then masters (global ids).
    pub fn contact_nodes(&self) -> &[usize] {
        &self.cnodes
    }

    /// Number of contact dofs (the Delassus operator's size).
    pub fn n_contact_dof(&self) -> usize {
        3 * self.cnodes.len()
    }

    fn pair_all(
        &self,
        uc: &[f64],
        grid_out: &mut Option<FacetGrid>,
        pairs: &mut [Pair3],
        mu: &[f64],
    ) -> Result<(), ContactError> {
        let m = &self.model;
        let ns = m.slaves.len();
        let x = |i: usize| {
            let r = self.x_ref[i];
            [r[0] + uc[3 * i], r[1] + uc[3 * i + 1], r[2] + uc[3 * i + 2]]
        };
        let xm: Vec<[f64; 3]> = (0..m.masters.len()).map(|k| x(ns + k)).collect();
        let mut grid = FacetGrid::new(&m.surface, &xm);
        for (s, p) in pairs.iter_mut().enumerate() {
            let xs = x(s);
            if xs.iter().any(|v| !v.is_finite()) {
                return Err(ContactError::Pairing { param: Mu::of(mu), slave: s });
            }
            *p = if self.slave_fixed[s] { Pair3::UNPAIRED } else { grid.pair(&m.surface, &xm, xs) };
        }
        *grid_out = Some(grid);
        Ok(())
    }

    /// Solve at parameter `mu` from the cold start (no contact, empty active set).
    pub fn solve(&self, mu: &[f64], p: &ContactSolveParams) -> Result<Snapshot, ContactError> {
        let m = &self.model;
        if mu.len() != m.n_params() || mu.iter().any(|v| !v.is_finite()) {
            return Err(ContactError::BadParameter(Mu::of(mu)));
        }
        let (ns, ncd) = (m.slaves.len(), self.n_contact_dof());
        let a: Vec<f64> = (0..ncd).map(|i| affine(&self.a[0], &self.a[1..], mu, i)).collect();
        let xa: Vec<f64> = (0..ncd).map(|i| self.x_ref[i / 3][i % 3] + a[i]).collect();
        let mut uc = a.clone();
        let mut pairs = vec![Pair3::UNPAIRED; ns];
        let mut grid = None;
        self.pair_all(&uc, &mut grid, &mut pairs, mu)?;
        let mut lam_s = vec![0.0; ns];
        let mut active_s = vec![false; ns];
        let mut lcp_ws = LcpWork::new(ns);
        let (mut iterations, mut pairings) = (0usize, 1usize);
        let mut last_residual = f64::INFINITY;
        let mut c_scale;
        let mut rows = Rows::build(&pairs, ns);
        loop {
            let np = rows.len();
            // V = W B^T (ncd x np, column-major), D = B V, q = B (X_c + a_c)
            let mut v = vec![0.0; ncd * np];
            for r in 0..np {
                let col = &mut v[r * ncd..(r + 1) * ncd];
                for &(d, c) in rows.row(r) {
                    let wrow = &self.w[d * ncd..(d + 1) * ncd];
                    for (o, wv) in col.iter_mut().zip(wrow) {
                        *o += c * wv;
                    }
                }
            }
            let mut dmat = vec![0.0; np * np];
            let mut q = vec![0.0; np];
            for r in 0..np {
                q[r] = rows.row(r).iter().map(|&(d, c)| c * xa[d]).sum();
                for k in 0..np {
                    dmat[r * np + k] = rows.row(r).iter().map(|&(d, c)| c * v[k * ncd + d]).sum();
                }
            }
            let diag_mean = if np > 0 { (0..np).map(|r| dmat[r * np + r]).sum::<f64>() / np as f64 } else { 1.0 };
            c_scale = if diag_mean > 0.0 { 1.0 / diag_mean } else { 1.0 };
            let mut act: Vec<bool> = rows.slave.iter().map(|&s| active_s[s]).collect();
            let mut lam = vec![0.0; np];
            let mut g = vec![0.0; np];
            let lcp = Lcp { d: &dmat, q: &q, c: c_scale, eps: 0.0 };
            let budget = p.max_iter.saturating_sub(iterations).max(1);
            let out = solve_lcp(&lcp, &mut act, &mut lam, &mut g, &mut lcp_ws, budget).map_err(|e| match e {
                LcpError::NotPositiveDefinite(pivot) => ContactError::Singular { param: Mu::of(mu), pivot },
                LcpError::Budget => ContactError::NoConvergence {
                    param: Mu::of(mu),
                    iterations,
                    repairings: pairings,
                    residual: last_residual,
                },
            })?;
            iterations += out.iterations;
            lam_s.fill(0.0);
            active_s.fill(false);
            for (r, &s) in rows.slave.iter().enumerate() {
                lam_s[s] = lam[r];
                active_s[s] = act[r];
            }
            uc.copy_from_slice(&a);
            for (r, &l) in lam.iter().enumerate() {
                if l != 0.0 {
                    for (o, vv) in uc.iter_mut().zip(&v[r * ncd..(r + 1) * ncd]) {
                        *o += l * vv;
                    }
                }
            }
            // re-pair at the new configuration and measure the KKT residual for the new pairing
            let old: Vec<Feature> = pairs.iter().map(|p| p.feature).collect();
            let mut f_old = vec![0.0; ncd];
            rows.scatter(&lam, &mut f_old);
            self.pair_all(&uc, &mut grid, &mut pairs, mu)?;
            pairings += 1;
            let new_rows = Rows::build(&pairs, ns);
            let lam_new: Vec<f64> = new_rows.slave.iter().map(|&s| lam_s[s]).collect();
            let mut f_new = vec![0.0; ncd];
            new_rows.scatter(&lam_new, &mut f_new);
            let unpaired_force = (0..ns).any(|s| lam_s[s] > 0.0 && !pairs[s].is_paired());
            let f_inf = f_new.iter().fold(0.0f64, |acc, x| acc.max(x.abs()));
            let eq = if f_inf > 0.0 {
                f_old.iter().zip(&f_new).fold(0.0f64, |acc, (a, b)| acc.max((a - b).abs())) / f_inf
            } else if f_old.iter().any(|&x| x != 0.0) {
                1.0
            } else {
                0.0
            };
            let comp = complementarity(&pairs, &lam_s, c_scale);
            last_residual = eq.max(comp);
            let same = old.iter().zip(&pairs).all(|(o, p)| *o == p.feature);
            if same && !unpaired_force && last_residual <= p.rel_tol {
                break;
            }
            if iterations >= p.max_iter || pairings >= MAX_PAIRINGS {
                return Err(ContactError::NoConvergence {
                    param: Mu::of(mu),
                    iterations,
                    repairings: pairings,
                    residual: last_residual,
                });
            }
            rows = new_rows;
        }
        Ok(self.finish(mu, &rows, &lam_s, &pairs, c_scale, iterations))
    }

    /// The full displacement, the pressure and the statistics of a converged state.
    fn finish(
        &self,
        mu: &[f64],
        rows: &Rows,
        lam_s: &[f64],
        pairs: &[Pair3],
        c_scale: f64,
        iterations: usize,
    ) -> Snapshot {
        let m = &self.model;
        let split = &m.split;
        let ncd = self.n_contact_dof();
        let lam: Vec<f64> = rows.slave.iter().map(|&s| lam_s[s]).collect();
        let mut fc = vec![0.0; ncd];
        rows.scatter(&lam, &mut fc);
        let mut f = vec![0.0; m.n_dof()];
        for (i, &n) in self.cnodes.iter().enumerate() {
            for c in 0..3 {
                f[3 * n + c] += fc[3 * i + c];
            }
        }
        let nf = split.n_free();
        let mut b: Vec<f64> = split.free().iter().map(|&d| f[d]).collect();
        self.llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut b, nf, 1));
        let mut u = split.contact_free(&m.u_d, &self.resp, mu);
        for (k, &d) in split.free().iter().enumerate() {
            u[d] += b[k];
        }
        // backward error of K u = f_c on the free dofs (with the lift's loads: f = 0 there)
        let ku = m.k.matvec(&u);
        let mut abs_ku = vec![0.0; m.n_dof()];
        for (r, o) in abs_ku.iter_mut().enumerate() {
            let (cols, vals) = m.k.row(r);
            *o = cols.iter().zip(vals).map(|(&c, &v)| (v * u[c]).abs()).sum();
        }
        let scale = split
            .free()
            .iter()
            .map(|&d| abs_ku[d] + f[d].abs())
            .fold(f.iter().fold(0.0f64, |acc, x| acc.max(x.abs())), f64::max)
            .max(f64::MIN_POSITIVE);
        let kkt = split.free().iter().map(|&d| (ku[d] - f[d]).abs()).fold(0.0f64, f64::max) / scale;
        // gaps at the recovered field
        let ns = m.slaves.len();
        let gaps: Vec<f64> = pairs.iter().map(|p| if p.is_paired() { p.gap } else { f64::INFINITY }).collect();
        let paired = (0..ns).filter(|&s| pairs[s].is_paired());
        let min_gap = paired.clone().map(|s| gaps[s]).fold(f64::INFINITY, f64::min);
        let active_gap = paired.clone().filter(|&s| lam_s[s] > 0.0).map(|s| gaps[s].abs()).fold(0.0, f64::max);
        let stats = SolveStats {
            iterations,
            active: lam_s.iter().filter(|&&l| l > 0.0).count(),
            max_penetration: paired.map(|s| (-gaps[s]).max(0.0)).fold(0.0, f64::max),
            min_lambda: lam_s.iter().copied().fold(f64::INFINITY, f64::min),
            complementarity: complementarity(pairs, lam_s, c_scale),
            kkt_residual: kkt,
            vertex_ties: 0,
            vertex_nodes: String::new(),
            vertex_rounds: 0,
            min_gap: if min_gap.is_finite() { min_gap } else { 0.0 },
            active_gap,
            cone_angle: 0.0,
        };
        let pressure = lam_s.iter().zip(&m.area).map(|(l, a)| if *a > 0.0 { l / a } else { 0.0 }).collect();
        Snapshot { u, pressure, stats }
    }
}

/// `||min(lambda, c g)||_inf / max(||lambda||_inf, c ||g^-||_inf)` over the paired slaves (an
/// unpaired slave's gap is not defined; its force is counted by the equilibrium residual).
fn complementarity(pairs: &[Pair3], lam: &[f64], c: f64) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (p, &l) in pairs.iter().zip(lam) {
        if !p.is_paired() {
            continue;
        }
        num = num.max(l.min(c * p.gap).abs());
        den = den.max(l.abs()).max(c * (-p.gap).max(0.0));
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}
