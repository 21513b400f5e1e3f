//! Helpers shared by the reduced-model tests: full bases from training snapshots, the
//! ironing-coarse training and test points, and comparisons of two solves.

use faer::MatRef;

use crate::basis::{cpg, pod_full, CpgParams};
use crate::contact::FactoredModel;
use crate::rom::{Algorithm, ContactOperator, Indicator, ReducedModel, RomOutcome, RomParams, RomWork};
use crate::snapshot::Snapshot;
use crate::testing::TOL;

/// The 17 ironing-coarse training points of the reduced-model tests, `d_x = 3 k / 16`.
pub(crate) fn coarse_mus() -> Vec<f64> {
    (0..17).map(|k| 3.0 * k as f64 / 16.0).collect()
}

/// Scalar parameters as parameter points.
pub(crate) fn points(mus: &[f64]) -> Vec<Vec<f64>> {
    mus.iter().map(|&m| vec![m]).collect()
}

/// The 48 ironing-coarse test parameters: the midpoints of 48 equal cells of `d_x` in
/// [0, 3], between the training points.
pub(crate) fn coarse_tests() -> Vec<f64> {
    (0..48).map(|k| 3.0 * (k as f64 + 0.5) / 48.0).collect()
}

/// Two ways of solving (`a` with buffers `wa`, `b` with `wb`) at every coarse test point:
/// both must converge at each; returns the largest distance of their answers relative to
/// `a`'s, and the linearisations each took in all.
pub(crate) fn compare_solves(
    (a, wa): (&ReducedModel, &mut RomWork),
    (b, wb): (&ReducedModel, &mut RomWork),
    p: &RomParams,
) -> (f64, usize, usize) {
    let (mut worst, mut lin_a, mut lin_b) = (0.0f64, 0, 0);
    for d in coarse_tests() {
        let (x, y) = (a.solve(&[d], p, wa), b.solve(&[d], p, wb));
        assert_eq!((x.outcome, y.outcome), (RomOutcome::Converged, RomOutcome::Converged), "d_x {d}");
        let diff = x.u_hat.iter().zip(&y.u_hat).map(|(s, t)| (s - t) * (s - t)).sum::<f64>().sqrt();
        worst = worst.max(diff / x.u_hat.iter().map(|s| s * s).sum::<f64>().sqrt());
        lin_a += x.linearizations;
        lin_b += y.linearizations;
    }
    (worst, lin_a, lin_b)
}

/// A matrix as its columns, concatenated (column-major).
pub(crate) fn columns(m: MatRef<'_, f64>) -> Vec<f64> {
    (0..m.ncols()).flat_map(|j| m.col(j).iter().copied().collect::<Vec<_>>()).collect()
}

/// Full bases from the training snapshots at `mus`: primal POD of the responses
/// `u_k - u0(mu_k)` at numerical rank, CPG of the pressures at tolerance 0; returns the
/// reduced model, the primal basis (for reconstruction) and the snapshots.
pub(crate) fn full_rom(fm: &FactoredModel, mus: &[f64]) -> (ReducedModel, Vec<f64>, Vec<Snapshot>) {
    full_rom_with(fm, mus, None)
}

