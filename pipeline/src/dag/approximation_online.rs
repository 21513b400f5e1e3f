//! Online approximation stage: the reduced solve of the online stage
//! ([`crom_stages::rom`], exact algorithm) with the dual basis of one approximation of the
//! scene's `[comparison]` that has a non-negative one (CPG, Angle-Greedy, NNMF, local bases,
//! the dictionary, registered CPG), at the full primal rank, for a few dual sizes m, at every
//! test point. One artifact per approximation; [`super::comparison::gather`] puts them side by
//! side.
//!
//! A basis that does not depend on the parameter is read from the approximation's artifact
//! (`bases.h5`), not built again; a local or registered one is built from the training set
//! (cheap: the dearest, NNMF, is parameter-independent). The dictionary is solved by a working
//! set of atoms (`crom_stages::rom::working_set::WorkingSet`: the nearest atoms first, then
//! the violated ones), the whole loop timed.
//!
//! The reduced model is built once per run (`K̂`, the contact-dof rows of the primal basis;
//! [`OnlineBase`], shared by every approximation's stage in the process) and only its dual part
//! is replaced per approximation ([`ReducedModel::set_dual`], `O(n_contact m)`). A registered
//! approximation with `primal_translates` has a primal space of its own (the training responses
//! and their translates, [`super::online::translated_response_basis`]) and the exact corrected
//! re-pairing step; its stage builds that model and its primal references. A fixed basis
//! is set before the timer starts; a basis that depends on the parameter (a registered one is
//! pushed forward to the query's frame, a local one is its cell's) is evaluated and set inside
//! the timed query, so its online time includes that work — which reads only contact-surface
//! data. The full-order solve is timed in the same process at the same points, as in the
//! online stage (once per process, in [`OnlineBase`]); every timed solve runs alone, one at a
//! time.

use std::time::Instant;

use crom_schemas::artifact::{comparison as names, ArtifactKind};
use crom_schemas::comparison::ApproximationSpec;
use crom_schemas::scene::{SAMPLED_SUFFIX, WHOLE_NODE_PREFIX};
use crom_schemas::SceneConfig;
use crom_stages::dual::{self, Approach, DualApprox};
use crom_stages::metrics::order::quantile;
use crom_stages::rom::working_set::{WorkingSet, WorkingSetScratch, WS_START};
use crom_stages::rom::{
    cone_basis_columns, Algorithm, PrimalErrors, ReducedModel, RomOutcome, RomParams, RomWork, SolveInfo,
    EXACT_STEP_ITERATIONS,
};
use serde::Serialize;
use serde_json::json;

use super::approximation::ONLINE_MS;
use super::comparison::{self, contact_surface, item};
use super::convert::view;
use super::ctx::Ctx;
use super::graph::{Input, StageDef};
use super::online::{dual_error, online_params, sampled_registered, subsample, OnlineBase, SAMPLING_FIT_POINTS};
use super::shared::LazyPhysics;
use super::shared::Shared;
use super::timing::time_each;
use crate::cache::{Key, KeySpec, NnlsKey, StageKey};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In};
use crate::io::table::{Column, Table};

/// What determines one approximation's online artifact besides its inputs.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct OnlineApproximationKey {
    approximation: ApproximationSpec,
    max_m: usize,
    nnls: NnlsKey,
    max_iter: usize,
    gap_tol: f64,
    u_tol: f64,
    /// The dictionary's first working set.
    ws_start: usize,
    /// A 3-D scene: its queries with a dual basis set per query start from the warm-start
    /// samples' answers too (since 2026-11-29; only the path changes). Absent from a 2-D
    /// scene's key, whose solves did already.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    starts_3d: bool,
    /// `study.contact_sampling`'s fit tolerance, for a registered basis on whole-node shifts:
    /// its rows are also measured with a quadrature fitted in the reference frame (named with
    /// [`SAMPLED_SUFFIX`]). Absent otherwise, so the other keys are unchanged.
    #[serde(skip_serializing_if = "Option::is_none")]
    sampling: Option<f64>,
    /// The primal rank of those rows: `study.model_ranks`' first where the scene names one (the
    /// stored model's, so that the study measures the model it stores), else the full one.
    #[serde(skip_serializing_if = "Option::is_none")]
    sampled_r_primal: Option<usize>,
}

