//! Online stage (paper Alg. 1, Figs. 3, 7, Tables 1–2) and the speed/accuracy trade.
//!
//! The primal basis of the online solve is the POD (numerical rank) of the training snapshots'
//! contact responses `u_k - u0(mu_k)` (see `crom_stages::rom` on lifting); the dual bases are
//! the stored CPG bases, full and truncated (a prefix of the same greedy path). One
//! [`ReducedModel`] is built offline for the full ranks; every other rank pair is its leading
//! block. Every training and test point is solved with both dual bases and both algorithms
//! (`exact`: QP per linearisation; `paper`: Algorithm 1). Errors are relative, primal in the H1
//! norm ([`PrimalErrors`], from precomputed projections — no field is reconstructed per
//! query), dual in the tributary-weighted L2 norm (`NaN` where the full-order field is zero:
//! reported, never divided by); each query also stores the a-posteriori error indicator.
//!
//! **Timing.** The online time of a query is [`ReducedModel::solve_in`] alone (reads only the
//! reduced model: cost independent of `n_dof`); the indicator is timed separately; the
//! full-order time is measured here, in the same process, at the test points; every timed solve
//! runs alone, one at a time, the fastest of repeated runs ([`super::timing`]). Every model of
//! the exact solve carries its answers and active sets at (up to 64 of) the training points,
//! computed offline ([`ReducedModel::with_warm_starts`]); a query starts from the nearest one's
//! active set and, Type-2, from its `y` interpolated toward the sample on the other side of the
//! query, and that lookup is part of the timed query. The trade-off
//! sweeps, for `exact`, the primal rank with the full and the truncated dual basis and the dual
//! rank with the full primal basis, and for `paper` the primal rank with the full dual basis
//! (up to [`PAPER_SWEEP_MAX_DUAL`] dual modes); per rank pair it counts converged, refused
//! (infeasible) and failed queries and gives medians and 95th percentiles of time and error
//! over the test points (errors over converged points only), and how well the indicator ranks
//! the true errors (Spearman) and its median effectivity (indicator / error).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use crom_schemas::artifact::{basis as bnames, rom as names, ArtifactKind};
use crom_schemas::scene::ContactSamplingSpec;
use crom_schemas::SceneConfig;
use crom_stages::metrics::order::{quantile, spearman};
use crom_stages::rom::{
    Algorithm, ContactOperator, Indicator, PrimalErrors, ReducedModel, ReducedSolution, RomOutcome, RomParams, RomWork,
};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::labels::Labels;
use super::online::{dual_error, online_params, subsample, SAMPLING_FIT_POINTS};
use super::shared::LazyPhysics;
use super::shared::Shared;
use super::timing::time_each;
use super::trainset;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In, H5Out};
use crate::io::table::{Column, Table};
use crate::physics::Physics;

/// What determines the online stage's results besides its inputs (training set, test set,
/// bases): the reduced solver's settings, shared by both algorithms.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct RomKey {
    max_iter: usize,
    gap_tol: f64,
    u_tol: f64,
    /// The sampled-surface rows (absent from the key when not asked for, so the keys of
    /// scenes without them are unchanged).
    #[serde(skip_serializing_if = "Option::is_none")]
    contact_sampling: Option<ContactSamplingSpec>,
    /// The samples of a large set that are measured (absent where every set has at most
    /// [`PAPER_POINTS`] points and every point is measured, so the keys of those scenes are
    /// unchanged).
    #[serde(skip_serializing_if = "Option::is_none")]
    measured: Option<Measured>,
}

impl RomKey {
    /// The scene's online settings.
    fn of(scene: &SceneConfig) -> Self {
        let p = online_params(scene);
        let contact_sampling = scene.study.contact_sampling.clone();
        let largest = scene.parameter.train_points().len().max(scene.parameter.test_points().len());
        let measured = (largest > PAPER_POINTS).then_some(Measured {
            points: MEASURED_POINTS,
            paper_points: PAPER_POINTS,
            seed: scene.study.seed,
        });
        Self { max_iter: p.max_iter, gap_tol: p.gap_tol, u_tol: p.u_tol, contact_sampling, measured }
    }

    /// The columns of set `which` (0 training, 1 test; `n` points) that are measured, and the
    /// positions among them at which the paper's algorithm is measured when its dual basis is
    /// large ([`Measured::columns`]); every point where nothing is sampled.
    fn measured(&self, which: u64, n: usize) -> Sample {
        match &self.measured {
            Some(m) => m.columns(which, n),
            None => ((0..n).collect(), (0..n).collect()),
        }
    }

    /// The reduced solver's settings (the algorithm chosen per query).
    fn params(&self) -> RomParams {
        RomParams { max_iter: self.max_iter, gap_tol: self.gap_tol, u_tol: self.u_tol, ..RomParams::default() }
    }
}

