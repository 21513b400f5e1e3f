//! Inputs read once per run: the first stage that needs a training set or the bases reads them
//! from the store (verifying every column), and every later stage of the run shares that copy
//! instead of reading the HDF5 files again. Only stages that compute (cache misses) ask, so a
//! fully cached run reads nothing. Nested levels are kept as their pressures and parameters
//! only ([`NestedLevel`]: every approximation of the comparison reads every level, and those are
//! small); their displacements are not kept (the nested stage holds two whole levels at a
//! time, docs/design-notes.md#the-nested-error-keeps-two-levels-in-memory).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

use super::bases::{self, Bases};
use super::sets;
use super::streamed::{self, MetricSet, StreamedSet};
use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::ColMatrix;
use crate::io::snapshot_set::TrainingSet;
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
        get_or_load(&self.sets, key, || sets::load_from(store, key))
    }

    /// The training set `key` with its primal snapshots left in the store
    /// ([`streamed`]).
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
            let (dual, parameters) = streamed::load_dual(store, key)?;
            Ok(NestedLevel { dual, parameters })
        })
    }

    /// Keep nested level `key`'s pressures and points, read by a stage that had the whole level
    /// (the nested stage), for the stages after it ([`Self::level`]); a level already kept stays.
    pub(crate) fn keep_level(&self, key: &Key, dual: &ColMatrix, parameters: &[Vec<f64>]) {
        let mut map = self.levels.lock().unwrap_or_else(PoisonError::into_inner);
        map.entry(key.clone())
            .or_insert_with(|| Arc::new(NestedLevel { dual: dual.clone(), parameters: parameters.to_vec() }));
    }

    /// The bases `key`.
    pub(crate) fn bases(&self, store: &Store, key: &Key) -> Result<Arc<Bases>, CromError> {
        get_or_load(&self.bases, key, || bases::load_from(store, key))
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
