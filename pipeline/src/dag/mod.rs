//! The study as a graph of cached stages.
//!
//! ```text
//! scene ─► mesh ─► snapshots (one sweep per point set) ─► trainset train, test, nested-k
//!   trainset ─► views (beside the main loop)
//!   trainset train ─► basis ─► views basis
//!   trainset train + basis ─► compactness, specificity
//!   trainset train ─► generalization
//!   trainset nested-1..K ─► nested
//!   trainset train, test, mesh (+ nested) ─► approximation <name> … ─► comparison
//!   trainset train, test, basis ─► rom ─► views online                       (online)
//!   trainset train, basis, rom ─► model (the reduced model `crom query` runs)  (online)
//!   approximation <name> ─► online-approximation <name> … ─► online-comparison (online)
//!   mesh, train, basis, the metrics, rom, comparisons ─► report             (online)
//! ```
//!
//! [`plan::Plan::of`] builds the graph from the scene file alone: each node is a typed stage
//! (`graph::StageDef`) holding its key spec and its named inputs, so the key of every
//! artifact is known before anything runs. Each stage is named by the content hash of its
//! parameters and inputs ([`crate::cache`]); a stage whose artifact is in the store and
//! verifies is not run again. `execute` runs the nodes in order with no stage-specific code.

mod approximation;
mod approximation_online;
pub(crate) mod basis;
mod beside;
mod compactness;
pub(crate) mod comparison;
mod convert;
mod external_mesh;
mod graph;
mod import;
mod labels;
mod loaded;
mod mesh;
mod metrics;
pub(crate) mod model;
pub mod plan;
pub mod publish;
mod report;
mod rom;
mod snapshots;
mod streamed;
mod timing;
pub(crate) mod trainset;
mod views;

pub(crate) use labels::Labels;
pub(crate) use rom::relative_dual_error;
pub(crate) use snapshots::{chunk_columns, shard_range};

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use crom_schemas::artifact::ArtifactKind;
use crom_schemas::SceneConfig;

use crate::cache::{Key, KeySpec};
use crate::error::CromError;
use crate::io::table::{Column, Table};
use crate::physics::Physics;
use crate::progress::Progress;
use crate::store::{Lookup, Manifest, Provenance, Staging, Store};

/// What one stage did in a run.
#[derive(Debug, Clone, PartialEq)]
pub struct StageRecord {
    /// Stage name.
    pub stage: &'static str,
    /// Artifacts computed in this run.
    pub computed: usize,
    /// Artifacts found in the store.
    pub cached: usize,
    /// Directory of the (last) artifact of the stage.
    pub dir: PathBuf,
}

/// Append the parameter values of `points` to a table: `parameter` (the first component) and,
/// for a vector parameter, one column per component named by `names` — the layout of every
/// table that carries parameter values.
pub(crate) fn with_parameters(mut t: Table, names: &[String], points: &[&[f64]]) -> Table {
    t = t.with("parameter", Column::F64(points.iter().map(|p| p[0]).collect()));
    if names.len() > 1 {
        for (c, name) in names.iter().enumerate() {
            t = t.with(name, Column::F64(points.iter().map(|p| p[c]).collect()));
        }
    }
    t
}

/// Snapshot points of a run: solved now, reused from the store, failed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PointCounts {
    /// Solved (or imported from the old layout) in this run.
    pub solved: usize,
    /// Found in the store.
    pub reused: usize,
    /// Failed to converge (missing; the next run tries them again).
    pub failed: usize,
}

impl PointCounts {
    pub(crate) fn add(&mut self, o: PointCounts) {
        self.solved += o.solved;
        self.reused += o.reused;
        self.failed += o.failed;
    }
}

