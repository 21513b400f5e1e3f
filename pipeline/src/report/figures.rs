//! The paper's figures, from the artifacts. Every chart follows one recipe: fetch the table's
//! columns (`Columns`, naming the file and the fix when one is missing), build the series
//! (`per_approximation` for the comparison's one-curve-per-approximation figures), and `draw`
//! them on their `Axes` with a caption.

use std::path::Path;

use crom_schemas::artifact::metrics as metric_names;
use crom_schemas::scene::Model;
use crom_schemas::SceneConfig;
use crom_stages::contact3d::HertzSpheres;
use crom_stages::rope::{Rope, RopeParams};

use super::chart::{render, render_spy, Chart, Legend, Mark, Series, Spy};
use super::{Figure, ReportData};
use crate::error::CromError;
use crate::io::table::Table;

/// At most this many snapshot curves in one figure (every k-th otherwise).
const MAX_CURVES: usize = 12;

/// The axes of a chart: labels, scales and where the legend goes.
struct Axes<'a> {
    x: &'a str,
    y: &'a str,
    log_x: bool,
    log_y: bool,
    legend: Legend,
}

/// Render `series` on `axes` under `title` to `dir/stem.png` and `dir/stem.svg`; the figure with
/// its caption.
fn draw(
    dir: &Path,
    stem: &str,
    title: String,
    axes: Axes<'_>,
    series: Vec<Series>,
    caption: impl Into<String>,
) -> Result<Figure, CromError> {
    let chart = Chart {
        title,
        x_label: axes.x.into(),
        y_label: axes.y.into(),
        log_y: axes.log_y,
        log_x: axes.log_x,
        series,
        legend: axes.legend,
    };
    render(&chart, dir, stem)?;
    Ok(Figure { stem: stem.into(), caption: caption.into() })
}

/// The columns a figure reads from one table: a missing column is an error naming the file,
/// the column and the fix.
struct Columns<'t> {
    table: &'t Table,
    file: &'static str,
    fix: &'static str,
}

impl<'t> Columns<'t> {
    fn of(table: &'t Table, file: &'static str, fix: &'static str) -> Self {
        Self { table, file, fix }
    }

    fn missing(&self, name: &str) -> CromError {
        CromError::artifact(self.file, format!("lacks the column `{name}`"), self.fix)
    }

    fn strs(&self, name: &str) -> Result<&'t [String], CromError> {
        self.table.strs(name).ok_or_else(|| self.missing(name))
    }

    fn u64s(&self, name: &str) -> Result<&'t [u64], CromError> {
        self.table.u64s(name).ok_or_else(|| self.missing(name))
    }

    fn f64s(&self, name: &str) -> Result<&'t [f64], CromError> {
        self.table.f64s(name).ok_or_else(|| self.missing(name))
    }
}

/// One series per approximation of `names`, each in the colour it has in every comparison
/// figure (its place in `all`), from its points `(x, y)`.
fn per_approximation(names: &[String], all: &[String], points: impl Fn(&str) -> (Vec<f64>, Vec<f64>)) -> Vec<Series> {
    names
        .iter()
        .map(|name| {
            let (x, y) = points(name);
            Series::line(name, x, y).color(all.iter().position(|m| m == name).unwrap_or(0))
        })
        .collect()
}

