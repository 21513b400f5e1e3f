//! Line charts (optionally log-scale, with ±1σ bands) and sparsity ("spy") plots, rendered to PNG
//! and SVG with plotters. Text uses the committed DejaVu Sans (no system fonts needed).

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::element::MultiLineText;
use plotters::prelude::*;

use crate::error::CromError;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Register the committed font under "sans-serif" (idempotent).
pub fn register_font() {
    REGISTER.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// A line.
    Line,
    /// Markers only.
    Points,
    /// A line with markers.
    LinePoints,
}

/// One series of a [`Chart`].
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates.
    pub y: Vec<f64>,
    /// Optional shaded band (lower, upper), e.g. mean ± 1σ.
    pub band: Option<(Vec<f64>, Vec<f64>)>,
    /// How to draw it.
    pub mark: Mark,
    /// Palette index (default: the series' position), so that one name keeps its colour
    /// across figures that show different subsets.
    pub color: Option<usize>,
}

impl Series {
    /// A line series.
    pub fn line(name: &str, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self { name: name.to_string(), x, y, band: None, mark: Mark::LinePoints, color: None }
    }

    /// Change the mark.
    pub fn mark(mut self, mark: Mark) -> Self {
        self.mark = mark;
        self
    }

    /// Fix the palette index.
    pub fn color(mut self, index: usize) -> Self {
        self.color = Some(index);
        self
    }

    /// Add a band.
    pub fn band(mut self, lo: Vec<f64>, hi: Vec<f64>) -> Self {
        self.band = Some((lo, hi));
        self
    }
}

/// A 2-D line chart.
#[derive(Debug, Clone)]
pub struct Chart {
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Log-scale y axis (non-positive values are drawn at the floor of the axis).
    pub log_y: bool,
    /// Log-scale x axis.
    pub log_x: bool,
    /// The series.
    pub series: Vec<Series>,
    /// Where the legend goes, unless its box there would cover more of the drawn points than
    /// at another corner ([`clear_position`]).
    pub legend: Legend,
}

/// Legend placement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Legend {
    /// Upper right corner.
    #[default]
    UpperRight,
    /// Lower left corner.
    LowerLeft,
    /// Lower right corner.
    LowerRight,
    /// Upper left corner.
    UpperLeft,
    /// Middle of the right edge.
    MiddleRight,
}

impl Legend {
    fn position(self) -> SeriesLabelPosition {
        match self {
            Legend::UpperRight => SeriesLabelPosition::UpperRight,
            Legend::LowerLeft => SeriesLabelPosition::LowerLeft,
            Legend::LowerRight => SeriesLabelPosition::LowerRight,
            Legend::UpperLeft => SeriesLabelPosition::UpperLeft,
            Legend::MiddleRight => SeriesLabelPosition::MiddleRight,
        }
    }
}

/// The legend box's margin inside the plotting area and the marker column's width (plotters'
/// series-label layout: `5` from the area's edge, `legend_area_size` 30, `margin` 10).
const LEGEND_EDGE: i32 = 5;
const LEGEND_MARKER: i32 = 30;
const LEGEND_MARGIN: i32 = 10;
/// Half a point marker's size in pixels (the [`Mark::Points`] circles' radius).
const MARKER_RADIUS: i32 = 4;

/// Where the legend box of `label` (the labels' text block, pixels) lies at `pos` in a plotting
/// area of `area` pixels, as plotters lays it out: `(x0, y0, x1, y1)`.
fn legend_box(pos: Legend, label: (i32, i32), area: (i32, i32)) -> (i32, i32, i32, i32) {
    let (w, h) = (label.0 + LEGEND_MARKER + 2 * LEGEND_MARGIN, label.1 + 2 * LEGEND_MARGIN);
    let x = match pos {
        Legend::UpperLeft | Legend::LowerLeft => LEGEND_EDGE,
        Legend::UpperRight | Legend::LowerRight | Legend::MiddleRight => area.0 - w - LEGEND_EDGE,
    };
    let y = match pos {
        Legend::UpperLeft | Legend::UpperRight => LEGEND_EDGE,
        Legend::MiddleRight => (area.1 - h) / 2,
        Legend::LowerLeft | Legend::LowerRight => area.1 - h - LEGEND_EDGE,
    };
    (x, y, x + w, y + h)
}

/// The legend's place: `preferred`, unless its box there covers more of `points` (pixels in the
/// plotting area, a marker's radius around each) than at another corner; then the corner that
/// covers the fewest, the first in the order upper right, upper left, lower right, lower left,
/// middle right on a tie. A chart's drawn points stay readable wherever the data put them (a
/// fixed corner covered hertz-3d's online errors).
fn clear_position(preferred: Legend, points: &[(i32, i32)], label: (i32, i32), area: (i32, i32)) -> Legend {
    let covered = |pos: Legend| {
        let (x0, y0, x1, y1) = legend_box(pos, label, area);
        let r = MARKER_RADIUS;
        points.iter().filter(|&&(x, y)| x + r >= x0 && x - r <= x1 && y + r >= y0 && y - r <= y1).count()
    };
    let order = [Legend::UpperRight, Legend::UpperLeft, Legend::LowerRight, Legend::LowerLeft, Legend::MiddleRight];
    let mut best = (covered(preferred), preferred);
    for pos in order {
        let c = covered(pos);
        if c < best.0 {
            best = (c, pos);
        }
    }
    best.1
}