/// Everything a stage needs from the run. It does not carry the scene: a stage computes from
/// its key struct, its inputs and its `Labels`, all fixed at plan time, so a setting it uses
/// cannot be missing from its key.
#[derive(Debug)]
pub struct Ctx<'a> {
    /// The open store.
    pub store: &'a Store,
    /// The scene's name, recorded in manifests.
    pub scene_name: String,
    /// The command line, recorded in manifests.
    pub command: String,
    /// Progress display.
    pub progress: Progress,
    /// What each stage did.
    pub records: Vec<StageRecord>,
    /// Warnings to show in the summary (e.g. quarantined artifacts).
    pub warnings: Vec<String>,
    /// Snapshot points solved, reused and failed.
    pub points: PointCounts,
    /// Inputs already read in this run ([`loaded`]).
    pub(crate) loaded: std::sync::Arc<loaded::Loaded>,
}

/// The keys of a finished run, for callers and tests.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutput {
    /// Mesh artifact (none for an external scene).
    pub mesh: Option<Key>,
    /// Snapshot artifacts of the training points, in order.
    pub train_snapshots: Vec<Key>,
    /// Training-set artifact.
    pub train: Key,
    /// Test-set artifact (`None`: an external scene whose every column trains).
    pub test: Option<Key>,
    /// Basis artifact.
    pub basis: Key,
    /// Compactness artifact.
    pub compactness: Key,
    /// Generalization artifact.
    pub generalization: Key,
    /// Specificity artifact.
    pub specificity: Key,
    /// Training-set artifacts of the nested levels 1..=K (scenes with nested levels).
    pub nested_sets: Vec<Key>,
    /// Nested-error artifact (scenes with nested levels).
    pub nested: Option<Key>,
    /// Views (XDMF time series) artifacts by subject: `train`, `test`, `nested-k`, `basis`.
    pub views: BTreeMap<String, Key>,
    /// Online ROM artifact.
    pub rom: Option<Key>,
    /// The dual approximations side by side (scenes with `[comparison]`).
    pub comparison: Option<Key>,
    /// Their online solves side by side (online runs of such scenes).
    pub online_comparison: Option<Key>,
    /// The stored reduced model (`crom query`'s), online runs of native scenes.
    pub model: Option<Key>,
    /// Report artifact.
    pub report: Option<Key>,
}

impl<'a> Ctx<'a> {
    /// Look an artifact up; on a miss (or a quarantined corrupt one) compute it with `compute`,
    /// which writes its files into the staging directory and returns summary facts.
    pub(crate) fn cached(
        &mut self,
        kind: ArtifactKind,
        spec: &KeySpec,
        compute: impl FnOnce(&Staging) -> Result<BTreeMap<String, serde_json::Value>, CromError>,
    ) -> Result<(Manifest, bool), CromError> {
        let key = spec.key();
        if let Some(m) = self.lookup(kind, &key)? {
            return Ok((m, false));
        }
        let staging = self.store.stage(spec)?;
        let start = Instant::now();
        let summary = compute(&staging)?;
        let m = self.commit(staging, start.elapsed().as_secs_f64(), summary)?;
        Ok((m, true))
    }

    /// A single-artifact stage: through the cache, with its progress line and its line in the
    /// run summary. Inputs are loaded inside `compute`, so a cache hit reads nothing but the
    /// manifest.
    pub(crate) fn single(
        &mut self,
        kind: ArtifactKind,
        label: &'static str,
        spec: &KeySpec,
        compute: impl FnOnce(&Staging) -> Result<BTreeMap<String, serde_json::Value>, CromError>,
    ) -> Result<Key, CromError> {
        let progress = self.progress.stage(label, 1);
        let (manifest, computed) = self.cached(kind, spec, compute)?;
        progress.finish(if computed { "computed" } else { "cached" });
        self.record(label, usize::from(computed), usize::from(!computed), self.store.dir(kind, &manifest.key));
        Ok(manifest.key)
    }

    /// Verified manifest of a stored artifact, or `None` (after quarantining a corrupt one).
    pub(crate) fn lookup(&mut self, kind: ArtifactKind, key: &Key) -> Result<Option<Manifest>, CromError> {
        match self.store.lookup(kind, key)? {
            Lookup::Hit(m) => Ok(Some(*m)),
            Lookup::Miss => Ok(None),
            Lookup::Quarantined(to, why) => {
                self.warnings.push(format!(
                    "{} artifact {} failed verification ({why}); moved to {} and recomputed",
                    kind.name(),
                    key.short(),
                    to.display()
                ));
                Ok(None)
            }
        }
    }