/// Draw every figure that applies to the scene into `dir`.
pub(crate) fn all(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Vec<Figure>, CromError> {
    let mut figs = Vec::new();
    if let Model::Rope(spec) = &scene.model {
        figs.push(rope_primal(scene, &Rope::new(RopeParams::from(spec)), d, dir)?);
    }
    if let Some(surface) = &d.surface {
        figs.push(pressure_on_mesh(scene, surface, d, dir)?);
        if let Some(online) = &d.online_pressure {
            figs.push(pressure_online(scene, surface, online, dir)?);
        }
    }
    if let Some(g) = &d.geometry {
        figs.push(deformed_bodies(scene, g, d, dir)?);
    }
    figs.push(dual_snapshots(scene, d, dir)?);
    if let (Model::Hertz3d(h), Some(profile)) = (&scene.model, &d.profile) {
        figs.push(hertz3d_theory(scene, h, profile, d, dir)?);
    }
    figs.push(singular_values(scene, d, dir)?);
    figs.push(sparsity(scene, d, dir)?);
    figs.push(compactness(scene, d, dir)?);
    figs.push(curve(
        scene,
        &d.generalization,
        dir,
        "fig10_generalization",
        "G(m) (eq. 17)",
        &generalization_caption(&d.generalization),
    )?);
    figs.push(curve(
        scene,
        &d.specificity,
        dir,
        "fig10_specificity",
        "S(m) (eq. 18)",
        "Specificity, mean ± 1σ over random members of the (sub)space or (sub)cone (paper Figs. 10, 16 right).",
    )?);
    if let Some(t) = &d.nested {
        figs.push(nested(scene, t, dir)?);
    }
    if d.online {
        for basis in ["full", "truncated"] {
            figs.push(rom_errors(scene, d, dir, basis)?);
        }
        figs.push(tradeoff(scene, d, dir)?);
    }
    if let Some(c) = &d.comparison {
        for (metric, stem, ylabel, caption) in COMPARISON_FIGURES {
            figs.push(comparison(scene, &c.curves, dir, metric, stem, ylabel, caption)?);
        }
        if c.nested.rows() > 0 {
            figs.push(comparison_nested(scene, &c.nested, &names_of(&c.curves), dir)?);
        }
        if let Some(t) = &c.online {
            figs.push(comparison_online(scene, t, &names_of(&c.curves), dir)?);
        }
    }
    Ok(figs)
}

/// The comparison's figures: (metric, stem, y label, caption).
const COMPARISON_FIGURES: [(&str, &str, &str, &str); 4] = [
    (
        "test",
        "fig_comparison_test",
        "mean relative dual error, test set",
        "Beyond the paper: every dual approximation's mean relative error over the test points (each snapshot at its own parameter, in the physical frame) against the number m of modes, generators or active atoms.",
    ),
    (
        "generalization",
        "fig_comparison_generalization",
        "G(m), leave-one-out",
        "Beyond the paper: leave-one-out generalization G(m) (eq. 17) of every dual approximation, each fold rebuilt without its snapshot, over comparison.loo_folds evenly spaced folds.",
    ),
    (
        "compactness",
        "fig_comparison_compactness",
        "C(m), training set",
        "Beyond the paper: compactness C(m) (eq. 16) of every dual approximation on its own training set (the dictionary holds every snapshot, so its C is 0 from m = 1).",
    ),
    (
        "specificity",
        "fig_comparison_specificity",
        "S(m), random members",
        "Beyond the paper: specificity S(m) (eq. 18) of every dual approximation with modes: random members (coefficients uniform in mean ± std of the training snapshots' own, at a random training parameter) against the closest training snapshot. The dictionary has no modes.",
    ),
];

/// The approximations of a comparison table, in table order.
pub(super) fn names_of(t: &Table) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for n in t.strs("approximation").unwrap_or_default() {
        if !names.contains(n) {
            names.push(n.clone());
        }
    }
    names
}

/// H(n) of every approximation against the level n.
fn comparison_nested(scene: &SceneConfig, t: &Table, all: &[String], dir: &Path) -> Result<Figure, CromError> {
    let c = Columns::of(t, "comparison_nested.parquet", "delete the comparison artifact and rerun");
    let (a, n, v) = (c.strs("approximation")?, c.u64s("n")?, c.f64s("value")?);
    let series = per_approximation(&names_of(t), all, |name| {
        (0..a.len()).filter(|&i| a[i] == name).map(|i| (n[i] as f64, v[i])).unzip()
    });
    draw(
        dir,
        "fig_comparison_nested",
        format!("{}: nested error of each dual approximation", scene.scene.name),
        Axes { x: "level n (2^n + 1 points)", y: "H(n) (eq. 19)", log_x: false, log_y: true, legend: Legend::LowerLeft },
        series,
        "Beyond the paper: nested error H(n) (eq. 19) of every dual approximation, built from level n with at most comparison.max_m modes and projecting level n + 1's snapshots, each at its own parameter.",
    )
}

