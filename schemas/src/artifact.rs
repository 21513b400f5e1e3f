//! Artifact kinds of the store, their schema versions, file names, HDF5 dataset paths and
//! Parquet column names: the contract between the pipeline and anyone reading the store from
//! h5py, pandas or ParaView.
//!
//! Bump a kind's `schema_version` whenever the layout of its files changes: the version is part of
//! every cache key, so old artifacts are never read with a new layout.
//!
//! The whole format is specified for readers in `docs/store-format.md`.
//!
//! **Undefined values.** No table or array holds NaN or infinity, except the cone curve of a
//! large training set (see [`basis::COMPACTNESS`]). A float that is undefined is a Parquet null (every float column is nullable; pandas reads it as NaN, `Table::read_parquet` in
//! crom too), and its reason is what the row says:
//!
//! | table | column | null when |
//! |---|---|---|
//! | `rom_timings.parquet` | `fom_seconds` | `set == "train"`: the full-order solve is timed at test points only |
//! | `rom_timings.parquet` | `online_seconds`, `indicator_seconds`, `fom_seconds` | the point is not among the set's 32 timed points (evenly spaced with both ends; every point of a set of at most 32 is timed) |
//! | `rom_errors.parquet` | `dual_error` | the full-order pressure of the point is zero everywhere (`0/0`; no contact) |
//! | `tradeoff.parquet` | `median_primal_error`, `p95_primal_error`, `mean_primal_error`, `max_primal_error`, `median_dual_error` | `converged == 0` (errors are taken over converged points only), or no converged point has a defined dual error |
//! | `tradeoff.parquet` | `indicator_spearman` | fewer than three converged points with finite indicator and error, or either side constant |
//! | `tradeoff.parquet` | `indicator_effectivity` | no converged point with a non-zero error |
//! | `tradeoff.parquet` | `min_inf_sup`, `median_inf_sup` | no converged point among the sampled ones (8 evenly spaced test points), or none has a dual basis vector that constrains at its pairing |
//! | `tradeoff_timings.parquet` | `speedup` | no test point (no full-order time) |
//! | `solver_stats.parquet`, the column index | `min_gap` | no slave has the master under it (no signed distance to take the minimum of) |
//!
//! Tested: `io::table` writes every non-finite float as a null (checked with the arrow reader),
//! and `tests/python/test_no_nonfinite.py` scans every Parquet and HDF5 file of the rope, hertz
//! and ironing-fine stores with pyarrow and h5py.

/// One kind of artifact (one stage's output): the directory its artifacts live in under the
/// store root, which is also the stage name in manifests and keys; the layout version of its
/// files; and which of its files carry wall-clock times. Each kind is declared once, as a
/// constant beside its files' names (`mesh::KIND`, `rom::KIND`, …), by the stage that writes
/// it. The shipped kinds are listed in [`ArtifactKind::ALL`]; a kind outside that list (a stage
/// added to the pipeline with its own `ArtifactKind::new`) is stored, verified, catalogued and
/// published like any other, and listed after them.
///
/// Bump a kind's `schema_version` whenever the layout of its files changes: the version is part
/// of every cache key, so old artifacts are never read with a new layout, and it is written into
/// every manifest and `study.json` entry, where the Python reader takes it from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ArtifactKind {
    name: &'static str,
    schema_version: u32,
    timing: &'static [&'static str],
}

impl ArtifactKind {
    /// The kind `name` (the directory under the store root; lower case, `-` between words) at
    /// layout version `schema_version`, no file of which carries times.
    pub const fn new(name: &'static str, schema_version: u32) -> Self {
        Self { name, schema_version, timing: &[] }
    }

