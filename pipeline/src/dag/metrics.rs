//! Metric stages, each its own artifact so that changing one metric's settings recomputes only
//! it: generalization G(m) by leave-one-out (eq. 17, folds in parallel), specificity S(m)
//! (eq. 18, seeded sampling) and the nested-training-set error H(n) (eq. 19).

use std::collections::BTreeMap;

use crom_schemas::artifact::{metrics as names, ArtifactKind};
use crom_schemas::SceneConfig;
use crom_stages::basis::PodError;
use crom_stages::blocks::modal_pass;
use crom_stages::cone::NnlsParams;
use crom_stages::metrics::{
    combine_folds, loo_fold_cone, mean_interval95, nested_error_cone, nested_error_orth, specificity_cone_path,
    specificity_orth, specificity_orth_modal, LooOrth, MetricCurve, SpecificityParams,
};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;

use super::basis;
use super::basis::Ticker;
use super::convert::view;
use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::inputs::sets;
use super::inputs::streamed::{self, MetricSet};
use super::labels::Labels;
use super::shared::Shared;
use crate::cache::{Key, KeySpec, NnlsKey, StageKey};
use crate::error::CromError;
use crate::io::h5::ColMatrix;
use crate::io::table::{Column, Table};

/// Bump when a metric's numbers change.
/// G(m): the rank range, the folds when only a sample of them is used, the NNLS settings of
/// the cone folds.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct GeneralizationKey {
    max_rank: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    folds: Option<usize>,
    nnls: NnlsKey,
    /// How the shared greedy path selects (`basis::selection_of`): absent for the Gram
    /// selection of up to `DENSE_CURVE_MAX` snapshots.
    #[serde(skip_serializing_if = "Option::is_none")]
    selection: Option<&'static str>,
    /// The interval column of a sample of folds (`ci95`, see
    /// `crom_stages::metrics::mean_interval95`); absent (and not in the key) when every fold
    /// is in.
    #[serde(skip_serializing_if = "Option::is_none")]
    interval: Option<&'static str>,
    /// `"streamed"` when the primal folds read the training set block by block
    /// ([`super::inputs::streamed`]); absent (and not in the key) at or below the switch-over size.
    #[serde(skip_serializing_if = "Option::is_none")]
    primal: Option<&'static str>,
}

impl StageKey for GeneralizationKey {
    const KIND: ArtifactKind = ArtifactKind::GENERALIZATION;
    /// Bump when G(m) changes (2: the NNLS settings in the key; 3: the CPG floor; 4: the
    /// orthogonal folds by column downdate, equal to the SVD folds to round-off).
    const ALGORITHM_VERSION: u32 = 4;
}

/// S(m): samples, seed, rank range, NNLS settings of the cone projections.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct SpecificityKey {
    samples: usize,
    seed: u64,
    max_rank: usize,
    nnls: NnlsKey,
    /// Every m up to this, then the quarter-octave rank grid (large training sets only).
    #[serde(skip_serializing_if = "Option::is_none")]
    dense_to: Option<usize>,
    /// `"streamed"` when the primal S(m) reads the training set block by block
    /// ([`super::inputs::streamed`]); absent (and not in the key) at or below the switch-over size.
    #[serde(skip_serializing_if = "Option::is_none")]
    primal: Option<&'static str>,
}

/// Every m of S(m) is evaluated up to this many training snapshots; above, every m up to
/// [`SPECIFICITY_DENSE_TO`] and then the quarter-octave grid of `metrics::on_rank_grid`
/// (one S(m) costs `samples x N x m`: the whole curve to 256 at N = 16 385 is ~4 CPU-minutes).
const SPECIFICITY_GRID_ABOVE: usize = crom_stages::basis::DENSE_CURVE_MAX;

/// See [`SPECIFICITY_GRID_ABOVE`].
const SPECIFICITY_DENSE_TO: usize = 32;

/// The specificity's rank grid for the scene: `None` (every m) or where the grid starts.
fn specificity_dense_to(scene: &SceneConfig) -> Option<usize> {
    (scene.parameter.train_points().len() > SPECIFICITY_GRID_ABOVE).then_some(SPECIFICITY_DENSE_TO)
}

