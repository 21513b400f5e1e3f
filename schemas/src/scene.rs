//! The scene file: `data/scenes/<name>.toml`. Every physical and numerical value of a scene
//! lives here (docs/scenes.md describes the shipped scenes); nothing of it is hard-coded in Rust.
//!
//! ```toml
//! [scene]
//! name = "rope"
//! description = "..."
//! [model.rope]          # exactly one of model.rope / hertz / ironing / hertz3d / ironing3d / external
//! ...
//! [parameter]           # the scalar parameter and its training grid
//! [solver]              # high-fidelity solver settings
//! [study]               # basis tolerances and metric settings
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{ParameterSpec, SceneError};

/// A whole, validated scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    /// Name and description.
    pub scene: SceneMeta,
    /// The physical model.
    pub model: Model,
    /// The parameter μ (a scalar, or a vector on a tensor grid). An external scene has none
    /// (its parameter values come from its files): [`ParameterSpec::unset`].
    #[serde(default = "ParameterSpec::unset")]
    pub parameter: ParameterSpec,
    /// High-fidelity solver settings. An external scene has none: [`SolverSpec::unset`].
    #[serde(default = "SolverSpec::unset")]
    pub solver: SolverSpec,
    /// Reduced-basis and metric settings.
    pub study: StudySpec,
    /// The dual approximations compared side by side (`[comparison]`, optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub comparison: Option<crate::comparison::ComparisonSpec>,
    /// Where the work runs (`crom run --executor`); changes no key and no result.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub executor: Option<ExecutorSpec>,
}

/// `[executor]`: settings of the executors other than the local one.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExecutorSpec {
    /// `[executor.slurm]`: the job array of `crom run --executor slurm`.
    #[serde(default)]
    pub slurm: SlurmSpec,
}

/// `[executor.slurm]`: how `crom run --executor slurm` submits its job array. Every field is
/// optional; a command-line flag of the same name overrides it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlurmSpec {
    /// `sbatch --partition`.
    pub partition: Option<String>,
    /// `sbatch --time` of one array task, e.g. `"01:00:00"`.
    pub time: Option<String>,
    /// `sbatch --mem` of one array task, e.g. `"4G"`.
    pub mem: Option<String>,
    /// `sbatch --account`.
    pub account: Option<String>,
    /// Snapshot points per array task (rounded to whole blocks); default 512.
    pub shard_size: Option<usize>,
    /// At most this many array tasks at once (`--array=…%N`).
    pub max_parallel: Option<usize>,
    /// CPUs per array task (`--cpus-per-task`, the worker's threads); default 1.
    pub cpus_per_task: Option<usize>,
}

/// Name and description of a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneMeta {
    /// Scene name (the file stem by convention).
    pub name: String,
    /// One line for humans.
    pub description: String,
}

/// The physical model of a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// 1-D rope over a rigid obstacle (Type-1, paper Sec. 3).
    Rope(RopeSpec),
    /// Two half-disks pressed together (Type-2, paper Sec. 5.1).
    Hertz(HertzSpec),
    /// An iron sliding on a slab (Type-2, paper Sec. 5.2).
    Ironing(IroningSpec),
    /// Two hemispheres pressed together, in 3-D (quarter model).
    Hertz3d(Hertz3dSpec),
    /// A die with a cylindrical sole slid along a block, in 3-D (half model).
    Ironing3d(Ironing3dSpec),
    /// Snapshots computed elsewhere, read from files ([`crate::external`]).
    External(Box<crate::external::ExternalSpec>),
}

impl Model {
    /// `rope`, `hertz`, `ironing`, `hertz3d`, `ironing3d` or `external`.
    pub fn kind(&self) -> &'static str {
        match self {
            Model::Rope(_) => "rope",
            Model::Hertz(_) => "hertz",
            Model::Ironing(_) => "ironing",
            Model::Hertz3d(_) => "hertz3d",
            Model::Ironing3d(_) => "ironing3d",
            Model::External(_) => "external",
        }
    }

    /// Whether the model is three-dimensional (hexahedra, node-to-surface contact).
    pub fn is_3d(&self) -> bool {
        matches!(self, Model::Hertz3d(_) | Model::Ironing3d(_))
    }

    /// The external scene's description, if this is one.
    pub fn external(&self) -> Option<&crate::external::ExternalSpec> {
        match self {
            Model::External(e) => Some(e.as_ref()),
            _ => None,
        }
    }
}

