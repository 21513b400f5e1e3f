//! `index.html`: every figure with its caption and the run's key numbers.

use std::path::Path;

use crom_schemas::SceneConfig;

use super::tables::ReportTable;
use super::{Figure, ReportData};
use crate::error::CromError;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// Write `index.html` into `dir`.
pub(crate) fn write_index(
    scene: &SceneConfig,
    d: &ReportData,
    figures: &[Figure],
    tables: &[ReportTable],
    dir: &Path,
) -> Result<(), CromError> {
    let [pr, dr, cr, ctr] = d.ranks;
    let facts = [
        ("scene".to_string(), esc(&scene.scene.name)),
        ("description".to_string(), esc(&scene.scene.description)),
        ("parameter".to_string(), parameter_fact(scene, d)),
        ("training snapshots".to_string(), d.train.parameters.len().to_string()),
        ("primal dofs / contact nodes".to_string(), format!("{} / {}", d.train.primal.rows, d.train.dual.rows)),
        ("primal POD rank (δ = ".to_string() + &scene.study.primal_tol.to_string() + ")", pr.to_string()),
        ("dual POD rank (δ = ".to_string() + &scene.study.dual_orth_tol.to_string() + ")", dr.to_string()),
        ("dual CPG rank (tol = ".to_string() + &scene.study.dual_cone_tol.to_string() + ")", cr.to_string()),
        (
            "truncated dual CPG rank (tol = ".to_string() + &scene.study.dual_cone_tol_truncated.to_string() + ")",
            ctr.to_string(),
        ),
    ];
    let mut facts = facts.to_vec();
    // a large test set is measured on a sample (the online stage's `measured`)
    let tests = scene.parameter.test_points().len();
    let measured = super::figures::rom_rows(d, "test", "full").0.len();
    let which = if super::figures::sampled(measured, tests) {
        format!("online solve, {measured} of the {tests} test points (drawn at random)")
    } else {
        "online solve, test points".to_string()
    };
    for basis in ["full", "truncated"] {
        if let Some(line) = online_summary(d, basis) {
            facts.push((format!("{which}, {basis} dual basis"), line));
        }
    }
    if let Some(m) = &d.model {
        facts.push(("stored reduced model (crom query)".to_string(), model_fact(scene, m)));
    }
    let mut html = String::new();
    html.push_str(&format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>crom report: {0}</title>\n<style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:4px 10px;text-align:left}}.wide{{overflow-x:auto;font-size:85%}}.wide td,.wide th{{padding:2px 6px}}figure{{margin:2em 0}}img{{max-width:100%;border:1px solid #eee}}figcaption{{color:#555}}</style></head><body>\n<h1>crom report: {0}</h1>\n<table>\n",
        esc(&scene.scene.name)
    ));
    for (k, v) in facts {
        html.push_str(&format!("<tr><th>{}</th><td>{v}</td></tr>\n", esc(&k)));
    }
    html.push_str("</table>\n");
    for f in figures {
        html.push_str(&format!(
            "<figure><img src=\"{0}.png\" alt=\"{1}\"><figcaption>{1} <a href=\"{0}.svg\">SVG</a></figcaption></figure>\n",
            f.stem,
            esc(&f.caption)
        ));
    }
    let skipped = skipped(scene, d);
    if !skipped.is_empty() {
        html.push_str("<h2>Not in this report</h2>\n<ul>\n");
        for line in skipped {
            html.push_str(&format!("<li>{}</li>\n", esc(line)));
        }
        html.push_str("</ul>\n");
    }
    for t in tables {
        html.push_str(&format!(
            "<h2>{}</h2>\n{}<p><a href=\"{}.csv\">CSV</a> · <a href=\"{}.md\">Markdown</a></p>\n",
            esc(&t.title),
            md_to_html(&t.markdown),
            t.stem,
            t.stem
        ));
    }
    html.push_str("</body></html>\n");
    let path = dir.join("index.html");
    std::fs::write(&path, html).map_err(|e| CromError::io(&path, "writing index.html", e))
}

