//! Basis stage: the primal POD, the dual POD ("dual orth") and the Cone-Projected Greedy dual
//! bases ("dual cone", full and truncated) of a training set (paper eqs. 9, 10, 12).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use crom_schemas::artifact::{basis as names, ArtifactKind};
use crom_schemas::SceneConfig;
use crom_stages::basis::{cpg_path_refined, pod, pod_blocks_framed, Cpg, CpgPath, CpgPathParams, Pod, PodParams};
use crom_stages::cone::NnlsParams;
use serde::Serialize;
use serde_json::json;

use super::convert::{to_col, view};
use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::shared::Shared;
use crate::cache::{Key, KeySpec, NnlsKey, StageKey};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5Out};

/// The dual training snapshots' tolerance-0 CPG path of this run, shared by the basis,
/// compactness, generalization and specificity stages (one greedy run instead of four): the
/// training-set key and max rank it was computed for.
static DUAL_PATH: Mutex<Option<PathMemo>> = Mutex::new(None);

/// What [`DUAL_PATH`] holds: the training-set key, max rank and cone tolerances (as bits) the
/// path was computed for, and the path.
struct PathMemo {
    train: String,
    max_rank: usize,
    tols: Vec<u64>,
    path: Arc<CpgPath>,
}

/// The CPG path of the dual snapshots `dual` of training set `train`, recording the metrics'
/// data up to `max_rank`, with the cone tolerances `tols` located exactly: computed once per
/// run (with a progress bar), then shared. Above `crom_stages::basis::DENSE_CURVE_MAX`
/// snapshots its curve C(m) is on a rank grid, with each of `tols` located exactly (so the
/// bases of the scene's two cone tolerances are the whole curve's). The tolerances change only
/// those extra points of C(m), never the generators, the leave-one-out data or the coefficient
/// ranges: a stage that reads none of C(m) asks with no tolerance and shares any path of the
/// same training set and max rank.
pub(crate) fn dual_path(
    ctx_progress: crate::progress::Progress,
    tols: &[f64],
    train: &Key,
    dual: &ColMatrix,
    max_rank: usize,
) -> Result<Arc<CpgPath>, String> {
    let tol_bits: Vec<u64> = tols.iter().map(|t| t.to_bits()).collect();
    let mut memo = DUAL_PATH.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(m) = memo.as_ref() {
        if m.train == train.0 && m.max_rank == max_rank && tol_bits.iter().all(|t| m.tols.contains(t)) {
            return Ok(Arc::clone(&m.path));
        }
    }
    // One step per selected generator, one per rank of the compactness pass (k <= N each).
    let bar = Ticker::new(ctx_progress, "CPG path", 2 * dual.cols);
    let params = CpgPathParams { nnls: NnlsParams::default(), max_rank, ..CpgPathParams::default() };
    let path = Arc::new(cpg_path_refined(view(dual), params, tols, &|| bar.tick("steps")).map_err(|e| e.to_string())?);
    bar.finish(&format!("{} generators", path.len()));
    *memo = Some(PathMemo { train: train.0.clone(), max_rank, tols: tol_bits, path: Arc::clone(&path) });
    Ok(path)
}

/// A stage progress bar that parallel work can tick (the bar shows the ETA).
pub(crate) struct Ticker {
    bar: Mutex<crate::progress::StageProgress>,
}

impl Ticker {
    pub(crate) fn new(progress: crate::progress::Progress, name: &str, len: usize) -> Self {
        Self { bar: Mutex::new(progress.stage(name, len)) }
    }

    /// One more item of kind `what` done.
    pub(crate) fn tick(&self, what: &str) {
        self.bar.lock().unwrap_or_else(|e| e.into_inner()).inc(what);
    }

    pub(crate) fn finish(self, outcome: &str) {
        self.bar.into_inner().unwrap_or_else(|e| e.into_inner()).finish(outcome);
    }
}

/// How the greedy path of `n_train` snapshots selects, for the keys of the stages that read it:
/// `None` for the selection with the Gram matrix, `"without-gram"` above
/// `crom_stages::basis::DENSE_CURVE_MAX` snapshots (`CpgPathParams::wide_above`: the same
/// generators in exact arithmetic, other round-off in the candidates' coefficients).
pub(crate) fn selection_of(n_train: usize) -> Option<&'static str> {
    (n_train > CpgPathParams::default().wide_above).then_some("without-gram")
}

/// The resolved `study.max_rank` of the scene (every m up to 256 training snapshots; the
/// training set of a vector parameter is the whole tensor grid).
pub(crate) fn max_rank_of(scene: &SceneConfig) -> usize {
    scene.study.max_rank_for(scene.parameter.train_points().len())
}