    /// The same kind whose files `timing` carry wall-clock times ([`timing_files`]).
    pub const fn with_timing(self, timing: &'static [&'static str]) -> Self {
        Self { timing, ..self }
    }

    /// The scene's discretisation: `mesh.h5` (+ `mesh.xdmf`).
    pub const MESH: ArtifactKind = mesh::KIND;
    /// One high-fidelity solve at one parameter value. The kind names snapshot and column-family
    /// keys; snapshots are stored as columns of a column family (`columns/`), and a
    /// `snapshot/<key>/snapshot.h5` directory is the former layout, read only to migrate it.
    pub const SNAPSHOT: ArtifactKind = snapshot::KIND;
    /// A set of snapshots as matrices: `snapshots.h5` + `solver_stats.parquet`.
    pub const TRAINING_SET: ArtifactKind = trainset::KIND;
    /// Reduced bases of one training set: `basis.h5`.
    pub const BASIS: ArtifactKind = basis::KIND;
    /// Compactness C(m) of every basis: `compactness.parquet`.
    pub const COMPACTNESS: ArtifactKind = compactness::KIND;
    /// Leave-one-out generalization G(m) (eq. 17): `generalization.parquet`.
    pub const GENERALIZATION: ArtifactKind = metrics::GENERALIZATION_KIND;
    /// Specificity S(m) (eq. 18): `specificity.parquet`.
    pub const SPECIFICITY: ArtifactKind = metrics::SPECIFICITY_KIND;
    /// Nested-training-set error H(n) (eq. 19): `nested.parquet`.
    pub const NESTED: ArtifactKind = metrics::NESTED_KIND;
    /// One dual approximation built and measured: the [`comparison`] tables of that
    /// approximation alone, and `bases.h5` where its basis does not depend on the parameter.
    pub const APPROXIMATION: ArtifactKind = comparison::APPROXIMATION_KIND;
    /// Dual approximations side by side: the `approximation` artifacts' tables
    /// concatenated, `comparison.parquet` and the rest of [`comparison`].
    pub const COMPARISON: ArtifactKind = comparison::KIND;
    /// The online solve with one dual approximation: [`comparison::ONLINE`] and
    /// [`comparison::ONLINE_TIMINGS`] of that approximation alone.
    pub const ONLINE_APPROXIMATION: ArtifactKind = comparison::ONLINE_APPROXIMATION_KIND;
    /// The online solve with each dual approximation: the `online-approximation`
    /// artifacts' tables concatenated, `online_comparison.parquet`.
    pub const ONLINE_COMPARISON: ArtifactKind = comparison::ONLINE_KIND;
    /// ParaView time series (XDMF) of a snapshot set or a basis: `*.xdmf` + `views.h5`.
    pub const VIEWS: ArtifactKind = views::KIND;
    /// Online reduced solves: errors and timings (`rom_errors.parquet`, `tradeoff.parquet`).
    pub const ROM: ArtifactKind = rom::KIND;
    /// The reduced model a user runs (`crom query`): [`model::FILE`], everything the online
    /// solve reads, and [`model::RECONSTRUCTION`], the bases that turn its answers into fields.
    pub const MODEL: ArtifactKind = model::KIND;
    /// Figures, tables and `index.html` of a scene's study.
    pub const REPORT: ArtifactKind = report::KIND;

    /// The shipped kinds, in DAG order (the order of listings).
    pub const ALL: [ArtifactKind; 16] = [
        Self::MESH,
        Self::SNAPSHOT,
        Self::TRAINING_SET,
        Self::BASIS,
        Self::COMPACTNESS,
        Self::GENERALIZATION,
        Self::SPECIFICITY,
        Self::NESTED,
        Self::APPROXIMATION,
        Self::COMPARISON,
        Self::ONLINE_APPROXIMATION,
        Self::ONLINE_COMPARISON,
        Self::VIEWS,
        Self::ROM,
        Self::MODEL,
        Self::REPORT,
    ];

    /// Directory name under the store root and stage name in manifests.
    pub fn name(self) -> &'static str {
        self.name
    }

    /// The shipped kind named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Layout version of this kind's files.
    pub fn schema_version(self) -> u32 {
        self.schema_version
    }

    /// The files of this kind that carry wall-clock times.
    pub fn timing(self) -> &'static [&'static str] {
        self.timing
    }

    /// Where the stage named `name` comes in listings: the shipped kinds in DAG order, any
    /// other after them.
    pub fn order_of(name: &str) -> usize {
        Self::ALL.iter().position(|k| k.name() == name).unwrap_or(usize::MAX)
    }
}

