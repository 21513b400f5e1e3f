//! Snapshot stage: one high-fidelity solve per parameter point, one artifact per point. A
//! snapshot's key is its mesh, its solver settings and its parameter value — not the set it
//! belongs to — so training, test and nested sets share solves, and a killed sweep resumes with
//! exactly the missing points. Missing points are solved in parallel (rayon); each result is
//! written (HDF5, from this thread) as soon as it arrives.

use std::collections::{BTreeMap, HashMap};
use std::sync::mpsc;
use std::time::Instant;

use crom_schemas::artifact::{snapshot as names, ArtifactKind};
use crom_schemas::scene::SolverSpec;
use crom_stages::snapshot::{Snapshot, SolveStats};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;

use super::{Ctx, LazyPhysics};
use crate::cache::{params, Key, KeySpec};
use crate::error::CromError;
use crate::io::h5::H5Out;
use crate::io::table::{Column, Table};
use crate::physics::Units;

/// Bump when the solvers change the numbers they produce.
const ALGORITHM_VERSION: u32 = 1;

#[derive(Serialize)]
struct SnapshotParams<'a> {
    parameter: f64,
    solver: &'a SolverSpec,
}

/// The key spec of the snapshot at `parameter` on the mesh `mesh`.
pub(crate) fn spec(mesh: &Key, solver: &SolverSpec, parameter: f64) -> KeySpec {
    KeySpec::new(ArtifactKind::Snapshot, ALGORITHM_VERSION, params(&SnapshotParams { parameter, solver }))
        .input("mesh", mesh)
}

type Solved = (usize, f64, Result<Snapshot, String>, f64);

/// Ensure a snapshot artifact exists for every point; their keys in the order of `points`.
pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    mesh: &Key,
    points: &[f64],
) -> Result<Vec<Key>, CromError> {
    let specs: Vec<KeySpec> = points.iter().map(|&p| spec(mesh, &ctx.scene.solver, p)).collect();
    let keys: Vec<Key> = specs.iter().map(KeySpec::key).collect();
    let mut first_of: HashMap<&Key, usize> = HashMap::new();
    let mut missing = Vec::new();
    let mut cached = 0;
    for (i, k) in keys.iter().enumerate() {
        if first_of.insert(k, i).is_some() {
            continue; // the same point twice in the sweep: one solve
        }
        if ctx.lookup(ArtifactKind::Snapshot, k)?.is_some() {
            cached += 1;
        } else {
            missing.push((i, points[i]));
        }
    }
    let mut progress = ctx.progress.stage("snapshot", missing.len());
    let mut failures: Vec<(f64, String)> = Vec::new();
    let mut write_error: Option<CromError> = None;
    let computed = missing.len();
    if !missing.is_empty() {
        let phys = physics.get()?;
        let units = phys.units();
        let name = ctx.scene.parameter.name.clone();
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel::<Solved>();
            s.spawn(move || {
                missing.par_iter().for_each_with(tx, |tx, &(i, p)| {
                    let t = Instant::now();
                    let r = phys.solve(p);
                    let _ = tx.send((i, p, r, t.elapsed().as_secs_f64()));
                });
            });
            for (i, p, r, secs) in rx {
                progress.inc(&format!("{name} = {p}"));
                match r {
                    Ok(snap) if write_error.is_none() => {
                        if let Err(e) = write(ctx, &specs[i], &snap, p, &name, secs, units) {
                            write_error = Some(e);
                        }
                    }
                    Ok(_) => {}
                    Err(msg) => failures.push((p, msg)),
                }
            }
        });
    }
    progress.finish(&format!("{} solved, {cached} cached, {} failed", computed - failures.len(), failures.len()));
    if let Some(e) = write_error {
        return Err(e);
    }
    let dir = keys.last().map(|k| ctx.store.dir(ArtifactKind::Snapshot, k)).unwrap_or_default();
    ctx.record("snapshot", computed - failures.len(), cached, dir);
    if !failures.is_empty() {
        failures.sort_by(|a, b| a.0.total_cmp(&b.0));
        let table_path = write_failures(ctx, &failures, points, &keys)?;
        let list = failures
            .iter()
            .map(|(p, m)| format!("  {} = {p}: {m}", ctx.scene.parameter.name))
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
    Ok(keys)
}