/// The online trade of every approximation: median dual error (converged queries) against
/// median online time, one point per dual size m, joined per approximation.
fn comparison_online(scene: &SceneConfig, t: &Table, all: &[String], dir: &Path) -> Result<Figure, CromError> {
    let c = Columns::of(t, "online_comparison.parquet", "delete the online-comparison artifact and rerun");
    let (a, x, y) = (c.strs("approximation")?, c.f64s("median_online_ms")?, c.f64s("median_dual_error")?);
    let conv = c.u64s("converged")?;
    let series = per_approximation(&names_of(t), all, |name| {
        let rows = (0..a.len()).filter(|&i| a[i] == name && conv[i] > 0 && x[i].is_finite() && y[i].is_finite());
        rows.map(|i| (x[i], y[i])).unzip()
    });
    draw(
        dir,
        "fig_comparison_online",
        format!("{}: online solve with each dual approximation", scene.scene.name),
        Axes {
            x: "median online time per query (ms)",
            y: "median relative dual error, converged test points",
            log_x: true,
            log_y: true,
            legend: Legend::LowerLeft,
        },
        series,
        format!("Beyond the paper: the online reduced solve (exact algorithm, full primal basis) with each non-negative dual approximation, one point per dual size m (the dictionary: all atoms); errors over converged test points, times over the timed ones ({} evenly spaced, or all of fewer). Failures per row are in table_comparison_online.", crate::dag::timing::TIMED_POINTS),
    )
}

/// One curve per approximation of the comparison table `t` for `metric`.
fn comparison(
    scene: &SceneConfig,
    t: &Table,
    dir: &Path,
    metric: &str,
    stem: &str,
    ylabel: &str,
    caption: &str,
) -> Result<Figure, CromError> {
    let c = Columns::of(t, "comparison.parquet", "delete the comparison artifact and rerun");
    let (a, k, m, y) = (c.strs("approximation")?, c.strs("metric")?, c.u64s("m")?, c.f64s("mean")?);
    let names = names_of(t);
    let series = per_approximation(&names, &names, |name| {
        let rows = (0..a.len()).filter(|&i| a[i] == name && k[i] == metric && y[i].is_finite());
        rows.map(|i| (m[i] as f64, y[i])).unzip()
    });
    draw(
        dir,
        stem,
        format!("{}: dual approximations, {metric}", scene.scene.name),
        Axes {
            x: "modes / generators / active atoms m",
            y: ylabel,
            log_x: true,
            log_y: true,
            legend: Legend::LowerLeft,
        },
        series,
        caption,
    )
}

fn every(n: usize) -> usize {
    n.div_ceil(MAX_CURVES).max(1)
}

fn label(scene: &SceneConfig, p: &[f64]) -> String {
    scene.parameter.names().iter().zip(p).map(|(n, v)| format!("{n} = {v:.3}")).collect::<Vec<_>>().join(", ")
}

fn rope_primal(scene: &SceneConfig, rope: &Rope, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let mut series = Vec::new();
    let step = every(d.train.parameters.len());
    for (j, p) in d.train.parameters.iter().enumerate().step_by(step) {
        series.push(
            Series::line(&format!("u, {}", label(scene, p)), d.line_x.clone(), d.train.primal.col(j).to_vec())
                .mark(Mark::Line),
        );
    }
    for p in [d.train.parameters.first(), d.train.parameters.last()].into_iter().flatten() {
        let g = d.line_x.iter().map(|&x| rope.obstacle(x, p[0])).collect();
        series.push(Series::line(&format!("obstacle g, {}", label(scene, p)), d.line_x.clone(), g).mark(Mark::Line));
    }
    draw(
        dir,
        "fig02_primal_snapshots",
        format!("{}: deformation and obstacle snapshots", scene.scene.name),
        Axes { x: "x", y: "u(x), g(x)", log_x: false, log_y: false, legend: Legend::LowerRight },
        series,
        "Deformation u(x, γ) and obstacle g(x, γ) at training points (paper Fig. 2, left).",
    )
}

fn deformed_bodies(
    scene: &SceneConfig,
    g: &super::bodies::Geometry,
    d: &ReportData,
    dir: &Path,
) -> Result<Figure, CromError> {
    let shown: Vec<super::bodies::Shown<'_>> = three(d.train.parameters.len())
        .into_iter()
        .map(|j| super::bodies::Shown {
            label: label(scene, &d.train.parameters[j]),
            u: d.train.primal.col(j),
            pressure: d.train.dual.col(j),
        })
        .collect();
    let title = format!("{}: deformed bodies and contact pressure at three training points", scene.scene.name);
    let factor = super::bodies::render(&title, g, &shown, dir, "fig_bodies")?;
    Ok(Figure {
        stem: "fig_bodies".into(),
        caption: format!(
            "Deformed configuration at the first, middle and last training points (paper Figs. 1, 6a, 11): true scale, and with each body's deformation about its rigid motion magnified {factor:.3} times (the displacement of its node farthest from the contact surface, on its Dirichlet boundary, is kept at true scale); the contact surface is coloured by the contact pressure λ (colour bar at the right), and the pressure profile along the surface is beside each row."
        ),
    })
}

