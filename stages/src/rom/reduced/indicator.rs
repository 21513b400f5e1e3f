//! The a-posteriori error indicator of a reduced solution ([`Indicator`]) and the reduced
//! inf-sup diagnostic ([`ReducedModel::inf_sup`]): what a solution's quality costs to check
//! without a full-order solve.

use super::linearise::set_positions;
use super::oracle::Oracle;
use super::{ReducedModel, RomWork, SurfaceData};
use crate::contact::pairing::GapRow;
use crate::mu::affine;
use crate::rom::la::dot;
use crate::rom::qp::QpConstraints;

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

impl ReducedModel {
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
            SurfaceData::Nts { .. } | SurfaceData::Nts3(_) => w.lin.ps.len(),
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
            SurfaceData::Nts3(d) => {
                let (f, p, c, u, ww) = self.indicator3(d, w, &mut phit_f);
                (force, pen, comp_sum, unpaired, fww) = (f, p, c, u, ww);
            }
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
                    let pr = l.peek_pair(s, xs, path, supported);
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
        // a 3-D model without its compliance has no residual (`max` would drop the NaN)
        let residual = if fww.is_nan() { f64::NAN } else { energy_residual(&w.u_hat, &phit_f, fww) };
        w.phit_f = phit_f;
        Indicator {
            penetration: pen.max(0.0),
            complementarity: if force > 0.0 { comp_sum / force } else { 0.0 },
            unpaired_force: if force > 0.0 { unpaired / force } else { 0.0 },
            residual,
        }
    }
}