/// The solver statistics as manifest summary entries (read back by the training-set stage).
fn stats_summary(s: &SolveStats, seconds: f64) -> BTreeMap<String, serde_json::Value> {
    BTreeMap::from([
        ("iterations".to_string(), json!(s.iterations)),
        ("active".to_string(), json!(s.active)),
        ("max_penetration".to_string(), json!(s.max_penetration)),
        ("min_lambda".to_string(), json!(s.min_lambda)),
        ("complementarity".to_string(), json!(s.complementarity)),
        ("kkt_residual".to_string(), json!(s.kkt_residual)),
        ("vertex_ties".to_string(), json!(s.vertex_ties)),
        ("seconds".to_string(), json!(seconds)),
    ])
}

fn write(
    ctx: &Ctx<'_>,
    spec: &KeySpec,
    snap: &Snapshot,
    p: f64,
    name: &str,
    secs: f64,
    units: Units,
) -> Result<(), CromError> {
    let staging = ctx.store.stage(spec)?;
    let path = staging.path(names::FILE);
    let f = H5Out::create(&path)?;
    f.attr_str("scene", &ctx.scene.scene.name)?;
    f.attr_str("kind", "snapshot")?;
    f.attr_u64("schema_version", u64::from(ArtifactKind::Snapshot.schema_version()))?;
    f.attr_str("cache_key", &staging.key().0)?;
    f.attr_str("parameter_name", name)?;
    f.attr_f64("parameter", p)?;
    f.attr_u64("iterations", snap.stats.iterations as u64)?;
    f.attr_f64("complementarity", snap.stats.complementarity)?;
    f.vec_f64(names::U, &snap.u, units.primal)?;
    f.vec_f64(names::PRESSURE, &snap.pressure, units.dual)?;
    drop(f);
    let mut summary = stats_summary(&snap.stats, secs);
    summary.insert("parameter".to_string(), json!(p));
    ctx.commit(staging, secs, summary)?;
    Ok(())
}

/// The failed points of this run as `<store>/runs/<scene>/solver_failures.parquet` (replaced by
/// each run that has failures; written under a temporary name and renamed). Failures are not
/// cached: the next run tries those points again.
fn write_failures(
    ctx: &Ctx<'_>,
    failures: &[(f64, String)],
    points: &[f64],
    keys: &[Key],
) -> Result<std::path::PathBuf, CromError> {
    let dir = ctx.store.root().join("runs").join(&ctx.scene.scene.name);
    std::fs::create_dir_all(&dir).map_err(|e| CromError::io(&dir, "creating the run directory", e))?;
    let key_of =
        |p: f64| points.iter().position(|q| q.to_bits() == p.to_bits()).map(|i| keys[i].0.clone()).unwrap_or_default();
    let n = failures.len();
    let table = Table::default()
        .with("scene", Column::Str(vec![ctx.scene.scene.name.clone(); n]))
        .with("parameter", Column::F64(failures.iter().map(|f| f.0).collect()))
        .with("snapshot_key", Column::Str(failures.iter().map(|f| key_of(f.0)).collect()))
        .with("error", Column::Str(failures.iter().map(|f| f.1.clone()).collect()));
    let tmp = dir.join(format!(".solver_failures.{}.tmp", std::process::id()));
    table.write_parquet(&tmp)?;
    let path = dir.join("solver_failures.parquet");
    std::fs::rename(&tmp, &path).map_err(|e| CromError::io(&path, "moving the failure table into place", e))?;
    Ok(path)
}