/// The files that carry wall-clock times, (stage, file), of the shipped kinds: they differ from
/// run to run. Every other file of every artifact is a result, byte-identical across runs and
/// thread counts with the same build (tested), and so are the snapshot blocks. Store metadata —
/// manifests, the columns' `index.parquet` (which records solve times), `catalog.parquet`,
/// `study.json` — records when and how long, and is not a result.
pub fn timing_files() -> impl Iterator<Item = (&'static str, &'static str)> {
    ArtifactKind::ALL.into_iter().flat_map(|k| k.timing().iter().map(move |f| (k.name(), *f)))
}

/// The report directory: `index.html`, the figures (`fig_*.png`, `fig_*.svg`) and the tables
/// (`table_*.csv`, `table_*.md`).
pub mod report {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("report", 1).with_timing(&[
        "index.html",
        "fig_tradeoff.png",
        "fig_tradeoff.svg",
        "table_tradeoff.csv",
        "table_tradeoff.md",
        "table_comparison_builds.csv",
        "table_comparison_builds.md",
        "table_comparison_online.csv",
        "table_comparison_online.md",
        "fig_comparison_online.png",
        "fig_comparison_online.svg",
    ]);
}

/// The comparison of dual approximations (`crom_stages::dual`). Every table has a
/// `scene` and an `approximation` column (`pod`, `cpg`, `angle-greedy`, `nnmf`, `local-K`,
/// `dictionary`, `registered-<map>-<basis>`), so a pandas user can rebuild any plot. Each
/// approximation is its own artifact (kind `approximation`, and `online-approximation` for its
/// online solve) holding these tables for that approximation alone, so changing one
/// approximation's settings recomputes only it; the `comparison` and `online-comparison`
/// artifacts hold the same tables of every approximation of the scene, concatenated in the
/// scene file's order.
pub mod comparison {
    use super::ArtifactKind;

    /// One approximation's tables.
    pub const APPROXIMATION_KIND: ArtifactKind = ArtifactKind::new("approximation", 1).with_timing(&[TIMINGS]);
    /// Every approximation's tables side by side.
    pub const KIND: ArtifactKind = ArtifactKind::new("comparison", 1).with_timing(&[TIMINGS]);
    /// One approximation's online solve.
    pub const ONLINE_APPROXIMATION_KIND: ArtifactKind =
        ArtifactKind::new("online-approximation", 1).with_timing(&[ONLINE_TIMINGS]);
    /// Every approximation's online solve side by side.
    pub const ONLINE_KIND: ArtifactKind = ArtifactKind::new("online-comparison", 1).with_timing(&[ONLINE_TIMINGS]);

