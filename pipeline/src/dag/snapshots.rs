//! Snapshot stage: one high-fidelity solve per parameter point, stored as one column of the
//! scene's column family ([`crate::store::columns`]). A snapshot's key is its mesh, its solver
//! settings and its parameter value — not the set it belongs to — so training, test and nested
//! sets share solves, a denser grid reuses every point it shares with a coarser one, and a killed
//! sweep resumes with exactly the missing points. Missing points are solved in parallel (rayon);
//! results are gathered on this thread into the blocks of their chunks ([`Sweep`]), each
//! committed atomically as soon as its last point is in, so a kill loses at most the chunks in
//! flight. Many workers may share a sweep ([`work`], `crom work --shard K/N`): each solves the
//! chunks of its shard and appends their blocks, and the blocks are the ones a single process
//! would have written.
//!
//! Stores written before the columnar layout hold one `snapshot/<key>/` directory per point:
//! such a point is imported into a block (verified against its manifest) instead of solved again.

use std::collections::HashMap;
use std::sync::mpsc;
use std::time::Instant;

use crom_schemas::artifact::{snapshot as names, ArtifactKind};
use crom_schemas::scene::SolverSpec;
use crom_schemas::SceneConfig;
use crom_stages::snapshot::{Snapshot, SolveStats};
use rayon::prelude::*;
use serde::Serialize;

use super::ctx::Ctx;
use super::ctx::PointCounts;
use super::graph::{Input, StageDef};
use super::labels::Labels;
use super::shared::Columns;
use super::shared::LazyPhysics;
use super::shared::Shared;
use crate::cache::{params, Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5In;
use crate::io::table::{Column, Table};
use crate::store::columns::{ColumnFamily, Evidence, FamilyMeta, Index, PendingColumn, COLUMNS_SCHEMA_VERSION};
use crate::store::Lookup;

/// Bump when the solvers change the numbers they produce.
/// 2: the vertex-zone rule (docs/design-notes.md#the-vertex-zone-rule) changes the snapshots near sole vertices, and the
/// index gains the geometric check.
/// 3: the stored equilibrium residual of the 2-D scenes is a backward error (`contact::solve`).
const ALGORITHM_VERSION: u32 = 3;

/// The version of the node-to-surface rule's arithmetic in a 3-D scene's keys (absent from a
/// 2-D scene's, whose keys stay as they were): 2, the normal projection stops at its rounding
/// floor instead of running out its 25 Newton steps (`crom_stages::contact3d::surface`; the
/// same pairs, answers that move by rounding).
const NODE_TO_SURFACE: u32 = 2;

/// [`NODE_TO_SURFACE`] for a 3-D scene, nothing for a 2-D one.
fn node_to_surface(scene: &SceneConfig) -> Option<u32> {
    scene.model.is_3d().then_some(NODE_TO_SURFACE)
}

/// A block is committed when it holds about this many bytes of snapshot data...
const BLOCK_BYTES: usize = 32 << 20;

/// A scalar parameter keeps the key layout it always had (`parameter: f64`), so stores of 1-D
/// studies stay valid; a vector parameter is keyed by all its components.
#[derive(Serialize)]
struct SnapshotParams<'a> {
    parameter: f64,
    solver: &'a SolverSpec,
    #[serde(skip_serializing_if = "Option::is_none")]
    node_to_surface: Option<u32>,
}

#[derive(Serialize)]
struct VectorSnapshotParams<'a> {
    parameters: &'a [f64],
    solver: &'a SolverSpec,
    #[serde(skip_serializing_if = "Option::is_none")]
    node_to_surface: Option<u32>,
}

#[derive(Serialize)]
struct FamilyParams<'a> {
    family: &'static str,
    solver: &'a SolverSpec,
    parameters: Vec<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    node_to_surface: Option<u32>,
}

impl StageKey for SnapshotParams<'_> {
    const KIND: ArtifactKind = ArtifactKind::SNAPSHOT;
    const ALGORITHM_VERSION: u32 = ALGORITHM_VERSION;
}