/// The relative energy-norm equilibrium residual `||Psi y - K^{-1} F||_K / ||Psi y||_K` of the
/// reduced answer `y` under the contact forces `F`, from `Psi^T F` and `F^T W F` (`fww`):
/// `||Psi y - K^{-1} F||_K^2 = |y - Psi^T F|^2 + (F^T W F - |Psi^T F|^2)`, `Psi` K-orthonormal.
fn energy_residual(z: &[f64], y: &[f64], fww: f64) -> f64 {
    let first: f64 = z.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum();
    let second = (fww - dot(y, y)).max(0.0);
    let un = dot(z, z).sqrt();
    let eta = (first + second).sqrt();
    if un > 0.0 {
        eta / un
    } else if eta > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use crate::assert_close;
    use crate::float_cmp::Tol;
    use crate::rom::reduced::test_support::full_rom;
    use crate::rom::{ContactOperator, Linearized, RomOutcome, RomParams, RomWork};
    use crate::testing::ironing_coarse;

    /// The reduced inf-sup constant against a slow reference assembled from the full-order
    /// linearisation at the reduced solution (`FactoredModel::linearize`, not the reduced
    /// model's contact rows) and `K̂ = Phiᵀ K Phi` from `stiffness_mul`:
    /// `beta_ref^2 = lambda_min(Â K̂^{-1} Âᵀ)` over the non-zero rows, on ironing-coarse (no
    /// vertex ties, so the two pairings agree). Tolerance 1e-8 relative: two assembly orders
    /// and a K̂ of condition ~1e4. Then the extremes: a dual vector nearly parallel to another
    /// drives beta below the bound its perturbation gives, and more constraining dual vectors
    /// than primal modes give exactly 0.
    #[test]
    fn inf_sup_matches_a_reference_and_detects_degenerate_bases() {
        let fm = ironing_coarse();
        let mus = [0.6, 0.9, 1.2, 1.5, 1.8];
        let (rom, phi, _) = full_rom(fm, &mus);
        let (ru, rl) = rom.ranks();
        let (n, nc) = (fm.n_dof(), fm.n_contact());
        let d = 1.05;
        let mut w = RomWork::default();
        let sol = rom.solve(&[d], &RomParams::default(), &mut w);
        assert_eq!(sol.outcome, RomOutcome::Converged);
        let beta = rom.inf_sup(&mut w).expect("constraining rows");
        // Reference: u = u0 + Phi û, its full-order gap rows, reduced by the dual basis.
        let mut u = fm.lift(&[d]);
        for (j, c) in sol.u_hat.iter().enumerate() {
            for (ui, p) in u.iter_mut().zip(&phi[j * n..(j + 1) * n]) {
                *ui += c * p;
            }
        }
        let mut lin = Linearized::default();
        fm.linearize(&[d], &u, &mut lin);
        let wts = fm.weights();
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for a in 0..rl {
            let mut unit = vec![0.0; rl];
            unit[a] = 1.0;
            let theta = rom.pressure(&unit);
            let mut row = vec![0.0; ru];
            for i in (0..nc).filter(|&i| lin.paired[i] && theta[i] != 0.0) {
                for k in lin.start[i]..lin.start[i + 1] {
                    for (j, r) in row.iter_mut().enumerate() {
                        *r += theta[i] * wts[i] * lin.coeffs[k] * phi[j * n + lin.dofs[k]];
                    }
                }
            }
            if row.iter().any(|v| *v != 0.0) {
                rows.push(row);
            }
        }
        let mut kphi = vec![0.0; n * ru];
        for j in 0..ru {
            fm.stiffness_mul(&phi[j * n..(j + 1) * n], &mut kphi[j * n..(j + 1) * n]);
        }
        let khat = faer::Mat::from_fn(ru, ru, |i, j| (0..n).map(|q| phi[i * n + q] * kphi[j * n + q]).sum::<f64>());
        let a = faer::Mat::from_fn(rows.len(), ru, |i, j| rows[i][j]);
        let kinv_at = faer::linalg::solvers::Solve::solve(&khat.as_ref().partial_piv_lu(), a.transpose());
        let schur = &a * &kinv_at;
        let sym = faer::Mat::from_fn(schur.nrows(), schur.ncols(), |i, j| 0.5 * (schur[(i, j)] + schur[(j, i)]));
        let eig = sym.as_ref().self_adjoint_eigenvalues(faer::Side::Lower).expect("eigenvalues");
        let reference = eig.iter().copied().fold(f64::INFINITY, f64::min).max(0.0).sqrt();
        assert!(reference > 0.0, "five independent generators constrain independently");
        assert_close!(beta, reference, Tol::rel(1e-8));
        // Nearly parallel dual vectors: the second generator replaced by the first plus 1e-9 of
        // the second (unit-norm generators): beta falls by orders of magnitude.
        let gen = |a: usize| {
            let mut unit = vec![0.0; rl];
            unit[a] = 1.0;
            rom.pressure(&unit)
        };
        let mut theta: Vec<f64> = (0..rl).flat_map(gen).collect();
        let (g0, g1) = (gen(0), gen(1));
        for i in 0..nc {
            theta[nc + i] = g0[i] + 1e-9 * g1[i];
        }
        let mut near = rom.clone();
        near.set_dual(&theta, rl);
        let _ = near.solve(&[d], &RomParams::default(), &mut w);
        let small = near.inf_sup(&mut w).expect("rows");
        // At λ̂ = (e_0 - e_1) / sqrt(2) the sup is 1e-9 |m_1| / sqrt(2), |m_1|^2 = a_1 K̂^{-1} a_1ᵀ
        // (the reference's Schur complement): an upper bound on beta (1e-6 slack: the near
        // basis' own solve may move û by round-off).
        assert_eq!(rows.len(), rl, "every generator constrains at d = {d}");
        let bound = 1e-9 * schur[(1, 1)].sqrt() / 2f64.sqrt();
        assert!(small <= bound * (1.0 + 1e-6), "nearly parallel dual vectors: beta {small} above {bound}");
        assert!(small < 1e-5 * beta, "beta {small} against {beta} for the original basis");
        // Two primal modes for five constraining dual vectors: no inf-sup.
        let thin = rom.leading(2, rl);
        let _ = thin.solve(&[d], &RomParams::default(), &mut w);
        assert_eq!(thin.inf_sup(&mut w), Some(0.0));
    }
}
