//! The paper's Tables 1–2 (truncation tolerances and ranks) and the speed/accuracy table, as CSV
//! and Markdown.

use std::path::Path;

use crom_schemas::SceneConfig;

use super::ReportData;
use crate::error::CromError;
use crate::io::table::{Column, Table};

/// A table of the report: file stem, title, Markdown text.
#[derive(Debug, Clone)]
pub(crate) struct ReportTable {
    pub stem: String,
    pub title: String,
    pub markdown: String,
}

fn markdown(t: &Table) -> String {
    let names: Vec<&str> = t.columns.iter().map(|(n, _)| n.as_str()).collect();
    let mut s = format!("| {} |\n|{}\n", names.join(" | "), "---|".repeat(names.len()));
    for r in 0..t.rows() {
        let cells: Vec<String> = t
            .columns
            .iter()
            .map(|(_, c)| match c {
                Column::Str(v) => v[r].clone(),
                Column::U64(v) => v[r].to_string(),
                Column::F64(v) => format!("{:.4e}", v[r]),
            })
            .collect();
        s.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    s
}

fn save(t: &Table, dir: &Path, stem: &str, title: &str) -> Result<ReportTable, CromError> {
    t.write_csv(&dir.join(format!("{stem}.csv")))?;
    let md = markdown(t);
    let path = dir.join(format!("{stem}.md"));
    std::fs::write(&path, format!("# {title}\n\n{md}"))
        .map_err(|e| CromError::io(&path, "writing a Markdown table", e))?;
    Ok(ReportTable { stem: stem.to_string(), title: title.to_string(), markdown: md })
}

/// The columns of the trade-off table a reader compares (the Parquet file has all of them).
fn tradeoff_view(t: &Table) -> Table {
    let mut v = Table::default();
    for name in ["algorithm", "dual_basis", "r_primal", "r_dual", "points", "converged", "infeasible", "failed"] {
        if let Some((_, c)) = t.columns.iter().find(|(n, _)| n == name) {
            v = v.with(name, c.clone());
        }
    }
    for name in ["median_primal_error", "p95_primal_error", "median_dual_error"] {
        if let Some(c) = t.f64s(name) {
            v = v.with(name, Column::F64(c.to_vec()));
        }
    }
    for (name, label) in [
        ("median_online_seconds", "median_online_ms"),
        ("p95_online_seconds", "p95_online_ms"),
        ("median_fom_seconds", "median_fom_ms"),
    ] {
        if let Some(c) = t.f64s(name) {
            v = v.with(label, Column::F64(c.iter().map(|x| x * 1e3).collect()));
        }
    }
    for name in ["speedup", "indicator_spearman"] {
        if let Some(c) = t.f64s(name) {
            v = v.with(name, Column::F64(c.to_vec()));
        }
    }
    v
}

/// Write every table; returns them for the index.
pub(crate) fn write_all(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Vec<ReportTable>, CromError> {
    let [pr, _, cr, ctr] = d.ranks;
    let r_online = d.rom_errors.u64s("r_primal").and_then(|v| v.first().copied()).unwrap_or(0);
    let st = &scene.study;
    let ranks = Table::default()
        .with("basis_set", Column::Str(vec!["full".into(), "truncated".into()]))
        .with("primal_tolerance", Column::F64(vec![st.primal_tol, st.primal_tol]))
        .with("primal_rank", Column::U64(vec![pr as u64, pr as u64]))
        .with("online_primal_rank", Column::U64(vec![r_online, r_online]))
        .with("dual_cpg_tolerance", Column::F64(vec![st.dual_cone_tol, st.dual_cone_tol_truncated]))
        .with("dual_cpg_rank", Column::U64(vec![cr as u64, ctr as u64]));
    let mut out = vec![save(
        &ranks,
        dir,
        "table_ranks",
        "Truncation tolerances and ranks of each basis (paper Tables 1–2); online_primal_rank is the POD rank of the contact responses used online",
    )?];
    out.push(save(
        &tradeoff_view(&d.tradeoff),
        dir,
        "table_tradeoff",
        "Speed/accuracy trade over the test points: errors over converged points, times over all (ms), speed-up = median full-order time / median online time in the same process, ρ = Spearman rank correlation of the indicator with the true error",
    )?);
    Ok(out)
}
