//! An external scene: snapshots computed by another solver, read from files
//! (`[model.external]`; docs/user-guide.md, "Bring your own snapshots").
//!
//! ```toml
//! [model.external]
//! dual = { file = "snapshots.h5", dataset = "/pressure" }     # required: n_contact x N
//! primal = { file = "u.npy", layout = "rows" }                # optional: n_dof x N (here N x n_dof)
//! parameters = { file = "mu.csv", names = ["d_x"] }           # N rows, one column per name
//! train = [0, 2, 4]                                           # columns of the training set ...
//! test = [1, 3]                                               # ... and of the test set
//! # or, instead of `test`: a second set of files, every column of which is a test point
//! # [model.external.test_files]
//! # dual = ...; primal = ...; parameters = ...
//! ```
//!
//! An array is one snapshot per column (`layout = "columns"`, the default: shape
//! `(rows, N)`) or one per row (`layout = "rows"`: shape `(N, rows)`), in an HDF5 dataset
//! (`file` + `dataset`) or a NumPy `.npy` file (`file` alone; C or Fortran order). Relative
//! paths are relative to the scene file's directory.
//!
//! The pipeline reads the files' headers and parameter values when it loads the scene and
//! records what it found in [`ResolvedExternal`] (never in the scene file): the snapshots'
//! keys are the blake3 of the source files' bytes and the column index, so the plan of an
//! external scene is known before anything is imported.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Default of [`ExternalSpec::negative_tolerance`].
pub const DEFAULT_NEGATIVE_TOLERANCE: f64 = 1e-10;

/// `[model.external]`: where the snapshots of an external scene are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExternalSpec {
    /// The contact pressures (dual snapshots), `n_contact x N`.
    pub dual: ArraySource,
    /// The displacements (primal snapshots), `n_dof x N` (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub primal: Option<ArraySource>,
    /// The parameter value of every column.
    pub parameters: ParameterSource,
    /// Columns of the training set (default: every column when `test_files` is given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train: Option<Vec<usize>>,
    /// Columns of the test set (exactly one of `test` and `test_files`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test: Option<Vec<usize>>,
    /// A second set of files whose every column is a test point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_files: Option<SetFiles>,
    /// The contact nodes' coordinates, `n_contact x d` (optional; the registered approximations
    /// need them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coordinates: Option<ArraySource>,
    /// The mesh the snapshots live on (optional; the views and the report's pictures need it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshSource>,
    /// A pressure below `-negative_tolerance * max |column|` is an error (the cone methods
    /// assume non-negative multipliers) unless `clip_negative` is set; default
    /// [`DEFAULT_NEGATIVE_TOLERANCE`]. Values within the tolerance are kept as they are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub negative_tolerance: Option<f64>,
    /// Set every negative pressure to zero on import (default false).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub clip_negative: bool,
    /// Units of the primal and dual fields, for the stored attributes (default `["1", "1"]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<[String; 2]>,
    /// What the pipeline found in the files (filled when it loads the scene; never in the file).
    #[serde(skip)]
    pub resolved: Option<ResolvedExternal>,
}

impl ExternalSpec {
    /// The tolerance of the negative-pressure check.
    pub fn negative_tolerance(&self) -> f64 {
        self.negative_tolerance.unwrap_or(DEFAULT_NEGATIVE_TOLERANCE)
    }
}

/// `mesh = { ... }`: the mesh of an external scene, as arrays in one HDF5 file (`file` +
/// dataset paths) or one `.npy` file per array (`file` absent, each entry a path relative to
/// the scene file's directory).
///
/// - `nodes`: `(n_nodes, d)` floats, `d` in 1..=3, one row per node;
/// - `cells`: `(n_cells, k)` integers, 0-based node indices, one row per cell: `k = 2` segments
///   (any `d`), 3 triangles and 4 quadrilaterals (`d` = 2), 4 tetrahedra and 8 hexahedra
///   (`d` = 3), node order as in VTK;
/// - `dual_nodes`: `(n_contact,)` integers, the node of each dual entry (distinct); absent: the
///   dual entries are the nodes, in order (`n_contact = n_nodes`).
///
/// The primal snapshots are node-major: entry `dofs_per_node * i + c` is component `c` of node
/// `i`, with `dofs_per_node = n_dof / n_nodes` (a whole number).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSource {
    /// The HDF5 file holding the arrays (absent: each array is a `.npy` file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Node coordinates (dataset path, or `.npy` file).
    #[serde(default = "default_nodes")]
    pub nodes: String,
    /// Cells (dataset path, or `.npy` file).
    #[serde(default = "default_cells")]
    pub cells: String,
    /// The node of each dual entry (dataset path, or `.npy` file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dual_nodes: Option<String>,
}

