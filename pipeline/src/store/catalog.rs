//! `catalog.parquet`: one row per artifact and per snapshot column family, so that
//! `pandas.read_parquet("data/store/catalog.parquet")` answers "what is in this store" without
//! reading a manifest or knowing a hash.
//!
//! The manifests are the source of truth; the catalog is derived from them and is rebuilt in
//! full (a few milliseconds per hundred artifacts) and replaced atomically — temporary file,
//! fsync, rename — whenever an artifact is committed, a scene's names are published or
//! something is quarantined. A reader therefore always sees a complete catalog, and a stale
//! one (e.g. after a killed run) is repaired by the next commit or by `crom catalog`. Snapshot
//! blocks do not rewrite it on every commit (a sweep commits many); a family's row is brought
//! up to date by the next artifact commit.

use std::collections::BTreeMap;
use std::path::Path;

use crom_schemas::artifact::{basis as basis_names, catalog as names, ArtifactKind};

use super::fs::write_atomic;
use super::manifest::{self, Manifest};
use super::{columns, published};
use crate::error::CromError;
use crate::io::table::{Column, Table};

/// One row of the catalog (see [`names::COLUMNS`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CatalogRow {
    /// Stage name, or `columns` for a snapshot column family.
    pub stage: String,
    /// Scene that first produced it.
    pub scene: String,
    /// Training-set name (train / test / nested-k), else empty.
    pub set: String,
    /// Basis groups the artifact holds (basis stage), else empty.
    pub bases: String,
    /// Key (directory name).
    pub key: String,
    /// Input keys by role, as a JSON object.
    pub inputs: String,
    /// Layout version.
    pub schema_version: u64,
    /// Algorithm version of the stage.
    pub algorithm_version: u64,
    /// crom version that wrote it.
    pub crom_version: String,
    /// Creation time, seconds since the Unix epoch.
    pub created_unix: u64,
    /// Creation time, ISO 8601 UTC.
    pub created: String,
    /// Total size of its files, bytes.
    pub bytes: u64,
    /// Number of files.
    pub files: u64,
    /// Directory relative to the store root.
    pub path: String,
    /// `scene/name` entries that point at it, comma-separated.
    pub published: String,
}

impl CatalogRow {
    fn from_manifest(m: &Manifest) -> Self {
        let set = m.parameters.get("set").and_then(|v| v.as_str()).unwrap_or_default().to_string();
        let bases = if m.stage == ArtifactKind::BASIS.name() {
            [basis_names::PRIMAL_POD, basis_names::DUAL_POD, basis_names::DUAL_CPG, basis_names::DUAL_CPG_TRUNCATED]
                .join(",")
        } else {
            String::new()
        };
        // A set's inputs are its snapshots (thousands of keys, listed in its solver_stats.parquet):
        // summarised by their count.
        let mut inputs: BTreeMap<&str, serde_json::Value> = BTreeMap::new();
        let mut snapshots = 0usize;
        for (role, key) in &m.inputs {
            if role.starts_with("snapshot") {
                snapshots += 1;
            } else {
                inputs.insert(role, serde_json::Value::from(key.0.clone()));
            }
        }
        if snapshots > 0 {
            inputs.insert("snapshots", serde_json::Value::from(snapshots));
        }
        Self {
            stage: m.stage.clone(),
            scene: m.scene.clone(),
            set,
            bases,
            key: m.key.0.clone(),
            inputs: serde_json::to_string(&inputs).unwrap_or_default(),
            schema_version: u64::from(m.schema_version),
            algorithm_version: u64::from(m.algorithm_version),
            crom_version: m.crom_version.clone(),
            created_unix: m.created_unix,
            created: iso_utc(m.created_unix),
            bytes: m.files.iter().map(|f| f.bytes).sum(),
            files: m.files.len() as u64,
            path: format!("{}/{}", m.stage, m.key.0),
            published: String::new(),
        }
    }

    fn from_family(root: &Path, fam: &columns::ColumnFamily) -> Self {
        let meta = fam.meta();
        let (mut bytes, mut files, mut created) = (0u64, 0u64, u64::MAX);
        let mut visit = |dir: &Path| {
            for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
                if let Ok(md) = e.metadata() {
                    if md.is_file() && !e.file_name().to_string_lossy().starts_with(".tmp") {
                        bytes += md.len();
                        files += 1;
                        let t = md.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
                        created = created.min(t.map_or(u64::MAX, |d| d.as_secs()));
                    }
                }
            }
        };
        for sub in ["", "blocks", "index"] {
            visit(&fam.dir().join(sub));
        }
        let created = if created == u64::MAX { 0 } else { created };
        let rel = fam.dir().strip_prefix(root).unwrap_or(fam.dir());
        Self {
            stage: columns::COLUMNS_DIR.to_string(),
            scene: meta.scene.clone(),
            set: String::new(),
            bases: String::new(),
            key: meta.family.0.clone(),
            inputs: "{}".to_string(),
            schema_version: u64::from(meta.schema_version),
            algorithm_version: 0,
            crom_version: String::new(),
            created_unix: created,
            created: iso_utc(created),
            bytes,
            files,
            path: rel.to_string_lossy().into_owned(),
            published: String::new(),
        }
    }
}