/// hertz-3d's pressure along the symmetry plane against Hertz theory for two equal spheres
/// ([`HertzSpheres`]) at the first, middle and last training approaches.
fn hertz3d_theory(
    scene: &SceneConfig,
    h: &crom_schemas::scene::Hertz3dSpec,
    profile: &[usize],
    d: &ReportData,
    dir: &Path,
) -> Result<Figure, CromError> {
    let (order, xs) = by_x(d, profile.to_vec());
    let mut series = Vec::new();
    for (k, j) in three(d.train.parameters.len()).into_iter().enumerate() {
        let approach = d.train.parameters[j].first().copied().unwrap_or(0.0);
        let col = d.train.dual.col(j);
        let name = label(scene, &d.train.parameters[j]);
        series.push(
            Series::line(&format!("{name}, crom"), xs.clone(), order.iter().map(|&i| col[i]).collect())
                .mark(Mark::Points)
                .color(k),
        );
        let theory = HertzSpheres::at(h.radius, h.material.young, h.material.poisson, approach);
        let top = xs.last().copied().unwrap_or(theory.a).max(theory.a);
        let rx: Vec<f64> = (0..=200).map(|t| top * t as f64 / 200.0).collect();
        let ry = rx.iter().map(|&r| theory.pressure(r)).collect();
        series.push(Series::line(&format!("{name}, Hertz"), rx, ry).color(k));
    }
    draw(
        dir,
        "fig_hertz3d_theory",
        format!("{}: contact pressure along the symmetry plane against Hertz theory", scene.scene.name),
        Axes { x: "distance r from the axis (on the plane y = 0)", y: "contact pressure", log_x: false, log_y: false, legend: Legend::UpperRight },
        series,
        "hertz-3d: the pressure at the slave nodes on the symmetry plane y = 0 (points) against Hertz theory for two equal spheres, p(r) = p0 sqrt(1 - r²/a²) with a = sqrt(R* d), p0 = (2E*/π) sqrt(d/R*), R* = R/2, E* = E/(2(1 − ν²)) (lines), at the first, middle and last training approaches. Each node's pressure is its force over its tributary area, so the nodes at the edge of contact read the mean over their cell; the hemispheres' finite size raises the force above Hertz's by a few per cent (docs/results.md#contact-in-3-d).",
    )
}

/// The contact entries `entries` in ascending x, and their x.
fn by_x(d: &ReportData, mut entries: Vec<usize>) -> (Vec<usize>, Vec<f64>) {
    entries.sort_by(|&a, &b| d.contact_x[a].total_cmp(&d.contact_x[b]));
    let xs = entries.iter().map(|&i| d.contact_x[i]).collect();
    (entries, xs)
}

/// The first, middle and last of `n` points (distinct).
fn three(n: usize) -> Vec<usize> {
    let mut picks = vec![0, n / 2, n.saturating_sub(1)];
    picks.dedup();
    picks.retain(|&j| j < n);
    picks
}

/// An external scene's pressure on its planar mesh at three training points.
fn pressure_on_mesh(scene: &SceneConfig, s: &super::Surface, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let panels: Vec<super::surface::Panel<'_>> = three(d.train.parameters.len())
        .into_iter()
        .map(|j| super::surface::Panel { label: label(scene, &d.train.parameters[j]), pressure: d.train.dual.col(j) })
        .collect();
    let title = format!("{}: contact pressure on the mesh at three training points", scene.scene.name);
    super::surface::render(&title, s, &panels, 3, dir, "fig_pressure_mesh")?;
    Ok(Figure {
        stem: "fig_pressure_mesh".into(),
        caption: "The contact pressure λ (the dual snapshots) on the scene's mesh at the first, middle and last training points: each cell coloured by the mean of its nodes' pressures (0 at nodes that carry no dual entry), one colour scale for the three (colour bar at the right).".into(),
    })
}

