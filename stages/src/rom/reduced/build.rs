//! The offline build: everything of length `n_dof` ([`ReducedModel::new`]), the model on leading
//! ranks, and what the online solve stores.

use super::nts3::Nts3;
use super::{ReducedModel, RomError, SurfaceData, WarmStarts};
use crate::contact3d::surface::MasterSurface;
use crate::full_order::{Compliance, ContactOperator, Linearized, Surface};
use crate::rom::la::{backward_t, dot, forward};
use crate::rom::saddle::cholesky;
use faer::MatRef;

/// A compressed sparse layout: starts, indices, values.
pub(super) type Compressed = (Vec<usize>, Vec<usize>, Vec<f64>);

/// `Theta[:, :rl]` by node (CSR) and by column (CSC).
pub(super) fn csr(theta: &[f64], nc: usize, rl: usize) -> (Compressed, Compressed) {
    let (mut by_node, mut by_col) = Default::default();
    csr_into(theta, nc, rl, &mut by_node, &mut by_col);
    (by_node, by_col)
}

/// [`csr`] into existing layouts (their buffers reused: a dual basis set per query).
pub(super) fn csr_into(theta: &[f64], nc: usize, rl: usize, by_node: &mut Compressed, by_col: &mut Compressed) {
    let at = |i: usize, a: usize| theta[i + a * nc];
    compress(nc, rl, at, by_node);
    compress(rl, nc, |a, i| at(i, a), by_col);
}

/// The non-zeros of `value(o, k)` row by row over `o < outer`, `k < inner`, into `c`.
fn compress(outer: usize, inner: usize, value: impl Fn(usize, usize) -> f64, c: &mut Compressed) {
    c.0.clear();
    c.1.clear();
    c.2.clear();
    c.0.push(0);
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
}

