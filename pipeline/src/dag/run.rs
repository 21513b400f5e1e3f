//! Running a study: the local executor ([`execute`]), which walks the plan's nodes in order
//! and runs each node's stage, and the command entry points that run part of it (`crom solve`,
//! `crom work`, the Slurm planner's preparation, `crom import`'s check). The plan, the stages
//! and the context are below it; nothing below imports it.

use std::collections::BTreeMap;

use crom_schemas::artifact::ArtifactKind;
use crom_schemas::SceneConfig;

use super::ctx::{Ctx, PointCounts};
use super::graph::{self, StageDef as _};
use super::labels::Labels;
use super::shared::{LazyPhysics, Shared};
use super::{beside, import, mesh, plan, snapshots};
use crate::cache::Key;
use crate::error::CromError;
use crate::progress::Progress;

/// One node of a finished run: its name in the plan, its artifact's kind and key, and the names
/// its stage publishes.
#[derive(Debug, Clone, PartialEq)]
pub struct Finished {
    /// The node's name, e.g. `trainset train`, `views basis`.
    pub node: String,
    /// Its artifact's kind.
    pub kind: ArtifactKind,
    /// Its artifact's key.
    pub key: Key,
    /// The names a finished study gives its files.
    pub(crate) published: Vec<graph::Published>,
}

/// What a finished run made: every node that ran, in plan order (the online ones only in an
/// online run). The plan fills it; no field names a stage.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunOutput {
    /// The nodes, in plan order.
    pub nodes: Vec<Finished>,
}

impl RunOutput {
    /// The key of the node `name`, if it ran.
    pub fn key(&self, name: &str) -> Option<&Key> {
        self.nodes.iter().find(|n| n.node == name).map(|n| &n.key)
    }
}

/// Solve (or find in the store) every snapshot of the scene's study — training, test and
/// nested points — and stop: `crom solve` (for an external scene: import its snapshots). The
/// other stages are left for `crom run`.
pub fn solve_points(ctx: &mut Ctx<'_>, scene: &SceneConfig) -> Result<(), CromError> {
    // An external scene's snapshots are imported, not solved.
    if let Some(import) = import::ImportStage::plan(scene) {
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
            ArtifactKind::MESH
                | ArtifactKind::SNAPSHOT
                | ArtifactKind::ROM
                | ArtifactKind::ONLINE_APPROXIMATION
                | ArtifactKind::MODEL
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
    let nodes = plan
        .nodes
        .iter()
        .filter_map(|n| {
            let key = keys.get(n.name.as_str())?.clone();
            Some(Finished { node: n.name.clone(), kind: n.kind, key, published: n.stage.published() })
        })
        .collect();
    Ok(RunOutput { nodes })
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

#[cfg(test)]
mod tests {
    use super::{run_scene, Ctx};
    use crate::store::Store;
    use crom_schemas::SceneConfig;

    fn ctx<'a>(store: &'a Store, scene: &'a SceneConfig) -> Ctx<'a> {
        Ctx::new(store, &scene.scene.name, "test".into(), true)
    }

    /// A cold run of the rope reads the training set, the test set and the bases once each
    /// (basis, compactness, generalization, specificity, rom and report share them); a second,
    /// fully cached run reads none.
    #[test]
    fn a_run_reads_each_input_once_and_a_cached_run_none() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/rope.toml");
        let scene = SceneConfig::load(&root).expect("rope.toml");
        let store = Store::open(dir.path()).expect("store");
        let mut c = ctx(&store, &scene);
        run_scene(&mut c, &scene, true).expect("cold run");
        assert_eq!(c.loaded.counts(), (2, 1));
        let mut c = ctx(&store, &scene);
        run_scene(&mut c, &scene, true).expect("cached run");
        assert_eq!(c.loaded.counts(), (0, 0));
    }
}
