//! The model stage: the reduced model a user runs (`crom query`), stored as an artifact.
//!
//! **Which model** ([`choice`]). The one the study measured as most accurate among those that
//! converged at every test point: the rows of the online stage's `tradeoff.parquet` with
//! algorithm `exact` (or `exact-sampled`, a sampled contact surface, when the scene asks for
//! it) — the study's CPG basis at a rank pair — and the rows of the online comparison of each
//! registered CPG approximation of the scene's `[comparison]` (full primal rank, `m`
//! generators pushed forward to each query's frame); the least median dual (pressure) error,
//! then the least median primal error, then the fewest modes. A scene may restrict the
//! candidates to one dual approximation (`study.model_dual`: `cpg`, `cpg-sampled` for the
//! sampled surface's rows, or a registered approximation's name) and ask for ranks (`study.model_ranks`, clipped to the bases; for a
//! registered basis `[r_primal, m]`): the model at those ranks, with the row the study measured
//! there, or nothing measured where it did not. A table without candidates (no dual mode at
//! all: a scene without contact) keeps the model of the full bases, with nothing measured
//! (`measured_points = 0`). The choice reads results only, never timings, so the artifact is
//! byte-identical run to run. Its measured accuracy is stored beside it (`model.h5`'s
//! `measured_*` attributes) and its measured speed in `model_speed.parquet` (a timing file).
//!
//! **The same model.** It is built by the measuring stage's own steps for that row. The CPG
//! basis: the reduced model of the full bases (`ReducedModel::new` on the POD of the training
//! responses and the full CPG basis), its leading block at the row's ranks, for `exact-sampled`
//! the reduced quadrature fitted to the same training subsample, and the warm starts at the
//! training points (`rom.rs`). A registered basis: the reduced model of the primal POD with no
//! dual basis, and the registered cone basis (CPG or neighbours) built from the training
//! pressures and the contact surface as the online comparison builds it
//! (`approximation_online.rs`), which the model pushes forward to each query point
//! (`ReducedModel::with_registered_dual`); the primal starts at the training points with that
//! basis (`ReducedModel::with_primal_starts`), as there. So a query of the stored model at a
//! test point gives the answer the study measured there, bit for bit (tested end to end).
//!
//! **Files.** `model.h5` (everything the online solve reads, [`crate::io::model::StoredModel`];
//! its size does not depend on `n_dof`), `reconstruction.h5` (the primal basis and the lift's
//! terms, to turn coefficients into fields; optional for a reader), `model_speed.parquet`.

mod choice;

use std::collections::BTreeMap;

use crom_schemas::artifact::{basis as bnames, comparison as cnames, model as names, rom as rom_names, ArtifactKind};
use crom_schemas::comparison::ApproximationSpec;
use crom_schemas::scene::{ContactSamplingSpec, MODEL_DUAL_CPG, MODEL_DUAL_CPG_SAMPLED, SAMPLED_SUFFIX};
use crom_schemas::SceneConfig;
use crom_stages::dual::registration::Registered;
use crom_stages::dual::{self, Approach, DualApprox, Inner};
use crom_stages::rom::{Algorithm, ReducedModel, RomParams, EXACT_STEP_ITERATIONS};
use serde::Serialize;
use serde_json::json;

use super::comparison::{contact_surface, item_of};
use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::labels::Labels;
use super::online::{online_params, sampled_registered, subsample, SAMPLING_FIT_POINTS};
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In};
use crate::io::model::{Reconstruction, StoredModel};
use crate::io::table::{read_parquet, Column, Table};
use choice::{Candidate, Source};