impl StageKey for VectorSnapshotParams<'_> {
    const KIND: ArtifactKind = ArtifactKind::SNAPSHOT;
    const ALGORITHM_VERSION: u32 = ALGORITHM_VERSION;
}

/// The key spec of the snapshot at the parameter point `mu` on the mesh `mesh`
/// (`node_to_surface`: [`NODE_TO_SURFACE`] for a 3-D scene).
pub(crate) fn spec(mesh: &Key, solver: &SolverSpec, mu: &[f64], node_to_surface: Option<u32>) -> KeySpec {
    let spec = match mu {
        [parameter] => KeySpec::of(&SnapshotParams { parameter: *parameter, solver, node_to_surface }),
        _ => KeySpec::of(&VectorSnapshotParams { parameters: mu, solver, node_to_surface }),
    };
    spec.input("mesh", mesh)
}

/// The key of the column family holding every snapshot of this mesh and solver.
pub(crate) fn family_key(
    mesh: &Key,
    solver: &SolverSpec,
    parameter_names: &[&str],
    node_to_surface: Option<u32>,
) -> Key {
    let p = FamilyParams { family: "columns", solver, parameters: parameter_names.to_vec(), node_to_surface };
    let mut spec = KeySpec::new(ArtifactKind::SNAPSHOT, ALGORITHM_VERSION, params(&p)).input("mesh", mesh);
    spec.schema_version = COLUMNS_SCHEMA_VERSION;
    spec.key()
}

/// Snapshots per block: about [`BLOCK_BYTES`] of data and at most [`MAX_BLOCK_COLUMNS`], or
/// `CROM_BLOCK_COLUMNS` if set (a storage knob: it changes no key and no result, only how
/// much work a kill can lose and how finely a sweep can be sharded). Sized from the scene
/// alone ([`crate::resources::snapshot_rows`]), so that a planner and every worker agree on the
/// chunks without meshing.
pub(crate) fn chunk_columns(scene: &SceneConfig) -> usize {
    if let Some(n) = std::env::var("CROM_BLOCK_COLUMNS").ok().and_then(|v| v.parse::<usize>().ok()).filter(|&n| n > 0) {
        return n.min(4096);
    }
    let (n, c) = crate::resources::snapshot_rows(scene);
    let by_bytes = BLOCK_BYTES as f64 / (8.0 * (n + c).max(1.0));
    (by_bytes.floor() as usize).clamp(1, MAX_BLOCK_COLUMNS)
}

/// At most this many snapshots per block: bounds the work a kill loses on fast meshes.
const MAX_BLOCK_COLUMNS: usize = 128;

type Solved = (usize, usize, Result<Snapshot, String>, f64);

/// `name = value` of every component, for progress lines and error messages.
pub(crate) fn point_label(names: &[String], mu: &[f64]) -> String {
    names.iter().zip(mu).map(|(n, v)| format!("{n} = {v}")).collect::<Vec<_>>().join(", ")
}

/// One sweep of the study: its points in the order their rows are handed on, their content
/// keys, and its **chunks** — the points it is the first sweep to list, in order, cut into
/// runs of [`chunk_columns`]. A chunk's missing points are solved together and committed as
/// one block, so the blocks of a study are a function of the scene and of what the store
/// already holds, never of thread timing or of which process solved them: a sweep run
/// locally, killed and resumed, or sharded over many workers writes the same block files.
#[derive(Debug, Clone)]
pub(crate) struct Sweep {
    /// `train+test` or `nested`.
    pub name: &'static str,
    /// Points, in order (a point may repeat).
    pub points: Vec<Vec<f64>>,
    /// Content key of each point.
    pub keys: Vec<Key>,
    /// Indices into `points` of each chunk.
    pub chunks: Vec<Vec<usize>>,
}

