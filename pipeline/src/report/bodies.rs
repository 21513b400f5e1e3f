//! The deformed bodies, like the paper's set-up figures (Figs. 1, 6a, 11): for a few training
//! points, the deformed configuration at true scale and magnified, the contact surface coloured
//! by the contact pressure, and the pressure profile along the surface beside them.
//!
//! Each body is drawn as its boundary (the cell edges that belong to one cell only, chained
//! into loops), filled, so the figure stays small whatever the mesh. The magnified view
//! exaggerates each body's deformation about its rigid motion: `x + r_b + s (u - r_b)`, where
//! `r_b` is the displacement of the body's node farthest from the contact surface — a node of
//! its Dirichlet boundary in every shipped scene (the slab's bottom, the iron's top, the flat
//! sides of the half-cylinders), so imposed motions stay at true scale and only the elastic
//! deformation is magnified. One factor `s` for every row: the largest elastic displacement
//! shown becomes a tenth of the mesh's extent (at least 1).

use std::collections::HashMap;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::chart::{register_font, PALETTE};
use crate::error::CromError;

/// The 2-D mesh as the report needs it.
#[derive(Debug, Clone)]
pub(crate) struct Geometry {
    /// Node coordinates.
    pub nodes: Vec<[f64; 2]>,
    /// Cells (node ids, counter-clockwise).
    pub cells: Vec<Vec<usize>>,
    /// Body of each cell.
    pub cell_body: Vec<u64>,
    /// Body of each node.
    pub node_body: Vec<u64>,
    /// Potential-contact nodes, in dual-row order.
    pub contact: Vec<usize>,
}

/// One snapshot to draw: its label, primal column (2 dofs per node) and dual column.
pub(crate) struct Shown<'a> {
    /// Row title (parameter values).
    pub label: String,
    /// Displacement, `2 * node + component`.
    pub u: &'a [f64],
    /// Pressure at the contact nodes.
    pub pressure: &'a [f64],
}

