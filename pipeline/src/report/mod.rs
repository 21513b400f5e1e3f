//! The report's content: every paper figure that applies to the scene (PNG + SVG), the tables
//! (CSV + Markdown) and an `index.html` showing them with the run's key numbers, rendered from
//! `ReportData`. The stage that keys it and reads its inputs is `dag::report`; this module
//! reads no artifact.

pub(crate) mod bodies;
pub mod chart;
mod figures;
mod html;
mod surface;
mod tables;

pub(crate) use surface::Surface;

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::CromError;
use crate::io::snapshot_set::TrainingSet;
use crate::io::table::Table;
use crom_schemas::SceneConfig;

/// One figure of the report.
#[derive(Debug, Clone)]
pub(crate) struct Figure {
    /// File stem (PNG and SVG).
    pub stem: String,
    /// Caption, with the paper's figure number.
    pub caption: String,
}

/// Render every figure, table and `index.html` into `dir`; returns the number of figures.
pub(crate) fn render(scene: &SceneConfig, data: &ReportData, dir: &Path) -> Result<usize, CromError> {
    let figures = figures::all(scene, data, dir)?;
    let tables = tables::write_all(scene, data, dir)?;
    html::write_index(scene, data, &figures, &tables, dir)?;
    Ok(figures.len())
}

/// Everything the figures need, read from the artifacts.
#[derive(Debug)]
pub(crate) struct ReportData {
    /// x coordinate of each potential-contact node (dual field abscissa); the entry index
    /// without a mesh.
    pub contact_x: Vec<f64>,
    /// A 3-D scene's contact entries along its symmetry plane (the lowest y of the slaves), in
    /// whose x the pressure snapshots are drawn as profiles; `None`: every entry.
    pub profile: Option<Vec<usize>>,
    /// Node x coordinates of a 1-D mesh (primal abscissa), empty for 2-D.
    pub line_x: Vec<f64>,
    /// The 2-D mesh (scenes with two displacement components per node), for the bodies figure.
    pub geometry: Option<bodies::Geometry>,
    /// A planar mesh to draw the pressure on (external scenes with a 2-D mesh).
    pub surface: Option<Surface>,
    /// The online pressure and its error at the test points (`online.h5`), for a scene drawn on
    /// its contact surface with the online stage.
    pub online_pressure: Option<OnlinePressure>,
    /// The scene has the online stage (native scenes); an external scene does not.
    pub online: bool,
    /// The scene has a mesh (every native scene; an external one when it gives one).
    pub mesh: bool,
    /// Parts of the study not planned, with their reasons (an external scene's approximations
    /// that need what it does not give).
    pub skipped: Vec<String>,
    /// Training set.
    pub train: std::sync::Arc<TrainingSet>,
    /// Singular values of the primal and dual snapshot matrices.
    pub primal_sv: Vec<f64>,
    /// Dual singular values.
    pub dual_sv: Vec<f64>,
    /// Ranks of the stored bases: primal, dual orth, dual cone, dual cone truncated.
    pub ranks: [usize; 4],
    /// (field, basis) → C(m).
    pub compactness: BTreeMap<(String, String), Vec<f64>>,
    /// Online errors per query (`rom_errors.parquet`).
    pub rom_errors: Table,
    /// Speed/accuracy trade (`tradeoff.parquet`).
    pub tradeoff: Table,
    /// G(m).
    pub generalization: Table,
    /// S(m).
    pub specificity: Table,
    /// H(n), if the scene has nested levels.
    pub nested: Option<Table>,
    /// The dual approximations compared, if the scene has `[comparison]`.
    pub comparison: Option<ComparisonData>,
    /// Conditioning of the stiffness and of the CPG Gram (`quantity, subject, value`).
    pub conditioning: Table,
    /// The reduced model the study stored for `crom query`, if it has one.
    pub model: Option<ModelFacts>,
}

/// The online pressure at the test points and its error against the full-order one (from
/// `online.h5`; the full-order pressure is the online one less its error).
#[derive(Debug)]
pub(crate) struct OnlinePressure {
    /// Parameter point of each test point.
    pub parameters: Vec<Vec<f64>>,
    /// Online pressure, `n_contact x k` (dual-entry order).
    pub online: crate::io::h5::ColMatrix,
    /// Online minus full-order pressure, same shape.
    pub error: crate::io::h5::ColMatrix,
}

/// What the report says of the stored reduced model (`model.h5` and `model_speed.parquet`).
#[derive(Debug)]
pub(crate) struct ModelFacts {
    /// `model.h5`'s `dual_basis` (`full`, `truncated` or a registered approximation's name).
    pub dual_basis: String,
    /// Its solve (`exact` or `exact-sampled`).
    pub algorithm: String,
    /// Primal rank and dual size (a registered basis: its most generators per query).
    pub ranks: (usize, usize),
    /// Test points the study measured it at.
    pub points: u64,
    /// Of which converged.
    pub converged: u64,
    /// Median relative error of the pressure there (NaN: undefined).
    pub median_dual_error: f64,
    /// Median relative H1 error of the displacement.
    pub median_primal_error: f64,
    /// Its speed-up over the full-order solve timed in the same process (a timing).
    pub speedup: Option<f64>,
    /// Every parameter component's name and the middle of its range (the example query, which
    /// must give each component once).
    pub example: Vec<(String, f64)>,
}

/// The comparison artifact's tables (`crom_schemas::artifact::comparison`).
#[derive(Debug)]
pub(crate) struct ComparisonData {
    /// C(m), G(m), T(m) per approximation.
    pub curves: Table,
    /// Smallest m reaching each threshold.
    pub reached: Table,
    /// Build facts.
    pub facts: Table,
    /// Build and metric times.
    pub timings: Table,
    /// H(n) per approximation.
    pub nested: Table,
    /// Local bases' metrics per cell.
    pub cells: Table,
    /// The online solve with each approximation (results and times joined), if run.
    pub online: Option<Table>,
}
