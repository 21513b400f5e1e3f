//! Training-set stage: a named set of snapshot columns (train, test, a nested level) as one
//! HDF5 file whose `primal` (n_dof x N) and `dual` (n_contact x N) are **virtual datasets**
//! mapping each column to its block in the column store — nothing is copied — plus the real
//! `parameters`, the per-snapshot table `solver_stats.parquet` (key, parameter, block,
//! column, blake3 of the column, solver evidence) and, apart because it differs from run to
//! run, `solver_timings.parquet` (each snapshot's solve time).
//!
//! The set's key is its name, its parameter values and its snapshots' content keys, not where
//! the columns live: a set rebuilt after a block was quarantined and re-solved keeps its key and
//! its downstream artifacts. A stored set whose columns moved is rewritten (the cache hit is
//! checked against the index). Loading reads the columns straight from the blocks, checking
//! each against its blake3.

use std::collections::BTreeMap;
use std::path::Path;

use crom_schemas::artifact::{trainset as names, ArtifactKind};
use serde::Serialize;
use serde_json::json;

use super::graph::{Input, StageDef};
use super::{Ctx, Labels, Shared};
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::{H5In, H5Out};
use crate::io::table::{read_parquet, Column, Table};
use crate::store::columns::{read_columns, Evidence, IndexRow};

/// A set's parameter values as keyed: a flat list for a scalar parameter (the layout it always
/// had), one list per point for a vector parameter.
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum Values {
    Scalar(Vec<f64>),
    Vector(Vec<Vec<f64>>),
}

/// A set's key: its name and parameter values (its snapshots' keys are inputs).
#[derive(Debug, Serialize)]
struct SetKey<'a> {
    set: &'a str,
    parameters: Values,
}

impl StageKey for SetKey<'_> {
    const KIND: ArtifactKind = ArtifactKind::TrainingSet;
    /// Bump when the assembly of the set changes.
    const ALGORITHM_VERSION: u32 = 3;
}

pub(crate) use crate::io::snapshot_set::TrainingSet;

/// The set's key spec: name, parameter values, snapshot keys. A scalar parameter keys its
/// values as a flat list (as it always did).
fn spec(set: &str, points: &[Vec<f64>], keys: &[&Key]) -> KeySpec {
    let values = if points.iter().all(|p| p.len() == 1) {
        Values::Scalar(points.iter().map(|p| p[0]).collect())
    } else {
        Values::Vector(points.to_vec())
    };
    let mut spec = KeySpec::of(&SetKey { set, parameters: values });
    for (i, k) in keys.iter().enumerate() {
        spec = spec.input(&format!("snapshot{i:05}"), k);
    }
    spec
}

/// A named snapshot set: the points `start..start + points.len()` of sweep `sweep` (whose index
/// rows the sweep hands on in memory).
#[derive(Debug)]
pub(crate) struct SetStage {
    pub spec: KeySpec,
    pub set: String,
    pub points: Vec<Vec<f64>>,
    pub snapshots: Input,
    pub sweep: usize,
    pub start: usize,
    pub labels: Labels,
}

impl SetStage {
    /// The set `set` of `points`, whose snapshot keys are `keys`, from the sweep node `snapshots`
    /// (its rows `start..`); `labels` name it.
    pub(crate) fn plan(
        set: &str,
        (points, keys): (&[Vec<f64>], &[&Key]),
        snapshots: Input,
        (sweep, start): (usize, usize),
        labels: &Labels,
    ) -> Self {
        Self {
            spec: spec(set, points, keys),
            set: set.to_string(),
            points: points.to_vec(),
            snapshots,
            sweep,
            start,
            labels: labels.clone(),
        }
    }
}

impl StageDef for SetStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::TrainingSet
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.snapshots]
    }
    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let cols = shared.columns.get(&self.sweep).ok_or_else(|| {
            CromError::artifact(
                ctx.store.root(),
                format!("set `{}` before its sweep", self.set),
                "report this as a bug in crom",
            )
        })?;
        let rows = &cols.rows[self.start..self.start + self.points.len()];
        run(ctx, &self.spec, (&self.set, &self.labels), &self.points, rows, cols.shape)
    }
}

pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    (set, labels): (&str, &Labels),
    points: &[Vec<f64>],
    rows: &[IndexRow],
    shape: (usize, usize),
) -> Result<Key, CromError> {
    let label = match set {
        "train" => "trainset",
        "test" => "testset",
        _ => "nested-set",
    };
    // A stored set whose columns have moved since (a block re-solved after quarantine) is stale.
    let dir = ctx.store.dir(ArtifactKind::TrainingSet, &spec.key());
    if dir.exists() && !locations_match(&dir.join(names::STATS), rows) {
        let _ = ctx.store.quarantine_dir(ArtifactKind::TrainingSet, &spec.key());
        ctx.warnings.push(format!("{set} set {} referred to moved columns; rewritten", spec.key().short()));
    }
    let (scene, pname, names) = (&labels.scene, &labels.parameter, &labels.names);
    let root = ctx.store.root().to_path_buf();
    ctx.single(ArtifactKind::TrainingSet, label, spec, |staging| {
        let path = staging.path(names::FILE);
        let f = H5Out::create(&path)?;
        f.attr_str("scene", scene)?;
        f.attr_str("kind", "trainset")?;
        f.attr_str("set", set)?;
        f.attr_str("parameter_name", pname)?;
        f.attr_str("parameter_names", &names.join(","))?;
        f.attr_u64("schema_version", u64::from(ArtifactKind::TrainingSet.schema_version()))?;
        f.attr_str("cache_key", &staging.key().0)?;
        let blocks = block_columns(&root, rows)?;
        let src: Vec<(String, usize)> = rows.iter().map(|r| (format!("{BLOCK_PREFIX}{}", r.block), r.column)).collect();
        let width = |s: &str| blocks.get(s.trim_start_matches(BLOCK_PREFIX)).copied().unwrap_or(0);
        f.virtual_columns(names::PRIMAL, "primal", shape.0, &src, &width, "primal field, one snapshot per column")?;
        f.virtual_columns(names::DUAL, "dual", shape.1, &src, &width, "contact pressure, one snapshot per column")?;
        if names.len() == 1 {
            f.vec_f64(names::PARAMETERS, &points.iter().map(|p| p[0]).collect::<Vec<_>>(), pname)?;
        } else {
            let flat: Vec<f64> = points.iter().flatten().copied().collect();
            f.table_f64(names::PARAMETERS, points.len(), names.len(), &flat, &names.join(","))?;
        }
        drop(f);
        stats_table(scene, names, points, rows).write_parquet(&staging.path(names::STATS))?;
        timings_table(scene, rows).write_parquet(&staging.path(names::TIMINGS))?;
        Ok(BTreeMap::from([
            ("snapshots".to_string(), json!(points.len())),
            ("primal_shape".to_string(), json!([shape.0, rows.len()])),
            ("dual_shape".to_string(), json!([shape.1, rows.len()])),
        ]))
    })
}

/// A set file sits two directories below the store root (`<stage>/<key>/`, and the staging
/// directory `.staging/<name>/` alike), so `../../<block>` reaches a block from either; HDF5
/// resolves a relative source file against the virtual dataset's own directory.
const BLOCK_PREFIX: &str = "../../";

/// Column count of every block the rows refer to (read from the block files).
pub(crate) fn block_columns(root: &Path, rows: &[IndexRow]) -> Result<BTreeMap<String, usize>, CromError> {
    let mut out = BTreeMap::new();
    for r in rows {
        if out.contains_key(&r.block) {
            continue;
        }
        let path = root.join(&r.block);
        let f = H5In::open(&path)?;
        let shape = f.shape("dual")?;
        out.insert(r.block.clone(), shape.get(1).copied().unwrap_or(0));
    }
    Ok(out)
}

