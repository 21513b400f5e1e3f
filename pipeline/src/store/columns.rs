//! The columnar snapshot store: every snapshot of one *column family* (same mesh, same solver
//! settings, same parameter names) is one column of chunked HDF5 block files, found through an
//! index table that pandas opens.
//!
//! ```text
//! <store>/columns/<family>/family.json            what the family is (n_dof, n_contact, parameters)
//! <store>/columns/<family>/blocks/<block>.h5      primal (n_dof x b), dual (n_contact x b),
//!                                                 parameters (b x p); chunk = one column
//! <store>/columns/<family>/index/<block>.parquet  index fragment of one committed block
//! <store>/columns/<family>/index.parquet          compacted index (every fragment at that time)
//! ```
//!
//! One index row per snapshot: its content key (mesh, solver settings, parameter value — the
//! same key a per-snapshot artifact had), its parameter values, the block file (path relative to
//! the store root) and column, the blake3 of the column (primal then dual, little-endian f64),
//! the block file's size and blake3, and the solver's evidence.
//!
//! **Commit.** A block is written under a temporary name, fsynced and renamed; then its index
//! fragment is written the same way. The fragment's rename is the commit point: a block without
//! a fragment (a writer killed between the two renames) is never read and is removed by the next
//! writer. **Reads** list the fragments first, then read the compacted index, then the fragments
//! it does not cover; a row whose block file is missing or has the wrong size is dropped (its
//! point counts as missing and is solved again). **Verification**: each column read is checked
//! against its blake3; a mismatch moves the block file to `<store>/.quarantine/` so its points
//! are recomputed. `crom verify` re-hashes every block.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::fs::{self, unix_now, write_atomic, writer_token};
use super::manifest::hash_file;
use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::ColMatrix;
use crate::io::table::{read_parquet, Column, Table};

/// Layout version of a column family (family.json, blocks, index).
pub const COLUMNS_SCHEMA_VERSION: u32 = 2;

/// Directory of all column families under the store root.
pub const COLUMNS_DIR: &str = "columns";

const FIX_CORRUPT: &str = "rerun: the damaged block was moved to .quarantine and its points are solved again";

/// What a column family holds (`family.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FamilyMeta {
    /// Layout version ([`COLUMNS_SCHEMA_VERSION`]).
    pub schema_version: u32,
    /// The family key.
    pub family: Key,
    /// Scene that created the family (informational: scenes with the same mesh and solver share it).
    pub scene: String,
    /// Rows of the primal field.
    pub n_dof: usize,
    /// Rows of the dual field.
    pub n_contact: usize,
    /// Parameter names, one index column each.
    pub parameter_names: Vec<String>,
    /// Units of the primal and dual fields.
    pub units: [String; 2],
}

/// Solver evidence of one snapshot (index columns).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Evidence {
    /// Active-set iterations.
    pub iterations: u64,
    /// Active constraints at the solution.
    pub active: u64,
    /// Slave nodes tied to a vertex.
    pub vertex_ties: u64,
    /// The tied slaves, `slave:vertex` pairs separated by spaces.
    pub vertex_nodes: String,
    /// Cold re-solves of the vertex-zone rule.
    pub vertex_rounds: u64,
    /// Geometric check: smallest signed distance of a slave to the master (negative: penetration).
    pub min_gap: f64,
    /// Geometric check: largest `|distance|` of a slave with pressure.
    pub active_gap: f64,
    /// Geometric check: largest angle (rad) of a contact force outside its normal cone.
    pub cone_angle: f64,
    /// Largest penetration.
    pub max_penetration: f64,
    /// Smallest multiplier.
    pub min_lambda: f64,
    /// Complementarity residual.
    pub complementarity: f64,
    /// Equilibrium residual.
    pub kkt_residual: f64,
    /// Wall time of the solve.
    pub seconds: f64,
}

/// One index row: where a snapshot lives and how it was obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexRow {
    /// The snapshot's content key.
    pub key: Key,
    /// Parameter values (one per parameter name).
    pub parameters: Vec<f64>,
    /// Block file, relative to the store root.
    pub block: String,
    /// Column in the block.
    pub column: usize,
    /// blake3 of the column (primal then dual, little-endian f64).
    pub blake3: String,
    /// Block file size in bytes.
    pub block_bytes: u64,
    /// blake3 of the whole block file.
    pub block_blake3: String,
    /// Solver evidence.
    pub evidence: Evidence,
}

/// The index of a family: every committed snapshot by key.
#[derive(Debug, Clone, Default)]
pub struct Index {
    /// Rows by snapshot key.
    pub rows: HashMap<Key, IndexRow>,
    /// Rows dropped because their block file is missing or has the wrong size.
    pub dropped: usize,
    /// Index fragments read that the compacted index does not cover yet.
    pub fragments: usize,
}