    /// Curves: `scene, approximation, metric, m, mean, std, count, n_zero`, one row per
    /// (approximation, metric, m). `metric` is `compactness` (C(m) over the training set;
    /// `std` null), `generalization` (leave-one-out G(m) over `comparison.loo_folds` evenly
    /// spaced folds), `test` (mean relative error over the test set, each snapshot at its own
    /// parameter, in the physical frame) or `specificity` (S(m), eq. 18, `study.specificity_samples`
    /// members; none for the dictionary, which has no modes). `count` is the number of snapshots averaged,
    /// `n_zero` the zero snapshots skipped (no relative error).
    pub const CURVES: &str = "comparison.parquet";
    /// Nested error H(n) (eq. 19) per approximation: `scene, approximation, n, m, value`,
    /// built from level n with at most `m` modes (the largest of the grid), level n + 1
    /// projected (empty without nested levels).
    pub const NESTED: &str = "comparison_nested.parquet";
    /// Local bases per cell: `scene, approximation, cell, metric, m, mean, count` — the test
    /// error (`test`, the test points of that cell) and leave-one-out (`generalization`, the
    /// folds whose snapshot lies in that cell) per cell; the cells' sizes are in [`FACTS`].
    pub const CELLS: &str = "comparison_cells.parquet";
    /// Smallest m reaching each threshold: `scene, approximation, metric, threshold, m`
    /// (`m` null: never within the curve).
    pub const REACHED: &str = "comparison_reached.parquet";
    /// The error thresholds of [`REACHED`] (mean relative error), largest first.
    pub const THRESHOLDS: [f64; 3] = [0.05, 0.01, 0.001];
    /// Numbers describing each build: `scene, approximation, name, m, value` (`m` null where
    /// the number is not per rank), e.g. NNMF's `iterations` and `relative_residual` per rank,
    /// a registration's `round_trip_error_mean` / `_max`, a local basis' cell sizes.
    pub const FACTS: &str = "comparison_facts.parquet";
    /// Wall-clock seconds: `scene, approximation, build_seconds, metrics_seconds`.
    pub const TIMINGS: &str = "comparison_timings.parquet";
    /// In an `approximation` artifact whose non-negative basis does not depend on the parameter
    /// (CPG, Angle-Greedy, NNMF): the basis of each dual size the online solve uses, dataset
    /// `m<k>` (`n_contact x k`, columns the generators, rows the potential-contact nodes in
    /// dual-field order); the online stage reads them instead of building the approximation
    /// again.
    pub const BASES: &str = "bases.h5";
    /// The online solve with each approximation that has a non-negative dual basis (artifact
    /// kind `online-comparison`), one row per (approximation, m) over the test points:
    /// `scene, approximation, m, r_primal, points, converged, infeasible, failed,
    /// median_primal_error, p95_primal_error, median_dual_error, p95_dual_error,
    /// median_nonzero_dual` (errors over converged points; `m` = the dual basis size asked for,
    /// for the dictionary its number of atoms; `median_nonzero_dual` = dual coefficients
    /// above 1e-9 of the largest: the active atoms).
    pub const ONLINE: &str = "online_comparison.parquet";
    /// Its times (same rows): `scene, approximation, m, median_online_ms, p95_online_ms,
    /// median_full_order_ms, speedup` (the full-order solve timed in the same process).
    pub const ONLINE_TIMINGS: &str = "online_comparison_timings.parquet";
}

/// Name of the JSON manifest in every artifact directory.
pub const MANIFEST: &str = "manifest.json";

/// `mesh.h5`: `/nodes` (n_nodes x dim), `/cells` (n_cells x nodes_per_cell, u64),
/// `/contact_nodes` (u64, the potential-contact nodes, order of the dual field),
/// `/node_body`, `/cell_body` (u64 body ids). Attributes: `scene`, `kind`, `schema_version`,
/// `cache_key`, `dofs_per_node` and the stiffness estimates below.
pub mod mesh {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("mesh", 2);

    /// HDF5 file.
    pub const FILE: &str = "mesh.h5";
    /// XDMF sidecar for ParaView.
    pub const XDMF: &str = "mesh.xdmf";
    /// Node coordinates.
    pub const NODES: &str = "nodes";
    /// Cell connectivity.
    pub const CELLS: &str = "cells";
    /// Potential-contact nodes.
    pub const CONTACT_NODES: &str = "contact_nodes";
    /// Body id of each node.
    pub const NODE_BODY: &str = "node_body";
    /// Body id of each cell.
    pub const CELL_BODY: &str = "cell_body";
    /// Root attributes (the conditioning of the stiffness): estimates of the largest and
    /// smallest eigenvalue of the stiffness on the free dofs and their ratio, a lower bound on
    /// its 2-norm condition number, by power and inverse iteration with the solver's own factor
    /// (`crom_stages::condition`).
    pub const STIFFNESS_LAMBDA_MAX: &str = "stiffness_lambda_max";
    /// See [`STIFFNESS_LAMBDA_MAX`].
    pub const STIFFNESS_LAMBDA_MIN: &str = "stiffness_lambda_min";
    /// See [`STIFFNESS_LAMBDA_MAX`].
    pub const STIFFNESS_CONDITION: &str = "stiffness_condition";
}

/// `snapshot.h5` of the former one-directory-per-snapshot layout, read only to import it into a
/// column family: `/u` (n_dof), `/pressure` (n_contact), attribute `parameter` and the solver
/// statistics as attributes.
pub mod snapshot {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("snapshot", 1);