impl StageKey for SpecificityKey {
    const KIND: ArtifactKind = ArtifactKind::SPECIFICITY;
    /// Bump when S(m) changes (2: the NNLS settings in the key; 3: the CPG floor).
    const ALGORITHM_VERSION: u32 = 3;
}

/// H(n): the number of levels (their keys are inputs), the NNLS settings of the cone errors.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct NestedKey {
    levels: usize,
    nnls: NnlsKey,
}

impl StageKey for NestedKey {
    const KIND: ArtifactKind = ArtifactKind::NESTED;
    /// Bump when H(n) changes (2: the NNLS settings in the key; 3: the CPG floor).
    const ALGORITHM_VERSION: u32 = 3;
}

fn numerical(scene: &str, stage: &'static str, e: impl std::fmt::Display) -> CromError {
    CromError::Numerical { stage, scene: scene.to_string(), message: e.to_string() }
}

impl GeneralizationKey {
    /// The scene's G(m) settings.
    fn of(scene: &SceneConfig) -> Self {
        let max_rank = basis::max_rank_of(scene);
        let n_train = scene.parameter.train_points().len();
        let folds = scene.study.loo_folds_for(n_train);
        // A sample of folds is part of the key; every fold is the default.
        let sampled = (folds.len() != n_train).then_some(folds.len());
        let selection = basis::selection_of(n_train);
        let interval = sampled.map(|_| names::INTERVAL);
        let primal = streamed::primal_of(scene);
        Self { max_rank, folds: sampled, nnls: NnlsKey::used(), selection, interval, primal }
    }

    /// The folds of `n` training snapshots: every one, or the keyed sample of them
    /// (`StudySpec::loo_folds_for`, from the count).
    fn folds(&self, n: usize) -> Vec<usize> {
        crom_schemas::scene::spaced_folds(self.folds.unwrap_or(n).min(n), n)
    }
}

impl SpecificityKey {
    /// The scene's S(m) settings.
    fn of(scene: &SceneConfig) -> Self {
        let st = &scene.study;
        let (max_rank, dense_to) = (basis::max_rank_of(scene), specificity_dense_to(scene));
        let primal = streamed::primal_of(scene);
        Self { samples: st.specificity_samples, seed: st.seed, max_rank, nnls: NnlsKey::used(), dense_to, primal }
    }
}

/// The nested-error artifact's key spec for the nested sets `levels` (level n at index n-1).
fn nested_spec(levels: &[Key]) -> KeySpec {
    let mut spec = KeySpec::of(&NestedKey { levels: levels.len(), nnls: NnlsKey::used() });
    for (i, k) in levels.iter().enumerate() {
        spec = spec.input(&format!("level{}", i + 1), k);
    }
    spec
}

/// G(m) of the training set (leave-one-out), computed from its key ([`GeneralizationKey`]).
#[derive(Debug)]
pub(crate) struct GeneralizationStage {
    pub spec: KeySpec,
    pub settings: GeneralizationKey,
    pub train: Input,
    pub labels: Labels,
}

impl GeneralizationStage {
    pub(crate) fn plan(scene: &SceneConfig, train: Input, labels: &Labels) -> Self {
        let settings = GeneralizationKey::of(scene);
        let spec = KeySpec::of(&settings).input("train", &train.key);
        Self { spec, settings, train, labels: labels.clone() }
    }
}

impl StageDef for GeneralizationStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::GENERALIZATION
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train]
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file("generalization.parquet", crom_schemas::artifact::metrics::GENERALIZATION)]
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        generalization(ctx, &self.spec, (&self.settings, &self.labels.scene), &self.train.key)
    }
}

/// S(m) of the training set's bases, computed from its key ([`SpecificityKey`]).
#[derive(Debug)]
pub(crate) struct SpecificityStage {
    pub spec: KeySpec,
    pub settings: SpecificityKey,
    pub train: Input,
    pub basis: Input,
    pub labels: Labels,
}

impl SpecificityStage {
    pub(crate) fn plan(scene: &SceneConfig, train: Input, basis: Input, labels: &Labels) -> Self {
        let settings = SpecificityKey::of(scene);
        let spec = KeySpec::of(&settings).input("train", &train.key).input("basis", &basis.key);
        Self { spec, settings, train, basis, labels: labels.clone() }
    }
}