/// The full-order and the online reduced pressure side by side on the contact surface, at the
/// first, middle and last test points.
fn pressure_online(
    scene: &SceneConfig,
    s: &super::Surface,
    o: &super::OnlinePressure,
    dir: &Path,
) -> Result<Figure, CromError> {
    let picks = three(o.online.cols);
    let full: Vec<Vec<f64>> =
        picks.iter().map(|&j| o.online.col(j).iter().zip(o.error.col(j)).map(|(a, e)| a - e).collect()).collect();
    let mut panels: Vec<super::surface::Panel<'_>> = Vec::new();
    for (&j, full) in picks.iter().zip(&full) {
        let at = o.parameters.get(j).map_or_else(String::new, |mu| label(scene, mu));
        panels.push(super::surface::Panel { label: format!("full order, {at}"), pressure: full });
        panels.push(super::surface::Panel { label: format!("online reduced, {at}"), pressure: o.online.col(j) });
    }
    let title = format!("{}: contact pressure at three test points, full order and online", scene.scene.name);
    super::surface::render(&title, s, &panels, 2, dir, "fig_pressure_online")?;
    Ok(Figure {
        stem: "fig_pressure_online".into(),
        caption: "The contact pressure λ on the contact surface at the first, middle and last test points: the full-order solution (left) and the online reduced solution (right; exact algorithm, full ranks, full CPG basis, as in online.h5), each cell coloured by the mean of its nodes' pressures, one colour scale for all panels.".into(),
    })
}

fn dual_snapshots(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let step = every(d.train.parameters.len());
    let (order, xs) = by_x(d, d.profile.clone().unwrap_or_else(|| (0..d.contact_x.len()).collect()));
    // An external scene's contact set need not be a curve (a membrane's is an area): points
    // where two entries share an x (to 1e-9 of the extent: nodes on one grid line), and the
    // entry number without a mesh.
    let external = scene.model.external().is_some();
    let extent = xs.last().copied().unwrap_or(0.0) - xs.first().copied().unwrap_or(0.0);
    let same = crom_stages::float_cmp::Tol { abs: 1e-9 * extent.abs(), rel: 0.0 };
    let shared = xs.windows(2).any(|w| crom_stages::float_cmp::close(w[0], w[1], same));
    let mark = if external && shared { Mark::Points } else { Mark::Line };
    let x_axis = match (d.mesh, d.profile.is_some()) {
        (true, true) => "x of the potential-contact node on the symmetry plane (lowest y)",
        (true, false) => "x of the potential-contact node",
        (false, _) => "dual entry (no mesh: model.external.mesh)",
    };
    let series = d
        .train
        .parameters
        .iter()
        .enumerate()
        .step_by(step)
        .map(|(j, p)| {
            let col = d.train.dual.col(j);
            Series::line(&label(scene, p), xs.clone(), order.iter().map(|&i| col[i]).collect()).mark(mark)
        })
        .collect();
    draw(
        dir,
        "fig_dual_snapshots",
        format!("{}: contact pressure snapshots", scene.scene.name),
        Axes { x: x_axis, y: "contact pressure λ", log_x: false, log_y: false, legend: Legend::UpperRight },
        series,
        "Contact pressure snapshots at training points (paper Figs. 2 right, 6b, 12).",
    )
}

fn singular_values(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let norm = |name: &str, s: &[f64]| {
        let s0 = s.first().copied().unwrap_or(1.0).max(f64::MIN_POSITIVE);
        Series::line(name, (1..=s.len()).map(|i| i as f64).collect(), s.iter().map(|v| v / s0).collect())
    };
    let (p, q) = (norm("primal σ_i / σ_1", &d.primal_sv), norm("dual σ_i / σ_1", &d.dual_sv));
    draw(
        dir,
        "fig04_singular_values",
        format!("{}: singular value decay", scene.scene.name),
        Axes { x: "index i", y: "normalised singular value", log_x: false, log_y: true, legend: Legend::UpperRight },
        vec![p, q],
        "Decay of the normalised singular values of the primal and dual snapshot matrices (paper Fig. 4).",
    )
}