/// An open column family.
#[derive(Debug, Clone)]
pub struct ColumnFamily {
    root: PathBuf,
    dir: PathBuf,
    meta: FamilyMeta,
}

/// blake3 of one snapshot column (primal then dual).
pub fn column_hash(primal: &[f64], dual: &[f64]) -> String {
    // The same bytes as one `update` per value, handed over in pieces (much faster).
    let mut h = blake3::Hasher::new();
    let mut buf: Vec<u8> = Vec::with_capacity(HASH_PIECE);
    for v in primal.iter().chain(dual) {
        buf.extend_from_slice(&v.to_le_bytes());
        if buf.len() >= HASH_PIECE {
            h.update(&buf);
            buf.clear();
        }
    }
    h.update(&buf);
    h.finalize().to_hex().to_string()
}

/// Bytes per `update` of [`column_hash`].
const HASH_PIECE: usize = 64 << 10;

impl ColumnFamily {
    /// Open the family `meta.family` under the store `root`, creating it if needed. A family
    /// directory whose `family.json` disagrees with `meta` is an error (it would mix shapes).
    pub fn open(root: &Path, meta: FamilyMeta) -> Result<Self, CromError> {
        let dir = root.join(COLUMNS_DIR).join(&meta.family.0);
        for sub in ["blocks", "index"] {
            let p = dir.join(sub);
            std::fs::create_dir_all(&p).map_err(|e| CromError::io(&p, "creating a column family", e))?;
        }
        let path = dir.join("family.json");
        if path.exists() {
            let found = read_meta(&path)?;
            let same = found.schema_version == meta.schema_version
                && found.n_dof == meta.n_dof
                && found.n_contact == meta.n_contact
                && found.parameter_names == meta.parameter_names;
            if !same {
                return Err(CromError::artifact(
                    &path,
                    format!("column family {} holds {found:?}, this run needs {meta:?}", meta.family.short()),
                    "delete the family directory (its snapshots are recomputed) and rerun",
                ));
            }
        } else {
            let text = serde_json::to_string_pretty(&meta).unwrap_or_default();
            write_atomic(&path, text.as_bytes())?;
        }
        Ok(Self { root: root.to_path_buf(), dir, meta })
    }

    /// The family `family` if it exists under `root` (read from its `family.json`).
    pub fn find(root: &Path, family: &Key) -> Result<Option<Self>, CromError> {
        let dir = root.join(COLUMNS_DIR).join(&family.0);
        let path = dir.join("family.json");
        if !path.exists() {
            return Ok(None);
        }
        let meta = read_meta(&path)?;
        if meta.schema_version != COLUMNS_SCHEMA_VERSION || &meta.family != family {
            return Err(CromError::artifact(
                &path,
                format!(
                    "column family of schema version {} (this crom writes {COLUMNS_SCHEMA_VERSION})",
                    meta.schema_version
                ),
                "delete the family directory (its snapshots are recomputed) or use the crom version that wrote it",
            ));
        }
        Ok(Some(Self { root: root.to_path_buf(), dir, meta }))
    }

    /// The family's description.
    pub fn meta(&self) -> &FamilyMeta {
        &self.meta
    }

