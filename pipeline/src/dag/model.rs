//! The model stage: the reduced model a user runs (`crom query`), stored as an artifact.
//!
//! **Which model.** The one the online stage measured as most accurate among those that
//! converged at every test point: of the rows of its `tradeoff.parquet` with algorithm `exact`
//! (or `exact-sampled`, a sampled contact surface, when the scene asks for it), the fewest
//! test points not converged (none, wherever some row converged everywhere), then the least
//! median dual (pressure) error, then the least median primal error, then the fewest modes
//! `r_primal + r_dual`, then the table's order (a defined error beats an undefined one). A
//! table without such rows (no dual mode at all: a scene without contact) keeps the model of
//! the full bases, with nothing measured (`measured_points = 0`). A scene may ask for other
//! ranks (`study.model_ranks`, clipped to the bases): the exact solve at those ranks, with the
//! row the online stage measured there, or nothing measured where it did not sweep them. The choice reads results only, never timings, so the artifact is
//! byte-identical run to run. Its measured accuracy is stored beside it (`model.h5`'s
//! `measured_*` attributes) and its measured speed in `model_speed.parquet` (a timing file).
//!
//! **The same model.** It is built by the online stage's own steps for that row: the reduced
//! model of the full bases (`ReducedModel::new` on the POD of the training responses and the
//! full CPG basis), its leading block at the row's ranks, for `exact-sampled` the reduced
//! quadrature fitted to the same training subsample, and the warm starts at the training points.
//! So a query of the stored model at a test point gives the answer the online stage measured
//! there, bit for bit (tested end to end).
//!
//! **Files.** `model.h5` (everything the online solve reads, [`crate::io::model::StoredModel`];
//! its size does not depend on `n_dof`), `reconstruction.h5` (the primal basis and the lift's
//! terms, to turn coefficients into fields; optional for a reader), `model_speed.parquet`.

use std::collections::BTreeMap;

use crom_schemas::artifact::{basis as bnames, model as names, rom as rom_names, ArtifactKind};
use crom_schemas::scene::ContactSamplingSpec;
use crom_schemas::SceneConfig;
use crom_stages::rom::{Algorithm, ReducedModel, RomParams};
use serde::Serialize;
use serde_json::json;

use super::graph::{Input, StageDef};
use super::rom::{response_basis, subsample, SAMPLING_FIT_POINTS};
use super::{Ctx, Labels, Shared};
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In};
use crate::io::model::{Measured, Reconstruction, StoredModel};
use crate::io::table::{read_parquet, Column, Table};

/// What determines the model artifact besides its inputs (training set, bases, the online
/// stage's measurements): the solver settings it stores, the sampled surface's settings, the
/// ranks a scene asks for, and the parameter's training domain, which the file records. The
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
    parameter_min: Vec<f64>,
    parameter_max: Vec<f64>,
}

impl StageKey for ModelKey {
    const KIND: ArtifactKind = ArtifactKind::Model;
    /// Bump when the stored model or the choice of it changes.
    const ALGORITHM_VERSION: u32 = 1;
}

impl ModelKey {
    /// The scene's settings of the stored model.
    fn of(scene: &SceneConfig) -> Self {
        let params = RomParams::default();
        let (_, parameter_min, parameter_max) = domain(scene);
        Self {
            max_iter: params.max_iter,
            gap_tol: params.gap_tol,
            u_tol: params.u_tol,
            contact_sampling: scene.study.contact_sampling.clone(),
            model_ranks: scene.study.model_ranks,
            parameter_min,
            parameter_max,
        }
    }

