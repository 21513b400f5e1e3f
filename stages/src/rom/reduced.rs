//! [`ReducedModel`]: the offline/online split, the exact and the paper's online solves, and the
//! a-posteriori error indicator (see the module doc of [`crate::rom`]).

use super::curvature::GapCurvature;
use super::la::{axpy, backward_t, dot, forward, Factor};
use super::qp::{solve_qp, QpConstraints, QpOutcome, QpWork};
use super::saddle::{cholesky, solve_saddle};
use crate::contact::pairing::{vertex_pair, Certificate, Feature, GapRow, MasterIndex, Pair, PairKind};
use crate::contact::vertex::VertexTies;
use crate::mu::affine;
use crate::operator::{ContactOperator, Surface};
use faer::MatRef;

/// Which online iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Algorithm {
    /// Exact QP per linearisation (dual active set, finite termination) inside an outer
    /// re-pairing loop.
    Exact,
    /// The paper's Algorithm 1: one saddle solve per iteration, drop `λ̂ < 0`, add violated
    /// reduced gaps, re-linearise every iteration.
    Paper,
}

impl Algorithm {
    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Exact => "exact",
            Algorithm::Paper => "paper",
        }
    }
}

/// Settings of the online solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RomParams {
    /// The iteration.
    pub algorithm: Algorithm,
    /// Cap on linearisations (exact) or iterations (paper); default 100.
    pub max_iter: usize,
    /// A reduced constraint counts as violated when `ŝ < -gap_tol * scale`, `scale` the largest
    /// `|ĝ0|` at the first linearisation (default 1e-12: rounding of the projections).
    pub gap_tol: f64,
    /// Type-2: converged once the pairing repeats and the distance of `û` to the fixed point of
    /// the re-linearisation, estimated from the last two steps, is `<= u_tol |û|` (default
    /// 1e-10, the full-order solver's tolerance; the paper algorithm uses the last step alone).
    pub u_tol: f64,
}

impl Default for RomParams {
    fn default() -> Self {
        Self { algorithm: Algorithm::Exact, max_iter: 100, gap_tol: 1e-12, u_tol: 1e-10 }
    }
}

/// How an online query ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RomOutcome {
    /// A KKT point of the reduced problem (at its own linearisation).
    Converged,
    /// Refused: the reduced constraints cannot all be satisfied by `u0 + Phi û` (the primal
    /// basis is too small for the dual one at this parameter), detected by the exact QP.
    Infeasible,
    /// An earlier discrete state came back: the active set (paper algorithm) or the pairing
    /// (exact algorithm, after a change of pairing) cycles.
    Cycled,
    /// The iteration cap was reached.
    NotConverged,
}

impl RomOutcome {
    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            RomOutcome::Converged => "converged",
            RomOutcome::Infeasible => "infeasible",
            RomOutcome::Cycled => "cycled",
            RomOutcome::NotConverged => "not_converged",
        }
    }
}

/// Result of one online query (reduced coordinates only).
#[derive(Debug, Clone, PartialEq)]
pub struct ReducedSolution {
    /// Reduced displacement coordinates.
    pub u_hat: Vec<f64>,
    /// Reduced dual coordinates (`>= 0`).
    pub lambda_hat: Vec<f64>,
    /// QP steps (exact) or Algorithm 1 iterations (paper).
    pub iterations: usize,
    /// Linearisations (pairings) computed.
    pub linearizations: usize,
    /// Active reduced constraints at the end.
    pub active: usize,
    /// Reduced dual dofs with `λ̂_i > 1e-9 max λ̂` (the paper's "active dofs of λ̂").
    pub nonzero_dual: usize,
    /// How it ended.
    pub outcome: RomOutcome,
}

/// What [`ReducedModel::solve_in`] returns (the coordinates stay in the work buffers).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SolveInfo {
    /// QP steps (exact) or Algorithm 1 iterations (paper).
    pub iterations: usize,
    /// Linearisations (pairings) computed.
    pub linearizations: usize,
    /// Active reduced constraints at the end.
    pub active: usize,
    /// How it ended.
    pub outcome: RomOutcome,
}

/// The a-posteriori error indicator of a reduced solution (no full-order solve): the
/// full-space KKT residuals that cost only contact-surface work.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Indicator {
    /// Largest penetration `max(0, -g_s)` over every potential-contact node (length).
    pub penetration: f64,
    /// Force-weighted mean `|g_s|` under the reduced pressure (length): zero iff pressure only
    /// acts where the gap is closed.
    pub complementarity: f64,
    /// Fraction of the contact force on nodes with no master under them (lost force).
    pub unpaired_force: f64,
    /// Equilibrium residual in the energy norm, relative: `||Phi û - K^{-1} F(p̂)||_K /
    /// ||Phi û||_K`, `F(p̂)` the full-order contact forces of the reduced pressure at the final
    /// pairing (zero iff the reduced displacement is the full-order response to its own
    /// contact forces).
    pub residual: f64,
}

/// Why a [`ReducedModel`] could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RomError {
    /// `Phi^T K Phi` is not positive definite.
    #[error("the reduced stiffness Phi^T K Phi is not positive definite (rank-deficient or non-lifted primal basis)")]
    SingularStiffness,
    /// The reduced quadrature's NNLS failed.
    #[error("the reduced quadrature of the contact constraints failed: {0}")]
    Sampling(String),
}

#[derive(Debug, Clone)]
enum SurfaceData {
    /// Type-1: everything precomputed.
    Fixed {
        /// `C Psi`, row-major `n_contact x r_u`.
        cphi: Vec<f64>,
        /// Affine terms of `C u0(mu) + gap0(mu)`, each length `n_contact`.
        cu0: Vec<Vec<f64>>,
        paired: Vec<bool>,
        /// `Ĉ = Theta^T W C Psi`, row-major `r_l x r_u` (the constraints are already in the
        /// QP's range space, so a query makes no triangular solve).
        chat: Vec<f64>,
        /// Affine terms of `ĝ0(mu)`, each length `r_l`.
        ghat: Vec<Vec<f64>>,
        /// `C W C^T` (row-major `n_contact^2`), for the indicator.
        cwc: Vec<f64>,
    },
    /// Type-2: contact-surface rows.
    Nts {
        ns: usize,
        nm: usize,
        x_ref: Vec<[f64; 2]>,
        slave_fixed: Vec<bool>,
        /// `Psi` on the contact dofs, row-major `n_cd x r_u`.
        phi_c: Vec<f64>,
        /// Affine terms of the lift on the contact dofs.
        a_terms: Vec<Vec<f64>>,
        /// Non-fixed slaves in the support of `Theta[:, :r_l]` (a sampled surface: the
        /// quadrature's slaves only).
        supp: Vec<usize>,
        /// A sampled surface's quadrature weights by slave ([`ReducedModel::with_sampled_surface`]);
        /// `None`: every supported slave with its tributary length.
        quad: Option<Vec<f64>>,
        /// Frobenius norm of the two rows of `Phi_c` of each contact node (bounds its motion
        /// per unit change of `û`), and the largest over the masters.
        node_norm: Vec<f64>,
        master_norm: f64,
        /// Compliance on the contact dofs (row-major `n_cd^2`), for the indicator.
        w_c: Vec<f64>,
    },
}

/// A reduced model: offline data whose size depends on the ranks and the contact surface only.
/// [`ReducedModel::solve`] reads nothing else — no `n_dof`-length vector.
#[derive(Debug, Clone)]
pub struct ReducedModel {
    r_u: usize,
    r_l: usize,
    n_contact: usize,
    /// The Cholesky factor `L` of `K̂ = Phi^T K Phi` (column-major). Every operator below is
    /// stored in the coordinates `y = L^T û` of the K-orthonormal basis `Psi = Phi L^{-T}`, in
    /// which the reduced stiffness is the identity; `L` only turns the answer back into `û`.
    khat_l: Vec<f64>,
    /// `L^{-T}` (column-major, upper triangular): `û = L^{-T} y` as a product.
    u_of_y: Vec<f64>,
    weights: Vec<f64>,
    /// `Theta[:, :r_l]` by node (CSR): `(column, value)`.
    by_node: Compressed,
    /// `Theta[:, :r_l]` by column (CSC): `(node, value)`.
    by_col: Compressed,
    surf: SurfaceData,
    /// Type-1 warm starts ([`ReducedModel::with_warm_starts`]); empty unless built.
    warm_starts: WarmStarts,
}

/// Sample parameters (row-major, `dim` per point) and the active sets of the exact solve there:
/// a Type-1 query starts the QP from the set of the nearest sample.
#[derive(Debug, Clone, Default)]
struct WarmStarts {
    dim: usize,
    points: Vec<f64>,
    sets: Vec<Vec<usize>>,
    /// Type-2: the answers `y` at the samples (`r_u` each), where a query's re-pairing starts.
    ys: Vec<Vec<f64>>,
}

/// Directions of `û` along which [`ReducedModel::with_sampled_surface`] matches the
/// constraints' derivatives (a sketch of `Ĉ`).
pub const SAMPLING_DIRECTIONS: usize = 3;

/// At most this many samples in a warm-start library (evenly spaced among those offered), so
/// the nearest-sample scan in the query stays a few dozen distance evaluations.
pub const WARM_START_SAMPLES: usize = 64;

/// A compressed sparse layout: starts, indices, values.
type Compressed = (Vec<usize>, Vec<usize>, Vec<f64>);

/// `Theta[:, :rl]` by node (CSR) and by column (CSC).
fn csr(theta: &[f64], nc: usize, rl: usize) -> (Compressed, Compressed) {
    let at = |i: usize, a: usize| theta[i + a * nc];
    (compress(nc, rl, at), compress(rl, nc, |a, i| at(i, a)))
}

/// The non-zeros of `value(o, k)` row by row over `o < outer`, `k < inner`.
fn compress(outer: usize, inner: usize, value: impl Fn(usize, usize) -> f64) -> Compressed {
    let mut c = (vec![0], Vec::new(), Vec::new());
    for o in 0..outer {
        for k in 0..inner {
            let t = value(o, k);
            if t != 0.0 {
                c.1.push(k);
                c.2.push(t);
            }
        }
        c.0.push(c.1.len());
    }
    c
}

/// `xc = base + Phi_c û` (`Phi_c` row-major `n_cd x r`) at the contact nodes `nodes`; at
/// `û = 0` (the first linearisation) the positions are the lifted reference itself.
fn set_positions(
    phi_c: &[f64],
    r: usize,
    u_hat: &[f64],
    base: &[f64],
    xc: &mut [f64],
    nodes: impl Iterator<Item = usize>,
) {
    let zero = u_hat.iter().all(|&v| v == 0.0);
    for c in nodes {
        for cd in [2 * c, 2 * c + 1] {
            let d = if zero { 0.0 } else { dot(&phi_c[cd * r..(cd + 1) * r], u_hat) };
            xc[cd] = base[cd] + d;
        }
    }
}

