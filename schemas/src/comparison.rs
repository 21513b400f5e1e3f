//! `[comparison]`: the dual approximations a scene compares side by side.
//!
//! ```toml
//! [comparison]
//! max_m = 32          # largest basis size m (or active atoms) of the curves
//! loo_folds = 32      # leave-one-out folds, evenly spaced over the training points
//! approximations = [
//!   { kind = "pod" }, { kind = "cpg" }, { kind = "angle-greedy" },
//!   { kind = "nnmf", iterations = 300 },
//!   { kind = "local", cells = [2, 4, 8], overlap = 0.1 },
//!   { kind = "dictionary" },
//!   { kind = "registered", map = "translate", interpolation = "nodes", basis = "pod" },
//!   { kind = "registered", map = "translate", interpolation = "nodes", basis = "neighbours",
//!     primal_translates = 8 },
//! ]
//! ```

use serde::{Deserialize, Serialize};

/// The comparison's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComparisonSpec {
    /// Largest m of the curves (>= 1).
    #[serde(default = "default_max_m")]
    pub max_m: usize,
    /// Leave-one-out folds of G(m) (>= 1; capped at the training set's size).
    #[serde(default = "default_loo_folds")]
    pub loo_folds: usize,
    /// The approximations, in the order the tables list them.
    pub approximations: Vec<ApproximationSpec>,
}

fn default_max_m() -> usize {
    32
}

fn default_loo_folds() -> usize {
    32
}

/// One approximation (a `local` entry with several cell counts is one approximation per count).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ApproximationSpec {
    /// Proper orthogonal decomposition.
    Pod,
    /// Cone-Projected Greedy basis (tolerance 0).
    Cpg,
    /// Angle-Greedy selection, cone projection.
    AngleGreedy,
    /// Non-negative matrix factorisation per rank.
    Nnmf {
        /// Largest number of HALS sweeps per rank.
        #[serde(default = "default_iterations")]
        iterations: usize,
    },
    /// One CPG per cell of the first parameter's range.
    Local {
        /// Cell counts K to study.
        cells: Vec<usize>,
        /// Overlap in cell widths (>= 0).
        #[serde(default)]
        overlap: f64,
    },
    /// Every training snapshot an atom.
    Dictionary,
    /// A change of variables of the contact surface, then POD, CPG or neighbours.
    Registered {
        /// `translate` (by the first parameter, the iron's travel) or `moments` (centre and
        /// half-width of the pressure, interpolated in the parameter).
        map: MapSpec,
        /// `nodes` (whole-node shifts, translate only) or `linear`.
        #[serde(default)]
        interpolation: InterpolationSpec,
        /// Reference cells per finest node spacing (linear only).
        #[serde(default = "default_refine")]
        refine: usize,
        /// Basis built in the reference frame.
        basis: BasisSpec,
        /// Online only: the primal space of this approximation's online solve is the POD of the
        /// training responses and their translates by this many slave-surface node spacings
        /// either way (a slave body meshed as a regular grid along the travel), truncated at
        /// the training set's size, with the exact corrected re-pairing step. Absent: the POD of
        /// the training responses, as every other online solve.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        primal_translates: Option<usize>,
    },
}

fn default_iterations() -> usize {
    300
}

fn default_refine() -> usize {
    4
}

/// The registration map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MapSpec {
    /// `xi = x - mu_1`.
    Translate,
    /// `xi = (x - c(mu)) / a(mu)` from the pressure's moments.
    Moments,
}

/// How mapped values are evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InterpolationSpec {
    /// Linear interpolation on a finer reference grid.
    #[default]
    Linear,
    /// Whole-node shifts.
    Nodes,
}

/// The basis of a registered approximation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BasisSpec {
    /// POD.
    Pod,
    /// CPG.
    Cpg,
    /// Per query, the training snapshots nearest in the registered frame (translate with
    /// whole-node shifts, one or two parameter components).
    Neighbours,
    /// Over two parameter components: one POD per interval between consecutive levels of the
    /// second component, of the registered snapshots on its two levels (signed modes: offline).
    LevelPod,
}

impl ApproximationSpec {
    /// Whether a stored model can carry this entry as its dual basis: a registered CPG or
    /// neighbours basis (non-negative generators), whatever its map.
    pub fn storable(&self) -> bool {
        matches!(self, ApproximationSpec::Registered { basis: BasisSpec::Cpg | BasisSpec::Neighbours, .. })
    }

    /// The translates of the training responses an online solve with this entry adds to its
    /// primal space (`primal_translates`), if any.
    pub fn primal_translates(&self) -> Option<usize> {
        match self {
            ApproximationSpec::Registered { primal_translates, .. } => *primal_translates,
            _ => None,
        }
    }

    /// The approximations this entry stands for, each its own stage: a `local` entry gives one
    /// per cell count (with that count alone), every other entry itself.
    pub fn expand(&self) -> Vec<ApproximationSpec> {
        match self {
            ApproximationSpec::Local { cells, overlap } => {
                cells.iter().map(|&k| ApproximationSpec::Local { cells: vec![k], overlap: *overlap }).collect()
            }
            other => vec![other.clone()],
        }
    }

    /// The name of an expanded approximation in the tables and the plan (`pod`, `cpg`,
    /// `angle-greedy`, `nnmf`, `local-K`, `dictionary`, `registered-<map>-<basis>`; a `local`
    /// entry with several cell counts is named by its first).
    pub fn name(&self) -> String {
        let basis = |b: &BasisSpec| match b {
            BasisSpec::Pod => "pod",
            BasisSpec::Cpg => "cpg",
            BasisSpec::Neighbours => "neighbours",
            BasisSpec::LevelPod => "level-pod",
        };
        match self {
            ApproximationSpec::Pod => "pod".into(),
            ApproximationSpec::Cpg => "cpg".into(),
            ApproximationSpec::AngleGreedy => "angle-greedy".into(),
            ApproximationSpec::Nnmf { .. } => "nnmf".into(),
            ApproximationSpec::Local { cells, .. } => format!("local-{}", cells.first().copied().unwrap_or(0)),
            ApproximationSpec::Dictionary => "dictionary".into(),
            ApproximationSpec::Registered { map, interpolation, basis: b, .. } => {
                let map = match (map, interpolation) {
                    (MapSpec::Translate, InterpolationSpec::Nodes) => "translate-nodes",
                    (MapSpec::Translate, InterpolationSpec::Linear) => "translate-linear",
                    (MapSpec::Moments, _) => "moments",
                };
                format!("registered-{map}-{}", basis(b))
            }
        }
    }
}
