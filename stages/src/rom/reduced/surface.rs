//! The offline data of the contact surface ([`SurfaceData`]: Type-1 precomputed constraints,
//! Type-2 contact-surface rows) and its reduced quadrature
//! ([`ReducedModel::with_sampled_surface`]).

use super::{ReducedModel, RomError, RomOutcome, RomParams, RomWork, WarmStarts};
use crate::contact::pairing::GapRow;
use crate::rom::la::{combine_rows, dot};

/// The offline data of the contact surface, by problem type.
#[derive(Debug, Clone)]
pub(super) enum SurfaceData {
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
    /// Type-2 in 3-D: node-to-surface rows ([`super::nts3`]).
    Nts3(Box<super::nts3::Nts3>),
}

impl SurfaceData {
    /// A Type-2 surface's summed slaves and quadrature weights (node-to-segment or
    /// node-to-surface alike); `None` for Type-1.
    pub(super) fn quadrature_mut(&mut self) -> Option<(&mut Vec<usize>, &mut Option<Vec<f64>>)> {
        match self {
            SurfaceData::Nts { supp, quad, .. } => Some((supp, quad)),
            SurfaceData::Nts3(d) => Some((&mut d.supp, &mut d.quad)),
            SurfaceData::Fixed { .. } => None,
        }
    }
}

/// Directions of `û` along which [`ReducedModel::with_sampled_surface`] matches the
/// constraints' derivatives (a sketch of `Ĉ`).
pub const SAMPLING_DIRECTIONS: usize = 3;

impl ReducedModel {
    /// The weight of slave `s` in the reduced constraints: its tributary length, or its
    /// quadrature weight on a sampled surface.
    pub(super) fn gap_weight(&self, s: usize) -> f64 {
        match &self.surf {
            SurfaceData::Nts { quad: Some(q), .. } => q[s],
            SurfaceData::Nts3(d) => d.quad.as_ref().map_or(self.weights[s], |q| q[s]),
            _ => self.weights[s],
        }
    }

    /// Slaves of a sampled surface (`None` for a full one or a Type-1 model).
    pub fn sampled_slaves(&self) -> Option<usize> {
        match &self.surf {
            SurfaceData::Nts { quad: Some(_), supp, .. } => Some(supp.len()),
            SurfaceData::Nts3(d) => d.quad.as_ref().map(|_| d.supp.len()),
            _ => None,
        }
    }