impl StageKey for OnlineApproximationKey {
    const KIND: ArtifactKind = ArtifactKind::ONLINE_APPROXIMATION;
    /// Bump when a number of the online solve changes (3: Newton-corrected re-pairing steps,
    /// docs/design-notes.md#newton-corrected-re-pairing-steps; 4: a row at m = 10; 5: NNMF's
    /// basis at m = 1 to the last bits, its products with S over S's non-zeros; 6: NNMF's W
    /// scaled once after the sweeps, its Gram products by fused multiply-adds, to rounding; 7: a
    /// dual basis of at most three columns summed into reduced rows, the same answers to 1e-10;
    /// 8: solves up to 0.1 s timed as the fastest of three, the results the same; 9: every
    /// query timed alone, one at a time, the results the same; 10: the timing runs in rounds
    /// over the points, the results the same; 11: the exact step's curvature applied through
    /// each term's two rows, the same answers to 1e-10; 12: the first linearisation's positions
    /// from the warm-start samples' displacements, the same answers to 1e-10; 13: half steps
    /// once the plain re-pairing cycles, the same answers where it did not, but for starts lent
    /// by samples that cycled before: ironing-fine's NNMF rows move; 14: a 3-D query answers
    /// with its verified linearisation point, 2-D the same; 15: in 3-D a feature renamed
    /// across a shared node is not a change of the pairing, 2-D the same).
    const ALGORITHM_VERSION: u32 = 15;
}

impl OnlineApproximationKey {
    /// The settings of approximation `index`'s online stage (None without `[comparison]`, past
    /// its end, or for an approximation without a non-negative basis).
    fn of(scene: &SceneConfig, index: usize) -> Option<Self> {
        let (cmp, item) = item(scene, index)?;
        if !item.approach.has_cone_basis() {
            return None;
        }
        let p = online_params(scene);
        let whole_nodes = item.spec.name().starts_with(WHOLE_NODE_PREFIX);
        Some(Self {
            approximation: item.spec,
            max_m: cmp.max_m,
            nnls: NnlsKey::used(),
            max_iter: p.max_iter,
            gap_tol: p.gap_tol,
            u_tol: p.u_tol,
            ws_start: WS_START,
            starts_3d: scene.model.is_3d(),
            sampling: scene.study.contact_sampling.as_ref().filter(|_| whole_nodes).map(|cs| cs.tol),
            sampled_r_primal: scene
                .study
                .model_ranks
                .filter(|_| whole_nodes && scene.study.contact_sampling.is_some())
                .map(|[ru, _]| ru),
        })
    }

    /// The exact online solve's settings.
    fn rom_params(&self) -> RomParams {
        RomParams {
            algorithm: Algorithm::Exact,
            max_iter: self.max_iter,
            gap_tol: self.gap_tol,
            u_tol: self.u_tol,
            exact_step: if self.approximation.primal_translates().is_some() { EXACT_STEP_ITERATIONS } else { 0 },
        }
    }
}

/// The key spec of the online stage `key`; `approximation` is the key of its offline artifact.
fn spec(key: &OnlineApproximationKey, train: &Key, test: &Key, mesh: &Key, approximation: &Key) -> KeySpec {
    KeySpec::of(key).input("train", train).input("test", test).input("mesh", mesh).input("approximation", approximation)
}

/// One query's outcome.
struct Query {
    outcome: RomOutcome,
    seconds: f64,
    primal: f64,
    dual: f64,
    nonzero: usize,
}

/// The online solve with dual approximation `index` (one with a non-negative basis), computed
/// from its key ([`OnlineApproximationKey`]).
#[derive(Debug)]
pub(crate) struct OnlineApproximationStage {
    pub spec: KeySpec,
    pub settings: OnlineApproximationKey,
    /// The scene's name, in the tables.
    pub scene: String,
    pub train: Input,
    pub test: Input,
    pub mesh: Input,
    /// Its offline artifact.
    pub approximation: Input,
}