    /// The family's directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Remove what a killed writer left behind: temporary files and blocks without a fragment.
    /// Call only while holding the store's writer lock.
    pub fn clean_orphans(&self) -> Result<usize, CromError> {
        let fragments: BTreeSet<String> = list(&self.dir.join("index"), ".parquet").into_iter().collect();
        let covered = self.compacted_blocks()?;
        let mut removed = 0;
        for sub in ["blocks", "index"] {
            let Ok(rd) = std::fs::read_dir(self.dir.join(sub)) else { continue };
            for e in rd.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                let orphan_block = sub == "blocks"
                    && name.ends_with(".h5")
                    && !fragments.contains(name.trim_end_matches(".h5"))
                    && !covered.contains(&self.block_rel(name.trim_end_matches(".h5")));
                if name.starts_with(".tmp") || orphan_block {
                    let _ = std::fs::remove_file(e.path());
                    removed += 1;
                }
            }
        }
        Ok(removed)
    }

    fn block_rel(&self, id: &str) -> String {
        format!("{COLUMNS_DIR}/{}/blocks/{id}.h5", self.meta.family.0)
    }

    /// Block ids the compacted index covers.
    fn compacted_blocks(&self) -> Result<BTreeSet<String>, CromError> {
        let path = self.dir.join("index.parquet");
        if !path.exists() {
            return Ok(BTreeSet::new());
        }
        let t = read_parquet(&path)?;
        Ok(t.strs("block").unwrap_or_default().iter().cloned().collect())
    }

    /// Read the index: the compacted table plus every fragment it does not cover. Rows whose
    /// block file is missing or has the wrong size are dropped.
    pub fn load_index(&self) -> Result<Index, CromError> {
        // Fragments may be removed by a concurrent compaction between listing and reading:
        // then the compacted index covers them and a retry sees a consistent state.
        for _ in 0..3 {
            let fragments = list(&self.dir.join("index"), ".parquet");
            let mut rows: Vec<IndexRow> = Vec::new();
            let compacted = self.dir.join("index.parquet");
            if compacted.exists() {
                rows.extend(self.rows_of(&read_parquet(&compacted)?, &compacted)?);
            }
            let covered: BTreeSet<String> = rows.iter().map(|r| r.block.clone()).collect();
            let mut vanished = false;
            let mut uncovered = 0;
            for id in fragments {
                if covered.contains(&self.block_rel(&id)) {
                    continue;
                }
                let p = self.dir.join("index").join(format!("{id}.parquet"));
                if !p.exists() {
                    vanished = true;
                    break;
                }
                rows.extend(self.rows_of(&read_parquet(&p)?, &p)?);
                uncovered += 1;
            }
            if vanished {
                continue;
            }
            let mut sizes: HashMap<String, Option<u64>> = HashMap::new();
            let mut index = Index { fragments: uncovered, ..Index::default() };
            for r in rows {
                let size = *sizes
                    .entry(r.block.clone())
                    .or_insert_with(|| std::fs::metadata(self.root.join(&r.block)).ok().map(|m| m.len()));
                if size != Some(r.block_bytes) {
                    index.dropped += 1;
                    continue;
                }
                index.rows.insert(r.key.clone(), r);
            }
            return Ok(index);
        }
        Err(CromError::artifact(
            &self.dir,
            "the index kept changing while it was read",
            "rerun when the other writers of the store have finished",
        ))
    }

    fn rows_of(&self, t: &Table, path: &Path) -> Result<Vec<IndexRow>, CromError> {
        let bad = |what: &str| {
            CromError::artifact(path, format!("index column `{what}` missing"), "delete the file and rerun")
        };
        let keys = t.strs("snapshot_key").ok_or_else(|| bad("snapshot_key"))?;
        let block = t.strs("block").ok_or_else(|| bad("block"))?;
        let column = t.u64s("column").ok_or_else(|| bad("column"))?;
        let hash = t.strs("blake3").ok_or_else(|| bad("blake3"))?;
        let bbytes = t.u64s("block_bytes").ok_or_else(|| bad("block_bytes"))?;
        let bhash = t.strs("block_blake3").ok_or_else(|| bad("block_blake3"))?;
        let params: Vec<&[f64]> =
            self.meta.parameter_names.iter().map(|n| t.f64s(n).ok_or_else(|| bad(n))).collect::<Result<_, _>>()?;
        let u = |n: &str| t.u64s(n).ok_or_else(|| bad(n));
        let f = |n: &str| t.f64s(n).ok_or_else(|| bad(n));
        let (it, act, ties) = (u("iterations")?, u("active")?, u("vertex_ties")?);
        let (pen, minl, comp, kkt, secs) =
            (f("max_penetration")?, f("min_lambda")?, f("complementarity")?, f("kkt_residual")?, f("seconds")?);
        let (rounds, nodes) = (u("vertex_rounds")?, t.strs("vertex_nodes").ok_or_else(|| bad("vertex_nodes"))?);
        let (min_gap, active_gap, cone) = (f("min_gap")?, f("active_gap")?, f("cone_angle")?);
        Ok((0..t.rows())
            .map(|i| IndexRow {
                key: Key(keys[i].clone()),
                parameters: params.iter().map(|p| p[i]).collect(),
                block: block[i].clone(),
                column: column[i] as usize,
                blake3: hash[i].clone(),
                block_bytes: bbytes[i],
                block_blake3: bhash[i].clone(),
                evidence: Evidence {
                    iterations: it[i],
                    active: act[i],
                    vertex_ties: ties[i],
                    vertex_nodes: nodes[i].clone(),
                    vertex_rounds: rounds[i],
                    min_gap: min_gap[i],
                    active_gap: active_gap[i],
                    cone_angle: cone[i],
                    max_penetration: pen[i],
                    min_lambda: minl[i],
                    complementarity: comp[i],
                    kkt_residual: kkt[i],
                    seconds: secs[i],
                },
            })
            .collect())
    }

    /// The index rows as a table (sorted by block, then column).
    fn table(&self, rows: &[&IndexRow]) -> Table {
        let mut rows = rows.to_vec();
        rows.sort_by(|a, b| (a.block.as_str(), a.column).cmp(&(b.block.as_str(), b.column)));
        let s = |f: &dyn Fn(&IndexRow) -> String| Column::Str(rows.iter().map(|r| f(r)).collect());
        let u = |f: &dyn Fn(&IndexRow) -> u64| Column::U64(rows.iter().map(|r| f(r)).collect());
        let x = |f: &dyn Fn(&IndexRow) -> f64| Column::F64(rows.iter().map(|r| f(r)).collect());
        let mut t = Table::default().with("snapshot_key", s(&|r| r.key.0.clone()));
        for (p, name) in self.meta.parameter_names.iter().enumerate() {
            t = t.with(name, x(&|r| r.parameters[p]));
        }
        t.with("block", s(&|r| r.block.clone()))
            .with("column", u(&|r| r.column as u64))
            .with("blake3", s(&|r| r.blake3.clone()))
            .with("block_bytes", u(&|r| r.block_bytes))
            .with("block_blake3", s(&|r| r.block_blake3.clone()))
            .with("iterations", u(&|r| r.evidence.iterations))
            .with("active", u(&|r| r.evidence.active))
            .with("vertex_ties", u(&|r| r.evidence.vertex_ties))
            .with("vertex_nodes", s(&|r| r.evidence.vertex_nodes.clone()))
            .with("vertex_rounds", u(&|r| r.evidence.vertex_rounds))
            .with("min_gap", x(&|r| r.evidence.min_gap))
            .with("active_gap", x(&|r| r.evidence.active_gap))
            .with("cone_angle", x(&|r| r.evidence.cone_angle))
            .with("max_penetration", x(&|r| r.evidence.max_penetration))
            .with("min_lambda", x(&|r| r.evidence.min_lambda))
            .with("complementarity", x(&|r| r.evidence.complementarity))
            .with("kkt_residual", x(&|r| r.evidence.kkt_residual))
            .with("seconds", x(&|r| r.evidence.seconds))
    }

    /// Rewrite `index.parquet` with every row of `index` and remove the fragments it now covers.
    /// Call only while holding the store's writer lock.
    pub fn compact(&self, index: &Index) -> Result<(), CromError> {
        let fragments = list(&self.dir.join("index"), ".parquet");
        let rows: Vec<&IndexRow> = index.rows.values().collect();
        let covered: BTreeSet<&str> = rows.iter().map(|r| r.block.as_str()).collect();
        let path = self.dir.join("index.parquet");
        let tmp = self.dir.join(format!(".tmp-index-{}.parquet", writer_token()));
        self.table(&rows).write_parquet(&tmp)?;
        fs::publish(&tmp, &path)?;
        for id in fragments {
            if covered.contains(self.block_rel(&id).as_str()) {
                let _ = std::fs::remove_file(self.dir.join("index").join(format!("{id}.parquet")));
            }
        }
        Ok(())
    }

    /// Take back a block this writer committed and nothing has read since (an import that
    /// found a bad value after its first blocks): its fragment first (the commit point), then
    /// its file. The compacted index must not cover it. Call only while holding the store's
    /// writer lock.
    pub fn uncommit(&self, block: &str) -> Result<(), CromError> {
        let id = Path::new(block).file_stem().and_then(|s| s.to_str()).unwrap_or_default();
        let fragment = self.dir.join("index").join(format!("{id}.parquet"));
        std::fs::remove_file(&fragment).map_err(|e| CromError::io(&fragment, "removing an index fragment", e))?;
        let file = self.root.join(block);
        std::fs::remove_file(&file).map_err(|e| CromError::io(&file, "removing a block", e))
    }

    /// Write one block of snapshots and commit it; returns its index rows (in key order).
    pub fn commit_block(&self, columns: &[PendingColumn]) -> Result<Vec<IndexRow>, CromError> {
        if columns.is_empty() {
            return Ok(Vec::new());
        }
        // Columns in key order: a block's file is a function of its set of snapshots, so a block
        // written again under the same id (after quarantine) has the same layout.
        let mut sorted: Vec<&PendingColumn> = columns.iter().collect();
        sorted.sort_by(|a, b| a.key.cmp(&b.key));
        let ids: Vec<&str> = sorted.iter().map(|c| c.key.0.as_str()).collect();
        let id = format!("blk-{}", &blake3::hash(ids.join(",").as_bytes()).to_hex()[..24]);
        let rel = self.block_rel(&id);
        let path = self.root.join(&rel);
        for sub in ["blocks", "index"] {
            let p = self.dir.join(sub);
            std::fs::create_dir_all(&p).map_err(|e| CromError::io(&p, "creating a column family", e))?;
        }
        let tmp = self.dir.join("blocks").join(format!(".tmp-{id}-{}.h5", writer_token()));
        write_block(&tmp, &self.meta, &sorted)?;
        fs::publish(&tmp, &path)?;
        let (bytes, bhash) = hash_file(&path).map_err(|e| CromError::io(&path, "hashing a block", e))?;
        let rows: Vec<IndexRow> = sorted
            .iter()
            .enumerate()
            .map(|(j, c)| IndexRow {
                key: c.key.clone(),
                parameters: c.parameters.clone(),
                block: rel.clone(),
                column: j,
                blake3: column_hash(&c.primal, &c.dual),
                block_bytes: bytes,
                block_blake3: bhash.clone(),
                evidence: c.evidence.clone(),
            })
            .collect();
        let frag = self.dir.join("index").join(format!("{id}.parquet"));
        let ftmp = self.dir.join("index").join(format!(".tmp-{id}-{}.parquet", writer_token()));
        self.table(&rows.iter().collect::<Vec<_>>()).write_parquet(&ftmp)?;
        fs::publish(&ftmp, &frag)?;
        Ok(rows)
    }

    /// Re-hash every block file and every column against the index; blocks that fail are moved
    /// to the quarantine. Returns `(blocks checked, problems)`; the caller acts on the quarantined
    /// blocks among the problems (`Store::verify_family` does).
    pub fn verify_all(&self) -> Result<(usize, Vec<BlockProblem>), CromError> {
        self.verify_each(|_| Ok(()))
    }

    /// [`ColumnFamily::verify_all`], handing each block to `quarantined` right after it was
    /// moved aside (before the next block is checked).
    pub fn verify_each(
        &self,
        mut quarantined: impl FnMut(&QuarantinedBlock) -> Result<(), CromError>,
    ) -> Result<(usize, Vec<BlockProblem>), CromError> {
        let index = self.load_index()?;
        let mut by_block: BTreeMap<&str, Vec<&IndexRow>> = BTreeMap::new();
        for r in index.rows.values() {
            by_block.entry(r.block.as_str()).or_default().push(r);
        }
        let mut problems = Vec::new();
        for (block, rows) in &by_block {
            let path = self.root.join(block);
            let (bytes, hash) = hash_file(&path).map_err(|e| CromError::io(&path, "hashing a block", e))?;
            let whole_ok = bytes == rows[0].block_bytes && hash == rows[0].block_blake3;
            let cols_ok = whole_ok && self.read_checked(rows).is_ok();
            if !cols_ok {
                let q = self.quarantine(block)?;
                quarantined(&q)?;
                problems.push(BlockProblem::Quarantined(q));
            }
        }
        if index.dropped > 0 {
            problems.push(BlockProblem::Dropped(index.dropped));
        }
        Ok((by_block.len(), problems))
    }

    /// Move a block file to `<store>/.quarantine/` (see [`quarantine_block`]).
    pub fn quarantine(&self, block: &str) -> Result<QuarantinedBlock, CromError> {
        quarantine_block(&self.root, block)
    }

    fn read_checked(&self, rows: &[&IndexRow]) -> Result<(ColMatrix, ColMatrix), String> {
        read_columns(&self.root, self.meta.n_dof, self.meta.n_contact, rows).map_err(|e| e.to_string())
    }
}

