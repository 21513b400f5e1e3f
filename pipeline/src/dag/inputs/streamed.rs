//! Large training sets with their primal snapshots left in the store.
//!
//! Above [`STREAM_PRIMAL_ABOVE`] training snapshots the offline stages (bases, compactness,
//! leave-one-out, specificity) do not hold the `n_dof x N` primal matrix (3.2 GB for 65 537
//! ironing-coarse snapshots): the set is loaded as its dual snapshots, its parameters and each
//! primal column's squared norm, and the primal metrics read the columns again from their
//! blocks, a fixed number of columns at a time ([`crom_stages::blocks`]), verifying each
//! column's blake3 as every read does. Their memory is a block and the rank, not N.
//!
//! The keys of those stages carry `primal = "streamed"` above the switch-over size: the frame's
//! tolerance is `eps ||S||_F` with the norm summed from the columns' norms, which can round
//! differently from the whole matrix's norm of the in-memory path. At or below it nothing
//! changes (the paper's studies are in memory, bit for bit).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use crom_schemas::artifact::{trainset as names, ArtifactKind};
use crom_stages::basis::{large_frame, Frame};
use crom_stages::blocks::{BlockError, ColumnBlocks, ColumnNorms};
use faer::{Mat, MatRef};

use super::sets;
use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::ColMatrix;
use crate::io::snapshot_set::TrainingSet;
use crate::store::columns::{read_columns, IndexRow};
use crate::store::Store;

/// Training sets larger than this are streamed (the frame's switch-over size: below it the
/// POD is the direct SVD of the whole matrix).
pub(crate) const STREAM_PRIMAL_ABOVE: usize = crom_stages::basis::POD_FRAME_ABOVE;

/// Columns read per block while loading a streamed set.
const LOAD_BLOCK: usize = 256;

/// Training sets whose primal snapshots take more than this many bytes are streamed whatever
/// their count: a 3-D scene's 1 025 columns of 109 431 dofs are 0.9 GB, and holding them, their
/// POD's working copy and its test set had a level-10 ironing-3d study peak at 4.7 GB.
pub(crate) const STREAM_PRIMAL_BYTES: f64 = 512.0 * 1024.0 * 1024.0;

/// The key marker of the stages that stream the primal snapshots of the scene's training set:
/// more than [`STREAM_PRIMAL_ABOVE`] points, or more than [`STREAM_PRIMAL_BYTES`] of primal
/// snapshots (rows as the memory estimate counts them from the scene, `resources`).
pub(crate) fn primal_of(scene: &crom_schemas::SceneConfig) -> Option<&'static str> {
    let n_train = scene.parameter.train_points().len();
    let (rows, _) = crate::resources::snapshot_rows(scene);
    (n_train > STREAM_PRIMAL_ABOVE || 8.0 * rows * n_train as f64 > STREAM_PRIMAL_BYTES).then_some("streamed")
}

/// A training set as the offline metrics read it: whole, or with its primal snapshots left in
/// the store.
#[derive(Debug, Clone)]
pub(crate) enum MetricSet {
    Whole(Arc<TrainingSet>),
    Streamed(Arc<StreamedSet>),
}

impl MetricSet {
    /// The dual snapshots (in memory either way).
    pub(crate) fn dual(&self) -> &ColMatrix {
        match self {
            Self::Whole(s) => &s.dual,
            Self::Streamed(s) => &s.dual,
        }
    }

    /// Number of snapshots.
    pub(crate) fn len(&self) -> usize {
        self.dual().cols
    }
}

/// A training set whose primal snapshots stay in the store.
#[derive(Debug)]
pub(crate) struct StreamedSet {
    /// Dual snapshots, `n_contact x N`, in memory.
    pub dual: ColMatrix,
    /// The primal columns, read block by block.
    pub primal: PrimalColumns,
    /// `||u_j||^2` of every primal column, and whether all are finite.
    pub primal_norms: ColumnNorms,
    /// The primal's [`large_frame`], once computed: the basis stage's POD and the
    /// generalization stage's orthogonal folds read the same one (one pass over the primal
    /// columns instead of two). Outer `None`: not computed yet.
    frame: Mutex<Option<Option<Arc<Frame>>>>,
}

impl StreamedSet {
    /// The primal's [`large_frame`], computed on first use and kept.
    pub(crate) fn frame(&self) -> Result<Option<Arc<Frame>>, BlockError> {
        let mut held = self.frame.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(frame) = held.as_ref() {
            return Ok(frame.clone());
        }
        let frame = large_frame(&self.primal, &self.primal_norms)?.map(Arc::new);
        *held = Some(frame.clone());
        Ok(frame)
    }