/// Euclidean distance of two points.
fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// The path length of `y` up to which a pairing proved with radius `r` at path length
/// `travel` holds, for a slave and masters moving at most `speed` per unit of path.
fn budget_until(travel: f64, r: f64, speed: f64) -> f64 {
    if speed > 0.0 {
        travel + r / speed
    } else {
        f64::INFINITY
    }
}

/// `out = sum_j coef_j Phi_c[dof_j, :]` over the entries of a gap row, in one pass over `out`
/// (each element written once, not read back per entry).
fn combine_rows(row: &GapRow, phi_c: &[f64], r: usize, out: &mut [f64]) {
    let rows: [&[f64]; 6] = std::array::from_fn(|j| {
        let cd = row.dof[j.min(row.len - 1)];
        &phi_c[cd * r..(cd + 1) * r]
    });
    let c = row.coef;
    match row.len {
        6 => {
            for (j, o) in out.iter_mut().enumerate() {
                *o = c[0] * rows[0][j]
                    + c[1] * rows[1][j]
                    + c[2] * rows[2][j]
                    + c[3] * rows[3][j]
                    + c[4] * rows[4][j]
                    + c[5] * rows[5][j];
            }
        }
        4 => {
            for (j, o) in out.iter_mut().enumerate() {
                *o = c[0] * rows[0][j] + c[1] * rows[1][j] + c[2] * rows[2][j] + c[3] * rows[3][j];
            }
        }
        _ => {
            out.iter_mut().for_each(|o| *o = 0.0);
            for k in 0..row.len {
                axpy(c[k], rows[k], out);
            }
        }
    }
}

/// Per contact node the Frobenius norm of its two rows of `Phi_c` (row-major `n_cd x r`), and
/// the largest over the masters (nodes `ns..`).
fn node_norms(phi_c: &[f64], r: usize, ns: usize) -> (Vec<f64>, f64) {
    let norms: Vec<f64> = phi_c.chunks(2 * r.max(1)).map(|rows| dot(rows, rows).sqrt()).collect();
    let master = norms[ns.min(norms.len())..].iter().fold(0.0f64, |m, v| m.max(*v));
    (norms, master)
}

/// `L^{-T}` (column-major) of a lower factor `L` (column-major `r x r`).
fn inverse_transpose(l: &[f64], r: usize) -> Vec<f64> {
    let mut u = vec![0.0; r * r];
    for (j, col) in u.chunks_exact_mut(r.max(1)).enumerate().take(r) {
        col[j] = 1.0;
        backward_t(l, r, col);
    }
    u
}

fn affine_into(terms: &[Vec<f64>], mu: &[f64], out: &mut [f64]) {
    for (i, o) in out.iter_mut().enumerate() {
        *o = affine(&terms[0], &terms[1..], mu, i);
    }
}

impl ReducedModel {
    /// Offline: `phi` (`n_dof x r_u`, column-major, zero on Dirichlet dofs) and `theta`
    /// (`n_contact x r_l`, column-major, non-negative).
    pub fn new(op: &dyn ContactOperator, phi: &[f64], r_u: usize, theta: &[f64], r_l: usize) -> Result<Self, RomError> {
        let (n_dof, nc) = (op.n_dof(), op.n_contact());
        assert_eq!(phi.len(), n_dof * r_u, "phi shape");
        assert_eq!(theta.len(), nc * r_l, "theta shape");
        let mut kphi = vec![0.0; n_dof * r_u];
        for j in 0..r_u {
            op.stiffness_mul(&phi[j * n_dof..(j + 1) * n_dof], &mut kphi[j * n_dof..(j + 1) * n_dof]);
        }
        let kg = MatRef::from_column_major_slice(phi, n_dof, r_u).transpose()
            * MatRef::from_column_major_slice(&kphi, n_dof, r_u);
        // symmetrise the rounding of the two-sided product before factoring
        let mut khat = vec![0.0; r_u * r_u];
        for j in 0..r_u {
            for i in 0..r_u {
                khat[i + j * r_u] = 0.5 * (kg[(i, j)] + kg[(j, i)]);
            }
        }
        let mut khat_l = khat;
        if !cholesky(&mut khat_l, r_u) {
            return Err(RomError::SingularStiffness);
        }
        // a row `rho` of an operator on `û` becomes `L^{-1} rho` on `y = L^T û`
        let to_psi = |rows: &mut [f64]| {
            for row in rows.chunks_exact_mut(r_u.max(1)) {
                forward(&khat_l, r_u, row);
            }
        };
        let (by_node, by_col) = csr(theta, nc, r_l);
        let weights = op.weights().to_vec();
        let lift = op.lift_terms();
        let comp = op.contact_compliance();
        let surf = match op.surface() {
            Surface::Fixed { rows, gap0_terms } => {
                let mut cphi = vec![0.0; nc * r_u];
                for i in 0..nc {
                    for k in rows.start[i]..rows.start[i + 1] {
                        let (d, c) = (rows.dofs[k], rows.coeffs[k]);
                        for j in 0..r_u {
                            cphi[i * r_u + j] += c * phi[d + j * n_dof];
                        }
                    }
                }
                to_psi(&mut cphi);
                let cu0: Vec<Vec<f64>> = lift
                    .iter()
                    .zip(&gap0_terms)
                    .map(|(t, g)| {
                        (0..nc)
                            .map(|i| if rows.paired[i] { rows.gap(i, t) - rows.gap0[i] + g[i] } else { 0.0 })
                            .collect()
                    })
                    .collect();
                let mut chat = vec![0.0; r_l * r_u];
                let mut ghat = vec![vec![0.0; r_l]; cu0.len()];
                for i in 0..nc {
                    for e in by_node.0[i]..by_node.0[i + 1] {
                        let (a, tw) = (by_node.1[e], by_node.2[e] * weights[i]);
                        for j in 0..r_u {
                            chat[a * r_u + j] += tw * cphi[i * r_u + j];
                        }
                        for (g, c) in ghat.iter_mut().zip(&cu0) {
                            g[a] += tw * c[i];
                        }
                    }
                }
                let pos: std::collections::HashMap<usize, usize> =
                    comp.dofs.iter().enumerate().map(|(k, &d)| (d, k)).collect();
                let nw = comp.dofs.len();
                let mut cwc = vec![0.0; nc * nc];
                for i in 0..nc {
                    for j in 0..nc {
                        let mut v = 0.0;
                        for ki in rows.start[i]..rows.start[i + 1] {
                            for kj in rows.start[j]..rows.start[j + 1] {
                                let (pi, pj) = (pos[&rows.dofs[ki]], pos[&rows.dofs[kj]]);
                                v += rows.coeffs[ki] * rows.coeffs[kj] * comp.w[pi * nw + pj];
                            }
                        }
                        cwc[i * nc + j] = v;
                    }
                }
                SurfaceData::Fixed { cphi, cu0, paired: rows.paired, chat, ghat, cwc }
            }
            Surface::NodeToSegment { n_slaves, x_ref, dofs, slave_fixed } => {
                assert_eq!(comp.dofs, dofs, "compliance on the contact dofs");
                let mut phi_c: Vec<f64> =
                    dofs.iter().flat_map(|&d| (0..r_u).map(move |j| phi[d + j * n_dof])).collect();
                to_psi(&mut phi_c);
                let a_terms = lift.iter().map(|t| dofs.iter().map(|&d| t[d]).collect()).collect();
                let supp = (0..n_slaves).filter(|&s| !slave_fixed[s] && by_node.0[s + 1] > by_node.0[s]).collect();
                let (node_norm, master_norm) = node_norms(&phi_c, r_u, n_slaves);
                SurfaceData::Nts {
                    ns: n_slaves,
                    nm: x_ref.len() - n_slaves,
                    x_ref,
                    slave_fixed,
                    phi_c,
                    a_terms,
                    supp,
                    quad: None,
                    node_norm,
                    master_norm,
                    w_c: comp.w,
                }
            }
        };
        let u_of_y = inverse_transpose(&khat_l, r_u);
        Ok(Self {
            r_u,
            r_l,
            n_contact: nc,
            khat_l,
            u_of_y,
            weights,
            by_node,
            by_col,
            surf,
            warm_starts: WarmStarts::default(),
        })
    }

    /// Primal and dual ranks.
    pub fn ranks(&self) -> (usize, usize) {
        (self.r_u, self.r_l)
    }

    /// The reduced model on the first `r_u` primal and `r_l` dual basis vectors, without
    /// recomputing `K̂`: `Phi[:, :r]^T K Phi[:, :r]` is the leading block of `K̂`, the Cholesky
    /// factor of a leading block is the leading block of the factor, and so is `L^{-T}` (upper
    /// triangular), so `Psi[:, :r] = Phi[:, :r] L_r^{-T}` is the leading columns of `Psi`.
    pub fn leading(&self, r_u: usize, r_l: usize) -> Self {
        assert!(r_u <= self.r_u && r_l <= self.r_l, "leading ranks exceed the model's");
        let lead =
            |m: &[f64]| -> Vec<f64> { (0..r_u).flat_map(|j| m[j * self.r_u..j * self.r_u + r_u].to_vec()).collect() };
        let restride = |m: &[f64], rows: usize| -> Vec<f64> {
            (0..rows).flat_map(|i| m[i * self.r_u..i * self.r_u + r_u].to_vec()).collect()
        };
        let nc = self.n_contact;
        let mut theta = vec![0.0; nc * r_l];
        for i in 0..nc {
            for e in self.by_node.0[i]..self.by_node.0[i + 1] {
                if self.by_node.1[e] < r_l {
                    theta[i + self.by_node.1[e] * nc] = self.by_node.2[e];
                }
            }
        }
        let (by_node, by_col) = csr(&theta, nc, r_l);
        let surf = match &self.surf {
            SurfaceData::Fixed { cphi, cu0, paired, chat, ghat, cwc } => SurfaceData::Fixed {
                cphi: restride(cphi, nc),
                cu0: cu0.clone(),
                paired: paired.clone(),
                chat: restride(&chat[..r_l * self.r_u], r_l),
                ghat: ghat.iter().map(|g| g[..r_l].to_vec()).collect(),
                cwc: cwc.clone(),
            },
            SurfaceData::Nts { ns, nm, x_ref, slave_fixed, phi_c, a_terms, w_c, .. } => {
                let phi_c = restride(phi_c, x_ref.len() * 2);
                let (node_norm, master_norm) = node_norms(&phi_c, r_u, *ns);
                SurfaceData::Nts {
                    ns: *ns,
                    nm: *nm,
                    x_ref: x_ref.clone(),
                    slave_fixed: slave_fixed.clone(),
                    phi_c,
                    a_terms: a_terms.clone(),
                    supp: (0..*ns).filter(|&s| !slave_fixed[s] && by_node.0[s + 1] > by_node.0[s]).collect(),
                    quad: None,
                    node_norm,
                    master_norm,
                    w_c: w_c.clone(),
                }
            }
        };
        Self {
            r_u,
            r_l,
            n_contact: nc,
            khat_l: lead(&self.khat_l),
            u_of_y: lead(&self.u_of_y),
            weights: self.weights.clone(),
            by_node,
            by_col,
            surf,
            warm_starts: WarmStarts::default(),
        }
    }