/// Rope: minimise `∫ ½ ν u'² + f u dx` on `[0, length]`, `u(0) = u(L) = 0`, `u >= g(x, γ)`, with
/// `g(x, γ) = Σ_k a_k sin(m_k π x) + offset + γ x` (paper eqs. 14–15).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RopeSpec {
    /// Length of the rope (domain `[0, length]`).
    pub length: f64,
    /// Number of uniform P1 elements.
    pub n_elements: usize,
    /// Tension ν.
    pub nu: f64,
    /// Distributed load f (positive pulls the rope down).
    pub f: f64,
    /// Obstacle shape.
    pub obstacle: ObstacleSpec,
}

/// Obstacle `g(x, γ) = Σ_k amplitudes[k] sin(modes[k] π x) + offset + γ x`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Sine mode numbers `m_k`.
    pub modes: Vec<f64>,
    /// Sine amplitudes `a_k` (same length as `modes`).
    pub amplitudes: Vec<f64>,
    /// Constant offset.
    pub offset: f64,
}

/// Linear isotropic material.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E (> 0).
    pub young: f64,
    /// Poisson ratio ν (in (-1, 0.5)).
    pub poisson: f64,
    /// How the Q1 elements of this body integrate the stiffness: `"full"` (2x2 Gauss, the
    /// default) or `"selective"` (the volumetric part with one point, the remedy for locking
    /// as ν → ½). Left out of keys when full, so existing scenes keep their keys.
    #[serde(default, skip_serializing_if = "Integration::is_full")]
    pub integration: Integration,
}

/// Quadrature of a body's Q1 stiffness.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Integration {
    /// 2x2 Gauss for the whole stiffness.
    #[default]
    Full,
    /// Selective reduced integration: deviatoric part 2x2, volumetric part at the centre.
    Selective,
}

impl Integration {
    /// The default (serde's `skip_serializing_if`).
    pub fn is_full(&self) -> bool {
        *self == Integration::Full
    }
}

/// Hertz: two identical half-disks; parameter d = imposed downward displacement of the top face.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HertzSpec {
    /// Radius of both half-disks.
    pub radius: f64,
    /// Material of both bodies.
    pub material: MaterialSpec,
    /// Elements on each curved edge.
    pub n_arc: usize,
}

/// Ironing: an iron with a circular sole pressed into a slab and moved by `d_x` (the parameter).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IroningSpec {
    /// The slab `[0, length] x [-height, 0]`.
    pub slab: SlabSpec,
    /// The iron.
    pub iron: IronSpec,
    /// Imposed downward displacement of the iron's top edge; absent when `d_y` is an axis of
    /// the parameter (`[[parameter.axes]]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d_y: Option<f64>,
}

/// The slab of the ironing scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlabSpec {
    /// Length along x.
    pub length: f64,
    /// Height (the slab spans y in [-height, 0]).
    pub height: f64,
    /// Elements along x.
    pub nx: usize,
    /// Elements along y.
    pub ny: usize,
    /// Material.
    pub material: MaterialSpec,
}

/// The iron of the ironing scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IronSpec {
    /// Width of the block.
    pub width: f64,
    /// Height of the block (sole's lowest point to the flat top).
    pub height: f64,
    /// Radius of the convex circular sole.
    pub sole_radius: f64,
    /// x of the sole's lowest point in the reference position (it touches the slab top there).
    pub contact_x: f64,
    /// Elements along x.
    pub nx: usize,
    /// Elements along y.
    pub ny: usize,
    /// Material.
    pub material: MaterialSpec,
}

