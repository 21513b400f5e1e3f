//! Reading a stored training set (train, test, a nested level): its index rows, its shape and
//! its columns, each read from its block and checked against its blake3. The set stage
//! (`trainset.rs`) writes these files; every stage that reads a set reads them through here.

use std::collections::BTreeMap;
use std::path::Path;

use crom_schemas::artifact::{trainset as names, ArtifactKind};

use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In};
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

/// Nested levels read through their finest ([`Nested::open`]).
#[derive(Debug)]
pub(crate) struct Nested {
    top: TrainingSet,
    /// Per level, the column of the finest level that holds each of its points.
    columns: Vec<Vec<usize>>,
    parameters: Vec<Vec<Vec<f64>>>,
}

impl Nested {
    /// The stored sets `keys` (the nested levels, coarse to fine, each point of a level also a
    /// point of the finest), with the finest read once (every column checked) and each other
    /// level taken from it by snapshot key: the columns of a coarse level are strided over the
    /// blocks, and reading them again took 0.16 s of ironing-fine's 0.25 s nested stage. `None`
    /// when the finest level's columns take more than `limit` bytes (the stage then holds two
    /// levels at a time) or a point of a level is not a column of the finest with the same
    /// checksum.
    pub(crate) fn open(store: &crate::store::Store, keys: &[Key], limit: usize) -> Result<Option<Self>, CromError> {
        let Some(finest) = keys.last() else { return Ok(None) };
        let rows: Vec<Vec<IndexRow>> = keys
            .iter()
            .map(|k| rows_of(&store.dir(ArtifactKind::TRAINING_SET, k).join(names::STATS)))
            .collect::<Result<_, _>>()?;
        let top_rows = rows.last().map_or(&[][..], Vec::as_slice);
        let (n_dof, n_contact) = set_shape(store, finest, top_rows)?;
        let bytes = top_rows.len().saturating_mul(n_dof.saturating_add(n_contact)).saturating_mul(8);
        if bytes > limit {
            return Ok(None);
        }
        let at: std::collections::HashMap<&Key, (usize, &str)> =
            top_rows.iter().enumerate().map(|(j, r)| (&r.key, (j, r.blake3.as_str()))).collect();
        let mut columns = Vec::with_capacity(rows.len());
        for level in &rows {
            let cols: Option<Vec<usize>> =
                level.iter().map(|r| at.get(&r.key).filter(|(_, h)| *h == r.blake3).map(|(j, _)| *j)).collect();
            let Some(cols) = cols else { return Ok(None) };
            columns.push(cols);
        }
        let parameters: Vec<Vec<Vec<f64>>> =
            rows.iter().map(|level| level.iter().map(|r| r.parameters.clone()).collect()).collect();
        // the finest level's columns, from the rows and shape read above (`load_from` would
        // read both again)
        let refs: Vec<&IndexRow> = top_rows.iter().collect();
        let (primal, dual) = read_columns(store.root(), n_dof, n_contact, &refs)?;
        let top = TrainingSet { primal, dual, parameters: parameters.last().cloned().unwrap_or_default() };
        Ok(Some(Self { top, columns, parameters }))
    }

    /// Level `i` (in the order of the keys given to [`Self::open`]).
    pub(crate) fn level(&self, i: usize) -> TrainingSet {
        let pick = |m: &ColMatrix| {
            let data = self.columns[i].iter().flat_map(|&j| m.col(j).iter().copied()).collect();
            ColMatrix { rows: m.rows, cols: self.columns[i].len(), data }
        };
        TrainingSet {
            primal: pick(&self.top.primal),
            dual: pick(&self.top.dual),
            parameters: self.parameters[i].clone(),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The nested levels taken from the finest ([`Nested`]) are the levels read one by one,
    /// bit for bit (columns and points), and a limit below the finest level's size reads them
    /// one by one instead: the rope with 10 training points and three nested levels, run into a
    /// fresh store, the levels' keys from the nested stage's manifest.
    #[test]
    fn nested_levels_from_the_finest_are_the_levels_read_alone() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/rope.toml");
        let text = std::fs::read_to_string(&path).expect("rope.toml");
        let text = text.replace("n_train = 10", "n_train = 10\nnested_levels = 3");
        let scene = crom_schemas::SceneConfig::from_toml_str(&text, &path).expect("scene");
        let store = crate::store::Store::open(dir.path()).expect("store");
        let mut ctx = crate::dag::ctx::Ctx::new(&store, &scene.scene.name, "test".into(), true);
        crate::dag::run_scene(&mut ctx, &scene, false).expect("run");
        let nested_dir = std::fs::read_dir(dir.path().join("nested")).expect("nested").flatten().next().expect("one");
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(nested_dir.path().join("manifest.json")).expect("manifest"))
                .expect("json");
        let keys: Vec<Key> =
            (1..=3).map(|i| Key(manifest["inputs"][format!("level{i}")].as_str().expect("level key").into())).collect();
        let nested = Nested::open(&store, &keys, usize::MAX).expect("open").expect("levels from the finest");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for (i, key) in keys.iter().enumerate() {
            let (got, want) = (nested.level(i), load_from(&store, key).expect("level"));
            assert!(got.primal.cols < nested.level(2).primal.cols || i == 2, "level {i} is coarser");
            assert_eq!((got.primal.rows, got.primal.cols), (want.primal.rows, want.primal.cols), "level {i}");
            assert_eq!(bits(&got.primal.data), bits(&want.primal.data), "level {i} primal");
            assert_eq!(bits(&got.dual.data), bits(&want.dual.data), "level {i} dual");
            assert_eq!(got.parameters, want.parameters, "level {i} points");
        }
        assert!(Nested::open(&store, &keys, 8).expect("open").is_none(), "over the limit: read alone");
    }
}