impl StageDef for SpecificityStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::SPECIFICITY
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train, &self.basis]
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file("specificity.parquet", crom_schemas::artifact::metrics::SPECIFICITY)]
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        specificity(ctx, &self.spec, (&self.settings, &self.labels.scene), &self.train.key, &self.basis.key)
    }
}

/// H(n) over the nested levels (level n at index n - 1).
#[derive(Debug)]
pub(crate) struct NestedStage {
    pub spec: KeySpec,
    pub levels: Vec<Input>,
    pub labels: Labels,
}

impl NestedStage {
    pub(crate) fn plan(levels: Vec<Input>, labels: &Labels) -> Self {
        let keys: Vec<Key> = levels.iter().map(|l| l.key.clone()).collect();
        Self { spec: nested_spec(&keys), levels, labels: labels.clone() }
    }
}

impl StageDef for NestedStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::NESTED
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        self.levels.iter().collect()
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file("nested.parquet", crom_schemas::artifact::metrics::NESTED)]
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        let keys: Vec<Key> = self.levels.iter().map(|l| l.key.clone()).collect();
        nested(ctx, &self.spec, &self.labels.scene, &keys)
    }
}

/// G(m) for primal orth, dual orth and dual cone, m = 1..=min(N - 1, max_rank).
fn generalization(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    (settings, scene): (&GeneralizationKey, &str),
    train: &Key,
) -> Result<Key, CromError> {
    let max_rank = settings.max_rank;
    let (store, loaded) = (ctx.store, std::sync::Arc::clone(&ctx.loaded));
    let progress = ctx.progress;
    ctx.single(ArtifactKind::GENERALIZATION, "generalization", spec, |staging| {
        let set = loaded.metric_set(store, train, settings.primal.is_some())?;
        let n_train = set.len();
        let folds = settings.folds(n_train);
        let max_m = n_train.saturating_sub(1).min(max_rank);
        let fail = |e: String| numerical(scene, "generalization", e);
        // G(m) reads the path's generators and leave-one-out data, not its C(m): no tolerance.
        let path = basis::dual_path(progress, &[], train, set.dual(), max_rank).map_err(fail)?;
        let bar = Ticker::new(progress, "LOO folds", 3 * folds.len());
        // A sample of folds: each mean with its interval over all N folds.
        let population = settings.interval.map(|_| n_train);
        let mut rows = CurveRows { population, ..CurveRows::default() };
        let primal = match &set {
            MetricSet::Whole(s) => LooOrth::new(view(&s.primal)).map_err(|e| fail(e.to_string()))?,
            MetricSet::Streamed(s) => s
                .take_frame()
                .map_err(PodError::from)
                .and_then(|frame| LooOrth::from_blocks_framed(&s.primal, &s.primal_norms, frame.as_deref()))
                .map_err(|e| s.primal.error_or(|| fail(e.to_string())))?,
        };
        let dual = LooOrth::new(view(set.dual())).map_err(|e| fail(e.to_string()))?;
        for (field, loo) in [("primal", &primal), ("dual", &dual)] {
            let curve = loo_orth(loo, &folds, max_m, &|| bar.tick(&format!("{field} orth"))).map_err(fail)?;
            rows.push(scene, field, "orth", &curve);
        }
        let curve = loo_cone(set.dual(), &path, &folds, max_m, &|| bar.tick("dual cone")).map_err(fail)?;
        rows.push(scene, "dual", "cone", &curve);
        bar.finish(&format!("m <= {max_m}"));
        rows.table().write_parquet(&staging.path(names::GENERALIZATION))?;
        Ok(BTreeMap::from([
            ("folds".to_string(), json!(folds.len())),
            ("snapshots".to_string(), json!(n_train)),
            ("max_rank".to_string(), json!(max_rank)),
            ("max_m".to_string(), json!(max_m)),
        ]))
    })
}