/// What determines the bases of a training set (its key is an input): the stage computes from
/// these fields alone.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct BasisKey {
    primal_tol: f64,
    dual_orth_tol: f64,
    dual_cone_tol: f64,
    dual_cone_tol_truncated: f64,
    /// The CPG greedy solves NNLS problems.
    nnls: NnlsKey,
    /// The rank up to which the stored C(m) of the cone is dense, where the scene's `max_rank`
    /// decides it (above `DENSE_CURVE_MAX` training snapshots and past `GRID_START`); absent
    /// (and not in the key) elsewhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    curve_dense_to: Option<usize>,
    /// How the greedy path selects ([`selection_of`]); absent (and not in the key) for the
    /// Gram selection of up to `DENSE_CURVE_MAX` snapshots.
    #[serde(skip_serializing_if = "Option::is_none")]
    selection: Option<&'static str>,
    /// `"streamed"` when the primal POD reads the training set block by block
    /// ([`super::inputs::streamed`]); absent (and not in the key) at or below the switch-over size.
    #[serde(skip_serializing_if = "Option::is_none")]
    primal: Option<&'static str>,
    /// The metrics' range recorded on the shared greedy path (`dual_path`): it decides the
    /// bases only through `curve_dense_to`, so it is not in the key itself.
    #[serde(skip)]
    max_rank: usize,
}

impl StageKey for BasisKey {
    const KIND: ArtifactKind = ArtifactKind::BASIS;
    /// Bump when POD or CPG change the bases they produce (2: the NNLS settings in the key;
    /// 3: the CPG floor, `crom_stages::basis::CPG_FLOOR`; 4: the stored C(m) on a rank grid
    /// above `crom_stages::basis::DENSE_CURVE_MAX` training snapshots).
    const ALGORITHM_VERSION: u32 = 4;
}

impl BasisKey {
    /// The cone tolerances (full, truncated), as the shared greedy path takes them.
    pub(crate) fn cone_tols(&self) -> [f64; 2] {
        [self.dual_cone_tol, self.dual_cone_tol_truncated]
    }

    /// The metrics' range recorded on the shared greedy path.
    pub(crate) fn max_rank(&self) -> usize {
        self.max_rank
    }

    /// True when the primal snapshots are read block by block ([`super::inputs::streamed`]).
    pub(crate) fn streams_primal(&self) -> bool {
        self.primal.is_some()
    }

    /// The scene's basis settings.
    fn of(scene: &SceneConfig) -> Self {
        let st = &scene.study;
        let max_rank = max_rank_of(scene);
        let n_train = scene.parameter.train_points().len();
        let grid = n_train > crom_stages::basis::DENSE_CURVE_MAX && max_rank > crom_stages::basis::GRID_START;
        Self {
            primal_tol: st.primal_tol,
            dual_orth_tol: st.dual_orth_tol,
            dual_cone_tol: st.dual_cone_tol,
            dual_cone_tol_truncated: st.dual_cone_tol_truncated,
            nnls: NnlsKey::used(),
            curve_dense_to: grid.then_some(max_rank),
            selection: selection_of(n_train),
            primal: super::inputs::streamed::primal_of(scene),
            max_rank,
        }
    }
}

/// POD and CPG bases of the training set. Its compute reads its settings from its key
/// ([`BasisKey`]) and its training set from its input: nothing it uses can be missing from its
/// key.
#[derive(Debug)]
pub(crate) struct BasisStage {
    pub spec: KeySpec,
    pub settings: BasisKey,
    pub train: Input,
    /// The scene's name, written into the artifact as a label.
    pub scene: String,
}

impl BasisStage {
    pub(crate) fn plan(scene: &SceneConfig, train: Input) -> Self {
        let settings = BasisKey::of(scene);
        let spec = KeySpec::of(&settings).input("train", &train.key);
        Self { spec, settings, train, scene: scene.scene.name.clone() }
    }
}

impl StageDef for BasisStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::BASIS
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train]
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file("basis.h5", names::FILE)]
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        self.compute(ctx)
    }
}