/// Tick label: `1e-6` style on log axes, a short decimal otherwise.
fn tick(v: f64, log: bool) -> String {
    if log && !(1e-3..1e4).contains(&v) {
        let e = v.log10().round();
        if (v.log10() - e).abs() < 1e-6 {
            return format!("1e{}", e as i64);
        }
        return format!("{v:.0e}");
    }
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

pub(crate) const PALETTE: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
    RGBColor(255, 187, 120),
];

/// Something drawable on any plotters backend.
trait Drawable {
    fn draw_on<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

impl Drawable for Chart {
    fn draw_on<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        draw(root, self)
    }
}

impl Drawable for Spy {
    fn draw_on<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        draw_spy(root, self)
    }
}

/// Render a figure to `<stem>.png` and `<stem>.svg` in `dir`.
fn render_both(fig: &impl Drawable, dir: &Path, stem: &str) -> Result<(), CromError> {
    register_font();
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let fail = |p: &Path, e: String| CromError::artifact(p, format!("drawing figure: {e}"), "report this as a bug");
    {
        let root = BitMapBackend::new(&png, (900, 600)).into_drawing_area();
        fig.draw_on(&root).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    let root = SVGBackend::new(&svg, (900, 600)).into_drawing_area();
    fig.draw_on(&root).map_err(|e| fail(&svg, e))?;
    root.present().map_err(|e| fail(&svg, e.to_string()))
}

/// Render `chart` to `<stem>.png` and `<stem>.svg` in `dir`.
pub fn render(chart: &Chart, dir: &Path, stem: &str) -> Result<(), CromError> {
    render_both(chart, dir, stem)
}

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if log { (1e-16, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        let (l, h) = (lo.log10().floor(), hi.log10().ceil());
        let h = if h <= l { l + 1.0 } else { h };
        (10f64.powf(l), 10f64.powf(h))
    } else {
        let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1.0) * 0.05 };
        (lo - pad, hi + pad)
    }
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, chart: &Chart) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let xs = chart.series.iter().flat_map(|s| s.x.iter().copied());
    let ys = chart
        .series
        .iter()
        .flat_map(|s| s.y.iter().copied().chain(s.band.iter().flat_map(|(l, h)| l.iter().chain(h.iter()).copied())));
    let (x0, x1) = range(xs, chart.log_x);
    let (y0, y1) = range(ys, chart.log_y);
    let clamp = |v: f64| if chart.log_y { v.max(y0) } else { v };
    let mut builder = ChartBuilder::on(root);
    builder.caption(&chart.title, ("sans-serif", 22)).margin(15).x_label_area_size(45).y_label_area_size(75);
    macro_rules! body {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            let xf = |v: &f64| tick(*v, chart.log_x);
            let yf = |v: &f64| tick(*v, chart.log_y);
            ctx.configure_mesh()
                .x_label_formatter(&xf)
                .y_label_formatter(&yf)
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .label_style(("sans-serif", 14))
                .axis_desc_style(("sans-serif", 16))
                .draw()
                .map_err(|e| e.to_string())?;
            for (i, s) in chart.series.iter().enumerate() {
                let color = PALETTE[s.color.unwrap_or(i) % PALETTE.len()];
                if let Some((lo, hi)) = &s.band {
                    let mut poly: Vec<(f64, f64)> = s.x.iter().zip(hi).map(|(x, y)| (*x, clamp(*y))).collect();
                    poly.extend(s.x.iter().zip(lo).rev().map(|(x, y)| (*x, clamp(*y))));
                    ctx.draw_series(std::iter::once(Polygon::new(poly, color.mix(0.18).filled())))
                        .map_err(|e| e.to_string())?;
                }
                let pts: Vec<(f64, f64)> =
                    s.x.iter().zip(&s.y).filter(|(_, y)| y.is_finite()).map(|(x, y)| (*x, clamp(*y))).collect();
                let style = ShapeStyle::from(&color).stroke_width(2);
                if s.mark == Mark::LinePoints && pts.len() <= 200 {
                    ctx.draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
                        .map_err(|e| e.to_string())?;
                }
                let anno = if s.mark == Mark::Points {
                    ctx.draw_series(pts.iter().map(|p| Circle::new(*p, 4, color.filled())))
                        .map_err(|e| e.to_string())?
                } else {
                    ctx.draw_series(LineSeries::new(pts, style)).map_err(|e| e.to_string())?
                };
                anno.label(s.name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(3)));
            }
            // the drawn points in the plotting area's pixels (a line's too, at four points per
            // segment), and the labels' text block as plotters measures it
            let (px, py) = ctx.plotting_area().get_pixel_range();
            let mut drawn: Vec<(i32, i32)> = Vec::new();
            for s in &chart.series {
                let pts: Vec<(i32, i32)> =
                    s.x.iter()
                        .zip(&s.y)
                        .filter(|(x, y)| x.is_finite() && y.is_finite())
                        .map(|(x, y)| {
                            let (bx, by) = ctx.backend_coord(&(*x, clamp(*y)));
                            (bx - px.start, by - py.start)
                        })
                        .collect();
                drawn.extend_from_slice(&pts);
                if s.mark != Mark::Points {
                    for w in pts.windows(2) {
                        drawn.extend((1..4).map(|k| {
                            let t = k as f64 / 4.0;
                            let lerp = |a: i32, b: i32| a + (t * (b - a) as f64).round() as i32;
                            (lerp(w[0].0, w[1].0), lerp(w[0].1, w[1].1))
                        }));
                    }
                }
            }
            let font: TextStyle = ("sans-serif", 14).into_font().into();
            let mut text = MultiLineText::<_, &str>::new((0, 0), &font);
            for s in &chart.series {
                text.push_line(s.name.as_str());
            }
            let label = text.estimate_dimension().map_err(|e| format!("{e:?}"))?;
            let area = (px.end - px.start, py.end - py.start);
            ctx.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .position(clear_position(chart.legend, &drawn, label, area).position())
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    match (chart.log_x, chart.log_y) {
        (false, false) => body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(|e| e.to_string())?),
        (false, true) => body!(builder.build_cartesian_2d(x0..x1, (y0..y1).log_scale()).map_err(|e| e.to_string())?),
        (true, false) => body!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1).map_err(|e| e.to_string())?),
        (true, true) => {
            body!(builder.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale()).map_err(|e| e.to_string())?)
        }
    }
    Ok(())
}