    /// Commit a staged artifact with this run's provenance.
    pub(crate) fn commit(
        &self,
        staging: Staging,
        wall_seconds: f64,
        summary: BTreeMap<String, serde_json::Value>,
    ) -> Result<Manifest, CromError> {
        let prov = Provenance { scene: self.scene_name.clone(), command: self.command.clone(), wall_seconds, summary };
        staging.commit(self.store, prov)
    }

    /// A context for a stage that runs beside the main loop ([`execute`]): the same store,
    /// scene and loaded inputs, its own records and warnings (merged back by
    /// [`merge`](Self::merge)), and no progress output (its line is printed when it is
    /// joined, so it never breaks into another stage's bar).
    fn beside(&self) -> Ctx<'a> {
        Ctx {
            store: self.store,
            scene_name: self.scene_name.clone(),
            command: self.command.clone(),
            progress: self.progress.silent(),
            records: Vec::new(),
            warnings: Vec::new(),
            points: PointCounts::default(),
            loaded: std::sync::Arc::clone(&self.loaded),
        }
    }

    /// Take in what a context from [`beside`](Self::beside) did.
    fn merge(&mut self, other: Ctx<'_>) {
        for r in other.records {
            self.record(r.stage, r.computed, r.cached, r.dir);
        }
        self.warnings.extend(other.warnings);
        self.points.add(other.points);
    }

    /// Count a stage's artifacts in the run summary (one line per stage name).
    pub(crate) fn record(&mut self, stage: &'static str, computed: usize, cached: usize, dir: PathBuf) {
        match self.records.iter_mut().find(|r| r.stage == stage) {
            Some(r) => {
                r.computed += computed;
                r.cached += cached;
                r.dir = dir;
            }
            None => self.records.push(StageRecord { stage, computed, cached, dir }),
        }
    }
}

/// Solve (or find in the store) every snapshot of the scene's study — training, test and
/// nested points — and stop: `crom solve` (for an external scene: import its snapshots). The
/// other stages are left for `crom run`.
pub fn solve_points(ctx: &mut Ctx<'_>, scene: &SceneConfig) -> Result<(), CromError> {
    // An external scene's snapshots are imported, not solved.
    if let Some(import) = import::ImportStage::plan(scene) {
        use graph::StageDef as _;
        return import.run(ctx, &mut Shared::new(scene)).map(|_| ());
    }
    let mut physics = LazyPhysics::new(scene);
    let labels = Labels::of(scene);
    let mesh_key = mesh::run(ctx, &mut physics, &mesh::spec(scene), &labels)?;
    let family = snapshots::scene_family(scene, &mesh_key);
    for sweep in snapshots::sweeps(scene, &mesh_key) {
        snapshots::run(ctx, &mut physics, &family, &labels, &sweep)?;
    }
    Ok(())
}

/// Before a sharded sweep (under the exclusive lock): the mesh artifact, and the clean-up of
/// what killed writers left in the scene's column family.
pub fn prepare_sweeps(ctx: &mut Ctx<'_>, scene: &SceneConfig) -> Result<(), CromError> {
    external_has_no_sweep(scene, "crom run --executor slurm")?;
    let mut physics = LazyPhysics::new(scene);
    let mesh_key = mesh::run(ctx, &mut physics, &mesh::spec(scene), &Labels::of(scene))?;
    let family = snapshots::scene_family(scene, &mesh_key);
    if let Some(f) = crate::store::columns::ColumnFamily::find(ctx.store.root(), &family)? {
        f.clean_orphans()?;
    }
    Ok(())
}