    /// The model with a warm-start library for queries of [`Algorithm::Exact`]: the exact
    /// solve (cold) at up to [`WARM_START_SAMPLES`] of `points` (evenly spaced, typically the
    /// training parameters), its active set and, Type-2, its answer `y`. A query starts from
    /// the nearest sample (Euclidean distance in the parameter): the QP from the sample's
    /// active set instead of the unconstrained minimiser, and Type-2 the re-pairing from the
    /// sample's `y`, interpolated toward a neighbouring sample's (`seed_warm`), instead of
    /// `y = 0`. The Type-1 QP is strictly convex, so the answer is the
    /// same (to round-off) from any start; only the number of active-set steps changes — from
    /// the 4–8 a cold start needs to reach the rope's 1–2 active constraints, to about one
    /// when the nearest sample's set is right. A Type-2 re-pairing converges to the same fixed
    /// point from either start wherever it has one (full bases: the full-order solution;
    /// measured on ironing-fine with 128 training points, before the interpolated starts and
    /// Newton-corrected steps of design note 42: cold and warm agree to 1e-10 at
    /// every test point for ranks from (16, 60) to (128, 128)); where a truncated reduced
    /// problem has several, the start picks one (there: 1 of 127 points at (128, 16) and 4 at
    /// (8, 8) moved, by at most 2.7e-5 relative, against median model errors of 4.7e-3 and
    /// 1.2e-2).
    /// The paper algorithm is returned unchanged. Offline work: one solve per sample.
    pub fn with_warm_starts(mut self, points: &[Vec<f64>], p: &RomParams) -> Self {
        self.warm_starts = WarmStarts::default();
        if p.algorithm != Algorithm::Exact || points.is_empty() {
            return self;
        }
        let repairs = matches!(self.surf, SurfaceData::Nts { .. });
        let n = points.len();
        let take = n.min(WARM_START_SAMPLES);
        let mut lib = WarmStarts { dim: points[0].len(), ..WarmStarts::default() };
        let mut w = RomWork::default();
        for k in 0..take {
            let mu = &points[if take == n { k } else { k * (n - 1) / (take - 1).max(1) }];
            if mu.len() != lib.dim {
                continue;
            }
            let info = self.solve_in(mu, p, &mut w);
            if info.outcome == RomOutcome::Converged {
                lib.points.extend_from_slice(mu);
                lib.sets.push(w.qp.active.clone());
                if repairs {
                    lib.ys.push(w.u_hat.clone());
                }
            }
        }
        self.warm_starts = lib;
        self
    }

    /// The weight of slave `s` in the reduced constraints: its tributary length, or its
    /// quadrature weight on a sampled surface.
    fn gap_weight(&self, s: usize) -> f64 {
        match &self.surf {
            SurfaceData::Nts { quad: Some(q), .. } => q[s],
            _ => self.weights[s],
        }
    }

    /// Slaves of a sampled surface (`None` for a full one or a Type-1 model).
    pub fn sampled_slaves(&self) -> Option<usize> {
        match &self.surf {
            SurfaceData::Nts { quad: Some(_), supp, .. } => Some(supp.len()),
            _ => None,
        }
    }

    /// A Type-2 model whose reduced constraints sum over a reduced quadrature of the slaves
    /// ([`crate::rom::sampling`], design note 40): at each of `samples` (typically the
    /// training parameters) the exact online solve of this model is run, and at its lift state
    /// (`û = 0`) and its converged state every paired supported slave's contributions to the
    /// reduced gaps `ŝ_a` and to their derivatives along [`SAMPLING_DIRECTIONS`] fixed
    /// directions of `û` are recorded (each block scaled by its largest full sum); the slaves
    /// and weights that reproduce the full sums to the relative residual `tol`
    /// ([`greedy_nnls`](crate::rom::sampling::greedy_nnls)) replace the supported slaves and
    /// their tributary lengths. The online query then positions, pairs and assembles only
    /// those. A Type-1 model is returned as it is (its constraints are precomputed). The
    /// answers change: measure them against this model's. Refused ([`RomError::Sampling`]):
    /// `tol` outside `[0, 1)`, no samples, or samples without contact (nothing to fit).
    pub fn with_sampled_surface(
        &self,
        samples: &[Vec<f64>],
        p: &RomParams,
        tol: f64,
    ) -> Result<(Self, crate::rom::sampling::Selection), RomError> {
        let SurfaceData::Nts { supp, .. } = &self.surf else {
            let all = crate::rom::sampling::Selection { columns: Vec::new(), weights: Vec::new(), residual: 0.0 };
            return Ok((self.clone(), all));
        };
        if !(tol.is_finite() && (0.0..1.0).contains(&tol)) {
            return Err(RomError::Sampling(format!(
                "the relative residual tol = {tol} is not in [0, 1): give e.g. 3e-2 (0 fits exactly)"
            )));
        }
        if samples.is_empty() {
            return Err(RomError::Sampling("no sample parameters to fit to: pass the training points".into()));
        }
        let (ru, rl) = (self.r_u, self.r_l);
        let cols = supp.clone();
        let mut col_of = vec![usize::MAX; self.n_contact];
        for (c, &s) in cols.iter().enumerate() {
            col_of[s] = c;
        }
        let mut rng = crate::rng::Rng::new(40);
        let dirs: Vec<Vec<f64>> =
            (0..SAMPLING_DIRECTIONS).map(|_| (0..ru).map(|_| rng.uniform_in(-1.0, 1.0)).collect()).collect();
        // rows: per state, r_l value rows then r_l rows per direction; row-major by state
        let per_state = rl * (1 + SAMPLING_DIRECTIONS);
        let mut values: Vec<f64> = Vec::new();
        let mut w = RomWork::default();
        let mut d = [0.0; SAMPLING_DIRECTIONS];
        let mut record = |w: &RomWork, values: &mut Vec<f64>| {
            let at = values.len();
            values.resize(at + per_state * cols.len(), 0.0);
            let block = &mut values[at..];
            let l = &w.lin;
            for (k, &s) in l.ps.iter().enumerate() {
                let c = col_of[s];
                if c == usize::MAX {
                    continue;
                }
                let row = &l.cphi[k * ru..(k + 1) * ru];
                let g = dot(row, &w.u_hat) + l.g0[k];
                d.iter_mut().zip(&dirs).for_each(|(dt, z)| *dt = dot(row, z));
                for e in self.by_node.0[s]..self.by_node.0[s + 1] {
                    let (a, th) = (self.by_node.1[e], self.by_node.2[e]);
                    block[a * cols.len() + c] += th * g;
                    for (t, dt) in d.iter().enumerate() {
                        block[((1 + t) * rl + a) * cols.len() + c] += th * dt;
                    }
                }
            }
        };
        for mu in samples {
            w.prepare(self, mu);
            self.linearize(&mut w);
            record(&w, &mut values);
            if self.solve_in(mu, p, &mut w).outcome == RomOutcome::Converged {
                record(&w, &mut values);
            }
        }
        let (n, rows) = (cols.len(), values.len() / cols.len().max(1));
        // the full sums (tributary weights) and a scale per block kind (values, derivatives)
        let mut b: Vec<f64> =
            (0..rows).map(|r| (0..n).map(|c| values[r * n + c] * self.weights[cols[c]]).sum()).collect();
        let kind = |r: usize| usize::from((r % per_state) >= rl);
        let mut scale = [0.0f64; 2];
        for (r, v) in b.iter().enumerate() {
            scale[kind(r)] = scale[kind(r)].max(v.abs());
        }
        for (r, v) in b.iter_mut().enumerate() {
            let f = if scale[kind(r)] > 0.0 { 1.0 / scale[kind(r)] } else { 0.0 };
            *v *= f;
            values[r * n..(r + 1) * n].iter_mut().for_each(|x| *x *= f);
        }
        if b.iter().all(|v| *v == 0.0) {
            // no training state puts a paired slave under a dual vector: a fit would keep no
            // slave, and the model would constrain nothing
            return Err(RomError::Sampling(
                "no sample state has contact under the dual basis: nothing to fit the quadrature to".into(),
            ));
        }
        // column-major for the greedy fit, which reads whole columns (a row-major matrix made
        // each correlation a strided pass: 2.9 s of ironing-fine's fit at (128, 128))
        let by_col: Vec<f64> =
            (0..n).flat_map(|c| (0..rows).map(move |r| (r, c))).map(|(r, c)| values[r * n + c]).collect();
        drop(values);
        let a = faer::MatRef::from_column_major_slice(&by_col, rows, n);
        let sel = crate::rom::sampling::greedy_nnls(a, &b, tol, n).map_err(|e| RomError::Sampling(e.to_string()))?;
        let mut model = self.clone();
        if let SurfaceData::Nts { supp, quad, .. } = &mut model.surf {
            let mut q = vec![0.0; self.n_contact];
            let mut chosen: Vec<usize> = sel.columns.iter().map(|&c| cols[c]).collect();
            for (&c, &xi) in sel.columns.iter().zip(&sel.weights) {
                q[cols[c]] = xi;
            }
            chosen.sort_unstable();
            *supp = chosen;
            *quad = Some(q);
        }
        model.warm_starts = WarmStarts::default();
        Ok((model, sel))
    }