impl StageKey for RomKey {
    const KIND: ArtifactKind = ArtifactKind::ROM;
    /// Bump when the online stage changes its numbers (9: Type-1 warm starts from the nearest
    /// training point's active set — the same answers to round-off, fewer QP steps; 10:
    /// Type-2 warm starts, the vertex-zone rule asked before the round's fixed point, a dot
    /// product summed in another order — docs/design-notes.md#certificates-instead-of-searches;
    /// 11: Newton-corrected re-pairing steps and interpolated warm starts, the same answers to
    /// 1e-10 — docs/design-notes.md#newton-corrected-re-pairing-steps; 12: a dual basis of at
    /// most three columns summed into reduced rows at each linearisation, the same answers to
    /// 1e-10 — docs/design-notes.md#small-dual-bases-are-summed-once-per-linearisation; 13:
    /// solves up to 0.1 s timed as the fastest of three, the results the same —
    /// docs/design-notes.md#what-the-online-stage-times-and-reports; 14: every solve timed
    /// alone, one at a time, the results the same; 15: the timing runs in rounds over the points,
    /// the results the same; 16: the exact step's curvature applied through each term's two
    /// rows, the same answers to 1e-10 — docs/design-notes.md#an-exact-corrected-step; 17: the
    /// first linearisation's positions from the warm-start samples' displacements, the same
    /// answers to 1e-10; 18: half steps once the plain re-pairing cycles, the same answers
    /// where it did not, but for starts lent by samples that cycled before —
    /// docs/design-notes.md#half-steps-after-a-cycling-re-pairing; 19: a 3-D query answers with
    /// its verified linearisation point, within `u_tol` of the checked next iterate — 2-D the
    /// same; 20: in 3-D a feature renamed across a shared node (`Pair3::continues`) is not a
    /// change of the pairing, within `u_tol` of the answers before — 2-D the same).
    const ALGORITHM_VERSION: u32 = 20;
}

const ALGORITHMS: [Algorithm; 2] = [Algorithm::Exact, Algorithm::Paper];

/// Points of a set that the online stage measures, at most: a larger set is measured on a
/// keyed sample of this many ([`Measured`]).
pub(crate) const MEASURED_POINTS: usize = 1024;

/// Points of a set at which the paper's Algorithm 1 is measured, at most, when its dual basis
/// has more than [`PAPER_SWEEP_MAX_DUAL`] columns: the first of the same draw. Its cost per
/// query grows with the dual basis (each iteration evaluates every reduced constraint and
/// solves eq. 13 on the active ones): on ironing-fine-2d with 129 x 33 training points, at
/// (392, 4257) modes, 79 ms per query, 337 s for the 4 257 training points alone.
pub(crate) const PAPER_POINTS: usize = 256;

/// The measured columns of a set, and the positions among them of the paper's sample
/// ([`Measured::columns`]).
type Sample = (Vec<usize>, Vec<usize>);

/// Which points of a large set the online stage measures: [`MEASURED_POINTS`] of them drawn
/// without replacement (a partial Fisher-Yates shuffle on a stream of the scene's seed and the
/// set), and of those the first [`PAPER_POINTS`] drawn for the paper's algorithm where its dual
/// basis is large. A uniform draw, not a stride: a tensor grid's points in storage order would
/// alias with a stride (every fourth of 128 x 32 test points lies on 8 of the 32 presses).
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Measured {
    points: usize,
    paper_points: usize,
    seed: u64,
}

impl Measured {
    /// The measured columns of set `which` (0 training, 1 test) of `n` points, ascending
    /// (all of them up to [`Self::points`]), and the positions among them of the paper's
    /// sample, ascending (all of them up to [`Self::paper_points`]).
    fn columns(&self, which: u64, n: usize) -> Sample {
        let k = n.min(self.points);
        let mut order: Vec<usize> = (0..n).collect();
        let mut rng =
            crom_stages::rng::Rng::new(self.seed ^ 0x6d65_6173_7572_6564 ^ which.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        for i in 0..k {
            let j = i + rng.below(n - i);
            order.swap(i, j);
        }
        order.truncate(k);
        let mut paper: Vec<usize> = order[..k.min(self.paper_points)].to_vec();
        order.sort_unstable();
        paper.sort_unstable();
        let positions = paper.iter().filter_map(|c| order.binary_search(c).ok()).collect();
        (order, positions)
    }
}

/// The online stage's key spec. The timing constants are not in the key: they change the
/// times, not the results.
fn spec(settings: &RomKey, train: &Key, test: &Key, basis: &Key) -> KeySpec {
    KeySpec::of(settings).input("train", train).input("test", test).input("basis", basis)
}

/// The online reduced model, measured at the test points, computed from its key ([`RomKey`]).
#[derive(Debug)]
pub(crate) struct RomStage {
    pub spec: KeySpec,
    pub settings: RomKey,
    pub train: Input,
    pub test: Input,
    pub basis: Input,
    pub labels: Labels,
}

impl RomStage {
    pub(crate) fn plan(scene: &SceneConfig, train: Input, test: Input, basis: Input, labels: &Labels) -> Self {
        let settings = RomKey::of(scene);
        let spec = spec(&settings, &train.key, &test.key, &basis.key);
        Self { spec, settings, train, test, basis, labels: labels.clone() }
    }
}

impl StageDef for RomStage {
    fn times_solves(&self) -> bool {
        true
    }
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::ROM
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train, &self.test, &self.basis]
    }
    fn published(&self) -> Vec<Published> {
        vec![
            Published::file("rom_errors.parquet", names::ERRORS),
            Published::file("tradeoff.parquet", names::TRADEOFF),
            Published::file("rom_timings.parquet", names::TIMINGS),
            Published::file("tradeoff_timings.parquet", names::TRADEOFF_TIMINGS),
            Published::file("online.h5", names::ONLINE),
        ]
    }

    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let keys = [&self.train.key, &self.test.key, &self.basis.key];
        run(ctx, &mut shared.physics, &self.spec, (&self.settings, &self.labels), keys)
    }
}

fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    spec: &KeySpec,
    settings: (&RomKey, &Labels),
    keys: [&Key; 3],
) -> Result<Key, CromError> {
    let (store, loaded, progress) = (ctx.store, std::sync::Arc::clone(&ctx.loaded), ctx.progress);
    let (manifest, computed) = ctx.cached(ArtifactKind::ROM, spec, |staging| {
        let (train, test) = (loaded.set(store, keys[0])?, loaded.set(store, keys[1])?);
        // the measured points of each set (all of them, or a keyed sample of a large set), drawn
        // once: the full-order solves are timed at the test sample, as the queries
        let sample = [settings.0.measured(0, train.parameters.len()), settings.0.measured(1, test.parameters.len())];
        let points: Vec<Vec<f64>> = sample[1].0.iter().map(|&j| test.parameters[j].clone()).collect();
        let fom = physics.fom_seconds(keys[1], &points)?;
        let phi = physics.responses(keys[0], &train, failure(&settings.1.scene))?;
        measure(physics.get()?, (store, &loaded, progress), settings, keys, (fom, phi, sample), staging)
    })?;
    if !computed {
        progress.stage("online ROM", 1).finish("cached");
    }
    ctx.record("rom", usize::from(computed), usize::from(!computed), store.dir(ArtifactKind::ROM, &manifest.key));
    Ok(manifest.key)
}

/// The online stage's numerical failure in `scene`, from its message.
fn failure(scene: &str) -> impl Fn(String) -> CromError + Copy + '_ {
    move |message| CromError::Numerical { stage: "rom", scene: scene.to_string(), message }
}

/// What the measurements of the online stage share: the operator, the sets, the primal basis,
/// the reduced models at full ranks (full and truncated dual basis) and the rank sweep.
struct Online<'a> {
    op: &'a dyn ContactOperator,
    params: RomParams,
    scene: &'a str,
    train: &'a trainset::TrainingSet,
    test: &'a trainset::TrainingSet,
    phi: Arc<ColMatrix>,
    /// Columns of the full and the truncated CPG basis; whether the truncated one is a prefix.
    theta: (usize, usize, bool),
    full: ReducedModel,
    sweep: Vec<(usize, usize, &'static str)>,
}

/// The online stage's measurements, written into `staging`; returns the manifest's summary.
fn measure(
    phys: &Physics,
    (store, loaded, progress): (&crate::store::Store, &super::inputs::loaded::Loaded, crate::progress::Progress),
    (settings, labels): (&RomKey, &Labels),
    [train, test, basis]: [&Key; 3],
    (test_fom, phi, sample): (Vec<f64>, Arc<ColMatrix>, [Sample; 2]),
    staging: &crate::store::Staging,
) -> Result<BTreeMap<String, serde_json::Value>, CromError> {
    let params = settings.params();
    let scene = labels.scene.as_str();
    let fail = failure(scene);
    let (train_all, test_all) = (loaded.set(store, train)?, loaded.set(store, test)?);
    // the measured points of each set ([`RomKey::measured`]) and the paper's among them
    let [(train_cols, train_paper), (test_cols, test_paper)] = sample;
    let (train_sub, test_sub);
    let train_set: &trainset::TrainingSet = if train_cols.len() == train_all.parameters.len() {
        &train_all
    } else {
        train_sub = train_all.columns(&train_cols);
        &train_sub
    };
    let test_set: &trainset::TrainingSet = if test_cols.len() == test_all.parameters.len() {
        &test_all
    } else {
        test_sub = test_all.columns(&test_cols);
        &test_sub
    };
    let bfile = H5In::open(&store.dir(ArtifactKind::BASIS, basis).join(bnames::FILE))?;
    let theta_full = bfile.matrix(&format!("{}/{}", bnames::DUAL_CPG, bnames::MODES))?;
    let theta_trunc = bfile.matrix(&format!("{}/{}", bnames::DUAL_CPG_TRUNCATED, bnames::MODES))?;
    drop(bfile);
    let op = phys.operator();
    let sweep = sweep_pairs(phi.cols, theta_full.cols, theta_trunc.cols);
    let paper_at = [&train_paper[..], &test_paper[..]];
    let error_rows: usize = [theta_full.cols, theta_trunc.cols]
        .into_iter()
        .map(|rl| {
            let paper =
                |k: usize, n: usize| if paper_limited(rl, paper_at[k].len(), n) { paper_at[k].len() } else { n };
            let (n_train, n_test) = (train_set.parameters.len(), test_set.parameters.len());
            n_train + n_test + paper(0, n_train) + paper(1, n_test)
        })
        .sum();
    let paper_pairs = sweep.iter().filter(|s| paper_pair(s, &sweep)).count();
    let sampled_pairs = settings.contact_sampling.as_ref().map_or(0, |cs| cs.ranks.len());
    let mut progress = progress.stage("online ROM", 2 + error_rows + sweep.len() + paper_pairs + sampled_pairs);
    // offline: the reduced model at full ranks, error references
    // warm starts of the exact solve at the training points (the paper algorithm does not read
    // them; `leading` drops them, so the sweep's models build their own), all of them
    let full = ReducedModel::new(op, &phi.data, phi.cols, &theta_full.data, theta_full.cols)
        .map_err(|e| fail(e.to_string()))?
        .with_warm_starts(&train_all.parameters, &params);
    let prefix = theta_trunc.data.len() <= theta_full.data.len()
        && theta_trunc.data == theta_full.data[..theta_trunc.data.len()];
    let trunc = if prefix {
        full.leading(phi.cols, theta_trunc.cols)
    } else {
        ReducedModel::new(op, &phi.data, phi.cols, &theta_trunc.data, theta_trunc.cols)
            .map_err(|e| fail(e.to_string()))?
    }
    .with_warm_starts(&train_all.parameters, &params);
    let references = |set: &trainset::TrainingSet| {
        let refs: Vec<(&[f64], &[f64])> =
            set.parameters.iter().enumerate().map(|(j, mu)| (mu.as_slice(), set.primal.col(j))).collect();
        PrimalErrors::new(op, &phi.data, phi.cols, &refs)
    };
    let (train_pe, test_pe) = rayon::join(|| references(train_set), || references(test_set));
    // the full-order solve is timed at the test points (the speed-ups are test-set figures)
    let sets = [
        ("train", train_set, train_pe, vec![f64::NAN; train_set.parameters.len()]),
        ("test", test_set, test_pe, test_fom),
    ];
    progress.inc("offline");
    let (_, _, test_pe, test_fom) = &sets[1];
    let test_pe = test_pe.as_ref().ok_or_else(|| fail("Phi^T H Phi is not positive definite".into()))?;
    let theta = (theta_full.cols, theta_trunc.cols, prefix);
    let online = Online { op, params, scene, train: &train_all, test: test_set, phi, theta, full, sweep };
    let (mut trade, mut at_full_ranks) = online.sweep_rows((test_pe, test_fom), &mut progress);
    if let Some(cs) = &settings.contact_sampling {
        online.sampled_rows(cs, (test_pe, test_fom), &mut trade, &mut progress).map_err(fail)?;
    }
    let (errors, shown) =
        online.error_rows(&trunc, (&sets, paper_at), &mut at_full_ranks, &labels.names, &mut progress).map_err(fail)?;
    let (errors, query_times) = errors.tables();
    errors.write_parquet(&staging.path(names::ERRORS))?;
    query_times.write_parquet(&staging.path(names::TIMINGS))?;
    let (trade, trade_times) = trade.tables();
    trade.write_parquet(&staging.path(names::TRADEOFF))?;
    trade_times.write_parquet(&staging.path(names::TRADEOFF_TIMINGS))?;
    let sampled = (test_cols.len() < test_all.parameters.len()).then_some(&test_cols[..]);
    write_online(&staging.path(names::ONLINE), op, &online.phi, &online.full, (test_set, sampled), &shown)?;
    progress.inc("written");
    progress.finish("computed");
    Ok(BTreeMap::from([
        ("r_primal".to_string(), json!(online.phi.cols)),
        ("r_dual_full".to_string(), json!(theta_full.cols)),
        ("r_dual_truncated".to_string(), json!(theta_trunc.cols)),
    ]))
}