    /// The exact solve's settings.
    fn params(&self) -> RomParams {
        RomParams { algorithm: Algorithm::Exact, max_iter: self.max_iter, gap_tol: self.gap_tol, u_tol: self.u_tol }
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
}

impl ModelStage {
    pub(crate) fn plan(scene: &SceneConfig, train: Input, basis: Input, rom: Input, labels: &Labels) -> Self {
        let settings = ModelKey::of(scene);
        let spec = KeySpec::of(&settings).input("train", &train.key).input("basis", &basis.key).input("rom", &rom.key);
        Self { spec, settings, labels: labels.clone(), train, basis, rom }
    }
}

impl StageDef for ModelStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::Model
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train, &self.basis, &self.rom]
    }
    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let (train, basis, rom) = (&self.train.key, &self.basis.key, &self.rom.key);
        let (settings, labels) = (&self.settings, &self.labels);
        let store = ctx.store;
        let loaded = std::sync::Arc::clone(&ctx.loaded);
        let physics = &mut shared.physics;
        ctx.single(ArtifactKind::Model, "model", &self.spec, |staging| {
            let fail = |m: String| CromError::Numerical { stage: "model", scene: labels.scene.clone(), message: m };
            let rom_dir = store.dir(ArtifactKind::Rom, rom);
            let trade = read_parquet(&rom_dir.join(rom_names::TRADEOFF))?;
            let times = read_parquet(&rom_dir.join(rom_names::TRADEOFF_TIMINGS))?;
            let phys = physics.get()?;
            let op = phys.operator();
            let train_set = loaded.set(store, train)?;
            let bfile = H5In::open(&store.dir(ArtifactKind::Basis, basis).join(bnames::FILE))?;
            let theta = bfile.matrix(&format!("{}/{}", bnames::DUAL_CPG, bnames::MODES))?;
            drop(bfile);
            let phi = response_basis(op, &train_set).map_err(fail)?;
            let row = match settings.model_ranks {
                Some([ru, rl]) => at_ranks(&trade, ru.min(phi.cols) as u64, rl.min(theta.cols) as u64),
                None => choose(&trade),
            };
            let mut pick = row.map_or_else(Pick::full_bases, |row| Pick::of(&trade, row));
            if let (Some([ru, rl]), None) = (settings.model_ranks, row) {
                (pick.r_primal, pick.r_dual) = (ru, rl);
            }
            let params = settings.params();
            // the online stage's steps for this row (`rom.rs`)
            let full =
                ReducedModel::new(op, &phi.data, phi.cols, &theta.data, theta.cols).map_err(|e| fail(e.to_string()))?;
            let mut model = full.leading(pick.r_primal.min(phi.cols), pick.r_dual.min(theta.cols));
            if pick.algorithm == rom_names::SAMPLED {
                let cs = settings.contact_sampling.as_ref().ok_or_else(|| {
                    fail("the trade-off has sampled rows but the scene has no study.contact_sampling".into())
                })?;
                let fit_points = subsample(&train_set.parameters, SAMPLING_FIT_POINTS);
                model = model.with_sampled_surface(&fit_points, &params, cs.tol).map_err(|e| fail(e.to_string()))?.0;
            }
            let model = model.with_warm_starts(&train_set.parameters, &params);
            let stored = StoredModel {
                parts: model.parts(),
                scene: labels.scene.clone(),
                algorithm: pick.algorithm.clone(),
                dual_basis: pick.dual_basis.clone(),
                max_iter: params.max_iter as u64,
                gap_tol: params.gap_tol,
                u_tol: params.u_tol,
                parameter_names: labels.names.clone(),
                parameter_min: settings.parameter_min.clone(),
                parameter_max: settings.parameter_max.clone(),
                measured: pick.measured.clone(),
            };
            let key = staging.key().0.clone();
            stored.write(&staging.path(names::FILE), &key)?;
            let r = model.ranks().0;
            let phi_r = ColMatrix { rows: phi.rows, cols: r, data: phi.data[..phi.rows * r].to_vec() };
            let terms = op.lift_terms();
            let lift = ColMatrix::from_columns(phi.rows, &terms.iter().map(Vec::as_slice).collect::<Vec<_>>());
            Reconstruction { phi: phi_r, lift }.write(&staging.path(names::RECONSTRUCTION), &key)?;
            let f = |c: &str| row.and_then(|row| times.f64s(c).map(|v| v[row])).unwrap_or(f64::NAN);
            Table::default()
                .with(names::SPEED_COLUMNS[0], Column::F64(vec![f("median_online_seconds")]))
                .with(names::SPEED_COLUMNS[1], Column::F64(vec![f("median_fom_seconds")]))
                .with(names::SPEED_COLUMNS[2], Column::F64(vec![f("speedup")]))
                .write_parquet(&staging.path(names::SPEED))?;
            let size = std::fs::metadata(staging.path(names::FILE)).map_or(0, |m| m.len());
            Ok(BTreeMap::from([
                ("algorithm".to_string(), json!(pick.algorithm)),
                ("r_primal".to_string(), json!(model.ranks().0)),
                ("r_dual".to_string(), json!(model.ranks().1)),
                ("model_bytes".to_string(), json!(size)),
            ]))
        })
    }
}

/// The chosen row of the trade-off table.
struct Pick {
    algorithm: String,
    dual_basis: String,
    r_primal: usize,
    r_dual: usize,
    measured: Measured,
}

impl Pick {
    /// Nothing measured: the full bases (`usize::MAX` ranks are clipped to the bases').
    fn full_bases() -> Self {
        Self {
            algorithm: Algorithm::Exact.name().into(),
            dual_basis: "full".into(),
            r_primal: usize::MAX,
            r_dual: usize::MAX,
            measured: Measured {
                median_primal_error: f64::NAN,
                p95_primal_error: f64::NAN,
                median_dual_error: f64::NAN,
                ..Measured::default()
            },
        }
    }