fn locations_match(stats: &Path, rows: &[IndexRow]) -> bool {
    let Ok(t) = read_parquet(stats) else { return false };
    let (Some(block), Some(column)) = (t.strs("block"), t.u64s("column")) else { return false };
    block.len() == rows.len()
        && rows.iter().zip(block.iter().zip(column)).all(|(r, (b, c))| &r.block == b && r.column as u64 == *c)
}

/// Load a training set artifact's matrices, reading each column from its block and checking it.
pub(crate) fn load_from(store: &crate::store::Store, key: &Key) -> Result<TrainingSet, CromError> {
    let dir = store.dir(ArtifactKind::TrainingSet, key);
    let rows = rows_of(&dir.join(names::STATS))?;
    let (n_dof, n_contact) = set_shape(store, key, &rows)?;
    let parameters: Vec<Vec<f64>> = rows.iter().map(|r| r.parameters.clone()).collect();
    let refs: Vec<&IndexRow> = rows.iter().collect();
    let (primal, dual) = read_columns(store.root(), n_dof, n_contact, &refs)?;
    Ok(TrainingSet { primal, dual, parameters })
}

/// `(n_dof, n_contact)` of the stored set `key` whose index rows are `rows`: from the block of
/// its first column. *Why not from the set's own file:* its `primal` and `dual` are virtual
/// datasets with one mapping per column, and opening one copies every mapping (42 MB at 16 385
/// columns, held by HDF5's free lists for the rest of the process; 0.6 GB of a level-14 study's
/// peak came from two such opens). The set's file is opened only for an empty set.
pub(crate) fn set_shape(
    store: &crate::store::Store,
    key: &Key,
    rows: &[IndexRow],
) -> Result<(usize, usize), CromError> {
    let (path, primal, dual) = match rows.first() {
        Some(r) => (store.root().join(&r.block), "primal", "dual"),
        None => (store.dir(ArtifactKind::TrainingSet, key).join(names::FILE), names::PRIMAL, names::DUAL),
    };
    let f = H5In::open(&path)?;
    let rows_of = |name: &str| -> Result<usize, CromError> { Ok(f.shape(name)?.first().copied().unwrap_or(0)) };
    Ok((rows_of(primal)?, rows_of(dual)?))
}

/// The index rows a stored set refers to (from its `solver_stats.parquet`).
pub(crate) fn rows_of(path: &Path) -> Result<Vec<IndexRow>, CromError> {
    let t = read_parquet(path)?;
    let bad = |c: &str| CromError::artifact(path, format!("column `{c}` missing"), "delete the artifact and rerun");
    let keys = t.strs("snapshot_key").ok_or_else(|| bad("snapshot_key"))?;
    let block = t.strs("block").ok_or_else(|| bad("block"))?;
    let column = t.u64s("column").ok_or_else(|| bad("column"))?;
    let hash = t.strs("blake3").ok_or_else(|| bad("blake3"))?;
    // A vector parameter has one column per component after `parameter` (its first component).
    let cols: Vec<&[f64]> = {
        let at = t.columns.iter().position(|(n, _)| n == "parameter").ok_or_else(|| bad("parameter"))?;
        let until = t.columns.iter().position(|(n, _)| n == "snapshot_key").ok_or_else(|| bad("snapshot_key"))?;
        let extra: Vec<&[f64]> = t.columns[at + 1..until].iter().filter_map(|(n, _)| t.f64s(n)).collect();
        if extra.is_empty() {
            vec![t.f64s("parameter").ok_or_else(|| bad("parameter"))?]
        } else {
            extra
        }
    };
    Ok((0..t.rows())
        .map(|i| IndexRow {
            key: Key(keys[i].clone()),
            parameters: cols.iter().map(|c| c[i]).collect(),
            block: block[i].clone(),
            column: column[i] as usize,
            blake3: hash[i].clone(),
            block_bytes: 0,
            block_blake3: String::new(),
            evidence: Evidence::default(),
        })
        .collect())
}