/// The test points' solves of one rank pair, in the order of the sets' columns.
type AtFullRanks = BTreeMap<(&'static str, &'static str), Vec<Query>>;

impl Online<'_> {
    /// The rank sweep at the test points, both algorithms (the paper's at its pairs only); the
    /// test-set solves at full ranks are kept for the error table, which they are part of.
    fn sweep_rows(
        &self,
        (test_pe, test_fom): (&PrimalErrors, &[f64]),
        progress: &mut crate::progress::StageProgress,
    ) -> (TradeRows, AtFullRanks) {
        let (theta_full, theta_trunc, prefix) = self.theta;
        let mut trade = TradeRows::default();
        let mut at_full_ranks = AtFullRanks::new();
        for alg in ALGORITHMS {
            let p = RomParams { algorithm: alg, ..self.params };
            let pairs = self.sweep.iter().filter(|s| alg == Algorithm::Exact || paper_pair(s, &self.sweep));
            for &(ru, rl, dual_basis) in pairs {
                let model = self.full.leading(ru, rl).with_warm_starts(&self.train.parameters, &p);
                let rows = solve_set(&model, self.test, &p);
                trade.push(self.scene, alg.name(), dual_basis, (ru, rl), &rows, test_pe, test_fom, |j, q| {
                    dual_error(self.op, &model, &q.sol, self.test, j)
                });
                progress.inc(&format!("{} ranks ({ru}, {rl})", alg.name()));
                let full_ranks = ru == self.phi.cols
                    && ((dual_basis == "full" && rl == theta_full)
                        || (dual_basis == "truncated" && prefix && rl == theta_trunc));
                if full_ranks {
                    at_full_ranks.insert((alg.name(), dual_basis), rows);
                }
            }
        }
        (trade, at_full_ranks)
    }

    /// The exact solve on a reduced quadrature of the contact constraints
    /// (docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints), fitted per rank
    /// pair to a subsample of the training points.
    fn sampled_rows(
        &self,
        cs: &ContactSamplingSpec,
        (test_pe, test_fom): (&PrimalErrors, &[f64]),
        trade: &mut TradeRows,
        progress: &mut crate::progress::StageProgress,
    ) -> Result<(), String> {
        let p = RomParams { algorithm: Algorithm::Exact, ..self.params };
        let fit_points = subsample(&self.train.parameters, SAMPLING_FIT_POINTS);
        for &[ru, rl] in &cs.ranks {
            let (ru, rl) = (ru.min(self.phi.cols), rl.min(self.theta.0));
            let exact = self.full.leading(ru, rl);
            let (model, _) = exact.with_sampled_surface(&fit_points, &p, cs.tol).map_err(|e| e.to_string())?;
            let model = model.with_warm_starts(&self.train.parameters, &p);
            let rows = solve_set(&model, self.test, &p);
            trade.push(self.scene, names::SAMPLED, "full", (ru, rl), &rows, test_pe, test_fom, |j, q| {
                dual_error(self.op, &model, &q.sol, self.test, j)
            });
            progress.inc(&format!("sampled ranks ({ru}, {rl})"));
        }
        Ok(())
    }

    /// Every training and test point with both dual bases and both algorithms at full ranks
    /// (the test points' solves taken from the sweep where it made them); returns the rows and
    /// the solutions whose fields are stored (`online.h5`: exact, full dual basis, test points).
    #[allow(clippy::type_complexity)]
    fn error_rows(
        &self,
        trunc: &ReducedModel,
        (sets, paper_at): (&[(&str, &trainset::TrainingSet, Option<PrimalErrors>, Vec<f64>); 2], [&[usize]; 2]),
        at_full_ranks: &mut AtFullRanks,
        names: &[String],
        progress: &mut crate::progress::StageProgress,
    ) -> Result<(ErrorRows, Vec<ReducedSolution>), String> {
        let mut errors = ErrorRows { names: names.to_vec(), ..Default::default() };
        let mut shown: Vec<ReducedSolution> = Vec::new();
        for (dual_basis, model) in [("full", &self.full), ("truncated", trunc)] {
            for alg in ALGORITHMS {
                let p = RomParams { algorithm: alg, ..self.params };
                for ((set, data, pe, fom), paper) in sets.iter().zip(paper_at) {
                    let pe = pe.as_ref().ok_or_else(|| "Phi^T H Phi is not positive definite".to_string())?;
                    let n = data.parameters.len();
                    // the paper's algorithm on a large dual basis: at its sample only
                    let limited = alg == Algorithm::Paper && paper_limited(model.ranks().1, paper.len(), n);
                    let at: Vec<usize> = if limited { paper.to_vec() } else { (0..n).collect() };
                    let cached = if *set == "test" { at_full_ranks.remove(&(alg.name(), dual_basis)) } else { None };
                    let rows = match cached {
                        Some(rows) if rows.len() == at.len() => rows,
                        _ => solve_at(model, data, &at, &p),
                    };
                    let keep = *set == "test" && dual_basis == "full" && alg == Algorithm::Exact;
                    for (q, &j) in rows.into_iter().zip(&at) {
                        let errs = (pe.relative(j, &q.sol.u_hat), dual_error(self.op, model, &q.sol, data, j));
                        let ranks = model.ranks();
                        errors.push(self.scene, set, dual_basis, alg, &data.parameters[j], ranks, errs, &q, fom[j]);
                        progress.inc(&format!("{set} {dual_basis} {}", alg.name()));
                        if keep {
                            shown.push(q.sol);
                        }
                    }
                }
            }
        }
        Ok((errors, shown))
    }
}