fn sparsity(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let (order, _) = by_x(d, (0..d.contact_x.len()).collect());
    let max = d.train.dual.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // "Non-zero" relative to the largest pressure: solver tolerance is 1e-10, so 1e-12 of the
    // maximum separates contact from rounding.
    let thresh = 1e-12 * max;
    let nonzero =
        (0..d.train.dual.cols).map(|j| order.iter().map(|&i| d.train.dual.col(j)[i] > thresh).collect()).collect();
    let spy = Spy {
        title: format!("{}: sparsity pattern of the dual snapshots", scene.scene.name),
        x_label: "potential-contact node (sorted by x)".into(),
        y_label: "snapshot".into(),
        nonzero,
    };
    render_spy(&spy, dir, "fig05_sparsity")?;
    Ok(Figure {
        stem: "fig05_sparsity".into(),
        caption: "Non-zero pattern of the contact pressure snapshots, one row per snapshot (paper Figs. 5, 8, 13)."
            .into(),
    })
}

fn compactness(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let series = [("primal", "orth", "primal orth"), ("dual", "orth", "dual orth"), ("dual", "cone", "dual cone")]
        .iter()
        .filter_map(|(f, b, name)| {
            d.compactness
                .get(&(f.to_string(), b.to_string()))
                .map(|v| Series::line(name, (0..v.len()).map(|m| m as f64).collect(), v.clone()))
        })
        .collect();
    draw(
        dir,
        "fig09_compactness",
        format!("{}: compactness", scene.scene.name),
        Axes { x: "rank m", y: "C(m) (eq. 16)", log_x: false, log_y: true, legend: Legend::UpperRight },
        series,
        "Compactness C(m) of the primal POD, dual POD and dual CPG bases (paper Figs. 9, 14); values at 0 are drawn at the axis floor.",
    )
}

/// Whether `shown` rows of a set of `size` points are a sample (the online stage measures a large
/// set at points drawn at random): some rows, fewer than the points.
pub(super) fn sampled(shown: usize, size: usize) -> bool {
    (1..size).contains(&shown)
}

/// Rows of the ROM error table for one set and dual basis: (parameter, primal error, dual error).
pub(super) fn rom_rows(d: &ReportData, set: &str, basis: &str) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let t = &d.rom_errors;
    let (Some(sets), Some(bases), Some(mu), Some(pe), Some(de)) =
        (t.strs("set"), t.strs("dual_basis"), t.f64s("parameter"), t.f64s("primal_error"), t.f64s("dual_error"))
    else {
        return Default::default();
    };
    let algs = t.strs("algorithm");
    let mut out: (Vec<f64>, Vec<f64>, Vec<f64>) = Default::default();
    for i in 0..mu.len() {
        if sets[i] == set && bases[i] == basis && algs.is_none_or(|a| a[i] == "exact") {
            out.0.push(mu[i]);
            out.1.push(pe[i]);
            out.2.push(de[i]);
        }
    }
    out
}

fn rom_errors(scene: &SceneConfig, d: &ReportData, dir: &Path, basis: &str) -> Result<Figure, CromError> {
    let mut series = Vec::new();
    // a large set is measured on a sample (the online stage's `measured`): say how many points
    let sizes = [scene.parameter.train_points().len(), scene.parameter.test_points().len()];
    let mut shown = [0; 2];
    for (k, set) in ["train", "test"].into_iter().enumerate() {
        let (mu, pe, de) = rom_rows(d, set, basis);
        shown[k] = mu.len();
        let what = if set == "train" { "training points" } else { "test points" };
        series.push(Series::line(&format!("primal (H1), {what}"), mu.clone(), pe).mark(Mark::Points));
        series.push(Series::line(&format!("dual (L2), {what}"), mu, de).mark(Mark::Points));
    }
    let rank = |name: &str| {
        d.rom_errors.u64s(name).and_then(|v| {
            let bases = d.rom_errors.strs("dual_basis")?;
            bases.iter().position(|b| b == basis).map(|i| v[i])
        })
    };
    draw(
        dir,
        &format!("fig03_rom_errors_{basis}"),
        format!(
            "{}: online reconstruction error, {basis} dual basis (r_u = {}, r_λ = {})",
            scene.scene.name,
            rank("r_primal").unwrap_or(0),
            rank("r_dual").unwrap_or(0)
        ),
        Axes { x: &scene.parameter.name, y: "relative error", log_x: false, log_y: true, legend: Legend::MiddleRight },
        series,
        format!(
            "Relative errors of the online reduced solve (crom's exact solve; the paper's Figs. 3 and 7 show its Algorithm 1) at {} with the {basis} CPG dual basis.",
            if sampled(shown[0], sizes[0]) || sampled(shown[1], sizes[1]) {
                format!(
                    "{} of the {} training and {} of the {} test points, drawn at random (a large set is measured on a sample)",
                    shown[0], sizes[0], shown[1], sizes[1]
                )
            } else {
                "training and test points".to_string()
            }
        ),
    )
}

