//! The contact pressure on a planar mesh (external scenes with a 2-D mesh: the report's
//! pictures of their data): for a few training points, every cell filled with the mean of its
//! nodes' pressures (0 at nodes that are no dual entry) on one colour scale, the mesh at its
//! true aspect ratio, a colour bar at the right.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::bodies::colormap;
use super::chart::register_font;
use crate::error::CromError;

/// A planar mesh and where the dual entries are on it.
#[derive(Debug, Clone)]
pub(crate) struct Surface {
    /// Node coordinates (x, y).
    pub nodes: Vec<[f64; 2]>,
    /// Cells (node ids).
    pub cells: Vec<Vec<usize>>,
    /// The node of each dual entry.
    pub contact: Vec<usize>,
}

/// One snapshot to draw: its label and its dual column.
pub(crate) struct Panel<'a> {
    /// Panel title (parameter values).
    pub label: String,
    /// Pressure of each dual entry.
    pub pressure: &'a [f64],
}

/// Per panel, each cell's mean nodal pressure; and the largest value over the panels.
fn cell_values(s: &Surface, panels: &[Panel<'_>]) -> (Vec<Vec<f64>>, f64) {
    let mut at_node = vec![0.0; s.nodes.len()];
    let mut max = 0.0f64;
    let values = panels
        .iter()
        .map(|p| {
            at_node.iter_mut().for_each(|v| *v = 0.0);
            for (k, &node) in s.contact.iter().enumerate() {
                at_node[node] = if p.pressure[k].is_finite() { p.pressure[k] } else { 0.0 };
            }
            let cells: Vec<f64> =
                s.cells.iter().map(|c| c.iter().map(|&i| at_node[i]).sum::<f64>() / c.len().max(1) as f64).collect();
            max = cells.iter().copied().fold(max, f64::max);
            cells
        })
        .collect();
    (values, max)
}

/// The drawn cells' extent: `[x0, x1, y0, y1]` (a 3-D scene's nodes hold both bodies; its
/// cells are the contact surface).
fn extent(s: &Surface) -> [f64; 4] {
    let mut e = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
    for p in s.cells.iter().flatten().map(|&i| s.nodes[i]) {
        e = [e[0].min(p[0]), e[1].max(p[0]), e[2].min(p[1]), e[3].max(p[1])];
    }
    e
}

/// Panel width in pixels; its height follows the surface's aspect ratio (between
/// [`MIN_PANEL_HEIGHT`] and [`MAX_PANEL_HEIGHT`]), so that a long contact strip is not drawn in
/// a square of white.
const PANEL_WIDTH: u32 = 480;
const MIN_PANEL_HEIGHT: u32 = 170;
const MAX_PANEL_HEIGHT: u32 = 520;

/// Draw the panels, `cols` to a row, to `<stem>.png` and `<stem>.svg` in `dir`.
pub(crate) fn render(
    title: &str,
    s: &Surface,
    panels: &[Panel<'_>],
    cols: usize,
    dir: &Path,
    stem: &str,
) -> Result<(), CromError> {
    register_font();
    let (values, max) = cell_values(s, panels);
    let cols = cols.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    let [x0, x1, y0, y1] = extent(s);
    let aspect = if x1 > x0 && y1 >= y0 { (y1 - y0) / (x1 - x0) } else { 1.0 };
    // the drawing area less the panel's margins and labels (70 x 80 pixels), as in `draw`
    let height = ((f64::from(PANEL_WIDTH) - 70.0) * aspect * 1.02 + 80.0) as u32;
    let height = height.clamp(MIN_PANEL_HEIGHT, MAX_PANEL_HEIGHT);
    let size = (PANEL_WIDTH * cols as u32 + 120, height * rows as u32 + 40);
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let fail = |p: &Path, e: String| CromError::artifact(p, format!("drawing figure: {e}"), "report this as a bug");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw(&root, title, s, panels, (rows, cols), (&values, max)).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    let root = SVGBackend::new(&svg, size).into_drawing_area();
    draw(&root, title, s, panels, (rows, cols), (&values, max)).map_err(|e| fail(&svg, e))?;
    root.present().map_err(|e| fail(&svg, e.to_string()))
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    s: &Surface,
    panels: &[Panel<'_>],
    (rows, cols): (usize, usize),
    (values, max): (&[Vec<f64>], f64),
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(e)?;
    let (main, bar) = root.split_horizontally(root.dim_in_pixel().0 - 110);
    let [x0, x1, y0, y1] = extent(s);
    for ((panel, cells), area) in panels.iter().zip(values).zip(main.split_evenly((rows, cols))) {
        // Equal aspect ratio: widen the narrower range to the panel's pixel proportions.
        let (w, h) = area.dim_in_pixel();
        let (w, h) = (f64::from(w.max(1)) - 70.0, f64::from(h.max(1)) - 80.0);
        let (dx, dy) = ((x1 - x0).max(1e-12), (y1 - y0).max(1e-12));
        let per = (dx / w.max(1.0)).max(dy / h.max(1.0)) * 1.02;
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let (hx, hy) = (0.5 * per * w, 0.5 * per * h);
        let mut chart = ChartBuilder::on(&area)
            .caption(&panel.label, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(25)
            .y_label_area_size(40)
            .build_cartesian_2d(cx - hx..cx + hx, cy - hy..cy + hy)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x")
            .y_desc("y")
            .label_style(("sans-serif", 11))
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(s.cells.iter().zip(cells).map(|(c, &v)| {
                let t = if max > 0.0 { v / max } else { 0.0 };
                Polygon::new(
                    c.iter().map(|&i| (s.nodes[i][0], s.nodes[i][1])).collect::<Vec<_>>(),
                    colormap(t).filled(),
                )
            }))
            .map_err(|e| e.to_string())?;
    }
    let (_, bh) = bar.dim_in_pixel();
    let (top, bottom, x) = (40_i32, bh as i32 - 40, 20_i32);
    let levels = 100;
    for k in 0..levels {
        let t0 = k as f64 / levels as f64;
        let y_hi = bottom - ((bottom - top) as f64 * (t0 + 1.0 / levels as f64)) as i32;
        let y_lo = bottom - ((bottom - top) as f64 * t0) as i32;
        bar.draw(&Rectangle::new([(x, y_hi), (x + 25, y_lo)], colormap(t0 + 0.5 / levels as f64).filled()))
            .map_err(e)?;
    }
    let style = ("sans-serif", 13).into_font();
    for (t, v) in [(0.0, 0.0), (0.5, 0.5 * max), (1.0, max)] {
        let y = bottom - ((bottom - top) as f64 * t) as i32;
        bar.draw(&Text::new(format!("{v:.3}"), (x + 30, y - 6), style.clone())).map_err(e)?;
    }
    bar.draw(&Text::new("λ", (x + 5, top - 25), ("sans-serif", 16).into_font())).map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of the unit square, pressure 3 at node 2 only (the one dual entry):
    /// the cell (1, 2, 3) has mean 1, the cell (0, 1, 3) holds no pressure.
    #[test]
    fn each_cell_gets_the_mean_of_its_nodes() {
        let s = Surface {
            nodes: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            cells: vec![vec![0, 1, 3], vec![1, 2, 3]],
            contact: vec![2],
        };
        let (v, max) = cell_values(&s, &[Panel { label: String::new(), pressure: &[3.0] }]);
        // Means of exact small integers: exact.
        assert_eq!(v, vec![vec![0.0, 1.0]]);
        assert!(crom_stages::float_cmp::close(max, 1.0, crom_stages::float_cmp::Tol { abs: 0.0, rel: 0.0 }));
    }
}