/// Every column family under the store root `root`, in key order (families whose
/// `family.json` cannot be read are skipped).
pub fn families(root: &Path) -> Vec<ColumnFamily> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(root.join(COLUMNS_DIR)) else { return out };
    let mut names: Vec<String> = entries.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    for n in names {
        if let Ok(Some(f)) = ColumnFamily::find(root, &Key(n)) {
            out.push(f);
        }
    }
    out
}

/// A snapshot block that was moved to the quarantine. Its index rows are dropped by the next
/// index read (the file is missing), but the published names and the catalog still refer to
/// it: the caller withdraws the names of the training sets that read it and refreshes the
/// catalog (`Store::quarantine_block`, `Store::verify_family`).
#[derive(Debug, Clone, PartialEq)]
#[must_use = "the published names and the catalog still refer to the block"]
pub struct QuarantinedBlock {
    /// The block file, relative to the store root.
    pub block: String,
    /// Where it is now.
    pub to: PathBuf,
}

/// What [`ColumnFamily::verify_all`] found wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum BlockProblem {
    /// A block that does not match the index, now in the quarantine.
    Quarantined(QuarantinedBlock),
    /// Index rows that point at missing blocks (their count).
    Dropped(usize),
}

impl std::fmt::Display for BlockProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Quarantined(q) => write!(f, "{}: does not match the index; moved to {}", q.block, q.to.display()),
            Self::Dropped(n) => {
                write!(f, "{n} index rows point at missing blocks (their points will be solved again)")
            }
        }
    }
}