/// Whether the paper's algorithm with `r_l` dual modes is measured at a sample of `sample` of
/// a set's `n` measured points only ([`PAPER_POINTS`]).
fn paper_limited(r_l: usize, sample: usize, n: usize) -> bool {
    r_l > PAPER_SWEEP_MAX_DUAL && sample < n
}

/// `online.h5`: the online solution at every test point as fields, with its pointwise error
/// against the test snapshot (reconstructed here, outside every timer, one block of columns at
/// a time so that a large test set never needs the whole matrices in memory).
fn write_online(
    path: &std::path::Path,
    op: &dyn ContactOperator,
    phi: &ColMatrix,
    model: &ReducedModel,
    (test, sampled): (&trainset::TrainingSet, Option<&[usize]>),
    shown: &[ReducedSolution],
) -> Result<(), CromError> {
    let (n, m, k) = (test.primal.rows, test.dual.rows, shown.len());
    let f = H5Out::create(path)?;
    f.attr_str("algorithm", Algorithm::Exact.name())?;
    f.attr_str("dual_basis", "full")?;
    f.attr_u64("r_primal", model.ranks().0 as u64)?;
    f.attr_u64("r_dual", model.ranks().1 as u64)?;
    let primal = f.column_writer("primal", n, k, "online solution u0(mu) + Phi u_hat, one test point per column")?;
    let dual = f.column_writer("dual", m, k, "online contact pressure Theta lambda_hat")?;
    let primal_error = f.column_writer("primal_error", n, k, "online minus full-order displacement")?;
    let dual_error = f.column_writer("dual_error", m, k, "online minus full-order contact pressure")?;
    // the fields of a block of test points are computed (on every core) while the block before
    // is written (HDF5, one thread): the same columns in the same order
    const BLOCK: usize = 32;
    let fields = |start: usize| -> Vec<(Vec<f64>, Vec<f64>)> {
        (start..(start + BLOCK).min(k))
            .into_par_iter()
            .map(|j| {
                let u = ReducedModel::displacement(op, &phi.data, &test.parameters[j], &shown[j].u_hat);
                (u, model.pressure(&shown[j].lambda_hat))
            })
            .collect()
    };
    let write = |start: usize, cols: &[(Vec<f64>, Vec<f64>)]| -> Result<(), CromError> {
        for (i, (u, p)) in cols.iter().enumerate() {
            let j = start + i;
            primal.write(j, u)?;
            dual.write(j, p)?;
            let du: Vec<f64> = u.iter().zip(test.primal.col(j)).map(|(a, b)| a - b).collect();
            let dp: Vec<f64> = p.iter().zip(test.dual.col(j)).map(|(a, b)| a - b).collect();
            primal_error.write(j, &du)?;
            dual_error.write(j, &dp)?;
        }
        Ok(())
    };
    let mut next = (k > 0).then(|| fields(0));
    for start in (0..k).step_by(BLOCK) {
        let cols = next.take().unwrap_or_default();
        let following = start + BLOCK;
        let (written, computed) = rayon::join(|| write(start, &cols), || (following < k).then(|| fields(following)));
        written?;
        next = computed;
    }
    let names_len = test.parameters.first().map_or(1, Vec::len);
    let flat: Vec<f64> = test.parameters.iter().flatten().copied().collect();
    if names_len == 1 {
        f.vec_f64("parameters", &flat, "parameter value of each column")?;
    } else {
        f.table_f64("parameters", k, names_len, &flat, "parameter values of each column")?;
    }
    let converged: Vec<u64> = shown.iter().map(|s| u64::from(s.outcome == RomOutcome::Converged)).collect();
    if let Some(cols) = sampled {
        // a sample of a large test set: which column of the test set each solution is at
        f.vec_u64(names::TEST_COLUMNS, &cols.iter().map(|&c| c as u64).collect::<Vec<_>>())?;
    }
    f.vec_u64("converged", &converged)
}

