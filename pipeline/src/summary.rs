//! What a run tells the user at the end, and `crom ls`.

use std::io::Write;

use crom_schemas::artifact::ArtifactKind;

use crate::dag::Ctx;
use crate::store::Store;

/// The closing summary of `crom run`: what ran, what came from cache, where the artifacts are.
/// Output errors (a closed pipe) are ignored: the summary is informational.
pub(crate) fn print_run(ctx: &Ctx<'_>, seconds: f64, ok: bool, report: Option<&std::path::Path>) {
    let mut out = std::io::stdout().lock();
    let name = &ctx.scene.scene.name;
    let _ = writeln!(out, "crom run {name}: {} in {seconds:.2} s", if ok { "done" } else { "stopped" });
    let _ = writeln!(out, "  {:<15} {:>9} {:>7}  artifact", "stage", "computed", "cached");
    for r in &ctx.records {
        let _ = writeln!(out, "  {:<15} {:>9} {:>7}  {}", r.stage, r.computed, r.cached, r.dir.display());
    }
    let p = ctx.points;
    if p.solved + p.reused + p.failed > 0 {
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

/// `crom ls`: one line per artifact.
pub(crate) fn print_ls(store: &Store, stage: Option<&str>) {
    let mut out = std::io::stdout().lock();
    let mut all = store.catalog();
    let order = |s: &str| ArtifactKind::from_name(s).map_or(usize::MAX, |k| k as usize);
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
}

/// `crom verify`: full re-hash of every artifact and every snapshot block.
pub(crate) fn verify(store: &Store) -> Result<(), crate::error::CromError> {
    let mut out = std::io::stdout().lock();
    let mut problems = Vec::new();
    let mut checked = 0;
    for m in store.catalog() {
        let Some(kind) = ArtifactKind::from_name(&m.stage) else { continue };
        checked += 1;
        if let crate::store::Lookup::Quarantined(to, why) = store.lookup(kind, &m.key)? {
            problems.push(format!("{}/{}: {why}; moved to {}", m.stage, m.key.short(), to.display()));
        }
    }
    let mut blocks = 0;
    for fam in store.families() {
        let (n, p) = fam.verify_all()?;
        blocks += n;
        problems.extend(p);
    }
    for p in &problems {
        let _ = writeln!(out, "  FAILED {p}");
    }
    let _ = writeln!(
        out,
        "crom verify: {checked} artifacts and {blocks} snapshot blocks checked, {} problems in {}",
        problems.len(),
        store.root().display()
    );
    if problems.is_empty() {
        Ok(())
    } else {
        Err(crate::error::CromError::artifact(
            store.root(),
            format!("{} problems found (listed above); the damaged files are in .quarantine", problems.len()),
            "rerun the affected scenes: what was moved aside is recomputed",
        ))
    }
}