impl BasisStage {
    fn compute(&self, ctx: &mut Ctx<'_>) -> Result<Key, CromError> {
        let (st, train, scene) = (&self.settings, &self.train.key, &self.scene);
        let tols = st.cone_tols();
        let progress = ctx.progress;
        let (store, loaded) = (ctx.store, std::sync::Arc::clone(&ctx.loaded));
        let numerical = |m: String| CromError::Numerical { stage: "basis", scene: scene.clone(), message: m };
        ctx.single(ArtifactKind::BASIS, "basis", &self.spec, |staging| {
            // The primal POD (the large SVD) beside the dual POD and the greedy path: independent
            // computations, each deterministic, on the two cores.
            let dual_side = |dual_set: &ColMatrix| {
                let dual = pod(view(dual_set), PodParams { rel_tol: st.dual_orth_tol });
                (dual, dual_path(progress, &tols, train, dual_set, st.max_rank))
            };
            let primal_params = PodParams { rel_tol: st.primal_tol };
            let (primal, (dual, path)) = if st.streams_primal() {
                let set = loaded.streamed(store, train)?;
                let primal_pod = || {
                    let frame = set.frame()?;
                    pod_blocks_framed(&set.primal, &set.primal_norms, frame.as_deref(), primal_params)
                };
                let (primal, rest) = rayon::join(primal_pod, || dual_side(&set.dual));
                if let Some(e) = set.primal.failure() {
                    return Err(e);
                }
                (primal, rest)
            } else {
                let set = loaded.set(store, train)?;
                rayon::join(|| pod(view(&set.primal), primal_params), || dual_side(&set.dual))
            };
            let primal = primal.map_err(|e| numerical(e.to_string()))?;
            let dual = dual.map_err(|e| numerical(e.to_string()))?;
            // One greedy path; both bases are its prefixes (the greedy is deterministic).
            let path = path.map_err(numerical)?;
            let full = path.truncated(st.dual_cone_tol);
            let trunc = path.truncated(st.dual_cone_tol_truncated);
            let f = H5Out::create(&staging.path(names::FILE))?;
            f.attr_str("scene", scene)?;
            f.attr_str("kind", "basis")?;
            f.attr_u64("schema_version", u64::from(ArtifactKind::BASIS.schema_version()))?;
            f.attr_str("cache_key", &staging.key().0)?;
            // the primal modes (over every dof) uncompressed, the dual ones (over the contact
            // nodes) deflated (`H5Out::matrix_raw`)
            write_pod(&f, names::PRIMAL_POD, &primal, st.primal_tol, true)?;
            write_pod(&f, names::DUAL_POD, &dual, st.dual_orth_tol, false)?;
            // Both are prefixes of one path, so one condition path (of the longer) serves both;
            // 1 / kappa is finite always (0 = a generator in the span of the earlier ones).
            let longer = if full.basis.ncols() >= trunc.basis.ncols() { &full } else { &trunc };
            let rcond: Vec<f64> =
                crom_stages::basis::gram_condition_path(longer.basis.as_ref()).iter().map(|k| 1.0 / k).collect();
            write_cpg(&f, names::DUAL_CPG, &full, st.dual_cone_tol, &rcond[..full.basis.ncols()])?;
            let t = trunc.basis.ncols();
            write_cpg(&f, names::DUAL_CPG_TRUNCATED, &trunc, st.dual_cone_tol_truncated, &rcond[..t])?;
            drop(f);
            Ok(BTreeMap::from([
                ("primal_rank".to_string(), json!(primal.modes.ncols())),
                ("dual_orth_rank".to_string(), json!(dual.modes.ncols())),
                ("dual_cone_rank".to_string(), json!(full.basis.ncols())),
                ("dual_cone_truncated_rank".to_string(), json!(trunc.basis.ncols())),
            ]))
        })
    }
}

/// A POD group; its modes uncompressed if `raw` ([`H5Out::matrix_raw`]).
fn write_pod(f: &H5Out, group: &str, p: &Pod, tol: f64, raw: bool) -> Result<(), CromError> {
    let g = f.group(group)?;
    g.attr_f64("tolerance", tol)?;
    g.attr_u64("rank", p.modes.ncols() as u64)?;
    g.attr_u64("numerical_rank", p.rank as u64)?;
    let (modes, units) = (to_col(p.modes.as_ref()), "orthonormal modes, one per column");
    if raw {
        g.matrix_raw(names::MODES, &modes, units)?;
    } else {
        g.matrix(names::MODES, &modes, units)?;
    }
    g.vec_f64(names::SINGULAR_VALUES, &p.singular_values, "singular values, descending")
}

/// A CPG group; `rcond` is the reciprocal Gram condition after each of its selections.
fn write_cpg(f: &H5Out, group: &str, c: &Cpg, tol: f64, rcond: &[f64]) -> Result<(), CromError> {
    let g = f.group(group)?;
    g.attr_f64("tolerance", tol)?;
    g.attr_u64("rank", c.basis.ncols() as u64)?;
    g.matrix(names::MODES, &to_col(c.basis.as_ref()), "unit-norm non-negative generators, selection order")?;
    let sel: Vec<u64> = c.selected.iter().map(|&i| i as u64).collect();
    g.vec_u64(names::SELECTED, &sel)?;
    let what = if c.compactness.iter().any(|v| v.is_nan()) {
        "C(m) of eq. 16 after each selection (NaN: off the rank grid of a large training set)"
    } else {
        "C(m) of eq. 16 after each selection"
    };
    g.vec_f64(names::COMPACTNESS, &c.compactness, what)?;
    g.vec_f64(
        names::GRAM_RCOND,
        rcond,
        "1 / estimated 1-norm condition number of the Gram of the first t generators, t = 1..rank",
    )
}