/// Shard `k` of `n` of the scene's snapshot sweeps, as one of many concurrent workers under the
/// store's shared lock (`crom work --shard K/N`): solve the missing points of the shard's chunks
/// and append their blocks. The mesh artifact is not written (the planner writes it).
pub fn work_shard(ctx: &mut Ctx<'_>, scene: &SceneConfig, k: usize, n: usize) -> Result<PointCounts, CromError> {
    external_has_no_sweep(scene, "crom work")?;
    let mut physics = LazyPhysics::new(scene);
    let mesh_key = mesh::spec(scene).key();
    let sweeps = snapshots::sweeps(scene, &mesh_key);
    let family = snapshots::scene_family(scene, &mesh_key);
    snapshots::work(ctx, &mut physics, &family, &Labels::of(scene), &sweeps, k, n)
}

/// Check every value of a resolved external scene's snapshots, storing nothing (`crom import`).
pub fn check_external_values(scene: &SceneConfig, progress: &Progress) -> Result<(), CromError> {
    match import::ImportStage::plan(scene) {
        Some(import) => import.check_all(progress),
        None => Ok(()),
    }
}

/// An external scene solves nothing: the commands that only solve refuse it.
fn external_has_no_sweep(scene: &SceneConfig, command: &str) -> Result<(), CromError> {
    if scene.model.external().is_none() {
        return Ok(());
    }
    Err(CromError::Usage {
        message: format!(
            "`{command}` solves snapshots, and scene `{}` is external (it has none to solve)",
            scene.scene.name
        ),
        fix: "use `crom run` (locally), which imports the scene's snapshots".into(),
    })
}

/// Run every stage of the scene's study; with `online = false` stop before the online ROM
/// and the report that shows it (`crom run --offline`).
pub fn run_scene(ctx: &mut Ctx<'_>, scene: &SceneConfig, online: bool) -> Result<RunOutput, CromError> {
    execute(ctx, scene, &plan::Plan::of(scene), online)
}

/// The local executor: walk the plan's nodes in order (each node's inputs come before it),
/// running each node's stage with its inputs' keys; a stage whose artifact is stored is a
/// cache hit inside the stage. Every key a stage returns is checked against the plan's.
///
/// The views (XDMF over stored columns: HDF5 metadata, one core, no numerics) run on one
/// worker beside the main loop ([`beside`]) as soon as their inputs exist: the heavy stages
/// after them (the basis' greedy path is mostly sequential) leave a core idle. Before a stage
/// that times solves against each other (the online ROM's trade-off, each online
/// approximation) every job beside is waited for, so the speed-ups are measured on a quiet
/// machine.
/// `scene` builds the high-fidelity model on first use ([`LazyPhysics`]) and nothing else:
/// the stages read their settings from the plan.
pub(crate) fn execute(
    ctx: &mut Ctx<'_>,
    scene: &SceneConfig,
    plan: &plan::Plan,
    online: bool,
) -> Result<RunOutput, CromError> {
    std::thread::scope(|scope| execute_in(scope, ctx, scene, plan, online))
}