/// [`full_rom`], optionally with a given dual basis (column-major, `mus.len()` columns).
pub(crate) fn full_rom_with(
    fm: &FactoredModel,
    mus: &[f64],
    theta: Option<&[f64]>,
) -> (ReducedModel, Vec<f64>, Vec<Snapshot>) {
    let snaps: Vec<Snapshot> = mus.iter().map(|&d| fm.solve(&[d], &TOL).expect("solve")).collect();
    let (n, nc) = (fm.n_dof(), fm.n_contact());
    let responses: Vec<f64> = mus
        .iter()
        .zip(&snaps)
        .flat_map(|(&d, s)| s.u.iter().zip(fm.lift(&[d])).map(|(a, b)| a - b).collect::<Vec<_>>())
        .collect();
    let duals: Vec<f64> = snaps.iter().flat_map(|s| s.pressure.iter().copied()).collect();
    let phi = pod_full(MatRef::from_column_major_slice(&responses, n, mus.len())).expect("pod");
    let theta = match theta {
        Some(t) => t.to_vec(),
        None => columns(
            cpg(MatRef::from_column_major_slice(&duals, nc, mus.len()), CpgParams::default())
                .expect("cpg")
                .basis
                .as_ref(),
        ),
    };
    let (ru, rl) = (phi.modes.ncols(), theta.len() / nc);
    assert_eq!((ru, rl), (mus.len(), mus.len()), "independent training snapshots");
    let phi_c = columns(phi.modes.as_ref());
    let rom = ReducedModel::new(fm, &phi_c, ru, &theta, rl).expect("K̂ SPD");
    (rom, phi_c, snaps)
}

/// Relative H1 error of `u` and relative Euclidean error of `p` against a snapshot.
pub(crate) fn errors(fm: &FactoredModel, u: &[f64], p: &[f64], s: &Snapshot) -> (f64, f64) {
    let diff: Vec<f64> = u.iter().zip(&s.u).map(|(a, b)| a - b).collect();
    let eu = (fm.primal_norm_sq(&diff) / fm.primal_norm_sq(&s.u)).sqrt();
    let dn = s.pressure.iter().map(|x| x * x).sum::<f64>().sqrt();
    let ep = p.iter().zip(&s.pressure).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / dn;
    (eu, ep)
}

/// Solve every training point with full bases and both algorithms; return the largest
/// primal and dual errors and indicator values per algorithm.
pub(crate) fn reproduce(fm: &FactoredModel, mus: &[f64], algorithm: Algorithm) -> Vec<(f64, f64, f64, Indicator)> {
    let (rom, phi, snaps) = full_rom(fm, mus);
    let mut w = RomWork::default();
    let p = RomParams { algorithm, ..RomParams::default() };
    mus.iter()
        .zip(&snaps)
        .map(|(&mu, s)| {
            let r = rom.solve(&[mu], &p, &mut w);
            assert_eq!(r.outcome, RomOutcome::Converged, "{algorithm:?} mu {mu}");
            let u = ReducedModel::displacement(fm, &phi, &[mu], &r.u_hat);
            let (eu, ep) = errors(fm, &u, &rom.pressure(&r.lambda_hat), s);
            (mu, eu, ep, rom.indicator(&[mu], &mut w))
        })
        .collect()
}

/// `model` written as parts and read back: the parts are identical, and at every point of
/// `at`, with both algorithms, the loaded model's answer (coordinates, outcome, steps) and its
/// indicator have the same bits as the original's — `==` on floats on purpose: the loaded
/// model must be the same data, not a close one.
pub(crate) fn assert_round_trip(model: &ReducedModel, at: &[Vec<f64>]) {
    let parts = model.parts();
    let loaded = ReducedModel::from_parts(&parts).expect("parts make a model");
    assert_eq!(loaded.parts(), parts, "parts differ after a round trip");
    let (mut wa, mut wb) = (RomWork::default(), RomWork::default());
    for algorithm in [Algorithm::Exact, Algorithm::Paper] {
        let p = RomParams { algorithm, ..RomParams::default() };
        for mu in at {
            let (a, b) = (model.solve(mu, &p, &mut wa), loaded.solve(mu, &p, &mut wb));
            assert_eq!(a, b, "{algorithm:?} at {mu:?}");
            let (ia, ib) = (model.indicator(mu, &mut wa), loaded.indicator(mu, &mut wb));
            assert!(ia.residual.to_bits() == ib.residual.to_bits(), "indicator at {mu:?}: {ia:?} vs {ib:?}");
            assert!(ia.penetration.to_bits() == ib.penetration.to_bits(), "indicator at {mu:?}");
        }
    }
}
