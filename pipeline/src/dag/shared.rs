//! What the stages of one run hand each other in memory rather than through the store
//! ([`Shared`]): the high-fidelity model, built on first use ([`LazyPhysics`]), with the
//! full-order times and response bases it computes once per process; the snapshot sweeps'
//! index rows ([`Columns`]); the online approximations' shared base.

use std::collections::BTreeMap;

use crom_schemas::SceneConfig;

use super::online::{self, OnlineBase};
use crate::cache::Key;
use crate::error::CromError;
use crate::io::snapshot_set::TrainingSet;
use crate::physics::Physics;
use crate::store::columns::IndexRow;

/// What the snapshot stage hands on: the index rows of the requested points, in order.
#[derive(Debug, Clone)]
pub(crate) struct Columns {
    /// One row per requested point (the same row twice for a repeated point).
    pub rows: Vec<IndexRow>,
    /// Rows of the family's block files (n_dof, n_contact).
    pub shape: (usize, usize),
}

/// What stages of one run hand each other in memory rather than through the store: the
/// high-fidelity model (built on first use), the snapshot sweeps' index rows, the online
/// approximations' shared base.
#[derive(Debug)]
pub(crate) struct Shared<'s> {
    /// The high-fidelity model.
    pub physics: LazyPhysics<'s>,
    /// The index rows of each sweep run so far, by sweep number.
    pub columns: BTreeMap<usize, Columns>,
    /// The online approximations' full-order base.
    pub online_base: Option<OnlineBase>,
}

impl<'s> Shared<'s> {
    /// Nothing built yet.
    pub(crate) fn new(scene: &'s SceneConfig) -> Self {
        Self { physics: LazyPhysics::new(scene), columns: BTreeMap::new(), online_base: None }
    }
}

/// The high-fidelity model, built on first use: a fully cached run never meshes or factorises.
#[derive(Debug)]
pub(crate) struct LazyPhysics<'s> {
    scene: &'s SceneConfig,
    built: Option<Physics>,
    /// The full-order solve times at some points of one set (its key, the points), measured on
    /// first use.
    fom: Option<(Key, Vec<Vec<f64>>, Vec<f64>)>,
    /// The POD of one training set's responses (its key), computed on first use.
    responses: Option<(Key, std::sync::Arc<crate::io::h5::ColMatrix>)>,
    /// The POD of one training set's responses and their translates (its key and the shift).
    translated: Option<((Key, usize), std::sync::Arc<crate::io::h5::ColMatrix>)>,
}

impl<'s> LazyPhysics<'s> {
    /// Nothing built yet.
    pub(crate) fn new(scene: &'s SceneConfig) -> Self {
        Self { scene, built: None, fom: None, responses: None, translated: None }
    }

    /// The full-order solve time at each of `parameters`, points of the set `set` (its key; all
    /// of them, or the sample of them an online stage measures), measured on the first call in
    /// this process ([`online::fom_seconds`]) and handed to every later stage that asks for the
    /// same points of the same set: the trade-off and the online comparison then state their
    /// speed-ups against one measurement, and the full-order solves are timed once per run
    /// instead of once per stage.
    pub(crate) fn fom_seconds(&mut self, set: &Key, parameters: &[Vec<f64>]) -> Result<Vec<f64>, CromError> {
        if let Some((of, points, seconds)) = &self.fom {
            if of == set && points.as_slice() == parameters {
                return Ok(seconds.clone());
            }
        }
        let seconds = online::fom_seconds(self.get()?, parameters);
        self.fom = Some((set.clone(), parameters.to_vec(), seconds.clone()));
        Ok(seconds)
    }

    /// The primal basis of the online stages, the POD of the responses of the training set
    /// `set` (its key; `train` its data, [`online::response_basis`]), computed on the first call in
    /// this process and handed to every later stage that asks for the same set: the trade-off,
    /// the online comparison and the stored model each took the same SVD again (0.09 s each
    /// on ironing-fine). `fail` turns the basis's error into the calling stage's.
    pub(crate) fn responses(
        &mut self,
        set: &Key,
        train: &TrainingSet,
        fail: impl Fn(String) -> CromError,
    ) -> Result<std::sync::Arc<crate::io::h5::ColMatrix>, CromError> {
        if let Some((of, phi)) = &self.responses {
            if of == set {
                return Ok(std::sync::Arc::clone(phi));
            }
        }
        let op = self.get()?.operator();
        let phi = std::sync::Arc::new(online::response_basis(op, train).map_err(fail)?);
        self.responses = Some((set.clone(), std::sync::Arc::clone(&phi)));
        Ok(phi)
    }

    /// The primal basis of an online solve with `primal_translates = shift`: the POD of the
    /// training set's responses and their translates ([`online::translated_response_basis`]),
    /// computed on the first call in this process for that set and shift, and handed to the
    /// model stage after the online comparison.
    pub(crate) fn translated_responses(
        &mut self,
        set: &Key,
        train: &TrainingSet,
        shift: usize,
        fail: impl Fn(String) -> CromError,
    ) -> Result<std::sync::Arc<crate::io::h5::ColMatrix>, CromError> {
        if let Some(((of, k), phi)) = &self.translated {
            if of == set && *k == shift {
                return Ok(std::sync::Arc::clone(phi));
            }
        }
        let phi = std::sync::Arc::new(online::translated_response_basis(self.get()?, train, shift).map_err(fail)?);
        self.translated = Some(((set.clone(), shift), std::sync::Arc::clone(&phi)));
        Ok(phi)
    }