fn tradeoff(scene: &SceneConfig, d: &ReportData, dir: &Path) -> Result<Figure, CromError> {
    let t = &d.tradeoff;
    let c = Columns::of(t, "tradeoff.parquet", "delete the rom artifact and rerun");
    let (alg, basis, ru, rl) = (c.strs("algorithm")?, c.strs("dual_basis")?, c.u64s("r_primal")?, c.u64s("r_dual")?);
    let (conv, err, sp) = (c.u64s("converged")?, c.f64s("median_primal_error")?, c.f64s("speedup")?);
    let (points, inf, failed) = (t.u64s("points"), t.u64s("infeasible"), t.u64s("failed"));
    let (ru_max, rl_max) = (ru.iter().max().copied().unwrap_or(0), rl.iter().max().copied().unwrap_or(0));
    // a rank pair is drawn only from its converged points, and only if it has any
    let drawn = |i: usize| conv[i] > 0 && err[i].is_finite() && err[i] > 0.0 && sp[i].is_finite();
    let pick = |f: &dyn Fn(usize) -> bool| -> (Vec<f64>, Vec<f64>) {
        (0..ru.len()).filter(|&i| drawn(i) && f(i)).map(|i| (sp[i], err[i])).unzip()
    };
    let (x1, y1) = pick(&|i| alg[i] == "exact" && basis[i] == "full" && rl[i] == rl_max);
    let (x2, y2) = pick(&|i| alg[i] == "exact" && ru[i] == ru_max && rl[i] != rl_max);
    let (x3, y3) = pick(&|i| alg[i] == "exact" && basis[i] == "truncated" && ru[i] != ru_max);
    let (x4, y4) = pick(&|i| alg[i] == "paper");
    let (x5, y5) = pick(&|i| alg[i] == crom_schemas::artifact::rom::SAMPLED);
    // Pareto front of the exact solves: no other pair is both faster and more accurate
    let exact: Vec<usize> = (0..ru.len()).filter(|&i| drawn(i) && alg[i] == "exact").collect();
    let mut front: Vec<(f64, f64)> = exact
        .iter()
        .filter(|&&i| {
            !exact.iter().any(|&j| j != i && sp[j] >= sp[i] && err[j] <= err[i] && (sp[j] > sp[i] || err[j] < err[i]))
        })
        .map(|&i| (sp[i], err[i]))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (xf, yf): (Vec<f64>, Vec<f64>) = front.into_iter().unzip();
    let mut series = vec![
        Series::line(&format!("exact: primal rank 1…{ru_max}, full dual basis"), x1, y1).mark(Mark::LinePoints),
        Series::line(&format!("exact: dual rank 1…{rl_max}, full primal basis"), x2, y2).mark(Mark::LinePoints),
        Series::line("exact: primal ranks, truncated dual basis", x3, y3).mark(Mark::LinePoints),
        Series::line("paper Algorithm 1 (all rank pairs)", x4, y4).mark(Mark::Points),
        Series::line("Pareto front (exact)", xf, yf),
    ];
    if !x5.is_empty() {
        series.push(Series::line("exact on a sampled surface (study.contact_sampling)", x5, y5).mark(Mark::Points));
    }
    let mut notes: Vec<String> = Vec::new();
    if let (Some(points), Some(inf), Some(failed)) = (points, inf, failed) {
        for i in 0..ru.len() {
            if inf[i] + failed[i] > 0 {
                notes.push(format!(
                    "{} ({}, {}): {} refused as infeasible, {} failed (cycled or at the iteration cap) of {}",
                    alg[i], ru[i], rl[i], inf[i], failed[i], points[i]
                ));
            }
        }
    }
    let sampled = if alg.iter().any(|a| a == crom_schemas::artifact::rom::SAMPLED) {
        " The sampled-surface points solve the same reduced problem with its contact constraints summed over a fitted subset of the slaves (a reduced quadrature, study.contact_sampling): cheaper per query on fine contact meshes, at the accuracy shown; they are not part of the exact front."
    } else {
        ""
    };
    let failures = if notes.is_empty() {
        "Every query of every rank pair converged.".to_string()
    } else {
        format!("Queries not drawn (ranks r_u, r_λ): {}.", notes.join("; "))
    };
    draw(
        dir,
        "fig_tradeoff",
        format!("{}: speed/accuracy trade over the test points (converged points only)", scene.scene.name),
        Axes {
            x: "median speed-up over the full-order solve",
            y: "median relative primal error (H1)",
            log_x: true,
            log_y: true,
            legend: Legend::LowerRight,
        },
        series,
        format!("Pareto view of the speed/accuracy trade: each point is one (primal rank, dual rank) pair, median error over its converged test points against its median speed-up (full-order solve timed in the same process).{sampled} {failures}"),
    )
}

