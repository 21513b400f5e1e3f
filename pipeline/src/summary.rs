//! What a run tells the user at the end, and `crom ls`.

use std::io::{IsTerminal, Write};

use crom_schemas::artifact::ArtifactKind;

use crate::cli::LsFormat;
use crate::dag::Ctx;
use crate::error::CromError;
use crate::store::{catalog, Store};

/// The closing summary of `crom run`: what ran, what came from cache, where the artifacts are.
/// Output errors (a closed pipe) are ignored: the summary is informational.
pub(crate) fn print_run(
    ctx: &Ctx<'_>,
    scene: &crom_schemas::SceneConfig,
    seconds: f64,
    ok: bool,
    report: Option<&std::path::Path>,
) {
    let mut out = std::io::stdout().lock();
    let name = &ctx.scene_name;
    let _ = writeln!(out, "crom run {name}: {} in {seconds:.2} s", if ok { "done" } else { "stopped" });
    let _ = writeln!(out, "  {:<21} {:>9} {:>7}  artifact", "stage", "computed", "cached");
    for r in &ctx.records {
        let _ = writeln!(out, "  {:<21} {:>9} {:>7}  {}", r.stage, r.computed, r.cached, r.dir.display());
    }
    let p = ctx.points;
    if scene.model.external().is_some() {
        let _ = writeln!(out, "  snapshots: {} imported, {} reused from the store", p.solved, p.reused);
    } else if p.solved + p.reused + p.failed > 0 {
        let _ = writeln!(
            out,
            "  snapshots: {} solved, {} reused from the store, {} missing (failed; retried by the next run)",
            p.solved, p.reused, p.failed
        );
    }
    for w in &ctx.warnings {
        let _ = writeln!(out, "  warning: {w}");
    }
    let computed: usize = ctx.records.iter().map(|r| r.computed).sum();
    if ok && computed == 0 {
        let _ = writeln!(out, "  nothing computed: every artifact came from the cache");
    }
    let _ = writeln!(out, "  store: {}", ctx.store.root().display());
    if let Some(r) = report {
        let _ = writeln!(out, "  report: {}", r.join("index.html").display());
    }
}

/// `crom ls`: the store's contents, as aligned text for people or as the catalog's rows
/// ([`crate::store::catalog`]) in CSV, JSON or Parquet for programs; to `output` (written
/// atomically) or standard output.
pub(crate) fn ls(
    store: &Store,
    stage: Option<&str>,
    format: LsFormat,
    output: Option<&std::path::Path>,
) -> Result<(), CromError> {
    if let Some(s) = stage {
        let stored = || store.manifests().iter().any(|m| m.stage == s);
        if s != "columns" && s != "snapshot" && ArtifactKind::from_name(s).is_none() && !stored() {
            let known: Vec<&str> =
                std::iter::once("columns").chain(ArtifactKind::ALL.iter().map(|k| k.name())).collect();
            return Err(CromError::Usage {
                message: format!("--stage {s}: no such stage"),
                fix: format!("use one of: {}", known.join(", ")),
            });
        }
    }
    let bytes = match format {
        LsFormat::Text => text_listing(store, stage).into_bytes(),
        _ => {
            let rows: Vec<catalog::CatalogRow> = catalog::rows(store.root())
                .into_iter()
                .filter(|r| stage.is_none_or(|s| s == r.stage || (s == "snapshot" && r.stage == "columns")))
                .collect();
            let t = catalog::table(&rows);
            match format {
                LsFormat::Csv => t.to_csv().into_bytes(),
                LsFormat::Json => {
                    let mut b = serde_json::to_vec_pretty(&t.to_json_records()).unwrap_or_default();
                    b.push(b'\n');
                    b
                }
                _ => {
                    if output.is_none() && std::io::stdout().is_terminal() {
                        return Err(CromError::Usage {
                            message: "--format parquet writes binary data, and standard output is a terminal".into(),
                            fix: "redirect it (crom ls --format parquet > catalog.parquet) or give --output FILE"
                                .into(),
                        });
                    }
                    let mut b = Vec::new();
                    t.write_parquet_to(&mut b).map_err(|e| CromError::Usage {
                        message: format!("cannot encode the listing as Parquet: {e}"),
                        fix: "use --format csv or json".into(),
                    })?;
                    b
                }
            }
        }
    };
    match output {
        Some(path) => crate::store::fs::write_atomic(path, &bytes),
        None => {
            // A closed pipe (e.g. `| head`) is not an error of the listing.
            let _ = std::io::stdout().lock().write_all(&bytes);
            Ok(())
        }
    }
}