/// Per-snapshot table: `parameter` is the first component; a vector parameter adds one column
/// per component (by name) before `snapshot_key`.
fn stats_table(scene: &str, names: &[String], points: &[Vec<f64>], rows: &[IndexRow]) -> Table {
    let n = rows.len();
    let u = |f: &dyn Fn(&Evidence) -> u64| Column::U64(rows.iter().map(|r| f(&r.evidence)).collect());
    let x = |f: &dyn Fn(&Evidence) -> f64| Column::F64(rows.iter().map(|r| f(&r.evidence)).collect());
    let t = Table::default()
        .with("scene", Column::Str(vec![scene.to_string(); n]))
        .with("index", Column::U64((0..n as u64).collect()));
    let points: Vec<&[f64]> = points.iter().map(Vec::as_slice).collect();
    super::with_parameters(t, names, &points)
        .with("snapshot_key", Column::Str(rows.iter().map(|r| r.key.0.clone()).collect()))
        .with("block", Column::Str(rows.iter().map(|r| r.block.clone()).collect()))
        .with("column", Column::U64(rows.iter().map(|r| r.column as u64).collect()))
        .with("blake3", Column::Str(rows.iter().map(|r| r.blake3.clone()).collect()))
        .with("iterations", u(&|e| e.iterations))
        .with("active", u(&|e| e.active))
        .with("max_penetration", x(&|e| e.max_penetration))
        .with("min_lambda", x(&|e| e.min_lambda))
        .with("complementarity", x(&|e| e.complementarity))
        .with("kkt_residual", x(&|e| e.kkt_residual))
        .with("vertex_ties", u(&|e| e.vertex_ties))
        .with("vertex_nodes", Column::Str(rows.iter().map(|r| r.evidence.vertex_nodes.clone()).collect()))
        .with("vertex_rounds", u(&|e| e.vertex_rounds))
        .with("min_gap", x(&|e| e.min_gap))
        .with("active_gap", x(&|e| e.active_gap))
        .with("cone_angle", x(&|e| e.cone_angle))
}

/// Per-snapshot solve time, apart from the results (same rows as the statistics).
fn timings_table(scene: &str, rows: &[IndexRow]) -> Table {
    let n = rows.len();
    Table::default()
        .with("scene", Column::Str(vec![scene.to_string(); n]))
        .with("index", Column::U64((0..n as u64).collect()))
        .with("snapshot_key", Column::Str(rows.iter().map(|r| r.key.0.clone()).collect()))
        .with("seconds", Column::F64(rows.iter().map(|r| r.evidence.seconds).collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_key_keeps_the_layout_existing_stores_were_keyed_with() {
        // The untyped layout before typed keys: {"set", "parameters": flat list or list of points}.
        let old = |v: serde_json::Value| {
            KeySpec::new(ArtifactKind::TrainingSet, 3, serde_json::json!({ "set": "train", "parameters": v })).key()
        };
        let scalar = spec("train", &[vec![0.5], vec![1.5]], &[]).key();
        assert_eq!(scalar, old(serde_json::json!([0.5, 1.5])));
        let vector = spec("train", &[vec![0.5, 0.02]], &[]).key();
        assert_eq!(vector, old(serde_json::json!([[0.5, 0.02]])));
    }

    #[test]
    fn tables_have_the_contract_columns_and_no_timing_in_the_results() {
        let row = IndexRow {
            key: Key("k".into()),
            parameters: vec![0.5],
            block: "b".into(),
            column: 0,
            blake3: "h".into(),
            block_bytes: 0,
            block_blake3: String::new(),
            evidence: Evidence::default(),
        };
        let cols = |t: &Table| t.columns.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
        let stats = stats_table("s", &["p".to_string()], &[vec![0.5]], std::slice::from_ref(&row));
        assert_eq!(cols(&stats), names::STATS_COLUMNS);
        assert_eq!(cols(&timings_table("s", &[row])), names::TIMING_COLUMNS);
    }
}