/// What determines the model artifact besides its inputs (training set, bases, the online
/// stage's measurements, the registered approximations' online measurements and the mesh they
/// read the contact surface from): the solver settings it stores, the sampled surface's
/// settings, the ranks and the dual approximation a scene asks for, the registered
/// approximations' settings, and the parameter's training domain, which the file records. The
/// scene's and the parameter's names label the file and are not in the key ([`Labels`]).
#[derive(Debug, Clone, Serialize)]
pub(crate) struct ModelKey {
    max_iter: usize,
    gap_tol: f64,
    u_tol: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    contact_sampling: Option<ContactSamplingSpec>,
    /// `study.model_ranks` (absent from the key when not asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    model_ranks: Option<[usize; 2]>,
    /// `study.model_dual` (absent from the key when not asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    model_dual: Option<String>,
    /// The registered CPG approximations that are candidates, in `[comparison]` order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    registered: Vec<RegisteredKey>,
    parameter_min: Vec<f64>,
    parameter_max: Vec<f64>,
    /// A 3-D scene: its queries with a dual basis set per query start from the warm-start
    /// samples' answers too (since 2026-11-29; only the path changes). Absent from a 2-D
    /// scene's key, whose solves did already.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    starts_3d: bool,
}

/// A registered CPG approximation the model may carry: what its basis is built from besides
/// the training set and the contact surface (its settings, and the comparison's `max_m`, which
/// sets how many generators it builds).
#[derive(Debug, Clone, Serialize)]
pub(crate) struct RegisteredKey {
    approximation: ApproximationSpec,
    max_m: usize,
}

impl StageKey for ModelKey {
    const KIND: ArtifactKind = ArtifactKind::MODEL;
    /// Bump when the stored model or the choice of it changes (2: registered dual bases; 3: its
    /// warm starts and measured errors from the online solve that sums a small dual basis's
    /// rows, the same answers to 1e-10; 4: the `exact_step` attribute, and a registered
    /// approximation's own primal space with translates; 5: warm starts and measured errors
    /// from the exact step that applies the curvature through each term's two rows, the same
    /// answers to 1e-10; 6: the same with the first linearisation's positions from the
    /// warm-start samples' displacements; 7: a 3-D query answers with its verified
    /// linearisation point, 2-D the same; 8: in 3-D a feature renamed across a shared node is
    /// not a change of the pairing, 2-D the same).
    const ALGORITHM_VERSION: u32 = 8;
}

impl ModelKey {
    /// The scene's settings of the stored model; `registered`: its registered CPG
    /// approximations that have an online stage.
    fn of(scene: &SceneConfig, registered: Vec<RegisteredKey>) -> Self {
        let params = online_params(scene);
        let (_, parameter_min, parameter_max) = domain(scene);
        Self {
            max_iter: params.max_iter,
            gap_tol: params.gap_tol,
            u_tol: params.u_tol,
            contact_sampling: scene.study.contact_sampling.clone(),
            model_ranks: scene.study.model_ranks,
            model_dual: scene.study.model_dual.clone(),
            registered,
            parameter_min,
            parameter_max,
            starts_3d: scene.model.is_3d(),
        }
    }

    /// The exact solve's settings.
    fn params(&self) -> RomParams {
        RomParams {
            algorithm: Algorithm::Exact,
            max_iter: self.max_iter,
            gap_tol: self.gap_tol,
            u_tol: self.u_tol,
            exact_step: 0,
        }
    }
}

/// The training domain of the scene's parameter: (names, lower bounds, upper bounds).
pub(crate) fn domain(scene: &SceneConfig) -> (Vec<&str>, Vec<f64>, Vec<f64>) {
    let p = &scene.parameter;
    let lo = std::iter::once(p.min).chain(p.axes.iter().map(|a| a.min)).collect();
    let hi = std::iter::once(p.max).chain(p.axes.iter().map(|a| a.max)).collect();
    (p.names(), lo, hi)
}

/// The reduced model a user runs.
#[derive(Debug)]
pub(crate) struct ModelStage {
    spec: KeySpec,
    settings: ModelKey,
    labels: Labels,
    train: Input,
    basis: Input,
    rom: Input,
    /// The mesh (the contact surface of a registered basis); only with registered candidates.
    mesh: Option<Input>,
    /// The online comparison stage of each registered candidate (same order as the key's).
    online: Vec<Input>,
}