fn loo_orth(loo: &LooOrth, which: &[usize], max_m: usize, tick: &(dyn Fn() + Sync)) -> Result<MetricCurve, String> {
    let folds: Result<Vec<_>, _> = which
        .par_iter()
        .copied()
        .map_init(
            || loo.workspace(),
            |ws, i| {
                let fold = loo.fold_with(i, max_m, ws);
                tick();
                fold
            },
        )
        .collect();
    Ok(combine_folds(folds.map_err(|e| e.to_string())?, max_m))
}

fn loo_cone(
    s: &ColMatrix,
    path: &crom_stages::basis::CpgPath,
    which: &[usize],
    max_m: usize,
    tick: &(dyn Fn() + Sync),
) -> Result<MetricCurve, String> {
    let folds: Result<Vec<_>, _> = which
        .par_iter()
        .map(|&i| {
            let fold = loo_fold_cone(view(s), path, i, max_m);
            tick();
            fold
        })
        .collect();
    Ok(combine_folds(folds.map_err(|e| e.to_string())?, max_m))
}

/// S(m) for primal orth, dual orth and dual cone, on the stored bases, m = 1..=min(k, max_rank).
fn specificity(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    (settings, scene): (&SpecificityKey, &str),
    train: &Key,
    basis_key: &Key,
) -> Result<Key, CromError> {
    let params = SpecificityParams {
        samples: settings.samples,
        seed: settings.seed,
        dense_to: settings.dense_to.unwrap_or(usize::MAX),
    };
    let max_rank = settings.max_rank;
    let (store, loaded) = (ctx.store, std::sync::Arc::clone(&ctx.loaded));
    let progress = ctx.progress;
    ctx.single(ArtifactKind::SPECIFICITY, "specificity", spec, |staging| {
        let set = loaded.metric_set(store, train, settings.primal.is_some())?;
        let b = loaded.bases(store, basis_key)?;
        // S(m) reads the path's generators and coefficient ranges, not its C(m): no tolerance.
        let path = basis::dual_path(progress, &[], train, set.dual(), max_rank)
            .map_err(|e| numerical(scene, "specificity", e))?;
        let pm = view(&b.primal_pod).subcols(0, b.primal_pod.cols.min(max_rank));
        let dm = view(&b.dual_pod).subcols(0, b.dual_pod.cols.min(max_rank));
        // The stored cone basis is a prefix of the path: the same m range as computing on it.
        let cone_m = b.dual_cpg.cols.min(max_rank);
        let bar = Ticker::new(progress, "specificity m", cone_m);
        // The primal snapshots' coordinates on the modes: from the set in memory, or from one
        // pass over its blocks.
        let modal = match &set {
            MetricSet::Whole(_) => None,
            MetricSet::Streamed(s) => {
                Some(modal_pass(&s.primal, pm).map_err(|e| s.primal.error_or(|| numerical(scene, "specificity", e)))?)
            }
        };
        let dual = set.dual();
        let (p, d, c) = rayon::join(
            || match (&set, modal) {
                (_, Some(modal)) => specificity_orth_modal(modal, params),
                (MetricSet::Whole(s), None) => specificity_orth(view(&s.primal), pm, params),
                (MetricSet::Streamed(_), None) => unreachable!("a streamed set has its modal pass"),
            },
            || {
                rayon::join(
                    || specificity_orth(view(dual), dm, params),
                    || specificity_cone_path(view(dual), &path, cone_m, params, &|| bar.tick("dual cone")),
                )
            },
        )
        .into_flat();
        bar.finish(&format!("m <= {max_rank}"));
        let mut rows = CurveRows::default();
        rows.push(scene, "primal", "orth", &p);
        rows.push(scene, "dual", "orth", &d);
        rows.push(scene, "dual", "cone", &c);
        rows.table().write_parquet(&staging.path(names::SPECIFICITY))?;
        Ok(BTreeMap::from([
            ("samples".to_string(), json!(params.samples)),
            ("seed".to_string(), json!(params.seed)),
            ("max_rank".to_string(), json!(max_rank)),
        ]))
    })
}

trait IntoFlat<A, B, C> {
    fn into_flat(self) -> (A, B, C);
}

impl<A, B, C> IntoFlat<A, B, C> for (A, (B, C)) {
    fn into_flat(self) -> (A, B, C) {
        (self.0, self.1 .0, self.1 .1)
    }
}

