//! Snapshot stage: one high-fidelity solve per parameter point, stored as one column of the
//! scene's column family ([`crate::store::columns`]). A snapshot's key is its mesh, its solver
//! settings and its parameter value — not the set it belongs to — so training, test and nested
//! sets share solves, a denser grid reuses every point it shares with a coarser one, and a killed
//! sweep resumes with exactly the missing points. Missing points are solved in parallel (rayon);
//! results are gathered on this thread into blocks, each committed atomically as soon as it is
//! full (or a few seconds old), so a kill loses at most one block of work.
//!
//! Stores written before the columnar layout hold one `snapshot/<key>/` directory per point:
//! such a point is imported into a block (verified against its manifest) instead of solved again.

use std::collections::HashMap;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crom_schemas::artifact::{snapshot as names, ArtifactKind};
use crom_schemas::scene::SolverSpec;
use crom_stages::snapshot::{Snapshot, SolveStats};
use rayon::prelude::*;
use serde::Serialize;

use super::{Ctx, LazyPhysics, PointCounts};
use crate::cache::{params, Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5In;
use crate::io::table::{Column, Table};
use crate::store::columns::{
    ColumnFamily, Evidence, FamilyMeta, Index, IndexRow, PendingColumn, COLUMNS_SCHEMA_VERSION,
};
use crate::store::Lookup;

/// Bump when the solvers change the numbers they produce.
/// 2: the vertex-zone rule (design note 27) changes the snapshots near sole vertices, and the
/// index gains the geometric check.
const ALGORITHM_VERSION: u32 = 2;

/// A block is committed when it holds about this many bytes of snapshot data...
const BLOCK_BYTES: usize = 32 << 20;
/// ...or when its oldest column has waited this long.
const BLOCK_AGE: Duration = Duration::from_secs(5);

/// A scalar parameter keeps the key layout it always had (`parameter: f64`), so stores of 1-D
/// studies stay valid; a vector parameter is keyed by all its components.
#[derive(Serialize)]
struct SnapshotParams<'a> {
    parameter: f64,
    solver: &'a SolverSpec,
}

#[derive(Serialize)]
struct VectorSnapshotParams<'a> {
    parameters: &'a [f64],
    solver: &'a SolverSpec,
}

#[derive(Serialize)]
struct FamilyParams<'a> {
    family: &'static str,
    solver: &'a SolverSpec,
    parameters: Vec<&'a str>,
}

impl StageKey for SnapshotParams<'_> {
    const KIND: ArtifactKind = ArtifactKind::Snapshot;
    const ALGORITHM_VERSION: u32 = ALGORITHM_VERSION;
}

impl StageKey for VectorSnapshotParams<'_> {
    const KIND: ArtifactKind = ArtifactKind::Snapshot;
    const ALGORITHM_VERSION: u32 = ALGORITHM_VERSION;
}

/// The key spec of the snapshot at the parameter point `mu` on the mesh `mesh`.
pub(crate) fn spec(mesh: &Key, solver: &SolverSpec, mu: &[f64]) -> KeySpec {
    let spec = match mu {
        [parameter] => KeySpec::of(&SnapshotParams { parameter: *parameter, solver }),
        _ => KeySpec::of(&VectorSnapshotParams { parameters: mu, solver }),
    };
    spec.input("mesh", mesh)
}

/// The key of the column family holding every snapshot of this mesh and solver.
pub(crate) fn family_key(mesh: &Key, solver: &SolverSpec, parameter_names: &[&str]) -> Key {
    let p = FamilyParams { family: "columns", solver, parameters: parameter_names.to_vec() };
    let mut spec = KeySpec::new(ArtifactKind::Snapshot, ALGORITHM_VERSION, params(&p)).input("mesh", mesh);
    spec.schema_version = COLUMNS_SCHEMA_VERSION;
    spec.key()
}