impl ModelStage {
    /// `online`: the scene's online comparison stages, with their approximations' settings;
    /// the registered CPG ones become candidates unless `study.model_dual` names another.
    pub(crate) fn plan(
        scene: &SceneConfig,
        (train, basis, rom, mesh): (Input, Input, Input, Input),
        online: &[(ApproximationSpec, Input)],
        labels: &Labels,
    ) -> Self {
        let max_m = scene.comparison.as_ref().map_or(0, |c| c.max_m);
        let wanted = |spec: &ApproximationSpec| match scene.study.model_dual.as_deref() {
            None => true,
            Some(name) => name == spec.name() || name.strip_suffix(SAMPLED_SUFFIX) == Some(spec.name().as_str()),
        };
        let (registered, online): (Vec<RegisteredKey>, Vec<Input>) = online
            .iter()
            .filter(|(spec, _)| spec.storable() && wanted(spec))
            .map(|(spec, input)| (RegisteredKey { approximation: spec.clone(), max_m }, input.clone()))
            .unzip();
        let settings = ModelKey::of(scene, registered);
        let mut spec =
            KeySpec::of(&settings).input("train", &train.key).input("basis", &basis.key).input("rom", &rom.key);
        let mesh = (!online.is_empty()).then_some(mesh);
        if let Some(mesh) = &mesh {
            spec = spec.input("mesh", &mesh.key);
        }
        for (k, input) in settings.registered.iter().zip(&online) {
            spec = spec.input(&format!("online-{}", k.approximation.name()), &input.key);
        }
        Self { spec, settings, labels: labels.clone(), train, basis, rom, mesh, online }
    }
}