    /// Start `w.warm` for a cold query at `mu`: the nearest warm-start sample's active set, if
    /// any, and (Type-2) the re-pairing's first point `y`: the nearest sample's `y`, moved
    /// linearly toward a second sample's when `mu` projects inside the segment between the two
    /// (of those, the sample nearest to `mu`; between neighbouring training points of a single
    /// parameter, the neighbour on the other side): `y = y_k + t (y_o - y_k)`,
    /// `t = (mu - mu_k)·(mu_o - mu_k) / |mu_o - mu_k|²` in `(0, 1]`. Between two neighbouring
    /// training points of ironing-fine this starts 2.5x closer to the answer than the nearest
    /// sample (relative distance 1.7e-2 against 4.3e-2; design note 42). Only the path
    /// changes: the re-pairing converges to the same fixed point wherever it has one.
    fn seed_warm(&self, mu: &[f64], w: &mut RomWork) {
        w.warm.clear();
        let lib = &self.warm_starts;
        if lib.sets.is_empty() || mu.len() != lib.dim {
            return;
        }
        let dim = lib.dim.max(1);
        let point = |k: usize| &lib.points[k * dim..(k + 1) * dim];
        let d2 = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
        let mut best = (f64::INFINITY, 0);
        for k in 0..lib.sets.len() {
            let d = d2(point(k), mu);
            if d < best.0 {
                best = (d, k);
            }
        }
        let k = best.1;
        w.warm.extend_from_slice(&lib.sets[k]);
        let Some(yk) = lib.ys.get(k) else { return };
        w.u_hat.copy_from_slice(yk);
        let pk = point(k);
        let mut toward: Option<(f64, usize, f64)> = None;
        for o in (0..lib.ys.len()).filter(|&o| o != k) {
            let po = point(o);
            let len2 = d2(po, pk);
            let t = pk.iter().zip(po).zip(mu).map(|((a, b), m)| (m - a) * (b - a)).sum::<f64>() / len2;
            let d = d2(po, mu);
            if len2 > 0.0 && t > 0.0 && t <= 1.0 && toward.is_none_or(|(best, _, _)| d < best) {
                toward = Some((d, o, t));
            }
        }
        if let Some((_, o, t)) = toward {
            for (u, (a, b)) in w.u_hat.iter_mut().zip(yk.iter().zip(&lib.ys[o])) {
                *u = a + t * (b - a);
            }
        }
    }

    /// Replace the dual basis by `theta` (`n_contact x r_l`, column-major, non-negative) and
    /// keep the primal part: what a dual basis that depends on the parameter (a registered or a
    /// local one, `crom_stages::dual`) needs per query. Costs `O(n_contact r_l)` for a Type-2
    /// problem (the sparse layouts and the supported slaves), `O(nnz(theta) r_u)` for Type-1
    /// (`Ĉ` and `ĝ0`'s terms); no `n_dof` work.
    pub fn set_dual(&mut self, theta: &[f64], r_l: usize) {
        let nc = self.n_contact;
        assert_eq!(theta.len(), nc * r_l, "theta shape");
        let (by_node, by_col) = csr(theta, nc, r_l);
        let r_u = self.r_u;
        match &mut self.surf {
            SurfaceData::Fixed { cphi, cu0, chat, ghat, .. } => {
                chat.clear();
                chat.resize(r_l * r_u, 0.0);
                *ghat = vec![vec![0.0; r_l]; cu0.len()];
                for i in 0..nc {
                    for e in by_node.0[i]..by_node.0[i + 1] {
                        let (a, tw) = (by_node.1[e], by_node.2[e] * self.weights[i]);
                        for j in 0..r_u {
                            chat[a * r_u + j] += tw * cphi[i * r_u + j];
                        }
                        for (g, c) in ghat.iter_mut().zip(cu0.iter()) {
                            g[a] += tw * c[i];
                        }
                    }
                }
            }
            SurfaceData::Nts { ns, slave_fixed, supp, quad, .. } => {
                supp.clear();
                supp.extend((0..*ns).filter(|&s| !slave_fixed[s] && by_node.0[s + 1] > by_node.0[s]));
                *quad = None;
            }
        }
        self.by_node = by_node;
        self.by_col = by_col;
        self.r_l = r_l;
        // the samples' active sets index the old dual basis
        self.warm_starts = WarmStarts::default();
    }

    /// Lengths of every array the online solve can read (name, length): none of them depends
    /// on the number of dofs of the full-order model, only on the ranks and the contact surface.
    pub fn storage(&self) -> Vec<(&'static str, usize)> {
        let mut v = vec![
            ("khat_l", self.khat_l.len()),
            ("u_of_y", self.u_of_y.len()),
            ("weights", self.weights.len()),
            ("theta_by_node", self.by_node.2.len()),
            ("theta_by_col", self.by_col.2.len()),
        ];
        match &self.surf {
            SurfaceData::Fixed { cphi, cu0, chat, ghat, cwc, .. } => v.extend([
                ("cphi", cphi.len()),
                ("cu0", cu0.iter().map(Vec::len).sum()),
                ("chat", chat.len()),
                ("ghat", ghat.iter().map(Vec::len).sum()),
                ("cwc", cwc.len()),
            ]),
            SurfaceData::Nts { x_ref, phi_c, a_terms, supp, quad, w_c, .. } => v.extend([
                ("x_ref", x_ref.len()),
                ("phi_c", phi_c.len()),
                ("a_terms", a_terms.iter().map(Vec::len).sum()),
                ("supp", supp.len()),
                ("quad", quad.as_ref().map_or(0, Vec::len)),
                ("w_c", w_c.len()),
            ]),
        }
        v
    }

    /// The reduced pressure `Theta λ̂` (one value per potential-contact node).
    pub fn pressure(&self, lambda_hat: &[f64]) -> Vec<f64> {
        (0..self.n_contact)
            .map(|i| {
                (self.by_node.0[i]..self.by_node.0[i + 1])
                    .map(|e| self.by_node.2[e] * lambda_hat[self.by_node.1[e]])
                    .sum()
            })
            .collect()
    }

    /// `u0(mu) + Phi û` on all dofs (offline side: reads the full `Phi`).
    pub fn displacement(op: &dyn ContactOperator, phi: &[f64], mu: &[f64], u_hat: &[f64]) -> Vec<f64> {
        let mut u = op.lift(mu);
        let n = u.len();
        for (j, c) in u_hat.iter().enumerate() {
            for (x, p) in u.iter_mut().zip(&phi[j * n..(j + 1) * n]) {
                *x += c * p;
            }
        }
        u
    }

    /// Online: the reduced solution at `mu`. Reads only `self`, `mu` and the buffers in `w`.
    pub fn solve(&self, mu: &[f64], p: &RomParams, w: &mut RomWork) -> ReducedSolution {
        let info = self.solve_in(mu, p, w);
        w.solution(&info)
    }

    /// [`Self::solve`] without allocating: the reduced coordinates stay in `w` (read them with
    /// [`RomWork::solution`]); this is the query the online timings measure.
    ///
    /// Type-2 queries of [`Algorithm::Exact`] apply the full-order solver's vertex-zone rule
    /// ([`crate::contact::vertex`]): when the converged state has slaves with pressure in a
    /// vertex zone (or flip-tied) that are not tied yet, the query is solved again from its
    /// cold start with those slaves forced to their vertices, until no slave is added. The
    /// paper's Algorithm 1 is kept as the paper states it, with flip ties only (with the rule,
    /// its restarts settled on other tie sets: errors up to 8e-4 with full bases on hertz
    /// training points, against 3.3e-4 without).
    pub fn solve_in(&self, mu: &[f64], p: &RomParams, w: &mut RomWork) -> SolveInfo {
        w.prepare(self, mu);
        w.forced.clear();
        if let SurfaceData::Nts { ns, .. } = &self.surf {
            w.forced.resize(*ns, None);
        }
        let (mut iterations, mut linearizations, mut resume) = (0, 0, false);
        loop {
            let (out, retied) = match p.algorithm {
                Algorithm::Exact => self.solve_exact(mu, p, w, resume),
                Algorithm::Paper => (self.solve_paper(p, w), false),
            };
            iterations += out.0;
            linearizations += w.lin.count;
            let rule = p.algorithm == Algorithm::Exact;
            if !retied && (out.2 != RomOutcome::Converged || !rule || !self.add_zone_ties(w)) {
                // the answer in the caller's basis: û = L^{-T} y
                let ru = self.r_u;
                w.coords.clear();
                w.coords.resize(ru, 0.0);
                for (j, &y) in w.u_hat.iter().enumerate() {
                    axpy(y, &self.u_of_y[j * ru..j * ru + j + 1], &mut w.coords[..j + 1]);
                }
                return SolveInfo { iterations, linearizations, active: out.1, outcome: out.2 };
            }
            // the next round starts from this round's answer (see `solve_exact`)
            w.lin.restart(&w.forced);
            resume = true;
        }
    }

    /// Add to `w.forced` the supported slaves with pressure that are in a vertex zone or
    /// flip-tied at the converged state in `w`; returns whether any was added.
    fn add_zone_ties(&self, w: &mut RomWork) -> bool {
        let SurfaceData::Nts { supp, .. } = &self.surf else { return false };
        // the largest pressure over every slave (a slave outside the support has none)
        w.pressures.clear();
        w.pressures.extend((0..w.forced.len()).map(|s| self.pressure_at(s, &w.lam)));
        let max = w.pressures.iter().fold(0.0f64, |m, &p| m.max(p));
        let l = &w.lin;
        let mut added = false;
        for &s in supp {
            if w.forced[s].is_some() || !l.pairs[s].kind.is_paired() || w.pressures[s] <= 1e-9 * max {
                continue;
            }
            // every supported slave not forced had its natural pairing recorded at its current
            // position by the last linearisation (a slave known unpaired is skipped above), so
            // the rule needs no search
            if let Some(v) = l.ties.rule_tie_recorded(s, [l.xc[2 * s], l.xc[2 * s + 1]], &l.xm) {
                w.forced[s] = Some(v);
                added = true;
            }
        }
        added
    }