/// Per contact node the Frobenius norm of its two rows of `Phi_c` (row-major `n_cd x r`), and
/// the largest over the masters (nodes `ns..`).
pub(super) fn node_norms(phi_c: &[f64], r: usize, ns: usize) -> (Vec<f64>, f64) {
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
/// `K̂ = Phi^T K Phi` (column-major `r_u x r_u`, `phi` column-major `n_dof x r_u`), with the
/// rounding of the two-sided product symmetrised. The products `K phi_j` are taken in parallel
/// over the columns, each the one `stiffness_mul` computes alone.
fn reduced_stiffness(op: &dyn ContactOperator, phi: &[f64], n_dof: usize, r_u: usize) -> Vec<f64> {
    use rayon::prelude::*;
    let mut kphi = vec![0.0; n_dof * r_u];
    if n_dof > 0 {
        kphi.par_chunks_mut(n_dof).zip(phi.par_chunks(n_dof)).for_each(|(y, x)| op.stiffness_mul(x, y));
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
    khat
}

/// Type-1: `C Phi` (row-major `nc x r_u`) from the constant rows of `C`.
fn constraint_rows(rows: &Linearized, phi: &[f64], n_dof: usize, r_u: usize, nc: usize) -> Vec<f64> {
    let mut cphi = vec![0.0; nc * r_u];
    for i in 0..nc {
        for k in rows.start[i]..rows.start[i + 1] {
            let (d, c) = (rows.dofs[k], rows.coeffs[k]);
            for j in 0..r_u {
                cphi[i * r_u + j] += c * phi[d + j * n_dof];
            }
        }
    }
    cphi
}

/// Type-1: add `Theta^T W` times the rows `cphi` (row-major, `r_u` columns) and the affine
/// terms `cu0` of the offsets into `chat` (row-major `r_l x r_u`) and `ghat` (zeroed by the
/// caller); `by_node` is `Theta` by node, `weights` the tributary lengths.
pub(super) fn reduce_fixed(
    by_node: &Compressed,
    weights: &[f64],
    r_u: usize,
    cphi: &[f64],
    cu0: &[Vec<f64>],
    chat: &mut [f64],
    ghat: &mut [Vec<f64>],
) {
    for i in 0..by_node.0.len() - 1 {
        for e in by_node.0[i]..by_node.0[i + 1] {
            let (a, tw) = (by_node.1[e], by_node.2[e] * weights[i]);
            for j in 0..r_u {
                chat[a * r_u + j] += tw * cphi[i * r_u + j];
            }
            for (g, c) in ghat.iter_mut().zip(cu0) {
                g[a] += tw * c[i];
            }
        }
    }
}

/// Type-1: `C W C^T` (row-major `nc x nc`) from the constant rows of `C` and the compliance on
/// the contact dofs, for the indicator.
fn compliance_gram(rows: &Linearized, comp: &Compliance, nc: usize) -> Vec<f64> {
    let pos: std::collections::HashMap<usize, usize> = comp.dofs.iter().enumerate().map(|(k, &d)| (d, k)).collect();
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
    cwc
}

impl ReducedModel {
    /// Offline: `phi` (`n_dof x r_u`, column-major, zero on Dirichlet dofs) and `theta`
    /// (`n_contact x r_l`, column-major, non-negative).
    pub fn new(op: &dyn ContactOperator, phi: &[f64], r_u: usize, theta: &[f64], r_l: usize) -> Result<Self, RomError> {
        let (n_dof, nc) = (op.n_dof(), op.n_contact());
        assert_eq!(phi.len(), n_dof * r_u, "phi shape");
        assert_eq!(theta.len(), nc * r_l, "theta shape");
        let mut khat_l = reduced_stiffness(op, phi, n_dof, r_u);
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
                let mut cphi = constraint_rows(&rows, phi, n_dof, r_u, nc);
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
                reduce_fixed(&by_node, &weights, r_u, &cphi, &cu0, &mut chat, &mut ghat);
                let cwc = compliance_gram(&rows, &comp, nc);
                SurfaceData::Fixed { cphi, cu0, paired: rows.paired, chat, ghat, cwc }
            }
            Surface::NodeToSurface { n_slaves, x_ref, dofs, slave_fixed, facets, planes, plane_tol } => {
                assert_eq!(comp.dofs, dofs, "compliance on the contact dofs");
                let mut phi_c: Vec<f64> =
                    dofs.iter().flat_map(|&d| (0..r_u).map(move |j| phi[d + j * n_dof])).collect();
                to_psi(&mut phi_c);
                let a_terms = lift.iter().map(|t| dofs.iter().map(|&d| t[d]).collect()).collect();
                let master = MasterSurface::new(facets, &x_ref[n_slaves..], &planes, plane_tol);
                let w_c = (comp.w.len() <= super::nts3::MAX_W_C).then_some(comp.w);
                let mut d = Nts3 {
                    ns: n_slaves,
                    nm: x_ref.len() - n_slaves,
                    x_ref,
                    slave_fixed,
                    master,
                    phi_c,
                    a_terms,
                    supp: Vec::new(),
                    quad: None,
                    w_c,
                };
                d.supp = d.support(&by_node.0);
                SurfaceData::Nts3(Box::new(d))
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
            per_query: None,
        })
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
            SurfaceData::Nts3(d) => SurfaceData::Nts3(Box::new(d.leading(self.r_u, r_u, &by_node.0))),
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
            per_query: self.per_query.clone(),
        }
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
            SurfaceData::Nts3(d) => v.extend([
                ("x_ref", 3 * d.x_ref.len()),
                ("facets", 4 * d.master.facets().len()),
                ("phi_c", d.phi_c.len()),
                ("a_terms", d.a_terms.iter().map(Vec::len).sum()),
                ("supp", d.supp.len()),
                ("w_c", d.w_c.as_ref().map_or(0, Vec::len)),
            ]),
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
        if let Some(a) = self.registered_dual().and_then(|(basis, _)| basis.arrays()) {
            v.extend([("reg_surface", a.surface.len()), ("reg_table", a.table.len()), ("reg_modes", a.modes.len())]);
        }
        v
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
}

#[cfg(test)]
mod tests {
    use crate::contact::{build_ironing, IroningParams};
    use crate::rom::reduced::test_support::full_rom_with;
    use crate::rom::ContactOperator;
    use crate::snapshot::Snapshot;
    use crate::testing::{ironing_coarse, ironing_coarse_params, TOL};

    /// The online solve reads no `n_dof`-length data: the arrays of a reduced model built on
    /// ironing-coarse and on the same scene with a slab twice as deep (twice the nodes below the
    /// surface, the same contact surface, the same dual basis) have identical lengths, although
    /// `n_dof` differs.
    #[test]
    fn reduced_model_size_does_not_depend_on_n_dof() {
        let p = IroningParams { slab_height: 2.0, slab_ny: 40, ..ironing_coarse_params() };
        let deep = build_ironing(&p).expect("ironing").factor().expect("factor");
        let coarse = ironing_coarse();
        assert!(deep.n_dof() > coarse.n_dof() + 4000);
        let mus = [0.5, 1.5, 2.5];
        let snaps: Vec<Snapshot> = mus.iter().map(|&d| coarse.solve(&[d], &TOL).expect("solve")).collect();
        let theta: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
        let (a, _, _) = full_rom_with(coarse, &mus, Some(&theta));
        let (b, _, _) = full_rom_with(&deep, &mus, Some(&theta));
        assert_eq!(a.storage(), b.storage());
    }
}