/// `hertz3d`: two equal hemispheres (radius `radius`) touching at the origin, quarter model with
/// the symmetry planes `x = 0` and `y = 0`; the parameter `d` is the approach of the flat faces.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Hertz3dSpec {
    /// Radius of both hemispheres.
    pub radius: f64,
    /// Material of both bodies.
    pub material: MaterialSpec,
    /// Elements along each direction of each quarter hemisphere's block.
    pub n: usize,
    /// Grading of the elements toward the pole (1: uniform; 3 puts six slaves inside a contact
    /// radius of 0.05 R at n = 16).
    pub grading: f64,
    /// Slave nodes and master facets lie within this distance of the axis.
    pub contact_radius: f64,
    /// Symmetry planes, roller conditions (the quarter model's: `x = 0` and `y = 0`).
    pub symmetry: Vec<PlaneSpec>,
}

/// A symmetry plane `axis = at`: the displacement normal to it is zero on every node of it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// The plane's normal axis.
    pub axis: Axis,
    /// Where it lies on that axis.
    pub at: f64,
}

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z.
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// `ironing3d`: a die with a cylindrical sole (axis along y) pressed into a block and slid
/// along x by `d_x`, half model with the symmetry plane `y = 0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ironing3dSpec {
    /// The block `[0, length] x [0, depth] x [-height, 0]`.
    pub block: Block3dSpec,
    /// The die.
    pub die: DieSpec,
    /// Imposed downward displacement of the die's top; absent when `d_z` is a parameter axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d_z: Option<f64>,
    /// The slave nodes: the block-top nodes with `x_min <= x <= x_max` and `y <= y_max`.
    pub slaves: SlaveBoxSpec,
    /// Symmetry planes, roller conditions (the half model's: `y = 0`).
    pub symmetry: Vec<PlaneSpec>,
}

/// The block of `ironing3d`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Block3dSpec {
    /// Length along x.
    pub length: f64,
    /// Depth along y (the half model's; the symmetry plane is y = 0).
    pub depth: f64,
    /// Height (the block spans z in [-height, 0]).
    pub height: f64,
    /// Elements along x.
    pub nx: usize,
    /// Elements along y.
    pub ny: usize,
    /// Elements along z.
    pub nz: usize,
    /// Material.
    pub material: MaterialSpec,
}

/// The die of `ironing3d`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DieSpec {
    /// Width along x.
    pub width: f64,
    /// Depth along y (from the symmetry plane).
    pub depth: f64,
    /// Height from the sole's lowest line to the flat top.
    pub height: f64,
    /// Radius of the sole's cylinder (axis along y).
    pub sole_radius: f64,
    /// x of the sole's lowest line in the reference position (it touches the block there).
    pub contact_x: f64,
    /// Elements along x.
    pub nx: usize,
    /// Elements along y.
    pub ny: usize,
    /// Elements along z.
    pub nz: usize,
    /// Material.
    pub material: MaterialSpec,
}

/// The box of block-top nodes that are slaves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlaveBoxSpec {
    /// Least x.
    pub x_min: f64,
    /// Greatest x.
    pub x_max: f64,
    /// Greatest y.
    pub y_max: f64,
}

/// High-fidelity solver settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Relative KKT / complementarity residual to reach (> 0).
    pub rel_tol: f64,
    /// Iteration cap of the active-set loop (>= 1).
    pub max_iter: usize,
}

impl SolverSpec {
    /// The stand-in of an external scene, which solves nothing (no `[solver]` table): zeros,
    /// which validation refuses for a native scene ([`Self::is_unset`]).
    pub fn unset() -> Self {
        SolverSpec { rel_tol: 0.0, max_iter: 0 }
    }

    /// Whether this is [`Self::unset`].
    pub fn is_unset(&self) -> bool {
        self.rel_tol.to_bits() == 0 && self.max_iter == 0
    }
}