/// The largest finest nested level (its columns, bytes) that the nested stage reads once and
/// takes every other level from ([`sets::Nested`]); larger studies read two levels at a time.
const NESTED_IN_MEMORY: usize = 256 << 20;

/// H(n), n = 1..levels-1, from the nested sets (level n at index n-1).
fn nested(ctx: &mut Ctx<'_>, spec: &KeySpec, scene: &str, levels: &[Key]) -> Result<Key, CromError> {
    let (store, progress, loaded) = (ctx.store, ctx.progress, std::sync::Arc::clone(&ctx.loaded));
    ctx.single(ArtifactKind::NESTED, "nested", spec, |staging| {
        // Two levels in memory at a time (level n and n + 1), the finer one kept for the next
        // pair: memory is bounded by the two finest levels, not by all of them.
        let mut t = NestedRows::default();
        let n_levels = levels.len();
        let mut bar = progress.stage("nested pairs", n_levels.saturating_sub(1));
        // sets up to NESTED_IN_MEMORY bytes: every level from the finest, read once
        let nested = sets::Nested::open(store, levels, NESTED_IN_MEMORY)?;
        // each level's pressures are kept for the comparison's H(n), which reads every level
        let load = |i: usize| -> Result<_, CromError> {
            let level = match &nested {
                Some(n) => n.level(i),
                None => sets::load_from(store, &levels[i])?,
            };
            loaded.keep_level(&levels[i], &level.dual, &level.parameters);
            Ok(level)
        };
        let mut lo = if levels.is_empty() { None } else { Some(load(0)?) };
        for i in 1..levels.len() {
            let hi = load(i)?;
            let lo_set = lo.as_ref().expect("loaded above");
            let ((po, dor), dc) = rayon::join(
                || {
                    rayon::join(
                        || nested_error_orth(view(&lo_set.primal), view(&hi.primal)),
                        || nested_error_orth(view(&lo_set.dual), view(&hi.dual)),
                    )
                },
                || nested_error_cone(view(&lo_set.dual), view(&hi.dual), NnlsParams::default()),
            );
            let fail = |e: String| numerical(scene, "nested", e);
            let v = [
                po.map_err(|e| fail(e.to_string()))?,
                dor.map_err(|e| fail(e.to_string()))?,
                dc.map_err(|e| fail(e.to_string()))?,
            ];
            let zero = (0..hi.dual.cols).filter(|&j| hi.dual.col(j).iter().all(|x| x.abs() <= 0.0)).count();
            for ((field, basis), value) in [("primal", "orth"), ("dual", "orth"), ("dual", "cone")].iter().zip(v) {
                t.push(scene, field, basis, i, value, hi.parameters.len(), if *field == "dual" { zero } else { 0 });
            }
            bar.inc(&format!("H({i})"));
            lo = Some(hi);
        }
        bar.finish("done");
        t.table().write_parquet(&staging.path(names::NESTED))?;
        Ok(BTreeMap::from([("levels".to_string(), json!(n_levels))]))
    })
}

#[derive(Default)]
struct CurveRows {
    s: [Vec<String>; 3],
    m: Vec<u64>,
    mean: Vec<f64>,
    std: Vec<f64>,
    ints: [Vec<u64>; 3],
    /// The means are over a sample of this many folds' population: each row carries the
    /// half-width of its 95 % interval (`ci95`).
    population: Option<usize>,
    ci95: Vec<f64>,
}

impl CurveRows {
    fn push(&mut self, scene: &str, field: &str, basis: &str, c: &MetricCurve) {
        for k in (0..c.len()).filter(|&k| !c.skipped[k]) {
            self.s[0].push(scene.to_string());
            self.s[1].push(field.to_string());
            self.s[2].push(basis.to_string());
            self.m.push(k as u64 + 1);
            self.mean.push(c.mean[k]);
            self.std.push(c.std[k]);
            self.ints[0].push(c.count[k] as u64);
            self.ints[1].push(c.padded[k] as u64);
            self.ints[2].push(c.n_zero as u64);
            if let Some(n) = self.population {
                self.ci95.push(mean_interval95(c.std[k], c.count[k], n));
            }
        }
    }