    /// HDF5 file.
    pub const FILE: &str = "snapshot.h5";
    /// Primal field (all dofs).
    pub const U: &str = "u";
    /// Dual field as pressure.
    pub const PRESSURE: &str = "pressure";
}

/// `snapshots.h5`: `/primal` (n_dof x n_snap), `/dual` (n_contact x n_snap), `/parameters`
/// (n_snap); column j of both matrices is the solve at `parameters[j]`.
pub mod trainset {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("trainset", 4).with_timing(&[TIMINGS]);

    /// HDF5 file.
    pub const FILE: &str = "snapshots.h5";
    /// Primal snapshot matrix.
    pub const PRIMAL: &str = "primal";
    /// Dual snapshot matrix (pressure).
    pub const DUAL: &str = "dual";
    /// Parameter value of each column.
    pub const PARAMETERS: &str = "parameters";
    /// Per-snapshot solver statistics table: where each column lives and the solver's evidence
    /// (deterministic: byte-identical across runs).
    pub const STATS: &str = "solver_stats.parquet";
    /// Columns of [`STATS`], in order; a vector parameter adds one column per component (by
    /// name) after `parameter`, its first component.
    pub const STATS_COLUMNS: [&str; 19] = [
        "scene",
        "index",
        "parameter",
        "snapshot_key",
        "block",
        "column",
        "blake3",
        "iterations",
        "active",
        "max_penetration",
        "min_lambda",
        "complementarity",
        "kkt_residual",
        "vertex_ties",
        "vertex_nodes",
        "vertex_rounds",
        "min_gap",
        "active_gap",
        "cone_angle",
    ];
    /// Wall-clock solve time of each snapshot, apart from the results (it differs per run).
    pub const TIMINGS: &str = "solver_timings.parquet";
    /// Columns of [`TIMINGS`] (same rows as [`STATS`]).
    pub const TIMING_COLUMNS: [&str; 4] = ["scene", "index", "snapshot_key", "seconds"];
}

/// `basis.h5`: groups `/primal_pod`, `/dual_pod` with `modes` (n x m) and `singular_values`
/// (all, descending); `/dual_cpg` with `modes` (n x m, unit columns, selection order),
/// `selected` (u64 snapshot indices), `compactness` (C(0..=m) of the greedy) and `gram_rcond`;
/// `/dual_cpg_truncated` likewise at the truncation tolerance. Group attributes: `tolerance`,
/// `rank` and, for the POD groups, `numerical_rank`.
pub mod basis {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("basis", 2);

    /// HDF5 file.
    pub const FILE: &str = "basis.h5";
    /// Group of the primal POD.
    pub const PRIMAL_POD: &str = "primal_pod";
    /// Group of the dual POD.
    pub const DUAL_POD: &str = "dual_pod";
    /// Group of the full CPG dual basis.
    pub const DUAL_CPG: &str = "dual_cpg";
    /// Group of the truncated CPG dual basis.
    pub const DUAL_CPG_TRUNCATED: &str = "dual_cpg_truncated";
    /// Basis vectors, one per column.
    pub const MODES: &str = "modes";
    /// Singular values (POD groups).
    pub const SINGULAR_VALUES: &str = "singular_values";
    /// Selected snapshot indices (CPG groups).
    pub const SELECTED: &str = "selected";
    /// Greedy compactness trace (CPG groups). Above 1 025 training snapshots it is evaluated on
    /// a rank grid and NaN at the other ranks (the dataset's `units` attribute says so): the one
    /// place an artifact holds NaN.
    pub const COMPACTNESS: &str = "compactness";
    /// CPG groups: after each selection t, the reciprocal of the estimated 1-norm
    /// condition number of the Gram `G_t = B_tᵀ B_t` of the first t generators
    /// (`crom_stages::basis::gram_condition_path`; Hager's estimator on the MGS-twice factor).
    /// It bounds the conditioning of every NNLS Gram of that step (each is a principal
    /// submatrix of `G_t`). The LAPACK `rcond` convention keeps it finite: 0 means a generator
    /// lies in the span of the earlier ones.
    pub const GRAM_RCOND: &str = "gram_rcond";
}