/// Reduced-basis and metric settings (docs/scenes.md#study-settings).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySpec {
    /// Relative Frobenius truncation tolerance δ of the primal POD (eq. 9); 0 keeps the numerical rank.
    pub primal_tol: f64,
    /// Same for the dual POD ("dual orth").
    pub dual_orth_tol: f64,
    /// Stopping tolerance of the Cone-Projected Greedy dual basis ("dual cone", full basis).
    pub dual_cone_tol: f64,
    /// Tolerance of the truncated CPG basis (paper Tables 1–2).
    pub dual_cone_tol_truncated: f64,
    /// Number of random samples for specificity (eq. 18).
    pub specificity_samples: usize,
    /// Seed of the specificity sampler.
    pub seed: u64,
    /// Largest basis size m of the generalization and specificity curves (>= 1, optional).
    /// Default: every m while the training set has at most [`DEFAULT_MAX_RANK`] snapshots,
    /// [`DEFAULT_MAX_RANK`] beyond (see [`StudySpec::max_rank_for`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_rank: Option<usize>,
    /// Leave-one-out folds averaged into G(m) (>= 1, optional). Default: every fold while the
    /// training set has at most [`DEFAULT_MAX_RANK`] snapshots, [`DEFAULT_MAX_RANK`] evenly
    /// spaced folds beyond (see [`StudySpec::loo_folds_for`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loo_folds: Option<usize>,
    /// A reduced quadrature of the contact constraints (hyper-reduction, optional; node-to-segment
    /// and node-to-surface scenes): the online stage adds trade-off rows of the exact solve on a
    /// sampled surface at the given rank pairs (docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_sampling: Option<ContactSamplingSpec>,
    /// The ranks `[r_primal, r_dual]` of the reduced model the study stores for `crom query`
    /// (each >= 1, clipped to the bases' sizes; optional): the exact solve with the leading
    /// modes of the primal POD and the full CPG basis. Default: the most accurate model of the
    /// exact solve that converged at every test point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_ranks: Option<[usize; 2]>,
    /// The dual approximation of the stored reduced model (optional): [`MODEL_DUAL_CPG`], the
    /// study's CPG basis (the rows of the online trade-off), [`MODEL_DUAL_CPG_SAMPLED`], the
    /// same on the sampled contact surface (`study.contact_sampling`'s rows), or the name of a registered CPG
    /// approximation of `[comparison]` (e.g. `registered-translate-nodes-cpg`), whose basis
    /// the model rebuilds at each query point. Default: whichever of those the study measured
    /// as most accurate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_dual: Option<String>,
    /// The online solve's re-pairing tolerance `u_tol` (optional, in `(0, 1)`): the relative
    /// distance to the re-pairing's fixed point at which the exact solve stops, in the online
    /// stage, the comparison's online stages and the stored model (`crom query --u-tol`
    /// overrides it per query). Default: the solver's own, 1e-10. A looser value takes fewer
    /// linearisations; how far it moves the answers is measured per scene
    /// (docs/scenes.md#study-settings).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub online_u_tol: Option<f64>,
}

/// Whether `t` is a re-pairing tolerance `u_tol`: a relative distance in `(0, 1)` (NaN is not).
/// The one rule for `study.online_u_tol`, `crom query --u-tol` and `Scene.rom(u_tol=…)`.
pub fn is_u_tol(t: f64) -> bool {
    t > 0.0 && t < 1.0
}

/// `study.model_dual` for the study's CPG basis (the online trade-off's rows).
pub const MODEL_DUAL_CPG: &str = "cpg";

/// `study.model_dual` for the study's CPG basis on the sampled contact surface (the online
/// trade-off's `exact-sampled` rows; needs `study.contact_sampling`).
pub const MODEL_DUAL_CPG_SAMPLED: &str = "cpg-sampled";

/// A registered approximation's name followed by this in `study.model_dual`: the same basis
/// with a reduced quadrature of the contact constraints fitted in its reference frame (needs
/// `study.contact_sampling` and whole-node shifts, `registered-translate-nodes-…`).
pub const SAMPLED_SUFFIX: &str = "-sampled";

/// The registered approximations a quadrature in the reference frame applies to (their names
/// start so): whole-node shifts, whose pull and push move values exactly.
pub const WHOLE_NODE_PREFIX: &str = "registered-translate-nodes-";