    /// The exact online solve from `w.u_hat`. `resume`: a later round of the vertex-zone rule,
    /// started from the previous round's answer and active set instead of from the cold start
    /// the full-order solver uses (a tied slave moves by less than 1 % of a segment). Where the
    /// re-pairing has one fixed point with those ties, as the rule makes it for the full-order
    /// problem (design note 27), that is the cold round's answer: the full-basis reproduction
    /// of every hertz training snapshot (each has tied slaves) to 1e-9 tests it. Where a
    /// truncated reduced problem has several nearby fixed points, which one a start reaches
    /// is a property of the start, cold or resumed alike (measured with other starts on
    /// ironing-coarse: 1 point in 30 moved, by 5e-5 relative, against a reduced-model error of
    /// 1.4e-2 there).
    ///
    /// The vertex-zone rule is first asked once the round is within [`ZONE_PROBE`] of its fixed
    /// point (relative), not at the fixed point itself: where it ties a slave there, the round
    /// ends at once (returns `true`; the next round starts from this iterate), sparing the
    /// linearisations that would converge a state the ties are about to change. Where it ties
    /// nothing, the round goes on to `u_tol` and the caller asks the rule again at the fixed
    /// point, as the full-order solver does. A decision taken `ZONE_PROBE` from the fixed
    /// point differs from the one at it only for a slave within that distance of a zone's
    /// edge (measured on ironing-fine's 127 test points at five rank pairs: the same answers
    /// to 2.1e-11, design note 41).
    fn solve_exact(
        &self,
        mu: &[f64],
        p: &RomParams,
        w: &mut RomWork,
        resume: bool,
    ) -> ((usize, usize, RomOutcome), bool) {
        let ru = self.r_u;
        if !resume {
            self.seed_warm(mu, w);
        }
        self.linearize(w);
        let mut scale = self.offset_scale(w);
        if scale == 0.0 && w.u_hat.iter().any(|&v| v != 0.0) {
            // no constraint at the sample's answer: start cold
            w.u_hat.iter_mut().for_each(|v| *v = 0.0);
            w.warm.clear();
            self.linearize(w);
            scale = self.offset_scale(w);
        }
        if scale == 0.0 {
            return ((0, 0, RomOutcome::Converged), false);
        }
        let tol = p.gap_tol * scale;
        let max_steps = 10 * (ru + self.r_l) + 10;
        let repairs = matches!(self.surf, SurfaceData::Nts { .. });
        w.seen.clear();
        w.seen.push(w.lin.pairing_hash());
        let (mut steps, mut smooth, mut last_du, mut probed) = (0, false, 0.0f64, false);
        let mut newton = true;
        for _ in 0..p.max_iter {
            let out = {
                let RomWork { lin, qp, x, warm, .. } = w;
                let mut oracle = Oracle { m: self, lin };
                solve_qp(Factor::Identity, ru, &mut oracle, tol, max_steps, warm, x, qp)
            };
            steps += w.qp.steps;
            match out {
                QpOutcome::Solved => {}
                QpOutcome::Infeasible(_) => return ((steps, w.qp.active.len(), RomOutcome::Infeasible), false),
                QpOutcome::StepLimit => return ((steps, w.qp.active.len(), RomOutcome::NotConverged), false),
            }
            w.lam.iter_mut().for_each(|l| *l = 0.0);
            for (&a, &u) in w.qp.active.iter().zip(&w.qp.u) {
                w.lam[a] = u;
            }
            w.warm.clear();
            w.warm.extend_from_slice(&w.qp.active);
            if !repairs {
                // Type-1: one linearisation, the QP solution is the answer
                w.u_hat.copy_from_slice(&w.x);
                return ((steps, w.qp.active.len(), RomOutcome::Converged), false);
            }
            let du = w.x.iter().zip(&w.u_hat).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
            let un = dot(&w.x, &w.x).sqrt();
            // distance to the fixed point, estimated from the contraction of the last two steps
            // (a linearly convergent iteration with ratio rho is within du rho / (1 - rho); the
            // Newton-corrected one contracts faster as it converges, so this overestimates)
            let rho = if smooth && last_du > 0.0 { du / last_du } else { f64::INFINITY };
            let estimate = if rho < 0.5 { du * rho / (1.0 - rho) } else { du };
            last_du = du;
            if !probed && estimate <= ZONE_PROBE * un {
                probed = true;
                if self.add_zone_ties(w) {
                    w.u_hat.copy_from_slice(&w.x);
                    return ((steps, w.qp.active.len(), RomOutcome::Converged), true);
                }
            }
            if estimate <= p.u_tol * un {
                // fixed point of the linearisation: converged if the pairing at the solution is
                // the one it was computed with
                w.u_hat.copy_from_slice(&w.x);
                if !self.linearize_with(w, false) {
                    return ((steps, w.qp.active.len(), RomOutcome::Converged), false);
                }
                self.assemble(w);
                smooth = false;
                continue;
            }
            // the next linearisation point: the QP's answer, Newton-corrected for the gaps'
            // curvature once the pairing has settled (a step across a change of pairing is
            // outside the curvature's reach; measured, correcting those too made the ironing-fine
            // queries 8 % slower: more corrections than linearisations saved)
            if newton && smooth && w.lin.newton() {
                self.curvature_step(w);
            }
            w.u_hat.copy_from_slice(&w.x);
            let changed = self.linearize(w);
            if changed {
                // a pairing seen before, reached by a change: the re-pairing cycles
                let h = w.lin.pairing_hash();
                if w.seen.contains(&h) {
                    if !newton {
                        return ((steps, w.qp.active.len(), RomOutcome::Cycled), false);
                    }
                    // the corrected steps cycle: go on with the plain re-pairing, which decides
                    newton = false;
                    w.seen.clear();
                }
                w.seen.push(h);
            }
            smooth = !changed;
        }
        ((steps, w.qp.active.len(), RomOutcome::NotConverged), false)
    }

    /// The Newton correction of a re-pairing step (design note 42, [`super::curvature`]):
    /// with `x` the QP's answer at the linearisation `y_k = û` and `A` its active set,
    ///
    /// ```text
    /// x <- x - (I - P_A) H (x - y_k),   H = Σ_s p_s [A_s B_sᵀ + B_s A_sᵀ + g_s A_s A_sᵀ],
    /// ```
    ///
    /// (a tied slave contributes `p_s B_s A_sᵀ` only, [`super::curvature`]),
    /// `P_A` the projector onto the active constraints' rows (their gaps stay as the QP left
    /// them) and `p_s` the forces of the QP's multipliers. It is the SQP step with the
    /// Lagrangian's Hessian `I + H` to first order in `H` (`(I + H)^{-1} ≈ I - H` on the
    /// active constraints' null space), which turns the re-pairing's linear rate from `|H|`
    /// (about 1e-2) to `|H|²` plus the step's second-order term. At a fixed point `x = y_k`
    /// the correction vanishes, so the answers are the QP's own.
    fn curvature_step(&self, w: &mut RomWork) {
        let SurfaceData::Nts { ns, phi_c, .. } = &self.surf else { return };
        let (ns, ru) = (*ns, self.r_u);
        let l = &mut w.lin;
        // the forces of the active multipliers on the slaves, scattered by column: only the
        // active columns are read (`pressure_at` reads every column of a slave's row, most of
        // them zero here; measured 2.6 % of an ironing-fine query against 0.6 %)
        l.force.resize(self.n_contact, 0.0);
        for (&a, &lam) in w.qp.active.iter().zip(&w.qp.u) {
            for e in self.by_col.0[a]..self.by_col.0[a + 1] {
                l.force[self.by_col.1[e]] += self.by_col.2[e] * lam;
            }
        }
        l.step.clear();
        l.step.extend(w.x.iter().zip(&w.u_hat).map(|(a, b)| a - b));
        l.hv.clear();
        l.hv.resize(ru, 0.0);
        for &s in &l.ps {
            let p = self.gap_weight(s) * l.force[s];
            if p > 0.0 {
                if let Some(c) = GapCurvature::new(s, ns, &l.pairs[s], &l.xm) {
                    c.apply(p, phi_c, ru, &l.step, &mut l.hv);
                }
            }
        }
        for &a in &w.qp.active {
            for e in self.by_col.0[a]..self.by_col.0[a + 1] {
                l.force[self.by_col.1[e]] = 0.0;
            }
        }
        w.qp.remove_active_span(ru, &mut l.hv);
        axpy(-1.0, &l.hv, &mut w.x);
    }