    /// A Type-2 model whose reduced constraints sum over a reduced quadrature of the slaves
    /// ([`crate::rom::sampling`], docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints): at each of `samples` (typically the
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
        let supp = match &self.surf {
            SurfaceData::Nts { supp, .. } => supp,
            SurfaceData::Nts3(d) => &d.supp,
            SurfaceData::Fixed { .. } => {
                let all = crate::rom::sampling::Selection { columns: Vec::new(), weights: Vec::new(), residual: 0.0 };
                return Ok((self.clone(), all));
            }
        };
        check_fit(samples, tol)?;
        let rl = self.r_l;
        let cols = supp.clone();
        let values = self.quadrature_rows(samples, p, &cols);
        let (n, rows) = (cols.len(), values.len() / cols.len().max(1));
        // the full sums (tributary weights)
        let b: Vec<f64> = (0..rows).map(|r| (0..n).map(|c| values[r * n + c] * self.weights[cols[c]]).sum()).collect();
        let sel = fit_quadrature(values, b, n, rl, tol)?;
        let mut model = self.clone();
        let mut q = vec![0.0; self.n_contact];
        let mut chosen: Vec<usize> = sel.columns.iter().map(|&c| cols[c]).collect();
        for (&c, &xi) in sel.columns.iter().zip(&sel.weights) {
            q[cols[c]] = xi;
        }
        chosen.sort_unstable();
        if let Some((supp, quad)) = model.surf.quadrature_mut() {
            (*supp, *quad) = (chosen, Some(q));
        }
        model.warm_starts = WarmStarts::default();
        Ok((model, sel))
    }

    /// The rows of the quadrature fit: at the lift state and at the converged state of the
    /// exact solve at each of `samples`, the contributions of every slave of `cols` (one column
    /// each) to the reduced gaps and to their derivatives along [`SAMPLING_DIRECTIONS`] fixed
    /// directions; row-major, `r_l (1 + SAMPLING_DIRECTIONS)` rows per state.
    fn quadrature_rows(&self, samples: &[Vec<f64>], p: &RomParams, cols: &[usize]) -> Vec<f64> {
        let mut col_of = vec![usize::MAX; self.n_contact];
        for (c, &s) in cols.iter().enumerate() {
            col_of[s] = c;
        }
        let dirs = sampling_directions(self.r_u);
        let (mut values, mut sums, mut row) = (Vec::new(), Vec::new(), Vec::new());
        let mut w = RomWork::default();
        for mu in samples {
            self.fit_states(mu, p, &mut w, |w| {
                self.record_state(w, (&col_of, cols.len(), self.r_l), &dirs, (&mut values, &mut sums), &mut row)
            });
        }
        values
    }

    /// The states a quadrature is fitted to at `mu` ([`Self::quadrature_rows`]): `record` at the
    /// lift state (`û = 0`, linearised) and, where the exact solve converges, at its answer
    /// (re-linearised in 3-D, where an answer may be the QP's answer past the last assembled
    /// rows).
    pub(super) fn fit_states(&self, mu: &[f64], p: &RomParams, w: &mut RomWork, mut record: impl FnMut(&RomWork)) {
        w.prepare(self, mu);
        self.linearize(w);
        record(w);
        if self.solve_in(mu, p, w).outcome == RomOutcome::Converged {
            if matches!(self.surf, SurfaceData::Nts3(_)) {
                self.linearize(w);
            }
            record(w);
        }
    }

    /// One state's rows of a quadrature fit, appended to `values` (`rows · ncols`, row-major:
    /// `rl` value rows, then `rl` rows per direction of `dirs`): each paired supported slave
    /// `s` with a column `col_of[s]` adds its contributions `θ_as g_s` and `θ_as (row_s · z)`;
    /// `sums` gets the state's full sums, every paired supported slave weighted by its
    /// tributary measure. `rl` may exceed the model's dual rank (a basis set per query, whose
    /// rank varies): the rows beyond it stay zero.
    pub(super) fn record_state(
        &self,
        w: &RomWork,
        (col_of, ncols, rl): (&[usize], usize, usize),
        dirs: &[Vec<f64>],
        (values, sums): (&mut Vec<f64>, &mut Vec<f64>),
        row: &mut Vec<f64>,
    ) {
        let ru = self.r_u;
        let per_state = rl * (1 + dirs.len());
        let (at, sat) = (values.len(), sums.len());
        values.resize(at + per_state * ncols, 0.0);
        sums.resize(sat + per_state, 0.0);
        row.resize(ru, 0.0);
        let l = &w.lin;
        for (k, &s) in l.ps.iter().enumerate() {
            // the slave's own row: in 2-D from its pair (the assembly may have summed the rows
            // instead), in 3-D the one the assembly keeps
            let r: &[f64] = match &self.surf {
                SurfaceData::Nts { ns, phi_c, .. } => {
                    combine_rows(&GapRow::new(s, *ns, &l.pairs[s]), phi_c, ru, row);
                    &row[..]
                }
                _ => &l.cphi[k * ru..(k + 1) * ru],
            };
            // the gap, then its derivatives along the directions: once per slave
            let mut d = [0.0; 1 + SAMPLING_DIRECTIONS];
            d[0] = dot(r, &w.u_hat) + l.g0[k];
            for (dt, z) in d[1..].iter_mut().zip(dirs) {
                *dt = dot(r, z);
            }
            let c = col_of[s];
            for e in self.by_node.0[s]..self.by_node.0[s + 1] {
                let (a, th) = (self.by_node.1[e], self.by_node.2[e]);
                for (t, dt) in d[..=dirs.len()].iter().enumerate() {
                    let v = th * dt;
                    sums[sat + t * rl + a] += self.weights[s] * v;
                    if c != usize::MAX {
                        values[at + (t * rl + a) * ncols + c] += v;
                    }
                }
            }
        }
    }
}

/// A quadrature fit's inputs ([`ReducedModel::with_sampled_surface`],
/// [`ReducedModel::with_registered_quadrature`]): refused for `tol` outside `[0, 1)` or no
/// samples.
pub(super) fn check_fit(samples: &[Vec<f64>], tol: f64) -> Result<(), RomError> {
    if !(tol.is_finite() && (0.0..1.0).contains(&tol)) {
        return Err(RomError::Sampling(format!(
            "the relative residual tol = {tol} is not in [0, 1): give e.g. 3e-2 (0 fits exactly)"
        )));
    }
    if samples.is_empty() {
        return Err(RomError::Sampling("no sample parameters to fit to: pass the training points".into()));
    }
    Ok(())
}

/// The greedy non-negative fit of a quadrature ([`ReducedModel::with_sampled_surface`]):
/// `values` the rows (row-major, `n` columns; per state `rl` value rows then `rl` rows per
/// direction), `b` their full sums; each block kind (values, derivatives) scaled by its largest
/// full sum. Refused where no state has contact under the dual basis (the fit would keep
/// nothing and the model constrain nothing).
pub(super) fn fit_quadrature(
    mut values: Vec<f64>,
    mut b: Vec<f64>,
    n: usize,
    rl: usize,
    tol: f64,
) -> Result<crate::rom::sampling::Selection, RomError> {
    let per_state = rl * (1 + SAMPLING_DIRECTIONS);
    let rows = b.len();
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
    crate::rom::sampling::greedy_nnls(a, &b, tol, n).map_err(|e| RomError::Sampling(e.to_string()))
}

