//! What the online stages share: the full-order solve times a speed-up divides by, the primal
//! basis of the online solve (the POD of the training contact responses, with or without their
//! translates), the dual error every online table states, the subsample of training points
//! that fits the reduced quadrature, the solver's settings a scene asks for
//! ([`online_params`]), and the online approximations' shared base
//! ([`OnlineBase`]). The rom, online-approximation and model stages use them; the run keeps the
//! costly ones once per process (`shared::LazyPhysics`).

use crom_schemas::SceneConfig;
use crom_stages::basis::{pod_by_gram, pod_full};
use crom_stages::rom::{ContactOperator, PrimalErrors, ReducedModel, ReducedSolution, RomParams};
use faer::MatRef;

use super::timing::time_sample;
use crate::cache::Key;
use crate::io::h5::ColMatrix;
use crate::io::snapshot_set::TrainingSet;
use crate::physics::Physics;

/// Training points the sampled surface is fitted to, at most (evenly spaced, ends included):
/// the fit's rows grow as points x 2 states x r_dual x 4 (values and three derivative
/// directions), 32 x 2 x 60 x 4 = 15 360 rows of 143 slaves at ironing-fine's (128, 60).
pub(crate) const SAMPLING_FIT_POINTS: usize = 32;

/// The stored model of a registered basis with a reduced quadrature of the contact constraints
/// in its reference frame: `base` started at the training points `train` with the basis
/// (`with_primal_starts`), the basis set per query with at most `m` generators
/// (`with_registered_dual`), the quadrature fitted at `fit` to `tol`
/// (`with_registered_quadrature`). The online comparison measures it and the model stage
/// stores it by these same steps, so the stored model answers as measured.
pub(crate) fn sampled_registered(
    base: &crom_stages::rom::ReducedModel,
    reg: crom_stages::dual::registration::Registered,
    m: usize,
    (train, fit): (&[Vec<f64>], &[Vec<f64>]),
    params: &crom_stages::rom::RomParams,
    tol: f64,
) -> Result<crom_stages::rom::ReducedModel, String> {
    let started = base.clone().with_primal_starts(&reg, m, train, params);
    let model = started.with_registered_dual(reg, m).map_err(|e| e.to_string())?;
    model.with_registered_quadrature(fit, params, tol).map(|(model, _)| model).map_err(|e| e.to_string())
}

/// The reduced solver's settings of `scene`'s online stages and stored model: the solver's
/// defaults, with the scene's `study.online_u_tol` where it sets one.
pub(crate) fn online_params(scene: &SceneConfig) -> RomParams {
    let p = RomParams::default();
    RomParams { u_tol: scene.study.online_u_tol.unwrap_or(p.u_tol), ..p }
}

/// At most `n` of `points`, evenly spaced with both ends.
pub(crate) fn subsample(points: &[Vec<f64>], n: usize) -> Vec<Vec<f64>> {
    crom_schemas::scene::spaced_with_ends(n, points.len()).into_iter().map(|k| points[k].clone()).collect()
}

/// High-fidelity solve time at each parameter of the timed sample ([`time_sample`]; NaN at the
/// others, which are not solved: their snapshots are in the store), measured here — same build,
/// same process, by the same rules as the online queries (alone, the fastest of
/// repeated runs, a failed solve by its one run) — rather than read from the snapshot
/// artifacts, which may have been computed by another build (once per run and set:
/// `LazyPhysics::fom_seconds`).
pub(crate) fn fom_seconds(phys: &Physics, parameters: &[Vec<f64>]) -> Vec<f64> {
    time_sample(parameters, |mu| phys.solve(mu), Result::is_ok)
}

/// POD (numerical rank) of the training contact responses `u_k - u0(mu_k)`.
pub(crate) fn response_basis(op: &dyn ContactOperator, train: &TrainingSet) -> Result<ColMatrix, String> {
    let data = responses(op, train);
    let pod = pod_full(MatRef::from_column_major_slice(&data, train.primal.rows, train.primal.cols))
        .map_err(|e| e.to_string())?;
    Ok(super::convert::to_col(pod.modes.as_ref()))
}

