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
    out.push(save(&d.tradeoff, dir, "table_tradeoff", "Speed/accuracy trade over the test points")?);
    Ok(out)
}