/// The parameter's components with their ranges: the scene's for a native scene, the training
/// points' for an external one (its parameter values come from a file).
fn parameter_fact(scene: &SceneConfig, d: &ReportData) -> String {
    let p = &scene.parameter;
    let external = scene.model.external().is_some();
    std::iter::once((&p.name, p.min, p.max, &p.description))
        .chain(p.axes.iter().map(|a| (&a.name, a.min, a.max, &a.description)))
        .enumerate()
        .map(|(c, (n, lo, hi, what))| {
            let (lo, hi) = if external {
                let v = d.train.parameters.iter().map(|q| q[c]);
                (v.clone().fold(f64::INFINITY, f64::min), v.fold(f64::NEG_INFINITY, f64::max))
            } else {
                (lo, hi)
            };
            format!("{} ∈ [{lo}, {hi}] ({})", esc(n), esc(what))
        })
        .collect::<Vec<_>>()
        .join(" × ")
}

/// The stored model: what it is, what the study measured for it, and how to query it.
fn model_fact(scene: &SceneConfig, m: &super::ModelFacts) -> String {
    let dual = match m.dual_basis.as_str() {
        "full" | "truncated" => format!("the {} CPG basis", m.dual_basis),
        name => format!("the registered basis <code>{}</code> (rebuilt at each point)", esc(name)),
    };
    let error = |v: f64| if v.is_finite() { format!("{v:.2e}") } else { "undefined".to_string() };
    // a registered approximation with its own primal space (`primal_translates`)
    let translates = scene
        .comparison
        .iter()
        .flat_map(|c| &c.approximations)
        .find(|a| a.name() == m.dual_basis)
        .and_then(|a| a.primal_translates());
    let primal = match translates {
        Some(k) => format!(
            "primal rank {} (the POD of the training responses and their translates by ±{k} slave-surface node \
             spacings; corrected steps by GMRES)",
            m.ranks.0
        ),
        None => format!("primal rank {}", m.ranks.0),
    };
    let speed =
        m.speedup.map_or(String::new(), |s| format!(", speed-up {s:.1}x (median full-order over median online time)"));
    format!(
        "{} solve, {primal}, {dual} with {} dual vectors: converged {}/{} test points, median dual error {}, \
         median primal error (H1) {}{speed}. Query it without rerunning the study: \
         <code>crom query {} --at {}</code>",
        esc(&m.algorithm),
        m.ranks.1,
        m.converged,
        m.points,
        error(m.median_dual_error),
        error(m.median_primal_error),
        esc(&scene.scene.name),
        m.example.iter().map(|(n, v)| format!("{}={v}", esc(n))).collect::<Vec<_>>().join(",")
    )
}

/// What an external scene's report leaves out, each with its reason.
fn skipped<'d>(scene: &SceneConfig, d: &'d ReportData) -> Vec<&'d str> {
    let mut out: Vec<&str> = d.skipped.iter().map(String::as_str).collect();
    if scene.model.external().is_none() {
        return out;
    }
    if !d.online {
        out.push("The online reduced solve (errors and speed-ups, paper Figs. 3, 7), the speed/accuracy trade-off and the online solve with each dual approximation: they solve the full-order and the reduced problems, and an external scene has snapshots, not the full-order operators.");
    }
    if !d.mesh {
        out.push("Pictures of the snapshots on the body (and the views for ParaView): they need a mesh; give model.external.mesh (nodes, cells and the node of each dual entry). The pressure snapshots are drawn against the dual entry's number instead.");
    } else if d.surface.is_none() && d.geometry.is_none() && d.line_x.is_empty() {
        out.push("A picture of the pressure on the mesh: drawn for planar meshes only; open the views (train.xdmf, test.xdmf) in ParaView.");
    }
    out
}

/// A Markdown pipe table (as written by the report) to an HTML table.
fn md_to_html(md: &str) -> String {
    let mut rows = md.lines().filter(|l| l.starts_with('|') && !l.starts_with("|---"));
    let cells = |l: &str| -> Vec<String> { l.trim_matches('|').split('|').map(|c| esc(c.trim())).collect() };
    let mut s = String::from("<div class=\"wide\"><table>\n");
    if let Some(h) = rows.next() {
        s.push_str(&format!("<tr>{}</tr>\n", cells(h).iter().map(|c| format!("<th>{c}</th>")).collect::<String>()));
    }
    for r in rows {
        s.push_str(&format!("<tr>{}</tr>\n", cells(r).iter().map(|c| format!("<td>{c}</td>")).collect::<String>()));
    }
    s.push_str("</table></div>\n");
    s
}