fn default_nodes() -> String {
    "/nodes".to_string()
}

fn default_cells() -> String {
    "/cells".to_string()
}

/// The mesh of an external scene as read and checked when the scene is loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedMesh {
    /// Node coordinates, row-major `n_nodes x dim`.
    pub nodes: Vec<f64>,
    /// Coordinates per node (1, 2 or 3).
    pub dim: usize,
    /// Cells, row-major `n_cells x nodes_per_cell`.
    pub cells: Vec<u64>,
    /// Nodes per cell.
    pub nodes_per_cell: usize,
    /// The node of each dual entry.
    pub dual_nodes: Vec<u64>,
    /// Primal entries per node (0 without primal snapshots).
    pub dofs_per_node: usize,
    /// blake3 of all of the above: the mesh artifact's key.
    pub digest: String,
}

impl ResolvedMesh {
    /// Nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len() / self.dim.max(1)
    }

    /// Cells.
    pub fn n_cells(&self) -> usize {
        self.cells.len() / self.nodes_per_cell.max(1)
    }
}

/// The test set as a second set of files (`[model.external.test_files]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetFiles {
    /// Contact pressures.
    pub dual: ArraySource,
    /// Displacements (required when the training files have them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub primal: Option<ArraySource>,
    /// Parameter values (the same names as the training set's).
    pub parameters: ParameterSource,
}

/// How an array's snapshots are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// One snapshot per column: shape `(rows, N)`.
    #[default]
    Columns,
    /// One snapshot per row: shape `(N, rows)`.
    Rows,
}

/// One array in a file: an HDF5 dataset (`file` + `dataset`) or a `.npy` file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArraySource {
    /// The file (relative to the scene file's directory).
    pub file: PathBuf,
    /// The dataset path inside an HDF5 file (required for HDF5, absent for `.npy`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Snapshots as columns (default) or rows.
    #[serde(default, skip_serializing_if = "is_columns")]
    pub layout: Layout,
}

fn is_columns(l: &Layout) -> bool {
    *l == Layout::Columns
}

/// The parameter values: a CSV (header row with the names), a Parquet file (one column per
/// name), a `.npy` array (`N` or `N x p`, components in the order of `names`) or an HDF5 dataset
/// (same shapes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSource {
    /// The file (relative to the scene file's directory).
    pub file: PathBuf,
    /// The dataset path inside an HDF5 file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Names of the parameter's components (CSV / Parquet: the columns to read).
    pub names: Vec<String>,
    /// What the parameter means, for tables and figures.
    #[serde(default)]
    pub description: String,
}

/// One source array as found on disk.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedArray {
    /// Absolute (or scene-relative, as given and joined) path.
    pub path: PathBuf,
    /// HDF5 dataset, if any.
    pub dataset: Option<String>,
    /// Layout as given.
    pub layout: Layout,
    /// blake3 of the file's bytes.
    pub blake3: String,
    /// Entries per snapshot.
    pub rows: usize,
    /// Snapshots.
    pub cols: usize,
}

/// A set's columns in one pair of source arrays.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedSet {
    /// The dual array.
    pub dual: ResolvedArray,
    /// The primal array, if any.
    pub primal: Option<ResolvedArray>,
    /// Source columns, in the set's order.
    pub columns: Vec<usize>,
    /// Their parameter values.
    pub points: Vec<Vec<f64>>,
}

/// What the pipeline found in an external scene's files.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedExternal {
    /// The training set.
    pub train: ResolvedSet,
    /// The test set.
    pub test: ResolvedSet,
    /// Rows of the primal field (0 without primal snapshots).
    pub n_dof: usize,
    /// Rows of the dual field.
    pub n_contact: usize,
    /// The contact nodes' coordinates (`n_contact` points), if given.
    pub coordinates: Option<Vec<Vec<f64>>>,
    /// The mesh, if given.
    pub mesh: Option<ResolvedMesh>,
    /// Nested levels 1..=k of a training set that is a level-k grid (positions in the training
    /// set, ascending by parameter; level k is the whole set); empty otherwise.
    pub levels: Vec<Vec<usize>>,
}