    fn of(t: &Table, row: usize) -> Self {
        let s = |c: &str| t.strs(c).map_or(String::new(), |v| v[row].clone());
        let u = |c: &str| t.u64s(c).map_or(0, |v| v[row]);
        let f = |c: &str| t.f64s(c).map_or(f64::NAN, |v| v[row]);
        Self {
            algorithm: s("algorithm"),
            dual_basis: s("dual_basis"),
            r_primal: u("r_primal") as usize,
            r_dual: u("r_dual") as usize,
            measured: Measured {
                points: u("points"),
                converged: u("converged"),
                median_primal_error: f("median_primal_error"),
                p95_primal_error: f("p95_primal_error"),
                median_dual_error: f("median_dual_error"),
            },
        }
    }
}

/// The row of `tradeoff.parquet` of the exact solve (full surface) at ranks `(ru, rl)`, if the
/// online stage measured them.
fn at_ranks(t: &Table, ru: u64, rl: u64) -> Option<usize> {
    let (alg, r_primal, r_dual) = (t.strs("algorithm")?, t.u64s("r_primal")?, t.u64s("r_dual")?);
    (0..t.rows()).find(|&i| alg[i] == Algorithm::Exact.name() && r_primal[i] == ru && r_dual[i] == rl)
}

/// The row of `tradeoff.parquet` to keep (see the module doc), if the table has rows of the
/// exact solve.
pub(crate) fn choose(t: &Table) -> Option<usize> {
    let (alg, points, conv) = (t.strs("algorithm")?, t.u64s("points")?, t.u64s("converged")?);
    let (ru, rl) = (t.u64s("r_primal")?, t.u64s("r_dual")?);
    let (dual, primal) = (t.f64s("median_dual_error")?, t.f64s("median_primal_error")?);
    // an undefined error ranks after every defined one
    let rank = |x: f64| if x.is_nan() { f64::INFINITY } else { x };
    (0..t.rows()).filter(|&i| alg[i] == Algorithm::Exact.name() || alg[i] == rom_names::SAMPLED).min_by(|&a, &b| {
        let missed = |i: usize| points[i].saturating_sub(conv[i]);
        missed(a)
            .cmp(&missed(b))
            .then(rank(dual[a]).total_cmp(&rank(dual[b])))
            .then(rank(primal[a]).total_cmp(&rank(primal[b])))
            .then((ru[a] + rl[a]).cmp(&(ru[b] + rl[b])))
            .then(a.cmp(&b))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (algorithm, r_primal, r_dual, converged of 10, median dual error, median primal error)
    type Row<'a> = (&'a str, u64, u64, u64, f64, f64);

    fn table(rows: &[Row<'_>]) -> Table {
        let col = |f: &dyn Fn(&Row<'_>) -> f64| Column::F64(rows.iter().map(f).collect());
        Table::default()
            .with("algorithm", Column::Str(rows.iter().map(|r| r.0.to_string()).collect()))
            .with("r_primal", Column::U64(rows.iter().map(|r| r.1).collect()))
            .with("r_dual", Column::U64(rows.iter().map(|r| r.2).collect()))
            .with("points", Column::U64(vec![10; rows.len()]))
            .with("converged", Column::U64(rows.iter().map(|r| r.3).collect()))
            .with("median_dual_error", col(&|r| r.4))
            .with("median_primal_error", col(&|r| r.5))
    }

    /// The choice: exact algorithms only, the fewest points not converged, then the least dual
    /// error, then the least primal error, then the fewest modes; undefined errors last;
    /// nothing without a row of the exact solve.
    #[test]
    fn choose_prefers_converged_accurate_small_models() {
        let t = table(&[
            ("paper", 2, 2, 10, 1e-9, 1e-9),     // paper: never
            ("exact", 8, 8, 9, 1e-8, 1e-8),      // a point failed
            ("exact", 8, 4, 10, 2e-3, 1e-3),     // candidate
            ("exact", 4, 4, 10, 2e-3, 1e-3),     // same errors, fewer modes: chosen
            ("exact", 2, 2, 10, f64::NAN, 1e-4), // undefined dual error: last
        ]);
        assert_eq!(choose(&t), Some(3));
        let t = table(&[("exact", 2, 2, 10, f64::NAN, 1e-4), ("exact-sampled", 2, 2, 10, f64::NAN, 1e-5)]);
        assert_eq!(choose(&t), Some(1));
        let t =
            table(&[("exact", 2, 2, 8, 1e-4, 1e-4), ("exact", 2, 2, 9, 1e-3, 1e-3), ("paper", 2, 2, 10, 1e-3, 1e-3)]);
        assert_eq!(choose(&t), Some(1), "the most converged when none converged everywhere");
        assert_eq!(choose(&table(&[("paper", 2, 2, 10, 1e-3, 1e-3)])), None);
    }
}