/// The sweeps of a scene's study on the mesh `mesh`: the training and test points, then the
/// points of the nested levels (if any) that the first sweep does not list.
pub(crate) fn sweeps(scene: &SceneConfig, mesh: &Key) -> Vec<Sweep> {
    let p = &scene.parameter;
    let mut lists: Vec<(&'static str, Vec<Vec<f64>>)> =
        vec![("train+test", p.train_points().into_iter().chain(p.test_points()).collect())];
    if p.nested_levels > 0 {
        lists.push(("nested", (1..=p.nested_levels).flat_map(|n| p.nested_points(n)).collect()));
    }
    let per_chunk = chunk_columns(scene);
    let mut seen: std::collections::HashSet<Key> = std::collections::HashSet::new();
    lists
        .into_iter()
        .map(|(name, points)| {
            let keys: Vec<Key> =
                points.iter().map(|mu| spec(mesh, &scene.solver, mu, node_to_surface(scene)).key()).collect();
            let novel: Vec<usize> = (0..keys.len()).filter(|&i| seen.insert(keys[i].clone())).collect();
            let chunks = novel.chunks(per_chunk).map(<[usize]>::to_vec).collect();
            Sweep { name, points, keys, chunks }
        })
        .collect()
}

/// Shard `k` of `n` of a list of `total` chunks: the contiguous range `[k t / n, (k+1) t / n)`.
pub(crate) fn shard_range(total: usize, k: usize, n: usize) -> std::ops::Range<usize> {
    (k * total / n)..((k + 1) * total / n)
}

/// The key of this scene's column family on the mesh `mesh`.
pub(crate) fn scene_family(scene: &SceneConfig, mesh: &Key) -> Key {
    let names = scene.parameter.names();
    family_key(mesh, &scene.solver, &names.iter().map(|s| &**s).collect::<Vec<&str>>(), node_to_surface(scene))
}

/// The family's index as it stands (empty when the family does not exist yet).
pub(crate) fn load_index(root: &std::path::Path, family: &Key) -> Result<(Option<ColumnFamily>, Index), CromError> {
    let family = ColumnFamily::find(root, family)?;
    let index = match &family {
        Some(f) => f.load_index()?,
        None => Index::default(),
    };
    Ok((family, index))
}

/// Snapshot sweep `number` of the plan: its points' columns in the scene's column family (the
/// node's key is the family's). Hands its index rows on in memory ([`Shared::columns`]).
#[derive(Debug)]
pub(crate) struct SweepStage {
    pub number: usize,
    pub sweep: Sweep,
    pub mesh: Input,
    pub family: Key,
    pub labels: Labels,
}

impl StageDef for SweepStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::SNAPSHOT
    }
    fn key(&self) -> Key {
        self.family.clone()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.mesh]
    }
    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let columns = run(ctx, &mut shared.physics, &self.family, &self.labels, &self.sweep)?;
        shared.columns.insert(self.number, columns);
        Ok(self.family.clone())
    }
}