/// The training contact responses `u_k - u0(mu_k)`, column-major.
fn responses(op: &dyn ContactOperator, train: &TrainingSet) -> Vec<f64> {
    let mut data = Vec::with_capacity(train.primal.rows * train.primal.cols);
    for (j, mu) in train.parameters.iter().enumerate() {
        let u0 = op.lift(mu);
        data.extend(train.primal.col(j).iter().zip(&u0).map(|(u, l)| u - l));
    }
    data
}

/// The primal basis of an online solve with `primal_translates = shift`
/// (`crom_stages::rom::translates`): the POD of the training responses `u_k - u0(mu_k)` and
/// their translates by `-shift` and `+shift` slave-surface node spacings, truncated at the
/// training set's size (the rank of the plain response basis, so that the two spaces are
/// compared at one size; fewer where the singular values fall to `GRAM_CUT` of the largest),
/// by the method of snapshots (`crom_stages::basis::pod_by_gram`: 0.12–0.14 s instead of the thin
/// SVD's 0.66 s on ironing-fine). Refused where the slave body is not a regular grid along `x`.
pub(crate) fn translated_response_basis(
    phys: &crate::physics::Physics,
    train: &TrainingSet,
    shift: usize,
) -> Result<ColMatrix, String> {
    let crate::physics::Physics::Contact(fm, _) = phys else {
        return Err("primal_translates needs a two-body contact scene".into());
    };
    let op = phys.operator();
    let (n, data) = (train.primal.rows, responses(op, train));
    let model = fm.model();
    let all = crom_stages::rom::translates::with_translates(model.mesh(), model.slave_nodes(), &data, shift)
        .map_err(|e| format!("primal_translates: {e}; remove primal_translates from this [comparison] entry"))?;
    let count = all.len() / n.max(1);
    // the method of snapshots: every kept mode's singular value is well above its cut here
    // (the 128th of ironing-fine's 384 is 6.5e-5 of the first, the cut 1e-6)
    let (modes, _) =
        pod_by_gram(MatRef::from_column_major_slice(&all, n, count), train.primal.cols).map_err(|e| e.to_string())?;
    Ok(super::convert::to_col(modes.as_ref()))
}

/// Relative dual error (tributary-weighted L2) against column `j` of the set.
pub(crate) fn dual_error(
    op: &dyn ContactOperator,
    model: &ReducedModel,
    sol: &ReducedSolution,
    set: &TrainingSet,
    j: usize,
) -> f64 {
    relative_dual_error(op.weights(), &model.pressure(&sol.lambda_hat), set.dual.col(j))
}

/// Relative tributary-weighted L2 distance of the pressure `p` to `lam` (weights `w`; `NaN`
/// where `lam` is zero): the dual error of every online table and of `crom query --check`.
pub(crate) fn relative_dual_error(w: &[f64], p: &[f64], lam: &[f64]) -> f64 {
    let ln: f64 = lam.iter().zip(w).map(|(l, w)| w * l * l).sum();
    let dn: f64 = p.iter().zip(lam).zip(w).map(|((a, b), w)| w * (a - b) * (a - b)).sum();
    if ln > 0.0 {
        (dn / ln).sqrt()
    } else {
        f64::NAN
    }
}

/// What every approximation's online stage shares in one process: the primal basis and the
/// reduced model on it, the test points' primal references and the full-order solve's median
/// time at the test points.
pub(crate) struct OnlineBase {
    /// (train, test) keys it was built for.
    pub(crate) of: (Key, Key),
    pub(crate) r_primal: usize,
    pub(crate) model: ReducedModel,
    pub(crate) errors: PrimalErrors,
    pub(crate) fom_median: f64,
}

impl std::fmt::Debug for OnlineBase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnlineBase").field("of", &self.of).field("r_primal", &self.r_primal).finish_non_exhaustive()
    }
}