/// The human listing: one line per artifact, then the column families.
fn text_listing(store: &Store, stage: Option<&str>) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let mut all = store.manifests();
    let order = |s: &str| ArtifactKind::order_of(s);
    all.sort_by(|a, b| order(&a.stage).cmp(&order(&b.stage)).then(a.created_unix.cmp(&b.created_unix)));
    let _ = writeln!(out, "{:<12} {:<14} {:<16} {:>9}  summary", "stage", "key", "scene", "wall [s]");
    let mut n = 0;
    for m in all.iter().filter(|m| stage.is_none_or(|s| s == m.stage)) {
        let facts: Vec<String> = m.summary.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let _ = writeln!(
            out,
            "{:<12} {:<14} {:<16} {:>9.3}  {}",
            m.stage,
            m.key.short(),
            m.scene,
            m.wall_seconds,
            facts.join(" ")
        );
        n += 1;
    }
    let _ = writeln!(out, "{n} artifacts in {}", store.root().display());
    if stage.is_none_or(|s| s == "columns" || s == "snapshot") {
        for fam in store.families() {
            let meta = fam.meta();
            match fam.load_index() {
                Ok(index) => {
                    let blocks: std::collections::BTreeSet<&str> =
                        index.rows.values().map(|r| r.block.as_str()).collect();
                    let _ = writeln!(
                        out,
                        "columns {:<14} {:<16} {} snapshots ({} x {}) in {} blocks: {}",
                        meta.family.short(),
                        meta.scene,
                        index.rows.len(),
                        meta.n_dof,
                        meta.n_contact,
                        blocks.len(),
                        fam.dir().join("index.parquet").display()
                    );
                }
                Err(e) => {
                    let _ = writeln!(out, "columns {:<14} unreadable index: {e}", meta.family.short());
                }
            }
        }
    }
    for (scene, study) in crate::store::published::studies(store.root()) {
        let _ = writeln!(
            out,
            "scene   {scene:<31} {} names in {}",
            study.entries.len(),
            store.root().join(crom_schemas::artifact::published::DIR).join(&scene).display()
        );
    }
    out
}

/// `crom verify`: full re-hash of every artifact and every snapshot block.
pub(crate) fn verify(store: &Store) -> Result<(), CromError> {
    let mut out = std::io::stdout().lock();
    let mut problems = Vec::new();
    let mut checked = 0;
    // A kind the build does not ship (a stage added with its own `ArtifactKind::new`) is
    // verified against its manifest's schema version; its name lives as long as the command.
    let mut other: Vec<ArtifactKind> = Vec::new();
    for m in store.manifests() {
        let kind = match ArtifactKind::from_name(&m.stage) {
            Some(k) => k,
            None => match other.iter().find(|k| k.name() == m.stage && k.schema_version() == m.schema_version) {
                Some(k) => *k,
                None => {
                    let name: &'static str = Box::leak(m.stage.clone().into_boxed_str());
                    other.push(ArtifactKind::new(name, m.schema_version));
                    other[other.len() - 1]
                }
            },
        };
        checked += 1;
        if let crate::store::Lookup::Quarantined(to, why) = store.lookup(kind, &m.key)? {
            problems.push(format!("{}/{}: {why}; moved to {}", m.stage, m.key.short(), to.display()));
        }
    }
    let mut blocks = 0;
    for fam in store.families() {
        let (n, p) = store.verify_family(&fam)?;
        blocks += n;
        problems.extend(p);
    }
    for p in &problems {
        let _ = writeln!(out, "  FAILED {p}");
    }
    catalog::refresh(store.root())?;
    let _ = writeln!(
        out,
        "crom verify: {checked} artifacts and {blocks} snapshot blocks checked, {} problems in {}",
        problems.len(),
        store.root().display()
    );
    if problems.is_empty() {
        Ok(())
    } else {
        Err(CromError::artifact(
            store.root(),
            format!("{} problems found (listed above); the damaged files are in .quarantine", problems.len()),
            "rerun the affected scenes: what was moved aside is recomputed",
        ))
    }
}