/// Boundary loops of every body: (body, node loop).
fn boundary_loops(g: &Geometry) -> Vec<(u64, Vec<usize>)> {
    let mut count: HashMap<(usize, usize), usize> = HashMap::new();
    for c in &g.cells {
        for k in 0..c.len() {
            let (a, b) = (c[k], c[(k + 1) % c.len()]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    // Directed boundary edges a -> b, in the orientation of their one cell.
    let mut next: HashMap<usize, (usize, u64)> = HashMap::new();
    for (c, &body) in g.cells.iter().zip(&g.cell_body) {
        for k in 0..c.len() {
            let (a, b) = (c[k], c[(k + 1) % c.len()]);
            if count[&(a.min(b), a.max(b))] == 1 {
                next.insert(a, (b, body));
            }
        }
    }
    let mut starts: Vec<usize> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut seen = vec![false; g.nodes.len()];
    let mut loops = Vec::new();
    for s in starts {
        if seen[s] {
            continue;
        }
        let mut lp = vec![s];
        seen[s] = true;
        let mut at = s;
        while let Some(&(n, _)) = next.get(&at) {
            if n == s || seen[n] {
                break;
            }
            seen[n] = true;
            lp.push(n);
            at = n;
        }
        loops.push((next[&s].1, lp));
    }
    loops
}

/// Per body, the node farthest from the contact surface (reference configuration).
fn anchors(g: &Geometry) -> HashMap<u64, usize> {
    let mut best: HashMap<u64, (f64, usize)> = HashMap::new();
    for (i, p) in g.nodes.iter().enumerate() {
        let d =
            g.contact.iter().map(|&c| (g.nodes[c][0] - p[0]).hypot(g.nodes[c][1] - p[1])).fold(f64::INFINITY, f64::min);
        let e = best.entry(g.node_body[i]).or_insert((-1.0, i));
        if d > e.0 {
            *e = (d, i);
        }
    }
    best.into_iter().map(|(b, (_, i))| (b, i)).collect()
}

/// Colour of `t` in [0, 1] on a perceptually ordered map (viridis anchors).
pub(crate) fn colormap(t: f64) -> RGBColor {
    const A: [(f64, f64, f64); 5] =
        [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 } * (A.len() - 1) as f64;
    let k = (t.floor() as usize).min(A.len() - 2);
    let f = t - k as f64;
    let mix = |a: f64, b: f64| (a + f * (b - a)).round() as u8;
    RGBColor(mix(A[k].0, A[k + 1].0), mix(A[k].1, A[k + 1].1), mix(A[k].2, A[k + 1].2))
}

/// Everything a figure draws, computed once for PNG and SVG.
struct Scene {
    title: String,
    rows: Vec<Row>,
    p_max: f64,
    factor: f64,
}

/// Deformed boundary loops, by body.
type Loops = Vec<(u64, Vec<(f64, f64)>)>;
/// Contact-surface segments (two deformed end points) with their mean pressure.
type Segments = Vec<((f64, f64), (f64, f64), f64)>;

struct Row {
    label: String,
    /// (magnification, deformed loops by body, coloured contact segments).
    views: [(f64, Loops, Segments); 2],
    /// Pressure profile: (x of the contact node, pressure), sorted by x.
    profile: Vec<(f64, f64)>,
}

fn layout(title: &str, g: &Geometry, shown: &[Shown<'_>]) -> Scene {
    let loops = boundary_loops(g);
    let anchor = anchors(g);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &g.nodes {
        for c in 0..2 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(f64::MIN_POSITIVE);
    let rigid = |u: &[f64], node: usize| {
        let a = anchor.get(&g.node_body[node]).copied().unwrap_or(node);
        [u[2 * a], u[2 * a + 1]]
    };
    let elastic = shown
        .iter()
        .flat_map(|s| {
            (0..g.nodes.len()).map(move |i| {
                let r = rigid(s.u, i);
                (s.u[2 * i] - r[0]).hypot(s.u[2 * i + 1] - r[1])
            })
        })
        .fold(0.0_f64, f64::max);
    let factor = if elastic > 0.0 { (0.1 * extent / elastic).max(1.0) } else { 1.0 };
    let p_max = shown.iter().flat_map(|s| s.pressure.iter().copied()).filter(|p| p.is_finite()).fold(0.0, f64::max);
    let mut order: Vec<usize> = (0..g.contact.len()).collect();
    order.sort_by(|&a, &b| g.nodes[g.contact[a]][0].total_cmp(&g.nodes[g.contact[b]][0]));
    let rows = shown
        .iter()
        .map(|s| {
            let at = |i: usize, scale: f64| {
                let r = rigid(s.u, i);
                (
                    g.nodes[i][0] + r[0] + scale * (s.u[2 * i] - r[0]),
                    g.nodes[i][1] + r[1] + scale * (s.u[2 * i + 1] - r[1]),
                )
            };
            let view = |scale: f64| {
                let bodies = loops.iter().map(|(b, lp)| (*b, lp.iter().map(|&i| at(i, scale)).collect())).collect();
                let surface = order
                    .windows(2)
                    .map(|w| {
                        let (a, b) = (w[0], w[1]);
                        (at(g.contact[a], scale), at(g.contact[b], scale), 0.5 * (s.pressure[a] + s.pressure[b]))
                    })
                    .collect();
                (scale, bodies, surface)
            };
            Row {
                label: s.label.clone(),
                views: [view(1.0), view(factor)],
                profile: order.iter().map(|&k| (g.nodes[g.contact[k]][0], s.pressure[k])).collect(),
            }
        })
        .collect();
    Scene { title: title.to_string(), rows, p_max, factor }
}

/// Draw the figure to `<stem>.png` and `<stem>.svg` in `dir`; returns the magnification.
pub(crate) fn render(title: &str, g: &Geometry, shown: &[Shown<'_>], dir: &Path, stem: &str) -> Result<f64, CromError> {
    register_font();
    let scene = layout(title, g, shown);
    let size = (1500, 120 + 300 * scene.rows.len() as u32);
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let fail = |p: &Path, e: String| CromError::artifact(p, format!("drawing figure: {e}"), "report this as a bug");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw(&root, &scene).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    let root = SVGBackend::new(&svg, size).into_drawing_area();
    draw(&root, &scene).map_err(|e| fail(&svg, e))?;
    root.present().map_err(|e| fail(&svg, e.to_string()))?;
    Ok(scene.factor)
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, s: &Scene) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(&s.title, ("sans-serif", 24)).map_err(e)?;
    let (main, bar) = root.split_horizontally(root.dim_in_pixel().0 - 110);
    let rows = main.split_evenly((s.rows.len().max(1), 1));
    let body_fill = [RGBColor(200, 200, 205), RGBColor(160, 170, 185)];
    for (row, area) in s.rows.iter().zip(rows) {
        let (views, profile) = area.split_horizontally(area.dim_in_pixel().0 * 2 / 3);
        for ((scale, bodies, surface), panel) in row.views.iter().zip(views.split_evenly((1, 2))) {
            let pts = bodies.iter().flat_map(|(_, l)| l.iter());
            let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
            for &(x, y) in pts {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
            // Equal aspect ratio: widen the narrower range to the panel's pixel proportions.
            let (w, h) = panel.dim_in_pixel();
            let (w, h) = (f64::from(w.max(1)) - 20.0, f64::from(h.max(1)) - 50.0);
            let (dx, dy) = ((x1 - x0).max(1e-12), (y1 - y0).max(1e-12));
            let per = (dx / w).max(dy / h) * 1.05;
            let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
            let (hx, hy) = (0.5 * per * w, 0.5 * per * h);
            let what = if *scale > 1.0 { format!("deformation × {scale:.3}") } else { "true scale".to_string() };
            let mut chart = ChartBuilder::on(&panel)
                .caption(format!("{}: {what}", row.label), ("sans-serif", 15))
                .margin(8)
                .build_cartesian_2d(cx - hx..cx + hx, cy - hy..cy + hy)
                .map_err(|e| e.to_string())?;
            for (b, lp) in bodies {
                let fill = body_fill[(*b as usize) % body_fill.len()];
                chart
                    .draw_series(std::iter::once(Polygon::new(lp.clone(), fill.filled())))
                    .map_err(|e| e.to_string())?;
                let mut closed = lp.clone();
                closed.extend(lp.first().copied());
                chart
                    .draw_series(std::iter::once(PathElement::new(closed, BLACK.stroke_width(1))))
                    .map_err(|e| e.to_string())?;
            }
            chart
                .draw_series(surface.iter().map(|&(a, b, p)| {
                    let c = colormap(if s.p_max > 0.0 { p / s.p_max } else { 0.0 });
                    PathElement::new(vec![a, b], c.stroke_width(4))
                }))
                .map_err(|e| e.to_string())?;
        }
        let (px0, px1) =
            row.profile.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
        let (px0, px1) = if px1 > px0 { (px0, px1) } else { (px0 - 1.0, px0 + 1.0) };
        let top = if s.p_max > 0.0 { 1.08 * s.p_max } else { 1.0 };
        let mut chart = ChartBuilder::on(&profile)
            .caption(format!("{}: contact pressure", row.label), ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(px0..px1, 0.0..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("x of the contact node")
            .y_desc("λ")
            .light_line_style(WHITE)
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(LineSeries::new(row.profile.iter().copied(), PALETTE[7].stroke_width(1)))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(row.profile.iter().map(|&(x, p)| {
                Circle::new((x, p), 3, colormap(if s.p_max > 0.0 { p / s.p_max } else { 0.0 }).filled())
            }))
            .map_err(|e| e.to_string())?;
    }
    // Colour bar of the pressure.
    let (bw, bh) = bar.dim_in_pixel();
    let (top, bottom) = (40_i32, bh as i32 - 40);
    let x = 20_i32;
    let levels = 100;
    for k in 0..levels {
        let t0 = k as f64 / levels as f64;
        let y_hi = bottom - ((bottom - top) as f64 * (t0 + 1.0 / levels as f64)) as i32;
        let y_lo = bottom - ((bottom - top) as f64 * t0) as i32;
        bar.draw(&Rectangle::new([(x, y_hi), (x + 25, y_lo)], colormap(t0 + 0.5 / levels as f64).filled()))
            .map_err(e)?;
    }
    let style = ("sans-serif", 13).into_font();
    for (t, v) in [(0.0, 0.0), (0.5, 0.5 * s.p_max), (1.0, s.p_max)] {
        let y = bottom - ((bottom - top) as f64 * t) as i32;
        bar.draw(&Text::new(format!("{v:.3}"), (x + 30, y - 6), style.clone())).map_err(e)?;
    }
    bar.draw(&Text::new("λ", (x + 5, top - 25), ("sans-serif", 16).into_font())).map_err(e)?;
    let _ = bw;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crom_stages::float_cmp::{close, Tol};

    /// Exact arithmetic on short binary fractions: positions agree to rounding.
    const EXACT: Tol = Tol { abs: 1e-12, rel: 1e-12 };

    /// Two stacked unit squares of two bodies, each split into 2 x 1 quads.
    fn two_blocks() -> Geometry {
        let mut nodes = Vec::new();
        for (y0, _) in [(0.0, 0), (1.5, 1)] {
            for j in 0..2 {
                for i in 0..3 {
                    nodes.push([0.5 * i as f64, y0 + j as f64]);
                }
            }
        }
        let quad = |o: usize, i: usize| vec![o + i, o + i + 1, o + i + 4, o + i + 3];
        Geometry {
            cells: vec![quad(0, 0), quad(0, 1), quad(6, 0), quad(6, 1)],
            cell_body: vec![0, 0, 1, 1],
            node_body: (0..12).map(|i| u64::from(i >= 6)).collect(),
            contact: vec![6, 7, 8],
            nodes,
        }
    }

    #[test]
    fn each_body_has_one_boundary_loop_through_its_outer_nodes() {
        let g = two_blocks();
        let loops = boundary_loops(&g);
        assert_eq!(loops.len(), 2);
        for (b, lp) in &loops {
            // A 3 x 2 node block has 6 boundary nodes, no interior one.
            assert_eq!(lp.len(), 6, "body {b}: {lp:?}");
            assert!(lp.iter().all(|&i| g.node_body[i] == *b));
        }
    }

    #[test]
    fn the_anchor_is_the_node_farthest_from_the_contact_surface() {
        let g = two_blocks();
        let a = anchors(&g);
        // Body 0 (below): its bottom corners are farthest from the contact nodes at y = 1.5.
        assert!(close(g.nodes[a[&0]][1], 0.0, EXACT));
        // Body 1: the contact nodes are its bottom row; its top corners are farthest.
        assert!(close(g.nodes[a[&1]][1], 2.5, EXACT));
    }

    #[test]
    fn magnification_leaves_the_rigid_motion_at_true_scale() {
        let g = two_blocks();
        // Body 1 translated by (0.3, -0.2), nothing else deformed: the factor is 1 (no elastic
        // displacement) and every view equals the reference plus the translation.
        let mut u = vec![0.0; 24];
        for i in 6..12 {
            u[2 * i] = 0.3;
            u[2 * i + 1] = -0.2;
        }
        let p = vec![0.0; 3];
        let s = layout("t", &g, &[Shown { label: "x".into(), u: &u, pressure: &p }]);
        assert!(close(s.factor, 1.0, EXACT));
        // Now compress body 1's bottom row by 0.01: the factor makes it a tenth of the extent.
        for i in 6..9 {
            u[2 * i + 1] += 0.01;
        }
        let s = layout("t", &g, &[Shown { label: "x".into(), u: &u, pressure: &p }]);
        assert!(close(s.factor, 0.1 * 2.5 / 0.01, Tol::rel(1e-9)), "{}", s.factor);
        let (_, bodies, _) = &s.rows[0].views[1];
        // Body 1's anchor (top row) stays at reference + translation.
        let top = bodies.iter().find(|(b, _)| *b == 1).expect("body 1");
        assert!(top.1.iter().any(|&(x, y)| close(x, 0.3, EXACT) && close(y, 2.3, EXACT)));
    }
}