/// One timed online query.
struct Query {
    sol: ReducedSolution,
    seconds: f64,
    indicator: Indicator,
    indicator_seconds: f64,
    /// The reduced inf-sup constant at the query's final linearisation
    /// ([`ReducedModel::inf_sup`]), at the sampled points only (see [`INF_SUP_SAMPLES`]).
    inf_sup: Option<f64>,
}

/// Points of a set at which the reduced inf-sup constant is evaluated, evenly spaced (an SVD of
/// up to `r_dual x r_primal` per point: sampled so that the diagnostic stays a small part of
/// the stage's time).
const INF_SUP_SAMPLES: usize = 8;

/// Solve every point of the set, the timed sample's solves each alone ([`time_each`]), and the
/// indicator timed separately, once, right after the point's first solve (at the timed points
/// only).
fn solve_set(model: &ReducedModel, set: &trainset::TrainingSet, p: &RomParams) -> Vec<Query> {
    solve_at(model, set, &(0..set.parameters.len()).collect::<Vec<_>>(), p)
}

/// [`solve_set`] at the columns `at` of the set only, in that order.
fn solve_at(model: &ReducedModel, set: &trainset::TrainingSet, at: &[usize], p: &RomParams) -> Vec<Query> {
    let stride = at.len().div_ceil(INF_SUP_SAMPLES).max(1);
    time_each(
        at.iter().enumerate().map(|(i, &j)| (i, &set.parameters[j])),
        RomWork::default(),
        |w, (_, mu)| model.solve_in(mu, p, w),
        |i| i.outcome == RomOutcome::Converged,
        |w, &(i, mu), info| {
            let sol = w.solution(&info);
            // at the solve's own linearisation, before the indicator re-pairs
            let inf_sup = if i % stride == 0 { model.inf_sup(w) } else { None };
            let t = Instant::now();
            let indicator = model.indicator(mu, w);
            let indicator_seconds = t.elapsed().as_secs_f64();
            Query { sol, seconds: 0.0, indicator, indicator_seconds, inf_sup }
        },
    )
    .into_iter()
    // an untimed point's indicator ran beside other solves: its time is undefined too
    .map(|(q, seconds)| Query {
        seconds,
        indicator_seconds: if seconds.is_nan() { f64::NAN } else { q.indicator_seconds },
        ..q
    })
    .collect()
}

/// Ranks 1, 2, 4, … up to and including `r`.
fn ladder(r: usize) -> Vec<usize> {
    let mut v: Vec<usize> = std::iter::successors(Some(1usize), |x| Some(x * 2)).take_while(|&x| x < r).collect();
    if r > 0 {
        v.push(r);
    }
    v
}

/// Largest dual rank at which the paper's Algorithm 1 is swept (see [`paper_pair`]).
const PAPER_SWEEP_MAX_DUAL: usize = 128;

/// The paper's Algorithm 1 is swept over the primal ladder with the full dual basis (the
/// other ladders only for `exact`, to keep the stage short), and only up to
/// [`PAPER_SWEEP_MAX_DUAL`] dual modes: each of its iterations solves eq. 13 on `q` active
/// reduced constraints (`O(q r^2)`), and with a dual basis much richer than the primal one it
/// runs into its iteration cap on most points (measured on ironing-coarse with 512 training
/// snapshots: 70–100 ms per query at primal ranks 4–16). Above that it is compared at full
/// ranks only (the error table).
fn paper_pair(p: &(usize, usize, &'static str), sweep: &[(usize, usize, &'static str)]) -> bool {
    let rl_max = sweep.iter().map(|s| s.1).max().unwrap_or(0);
    p.1 == rl_max && rl_max <= PAPER_SWEEP_MAX_DUAL
}