    fn solve_paper(&self, p: &RomParams, w: &mut RomWork) -> (usize, usize, RomOutcome) {
        let (ru, rl) = (self.r_u, self.r_l);
        self.linearize(w);
        let scale = self.offset_scale(w);
        let violated = |g: f64| g < -p.gap_tol * scale;
        // deterministic start: the most violated reduced constraint at û = 0
        let start = (0..rl).filter(|&a| violated(w.s[a])).min_by(|&a, &b| w.s[a].total_cmp(&w.s[b]));
        let Some(first) = start else {
            return (0, 0, RomOutcome::Converged);
        };
        let mut mask = vec![false; rl];
        mask[first] = true;
        let mut history: Vec<(u64, PaperState)> = Vec::new();
        let (mut c_a, mut g_a, mut lam_a, mut work, mut row) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), vec![0.0; ru]);
        let mut prev = vec![0.0; ru];
        let repairs = matches!(self.surf, SurfaceData::Nts { .. });
        for it in 1..=p.max_iter {
            prev.copy_from_slice(&w.u_hat);
            // offsets ĝ0 at the current linearisation, rows of the active constraints
            self.offsets(w);
            c_a.clear();
            g_a.clear();
            let idx: Vec<usize> = (0..rl).filter(|&a| mask[a]).collect();
            for &a in &idx {
                let RomWork { lin, .. } = w;
                Oracle { m: self, lin }.row(a, &mut row);
                c_a.extend_from_slice(&row);
                g_a.push(w.s[a]);
            }
            lam_a.clear();
            lam_a.resize(idx.len(), 0.0);
            solve_saddle(Factor::Identity, ru, &c_a, &g_a, &mut w.u_hat, &mut lam_a, &mut work);
            w.lam.iter_mut().for_each(|x| *x = 0.0);
            for (k, &a) in idx.iter().enumerate() {
                w.lam[a] = lam_a[k];
            }
            let changed = self.linearize(w);
            {
                let RomWork { lin, s, u_hat, .. } = w;
                Oracle { m: self, lin }.values(u_hat, s);
            }
            // a multiplier counts as negative below -PAPER_LAM_TOL of the largest one: an exact
            // sign test cycles on degenerate constraints (zero gap, multiplier zero up to
            // rounding; measured -6e-12 relative on hertz with full bases)
            let lam_tol = PAPER_LAM_TOL * w.lam.iter().fold(0.0f64, |m, l| m.max(l.abs()));
            let new: Vec<bool> =
                (0..rl).map(|a| if mask[a] { w.lam[a] >= -lam_tol } else { violated(w.s[a]) }).collect();
            let settled = new == mask && !changed;
            let du = w.u_hat.iter().zip(&prev).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
            let un = w.u_hat.iter().map(|a| a * a).sum::<f64>().sqrt();
            let moved = repairs && du > p.u_tol * un;
            let active = mask.iter().filter(|m| **m).count();
            if settled && !moved {
                return (it, active, RomOutcome::Converged);
            }
            if settled {
                continue;
            }
            // a repeated (active set, pairing) state cycles; states are compared through their
            // hash first (O(1) per earlier state instead of O(r_l + n_s)), then in full
            let state = (new.clone(), w.lin.pairs.iter().map(|p| p.kind).collect::<Vec<_>>());
            let h = state_hash(&state.0, w.lin.pairing_hash());
            if history.iter().any(|(hh, st)| *hh == h && *st == state) {
                return (it, active, RomOutcome::Cycled);
            }
            history.push((h, state));
            mask = new;
        }
        (p.max_iter, mask.iter().filter(|m| **m).count(), RomOutcome::NotConverged)
    }

    /// Reduced offsets `ĝ0` at the current linearisation into `w.s`; returns their largest
    /// magnitude.
    fn offset_scale(&self, w: &mut RomWork) -> f64 {
        self.offsets(w);
        w.s.iter().fold(0.0f64, |m, g| m.max(g.abs()))
    }

    /// The reduced gaps at `û = 0` (Type-1: `ĝ(μ)` itself).
    fn offsets(&self, w: &mut RomWork) {
        let RomWork { lin, s, zero, .. } = w;
        if let SurfaceData::Fixed { .. } = &self.surf {
            s.copy_from_slice(&lin.g_mu);
        } else {
            Oracle { m: self, lin }.values(zero, s);
        }
    }

    /// Type-2: positions of the needed contact nodes at `y = w.u_hat`, re-pair the supported
    /// slaves (recording the pairing history for vertex ties) and rebuild their gap rows.
    /// Returns whether a pairing kind changed. Type-1: nothing to do.
    fn linearize(&self, w: &mut RomWork) -> bool {
        self.linearize_with(w, true)
    }

    /// [`Self::linearize`], rebuilding the gap rows only if `assemble`.
    ///
    /// A slave searched ([`MasterIndex::closest_point_proved`]) gets two proofs that its
    /// natural pairing holds while the slave and the masters move little:
    ///
    /// 1. a radius `R_s` within which the pairing kind cannot change at all. The slave and the
    ///    masters move by at most `(|Psi_s| + max_m |Psi_m|) |Δy|` per change `Δy` of the
    ///    coordinates, so with `T` the path length of `y` over the linearisations of this
    ///    query, the kind is known while `T <= T_s + R_s / (|Psi_s| + max_m |Psi_m|)` (its
    ///    budget), `T_s` the path length when it was searched. Then an unpaired slave keeps its
    ///    pairing without even being placed, and a slave paired with segment `k` is projected
    ///    on `k` again (the search's own arithmetic).
    /// 2. a [`Certificate`], for when the budget is spent: the natural pairing is re-derived
    ///    from the neighbourhood of the certified feature alone ([`MasterIndex::recheck`])
    ///    while the slave's actual displacement since its search plus the masters' largest
    ///    displacement (summed over the linearisations since, each measured when every master
    ///    was placed at it and the previous one, else bounded by `max_m |Psi_m| |Δy|`) is
    ///    below the certificate's radius. Unlike 1 it reads positions, so it needs them; it
    ///    spares the searches of the slaves far from the master (unpaired, barely moving)
    ///    and of those that slide along a segment.
    ///
    /// Slaves forced to a vertex by the zone rule are never searched; every other slave is
    /// searched and gets new proofs. Without `assemble` (the check after convergence), a
    /// pairing known unchanged by 1 returns at once: positions, pairs and rows stay those of
    /// the last linearisation, `|Δy| <= u_tol |y|` away.
    fn linearize_with(&self, w: &mut RomWork, assemble: bool) -> bool {
        let SurfaceData::Nts { ns, nm, supp, node_norm, master_norm, phi_c, .. } = &self.surf else {
            w.lin.count = 1;
            return false;
        };
        let (ns, nm) = (*ns, *nm);
        let l = &mut w.lin;
        let path = l.travel_to(&w.u_hat);
        let travel = path.unwrap_or(0.0);
        let known = |l: &LinState, s: usize| l.budget_holds(s, path);
        if !assemble && supp.iter().all(|&s| known(l, s) || l.ties.forced(s).is_some()) {
            return false;
        }
        let step = travel - l.travel;
        l.travel = travel;
        l.last_u.clear();
        l.last_u.extend_from_slice(&w.u_hat);
        let (pairs, first) = (&l.pairs, l.fresh);
        let budget = &l.budget;
        let slaves = supp.iter().copied().filter(|&s| first || travel > budget[s] || pairs[s].kind.is_paired());
        set_positions(phi_c, self.r_u, &w.u_hat, &l.base, &mut l.xc, slaves);
        // Every slave known by its budget on a segment or unpaired, or forced to a vertex,
        // needs the masters next to its pairing only; any other needs every master (for its
        // certificate or its search).
        let everything = supp.iter().any(|&s| {
            l.ties.forced(s).is_none()
                && !(known(l, s) && matches!(l.cert[s].feature, Feature::Segment(_) | Feature::End(_)))
        });
        let measured = l.prev_full && !first;
        l.masters_all = false;
        if everything {
            l.all_masters(phi_c, self.r_u, &w.u_hat, ns, nm);
            // the masters' largest displacement since the last linearisation, measured when
            // that one placed them all too
            let moved = if measured {
                l.xm.iter().zip(&l.xm_prev).map(|(&a, &b)| distance(a, b)).fold(0.0f64, f64::max)
            } else {
                master_norm * step
            };
            l.master_path += moved;
        } else {
            l.master_path += master_norm * step;
            l.stamp += 1;
            for &s in supp {
                // a tie's averaged normal reads v - 1..=v + 1, an end tie v and its segment, a
                // segment k its ends (and a tie on them up to k + 2)
                let lo = match (l.ties.forced(s), l.pairs[s].kind) {
                    (Some(v), _) | (None, PairKind::Tied(v) | PairKind::End(v) | PairKind::Vertex(v)) => Some(v),
                    (None, PairKind::Segment(k)) => Some(k),
                    (None, PairKind::None) => None,
                };
                let cert = match l.cert[s].feature {
                    Feature::Segment(k) | Feature::End(k) => Some(k),
                    _ => None,
                };
                for v in [lo, cert].into_iter().flatten() {
                    l.window(phi_c, self.r_u, &w.u_hat, ns, v.saturating_sub(1)..(v + 3).min(nm));
                }
            }
        }
        let mut changed = false;
        for &s in supp {
            let xs = [l.xc[2 * s], l.xc[2 * s + 1]];
            if let Some(v) = l.ties.forced(s) {
                let p = vertex_pair(xs, &l.xm, v, PairKind::Tied(v));
                changed |= p.kind != l.pairs[s].kind;
                l.pairs[s] = p;
                continue;
            }
            // the natural pairing from proof 1, else proof 2
            let mut nat = l.budget_pair(s, xs, path);
            if nat.is_none() && l.masters_all && !first && l.proofs() {
                let (x0, at) = (l.cert_x[s], l.cert_path[s]);
                #[cfg(test)]
                if l.verify {
                    // the bookkeeping bounds the masters' actual displacement since the search
                    let actual = l.xm.iter().zip(&l.cert_xm[s]).map(|(&a, &b)| distance(a, b)).fold(0.0f64, f64::max);
                    assert!(actual <= (l.master_path - at) * (1.0 + 1e-12) + 1e-15, "slave {s}: {actual} moved");
                }
                let moved = distance(xs, x0) + (l.master_path - at);
                if let Some((p, r)) = MasterIndex::recheck(xs, &l.xm, &l.cert[s], moved) {
                    // a new budget from here (proof 1 again)
                    l.budget[s] = budget_until(travel, r, node_norm[s] + master_norm);
                    nat = Some(p);
                }
            }
            #[cfg(test)]
            if let (Some(q), true) = (nat, l.verify) {
                // every proved pairing against a search at the same positions
                if !l.masters_all {
                    l.all_masters(phi_c, self.r_u, &w.u_hat, ns, nm);
                }
                assert_eq!(q, l.index.closest_point(xs, &l.xm), "slave {s}: proved pairing is not the search's");
            }
            let p = match nat {
                Some(nat) => l.ties.pair_known(s, nat, xs, &l.xm, l.count),
                None => {
                    if !l.masters_all {
                        l.all_masters(phi_c, self.r_u, &w.u_hat, ns, nm);
                    }
                    let (p, r, cert) = l.ties.pair_proved(s, xs, &l.xm, &l.index, l.count);
                    l.budget[s] = budget_until(travel, r, node_norm[s] + master_norm);
                    l.cert[s] = cert;
                    l.cert_x[s] = xs;
                    l.cert_path[s] = l.master_path;
                    #[cfg(test)]
                    if l.verify {
                        l.cert_xm.resize(ns, Vec::new());
                        l.cert_xm[s] = l.xm.clone();
                    }
                    p
                }
            };
            changed |= p.kind != l.pairs[s].kind;
            l.pairs[s] = p;
        }
        // the next linearisation measures the masters' displacement from here if all are placed
        l.prev_full = l.masters_all;
        if l.masters_all {
            l.xm_prev.clear();
            l.xm_prev.extend_from_slice(&l.xm);
        }
        l.count += 1;
        l.fresh = false;
        if assemble {
            self.assemble(w);
        }
        changed
    }

    /// Gap rows of the paired supported slaves: `C Phi` rows and constant parts.
    fn assemble(&self, w: &mut RomWork) {
        let SurfaceData::Nts { ns, supp, phi_c, .. } = &self.surf else { return };
        let ru = self.r_u;
        let l = &mut w.lin;
        l.ps.clear();
        l.g0.clear();
        for &s in supp {
            l.ps_of[s] = usize::MAX;
            if !l.pairs[s].kind.is_paired() {
                continue;
            }
            let row = GapRow::new(s, *ns, &l.pairs[s]);
            // row k of `cphi` (the buffer only grows: every row below `ps.len()` is written
            // here before it is read)
            let at = l.ps.len() * ru;
            l.ps_of[s] = l.ps.len();
            l.ps.push(s);
            if l.cphi.len() < at + ru {
                l.cphi.resize(at + ru, 0.0);
            }
            combine_rows(&row, phi_c, ru, &mut l.cphi[at..at + ru]);
            l.g0.push(row.apply(&l.base));
        }
    }

    /// The reduced inf-sup constant of the saddle-point system at the last solve's
    /// linearisation (after [`Self::solve_in`] with the same `w`):
    ///
    /// ```text
    /// beta = min_{λ̂ != 0} max_{û != 0} λ̂ᵀ Â û / (|λ̂| ||û||_K̂) = sigma_min(Â L^{-T}),   K̂ = L Lᵀ,
    /// ```
    ///
    /// `Â` the reduced constraint rows (`ĝ(û) = Â û + ĝ0`) of the dual basis vectors whose row
    /// is non-zero at this pairing (a vector supported only on unpaired nodes constrains
    /// nothing), `|λ̂|` the Euclidean norm of the coefficients. `beta > 0` iff the reduced
    /// multipliers are unique when every such constraint is active (the saddle-point system of
    /// the paper's Algorithm 1 is then non-singular); it is 0 when more dual vectors constrain
    /// than there are primal modes (`r_dual > r_primal`: too small a primal basis for the dual
    /// one) or paired contact nodes under them (the rows live on those nodes), or when two dual
    /// vectors constrain alike (nearly parallel dual bases). `None`
    /// without a constraining row. Costs one `k x r_primal` SVD, `k <= r_dual`: an offline
    /// diagnostic, not part of the online solve.
    pub fn inf_sup(&self, w: &mut RomWork) -> Option<f64> {
        let ru = self.r_u;
        let mut oracle = Oracle { m: self, lin: &mut w.lin };
        let mut rows: Vec<f64> = Vec::new();
        let mut row = vec![0.0; ru];
        for a in 0..self.r_l {
            oracle.row(a, &mut row);
            if row.iter().any(|v| *v != 0.0) {
                rows.extend_from_slice(&row);
            }
        }
        let k = rows.len() / ru.max(1);
        if k == 0 || ru == 0 {
            return None;
        }
        // Â = Thetaᵀ W (C Phi) on the paired nodes: its rank is at most the number of paired
        // nodes as well as r_u, so more constraining rows than either is exactly singular.
        let paired = match &self.surf {
            SurfaceData::Fixed { paired, .. } => paired.iter().filter(|p| **p).count(),
            SurfaceData::Nts { .. } => w.lin.ps.len(),
        };
        if k > ru.min(paired) {
            return Some(0.0);
        }
        // sigma_min of M = Â L^{-T} (k x r_u, row-major in `rows`) by its SVD: accurate to
        // eps |M|, where lambda_min(M Mᵀ) would floor beta at sqrt(eps) |M|.
        let m = faer::MatRef::from_row_major_slice(&rows, k, ru);
        let sv = m.singular_values().ok()?;
        Some(sv.iter().copied().fold(f64::INFINITY, f64::min))
    }

    /// The indicator of the solution in `w` (after [`Self::solve`] with the same `w` and `mu`).
    pub fn indicator(&self, mu: &[f64], w: &mut RomWork) -> Indicator {
        let ru = self.r_u;
        // gaps and force-carrying rows over every potential-contact node
        let mut force = 0.0;
        let (mut pen, mut comp_sum, mut unpaired) = (0.0f64, 0.0, 0.0);
        let mut phit_f = std::mem::take(&mut w.phit_f);
        phit_f.clear();
        phit_f.resize(ru, 0.0);
        let fww; // F^T W F
        match &self.surf {
            SurfaceData::Fixed { cphi, cu0, paired, cwc, .. } => {
                let nc = self.n_contact;
                w.fnode.clear();
                for i in 0..nc {
                    let f = self.weights[i] * self.pressure_at(i, &w.lam);
                    force += f;
                    if !paired[i] {
                        unpaired += f;
                        continue;
                    }
                    let g = dot(&cphi[i * ru..(i + 1) * ru], &w.u_hat) + affine(&cu0[0], &cu0[1..], mu, i);
                    pen = pen.max(-g);
                    comp_sum += f * g.abs();
                    if f != 0.0 {
                        w.fnode.push((i, f));
                        for (o, c) in phit_f.iter_mut().zip(&cphi[i * ru..(i + 1) * ru]) {
                            *o += f * c;
                        }
                    }
                }
                fww = w
                    .fnode
                    .iter()
                    .map(|&(i, fi)| w.fnode.iter().map(|&(j, fj)| fi * fj * cwc[i * nc + j]).sum::<f64>())
                    .sum::<f64>();
            }
            SurfaceData::Nts { ns, nm, slave_fixed, phi_c, w_c, .. } => {
                let (ns, nm) = (*ns, *nm);
                let l = &mut w.lin;
                let slaves = || (0..ns).filter(|&s| !slave_fixed[s]);
                // supported slaves whose natural pairing kind the solve's budgets still prove
                // (see `linearize_with`) are not searched again; the others are
                let path = l.travel_to(&w.u_hat);
                let by_node = &self.by_node;
                set_positions(phi_c, ru, &w.u_hat, &l.base, &mut l.xc, slaves());
                l.all_masters(phi_c, ru, &w.u_hat, ns, nm);
                let ncd = l.xc.len();
                l.fc.clear();
                l.fc.resize(ncd, 0.0);
                for s in slaves() {
                    let xs = [l.xc[2 * s], l.xc[2 * s + 1]];
                    let supported = by_node.0[s + 1] > by_node.0[s];
                    let nat = if supported { l.budget_pair(s, xs, path) } else { None };
                    let pr: Pair = match nat {
                        Some(nat) => l.ties.peek_known(s, nat, xs, &l.xm),
                        None => l.ties.pair_peek(s, xs, &l.xm, &l.index),
                    };
                    let f = self.weights[s] * self.pressure_at(s, &w.lam);
                    force += f;
                    if !pr.kind.is_paired() {
                        unpaired += f;
                        continue;
                    }
                    let row = GapRow::new(s, ns, &pr);
                    let g = row.apply(&l.xc);
                    pen = pen.max(-g);
                    comp_sum += f * g.abs();
                    if f != 0.0 {
                        row.scatter(f, &mut l.fc);
                        for (cd, c) in row.entries() {
                            for (o, v) in phit_f.iter_mut().zip(&phi_c[cd * ru..(cd + 1) * ru]) {
                                *o += f * c * v;
                            }
                        }
                    }
                }
                let nz: Vec<usize> = (0..ncd).filter(|&i| l.fc[i] != 0.0).collect();
                fww = nz
                    .iter()
                    .map(|&i| nz.iter().map(|&j| l.fc[i] * l.fc[j] * w_c[i * ncd + j]).sum::<f64>())
                    .sum::<f64>();
            }
        }
        // ||Psi y - K^{-1} F||_K^2 = |y - Psi^T F|^2 + (F^T W F - |Psi^T F|^2), Psi K-orthonormal
        let (z, y) = (&w.u_hat, &phit_f);
        let first: f64 = z.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum();
        let second = (fww - dot(y, y)).max(0.0);
        let un = dot(z, z).sqrt();
        let eta = (first + second).sqrt();
        w.phit_f = phit_f;
        Indicator {
            penetration: pen.max(0.0),
            complementarity: if force > 0.0 { comp_sum / force } else { 0.0 },
            unpaired_force: if force > 0.0 { unpaired / force } else { 0.0 },
            residual: if un > 0.0 {
                eta / un
            } else if eta > 0.0 {
                f64::INFINITY
            } else {
                0.0
            },
        }
    }

    /// The gap of every paired potential-contact node at the solution in `w` (after
    /// [`Self::solve_in`] with the same `w` and `mu`), as `(node, gap)`, over every node of the
    /// surface — not only the support of the dual basis: Type-2 positions and pairs every
    /// non-fixed slave with the solver's rule (as [`Self::indicator`] does). Unpaired nodes carry
    /// no constraint and are left out. What a dual basis that grows (the dictionary's working
    /// set, `crom_stages::dual::dictionary`) checks its candidates against.
    pub fn node_gaps(&self, mu: &[f64], w: &mut RomWork, out: &mut Vec<(usize, f64)>) {
        out.clear();
        let ru = self.r_u;
        match &self.surf {
            SurfaceData::Fixed { cphi, cu0, paired, .. } => {
                for (i, &p) in paired.iter().enumerate() {
                    if p {
                        out.push((i, dot(&cphi[i * ru..(i + 1) * ru], &w.u_hat) + affine(&cu0[0], &cu0[1..], mu, i)));
                    }
                }
            }
            SurfaceData::Nts { ns, nm, slave_fixed, phi_c, .. } => {
                let (ns, nm) = (*ns, *nm);
                let l = &mut w.lin;
                let slaves = || (0..ns).filter(|&s| !slave_fixed[s]);
                set_positions(phi_c, ru, &w.u_hat, &l.base, &mut l.xc, slaves().chain(ns..ns + nm));
                l.index_masters(ns, nm);
                for s in slaves() {
                    let xs = [l.xc[2 * s], l.xc[2 * s + 1]];
                    let pr = l.ties.pair_peek(s, xs, &l.xm, &l.index);
                    if pr.kind.is_paired() {
                        out.push((s, GapRow::new(s, ns, &pr).apply(&l.xc)));
                    }
                }
            }
        }
    }

    fn pressure_at(&self, i: usize, lam: &[f64]) -> f64 {
        (self.by_node.0[i]..self.by_node.0[i + 1]).map(|e| self.by_node.2[e] * lam[self.by_node.1[e]]).sum()
    }
}