/// Move the block file `block` (relative to the store root `root`) to `<root>/.quarantine/`;
/// its index rows are dropped by the next index read (the file is missing). Moves the file
/// only: what else must follow is the caller's (see [`QuarantinedBlock`]).
pub fn quarantine_block(root: &Path, block: &str) -> Result<QuarantinedBlock, CromError> {
    let q = root.join(".quarantine");
    std::fs::create_dir_all(&q).map_err(|e| CromError::io(&q, "creating the quarantine", e))?;
    let mut parts = Path::new(block).components().rev();
    let name = parts.next().map(|c| c.as_os_str().to_string_lossy().into_owned()).unwrap_or_default();
    let family: String =
        parts.nth(1).map(|c| c.as_os_str().to_string_lossy().chars().take(12).collect()).unwrap_or_default();
    let to = q.join(format!("columns-{family}-{}-{name}", unix_now()));
    let from = root.join(block);
    std::fs::rename(&from, &to).map_err(|e| CromError::io(&from, "moving a corrupt block aside", e))?;
    Ok(QuarantinedBlock { block: block.to_string(), to })
}

/// A solved snapshot waiting for its block.
#[derive(Debug, Clone)]
pub struct PendingColumn {
    /// Content key.
    pub key: Key,
    /// Parameter values.
    pub parameters: Vec<f64>,
    /// Primal field (n_dof).
    pub primal: Vec<f64>,
    /// Dual field (n_contact).
    pub dual: Vec<f64>,
    /// Solver evidence.
    pub evidence: Evidence,
}