impl OnlineApproximationStage {
    /// None where the scene has no approximation `index` or it has no non-negative basis.
    pub(crate) fn plan(
        scene: &SceneConfig,
        index: usize,
        train: Input,
        test: Input,
        mesh: Input,
        approximation: Input,
    ) -> Option<Self> {
        let settings = OnlineApproximationKey::of(scene, index)?;
        let spec = spec(&settings, &train.key, &test.key, &mesh.key, &approximation.key);
        Some(Self { spec, settings, scene: scene.scene.name.clone(), train, test, mesh, approximation })
    }
}

impl StageDef for OnlineApproximationStage {
    fn times_solves(&self) -> bool {
        true
    }
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::ONLINE_APPROXIMATION
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train, &self.test, &self.mesh, &self.approximation]
    }
    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let keys = [&self.train.key, &self.test.key, &self.mesh.key, &self.approximation.key];
        let labelled = (&self.settings, self.scene.as_str());
        run(ctx, &mut shared.physics, &mut shared.online_base, &self.spec, labelled, keys)
    }
}

/// Run the online solve with the approximation `settings`; returns the artifact's key. `shared` is
/// the process's [`OnlineBase`] (built here on first use); `keys` are the training set's, the
/// test set's, the mesh's and the offline approximation's.
fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    shared: &mut Option<OnlineBase>,
    spec: &KeySpec,
    (settings, scene): (&OnlineApproximationKey, &str),
    [train, test, mesh, approximation]: [&Key; 4],
) -> Result<Key, CromError> {
    let item = comparison::item_of(&settings.approximation);
    let key = spec.key();
    let label = format!("online {}", item.name);
    if ctx.lookup(ArtifactKind::ONLINE_APPROXIMATION, &key)?.is_some() {
        ctx.progress.stage(&label, 1).finish("cached");
        ctx.record("online-approximation", 0, 1, ctx.store.dir(ArtifactKind::ONLINE_APPROXIMATION, &key));
        return Ok(key);
    }
    let name = item.name.clone();
    let fail = |m: String| CromError::Numerical {
        stage: "online-approximation",
        scene: scene.to_string(),
        message: format!("{name}: {m}"),
    };
    let (train_set, test_set) = (ctx.loaded.set(ctx.store, train)?, ctx.loaded.set(ctx.store, test)?);
    let start = Instant::now();
    let of = (train.clone(), test.clone());
    let rebuild = shared.as_ref().is_none_or(|b| b.of != of);
    // measured by the trade-off's stage when it ran earlier in this process
    let fom = if rebuild { physics.fom_seconds(test, &test_set.parameters)? } else { Vec::new() };
    let phi = if rebuild { Some(physics.responses(train, &train_set, fail)?) } else { None };
    // an approximation with its own primal space (`primal_translates`)
    let translated = match settings.approximation.primal_translates() {
        Some(shift) => Some(physics.translated_responses(train, &train_set, shift, fail)?),
        None => None,
    };
    let phys = physics.get()?;
    let op = phys.operator();
    // the reduced model on a primal basis, without a dual basis, and the test points' primal
    // references in its coordinates
    let primal_part = |phi: &ColMatrix| -> Result<(ReducedModel, PrimalErrors), CromError> {
        let model = ReducedModel::new(op, &phi.data, phi.cols, &[], 0).map_err(|e| fail(e.to_string()))?;
        let refs: Vec<(&[f64], &[f64])> =
            test_set.parameters.iter().enumerate().map(|(j, mu)| (mu.as_slice(), test_set.primal.col(j))).collect();
        let errors = PrimalErrors::new(op, &phi.data, phi.cols, &refs)
            .ok_or_else(|| fail("Phi^T H Phi is not positive definite".into()))?;
        Ok((model, errors))
    };
    if let Some(phi) = phi {
        let (model, errors) = primal_part(&phi)?;
        let fom_median = quantile(&fom, 0.5);
        *shared = Some(OnlineBase { of, r_primal: phi.cols, model, errors, fom_median });
    }
    let Some(b) = shared.as_ref() else { return Err(fail("the shared reduced model was not built".into())) };
    let own = match &translated {
        Some(phi) => {
            let (model, errors) = primal_part(phi)?;
            Some((model, errors, phi.cols))
        }
        None => None,
    };
    let (base_model, primal_errors, r_primal) =
        own.as_ref().map_or((&b.model, &b.errors, b.r_primal), |(m, e, r)| (m, e, *r));
    let params = settings.rom_params();
    let mut progress = ctx.progress.stage(&label, 1);
    let errors = |j: usize, rm: &ReducedModel, sol: &crom_stages::rom::ReducedSolution| {
        (primal_errors.relative(j, &sol.u_hat), dual_error(op, rm, sol, &test_set, j))
    };
    let mut rows = Rows::default();
    let bases_path = ctx.store.dir(ArtifactKind::APPROXIMATION, approximation).join(names::BASES);
    if matches!(item.approach, Approach::Dictionary) {
        // Every training snapshot an atom, solved by a working set (column generation).
        let ws = WorkingSet::new(view(&train_set.dual), &train_set.parameters, op.weights(), settings.ws_start);
        let queries = solve_dictionary(&ws, &b.model, &test_set.parameters, &params, errors);
        rows.push(&name, ws.len(), b.r_primal, &queries, b.fom_median);
    } else if bases_path.exists() {
        // A parameter-independent basis, as the approximation stage stored it.
        let h5 = H5In::open(&bases_path)?;
        for m in ONLINE_MS {
            if !h5.contains(&format!("m{m}")) {
                continue;
            }
            let basis = h5.matrix(&format!("m{m}"))?;
            let source = Source::Fixed(basis.data.as_slice().into(), basis.cols);
            let queries = solve_all(&source, &b.model, &test_set.parameters, &params, errors);
            rows.push(&name, m, b.r_primal, &queries, b.fom_median);
        }
    } else {
        let (surface, across) = contact_surface(ctx.store, mesh)?;
        let ms = dual::m_grid(settings.max_m.min(train_set.parameters.len()));
        let training = super::convert::training((&train_set.dual, &train_set.parameters), &surface, &across, &ms);
        let model = dual::build(&item.approach, &training).map_err(|e| fail(e.to_string()))?;
        for m in ONLINE_MS.into_iter().filter(|&m| m <= model.size()) {
            // a basis that depends on the parameter: the queries start their re-pairing from the
            // answers at the training points with the basis there (`with_primal_starts`), as a
            // stored model with that basis does
            let (source, base) = if model.depends_on_mu() {
                let base = base_model.clone().with_primal_starts(model.as_ref(), m, &train_set.parameters, &params);
                (Source::PerQuery(model.as_ref(), m), std::borrow::Cow::Owned(base))
            } else {
                let (theta, k) = cone_basis_columns(model.as_ref(), &test_set.parameters[0], m);
                (Source::Fixed(theta.into(), k), std::borrow::Cow::Borrowed(base_model))
            };
            let queries = solve_all(&source, &base, &test_set.parameters, &params, errors);
            rows.push(&name, m, r_primal, &queries, b.fom_median);
        }
        if let (Some(tol), Approach::Registered { map, inner }) = (settings.sampling, &item.approach) {
            // the same basis with a quadrature in its reference frame, as a stored model
            // carries it (`sampled_registered`, the model stage's steps)
            let fit = subsample(&train_set.parameters, SAMPLING_FIT_POINTS);
            // at the stored model's primal rank where the scene names one (the model stage's
            // `leading` of the same base)
            let (sbase, sr) = match settings.sampled_r_primal.filter(|&r| r < r_primal) {
                Some(r) => (std::borrow::Cow::Owned(base_model.leading(r, 0)), r),
                None => (std::borrow::Cow::Borrowed(base_model), r_primal),
            };
            // the basis itself (`model` is the same one, behind the approximation trait), built
            // once and copied into each m's model
            let reg =
                dual::registration::Registered::build(&training, *map, *inner).map_err(|e| fail(e.to_string()))?;
            for m in ONLINE_MS.into_iter().filter(|&m| m <= model.size()) {
                let stored = sampled_registered(&sbase, reg.clone(), m, (&train_set.parameters, &fit), &params, tol)
                    .map_err(fail)?;
                let queries = solve_all(&Source::Stored, &stored, &test_set.parameters, &params, errors);
                rows.push(&format!("{name}{SAMPLED_SUFFIX}"), m, sr, &queries, b.fom_median);
            }
        }
    }
    let staging = ctx.store.stage(spec)?;
    let (results, times) = rows.tables(scene);
    results.write_parquet(&staging.path(names::ONLINE))?;
    times.write_parquet(&staging.path(names::ONLINE_TIMINGS))?;
    let summary = std::collections::BTreeMap::from([
        ("approximation".to_string(), json!(name)),
        ("r_primal".to_string(), json!(r_primal)),
        ("test_points".to_string(), json!(test_set.parameters.len())),
    ]);
    ctx.commit(staging, start.elapsed().as_secs_f64(), summary)?;
    progress.inc(&name);
    progress.finish("computed");
    ctx.record("online-approximation", 1, 0, ctx.store.dir(ArtifactKind::ONLINE_APPROXIMATION, &key));
    Ok(key)
}