fn execute_in<'scope, 'env, 'a: 'env>(
    scope: &'scope std::thread::Scope<'scope, 'env>,
    ctx: &mut Ctx<'a>,
    scene: &'env SceneConfig,
    plan: &'env plan::Plan,
    online: bool,
) -> Result<RunOutput, CromError> {
    if plan.is_external() {
        ctx.progress.note(plan::external_skips(plan.node("mesh").is_some()));
    }
    for line in &plan.skipped {
        ctx.progress.note(line);
    }
    let mut shared = Shared::new(scene);
    let mut keys: BTreeMap<&str, Key> = BTreeMap::new();
    let mut beside = beside::Beside::new(scope);
    // the last node that uses the full-order model: the mesh, the sweeps and the online stages
    let uses_physics = |k: ArtifactKind| {
        matches!(
            k,
            ArtifactKind::Mesh
                | ArtifactKind::Snapshot
                | ArtifactKind::Rom
                | ArtifactKind::OnlineApproximation
                | ArtifactKind::Model
        )
    };
    let last_physics = plan.nodes.iter().rposition(|n| (uses_physics(n.kind) || n.is_sweep()) && (online || !n.online));
    for (at, node) in plan.nodes.iter().enumerate() {
        if last_physics.is_some_and(|last| at > last) {
            // nothing later needs the factored model: free it for the metrics (a 3-D scene's
            // factor and Delassus operator are 1.3 GB at 109 431 dofs)
            shared.physics.release();
        }
        if node.online && !online {
            continue;
        }
        for done in beside.wait_for(&node.inputs) {
            join_beside(ctx, done, &mut keys)?;
        }
        if node.stage.times_solves() {
            // nothing beside a timed comparison of solves
            for done in beside.drain() {
                join_beside(ctx, done, &mut keys)?;
            }
        }
        if node.stage.placement() == graph::Placement::Beside {
            // Reserve the summary line in plan order; the worker adds its counts.
            ctx.record(node.kind.name(), 0, 0, ctx.store.dir(node.kind, &node.key));
            let stage = std::sync::Arc::clone(&node.stage);
            beside.hand(node, ctx.beside(), Box::new(move |sub| stage.run(sub, &mut Shared::new(scene))));
            continue;
        }
        let key = node.stage.run(ctx, &mut shared)?;
        check_key(ctx, node, &key)?;
        keys.insert(node.name.as_str(), key);
    }
    for done in beside.finish() {
        join_beside(ctx, done, &mut keys)?;
    }
    let k = |name: &str| keys[name].clone();
    let n_train = scene.parameter.train_points().len();
    let mut views = BTreeMap::new();
    for node in plan.nodes.iter().filter(|n| n.kind == ArtifactKind::Views) {
        if let Some(key) = keys.get(node.name.as_str()) {
            views.insert(node.name.trim_start_matches("views ").to_string(), key.clone());
        }
    }
    let nested_sets: Vec<Key> =
        plan.node("nested").map(|n| n.inputs.iter().map(|i| keys[i.as_str()].clone()).collect()).unwrap_or_default();
    Ok(RunOutput {
        mesh: keys.get("mesh").cloned(),
        train_snapshots: shared.columns[&0].rows[..n_train].iter().map(|r| r.key.clone()).collect(),
        train: k("trainset train"),
        test: keys.get("trainset test").cloned(),
        basis: k("basis"),
        compactness: k("compactness"),
        generalization: k("generalization"),
        specificity: k("specificity"),
        nested_sets,
        nested: keys.get("nested").cloned(),
        views,
        rom: keys.get("rom").cloned(),
        comparison: keys.get("comparison").cloned(),
        online_comparison: keys.get("online-comparison").cloned(),
        model: keys.get("model").cloned(),
        report: keys.get("report").cloned(),
    })
}

/// A stage's key against its plan's.
fn check_key(ctx: &Ctx<'_>, node: &plan::Node, key: &Key) -> Result<(), CromError> {
    if *key == node.key {
        return Ok(());
    }
    Err(CromError::artifact(
        ctx.store.dir(node.kind, key),
        format!("stage `{}` wrote key {}, its plan says {}", node.name, key.short(), node.key.short()),
        "report this as a bug in crom (the plan and the stage compute the key differently)",
    ))
}

/// A node that ran beside the main loop: print its line, take in its records, check and keep its
/// key.
fn join_beside<'p>(
    ctx: &mut Ctx<'_>,
    (node, (key, sub, secs)): (&'p plan::Node, beside::Done<'_>),
    keys: &mut BTreeMap<&'p str, Key>,
) -> Result<(), CromError> {
    let computed = sub.records.iter().map(|r| r.computed).sum::<usize>() > 0;
    ctx.merge(sub);
    let key = key?;
    ctx.progress.line(node.kind.name(), if computed { "computed beside" } else { "cached" }, secs);
    check_key(ctx, node, &key)?;
    keys.insert(node.name.as_str(), key);
    Ok(())
}