fn write_block(path: &Path, meta: &FamilyMeta, cols: &[&PendingColumn]) -> Result<(), CromError> {
    let werr = |what: &str, e: hdf5::Error| {
        CromError::artifact(path, format!("HDF5 write of {what}: {e}"), "check free space and permissions of the store")
    };
    let b = cols.len();
    let file = hdf5::File::create(path).map_err(|e| werr("block", e))?;
    for (name, rows, units) in
        [("primal", meta.n_dof, meta.units[0].as_str()), ("dual", meta.n_contact, meta.units[1].as_str())]
    {
        let mut row_major = vec![0.0; rows * b];
        for (j, c) in cols.iter().enumerate() {
            let v = if name == "primal" { &c.primal } else { &c.dual };
            if v.len() != rows {
                return Err(CromError::artifact(
                    path,
                    format!("snapshot {} has {} {name} values, the family has {rows}", c.key.short(), v.len()),
                    "delete the column family and rerun",
                ));
            }
            for (i, x) in v.iter().enumerate() {
                row_major[i * b + j] = *x;
            }
        }
        let builder = file.new_dataset::<f64>().shape((rows, b));
        let ds = if rows == 0 { builder.create(name) } else { builder.chunk((rows, 1)).create(name) }
            .map_err(|e| werr(name, e))?;
        ds.write_raw(&row_major).map_err(|e| werr(name, e))?;
        let u: hdf5::types::VarLenUnicode = units.parse().map_err(|_| werr(name, hdf5::Error::from("units")))?;
        ds.new_attr::<hdf5::types::VarLenUnicode>()
            .create("units")
            .and_then(|a| a.write_scalar(&u))
            .map_err(|e| werr(name, e))?;
    }
    let p = meta.parameter_names.len();
    let params: Vec<f64> = cols.iter().flat_map(|c| c.parameters.iter().copied()).collect();
    let ds = file.new_dataset::<f64>().shape((b, p)).create("parameters").map_err(|e| werr("parameters", e))?;
    ds.write_raw(&params).map_err(|e| werr("parameters", e))?;
    file.close().map_err(|e| werr("close", e))
}