/// Every row of the store at `root`, built from the manifests, the column families and the
/// published scene names; in DAG order of the stages (families first), then by creation time
/// and key.
pub fn rows(root: &Path) -> Vec<CatalogRow> {
    let mut rows: Vec<CatalogRow> = columns::families(root).iter().map(|f| CatalogRow::from_family(root, f)).collect();
    let mut artifacts: Vec<CatalogRow> = manifest::read_all(root).iter().map(CatalogRow::from_manifest).collect();
    let order = |s: &str| ArtifactKind::order_of(s);
    artifacts.sort_by(|a, b| {
        order(&a.stage).cmp(&order(&b.stage)).then(a.created_unix.cmp(&b.created_unix)).then(a.key.cmp(&b.key))
    });
    rows.extend(artifacts);
    let mut names: BTreeMap<(String, String), Vec<String>> = BTreeMap::new();
    for (scene, study) in published::studies(root) {
        for (name, e) in study.entries {
            names.entry((e.stage, e.key.0)).or_default().push(format!("{scene}/{name}"));
        }
    }
    for r in &mut rows {
        if let Some(n) = names.get(&(r.stage.clone(), r.key.clone())) {
            r.published = n.join(",");
        }
    }
    rows
}

/// The rows as a table with the columns of [`names::COLUMNS`], in that order.
pub fn table(rows: &[CatalogRow]) -> Table {
    let s = |f: &dyn Fn(&CatalogRow) -> &str| Column::Str(rows.iter().map(|r| f(r).to_string()).collect());
    let u = |f: &dyn Fn(&CatalogRow) -> u64| Column::U64(rows.iter().map(f).collect());
    let cols = [
        s(&|r| &r.stage),
        s(&|r| &r.scene),
        s(&|r| &r.set),
        s(&|r| &r.bases),
        s(&|r| &r.key),
        s(&|r| &r.inputs),
        u(&|r| r.schema_version),
        u(&|r| r.algorithm_version),
        s(&|r| &r.crom_version),
        u(&|r| r.created_unix),
        s(&|r| &r.created),
        u(&|r| r.bytes),
        u(&|r| r.files),
        s(&|r| &r.path),
        s(&|r| &r.published),
    ];
    names::COLUMNS.iter().zip(cols).fold(Table::default(), |t, (n, c)| t.with(n, c))
}

/// Rebuild `catalog.parquet` of the store at `root` and replace it atomically.
///
/// Serialised within the process (stages commit from more than one thread): each refresh
/// lists the store after every rename that came before it, so the last one written holds
/// every artifact.
pub fn refresh(root: &Path) -> Result<std::path::PathBuf, CromError> {
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let path = root.join(names::FILE);
    let mut bytes = Vec::new();
    table(&rows(root)).write_parquet_to(&mut bytes).map_err(|e| {
        CromError::artifact(&path, format!("Parquet write: {e}"), "check free space and permissions of the store")
    })?;
    write_atomic(&path, &bytes)?;
    Ok(path)
}

/// `YYYY-MM-DDTHH:MM:SSZ` of a Unix time (proleptic Gregorian calendar, UTC).
pub fn iso_utc(unix: u64) -> String {
    let days = (unix / 86_400) as i64;
    let secs = unix % 86_400;
    // Civil date from days since 1970-01-01 (H. Hinnant's `civil_from_days`).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", secs / 3600, secs % 3600 / 60, secs % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_dates_match_known_instants() {
        // Reference instants from the definition of Unix time (86 400 s per day since
        // 1970-01-01): 2000-03-01 is 11 017 days later, 2000 being a leap year.
        assert_eq!(iso_utc(0), "1970-01-01T00:00:00Z");
        assert_eq!(iso_utc(11_017 * 86_400 - 1), "2000-02-29T23:59:59Z");
        assert_eq!(iso_utc(11_017 * 86_400), "2000-03-01T00:00:00Z");
        // 2100 is not a leap year (divisible by 100, not by 400): 2100-03-01 is 47 541 days in.
        assert_eq!(iso_utc(47_541 * 86_400 - 1), "2100-02-28T23:59:59Z");
        assert_eq!(iso_utc(1_234_567_890), "2009-02-13T23:31:30Z");
    }

    #[test]
    fn table_has_the_contract_columns_in_order() {
        let t = table(&[]);
        let got: Vec<&str> = t.columns.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(got, names::COLUMNS);
    }
}