/// What stages of one run hand each other in memory rather than through the store: the
/// high-fidelity model (built on first use), the snapshot sweeps' index rows, the online
/// approximations' shared base.
#[derive(Debug)]
pub(crate) struct Shared<'s> {
    /// The high-fidelity model.
    pub physics: LazyPhysics<'s>,
    /// The index rows of each sweep run so far, by sweep number.
    pub columns: BTreeMap<usize, snapshots::Columns>,
    /// The online approximations' full-order base.
    pub online_base: Option<approximation_online::OnlineBase>,
}

impl<'s> Shared<'s> {
    /// Nothing built yet.
    pub(crate) fn new(scene: &'s SceneConfig) -> Self {
        Self { physics: LazyPhysics::new(scene), columns: BTreeMap::new(), online_base: None }
    }
}

/// The high-fidelity model, built on first use: a fully cached run never meshes or factorises.
#[derive(Debug)]
pub(crate) struct LazyPhysics<'s> {
    scene: &'s SceneConfig,
    built: Option<Physics>,
    /// The full-order solve times at the points of one set (its key), measured on first use.
    fom: Option<(Key, Vec<f64>)>,
    /// The POD of one training set's responses (its key), computed on first use.
    responses: Option<(Key, std::sync::Arc<crate::io::h5::ColMatrix>)>,
    /// The POD of one training set's responses and their translates (its key and the shift).
    translated: Option<((Key, usize), std::sync::Arc<crate::io::h5::ColMatrix>)>,
}

impl<'s> LazyPhysics<'s> {
    /// Nothing built yet.
    pub(crate) fn new(scene: &'s SceneConfig) -> Self {
        Self { scene, built: None, fom: None, responses: None, translated: None }
    }

    /// The full-order solve time at each point of the set `set` (its key; `parameters` its
    /// points), measured on the first call in this process ([`rom::fom_seconds`]) and handed to
    /// every later stage that asks for the same set: the trade-off and the online comparison
    /// then state their speed-ups against one measurement, and the full-order solves are timed
    /// once per run instead of once per stage.
    pub(crate) fn fom_seconds(&mut self, set: &Key, parameters: &[Vec<f64>]) -> Result<Vec<f64>, CromError> {
        if let Some((of, seconds)) = &self.fom {
            if of == set && seconds.len() == parameters.len() {
                return Ok(seconds.clone());
            }
        }
        let seconds = rom::fom_seconds(self.get()?, parameters);
        self.fom = Some((set.clone(), seconds.clone()));
        Ok(seconds)
    }

    /// The primal basis of the online stages, the POD of the responses of the training set
    /// `set` (its key; `train` its data, [`rom::response_basis`]), computed on the first call in
    /// this process and handed to every later stage that asks for the same set: the trade-off,
    /// the online comparison and the stored model each took the same SVD again (0.09 s each
    /// on ironing-fine). `fail` turns the basis's error into the calling stage's.
    pub(crate) fn responses(
        &mut self,
        set: &Key,
        train: &trainset::TrainingSet,
        fail: impl Fn(String) -> CromError,
    ) -> Result<std::sync::Arc<crate::io::h5::ColMatrix>, CromError> {
        if let Some((of, phi)) = &self.responses {
            if of == set {
                return Ok(std::sync::Arc::clone(phi));
            }
        }
        let op = self.get()?.operator().ok_or_else(|| fail(crate::physics::NO_ONLINE_OPERATOR.into()))?;
        let phi = std::sync::Arc::new(rom::response_basis(op, train).map_err(fail)?);
        self.responses = Some((set.clone(), std::sync::Arc::clone(&phi)));
        Ok(phi)
    }

    /// The primal basis of an online solve with `primal_translates = shift`: the POD of the
    /// training set's responses and their translates ([`rom::translated_response_basis`]),
    /// computed on the first call in this process for that set and shift, and handed to the
    /// model stage after the online comparison.
    pub(crate) fn translated_responses(
        &mut self,
        set: &Key,
        train: &trainset::TrainingSet,
        shift: usize,
        fail: impl Fn(String) -> CromError,
    ) -> Result<std::sync::Arc<crate::io::h5::ColMatrix>, CromError> {
        if let Some(((of, k), phi)) = &self.translated {
            if of == set && *k == shift {
                return Ok(std::sync::Arc::clone(phi));
            }
        }
        let phi = std::sync::Arc::new(rom::translated_response_basis(self.get()?, train, shift).map_err(fail)?);
        self.translated = Some(((set.clone(), shift), std::sync::Arc::clone(&phi)));
        Ok(phi)
    }