/// Read snapshot columns (in the order of `rows`) from their blocks into two column-major
/// matrices, checking every column against its blake3. A mismatch moves nothing (the caller
/// decides) and names the block.
pub fn read_columns(
    root: &Path,
    n_dof: usize,
    n_contact: usize,
    rows: &[&IndexRow],
) -> Result<(ColMatrix, ColMatrix), CromError> {
    let n = rows.len();
    let mut primal = ColMatrix { rows: n_dof, cols: n, data: vec![0.0; n_dof * n] };
    let mut dual = ColMatrix { rows: n_contact, cols: n, data: vec![0.0; n_contact * n] };
    let mut by_block: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (k, r) in rows.iter().enumerate() {
        by_block.entry(r.block.as_str()).or_default().push(k);
    }
    for (block, ks) in by_block {
        let path = root.join(block);
        let rerr = |what: &str, e: &dyn std::fmt::Display| CorruptBlock::error(&path, block, format!("{what}: {e}"));
        let file = hdf5::File::open(&path).map_err(|e| rerr("opening the block", &e))?;
        let pds = file.dataset("primal").map_err(|e| rerr("primal", &e))?;
        let dds = file.dataset("dual").map_err(|e| rerr("dual", &e))?;
        // Columns j0..j0 + len of a dataset (row-major in the block) into the output columns
        // k0..k0 + len of `out` (column-major, `rows` each): one HDF5 read per run.
        let read =
            |ds: &hdf5::Dataset, what: &str, (j0, k0, len): (usize, usize, usize), rows: usize, out: &mut [f64]| {
                if rows == 0 {
                    return Ok(());
                }
                let v = ds.read_slice_2d::<f64, _>((.., j0..j0 + len)).map_err(|e| rerr(what, &e))?;
                if v.dim() != (rows, len) {
                    return Err(rerr(what, &format!("{:?} values, expected ({rows}, {len})", v.dim())));
                }
                for (c, col) in out[k0 * rows..(k0 + len) * rows].chunks_exact_mut(rows).enumerate() {
                    col.iter_mut().zip(v.column(c)).for_each(|(a, b)| *a = *b);
                }
                Ok(())
            };
        // Runs of output columns that are consecutive columns of the block.
        let mut at = 0;
        while at < ks.len() {
            let (k0, j0) = (ks[at], rows[ks[at]].column);
            let mut len = 1;
            while at + len < ks.len() && ks[at + len] == k0 + len && rows[ks[at + len]].column == j0 + len {
                len += 1;
            }
            read(&pds, "primal columns", (j0, k0, len), n_dof, &mut primal.data)?;
            read(&dds, "dual columns", (j0, k0, len), n_contact, &mut dual.data)?;
            for (k, row) in rows.iter().enumerate().skip(k0).take(len) {
                let pcol = &primal.data[k * n_dof..(k + 1) * n_dof];
                let dcol = &dual.data[k * n_contact..(k + 1) * n_contact];
                if column_hash(pcol, dcol) != row.blake3 {
                    return Err(CorruptBlock::error(
                        &path,
                        block,
                        format!(
                            "column {} (snapshot {}) does not match its blake3 in the index",
                            row.column,
                            row.key.short()
                        ),
                    ));
                }
            }
            at += len;
        }
    }
    Ok((primal, dual))
}

/// Helper for the corrupt-block error.
struct CorruptBlock;

impl CorruptBlock {
    fn error(path: &Path, block: &str, message: String) -> CromError {
        CromError::CorruptColumns { path: path.to_path_buf(), block: block.to_string(), message, fix: FIX_CORRUPT }
    }
}

/// Names of files in `dir` ending in `ext` (without it), skipping temporary files; sorted.
fn list(dir: &Path, ext: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(ext) && !n.starts_with(".tmp"))
                .map(|n| n.trim_end_matches(ext).to_string())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// A `family.json`.
