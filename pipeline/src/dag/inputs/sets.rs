//! Reading a stored training set (train, test, a nested level): its index rows, its shape and
//! its columns, each read from its block and checked against its blake3. The set stage
//! (`trainset.rs`) writes these files; every stage that reads a set reads them through here.

use std::collections::BTreeMap;
use std::path::Path;

use crom_schemas::artifact::{trainset as names, ArtifactKind};

use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::H5In;
use crate::io::snapshot_set::TrainingSet;
use crate::io::table::read_parquet;
use crate::store::columns::{read_columns, Evidence, IndexRow};

/// A set file sits two directories below the store root (`<stage>/<key>/`, and the staging
/// directory `.staging/<name>/` alike), so `../../<block>` reaches a block from either; HDF5
/// resolves a relative source file against the virtual dataset's own directory.
pub(crate) const BLOCK_PREFIX: &str = "../../";

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

pub(crate) fn locations_match(stats: &Path, rows: &[IndexRow]) -> bool {
    let Ok(t) = read_parquet(stats) else { return false };
    let (Some(block), Some(column)) = (t.strs("block"), t.u64s("column")) else { return false };
    block.len() == rows.len()
        && rows.iter().zip(block.iter().zip(column)).all(|(r, (b, c))| &r.block == b && r.column as u64 == *c)
}

/// Load a training set artifact's matrices, reading each column from its block and checking it.
pub(crate) fn load_from(store: &crate::store::Store, key: &Key) -> Result<TrainingSet, CromError> {
    let dir = store.dir(ArtifactKind::TRAINING_SET, key);
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
        None => (store.dir(ArtifactKind::TRAINING_SET, key).join(names::FILE), names::PRIMAL, names::DUAL),
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