    fn table(self) -> Table {
        let [scene, field, basis] = self.s;
        let [count, padded, n_zero] = self.ints;
        let t = Table::default()
            .with("scene", Column::Str(scene))
            .with("field", Column::Str(field))
            .with("basis", Column::Str(basis))
            .with("m", Column::U64(self.m))
            .with("mean", Column::F64(self.mean))
            .with("std", Column::F64(self.std))
            .with("count", Column::U64(count))
            .with("padded", Column::U64(padded))
            .with("n_zero", Column::U64(n_zero));
        match self.population {
            Some(_) => t.with(names::INTERVAL, Column::F64(self.ci95)),
            None => t,
        }
    }
}

#[derive(Default)]
struct NestedRows {
    s: [Vec<String>; 3],
    n: Vec<u64>,
    value: Vec<f64>,
    snaps: Vec<u64>,
    zero: Vec<u64>,
}

impl NestedRows {
    #[allow(clippy::too_many_arguments)]
    fn push(&mut self, scene: &str, field: &str, basis: &str, n: usize, value: f64, snaps: usize, zero: usize) {
        self.s[0].push(scene.to_string());
        self.s[1].push(field.to_string());
        self.s[2].push(basis.to_string());
        self.n.push(n as u64);
        self.value.push(value);
        self.snaps.push(snaps as u64);
        self.zero.push(zero as u64);
    }

    fn table(self) -> Table {
        let [scene, field, basis] = self.s;
        Table::default()
            .with("scene", Column::Str(scene))
            .with("field", Column::Str(field))
            .with("basis", Column::Str(basis))
            .with("n", Column::U64(self.n))
            .with("value", Column::F64(self.value))
            .with("snapshots", Column::U64(self.snaps))
            .with("n_zero", Column::U64(self.zero))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve() -> MetricCurve {
        MetricCurve {
            mean: vec![0.5, 0.25],
            std: vec![0.2, 0.1],
            count: vec![16, 16],
            padded: vec![0, 0],
            n_zero: 0,
            skipped: vec![false, false],
        }
    }

    /// Every fold: the table has exactly the contract's columns (the layout of every store so
    /// far); a sample of folds adds `ci95`, each row's interval by `mean_interval95`.
    #[test]
    fn a_sample_of_folds_adds_its_interval_column() {
        let cols = |t: &Table| t.columns.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
        let mut every = CurveRows::default();
        every.push("s", "dual", "orth", &curve());
        assert_eq!(cols(&every.table()), names::CURVE_COLUMNS);
        let mut sampled = CurveRows { population: Some(513), ..CurveRows::default() };
        sampled.push("s", "dual", "orth", &curve());
        let t = sampled.table();
        let mut expected: Vec<String> = names::CURVE_COLUMNS.iter().map(|c| c.to_string()).collect();
        expected.push(names::INTERVAL.to_string());
        assert_eq!(cols(&t), expected);
        let want = [mean_interval95(0.2, 16, 513), mean_interval95(0.1, 16, 513)];
        assert_eq!(t.f64s(names::INTERVAL).expect("ci95"), &want[..]);
    }

    /// The interval is keyed exactly when the folds are a sample, so the keys of scenes that
    /// run every fold are unchanged.
    #[test]
    fn the_interval_is_keyed_only_for_a_sample_of_folds() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/rope.toml");
        let text = std::fs::read_to_string(path).expect("rope.toml");
        let every = SceneConfig::from_toml_str(&text, std::path::Path::new("rope.toml")).expect("scene");
        let key = serde_json::to_value(GeneralizationKey::of(&every)).expect("json");
        assert!(key.get("interval").is_none() && key.get("folds").is_none(), "{key}");
        let sampled_text = text.replacen("[study]", "[study]\nloo_folds = 4", 1);
        assert_ne!(sampled_text, text, "rope.toml has a [study] table");
        let sampled = SceneConfig::from_toml_str(&sampled_text, std::path::Path::new("rope.toml")).expect("scene");
        let key = serde_json::to_value(GeneralizationKey::of(&sampled)).expect("json");
        assert_eq!(key["interval"], names::INTERVAL);
        assert_eq!(key["folds"], 4);
    }
}
