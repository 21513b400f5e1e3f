//! Online comparison stage (issue 15): the reduced solve of the online stage
//! ([`crom_stages::rom`], exact algorithm) with the dual basis of each approximation of the
//! scene's `[comparison]` that has a non-negative one (CPG, Angle-Greedy, NNMF, local bases,
//! the dictionary, registered CPG), at the full primal rank, for a few dual sizes m, at every
//! test point.
//!
//! The dictionary is solved by a working set of atoms (`crom_stages::dual::dictionary::
//! WorkingSet`: the nearest atoms first, then the violated ones), the whole loop timed.
//!
//! The reduced model is built once (`K̂`, the contact-dof rows of the primal basis) and only
//! its dual part is replaced per approximation ([`ReducedModel::set_dual`], `O(n_contact m)`).
//! A fixed basis is set before the timer starts; a basis that depends on the parameter (a
//! registered one is pushed forward to the query's frame, a local one is its cell's) is
//! evaluated and set inside the timed query, so its online time includes that work — which
//! reads only contact-surface data. The full-order solve is timed in the same process at the
//! same points, as in the online stage.

use std::time::Instant;

use crom_schemas::artifact::{comparison as names, ArtifactKind};
use crom_schemas::SceneConfig;
use crom_stages::dual::dictionary::{WorkingSet, WorkingSetScratch};
use crom_stages::dual::{self, Approach, DualApprox, Training};
use crom_stages::metrics::order::quantile;
use crom_stages::rom::{Algorithm, PrimalErrors, ReducedModel, RomOutcome, RomParams, RomWork};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;

use super::comparison::{approaches, contact_x};
use super::convert::view;
use super::rom::{dual_error, fom_seconds, response_basis, REPEAT_BELOW, TIMING_REPEATS};
use super::{Ctx, LazyPhysics};
use crate::cache::{Key, KeySpec, NnlsKey, StageKey};
use crate::error::CromError;
use crate::io::table::{Column, Table};

/// What determines the online comparison besides its inputs.
#[derive(Debug, Serialize)]
struct OnlineComparisonKey<'a> {
    spec: &'a crom_schemas::comparison::ComparisonSpec,
    nnls: NnlsKey,
    max_iter: usize,
    gap_tol: f64,
    u_tol: f64,
}

impl StageKey for OnlineComparisonKey<'_> {
    const KIND: ArtifactKind = ArtifactKind::OnlineComparison;
    /// Bump when a number of the online comparison changes.
    const ALGORITHM_VERSION: u32 = 2;
}

/// The dual sizes the online solve is run at (those up to the basis size; the dictionary is
/// run once, with all its atoms).
const ONLINE_MS: [usize; 7] = [1, 2, 3, 5, 8, 16, 32];

/// The stage's key spec (None without `[comparison]`).
pub(crate) fn spec(scene: &SceneConfig, train: &Key, test: &Key, mesh: &Key) -> Option<KeySpec> {
    let cmp = scene.comparison.as_ref()?;
    let p = RomParams::default();
    let key = OnlineComparisonKey {
        spec: cmp,
        nnls: NnlsKey::used(),
        max_iter: p.max_iter,
        gap_tol: p.gap_tol,
        u_tol: p.u_tol,
    };
    Some(KeySpec::of(&key).input("train", train).input("test", test).input("mesh", mesh))
}

/// One query's outcome.
struct Query {
    outcome: RomOutcome,
    seconds: f64,
    primal: f64,
    dual: f64,
    nonzero: usize,
}

pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    train: &Key,
    test: &Key,
    mesh: &Key,
) -> Result<Key, CromError> {
    let scene_cfg = ctx.scene;
    let (Some(cmp), Some(spec)) = (scene_cfg.comparison.clone(), spec(scene_cfg, train, test, mesh)) else {
        return Err(CromError::artifact(
            "online-comparison",
            "the scene has no [comparison] section".to_string(),
            "add one or do not run the online comparison stage",
        ));
    };
    let key = spec.key();
    if ctx.lookup(ArtifactKind::OnlineComparison, &key)?.is_some() {
        ctx.progress.stage("online comparison", 1).finish("cached");
        ctx.record("online-comparison", 0, 1, ctx.store.dir(ArtifactKind::OnlineComparison, &key));
        return Ok(key);
    }
    let scene = scene_cfg.scene.name.clone();
    let fail = |m: String| CromError::Numerical { stage: "online-comparison", scene: scene.clone(), message: m };
    let phys = physics.get()?;
    let op = phys.operator();
    let (train_set, test_set) = (ctx.loaded.set(ctx.store, train)?, ctx.loaded.set(ctx.store, test)?);
    let surface = contact_x(ctx.store, mesh)?;
    let start = Instant::now();
    let phi = response_basis(op, &train_set).map_err(fail)?;
    let nc = test_set.dual.rows;
    let base = ReducedModel::new(op, &phi.data, phi.cols, &[], 0).map_err(|e| fail(e.to_string()))?;
    let refs: Vec<(&[f64], &[f64])> =
        test_set.parameters.iter().enumerate().map(|(j, mu)| (mu.as_slice(), test_set.primal.col(j))).collect();
    let pe = PrimalErrors::new(op, &phi.data, phi.cols, &refs)
        .ok_or_else(|| fail("Phi^T H Phi is not positive definite".into()))?;
    let fom = fom_seconds(phys, &test_set.parameters);
    let fom_median = quantile(&fom, 0.5);
    let n_train = train_set.parameters.len();
    let ms = dual::m_grid(cmp.max_m.min(n_train));
    let training =
        Training { snapshots: view(&train_set.dual), params: &train_set.parameters, surface: &surface, ms: &ms };
    let list: Vec<Approach> = approaches(&cmp);
    let mut progress = ctx.progress.stage("online comparison", list.len());
    let params = RomParams { algorithm: Algorithm::Exact, ..RomParams::default() };
    let mut rows = Rows::default();
    for a in &list {
        let name = a.name();
        let model = dual::build(a, &training).map_err(|e| fail(format!("{name}: {e}")))?;
        let Some(probe) = model.cone_basis(&test_set.parameters[0], 1) else {
            progress.inc(&format!("{name}: signed modes, no online solve"));
            continue;
        };
        if matches!(a, Approach::Dictionary) {
            // Every training snapshot an atom, solved by a working set (column generation).
            let ws = WorkingSet::new(view(&train_set.dual), &train_set.parameters, op.weights(), WS_START);
            let queries = solve_dictionary(&ws, &base, &test_set.parameters, &params, |j, rm, sol| {
                (pe.relative(j, &sol.u_hat), dual_error(op, rm, sol, &test_set, j))
            });
            rows.push(&name, probe.ncols(), phi.cols, &queries, fom_median);
            progress.inc(&name);
            continue;
        }
        let sizes: Vec<usize> = ONLINE_MS.iter().copied().filter(|&m| m <= model.size()).collect();
        for m in sizes {
            let queries = solve_all(model.as_ref(), &base, m, nc, &test_set.parameters, &params, |j, rm, sol| {
                (pe.relative(j, &sol.u_hat), dual_error(op, rm, sol, &test_set, j))
            });
            rows.push(&name, m, phi.cols, &queries, fom_median);
        }
        progress.inc(&name);
    }
    let staging = ctx.store.stage(&spec)?;
    let (results, times) = rows.tables(&scene);
    results.write_parquet(&staging.path(names::ONLINE))?;
    times.write_parquet(&staging.path(names::ONLINE_TIMINGS))?;
    let summary = std::collections::BTreeMap::from([
        ("approximations".to_string(), json!(list.len())),
        ("r_primal".to_string(), json!(phi.cols)),
        ("test_points".to_string(), json!(test_set.parameters.len())),
    ]);
    ctx.commit(staging, start.elapsed().as_secs_f64(), summary)?;
    progress.finish("computed");
    ctx.record("online-comparison", 1, 0, ctx.store.dir(ArtifactKind::OnlineComparison, &key));
    Ok(key)
}