/// `compactness.parquet`: columns scene, field, basis, m, value (eq. 16).
pub mod compactness {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("compactness", 1);

    /// Parquet file.
    pub const FILE: &str = "compactness.parquet";
    /// Columns, in order.
    pub const COLUMNS: [&str; 5] = ["scene", "field", "basis", "m", "value"];
}

/// Metric tables (`generalization.parquet`, `specificity.parquet`): one row per field, basis and
/// rank m; `nested.parquet`: one row per field, projection and level n.
pub mod metrics {
    use super::ArtifactKind;

    /// The kind of [`GENERALIZATION`].
    pub const GENERALIZATION_KIND: ArtifactKind = ArtifactKind::new("generalization", 1);
    /// The kind of [`SPECIFICITY`].
    pub const SPECIFICITY_KIND: ArtifactKind = ArtifactKind::new("specificity", 1);
    /// The kind of [`NESTED`].
    pub const NESTED_KIND: ArtifactKind = ArtifactKind::new("nested", 1);

    /// G(m) table.
    pub const GENERALIZATION: &str = "generalization.parquet";
    /// S(m) table.
    pub const SPECIFICITY: &str = "specificity.parquet";
    /// Columns of the G(m) and S(m) tables.
    pub const CURVE_COLUMNS: [&str; 9] = ["scene", "field", "basis", "m", "mean", "std", "count", "padded", "n_zero"];
    /// The column a G(m) table from a sample of folds adds after [`CURVE_COLUMNS`]: the
    /// half-width of the 95 % interval of each `mean` as an estimate of the mean over every
    /// fold (NaN where fewer than two folds count at that m).
    pub const INTERVAL: &str = "ci95";
    /// H(n) table.
    pub const NESTED: &str = "nested.parquet";
    /// Columns of the H(n) table.
    pub const NESTED_COLUMNS: [&str; 7] = ["scene", "field", "basis", "n", "value", "snapshots", "n_zero"];
}

/// `rom_errors.parquet` (one row per query point and dual basis), `tradeoff.parquet` (one row
/// per primal/dual rank pair, over the test points) and `online.h5`: the online solution at
/// every test point (exact algorithm, full ranks, full CPG dual basis) as fields — `primal`
/// (n_dof x n_test, `u0(mu) + Phi û`), `dual` (n_contact x n_test, `Theta λ̂`), their pointwise
/// errors against the test snapshots `primal_error`, `dual_error` (reduced minus full order),
/// `parameters`, and `converged` (1 where the query converged).
/// The reduced model a user runs (`crom query`; layout in `docs/store-format.md`).
pub mod model {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("model", SCHEMA_VERSION).with_timing(&[SPEED]);

    /// Everything the online solve reads: the reduced operators, the contact-surface rows and
    /// pairing geometry, the dual basis, the warm starts (datasets named as in
    /// `crom_stages::rom::ModelParts`), the solver settings, the parameter's names and domain,
    /// and the accuracy the study measured (attributes). Its size does not depend on `n_dof`.
    pub const FILE: &str = "model.h5";
    /// Optional part: the primal basis `phi` (`n_dof x r_primal`) and the lift's affine terms
    /// `lift` (`n_dof x (1 + dim)`), for `u(mu) = lift[:, 0] + sum_k mu_k lift[:, k + 1] + phi u_hat`.
    pub const RECONSTRUCTION: &str = "reconstruction.h5";
    /// The speed the study measured for this model (one row: `median_online_seconds`,
    /// `median_fom_seconds`, `speedup`), apart from the results: a timing.
    pub const SPEED: &str = "model_speed.parquet";
    /// Columns of [`SPEED`].
    pub const SPEED_COLUMNS: [&str; 3] = ["median_online_seconds", "median_fom_seconds", "speedup"];
    /// The schema version written into [`FILE`] as its `schema_version` attribute (the
    /// kind's), which `crom query` checks before reading (2: a registered dual basis, the
    /// `reg_*` datasets and attributes; 3: a registered neighbours basis, `reg_travels` and
    /// `reg_weight`; 4: the `exact_step` attribute, the corrected re-pairing step of a model
    /// whose primal space holds translated responses; older files are refused with the fix to
    /// run the study again).
    pub const SCHEMA_VERSION: u32 = 4;
}