/// The reduced constraints at the current linearisation, for the QP.
struct Oracle<'a> {
    m: &'a ReducedModel,
    lin: &'a mut LinState,
}

impl QpConstraints for Oracle<'_> {
    fn len(&self) -> usize {
        self.m.r_l
    }

    fn values(&mut self, x: &[f64], s: &mut [f64]) {
        let (m, ru) = (self.m, self.m.r_u);
        match &m.surf {
            SurfaceData::Fixed { chat, .. } => {
                for (a, sa) in s.iter_mut().enumerate() {
                    *sa = dot(&chat[a * ru..(a + 1) * ru], x) + self.lin.g_mu[a];
                }
            }
            SurfaceData::Nts { .. } => {
                s.iter_mut().for_each(|v| *v = 0.0);
                let l = &*self.lin;
                // at x = 0 (the QP's warm start) the gaps are the constant parts
                let zero = x.iter().all(|&v| v == 0.0);
                for (k, &sl) in l.ps.iter().enumerate() {
                    let g = if zero { l.g0[k] } else { dot(&l.cphi[k * ru..(k + 1) * ru], x) + l.g0[k] };
                    let wg = m.gap_weight(sl) * g;
                    for e in m.by_node.0[sl]..m.by_node.0[sl + 1] {
                        s[m.by_node.1[e]] += m.by_node.2[e] * wg;
                    }
                }
            }
        }
    }

    fn row(&mut self, a: usize, out: &mut [f64]) {
        let (m, ru) = (self.m, self.m.r_u);
        match &m.surf {
            SurfaceData::Fixed { chat, .. } => out.copy_from_slice(&chat[a * ru..(a + 1) * ru]),
            SurfaceData::Nts { .. } => {
                out.iter_mut().for_each(|v| *v = 0.0);
                let l = &*self.lin;
                for e in m.by_col.0[a]..m.by_col.0[a + 1] {
                    let sl = m.by_col.1[e];
                    let k = l.ps_of[sl];
                    if k == usize::MAX {
                        continue;
                    }
                    let tw = m.by_col.2[e] * m.gap_weight(sl);
                    for (o, c) in out.iter_mut().zip(&l.cphi[k * ru..(k + 1) * ru]) {
                        *o += tw * c;
                    }
                }
            }
        }
    }
}

