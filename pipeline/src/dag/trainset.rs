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

use crom_schemas::artifact::{trainset as names, ArtifactKind};
use serde::Serialize;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::inputs::sets::{block_columns, locations_match, BLOCK_PREFIX};
use super::labels::Labels;
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5Out;
use crate::io::table::{Column, Table};
use crate::store::columns::{Evidence, IndexRow};

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
    const KIND: ArtifactKind = ArtifactKind::TRAINING_SET;
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
        ArtifactKind::TRAINING_SET
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.snapshots]
    }
    /// `train.h5` and its tables; a nested level's under `nested/level-K`.
    fn published(&self) -> Vec<Published> {
        let base = match self.set.strip_prefix("nested-") {
            Some(level) => format!("{}/level-{level}", crom_schemas::artifact::published::NESTED_DIR),
            None => self.set.clone(),
        };
        vec![
            Published::file(format!("{base}.h5"), names::FILE),
            Published::file(format!("{base}_solver_stats.parquet"), names::STATS),
            Published::file(format!("{base}_solver_timings.parquet"), names::TIMINGS),
        ]
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
    let dir = ctx.store.dir(ArtifactKind::TRAINING_SET, &spec.key());
    if dir.exists() && !locations_match(&dir.join(names::STATS), rows) {
        let _ = ctx.store.quarantine_dir(ArtifactKind::TRAINING_SET, &spec.key());
        ctx.warnings.push(format!("{set} set {} referred to moved columns; rewritten", spec.key().short()));
    }
    let (scene, pname, names) = (&labels.scene, &labels.parameter, &labels.names);
    let root = ctx.store.root().to_path_buf();
    ctx.single(ArtifactKind::TRAINING_SET, label, spec, |staging| {
        let path = staging.path(names::FILE);
        let f = H5Out::create(&path)?;
        f.attr_str("scene", scene)?;
        f.attr_str("kind", "trainset")?;
        f.attr_str("set", set)?;
        f.attr_str("parameter_name", pname)?;
        f.attr_str("parameter_names", &names.join(","))?;
        f.attr_u64("schema_version", u64::from(ArtifactKind::TRAINING_SET.schema_version()))?;
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
    super::ctx::with_parameters(t, names, &points)
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
            KeySpec::new(ArtifactKind::TRAINING_SET, 3, serde_json::json!({ "set": "train", "parameters": v })).key()
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