/// The fixed directions of `û` (`r_u` components) along which a quadrature fit matches the
/// constraints' derivatives ([`SAMPLING_DIRECTIONS`] of them, uniform in [-1, 1], seed 40).
pub(super) fn sampling_directions(r_u: usize) -> Vec<Vec<f64>> {
    let mut rng = crate::rng::Rng::new(40);
    (0..SAMPLING_DIRECTIONS).map(|_| (0..r_u).map(|_| rng.uniform_in(-1.0, 1.0)).collect()).collect()
}

#[cfg(test)]
mod tests {
    use crate::rom::reduced::test_support::{coarse_mus, coarse_tests, full_rom, points};
    use crate::rom::{RomOutcome, RomParams, RomWork};
    use crate::testing::{ironing_coarse, TOL};

    /// The reduced quadrature of the contact constraints (`with_sampled_surface`,
    /// docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints) on ironing-coarse with 17 training points and full bases.
    ///
    /// * Fitted to zero residual it is the full surface: the fit reproduces the exact sums on 34
    ///   training states (values and 3 derivative directions of 17 dual vectors: 2 312 rows for
    ///   71 unknown weights), whose solution is unique when the slaves' columns are independent —
    ///   the tributary lengths. So it keeps every supported slave that any training state
    ///   pairs, and its answers equal the exact model's at 48 test points to 1e-8 relative (both
    ///   stop at the re-linearisation tolerance 1e-10).
    /// * Fitted to 3e-2 it keeps fewer slaves (measured 44 of 71), converges at every test
    ///   point, and its largest H1 error against the full-order solves stays within 2x of the
    ///   exact model's (a regression bound: measured 0.96x here; the medians of `bench_rom`'s
    ///   meshes are 1.3x).
    #[test]
    fn sampled_surface_is_exact_at_zero_tolerance_and_trades_accuracy_above() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (rom, phi, _) = full_rom(fm, &mus);
        let p = RomParams::default();
        let samples = points(&mus);
        let (exact_q, sel) = rom.with_sampled_surface(&samples, &p, 0.0).expect("fit");
        assert!(sel.residual <= 1e-10, "fit residual {:e}", sel.residual);
        let (loose, loose_sel) = rom.with_sampled_surface(&samples, &p, 3e-2).expect("fit");
        let kept = exact_q.sampled_slaves().expect("sampled");
        assert!(loose.sampled_slaves().expect("sampled") < kept, "{} of {kept}", loose_sel.columns.len());
        let tests = coarse_tests();
        let refs: Vec<(Vec<f64>, Vec<f64>)> =
            tests.iter().map(|&d| (vec![d], fm.solve(&[d], &TOL).expect("solve").u)).collect();
        let view: Vec<(&[f64], &[f64])> = refs.iter().map(|(m, u)| (m.as_slice(), u.as_slice())).collect();
        let pe = crate::rom::PrimalErrors::new(fm, &phi, mus.len(), &view).expect("M SPD");
        let (mut w, mut v) = (RomWork::default(), RomWork::default());
        let (mut err_exact, mut err_loose) = (0.0f64, 0.0f64);
        for (j, &d) in tests.iter().enumerate() {
            let a = rom.solve(&[d], &p, &mut w);
            let b = exact_q.solve(&[d], &p, &mut v);
            assert_eq!((a.outcome, b.outcome), (RomOutcome::Converged, RomOutcome::Converged), "d {d}");
            let scale = a.u_hat.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            for (x, y) in a.u_hat.iter().zip(&b.u_hat) {
                assert!((x - y).abs() <= 1e-8 * scale, "d {d}: {x} vs {y}");
            }
            let c = loose.solve(&[d], &p, &mut v);
            assert_eq!(c.outcome, RomOutcome::Converged, "d {d} sampled at 3e-2");
            err_exact = err_exact.max(pe.relative(j, &a.u_hat));
            err_loose = err_loose.max(pe.relative(j, &c.u_hat));
        }
        assert!(err_loose <= 2.0 * err_exact, "largest H1 error {err_loose:e} sampled, {err_exact:e} exact");
        // Inputs that would give a model constraining nothing are refused, not fitted.
        for (pts, tol) in [(&samples[..], f64::NAN), (&samples[..], -1e-2), (&samples[..], 1.0), (&samples[..0], 3e-2)]
        {
            assert!(
                matches!(rom.with_sampled_surface(pts, &p, tol), Err(crate::rom::RomError::Sampling(_))),
                "tol {tol}, {} samples",
                pts.len()
            );
        }
    }
}