/// Linearisation state of a Type-2 query.
#[derive(Debug, Clone, Default)]
struct LinState {
    /// Reference position plus lift on the contact dofs.
    base: Vec<f64>,
    /// Current positions of the contact dofs (only the needed nodes are up to date).
    xc: Vec<f64>,
    xm: Vec<[f64; 2]>,
    index: MasterIndex,
    ties: VertexTies,
    pairs: Vec<Pair>,
    /// Paired supported slaves, their `C Phi` rows (row-major) and constant parts.
    ps: Vec<usize>,
    ps_of: Vec<usize>,
    cphi: Vec<f64>,
    g0: Vec<f64>,
    /// The Newton correction's buffers: forces per slave (zero between uses), the step and
    /// `H` times it.
    force: Vec<f64>,
    step: Vec<f64>,
    hv: Vec<f64>,
    /// Contact forces on the contact dofs (indicator).
    fc: Vec<f64>,
    /// Type-1: `ĝ0(mu)` of the query.
    g_mu: Vec<f64>,
    /// No linearisation yet in this query: every supported slave is searched.
    fresh: bool,
    /// Path length of `y` over the linearisations of this query, and `y` at the last one.
    travel: f64,
    last_u: Vec<f64>,
    /// Path length up to which each slave's pairing kind is known (see
    /// [`ReducedModel::linearize_with`]).
    budget: Vec<f64>,
    /// Linearisations computed.
    count: usize,
    /// Whether `xm` and `index` hold every master at the last linearisation (else only the
    /// masters next to the pairings, see [`ReducedModel::linearize_with`]).
    masters_all: bool,
    /// Per master the `stamp` of the linearisation that placed it last.
    placed: Vec<usize>,
    stamp: usize,
    /// Each slave's certificate from its last search, its position then and `master_path`
    /// then (see [`ReducedModel::linearize_with`]).
    cert: Vec<Certificate>,
    cert_x: Vec<[f64; 2]>,
    cert_path: Vec<f64>,
    /// Bound of the path length of the largest master displacement over this query's
    /// linearisations, and the masters at the last linearisation that placed them all.
    master_path: f64,
    xm_prev: Vec<[f64; 2]>,
    prev_full: bool,
    /// Tests: search every slave at every linearisation (no proofs).
    #[cfg(test)]
    search_all: bool,
    /// Tests: check every proved pairing against a search, and the masters at each search.
    #[cfg(test)]
    verify: bool,
    /// Tests: plain re-pairing steps, without the Newton correction.
    #[cfg(test)]
    plain: bool,
    #[cfg(test)]
    cert_xm: Vec<Vec<[f64; 2]>>,
}

impl LinState {
    /// Whether re-pairing steps are Newton-corrected (always, but in tests that compare
    /// against plain steps).
    fn newton(&self) -> bool {
        #[cfg(test)]
        return !self.plain;
        #[cfg(not(test))]
        true
    }

    /// Whether pairings may be proved unchanged instead of searched (always, but in tests that
    /// compare against searching every slave).
    fn proofs(&self) -> bool {
        #[cfg(test)]
        return !self.search_all;
        #[cfg(not(test))]
        true
    }

    /// Whether slave `s`'s budget still proves its natural pairing kind at the path length
    /// `path` of `y` (proof 1 of [`ReducedModel::linearize_with`]).
    fn budget_holds(&self, s: usize, path: Option<f64>) -> bool {
        self.proofs() && path.is_some_and(|t| t <= self.budget[s])
    }

    /// Slave `s`'s natural pairing at `xs` when its budget proves it: unpaired, or projected
    /// on its segment again (the search's arithmetic; `None` if the projection is invalid).
    fn budget_pair(&self, s: usize, xs: [f64; 2], path: Option<f64>) -> Option<Pair> {
        if !self.budget_holds(s, path) {
            return None;
        }
        match self.cert[s].feature {
            Feature::End(_) => Some(Pair::NONE),
            Feature::Segment(k) => MasterIndex::segment_pair(xs, &self.xm, k),
            _ => None,
        }
    }

    /// The path length of `y` up to `u` (the linearisations' path plus the step from the last
    /// one to `u`); `None` before the first linearisation of the query.
    fn travel_to(&self, u: &[f64]) -> Option<f64> {
        (!self.fresh)
            .then(|| self.travel + u.iter().zip(&self.last_u).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt())
    }

    /// A new round of the vertex-zone rule: `forced` slaves tied, pairing history cleared.
    /// The budgets stay: they bound the natural pairing kinds, which do not depend on ties.
    fn restart(&mut self, forced: &[Option<usize>]) {
        self.ties.force(forced);
        self.count = 0;
    }

    /// Every master's position at `y` (contact nodes `ns..ns + nm`, into `xc` and `xm`) and
    /// the search index over them.
    fn all_masters(&mut self, phi_c: &[f64], r: usize, y: &[f64], ns: usize, nm: usize) {
        set_positions(phi_c, r, y, &self.base, &mut self.xc, ns..ns + nm);
        self.index_masters(ns, nm);
        self.masters_all = true;
    }

    /// The positions at `y` of the masters in `range` not yet placed at this linearisation
    /// (`stamp`), into `xc` and `xm`; the index is left as it was.
    fn window(&mut self, phi_c: &[f64], r: usize, y: &[f64], ns: usize, range: std::ops::Range<usize>) {
        for k in range {
            if self.placed[k] != self.stamp {
                self.placed[k] = self.stamp;
                set_positions(phi_c, r, y, &self.base, &mut self.xc, std::iter::once(ns + k));
                self.xm[k] = [self.xc[2 * (ns + k)], self.xc[2 * (ns + k) + 1]];
            }
        }
    }

    /// Copy the masters' positions (contact nodes `ns..ns + nm`) into `xm` and rebuild the
    /// search index over them.
    fn index_masters(&mut self, ns: usize, nm: usize) {
        for k in 0..nm {
            self.xm[k] = [self.xc[2 * (ns + k)], self.xc[2 * (ns + k) + 1]];
        }
        self.index.build(&self.xm);
    }

    /// FNV-1a hash of the discrete pairing of every slave.
    fn pairing_hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for p in &self.pairs {
            let (tag, v) = match p.kind {
                PairKind::None => (0u64, 0u64),
                PairKind::Segment(k) => (1, k as u64),
                PairKind::Vertex(v) => (2, v as u64),
                PairKind::Tied(v) => (3, v as u64),
                PairKind::End(v) => (4, v as u64),
            };
            for x in [tag, v] {
                h ^= x;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        h
    }
}

/// A discrete state of the paper's algorithm: the active-set mask and every slave's pairing.
type PaperState = (Vec<bool>, Vec<PairKind>);

/// FNV-1a of an active-set mask, continued from a pairing hash.
fn state_hash(mask: &[bool], pairing: u64) -> u64 {
    mask.iter().fold(pairing, |h, &m| (h ^ u64::from(m)).wrapping_mul(0x0000_0100_0000_01b3))
}

/// Relative size below which a negative multiplier of the paper's algorithm counts as zero: the
/// full-order snapshots the bases come from are KKT points to 1e-10 relative
/// (`ContactSolveParams::rel_tol`), so smaller multipliers carry no information.
const PAPER_LAM_TOL: f64 = 1e-10;

/// Distance to a round's fixed point (relative to `|y|`) at which the online solve first asks
/// the vertex-zone rule (see [`ReducedModel::solve_in`]'s rounds).
const ZONE_PROBE: f64 = 1e-6;

/// Buffers of online queries; one per thread, reused across queries.
#[derive(Debug, Clone, Default)]
pub struct RomWork {
    lin: LinState,
    qp: QpWork,
    warm: Vec<usize>,
    /// Hashes of the pairings reached by a change (cycle detection).
    seen: Vec<u64>,
    x: Vec<f64>,
    /// The iterate in the K-orthonormal coordinates `y` (see [`ReducedModel`]).
    u_hat: Vec<f64>,
    /// The answer `û = L^{-T} y` in the caller's primal basis.
    coords: Vec<f64>,
    lam: Vec<f64>,
    s: Vec<f64>,
    zero: Vec<f64>,
    phit_f: Vec<f64>,
    fnode: Vec<(usize, f64)>,
    /// Slaves forced to a vertex by the vertex-zone rule in the current query.
    forced: Vec<Option<usize>>,
    /// Pressure per slave (the vertex-zone rule).
    pressures: Vec<f64>,
}

impl RomWork {
    /// Buffers whose queries search every slave at every linearisation (tests).
    #[cfg(test)]
    pub(crate) fn searching_always() -> Self {
        let mut w = Self::default();
        w.lin.search_all = true;
        w
    }

    /// Buffers whose queries check every proved pairing against a search, and panic if they
    /// differ (tests).
    #[cfg(test)]
    pub(crate) fn verifying_proofs() -> Self {
        let mut w = Self::default();
        w.lin.verify = true;
        w
    }

    /// Buffers whose queries take plain re-pairing steps, without the Newton correction
    /// (tests).
    #[cfg(test)]
    pub(crate) fn plain_steps() -> Self {
        let mut w = Self::default();
        w.lin.plain = true;
        w
    }

    /// The solution of the last [`ReducedModel::solve_in`] with these buffers.
    pub fn solution(&self, info: &SolveInfo) -> ReducedSolution {
        let max = self.lam.iter().fold(0.0f64, |m, l| m.max(*l));
        ReducedSolution {
            u_hat: self.coords.clone(),
            lambda_hat: self.lam.clone(),
            iterations: info.iterations,
            linearizations: info.linearizations,
            active: info.active,
            nonzero_dual: self.lam.iter().filter(|l| **l > 1e-9 * max).count(),
            outcome: info.outcome,
        }
    }

    fn prepare(&mut self, m: &ReducedModel, mu: &[f64]) {
        let (ru, rl) = (m.r_u, m.r_l);
        for (v, n) in
            [(&mut self.x, ru), (&mut self.u_hat, ru), (&mut self.zero, ru), (&mut self.lam, rl), (&mut self.s, rl)]
        {
            v.clear();
            v.resize(n, 0.0);
        }
        self.lin.count = 0;
        if let SurfaceData::Fixed { ghat, .. } = &m.surf {
            self.lin.g_mu.resize(rl, 0.0);
            affine_into(ghat, mu, &mut self.lin.g_mu);
        }
        if let SurfaceData::Nts { ns, nm, x_ref, a_terms, .. } = &m.surf {
            let ncd = 2 * x_ref.len();
            let l = &mut self.lin;
            l.base.resize(ncd, 0.0);
            affine_into(a_terms, mu, &mut l.base);
            for (cd, b) in l.base.iter_mut().enumerate() {
                *b += x_ref[cd / 2][cd % 2];
            }
            l.xc.clear();
            l.xc.resize(ncd, f64::NAN);
            l.xm.clear();
            l.xm.resize(*nm, [0.0; 2]);
            l.placed.resize(*nm, 0);
            l.masters_all = false;
            l.pairs.clear();
            l.pairs.resize(*ns, Pair::NONE);
            l.ps_of.clear();
            l.ps_of.resize(*ns, usize::MAX);
            l.budget.clear();
            l.budget.resize(*ns, 0.0);
            l.cert.clear();
            l.cert.resize(*ns, Certificate::default());
            l.cert_x.clear();
            l.cert_x.resize(*ns, [0.0; 2]);
            l.cert_path.clear();
            l.cert_path.resize(*ns, 0.0);
            l.master_path = 0.0;
            l.prev_full = false;
            l.travel = 0.0;
            l.fresh = true;
            l.ties.set_end_ties(true);
            l.ties.reset(*ns);
        }
    }
}