/// Snapshots per block: about [`BLOCK_BYTES`] of data, or `CROM_BLOCK_COLUMNS` if set (a storage
/// knob: it changes no key and no result, only how much work a kill can lose).
fn block_columns(rows: (usize, usize)) -> usize {
    std::env::var("CROM_BLOCK_COLUMNS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| BLOCK_BYTES / (8 * (rows.0 + rows.1).max(1)))
        .clamp(1, 4096)
}

type Solved = (usize, Result<Snapshot, String>, f64);

/// `name = value` of every component, for progress lines and error messages.
pub(crate) fn point_label(names: &[String], mu: &[f64]) -> String {
    names.iter().zip(mu).map(|(n, v)| format!("{n} = {v}")).collect::<Vec<_>>().join(", ")
}

/// What the snapshot stage hands on: the index rows of the requested points, in order.
#[derive(Debug, Clone)]
pub(crate) struct Columns {
    /// One row per requested point (the same row twice for a repeated point).
    pub rows: Vec<IndexRow>,
    /// Rows of the family's block files (n_dof, n_contact).
    pub shape: (usize, usize),
}

/// Ensure a stored column exists for every point; their index rows in the order of `points`.
pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    mesh: &Key,
    points: &[Vec<f64>],
) -> Result<Columns, CromError> {
    let names: Vec<String> = ctx.scene.parameter.names().iter().map(|s| s.to_string()).collect();
    let fkey = family_key(mesh, &ctx.scene.solver, &names.iter().map(String::as_str).collect::<Vec<_>>());
    let keys: Vec<Key> = points.iter().map(|p| spec(mesh, &ctx.scene.solver, p).key()).collect();
    let mut family = ColumnFamily::find(ctx.store.root(), &fkey)?;
    let mut index = match &family {
        Some(f) => {
            f.clean_orphans()?;
            f.load_index()?
        }
        None => Index::default(),
    };
    if index.dropped > 0 {
        ctx.warnings.push(format!(
            "{} stored snapshots point at missing or damaged blocks and were solved again",
            index.dropped
        ));
    }
    let mut first_of: HashMap<&Key, usize> = HashMap::new();
    let mut missing = Vec::new();
    let mut cached = 0;
    for (i, k) in keys.iter().enumerate() {
        if first_of.insert(k, i).is_some() {
            continue; // the same point twice in the sweep: one solve
        }
        if index.rows.contains_key(k) {
            cached += 1;
        } else {
            missing.push(i);
        }
    }
    let mut pending: Vec<PendingColumn> = Vec::new();
    let mut imported = 0;
    missing.retain(|&i| match import_old_layout(ctx, &keys[i], &points[i]) {
        Some(col) => {
            pending.push(col);
            imported += 1;
            false
        }
        None => true,
    });
    let mut progress = ctx.progress.stage("snapshot", missing.len());
    let mut failures: Vec<(usize, String)> = Vec::new();
    let mut write_error: Option<CromError> = None;
    let computed = missing.len();
    let mut committed = 0usize;
    let scene_name = ctx.scene.scene.name.clone();
    let root = ctx.store.root().to_path_buf();
    if !missing.is_empty() || !pending.is_empty() {
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
        if !pending.is_empty() {
            commit(&mut family, &mut index, &mut pending)?;
        }
        let n_rows = phys.mesh_rows();
        let per_block = block_columns(n_rows);
        let mut oldest: Option<Instant> = None;
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel::<Solved>();
            let work = std::mem::take(&mut missing);
            s.spawn(move || {
                work.par_iter().for_each_with(tx, |tx, &i| {
                    let t = Instant::now();
                    let r = phys.solve(&points[i]);
                    let _ = tx.send((i, r, t.elapsed().as_secs_f64()));
                });
            });
            for (i, r, secs) in rx {
                progress.inc(&point_label(&names, &points[i]));
                match r {
                    Ok(snap) if write_error.is_none() => {
                        pending.push(PendingColumn {
                            key: keys[i].clone(),
                            parameters: points[i].clone(),
                            evidence: evidence(&snap.stats, secs),
                            primal: snap.u,
                            dual: snap.pressure,
                        });
                        let first = *oldest.get_or_insert_with(Instant::now);
                        if pending.len() >= per_block || first.elapsed() >= BLOCK_AGE {
                            if let Err(e) = commit(&mut family, &mut index, &mut pending) {
                                write_error = Some(e);
                            }
                            oldest = None;
                        }
                    }
                    Ok(_) => {}
                    Err(msg) => failures.push((i, msg)),
                }
            }
        });
        if write_error.is_none() {
            if let Err(e) = commit(&mut family, &mut index, &mut pending) {
                write_error = Some(e);
            }
        }
        if let (Some(f), true) = (&family, committed > 0 && write_error.is_none()) {
            f.compact(&index)?;
        }
    }
    let solved = computed - failures.len();
    let mut outcome = format!("{solved} solved, {cached} reused, {} failed", failures.len());
    if imported > 0 {
        outcome.push_str(&format!(", {imported} imported from the old layout"));
    }
    progress.finish(&outcome);
    if let Some(e) = write_error {
        return Err(e);
    }
    let dir = family.as_ref().map(|f| f.dir().to_path_buf()).unwrap_or_default();
    ctx.record("snapshot", solved + imported, cached, dir);
    ctx.points.add(PointCounts { solved: solved + imported, reused: cached, failed: failures.len() });
    if !failures.is_empty() {
        failures.sort_by_key(|f| f.0);
        let table_path = write_failures(ctx, &failures, points, &keys)?;
        let list = failures
            .iter()
            .map(|(i, m)| format!("  {}: {m}", point_label(&names, &points[*i])))
            .collect::<Vec<_>>()
            .join("\n");
        return Err(CromError::SolveFailures {
            scene: ctx.scene.scene.name.clone(),
            failed: failures.len(),
            total: computed,
            list,
            table: table_path,
        });
    }
    let family = family.ok_or_else(|| {
        CromError::artifact(ctx.store.root(), "no snapshot was stored for this scene", "rerun the scene")
    })?;
    let rows = keys
        .iter()
        .map(|k| {
            index.rows.get(k).cloned().ok_or_else(|| {
                CromError::artifact(family.dir(), format!("snapshot {} is not in the index", k.short()), "rerun")
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Columns { rows, shape: (family.meta().n_dof, family.meta().n_contact) })
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
    let dir = ctx.store.dir(ArtifactKind::Snapshot, key);
    if !dir.exists() {
        return None;
    }
    let manifest = match ctx.store.lookup(ArtifactKind::Snapshot, key) {
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
    failures: &[(usize, String)],
    points: &[Vec<f64>],
    keys: &[Key],
) -> Result<std::path::PathBuf, CromError> {
    let dir = crate::store::named_dir(ctx.store.root(), "runs", &ctx.scene.scene.name)?;
    std::fs::create_dir_all(&dir).map_err(|e| CromError::io(&dir, "creating the run directory", e))?;
    let n = failures.len();
    let table = Table::default().with("scene", Column::Str(vec![ctx.scene.scene.name.clone(); n]));
    let names: Vec<String> = ctx.scene.parameter.names().iter().map(|s| s.to_string()).collect();
    let failed: Vec<&[f64]> = failures.iter().map(|f| points[f.0].as_slice()).collect();
    let table = super::with_parameters(table, &names, &failed)
        .with("snapshot_key", Column::Str(failures.iter().map(|f| keys[f.0].0.clone()).collect()))
        .with("error", Column::Str(failures.iter().map(|f| f.1.clone()).collect()));
    let tmp = dir.join(format!(".solver_failures.{}.tmp", std::process::id()));
    table.write_parquet(&tmp)?;
    let path = dir.join("solver_failures.parquet");
    std::fs::rename(&tmp, &path).map_err(|e| CromError::io(&path, "moving the failure table into place", e))?;
    Ok(path)
}