pub mod rom {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("rom", 4).with_timing(&[TIMINGS, TRADEOFF_TIMINGS]);

    /// Online solution fields at the test points.
    pub const ONLINE: &str = "online.h5";
    /// In [`ONLINE`], where the online stage measured a sample of a large test set only: the
    /// test set's column of each solution (absent: every column, in order).
    pub const TEST_COLUMNS: &str = "test_columns";
    /// Errors of the online solve at training and test points.
    pub const ERRORS: &str = "rom_errors.parquet";
    /// Columns of [`ERRORS`]; a vector parameter adds one column per component after
    /// `parameter`.
    pub const ERROR_COLUMNS: [&str; 17] = [
        "scene",
        "set",
        "dual_basis",
        "algorithm",
        "parameter",
        "r_primal",
        "r_dual",
        "primal_error",
        "dual_error",
        "iterations",
        "linearizations",
        "nonzero_dual",
        "outcome",
        "indicator",
        "penetration",
        "complementarity",
        "unpaired_force",
    ];
    /// Wall-clock times of each query of [`ERRORS`] (same rows), apart from the results.
    pub const TIMINGS: &str = "rom_timings.parquet";
    /// Columns of [`TIMINGS`].
    pub const TIMING_COLUMNS: [&str; 10] = [
        "scene",
        "set",
        "dual_basis",
        "algorithm",
        "parameter",
        "r_primal",
        "r_dual",
        "online_seconds",
        "indicator_seconds",
        "fom_seconds",
    ];
    /// Accuracy over rank pairs (the results half of the speed/accuracy trade).
    pub const TRADEOFF: &str = "tradeoff.parquet";
    /// The `algorithm` of [`TRADEOFF`]'s rows of the exact solve on a sampled surface (a
    /// reduced quadrature of the contact constraints, `study.contact_sampling`); the other
    /// values are `exact` and `paper`.
    pub const SAMPLED: &str = "exact-sampled";
    /// Columns of [`TRADEOFF`]. `min_inf_sup` and `median_inf_sup`: the reduced inf-sup
    /// constant `sigma_min(Â L^{-T})` of the saddle-point system at each query's final
    /// linearisation (`crom_stages::rom::ReducedModel::inf_sup`; 0: more constraining dual
    /// vectors than primal modes or paired nodes, or nearly parallel ones), over the converged ones among 8
    /// evenly spaced test points.
    pub const TRADEOFF_COLUMNS: [&str; 18] = [
        "scene",
        "algorithm",
        "dual_basis",
        "r_primal",
        "r_dual",
        "points",
        "converged",
        "infeasible",
        "failed",
        "median_primal_error",
        "p95_primal_error",
        "mean_primal_error",
        "max_primal_error",
        "median_dual_error",
        "indicator_spearman",
        "indicator_effectivity",
        "min_inf_sup",
        "median_inf_sup",
    ];
    /// Speed over rank pairs (same rows as [`TRADEOFF`]): online and full-order times measured
    /// in the same process, the speed-up.
    pub const TRADEOFF_TIMINGS: &str = "tradeoff_timings.parquet";
    /// Columns of [`TRADEOFF_TIMINGS`].
    pub const TRADEOFF_TIMING_COLUMNS: [&str; 10] = [
        "scene",
        "algorithm",
        "dual_basis",
        "r_primal",
        "r_dual",
        "median_online_seconds",
        "p95_online_seconds",
        "median_fom_seconds",
        "speedup",
        "median_indicator_seconds",
    ];
}