/// Every test point with the dictionary's working-set solve, each timed alone
/// ([`time_each`]); the whole working-set loop is timed.
fn solve_dictionary(
    ws: &WorkingSet,
    base: &ReducedModel,
    points: &[Vec<f64>],
    params: &RomParams,
    errors: impl Fn(usize, &ReducedModel, &crom_stages::rom::ReducedSolution) -> (f64, f64) + Sync,
) -> Vec<Query> {
    let state = (base.clone(), RomWork::default(), WorkingSetScratch::default());
    time_each(
        points.iter().enumerate(),
        state,
        |(rm, w, sc), (_, mu)| ws.solve(rm, mu, params, w, sc),
        |i| i.info.outcome == RomOutcome::Converged,
        |(rm, w, _), &(j, _), info| answer_row(rm, w, j, &info.info, &errors),
    )
    .into_iter()
    .map(|(q, seconds)| Query { seconds, ..q })
    .collect()
}

/// Where a query's dual basis comes from.
enum Source<'a> {
    /// Fixed, column-major with this many columns (read from `bases.h5`, or built here).
    Fixed(std::borrow::Cow<'a, [f64]>, usize),
    /// Evaluated at each query's parameter, with at most this many columns (inside the timer).
    PerQuery(&'a dyn DualApprox, usize),
    /// The model's own, set at each query's parameter as a stored model sets it
    /// ([`ReducedModel::dual_at`], inside the timer).
    Stored,
}

/// Every test point with the dual basis from `source`, each solve timed alone ([`time_each`]).
fn solve_all(
    source: &Source<'_>,
    base: &ReducedModel,
    points: &[Vec<f64>],
    params: &RomParams,
    errors: impl Fn(usize, &ReducedModel, &crom_stages::rom::ReducedSolution) -> (f64, f64) + Sync,
) -> Vec<Query> {
    let mut rm = base.clone();
    if let Source::Fixed(theta, k) = source {
        rm.set_dual(theta, *k);
    }
    time_each(
        points.iter().enumerate(),
        (rm, RomWork::default()),
        |(rm, w), (_, mu)| {
            match source {
                // the step a stored model with a registered basis takes (`dual_at`)
                Source::PerQuery(model, m) => rm.set_dual_of(*model, mu, *m),
                Source::Stored => rm.dual_at(mu),
                Source::Fixed(..) => {}
            }
            rm.solve_in(mu, params, w)
        },
        |i| i.outcome == RomOutcome::Converged,
        |(rm, w), &(j, _), info| answer_row(rm, w, j, &info, &errors),
    )
    .into_iter()
    .map(|(q, seconds)| Query { seconds, ..q })
    .collect()
}

/// The row of test point `j`'s answer, held in `w` after its first solve (`info`): outcome,
/// errors and non-zero dual coefficients; its time is set by the caller from [`time_each`].
fn answer_row(
    rm: &ReducedModel,
    w: &RomWork,
    j: usize,
    info: &SolveInfo,
    errors: &impl Fn(usize, &ReducedModel, &crom_stages::rom::ReducedSolution) -> (f64, f64),
) -> Query {
    let sol = w.solution(info);
    let (primal, dual) = errors(j, rm, &sol);
    Query { outcome: sol.outcome, seconds: 0.0, primal, dual, nonzero: sol.nonzero_dual }
}

/// One (approximation, m) row: name, m, primal rank, counts (points, converged, infeasible,
/// failed), errors (median and p95, primal then dual), median non-zero dual coefficients.
type ResultRow = (String, usize, usize, [usize; 4], [f64; 4], f64);

#[derive(Default)]
struct Rows {
    results: Vec<ResultRow>,
    times: Vec<(String, usize, [f64; 4])>,
}

impl Rows {
    fn push(&mut self, name: &str, m: usize, r_primal: usize, q: &[Query], fom_median: f64) {
        let conv: Vec<&Query> = q.iter().filter(|x| x.outcome == RomOutcome::Converged).collect();
        let infeasible = q.iter().filter(|x| x.outcome == RomOutcome::Infeasible).count();
        let counts = [q.len(), conv.len(), infeasible, q.len() - conv.len() - infeasible];
        let pe: Vec<f64> = conv.iter().map(|x| x.primal).collect();
        let de: Vec<f64> = conv.iter().map(|x| x.dual).collect();
        let errs = [quantile(&pe, 0.5), quantile(&pe, 0.95), quantile(&de, 0.5), quantile(&de, 0.95)];
        let nz: Vec<f64> = conv.iter().map(|x| x.nonzero as f64).collect();
        self.results.push((name.to_string(), m, r_primal, counts, errs, quantile(&nz, 0.5)));
        let secs: Vec<f64> = q.iter().map(|x| x.seconds).collect();
        let med = quantile(&secs, 0.5);
        self.times.push((
            name.to_string(),
            m,
            [1e3 * med, 1e3 * quantile(&secs, 0.95), 1e3 * fom_median, fom_median / med],
        ));
    }

    fn tables(self, scene: &str) -> (Table, Table) {
        let r = &self.results;
        let n = r.len();
        let u = |f: &dyn Fn(&ResultRow) -> u64| Column::U64(r.iter().map(f).collect());
        let results = Table::default()
            .with("scene", Column::Str(vec![scene.to_string(); n]))
            .with("approximation", Column::Str(r.iter().map(|x| x.0.clone()).collect()))
            .with("m", u(&|x| x.1 as u64))
            .with("r_primal", u(&|x| x.2 as u64))
            .with("points", u(&|x| x.3[0] as u64))
            .with("converged", u(&|x| x.3[1] as u64))
            .with("infeasible", u(&|x| x.3[2] as u64))
            .with("failed", u(&|x| x.3[3] as u64))
            .with("median_primal_error", Column::F64(r.iter().map(|x| x.4[0]).collect()))
            .with("p95_primal_error", Column::F64(r.iter().map(|x| x.4[1]).collect()))
            .with("median_dual_error", Column::F64(r.iter().map(|x| x.4[2]).collect()))
            .with("p95_dual_error", Column::F64(r.iter().map(|x| x.4[3]).collect()))
            .with("median_nonzero_dual", Column::F64(r.iter().map(|x| x.5).collect()));
        let t = &self.times;
        let times = Table::default()
            .with("scene", Column::Str(vec![scene.to_string(); t.len()]))
            .with("approximation", Column::Str(t.iter().map(|x| x.0.clone()).collect()))
            .with("m", Column::U64(t.iter().map(|x| x.1 as u64).collect()))
            .with("median_online_ms", Column::F64(t.iter().map(|x| x.2[0]).collect()))
            .with("p95_online_ms", Column::F64(t.iter().map(|x| x.2[1]).collect()))
            .with("median_full_order_ms", Column::F64(t.iter().map(|x| x.2[2]).collect()))
            .with("speedup", Column::F64(t.iter().map(|x| x.2[3]).collect()));
        (results, times)
    }
}