/// `study.contact_sampling`: the quadrature's fit tolerance and the rank pairs it is measured
/// at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSamplingSpec {
    /// Relative residual at which the greedy non-negative fit stops, in `[0, 1)` (0 keeps the
    /// exact sums; 3e-2 is the measured trade in
    /// docs/design-notes.md#a-reduced-quadrature-of-the-contact-constraints).
    pub tol: f64,
    /// `[r_primal, r_dual]` pairs (each clipped to the bases' sizes), at least one.
    pub ranks: Vec<[usize; 2]>,
}

/// The default cap of the metric curves' basis size for training sets larger than this.
pub const DEFAULT_MAX_RANK: usize = 256;

impl StudySpec {
    /// The largest basis size m the metric curves cover for `n_snapshots` training snapshots:
    /// `study.max_rank` if set, else `n_snapshots` (every m) up to [`DEFAULT_MAX_RANK`]
    /// snapshots and [`DEFAULT_MAX_RANK`] beyond. Curves also stop at the basis size (and at
    /// N - 1 for leave-one-out), so a cap above those changes nothing.
    pub fn max_rank_for(&self, n_snapshots: usize) -> usize {
        self.max_rank.unwrap_or(if n_snapshots <= DEFAULT_MAX_RANK { n_snapshots } else { DEFAULT_MAX_RANK })
    }

    /// The leave-one-out folds of eq. 17 for `n_snapshots` training snapshots: every fold, or
    /// `F = study.loo_folds` (default [`DEFAULT_MAX_RANK`] above that many snapshots) evenly
    /// spaced ones, `i_k = floor(k N / F)`, k = 0..F. The training points are in parameter
    /// order, so the sample is stratified over the parameter domain, and deterministic.
    pub fn loo_folds_for(&self, n_snapshots: usize) -> Vec<usize> {
        let f = self
            .loo_folds
            .unwrap_or(if n_snapshots <= DEFAULT_MAX_RANK { n_snapshots } else { DEFAULT_MAX_RANK })
            .min(n_snapshots);
        spaced_folds(f, n_snapshots)
    }
}

/// `count` of `n` points evenly spaced with both ends, `i_k = floor(k (n - 1) / (count - 1))`,
/// k = 0..count (every point when `n <= count` or `count < 2`): the training points a sampled
/// surface is fitted to, and the test points the online stages time.
pub fn spaced_with_ends(count: usize, n: usize) -> Vec<usize> {
    if n <= count || count < 2 {
        return (0..n).collect();
    }
    (0..count).map(|k| k * (n - 1) / (count - 1)).collect()
}

/// `f` evenly spaced leave-one-out folds of `n` snapshots, `i_k = floor(k n / f)`, k = 0..f
/// (every fold when `f = n`): the folds of [`StudySpec::loo_folds_for`], from their count.
pub fn spaced_folds(f: usize, n: usize) -> Vec<usize> {
    (0..f).map(|k| k * n / f).collect()
}

impl SceneConfig {
    /// Parse and validate a scene file's text; `path` only names the file in errors.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, SceneError> {
        let cfg: SceneConfig = toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
            fix: parse_fix(e.message()),
        })?;
        cfg.validate(path)?;
        Ok(cfg)
    }

    /// Read, parse and validate a scene file.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| SceneError::Read { path: path.to_path_buf(), source })?;
        Self::from_toml_str(&text, path)
    }
}

fn parse_fix(message: &str) -> String {
    if message.contains("unknown field") {
        "remove or rename the key; the expected keys are listed above (see data/scenes/rope.toml for a complete example)".into()
    } else if message.contains("missing field") {
        "add the missing key; see data/scenes/*.toml for complete examples".into()
    } else if message.contains("unknown variant") {
        "use exactly one of [model.rope], [model.hertz], [model.ironing], [model.external]".into()
    } else if message.contains("invalid type") {
        "give the value the type named above (numbers for numeric fields, integers without a decimal point for counts)"
            .into()
    } else {
        "correct the TOML at the line shown above".into()
    }
}