/// The dictionary's first working set: the atoms nearest to the query's parameter.
const WS_START: usize = 16;

/// Every test point with the dictionary's working-set solve (in parallel, one reduced model,
/// work buffer and scratch per thread); the whole working-set loop is timed.
fn solve_dictionary(
    ws: &WorkingSet,
    base: &ReducedModel,
    points: &[Vec<f64>],
    params: &RomParams,
    errors: impl Fn(usize, &ReducedModel, &crom_stages::rom::ReducedSolution) -> (f64, f64) + Sync,
) -> Vec<Query> {
    (0..points.len())
        .into_par_iter()
        .map_init(
            || (base.clone(), RomWork::default(), WorkingSetScratch::default()),
            |(rm, w, sc), j| {
                let mu = &points[j];
                let mut best = f64::INFINITY;
                let mut info = None;
                for _ in 0..TIMING_REPEATS {
                    let t = Instant::now();
                    let i = ws.solve(rm, mu, params, w, sc);
                    best = best.min(t.elapsed().as_secs_f64());
                    info = Some(i);
                    if best >= REPEAT_BELOW {
                        break;
                    }
                }
                let sol = w.solution(&info.expect("TIMING_REPEATS >= 1").info);
                let (primal, dual) = errors(j, rm, &sol);
                Query { outcome: sol.outcome, seconds: best, primal, dual, nonzero: sol.nonzero_dual }
            },
        )
        .collect()
}

/// The dual basis of `model` at `mu` with at most `m` columns, column-major.
fn basis_at(model: &dyn DualApprox, mu: &[f64], m: usize) -> (Vec<f64>, usize) {
    let b = model.cone_basis(mu, m).unwrap_or_else(|| faer::Mat::zeros(0, 0));
    let k = b.ncols();
    ((0..k).flat_map(|j| b.col(j).iter().copied().collect::<Vec<_>>()).collect(), k)
}

/// Every test point with the dual basis of `model` of size `m` (in parallel, one reduced
/// model and work buffer per thread).
fn solve_all(
    model: &dyn DualApprox,
    base: &ReducedModel,
    m: usize,
    nc: usize,
    points: &[Vec<f64>],
    params: &RomParams,
    errors: impl Fn(usize, &ReducedModel, &crom_stages::rom::ReducedSolution) -> (f64, f64) + Sync,
) -> Vec<Query> {
    let per_query = model.depends_on_mu();
    let fixed = (!per_query).then(|| basis_at(model, &points[0], m));
    let prepared = |rm: &mut ReducedModel| {
        if let Some((theta, k)) = &fixed {
            rm.set_dual(theta, *k);
        }
    };
    (0..points.len())
        .into_par_iter()
        .map_init(
            || {
                let mut rm = base.clone();
                prepared(&mut rm);
                (rm, RomWork::default())
            },
            |(rm, w), j| {
                let mu = &points[j];
                let mut best = f64::INFINITY;
                let mut info = None;
                for _ in 0..TIMING_REPEATS {
                    let t = Instant::now();
                    if per_query {
                        let (theta, k) = basis_at(model, mu, m);
                        debug_assert_eq!(theta.len(), nc * k);
                        rm.set_dual(&theta, k);
                    }
                    let i = rm.solve_in(mu, params, w);
                    best = best.min(t.elapsed().as_secs_f64());
                    info = Some(i);
                    if best >= REPEAT_BELOW {
                        break;
                    }
                }
                let sol = w.solution(&info.expect("TIMING_REPEATS >= 1"));
                let (primal, dual) = errors(j, rm, &sol);
                Query { outcome: sol.outcome, seconds: best, primal, dual, nonzero: sol.nonzero_dual }
            },
        )
        .collect()
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