/// Rank pairs of the trade-off: the primal ladder with the full and with the truncated dual
/// basis, the dual ladder with the full primal basis.
fn sweep_pairs(ru: usize, rl: usize, rt: usize) -> Vec<(usize, usize, &'static str)> {
    let mut pairs: Vec<(usize, usize, &'static str)> = ladder(ru).into_iter().map(|r| (r, rl, "full")).collect();
    pairs.extend(
        ladder(rl).into_iter().filter(|&r| r != rl).map(|r| (ru, r, if r == rt { "truncated" } else { "full" })),
    );
    if rt < rl {
        pairs.extend(ladder(ru).into_iter().map(|r| (r, rt, "truncated")));
    }
    pairs.sort_unstable();
    pairs.dedup_by(|a, b| (a.0, a.1) == (b.0, b.1));
    pairs
}

#[derive(Default)]
struct TradeRows {
    s: [Vec<String>; 3],
    ints: [Vec<u64>; 6],
    vals: [Vec<f64>; 14],
}

impl TradeRows {
    #[allow(clippy::too_many_arguments)]
    fn push(
        &mut self,
        scene: &str,
        alg: &str,
        dual_basis: &str,
        (ru, rl): (usize, usize),
        rows: &[Query],
        pe: &PrimalErrors,
        fom: &[f64],
        dual: impl Fn(usize, &Query) -> f64,
    ) {
        let conv: Vec<usize> = (0..rows.len()).filter(|&j| rows[j].sol.outcome == RomOutcome::Converged).collect();
        let infeasible = rows.iter().filter(|q| q.sol.outcome == RomOutcome::Infeasible).count();
        let perr: Vec<f64> = conv.iter().map(|&j| pe.relative(j, &rows[j].sol.u_hat)).collect();
        let derr: Vec<f64> = conv.iter().map(|&j| dual(j, &rows[j])).collect();
        let ind: Vec<f64> = conv.iter().map(|&j| rows[j].indicator.residual).collect();
        let eff: Vec<f64> = ind.iter().zip(&perr).filter(|(_, e)| **e > 0.0).map(|(i, e)| i / e).collect();
        let online: Vec<f64> = rows.iter().map(|q| q.seconds).collect();
        let finite: Vec<f64> = perr.iter().copied().filter(|x| x.is_finite()).collect();
        // no converged point: the mean is undefined (a null in the table), not 0
        let mean = if finite.is_empty() { f64::NAN } else { finite.iter().sum::<f64>() / finite.len() as f64 };
        let max = finite.iter().fold(f64::NAN, |m, x| if m.is_nan() { *x } else { m.max(*x) });
        let (on_med, fom_med) = (quantile(&online, 0.5), quantile(fom, 0.5));
        let beta: Vec<f64> = conv.iter().filter_map(|&j| rows[j].inf_sup).collect();
        let beta_min = beta.iter().copied().fold(f64::NAN, |m, x| if m.is_nan() { x } else { m.min(x) });
        for (v, x) in self.s.iter_mut().zip([scene, alg, dual_basis]) {
            v.push(x.to_string());
        }
        let ints = [ru, rl, rows.len(), conv.len(), infeasible, rows.len() - conv.len() - infeasible];
        for (v, x) in self.ints.iter_mut().zip(ints) {
            v.push(x as u64);
        }
        let vals = [
            quantile(&perr, 0.5),
            quantile(&perr, 0.95),
            mean,
            max,
            quantile(&derr, 0.5),
            on_med,
            quantile(&online, 0.95),
            fom_med,
            fom_med / on_med,
            spearman(&ind, &perr),
            quantile(&eff, 0.5),
            quantile(&rows.iter().map(|q| q.indicator_seconds).collect::<Vec<_>>(), 0.5),
            beta_min,
            quantile(&beta, 0.5),
        ];
        for (v, x) in self.vals.iter_mut().zip(vals) {
            v.push(x);
        }
    }

    /// The results (`tradeoff.parquet`) and, same rows, the timings (`tradeoff_timings.parquet`).
    fn tables(self) -> (Table, Table) {
        let [scene, alg, basis] = self.s;
        let [ru, rl, points, conv, inf, failed] = self.ints;
        let [pm, p95, mean, max, dm, om, o95, fm, sp, rho, eff, ind_s, bmin, bmed] = self.vals;
        let keys = Table::default()
            .with("scene", Column::Str(scene))
            .with("algorithm", Column::Str(alg))
            .with("dual_basis", Column::Str(basis))
            .with("r_primal", Column::U64(ru))
            .with("r_dual", Column::U64(rl));
        let results = keys
            .clone()
            .with("points", Column::U64(points))
            .with("converged", Column::U64(conv))
            .with("infeasible", Column::U64(inf))
            .with("failed", Column::U64(failed))
            .with("median_primal_error", Column::F64(pm))
            .with("p95_primal_error", Column::F64(p95))
            .with("mean_primal_error", Column::F64(mean))
            .with("max_primal_error", Column::F64(max))
            .with("median_dual_error", Column::F64(dm))
            .with("indicator_spearman", Column::F64(rho))
            .with("indicator_effectivity", Column::F64(eff))
            .with("min_inf_sup", Column::F64(bmin))
            .with("median_inf_sup", Column::F64(bmed));
        let timings = keys
            .with("median_online_seconds", Column::F64(om))
            .with("p95_online_seconds", Column::F64(o95))
            .with("median_fom_seconds", Column::F64(fm))
            .with("speedup", Column::F64(sp))
            .with("median_indicator_seconds", Column::F64(ind_s));
        (results, timings)
    }
}

#[derive(Default)]
struct ErrorRows {
    s: [Vec<String>; 4],
    /// Parameter component names.
    names: Vec<String>,
    param: Vec<Vec<f64>>,
    ranks: [Vec<u64>; 2],
    errs: [Vec<f64>; 2],
    ints: [Vec<u64>; 3],
    outcome: Vec<String>,
    ind: [Vec<f64>; 4],
    times: [Vec<f64>; 3],
}

impl ErrorRows {
    #[allow(clippy::too_many_arguments)]
    fn push(
        &mut self,
        scene: &str,
        set: &str,
        basis: &str,
        alg: Algorithm,
        mu: &[f64],
        ranks: (usize, usize),
        errs: (f64, f64),
        q: &Query,
        fom: f64,
    ) {
        self.s[3].push(alg.name().to_string());
        self.s[0].push(scene.to_string());
        self.s[1].push(set.to_string());
        self.s[2].push(basis.to_string());
        self.param.push(mu.to_vec());
        self.ranks[0].push(ranks.0 as u64);
        self.ranks[1].push(ranks.1 as u64);
        self.errs[0].push(errs.0);
        self.errs[1].push(errs.1);
        self.ints[0].push(q.sol.iterations as u64);
        self.ints[1].push(q.sol.linearizations as u64);
        self.ints[2].push(q.sol.nonzero_dual as u64);
        self.outcome.push(q.sol.outcome.name().to_string());
        let i = &q.indicator;
        for (v, x) in self.ind.iter_mut().zip([i.residual, i.penetration, i.complementarity, i.unpaired_force]) {
            v.push(x);
        }
        for (v, x) in self.times.iter_mut().zip([q.seconds, q.indicator_seconds, fom]) {
            v.push(x);
        }
    }

    /// The results (`rom_errors.parquet`) and, same rows, the timings (`rom_timings.parquet`).
    fn tables(self) -> (Table, Table) {
        let [scene, set, basis, alg] = self.s;
        let [rp, rd] = self.ranks;
        let [pe, de] = self.errs;
        let [it, lin, nz] = self.ints;
        let [res, pen, comp, unp] = self.ind;
        let [on, ind_s, fom] = self.times;
        // `parameter` is the first component; a vector parameter adds a column per component.
        let t = Table::default()
            .with("scene", Column::Str(scene))
            .with("set", Column::Str(set))
            .with("dual_basis", Column::Str(basis))
            .with("algorithm", Column::Str(alg));
        let points: Vec<&[f64]> = self.param.iter().map(Vec::as_slice).collect();
        let keys = super::ctx::with_parameters(t, &self.names, &points)
            .with("r_primal", Column::U64(rp))
            .with("r_dual", Column::U64(rd));
        let results = keys
            .clone()
            .with("primal_error", Column::F64(pe))
            .with("dual_error", Column::F64(de))
            .with("iterations", Column::U64(it))
            .with("linearizations", Column::U64(lin))
            .with("nonzero_dual", Column::U64(nz))
            .with("outcome", Column::Str(self.outcome))
            .with("indicator", Column::F64(res))
            .with("penetration", Column::F64(pen))
            .with("complementarity", Column::F64(comp))
            .with("unpaired_force", Column::F64(unp));
        let timings = keys
            .with("online_seconds", Column::F64(on))
            .with("indicator_seconds", Column::F64(ind_s))
            .with("fom_seconds", Column::F64(fom));
        (results, timings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The measured sample: every point of a set up to MEASURED_POINTS, else that many distinct
    /// columns, ascending, the same on every call, another draw for the other set; the paper's
    /// positions index PAPER_POINTS of them. On a 128 x 32 tensor grid in storage order (the
    /// vector scene's test points) every one of the 32 presses is drawn about 32 times, where a
    /// stride of four would draw 8 of them.
    #[test]
    fn the_measured_sample_is_a_uniform_draw_of_distinct_columns() {
        let m = Measured { points: MEASURED_POINTS, paper_points: PAPER_POINTS, seed: 20234 };
        for n in [0, 1, 200, PAPER_POINTS, 300, MEASURED_POINTS] {
            let (cols, paper) = m.columns(1, n);
            assert_eq!(cols, (0..n).collect::<Vec<_>>(), "{n}");
            assert_eq!(paper.len(), n.min(PAPER_POINTS), "{n}");
            assert!(paper.windows(2).all(|w| w[0] < w[1]) && paper.iter().all(|&p| p < n), "{n}");
        }
        let n = 128 * 32;
        let (cols, paper) = m.columns(1, n);
        assert_eq!(cols.len(), MEASURED_POINTS);
        assert!(cols.windows(2).all(|w| w[0] < w[1]) && cols[MEASURED_POINTS - 1] < n);
        assert_eq!(m.columns(1, n), (cols.clone(), paper.clone()), "the same draw on every call");
        assert_ne!(m.columns(0, n).0, cols, "the training set has its own draw");
        assert_eq!(paper.len(), PAPER_POINTS);
        assert!(paper.windows(2).all(|w| w[0] < w[1]) && paper[PAPER_POINTS - 1] < MEASURED_POINTS);
        let mut per_press = [0usize; 32];
        for c in &cols {
            per_press[c % 32] += 1;
        }
        // 1 024 draws over 32 presses: 32 each on average, a standard deviation of about 5.5
        assert!(per_press.iter().all(|&k| (12..=52).contains(&k)), "{per_press:?}");
    }

    /// The sample enters the stage's key only where a set is larger than PAPER_POINTS: the
    /// keys of the shipped scenes with smaller sets stay what they were.
    #[test]
    fn only_large_sets_put_the_sample_into_the_key() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        for (file, sampled) in
            [("ironing-fine.toml", false), ("ironing-3d-2d.toml", false), ("ironing-fine-2d.toml", true)]
        {
            let scene = SceneConfig::load(&dir.join(file)).expect("shipped scene");
            let key = serde_json::to_string(&RomKey::of(&scene)).expect("json");
            assert_eq!(key.contains("\"measured\""), sampled, "{file}: {key}");
        }
    }

    fn cols(t: &Table) -> Vec<String> {
        t.columns.iter().map(|(n, _)| n.clone()).collect()
    }

    #[test]
    fn results_and_timings_have_the_contract_columns() {
        let (errors, times) = ErrorRows { names: vec!["p".to_string()], ..Default::default() }.tables();
        assert_eq!(cols(&errors), names::ERROR_COLUMNS);
        assert_eq!(cols(&times), names::TIMING_COLUMNS);
        let (trade, trade_times) = TradeRows::default().tables();
        assert_eq!(cols(&trade), names::TRADEOFF_COLUMNS);
        assert_eq!(cols(&trade_times), names::TRADEOFF_TIMING_COLUMNS);
        // No wall-clock column among the results.
        for c in cols(&errors).iter().chain(&cols(&trade)) {
            assert!(!c.contains("seconds") && c != "speedup", "{c} is a timing");
        }
    }
}