impl StageDef for ModelStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::MODEL
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        let mut v = vec![&self.train, &self.basis, &self.rom];
        v.extend(&self.mesh);
        v.extend(&self.online);
        v
    }
    fn published(&self) -> Vec<Published> {
        use crom_schemas::artifact::model as m;
        vec![
            Published::file("model.h5", m::FILE),
            Published::file("reconstruction.h5", m::RECONSTRUCTION),
            Published::file("model_speed.parquet", m::SPEED),
        ]
    }

    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let (train, basis, rom) = (&self.train.key, &self.basis.key, &self.rom.key);
        let (settings, labels) = (&self.settings, &self.labels);
        let store = ctx.store;
        let loaded = std::sync::Arc::clone(&ctx.loaded);
        let physics = &mut shared.physics;
        ctx.single(ArtifactKind::MODEL, "model", &self.spec, |staging| {
            let fail = |m: String| CromError::Numerical { stage: "model", scene: labels.scene.clone(), message: m };
            // the candidates: the trade-off's rows, then each registered approximation's
            let mut candidates = Vec::new();
            // `cpg-sampled`: the sampled surface's rows only
            let sampled = settings.model_dual.as_deref() == Some(MODEL_DUAL_CPG_SAMPLED);
            if sampled || settings.model_dual.as_deref().is_none_or(|d| d == MODEL_DUAL_CPG) {
                let rom_dir = store.dir(ArtifactKind::ROM, rom);
                let trade = read_parquet(&rom_dir.join(rom_names::TRADEOFF))?;
                let times = read_parquet(&rom_dir.join(rom_names::TRADEOFF_TIMINGS))?;
                candidates.extend(choice::exact_rows(&trade, &times).into_iter().filter(|c| !sampled || c.sampled()));
            }
            // a registered basis with a quadrature in its reference frame: `<name>-sampled`
            let reg_sampled = settings.model_dual.as_deref().is_some_and(|d| d.ends_with(SAMPLED_SUFFIX) && !sampled);
            for (k, input) in self.online.iter().enumerate() {
                let dir = store.dir(ArtifactKind::ONLINE_APPROXIMATION, &input.key);
                let online = read_parquet(&dir.join(cnames::ONLINE))?;
                let times = read_parquet(&dir.join(cnames::ONLINE_TIMINGS))?;
                let name = settings.registered[k].approximation.name();
                let name = if reg_sampled { format!("{name}{SAMPLED_SUFFIX}") } else { name };
                candidates.extend(choice::registered_rows(&online, &times, k, &name));
            }
            let train_set = loaded.set(store, train)?;
            let phi = physics.responses(train, &train_set, fail)?;
            // a registered basis when the scene names one, the CPG basis otherwise
            let pinned_registered = settings
                .model_dual
                .as_deref()
                .filter(|d| *d != MODEL_DUAL_CPG && *d != MODEL_DUAL_CPG_SAMPLED)
                .map(|_| 0);
            let algorithm = if sampled { rom_names::SAMPLED } else { Algorithm::Exact.name() };
            let row = match settings.model_ranks {
                Some([ru, rl]) => choice::at_ranks(&candidates, pinned_registered, algorithm, ru.min(phi.cols), rl),
                None => choice::best(&candidates),
            };
            let mut pick = row.map_or_else(
                || match pinned_registered {
                    Some(k) => Candidate { source: Source::Registered(k), ..Candidate::full_bases() },
                    None => Candidate {
                        source: Source::Exact { algorithm: algorithm.into(), dual_basis: "full".into() },
                        ..Candidate::full_bases()
                    },
                },
                |row| candidates[row].clone(),
            );
            if let (Some([ru, rl]), None) = (settings.model_ranks, row) {
                (pick.r_primal, pick.r_dual) = (ru, rl);
            }
            // a registered approximation with its own primal space (`primal_translates`): the
            // online comparison's basis, and its exact corrected step
            let translates = match &pick.source {
                Source::Registered(k) => {
                    settings.registered.get(*k).and_then(|key| key.approximation.primal_translates())
                }
                Source::Exact { .. } => None,
            };
            let (phi, params) = match translates {
                Some(shift) => (
                    physics.translated_responses(train, &train_set, shift, fail)?,
                    RomParams { exact_step: EXACT_STEP_ITERATIONS, ..settings.params() },
                ),
                None => (phi, settings.params()),
            };
            let phys = physics.get()?;
            let op = phys.operator();
            let (model, algorithm, dual_basis) = match &pick.source {
                Source::Exact { algorithm, dual_basis } => {
                    let bfile = H5In::open(&store.dir(ArtifactKind::BASIS, basis).join(bnames::FILE))?;
                    let theta = bfile.matrix(&format!("{}/{}", bnames::DUAL_CPG, bnames::MODES))?;
                    drop(bfile);
                    // the online stage's steps for this row (`rom.rs`)
                    let full = ReducedModel::new(op, &phi.data, phi.cols, &theta.data, theta.cols)
                        .map_err(|e| fail(e.to_string()))?;
                    let mut model = full.leading(pick.r_primal.min(phi.cols), pick.r_dual.min(theta.cols));
                    if algorithm == rom_names::SAMPLED {
                        let cs = settings.contact_sampling.as_ref().ok_or_else(|| {
                            fail("the trade-off has sampled rows but the scene has no study.contact_sampling".into())
                        })?;
                        let fit_points = subsample(&train_set.parameters, SAMPLING_FIT_POINTS);
                        model = model
                            .with_sampled_surface(&fit_points, &params, cs.tol)
                            .map_err(|e| fail(e.to_string()))?
                            .0;
                    }
                    (model.with_warm_starts(&train_set.parameters, &params), algorithm.clone(), dual_basis.clone())
                }
                Source::Registered(k) => {
                    let (key, mesh) = (settings.registered.get(*k), self.mesh.as_ref());
                    let (Some(key), Some(mesh)) = (key, mesh) else {
                        return Err(fail(
                            "study.model_dual names a registered approximation with no online stage".into(),
                        ));
                    };
                    // the online comparison's steps (`approximation_online.rs`): the model of the
                    // primal POD without a dual basis, the registered basis built from the
                    // training pressures at the comparison's m grid, the primal starts
                    let Approach::Registered { map, inner: inner @ (Inner::Cpg | Inner::Neighbours) } =
                        item_of(&key.approximation).approach
                    else {
                        return Err(fail(format!("{} is not a registered cone basis", key.approximation.name())));
                    };
                    let (surface, across) = contact_surface(store, &mesh.key)?;
                    let ms = dual::m_grid(key.max_m.min(train_set.parameters.len()));
                    let training =
                        super::convert::training((&train_set.dual, &train_set.parameters), &surface, &across, &ms);
                    let reg = Registered::build(&training, map, inner).map_err(|e| fail(e.to_string()))?;
                    let m = pick.r_dual.min(reg.size());
                    let base = ReducedModel::new(op, &phi.data, phi.cols, &[], 0).map_err(|e| fail(e.to_string()))?;
                    let base = if pick.r_primal < phi.cols { base.leading(pick.r_primal, 0) } else { base };
                    let model = if reg_sampled {
                        // with its quadrature in the reference frame, as the online comparison
                        // measured it (`sampled_registered`)
                        let cs = settings.contact_sampling.as_ref().ok_or_else(|| {
                            fail(
                                "study.model_dual names a sampled basis but the scene has no study.contact_sampling"
                                    .into(),
                            )
                        })?;
                        let fit = subsample(&train_set.parameters, SAMPLING_FIT_POINTS);
                        sampled_registered(&base, reg, m, (&train_set.parameters, &fit), &params, cs.tol)
                            .map_err(fail)?
                    } else {
                        base.with_primal_starts(&reg, m, &train_set.parameters, &params)
                            .with_registered_dual(reg, m)
                            .map_err(|e| fail(e.to_string()))?
                    };
                    let name = key.approximation.name();
                    let name = if reg_sampled { format!("{name}{SAMPLED_SUFFIX}") } else { name };
                    (model, Algorithm::Exact.name().to_string(), name)
                }
            };
            let stored = StoredModel {
                parts: model.parts(),
                scene: labels.scene.clone(),
                algorithm,
                dual_basis: dual_basis.clone(),
                max_iter: params.max_iter as u64,
                gap_tol: params.gap_tol,
                u_tol: params.u_tol,
                exact_step: params.exact_step as u64,
                parameter_names: labels.names.clone(),
                parameter_min: settings.parameter_min.clone(),
                parameter_max: settings.parameter_max.clone(),
                measured: pick.measured.clone(),
            };
            // the reader's checks on what is about to be stored: a model `crom query` would refuse
            // is never committed (nothing is written; the message names the array)
            if let Err(e) = ReducedModel::from_parts(&stored.parts) {
                return Err(fail(format!(
                    "the built model fails the reader's own checks ({e}); report this as a bug in crom"
                )));
            }
            let key = staging.key().0.clone();
            stored.write(&staging.path(names::FILE), &key)?;
            let (r, r_dual) = model.stored_ranks();
            let phi_r = ColMatrix { rows: phi.rows, cols: r, data: phi.data[..phi.rows * r].to_vec() };
            let terms = op.lift_terms();
            let lift = ColMatrix::from_columns(phi.rows, &terms.iter().map(Vec::as_slice).collect::<Vec<_>>());
            Reconstruction { phi: phi_r, lift }.write(&staging.path(names::RECONSTRUCTION), &key)?;
            Table::default()
                .with(names::SPEED_COLUMNS[0], Column::F64(vec![pick.speed[0]]))
                .with(names::SPEED_COLUMNS[1], Column::F64(vec![pick.speed[1]]))
                .with(names::SPEED_COLUMNS[2], Column::F64(vec![pick.speed[2]]))
                .write_parquet(&staging.path(names::SPEED))?;
            let size = std::fs::metadata(staging.path(names::FILE)).map_or(0, |m| m.len());
            Ok(BTreeMap::from([
                ("algorithm".to_string(), json!(stored.algorithm)),
                ("dual_basis".to_string(), json!(dual_basis)),
                ("r_primal".to_string(), json!(r)),
                ("r_dual".to_string(), json!(r_dual)),
                ("model_bytes".to_string(), json!(size)),
            ]))
        })
    }
}