/// `views.h5` + XDMF files: a snapshot set (`snapshots.xdmf`), a basis (`primal_pod.xdmf`,
/// `dual_pod.xdmf`, `dual_cpg.xdmf`) or the online solutions (`online.xdmf`) as an XDMF
/// temporal collection that ParaView (and
/// meshio's `TimeSeriesReader`) opens, one step per snapshot or mode. Every step is a group
/// `/steps/<00000>` of `views.h5` whose `displacement` (n_nodes x 3, z = 0) and `pressure`
/// (n_nodes, 0 off the contact surface) are HDF5 virtual datasets onto the stored columns —
/// nothing is copied — and whose parameter fields (one per component, constant over the nodes)
/// are small compressed datasets. The mesh, `node_body` and `cell_body` come from `mesh.h5`.
pub mod views {
    use super::ArtifactKind;

    /// The kind.
    pub const KIND: ArtifactKind = ArtifactKind::new("views", 1);

    /// HDF5 file of the step datasets.
    pub const FILE: &str = "views.h5";
    /// XDMF of a snapshot set.
    pub const SET_XDMF: &str = "snapshots.xdmf";
    /// XDMF of the online solutions at the test points: `displacement`, `pressure` (online),
    /// `displacement_error`, `pressure_error` (online minus full order), `displacement_fom`,
    /// `pressure_fom`, the parameter and `converged` (1 or 0) per step.
    pub const ONLINE_XDMF: &str = "online.xdmf";
    /// Group of the steps.
    pub const STEPS: &str = "steps";
    /// Point vector field of a step (3 components, z = 0).
    pub const DISPLACEMENT: &str = "displacement";
    /// Point scalar field of a step (0 off the contact surface).
    pub const PRESSURE: &str = "pressure";
}

/// `catalog.parquet` at the store root: one row per artifact and per snapshot column family,
/// rebuilt from the manifests (the source of truth) and replaced atomically whenever an
/// artifact is committed, a scene's names are published or something is quarantined.
pub mod catalog {
    /// Parquet file at the store root.
    pub const FILE: &str = "catalog.parquet";
    /// Columns, in order: `set` is train / test / nested-k for training sets; `bases` the basis
    /// groups a basis artifact holds; `inputs` a JSON object role -> key (a set's snapshot keys
    /// are summarised, they are in its `solver_stats.parquet`); `path` is relative to the store;
    /// `published` lists the `scene/name` entries that point at the artifact. Empty strings
    /// where a column does not apply.
    pub const COLUMNS: [&str; 15] = [
        "stage",
        "scene",
        "set",
        "bases",
        "key",
        "inputs",
        "schema_version",
        "algorithm_version",
        "crom_version",
        "created_unix",
        "created",
        "bytes",
        "files",
        "path",
        "published",
    ];
}

/// Stable names of each scene's latest complete study: `scenes/<scene>` is a relative symbolic
/// link to `scenes/.versions/<scene>@<stamp>/`, a directory of relative links to the
/// content-addressed files plus `study.json`; a successful run swaps the one link atomically.
pub mod published {
    /// Directory under the store root.
    pub const DIR: &str = "scenes";
    /// Directory of link sets under [`DIR`].
    pub const VERSIONS: &str = ".versions";
    /// Description of the link set: scene, entries (stage, key, target, schema version).
    pub const STUDY: &str = "study.json";
    /// Layout version of [`STUDY`] and the names; bump when either changes in a way a reader
    /// of the previous version would misread (a renamed or removed name, a new field meaning).
    /// New names are not such a change: a reader lists and opens the names it knows.
    pub const LAYOUT_VERSION: u32 = 1;
    /// Directory of the nested levels' names.
    pub const NESTED_DIR: &str = "nested";
    /// Directory of the comparison's tables: `comparison/comparison.parquet` and the
    /// rest of [`super::comparison`], `comparison/online_comparison.parquet` and its timings.
    pub const COMPARISON_DIR: &str = "comparison";
    /// Name of the report directory link.
    pub const REPORT: &str = "report";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_are_unique() {
        for k in ArtifactKind::ALL {
            assert_eq!(ArtifactKind::from_name(k.name()), Some(k));
        }
        let mut names: Vec<_> = ArtifactKind::ALL.iter().map(|k| k.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), ArtifactKind::ALL.len());
        assert_eq!(ArtifactKind::from_name("nope"), None);
    }
}
