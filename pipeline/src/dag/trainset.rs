//! Training-set stage: gathers snapshot artifacts into snapshot matrices (one column per
//! parameter point) and the per-snapshot solver-statistics table.

use std::collections::BTreeMap;

use crom_schemas::artifact::{snapshot as snap_names, trainset as names, ArtifactKind};
use serde_json::json;

use super::Ctx;
use crate::cache::{Key, KeySpec};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In, H5Out};
use crate::io::table::{Column, Table};

/// Bump when the assembly of the set changes.
const ALGORITHM_VERSION: u32 = 1;

/// A loaded training set.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TrainingSet {
    /// Primal snapshots, `n_dof x n_snap`.
    pub primal: ColMatrix,
    /// Dual snapshots (pressure), `n_contact x n_snap`.
    pub dual: ColMatrix,
    /// Parameter values.
    pub parameters: Vec<f64>,
}

pub(crate) fn run(ctx: &mut Ctx<'_>, set: &str, points: &[f64], snapshots: &[Key]) -> Result<Key, CromError> {
    let mut spec =
        KeySpec::new(ArtifactKind::TrainingSet, ALGORITHM_VERSION, json!({ "set": set, "parameters": points }));
    for (i, k) in snapshots.iter().enumerate() {
        spec = spec.input(&format!("snapshot{i:05}"), k);
    }
    let label = match set {
        "train" => "trainset",
        "test" => "testset",
        _ => "nested-set",
    };
    let scene = ctx.scene.scene.name.clone();
    let pname = ctx.scene.parameter.name.clone();
    let store = ctx.store;
    ctx.single(ArtifactKind::TrainingSet, label, &spec, |staging| {
        let mut u_cols = Vec::with_capacity(snapshots.len());
        let mut p_cols = Vec::with_capacity(snapshots.len());
        let mut stats = StatsColumns::default();
        for (i, k) in snapshots.iter().enumerate() {
            let dir = store.dir(ArtifactKind::Snapshot, k);
            let f = H5In::open(&dir.join(snap_names::FILE))?;
            u_cols.push(f.vec_f64(snap_names::U)?);
            p_cols.push(f.vec_f64(snap_names::PRESSURE)?);
            let m = read_manifest(&dir)?;
            stats.push(&scene, i, points[i], k, &m.summary);
        }
        let primal = matrix(&u_cols, staging.path(names::FILE))?;
        let dual = matrix(&p_cols, staging.path(names::FILE))?;
        let f = H5Out::create(&staging.path(names::FILE))?;
        f.attr_str("scene", &scene)?;
        f.attr_str("kind", "trainset")?;
        f.attr_str("set", set)?;
        f.attr_str("parameter_name", &pname)?;
        f.attr_u64("schema_version", u64::from(ArtifactKind::TrainingSet.schema_version()))?;
        f.attr_str("cache_key", &staging.key().0)?;
        f.matrix(names::PRIMAL, &primal, "primal field, one snapshot per column")?;
        f.matrix(names::DUAL, &dual, "contact pressure, one snapshot per column")?;
        f.vec_f64(names::PARAMETERS, points, &pname)?;
        drop(f);
        stats.table().write_parquet(&staging.path(names::STATS))?;
        Ok(BTreeMap::from([
            ("snapshots".to_string(), json!(points.len())),
            ("primal_shape".to_string(), json!([primal.rows, primal.cols])),
            ("dual_shape".to_string(), json!([dual.rows, dual.cols])),
        ]))
    })
}

/// Load a training set artifact's matrices.
pub(crate) fn load_from(store: &crate::store::Store, key: &Key) -> Result<TrainingSet, CromError> {
    let path = store.dir(ArtifactKind::TrainingSet, key).join(names::FILE);
    let f = H5In::open(&path)?;
    Ok(TrainingSet {
        primal: f.matrix(names::PRIMAL)?,
        dual: f.matrix(names::DUAL)?,
        parameters: f.vec_f64(names::PARAMETERS)?,
    })
}

fn read_manifest(dir: &std::path::Path) -> Result<crate::store::Manifest, CromError> {
    let p = dir.join(crom_schemas::artifact::MANIFEST);
    let text = std::fs::read_to_string(&p).map_err(|e| CromError::io(&p, "reading a manifest", e))?;
    serde_json::from_str(&text).map_err(|e| CromError::artifact(&p, e, "delete the artifact directory and rerun"))
}

fn matrix(cols: &[Vec<f64>], path: std::path::PathBuf) -> Result<ColMatrix, CromError> {
    let rows = cols.first().map_or(0, Vec::len);
    if cols.iter().any(|c| c.len() != rows) {
        return Err(CromError::artifact(
            path,
            "snapshots of one set have different lengths",
            "delete the store's snapshot directory and rerun",
        ));
    }
    let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
    Ok(ColMatrix::from_columns(rows, &refs))
}

#[derive(Default)]
struct StatsColumns {
    scene: Vec<String>,
    index: Vec<u64>,
    parameter: Vec<f64>,
    key: Vec<String>,
    ints: [Vec<u64>; 3],
    floats: [Vec<f64>; 5],
}

const INT_FIELDS: [&str; 3] = ["iterations", "active", "vertex_ties"];
const FLOAT_FIELDS: [&str; 5] = ["max_penetration", "min_lambda", "complementarity", "kkt_residual", "seconds"];

impl StatsColumns {
    fn push(&mut self, scene: &str, i: usize, p: f64, k: &Key, s: &BTreeMap<String, serde_json::Value>) {
        self.scene.push(scene.to_string());
        self.index.push(i as u64);
        self.parameter.push(p);
        self.key.push(k.0.clone());
        for (col, name) in self.ints.iter_mut().zip(INT_FIELDS) {
            col.push(s.get(name).and_then(serde_json::Value::as_u64).unwrap_or(0));
        }
        for (col, name) in self.floats.iter_mut().zip(FLOAT_FIELDS) {
            col.push(s.get(name).and_then(serde_json::Value::as_f64).unwrap_or(f64::NAN));
        }
    }

    fn table(self) -> Table {
        let [it, active, ties] = self.ints;
        let [pen, minl, comp, kkt, secs] = self.floats;
        Table::default()
            .with("scene", Column::Str(self.scene))
            .with("index", Column::U64(self.index))
            .with("parameter", Column::F64(self.parameter))
            .with("snapshot_key", Column::Str(self.key))
            .with("iterations", Column::U64(it))
            .with("active", Column::U64(active))
            .with("max_penetration", Column::F64(pen))
            .with("min_lambda", Column::F64(minl))
            .with("complementarity", Column::F64(comp))
            .with("kkt_residual", Column::F64(kkt))
            .with("vertex_ties", Column::U64(ties))
            .with("seconds", Column::F64(secs))
    }
}