fn read_meta(path: &Path) -> Result<FamilyMeta, CromError> {
    let text = std::fs::read_to_string(path).map_err(|e| CromError::io(path, "reading", e))?;
    serde_json::from_str(&text).map_err(|e| {
        CromError::artifact(
            path,
            format!("not a column-family description: {e}"),
            "delete the family directory and rerun",
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> FamilyMeta {
        FamilyMeta {
            schema_version: COLUMNS_SCHEMA_VERSION,
            family: Key("f".repeat(64)),
            scene: "t".into(),
            n_dof: 5,
            n_contact: 3,
            parameter_names: vec!["mu".into()],
            units: ["m".into(), "N/m".into()],
        }
    }

    fn pending(i: usize) -> PendingColumn {
        PendingColumn {
            key: Key(format!("{i:064}")),
            parameters: vec![i as f64 * 0.5],
            primal: (0..5).map(|r| (r * 10 + i) as f64).collect(),
            dual: (0..3).map(|r| (r + i) as f64 * 0.25).collect(),
            evidence: Evidence { iterations: i as u64, ..Evidence::default() },
        }
    }

    #[test]
    fn blocks_commit_index_compacts_and_columns_read_back_exactly() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let fam = ColumnFamily::open(tmp.path(), meta()).expect("open");
        let a: Vec<PendingColumn> = (0..3).map(pending).collect();
        let b: Vec<PendingColumn> = (3..5).map(pending).collect();
        fam.commit_block(&a).expect("block a");
        fam.commit_block(&b).expect("block b");
        let index = fam.load_index().expect("index");
        assert_eq!(index.rows.len(), 5);
        fam.compact(&index).expect("compact");
        assert!(list(&fam.dir().join("index"), ".parquet").is_empty(), "fragments folded into index.parquet");
        let again = fam.load_index().expect("index after compaction");
        assert_eq!(again.rows.len(), 5);
        let order: Vec<&IndexRow> = [4, 0, 3].iter().map(|&i| &again.rows[&pending(i).key]).collect();
        let (p, d) = read_columns(tmp.path(), 5, 3, &order).expect("read");
        for (k, &i) in [4usize, 0, 3].iter().enumerate() {
            // Stored and read as f64 bit patterns: exact.
            assert_eq!(p.col(k), pending(i).primal.as_slice());
            assert_eq!(d.col(k), pending(i).dual.as_slice());
        }
        assert_eq!(again.rows[&pending(4).key].evidence.iterations, 4);
        // Runs of consecutive columns (read in one piece), a reversed pair, a gap and a repeat.
        let picks = [0usize, 1, 2, 4, 3, 1, 3, 4];
        let order: Vec<&IndexRow> = picks.iter().map(|&i| &again.rows[&pending(i).key]).collect();
        let (p, d) = read_columns(tmp.path(), 5, 3, &order).expect("read runs");
        for (k, &i) in picks.iter().enumerate() {
            assert_eq!(p.col(k), pending(i).primal.as_slice(), "column {k}");
            assert_eq!(d.col(k), pending(i).dual.as_slice(), "column {k}");
        }
    }

    #[test]
    fn a_flipped_byte_is_caught_and_a_missing_block_drops_its_rows() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let fam = ColumnFamily::open(tmp.path(), meta()).expect("open");
        let rows = fam.commit_block(&(0..4).map(pending).collect::<Vec<_>>()).expect("block");
        let path = tmp.path().join(&rows[0].block);
        // Overwrite one stored value of column 2 without changing the size: the column hash
        // must catch it (a float that differs in one bit).
        let index = fam.load_index().expect("index");
        let (p, _) = read_columns(tmp.path(), 5, 3, &[&index.rows[&rows[2].key]]).expect("clean read");
        let mut bytes = std::fs::read(&path).expect("read block");
        let needle = p.col(0)[1].to_le_bytes();
        let at = bytes.windows(8).position(|w| w == needle).expect("value in the file");
        bytes[at] ^= 1;
        std::fs::write(&path, &bytes).expect("write");
        let err = read_columns(tmp.path(), 5, 3, &[&index.rows[&rows[2].key]]).expect_err("corrupt");
        assert!(matches!(err, CromError::CorruptColumns { .. }), "{err}");
        let (checked, problems) = fam.verify_all().expect("verify");
        assert_eq!((checked, problems.len()), (1, 1), "{problems:?}");
        assert!(!path.exists(), "the corrupt block is quarantined");
        assert_eq!(fam.load_index().expect("index").rows.len(), 0, "its rows are dropped");
    }

    #[test]
    fn the_column_hash_is_the_hash_of_the_values_bytes_in_order() {
        // Long enough to span several pieces; the reference hashes one value at a time.
        let primal: Vec<f64> = (0..20_000).map(|i| (i as f64).sin()).collect();
        let dual: Vec<f64> = (0..37).map(|i| i as f64 * 0.5).collect();
        let mut h = blake3::Hasher::new();
        for v in primal.iter().chain(&dual) {
            h.update(&v.to_le_bytes());
        }
        assert_eq!(column_hash(&primal, &dual), h.finalize().to_hex().to_string());
    }

    #[test]
    fn an_uncommitted_block_leaves_nothing() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let fam = ColumnFamily::open(tmp.path(), meta()).expect("open");
        let kept = fam.commit_block(&[pending(0)]).expect("block");
        let rows = fam.commit_block(&[pending(1), pending(2)]).expect("block");
        fam.uncommit(&rows[0].block).expect("uncommit");
        assert!(!tmp.path().join(&rows[0].block).exists());
        let index = fam.load_index().expect("index");
        assert_eq!(index.rows.keys().collect::<Vec<_>>(), vec![&kept[0].key]);
        assert_eq!(fam.clean_orphans().expect("clean"), 0, "nothing left behind");
    }

    #[test]
    fn a_block_without_its_fragment_is_an_orphan() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let fam = ColumnFamily::open(tmp.path(), meta()).expect("open");
        let rows = fam.commit_block(&[pending(0)]).expect("block");
        let id = Path::new(&rows[0].block).file_stem().and_then(|s| s.to_str()).expect("id").to_string();
        std::fs::remove_file(fam.dir().join("index").join(format!("{id}.parquet"))).expect("drop fragment");
        assert_eq!(fam.load_index().expect("index").rows.len(), 0);
        assert_eq!(fam.clean_orphans().expect("clean"), 1);
        assert!(!tmp.path().join(&rows[0].block).exists());
    }

    #[test]
    fn a_family_with_other_shapes_is_refused() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        ColumnFamily::open(tmp.path(), meta()).expect("open");
        let mut other = meta();
        other.n_dof = 6;
        let err = ColumnFamily::open(tmp.path(), other).expect_err("mismatch");
        assert!(err.to_string().contains("delete the family directory"), "{err}");
    }
}