/// Median relative errors and speed-up of the online solve over the test points.
fn online_summary(d: &ReportData, basis: &str) -> Option<String> {
    let t = &d.rom_errors;
    let (sets, bases) = (t.strs("set")?, t.strs("dual_basis")?);
    let (pe, de, on, fom, outcome) = (
        t.f64s("primal_error")?,
        t.f64s("dual_error")?,
        t.f64s("online_seconds")?,
        t.f64s("fom_seconds")?,
        t.strs("outcome")?,
    );
    let algs = t.strs("algorithm");
    let rows: Vec<usize> = (0..sets.len())
        .filter(|&i| sets[i] == "test" && bases[i] == basis && algs.is_none_or(|a| a[i] == "exact"))
        .collect();
    if rows.is_empty() {
        return None;
    }
    let median = |v: Vec<f64>| -> f64 {
        let mut v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            f64::NAN
        } else {
            v[v.len() / 2]
        }
    };
    let converged = rows.iter().filter(|&&i| outcome[i] == "converged").count();
    Some(format!(
        "median primal error (H1) {:.2e}, median dual error {:.2e}, median speed-up {:.1}x (timed points), converged {}/{}",
        median(rows.iter().map(|&i| pe[i]).collect()),
        median(rows.iter().map(|&i| de[i]).collect()),
        median(rows.iter().map(|&i| fom[i] / on[i]).collect()),
        converged,
        rows.len()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::ModelFacts;

    fn facts(dual_basis: &str) -> ModelFacts {
        ModelFacts {
            dual_basis: dual_basis.into(),
            algorithm: "exact".into(),
            ranks: (128, 2),
            points: 127,
            converged: 127,
            median_dual_error: 9.8e-4,
            median_primal_error: 6.4e-5,
            speedup: Some(80.0),
            example: vec![("d_x".into(), 1.5)],
        }
    }

    /// The stored model's line says which primal space it solves in: ironing-fine's
    /// neighbours entry sets `primal_translates = 8` in the shipped scene, so its model's line
    /// names the translates by ±8 (read from the scene file, not written here); a model on the
    /// study's CPG basis, or on an entry without the option (the registered CPG), says the
    /// primal rank alone.
    #[test]
    fn the_model_line_names_a_primal_space_with_translates() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        let scene = SceneConfig::load(&dir.join("ironing-fine.toml")).expect("shipped scene");
        let shift = scene
            .comparison
            .iter()
            .flat_map(|c| &c.approximations)
            .find_map(|a| a.primal_translates().map(|k| (a.name(), k)))
            .expect("ironing-fine has an entry with primal_translates");
        let line = model_fact(&scene, &facts(&shift.0));
        assert!(line.contains(&format!("translates by ±{} slave-surface", shift.1)), "{line}");
        for plain in ["full", "registered-translate-nodes-cpg"] {
            let line = model_fact(&scene, &facts(plain));
            assert!(line.contains("primal rank 128,") && !line.contains("translates"), "{line}");
        }
    }

    /// The example query names every parameter component once (`crom query --at` refuses a
    /// point that leaves one out): one component as before, two joined by a comma.
    #[test]
    fn the_example_query_gives_every_component() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        let scene = SceneConfig::load(&dir.join("ironing-fine-2d.toml")).expect("shipped scene");
        let one = model_fact(&scene, &facts("full"));
        assert!(one.contains("<code>crom query ironing-fine-2d --at d_x=1.5</code>"), "{one}");
        let two = ModelFacts { example: vec![("d_x".into(), 1.5), ("d_y".into(), 0.04)], ..facts("full") };
        let line = model_fact(&scene, &two);
        assert!(line.contains("<code>crom query ironing-fine-2d --at d_x=1.5,d_y=0.04</code>"), "{line}");
    }
}