    /// The primal's frame for its last reader (the leave-one-out folds): computed if it is not
    /// held, and no longer held afterwards (its coordinates are N columns long).
    pub(crate) fn take_frame(&self) -> Result<Option<Arc<Frame>>, BlockError> {
        let frame = self.frame()?;
        *self.frame.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = None;
        Ok(frame)
    }
}

/// The primal snapshots of a stored set as a [`ColumnBlocks`] source. A failed read is kept
/// (the first one) so the stage can report the store's own error, with its file and fix.
#[derive(Debug)]
pub(crate) struct PrimalColumns {
    root: PathBuf,
    rows: Vec<IndexRow>,
    n_dof: usize,
    n_contact: usize,
    failure: Mutex<Option<CromError>>,
}

impl PrimalColumns {
    /// The store's error behind a failed block read, if one failed.
    pub(crate) fn failure(&self) -> Option<CromError> {
        self.failure.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take()
    }

    /// The error of a computation that read these columns: the store's own error when a read
    /// failed, else `otherwise` (the computation's).
    pub(crate) fn error_or(&self, otherwise: impl FnOnce() -> CromError) -> CromError {
        self.failure().unwrap_or_else(otherwise)
    }

    /// Columns `start..start + count`: primal and dual, each verified.
    fn read(&self, start: usize, count: usize) -> Result<(ColMatrix, ColMatrix), CromError> {
        let refs: Vec<&IndexRow> = self.rows[start..start + count].iter().collect();
        read_columns(&self.root, self.n_dof, self.n_contact, &refs)
    }
}

impl ColumnBlocks for PrimalColumns {
    fn nrows(&self) -> usize {
        self.n_dof
    }
    fn ncols(&self) -> usize {
        self.rows.len()
    }
    fn block(&self, start: usize, count: usize) -> Result<Mat<f64>, BlockError> {
        match self.read(start, count) {
            Ok((p, _)) => Ok(MatRef::from_column_major_slice(&p.data, p.rows, p.cols).to_owned()),
            Err(e) => {
                let message = e.to_string();
                let mut held = self.failure.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                held.get_or_insert(e);
                Err(BlockError(message))
            }
        }
    }
}

/// The dual snapshots and the parameters of the stored set `key`, read block by block (the
/// primal columns verified and dropped): what the comparison's stages and the nested error
/// read, without holding the primal even for a moment (a 3-D set's primal is 0.9 GB at 1 025
/// columns of 109 431 dofs).
pub(crate) fn load_dual(store: &Store, key: &Key) -> Result<(ColMatrix, Vec<Vec<f64>>), CromError> {
    let dir = store.dir(ArtifactKind::TRAINING_SET, key);
    let rows = sets::rows_of(&dir.join(names::STATS))?;
    let (n_dof, n_contact) = sets::set_shape(store, key, &rows)?;
    let parameters: Vec<Vec<f64>> = rows.iter().map(|r| r.parameters.clone()).collect();
    let count = rows.len();
    let primal = PrimalColumns { root: store.root().to_path_buf(), rows, n_dof, n_contact, failure: Mutex::new(None) };
    let mut dual = ColMatrix { rows: n_contact, cols: count, data: Vec::with_capacity(n_contact * count) };
    for start in (0..count).step_by(LOAD_BLOCK) {
        let (_, d) = primal.read(start, LOAD_BLOCK.min(count - start))?;
        dual.data.extend_from_slice(&d.data);
    }
    Ok((dual, parameters))
}

/// Load the training set `key` without its primal matrix: the dual snapshots and the primal
/// columns' norms, read block by block (one pass; every column verified).
pub(crate) fn load(store: &Store, key: &Key) -> Result<StreamedSet, CromError> {
    let dir = store.dir(ArtifactKind::TRAINING_SET, key);
    let rows = sets::rows_of(&dir.join(names::STATS))?;
    let (n_dof, n_contact) = sets::set_shape(store, key, &rows)?;
    let count = rows.len();
    let primal = PrimalColumns { root: store.root().to_path_buf(), rows, n_dof, n_contact, failure: Mutex::new(None) };
    let mut dual = ColMatrix { rows: n_contact, cols: count, data: Vec::with_capacity(n_contact * count) };
    let mut norms = ColumnNorms { norm2: Vec::with_capacity(count), finite: true };
    for start in (0..count).step_by(LOAD_BLOCK) {
        let (p, d) = primal.read(start, LOAD_BLOCK.min(count - start))?;
        let p = MatRef::from_column_major_slice(&p.data, p.rows, p.cols);
        for j in 0..p.ncols() {
            norms.finite &= p.col(j).iter().all(|v| v.is_finite());
            norms.norm2.push(p.col(j).squared_norm_l2());
        }
        dual.data.extend_from_slice(&d.data);
    }
    Ok(StreamedSet { dual, primal, primal_norms: norms, frame: Mutex::new(None) })
}