/// Ensure a stored column exists for every point of `sweep` in the column family `fkey`; their
/// index rows in its order. Holds the store's exclusive lock: cleans up after killed writers
/// and compacts the index.
pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    fkey: &Key,
    labels: &Labels,
    sweep: &Sweep,
) -> Result<Columns, CromError> {
    let (mut family, mut index) = load_index(ctx.store.root(), fkey)?;
    // Orphans (blocks without a fragment, temporary files) are never in the index: removing them
    // after reading it changes nothing it holds.
    if let Some(f) = &family {
        f.clean_orphans()?;
    }
    if index.dropped > 0 {
        ctx.warnings.push(format!(
            "{} stored snapshots point at missing or damaged blocks and were solved again",
            index.dropped
        ));
    }
    let uncompacted = index.fragments;
    // Reused: distinct points of the sweep already stored (also those an earlier sweep listed).
    let distinct: std::collections::HashSet<&Key> = sweep.keys.iter().collect();
    let reused = distinct.iter().filter(|k| index.rows.contains_key(**k)).count();
    let all: Vec<usize> = (0..sweep.chunks.len()).collect();
    let done = solve_chunks(ctx, physics, (fkey, labels), &mut family, &mut index, sweep, &all)?;
    if let (Some(f), true) = (&family, done.committed + uncompacted > 0) {
        f.compact(&index)?;
    }
    let dir = family.as_ref().map(|f| f.dir().to_path_buf()).unwrap_or_default();
    ctx.record("snapshot", done.solved, reused, dir);
    ctx.points.add(PointCounts { solved: done.solved, reused, failed: done.failures.len() });
    if !done.failures.is_empty() {
        return Err(failure_error(ctx, labels, &done.failures, sweep, done.solved + done.failures.len())?);
    }
    let family = family.ok_or_else(|| {
        CromError::artifact(ctx.store.root(), "no snapshot was stored for this scene", "rerun the scene")
    })?;
    let rows = sweep
        .keys
        .iter()
        .map(|k| {
            index.rows.get(k).cloned().ok_or_else(|| {
                CromError::artifact(family.dir(), format!("snapshot {} is not in the index", k.short()), "rerun")
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Columns { rows, shape: (family.meta().n_dof, family.meta().n_contact) })
}

/// A shard of a study's sweeps, as one of many concurrent workers (`crom work --shard K/N`,
/// under the store's shared lock): the chunks of every sweep, numbered in order, split into
/// `n` contiguous ranges; solve the missing points of range `k`. Appends blocks and index
/// fragments only. Returns what it did; failed points are an error naming them.
pub(crate) fn work(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    fkey: &Key,
    labels: &Labels,
    sweeps: &[Sweep],
    k: usize,
    n: usize,
) -> Result<PointCounts, CromError> {
    let (mut family, mut index) = load_index(ctx.store.root(), fkey)?;
    let total: usize = sweeps.iter().map(|s| s.chunks.len()).sum();
    let mine = shard_range(total, k, n);
    let mut counts = PointCounts::default();
    let mut first = 0;
    for sweep in sweeps {
        let ids: Vec<usize> = (0..sweep.chunks.len()).filter(|c| mine.contains(&(first + c))).collect();
        first += sweep.chunks.len();
        if ids.is_empty() {
            continue;
        }
        let done = solve_chunks(ctx, physics, (fkey, labels), &mut family, &mut index, sweep, &ids)?;
        counts.add(PointCounts { solved: done.solved, reused: done.cached, failed: done.failures.len() });
        ctx.record(
            "snapshot",
            done.solved,
            done.cached,
            family.as_ref().map(|f| f.dir().to_path_buf()).unwrap_or_default(),
        );
        if !done.failures.is_empty() {
            ctx.points.add(counts);
            return Err(failure_error(ctx, labels, &done.failures, sweep, done.solved + done.failures.len())?);
        }
    }
    ctx.points.add(counts);
    Ok(counts)
}

/// What [`solve_chunks`] did.
struct Done {
    solved: usize,
    cached: usize,
    committed: usize,
    failures: Vec<(usize, String)>,
}

/// Solve the missing points of the chunks `ids` of `sweep` (in parallel), committing each
/// chunk's block to the family `fkey` as soon as all its points are in.
fn solve_chunks(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    (fkey, labels): (&Key, &Labels),
    family: &mut Option<ColumnFamily>,
    index: &mut Index,
    sweep: &Sweep,
    ids: &[usize],
) -> Result<Done, CromError> {
    let names = &labels.names;
    let (points, keys) = (&sweep.points, &sweep.keys);
    // Missing points per chunk (a point already in the index, or imported, is not solved).
    let mut cached = 0;
    let mut imported: Vec<PendingColumn> = Vec::new();
    let mut todo: Vec<(usize, Vec<usize>)> = Vec::new();
    for &c in ids {
        let mut missing = Vec::new();
        for &i in &sweep.chunks[c] {
            if index.rows.contains_key(&keys[i]) {
                cached += 1;
            } else if let Some(col) = import_old_layout(ctx, &keys[i], &points[i]) {
                imported.push(col);
            } else {
                missing.push(i);
            }
        }
        if !missing.is_empty() {
            todo.push((c, missing));
        }
    }
    // Repeated points of the sweep that no chunk lists count as reused, as before.
    let n_missing: usize = todo.iter().map(|t| t.1.len()).sum();
    let mut progress = ctx.progress.stage("snapshot", n_missing);
    let mut failures: Vec<(usize, String)> = Vec::new();
    let mut write_error: Option<CromError> = None;
    let mut committed = 0usize;
    let n_imported = imported.len();
    let scene_name = labels.scene.clone();
    let root = ctx.store.root().to_path_buf();
    if n_missing > 0 || !imported.is_empty() {
        let phys = physics.get()?;
        let units = phys.units();
        let mut commit = |family: &mut Option<ColumnFamily>,
                          index: &mut Index,
                          pending: &mut Vec<PendingColumn>|
         -> Result<(), CromError> {
            if pending.is_empty() {
                return Ok(());
            }
            if family.is_none() {
                let first = &pending[0];
                let meta = FamilyMeta {
                    schema_version: COLUMNS_SCHEMA_VERSION,
                    family: fkey.clone(),
                    scene: scene_name.clone(),
                    n_dof: first.primal.len(),
                    n_contact: first.dual.len(),
                    parameter_names: names.clone(),
                    units: [units.primal.to_string(), units.dual.to_string()],
                };
                *family = Some(ColumnFamily::open(&root, meta)?);
            }
            let fam = family.as_ref().expect("created above");
            for row in fam.commit_block(pending)? {
                index.rows.insert(row.key.clone(), row);
            }
            committed += 1;
            pending.clear();
            Ok(())
        };
        commit(family, index, &mut imported)?;
        // Per chunk: columns in, and points still to come.
        let mut pending: HashMap<usize, (Vec<PendingColumn>, usize)> =
            todo.iter().map(|(c, m)| (*c, (Vec::new(), m.len()))).collect();
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel::<Solved>();
            let work: Vec<(usize, usize)> = todo.iter().flat_map(|(c, m)| m.iter().map(move |&i| (*c, i))).collect();
            s.spawn(move || {
                work.par_iter().for_each_with(tx, |tx, &(c, i)| {
                    let t = Instant::now();
                    let r = phys.solve(&points[i]);
                    let _ = tx.send((c, i, r, t.elapsed().as_secs_f64()));
                });
            });
            for (c, i, r, secs) in rx {
                progress.inc(&point_label(names, &points[i]));
                let slot = pending.get_mut(&c).expect("a planned chunk");
                slot.1 -= 1;
                match r {
                    Ok(snap) if write_error.is_none() => slot.0.push(PendingColumn {
                        key: keys[i].clone(),
                        parameters: points[i].clone(),
                        evidence: evidence(&snap.stats, secs),
                        primal: snap.u,
                        dual: snap.pressure,
                    }),
                    Ok(_) => {}
                    Err(msg) => failures.push((i, msg)),
                }
                if slot.1 == 0 && write_error.is_none() {
                    if let Err(e) = commit(family, index, &mut slot.0) {
                        write_error = Some(e);
                    }
                }
            }
        });
    }
    let solved = n_missing - failures.len();
    let mut outcome = format!("{solved} solved, {cached} reused, {} failed", failures.len());
    if n_imported > 0 {
        outcome.push_str(&format!(", {n_imported} imported from the old layout"));
    }
    progress.finish(&outcome);
    if let Some(e) = write_error {
        return Err(e);
    }
    failures.sort_by_key(|f| f.0);
    Ok(Done { solved: solved + n_imported, cached, committed, failures })
}

/// The error of a sweep with failed points (of `attempted` solves), after writing them to the
/// run's failure table.
fn failure_error(
    ctx: &Ctx<'_>,
    labels: &Labels,
    failures: &[(usize, String)],
    sweep: &Sweep,
    attempted: usize,
) -> Result<CromError, CromError> {
    let names = &labels.names;
    let table_path = write_failures(ctx, labels, failures, &sweep.points, &sweep.keys)?;
    let list = failures
        .iter()
        .map(|(i, m)| format!("  {}: {m}", point_label(names, &sweep.points[*i])))
        .collect::<Vec<_>>()
        .join("\n");
    Ok(CromError::SolveFailures {
        scene: labels.scene.clone(),
        failed: failures.len(),
        total: attempted,
        list,
        table: table_path,
    })
}

fn evidence(s: &SolveStats, seconds: f64) -> Evidence {
    Evidence {
        iterations: s.iterations as u64,
        active: s.active as u64,
        vertex_ties: s.vertex_ties as u64,
        vertex_nodes: s.vertex_nodes.clone(),
        vertex_rounds: s.vertex_rounds as u64,
        min_gap: s.min_gap,
        active_gap: s.active_gap,
        cone_angle: s.cone_angle,
        max_penetration: s.max_penetration,
        min_lambda: s.min_lambda,
        complementarity: s.complementarity,
        kkt_residual: s.kkt_residual,
        seconds,
    }
}

/// A snapshot stored by the per-directory layout (`snapshot/<key>/snapshot.h5`), verified
/// against its manifest, as a column to commit; `None` when absent or damaged.
fn import_old_layout(ctx: &mut Ctx<'_>, key: &Key, p: &[f64]) -> Option<PendingColumn> {
    let dir = ctx.store.dir(ArtifactKind::SNAPSHOT, key);
    if !dir.exists() {
        return None;
    }
    let manifest = match ctx.store.lookup(ArtifactKind::SNAPSHOT, key) {
        Ok(Lookup::Hit(m)) => m,
        _ => return None,
    };
    let f = H5In::open(&dir.join(names::FILE)).ok()?;
    let s = &manifest.summary;
    let u = |n: &str| s.get(n).and_then(serde_json::Value::as_u64).unwrap_or(0);
    let x = |n: &str| s.get(n).and_then(serde_json::Value::as_f64).unwrap_or(f64::NAN);
    Some(PendingColumn {
        key: key.clone(),
        parameters: p.to_vec(),
        primal: f.vec_f64(names::U).ok()?,
        dual: f.vec_f64(names::PRESSURE).ok()?,
        evidence: Evidence {
            iterations: u("iterations"),
            active: u("active"),
            vertex_ties: u("vertex_ties"),
            vertex_nodes: s.get("vertex_nodes").and_then(serde_json::Value::as_str).unwrap_or_default().to_string(),
            vertex_rounds: u("vertex_rounds"),
            min_gap: x("min_gap"),
            active_gap: x("active_gap"),
            cone_angle: x("cone_angle"),
            max_penetration: x("max_penetration"),
            min_lambda: x("min_lambda"),
            complementarity: x("complementarity"),
            kkt_residual: x("kkt_residual"),
            seconds: x("seconds"),
        },
    })
}

/// The failed points of this run as `<store>/runs/<scene>/solver_failures.parquet` (replaced by
/// each run that has failures; written under a temporary name and renamed). Failures are not
/// cached: the next run tries those points again.
fn write_failures(
    ctx: &Ctx<'_>,
    labels: &Labels,
    failures: &[(usize, String)],
    points: &[Vec<f64>],
    keys: &[Key],
) -> Result<std::path::PathBuf, CromError> {
    let dir = crate::store::fs::named_dir(ctx.store.root(), "runs", &labels.scene)?;
    std::fs::create_dir_all(&dir).map_err(|e| CromError::io(&dir, "creating the run directory", e))?;
    let n = failures.len();
    let table = Table::default().with("scene", Column::Str(vec![labels.scene.clone(); n]));
    let failed: Vec<&[f64]> = failures.iter().map(|f| points[f.0].as_slice()).collect();
    let table = super::ctx::with_parameters(table, &labels.names, &failed)
        .with("snapshot_key", Column::Str(failures.iter().map(|f| keys[f.0].0.clone()).collect()))
        .with("error", Column::Str(failures.iter().map(|f| f.1.clone()).collect()));
    // Workers on several hosts may write this at once: a name unique to host and process.
    let tmp = dir.join(format!(".solver_failures.{}.tmp", crate::store::fs::writer_token()));
    table.write_parquet(&tmp)?;
    let path = dir.join("solver_failures.parquet");
    std::fs::rename(&tmp, &path).map_err(|e| CromError::io(&path, "moving the failure table into place", e))?;
    Ok(path)
}
