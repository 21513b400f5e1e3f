//! Inputs read once per run: the first stage that needs a training set or the bases reads them
//! from the store (verifying every column), and every later stage of the run shares that copy
//! instead of reading the HDF5 files again. Only stages that compute (cache misses) ask, so a
//! fully cached run reads nothing. Nested levels are kept as their pressures and parameters
//! only ([`NestedLevel`]: every approximation of the comparison reads every level, and those are
//! small); their displacements are not kept (the nested stage holds two whole levels at a
//! time, docs/design-notes.md#the-nested-error-keeps-two-levels-in-memory).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

use super::basis::{self, Bases};
use super::streamed::{self, MetricSet, StreamedSet};
use super::trainset::{self, TrainingSet};
use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::ColMatrix;
use crate::store::Store;

/// The run's loaded inputs, by artifact key.
#[derive(Debug, Default)]
pub(crate) struct Loaded {
    sets: Mutex<HashMap<Key, Arc<TrainingSet>>>,
    streamed: Mutex<HashMap<Key, Arc<StreamedSet>>>,
    bases: Mutex<HashMap<Key, Arc<Bases>>>,
    levels: Mutex<HashMap<Key, Arc<NestedLevel>>>,
}

/// A nested level's pressures (`n_contact x points`) and parameter points: what the
/// comparison's nested error H(n) reads of it.
#[derive(Debug)]
pub(crate) struct NestedLevel {
    pub dual: ColMatrix,
    pub parameters: Vec<Vec<f64>>,
}

/// The value under `key`, loaded by `load` on first use.
fn get_or_load<T>(
    map: &Mutex<HashMap<Key, Arc<T>>>,
    key: &Key,
    load: impl FnOnce() -> Result<T, CromError>,
) -> Result<Arc<T>, CromError> {
    let mut map = map.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(v) = map.get(key) {
        return Ok(Arc::clone(v));
    }
    let v = Arc::new(load()?);
    map.insert(key.clone(), Arc::clone(&v));
    Ok(v)
}

impl Loaded {
    /// The training or test set `key`.
    pub(crate) fn set(&self, store: &Store, key: &Key) -> Result<Arc<TrainingSet>, CromError> {
        get_or_load(&self.sets, key, || trainset::load_from(store, key))
    }

    /// The training set `key` with its primal snapshots left in the store
    /// ([`super::streamed`]).
    pub(crate) fn streamed(&self, store: &Store, key: &Key) -> Result<Arc<StreamedSet>, CromError> {
        get_or_load(&self.streamed, key, || streamed::load(store, key))
    }

    /// The training set `key` for the offline metrics: streamed when `streamed`, else whole.
    pub(crate) fn metric_set(&self, store: &Store, key: &Key, streamed: bool) -> Result<MetricSet, CromError> {
        Ok(if streamed {
            MetricSet::Streamed(self.streamed(store, key)?)
        } else {
            MetricSet::Whole(self.set(store, key)?)
        })
    }

    /// The pressures and parameters of the nested level `key` (read whole and verified once,
    /// its displacements dropped).
    pub(crate) fn level(&self, store: &Store, key: &Key) -> Result<Arc<NestedLevel>, CromError> {
        get_or_load(&self.levels, key, || {
            let (dual, parameters) = super::streamed::load_dual(store, key)?;
            Ok(NestedLevel { dual, parameters })
        })
    }

    /// The bases `key`.
    pub(crate) fn bases(&self, store: &Store, key: &Key) -> Result<Arc<Bases>, CromError> {
        get_or_load(&self.bases, key, || basis::load_from(store, key))
    }

    /// How many sets and bases were read (for the tests).
    #[cfg(test)]
    pub(crate) fn counts(&self) -> (usize, usize) {
        fn n<T>(m: &Mutex<HashMap<Key, Arc<T>>>) -> usize {
            m.lock().unwrap_or_else(PoisonError::into_inner).len()
        }
        (n(&self.sets), n(&self.bases))
    }
}

#[cfg(test)]
mod tests {
    use super::super::{run_scene, Ctx, PointCounts};
    use crate::progress::Progress;
    use crate::store::Store;
    use crom_schemas::SceneConfig;

    fn ctx<'a>(store: &'a Store, scene: &'a SceneConfig) -> Ctx<'a> {
        Ctx {
            store,
            scene_name: scene.scene.name.clone(),
            command: "test".into(),
            progress: Progress::new(true),
            records: Vec::new(),
            warnings: Vec::new(),
            points: PointCounts::default(),
            loaded: Default::default(),
        }
    }

    /// A cold run of the rope reads the training set, the test set and the bases once each
    /// (basis, compactness, generalization, specificity, rom and report share them); a second,
    /// fully cached run reads none.
    #[test]
    fn a_run_reads_each_input_once_and_a_cached_run_none() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/rope.toml");
        let scene = SceneConfig::load(&root).expect("rope.toml");
        let store = Store::open(dir.path()).expect("store");
        let mut c = ctx(&store, &scene);
        run_scene(&mut c, &scene, true).expect("cold run");
        assert_eq!(c.loaded.counts(), (2, 1));
        let mut c = ctx(&store, &scene);
        run_scene(&mut c, &scene, true).expect("cached run");
        assert_eq!(c.loaded.counts(), (0, 0));
    }
}