    /// Drop the built model (it is built again if asked for).
    pub(crate) fn release(&mut self) {
        self.built = None;
    }

    /// The model, building it if needed.
    pub(crate) fn get(&mut self) -> Result<&Physics, CromError> {
        if self.built.is_none() {
            let p = Physics::build(self.scene).map_err(|message| CromError::Numerical {
                stage: "mesh",
                scene: self.scene.scene.name.clone(),
                message,
            })?;
            self.built = Some(p);
        }
        Ok(self.built.as_ref().expect("built above"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The full-order times are measured once per set and handed out again: a second
    /// measurement of wall-clock times would not repeat the first to the bit.
    #[test]
    fn the_full_order_times_are_measured_once_per_set() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        let scene = SceneConfig::load(&dir.join("rope.toml")).expect("shipped scene");
        let mut physics = LazyPhysics::new(&scene);
        let points: Vec<Vec<f64>> = (0..64).map(|k| vec![-0.3 + 0.01 * f64::from(k)]).collect();
        let (a, b) = (Key("a".into()), Key("b".into()));
        let first = physics.fom_seconds(&a, &points).expect("rope");
        assert_eq!(first.len(), points.len());
        assert!(first.iter().all(|&t| t > 0.0 && t.is_finite()));
        assert_eq!(physics.fom_seconds(&a, &points).expect("rope"), first, "the same set is not re-timed");
        let other = physics.fom_seconds(&b, &points).expect("rope");
        assert_ne!(other, first, "another set is timed afresh");
        assert_eq!(physics.fom_seconds(&b, &points).expect("rope"), other);
    }

    /// The response basis is computed once per training set and handed out again (the same
    /// allocation), equal to a direct computation; another set gets its own.
    #[test]
    fn the_response_basis_is_computed_once_per_set() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        let scene = SceneConfig::load(&dir.join("rope.toml")).expect("shipped scene");
        let mut physics = LazyPhysics::new(&scene);
        let set = |gammas: &[f64], physics: &mut LazyPhysics<'_>| {
            let parameters: Vec<Vec<f64>> = gammas.iter().map(|&g| vec![g]).collect();
            let snaps: Vec<_> =
                parameters.iter().map(|mu| physics.get().expect("rope").solve(mu).expect("solves")).collect();
            let u: Vec<&[f64]> = snaps.iter().map(|s| s.u.as_slice()).collect();
            let p: Vec<&[f64]> = snaps.iter().map(|s| s.pressure.as_slice()).collect();
            let rows = (u[0].len(), p[0].len());
            trainset::TrainingSet {
                primal: crate::io::h5::ColMatrix::from_columns(rows.0, &u),
                dual: crate::io::h5::ColMatrix::from_columns(rows.1, &p),
                parameters,
            }
        };
        let (one, two) = (set(&[-0.2, -0.1, 0.0], &mut physics), set(&[-0.25, -0.05], &mut physics));
        let (a, b) = (Key("a".into()), Key("b".into()));
        let fail = |m: String| CromError::Numerical { stage: "rom", scene: "rope".into(), message: m };
        let first = physics.responses(&a, &one, fail).expect("basis");
        let direct =
            rom::response_basis(physics.get().expect("rope").operator().expect("operator"), &one).expect("basis");
        assert_eq!(*first, direct);
        assert!(std::sync::Arc::ptr_eq(&first, &physics.responses(&a, &one, fail).expect("basis")), "not again");
        let other = physics.responses(&b, &two, fail).expect("basis");
        assert!(!std::sync::Arc::ptr_eq(&first, &other), "another set has its own");
        assert_eq!(
            *other,
            rom::response_basis(physics.get().expect("rope").operator().expect("operator"), &two).expect("basis")
        );
    }
}