/// A sparsity pattern: row i = snapshot i, a dark cell where the field is non-zero.
#[derive(Debug, Clone)]
pub struct Spy {
    /// Title.
    pub title: String,
    /// x-axis label (node index).
    pub x_label: String,
    /// y-axis label (snapshot index).
    pub y_label: String,
    /// `nonzero[i][j]`: snapshot i, node j.
    pub nonzero: Vec<Vec<bool>>,
}

/// Render a [`Spy`] to `<stem>.png` and `<stem>.svg`.
pub fn render_spy(spy: &Spy, dir: &Path, stem: &str) -> Result<(), CromError> {
    render_both(spy, dir, stem)
}

fn draw_spy<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, spy: &Spy) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let rows = spy.nonzero.len().max(1);
    let cols = spy.nonzero.first().map_or(1, Vec::len).max(1);
    let mut ctx = ChartBuilder::on(root)
        .caption(&spy.title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..cols as f64, (rows as f64)..0f64)
        .map_err(|e| e.to_string())?;
    let f = |v: &f64| tick(*v, false);
    ctx.configure_mesh()
        .disable_mesh()
        .x_label_formatter(&f)
        .y_label_formatter(&f)
        .x_desc(spy.x_label.as_str())
        .y_desc(spy.y_label.as_str())
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(|e| e.to_string())?;
    let cells = spy.nonzero.iter().enumerate().flat_map(|(i, row)| {
        row.iter()
            .enumerate()
            .filter(|(_, nz)| **nz)
            .map(move |(j, _)| Rectangle::new([(j as f64, i as f64), (j as f64 + 1.0, i as f64 + 1.0)], BLACK.filled()))
    });
    ctx.draw_series(cells).map_err(|e| e.to_string())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{clear_position, legend_box, Legend};

    /// The legend stays where the chart asks while that corner is clear, moves to the corner
    /// covering the fewest points otherwise (the first in the stated order on a tie), and the box
    /// is where plotters draws it: 5 px from the area's edges, the text block plus 30 px of marker
    /// column and 10 px of margin each side. A 600 x 400 area, a 100 x 40 text block (box 150 x 60).
    #[test]
    fn the_legend_takes_the_clearest_corner() {
        let (label, area) = ((100, 40), (600, 400));
        assert_eq!(legend_box(Legend::UpperRight, label, area), (445, 5, 595, 65));
        assert_eq!(legend_box(Legend::LowerLeft, label, area), (5, 335, 155, 395));
        assert_eq!(legend_box(Legend::MiddleRight, label, area), (445, 170, 595, 230));
        // nothing drawn: where asked
        assert_eq!(clear_position(Legend::MiddleRight, &[], label, area), Legend::MiddleRight);
        // a point under the asked corner (and one in the lower left): the upper right is clear
        let pts = [(500, 200), (50, 380)];
        assert_eq!(clear_position(Legend::MiddleRight, &pts, label, area), Legend::UpperRight);
        // a marker's radius counts: a point 3 px outside the upper right box is covered
        let pts = [(598, 30), (500, 200)];
        assert_eq!(clear_position(Legend::UpperRight, &pts, label, area), Legend::UpperLeft);
        // every corner covered once but the lower right twice: the asked one stays
        let pts = [(500, 30), (50, 30), (50, 380), (500, 380), (520, 390), (500, 200)];
        assert_eq!(clear_position(Legend::UpperLeft, &pts, label, area), Legend::UpperLeft);
    }
}
