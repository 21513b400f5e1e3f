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

/// The columns of the trade-off table that say how stable each rank pair's reduced system is.
fn stability_view(t: &Table) -> Table {
    let mut v = Table::default();
    for name in
        ["algorithm", "dual_basis", "r_primal", "r_dual", "points", "converged", "min_inf_sup", "median_inf_sup"]
    {
        if let Some((_, c)) = t.columns.iter().find(|(n, _)| n == name) {
            v = v.with(name, c.clone());
        }
    }
    v
}

/// Write every table; returns them for the index.
pub(crate) fn write_all(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Vec<ReportTable>, CromError> {
    let [pr, _, cr, ctr] = d.ranks;
    let r_online = d.rom_errors.u64s("r_primal").and_then(|v| v.first().copied()).unwrap_or(0);
    let st = &scene.study;
    let mut ranks = Table::default()
        .with("basis_set", Column::Str(vec!["full".into(), "truncated".into()]))
        .with("primal_tolerance", Column::F64(vec![st.primal_tol, st.primal_tol]))
        .with("primal_rank", Column::U64(vec![pr as u64, pr as u64]));
    if d.online {
        ranks = ranks.with("online_primal_rank", Column::U64(vec![r_online, r_online]));
    }
    let ranks = ranks
        .with("dual_cpg_tolerance", Column::F64(vec![st.dual_cone_tol, st.dual_cone_tol_truncated]))
        .with("dual_cpg_rank", Column::U64(vec![cr as u64, ctr as u64]));
    let title = if d.online {
        "Truncation tolerances and ranks of each basis (paper Tables 1–2); online_primal_rank is the POD rank of the contact responses used online"
    } else {
        "Truncation tolerances and ranks of each basis (paper Tables 1–2)"
    };
    let mut out = vec![save(&ranks, dir, "table_ranks", title)?];
    if d.online {
        out.extend(online_tables(d, dir)?);
    }
    out.push(save(
        &d.conditioning,
        dir,
        "table_conditioning",
        "Stability: conditioning of the stiffness on the free dofs (power and inverse iteration with the solver's factor; the ratio is a lower bound on kappa_2) and of the CPG generators' Gram after each selection (Hager's 1-norm estimate; it bounds every NNLS Gram of that step, each a principal submatrix; per step in basis.h5, gram_rcond)",
    )?);
    out.extend(comparison_tables(d, dir)?);
    Ok(out)
}

/// The online stage's tables: the trade-off and the stability of each rank pair.
fn online_tables(d: &ReportData, dir: &Path) -> Result<Vec<ReportTable>, CromError> {
    Ok(vec![
        save(
        &tradeoff_view(&d.tradeoff),
        dir,
        "table_tradeoff",
        &format!("Speed/accuracy trade over the test points: errors over converged points, times over the timed points ({} evenly spaced, or all of fewer; ms), speed-up = median full-order time / median online time in the same process, ρ = Spearman rank correlation of the indicator with the true error", crate::dag::timing::TIMED_POINTS),
    )?,
    save(
        &stability_view(&d.tradeoff),
        dir,
        "table_stability",
        "Stability of the reduced saddle-point system per rank pair: the reduced inf-sup constant beta = sigma_min(Â L^-T) (Â the reduced constraint rows of the dual vectors that constrain at the query's pairing, K̂ = L Lᵀ) at 8 evenly spaced test points, min and median over the converged ones; 0 = more constraining dual vectors than primal modes (r_dual > r_primal) or than paired contact nodes under them, or nearly parallel dual vectors: the multipliers are not unique",
    )?,
    ])
}

/// The comparison's tables, for scenes with `[comparison]`.
fn comparison_tables(d: &ReportData, dir: &Path) -> Result<Vec<ReportTable>, CromError> {
    let mut out = Vec::new();
    if let Some(c) = &d.comparison {
        out.push(save(
            &comparison_view(c),
            dir,
            "table_comparison",
            "What breaks the low-rank limit: smallest m (modes, generators or active atoms) at which each dual approximation's mean relative error reaches 5 %, 1 % and 0.1 %, on the test set (T) and by leave-one-out (G); \"never\" = not within the curve; T at m = 5 beside them",
        )?);
        if let Some(t) = &c.online {
            out.push(save(
                &online_view(t),
                dir,
                "table_comparison_online",
                "The online solve with each non-negative dual approximation (exact algorithm, full primal basis) over the test points: converged / refused / failed, median errors over converged points, median online time (ms), speed-up against the full-order solve timed in the same process, and the median number of non-zero dual coefficients (active atoms)",
            )?);
        }
        if c.cells.rows() > 0 {
            out.push(save(
                &cells_view(&c.cells),
                dir,
                "table_comparison_cells",
                "Local bases per cell: the test points and the mean relative test error of the points in each cell, at 1 and 5 generators and at the largest m (all rows, and leave-one-out per cell, in comparison_cells.parquet)",
            )?);
        }
        out.push(save(
            &facts_view(&c.facts),
            dir,
            "table_comparison_facts",
            "How each dual approximation was built: a registration's reference grid and round-trip error ||push(pull(s)) - s|| / ||s|| over the training snapshots, NNMF's HALS sweeps and relative residual per rank (m <= 8 shown; all in comparison_facts.parquet), local bases' snapshots and generators per cell",
        )?);
        out.push(save(
            &c.timings,
            dir,
            "table_comparison_builds",
            "Offline cost of each dual approximation (seconds): one build from the whole training set, and the metrics (a rebuild per leave-one-out fold)",
        )?);
    }
    Ok(out)
}

/// The columns of the online comparison a reader compares.
fn online_view(t: &Table) -> Table {
    let mut v = Table::default();
    for name in [
        "approximation",
        "m",
        "points",
        "converged",
        "infeasible",
        "failed",
        "median_primal_error",
        "median_dual_error",
        "median_online_ms",
        "speedup",
        "median_nonzero_dual",
    ] {
        if let Some((_, c)) = t.columns.iter().find(|(n, _)| n == name) {
            v = v.with(name, c.clone());
        }
    }
    v
}

/// Per (local approximation, cell): test points and T at m = 1, 5 and the largest m.
fn cells_view(t: &Table) -> Table {
    let (Some(a), Some(cell), Some(metric), Some(m), Some(mean), Some(count)) =
        (t.strs("approximation"), t.u64s("cell"), t.strs("metric"), t.u64s("m"), t.f64s("mean"), t.u64s("count"))
    else {
        return Table::default();
    };
    let test: Vec<usize> = (0..a.len()).filter(|&i| metric[i] == "test").collect();
    let mut keys: Vec<(String, u64)> = Vec::new();
    for &i in &test {
        if !keys.contains(&(a[i].clone(), cell[i])) {
            keys.push((a[i].clone(), cell[i]));
        }
    }
    let at = |k: &(String, u64), pick: &dyn Fn(&[usize]) -> Option<usize>| -> Option<usize> {
        let rows: Vec<usize> = test.iter().copied().filter(|&i| a[i] == k.0 && cell[i] == k.1).collect();
        pick(&rows)
    };
    let value = |k: &(String, u64), mm: Option<u64>| -> f64 {
        at(k, &|rows: &[usize]| match mm {
            Some(mm) => rows.iter().copied().find(|&i| m[i] == mm),
            None => rows.iter().copied().max_by_key(|&i| m[i]),
        })
        .map_or(f64::NAN, |i| mean[i])
    };
    Table::default()
        .with("approximation", Column::Str(keys.iter().map(|k| k.0.clone()).collect()))
        .with("cell", Column::U64(keys.iter().map(|k| k.1).collect()))
        .with(
            "test_points",
            Column::U64(
                keys.iter().map(|k| at(k, &|r: &[usize]| r.first().copied()).map_or(0, |i| count[i])).collect(),
            ),
        )
        .with("T(1)", Column::F64(keys.iter().map(|k| value(k, Some(1))).collect()))
        .with("T(5)", Column::F64(keys.iter().map(|k| value(k, Some(5))).collect()))
        .with("T(max m)", Column::F64(keys.iter().map(|k| value(k, None)).collect()))
}

/// The build facts without a rank, and those of ranks up to 8.
fn facts_view(f: &Table) -> Table {
    let (Some(a), Some(n), Some(m), Some(v)) = (f.strs("approximation"), f.strs("name"), f.f64s("m"), f.f64s("value"))
    else {
        return Table::default();
    };
    let keep: Vec<usize> = (0..a.len()).filter(|&i| !m[i].is_finite() || m[i] <= 8.0).collect();
    Table::default()
        .with("approximation", Column::Str(keep.iter().map(|&i| a[i].clone()).collect()))
        .with("name", Column::Str(keep.iter().map(|&i| n[i].clone()).collect()))
        .with(
            "m",
            Column::Str(
                keep.iter()
                    .map(|&i| if m[i].is_finite() { format!("{}", m[i] as u64) } else { String::new() })
                    .collect(),
            ),
        )
        .with("value", Column::F64(keep.iter().map(|&i| v[i]).collect()))
}

/// One row per approximation: the m reaching each threshold (test and leave-one-out) and the
/// test error at m = 5.
fn comparison_view(c: &super::ComparisonData) -> Table {
    let r = &c.reached;
    let (Some(a), Some(metric), Some(th), Some(m)) =
        (r.strs("approximation"), r.strs("metric"), r.f64s("threshold"), r.f64s("m"))
    else {
        return Table::default();
    };
    let names = super::figures::names_of(r);
    let mut t = Table::default().with("approximation", Column::Str(names.clone()));
    for (which, label) in [("test", "T"), ("generalization", "G")] {
        for level in crom_schemas::artifact::comparison::THRESHOLDS {
            let col = names
                .iter()
                .map(|n| {
                    (0..a.len())
                        .find(|&i| {
                            &a[i] == n
                                && metric[i] == which
                                && crom_stages::float_cmp::close(th[i], level, crom_stages::float_cmp::Tol::rel(1e-12))
                        })
                        .map(|i| if m[i].is_finite() { format!("{}", m[i] as u64) } else { "never".into() })
                        .unwrap_or_default()
                })
                .collect();
            t = t.with(&format!("{label} <= {}%", level * 100.0), Column::Str(col));
        }
    }
    let curves = &c.curves;
    if let (Some(ca), Some(ck), Some(cm), Some(cv)) =
        (curves.strs("approximation"), curves.strs("metric"), curves.u64s("m"), curves.f64s("mean"))
    {
        let at5 = names
            .iter()
            .map(|n| (0..ca.len()).find(|&i| &ca[i] == n && ck[i] == "test" && cm[i] == 5).map_or(f64::NAN, |i| cv[i]))
            .collect();
        t = t.with("T(5)", Column::F64(at5));
    }
    t
}