    /// Drop the built model (it is built again if asked for).
    pub(crate) fn release(&mut self) {
        self.built = None;
    }

    /// The model, building it if needed.
    pub(crate) fn get(&mut self) -> Result<&Physics, CromError> {
        self.get_with(false)
    }

    /// [`Self::get`] for the mesh stage, which reads the stiffness's condition estimate: a model
    /// built here computes it beside the rest of its factorisation
    /// ([`Physics::build_with_condition`]); one built before computes it on that read.
    pub(crate) fn get_with_condition(&mut self) -> Result<&Physics, CromError> {
        self.get_with(true)
    }

    fn get_with(&mut self, with_condition: bool) -> Result<&Physics, CromError> {
        if self.built.is_none() {
            let build = if with_condition { Physics::build_with_condition } else { Physics::build };
            let p = build(self.scene).map_err(|message| CromError::Numerical {
                stage: "mesh",
                scene: self.scene.scene.name.clone(),
                message,
            })?;
            self.built = Some(p);
        }
        Ok(self.built.as_ref().expect("built above"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The full-order times are measured once per set and handed out again: a second
    /// measurement of wall-clock times would not repeat the first to the bit. Of the 64 points,
    /// the 32 of the timed sample have a time and the others none (NaN).
    #[test]
    fn the_full_order_times_are_measured_once_per_set() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        let scene = SceneConfig::load(&dir.join("rope.toml")).expect("shipped scene");
        let mut physics = LazyPhysics::new(&scene);
        let points: Vec<Vec<f64>> = (0..64).map(|k| vec![-0.3 + 0.01 * f64::from(k)]).collect();
        let (a, b) = (Key("a".into()), Key("b".into()));
        let bits = |v: &[f64]| v.iter().map(|t| t.to_bits()).collect::<Vec<_>>();
        let first = physics.fom_seconds(&a, &points).expect("rope");
        assert_eq!(first.len(), points.len());
        let timed = super::super::timing::timed_points(points.len());
        assert_eq!(timed.iter().filter(|&&t| t).count(), super::super::timing::TIMED_POINTS);
        for (t, on) in first.iter().zip(&timed) {
            assert!(if *on { *t > 0.0 && t.is_finite() } else { t.is_nan() }, "{t} (timed: {on})");
        }
        let again = physics.fom_seconds(&a, &points).expect("rope");
        assert_eq!(bits(&again), bits(&first), "the same set is not re-timed");
        let other = physics.fom_seconds(&b, &points).expect("rope");
        assert_ne!(bits(&other), bits(&first), "another set is timed afresh");
        assert_eq!(bits(&physics.fom_seconds(&b, &points).expect("rope")), bits(&other));
        // other points of the same set (a sample an online stage measures): timed afresh
        let sample: Vec<Vec<f64>> = points.iter().step_by(2).cloned().collect();
        let part = physics.fom_seconds(&b, &sample).expect("rope");
        assert_eq!(part.len(), sample.len());
        assert_ne!(bits(&part), bits(&other[..sample.len()]), "a sample of the set is timed afresh");
    }

    /// The response basis is computed once per training set and handed out again (the same
    /// allocation), equal to a direct computation; another set gets its own.
    #[test]
    fn the_response_basis_is_computed_once_per_set() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        let scene = SceneConfig::load(&dir.join("rope.toml")).expect("shipped scene");
        let mut physics = LazyPhysics::new(&scene);
        let set = |gammas: &[f64], physics: &mut LazyPhysics<'_>| {
            let parameters: Vec<Vec<f64>> = gammas.iter().map(|&g| vec![g]).collect();
            let snaps: Vec<_> =
                parameters.iter().map(|mu| physics.get().expect("rope").solve(mu).expect("solves")).collect();
            let u: Vec<&[f64]> = snaps.iter().map(|s| s.u.as_slice()).collect();
            let p: Vec<&[f64]> = snaps.iter().map(|s| s.pressure.as_slice()).collect();
            let rows = (u[0].len(), p[0].len());
            TrainingSet {
                primal: crate::io::h5::ColMatrix::from_columns(rows.0, &u),
                dual: crate::io::h5::ColMatrix::from_columns(rows.1, &p),
                parameters,
            }
        };
        let (one, two) = (set(&[-0.2, -0.1, 0.0], &mut physics), set(&[-0.25, -0.05], &mut physics));
        let (a, b) = (Key("a".into()), Key("b".into()));
        let fail = |m: String| CromError::Numerical { stage: "rom", scene: "rope".into(), message: m };
        let first = physics.responses(&a, &one, fail).expect("basis");
        let direct = online::response_basis(physics.get().expect("rope").operator(), &one).expect("basis");
        assert_eq!(*first, direct);
        assert!(std::sync::Arc::ptr_eq(&first, &physics.responses(&a, &one, fail).expect("basis")), "not again");
        let other = physics.responses(&b, &two, fail).expect("basis");
        assert!(!std::sync::Arc::ptr_eq(&first, &other), "another set has its own");
        assert_eq!(*other, online::response_basis(physics.get().expect("rope").operator(), &two).expect("basis"));
    }
}