const FIELDS: [(&str, &str, &str); 3] =
    [("primal", "orth", "primal orth"), ("dual", "orth", "dual orth"), ("dual", "cone", "dual cone")];

/// Rows of a metric table for one (field, basis), as (x, y, std) by the x column `xcol`.
fn metric_rows(t: &Table, field: &str, basis: &str, xcol: &str, ycol: &str) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (Some(f), Some(b), Some(x), Some(y)) = (t.strs("field"), t.strs("basis"), t.u64s(xcol), t.f64s(ycol)) else {
        return Default::default();
    };
    let sd = t.f64s("std");
    let mut out: (Vec<f64>, Vec<f64>, Vec<f64>) = Default::default();
    for i in 0..x.len() {
        if f[i] == field && b[i] == basis {
            out.0.push(x[i] as f64);
            out.1.push(y[i]);
            out.2.push(sd.map_or(0.0, |s| s[i]));
        }
    }
    out
}

/// The G(m) caption; a sample of folds (the table's `ci95` column) says how many and where the
/// interval of each mean is.
fn generalization_caption(t: &Table) -> String {
    let base =
        "Generalization ability by leave-one-out, mean ± 1σ over the left-out snapshots (paper Figs. 10, 16 left).";
    match (t.f64s(metric_names::INTERVAL), t.u64s("count")) {
        (Some(_), Some(count)) => format!(
            "{base} The folds are a sample: {} evenly spaced left-out snapshots of the training set; the half-width of \
             each mean's 95 % interval over every fold is the ci95 column of generalization.parquet.",
            count.iter().max().copied().unwrap_or(0)
        ),
        _ => base.to_string(),
    }
}

fn curve(
    scene: &SceneConfig,
    t: &Table,
    dir: &Path,
    stem: &str,
    ylabel: &str,
    caption: &str,
) -> Result<Figure, CromError> {
    let series = FIELDS
        .iter()
        .map(|(f, b, name)| {
            let (x, y, sd) = metric_rows(t, f, b, "m", "mean");
            let lo = y.iter().zip(&sd).map(|(m, s)| m - s).collect();
            let hi = y.iter().zip(&sd).map(|(m, s)| m + s).collect();
            Series::line(name, x, y).band(lo, hi)
        })
        .collect();
    draw(
        dir,
        stem,
        format!("{}: {}", scene.scene.name, ylabel.split(' ').next().unwrap_or(ylabel)),
        Axes { x: "rank m", y: ylabel, log_x: false, log_y: true, legend: Legend::UpperRight },
        series,
        format!("{caption} Bands below the axis floor are clipped."),
    )
}

fn nested(scene: &SceneConfig, t: &Table, dir: &Path) -> Result<Figure, CromError> {
    let series = FIELDS
        .iter()
        .map(|(f, b, name)| {
            let (x, y, _) = metric_rows(t, f, b, "n", "value");
            Series::line(name, x, y)
        })
        .collect();
    draw(
        dir,
        "fig15_nested",
        format!("{}: nested training-set error", scene.scene.name),
        Axes {
            x: "level n (2^n + 1 points)",
            y: "H(n) (eq. 19)",
            log_x: false,
            log_y: true,
            legend: Legend::LowerLeft,
        },
        series,
        "Projection error of level n+1 snapshots on the span / cone of level n (paper Fig. 15).",
    )
}
