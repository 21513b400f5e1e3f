//! Every way a `crom` command can fail, with the exit code it maps to. Messages name the file,
//! the field and the fix.

use std::path::PathBuf;

use crom_schemas::SceneError;

/// A failed `crom` command.
#[derive(Debug, thiserror::Error)]
pub enum CromError {
    /// Bad scene file (exit 2).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// `crom run NAME` with no such scene (exit 2).
    #[error("unknown scene `{name}`: there is no file {path}\n  available scenes: {available}\n  fix: use one of the available names, or give a path to a scene TOML file")]
    UnknownScene {
        /// What the user typed.
        name: String,
        /// Where it was looked for.
        path: PathBuf,
        /// Names found in the scenes directory.
        available: String,
    },
    /// Another process holds the store (exit 3).
    #[error("store {root} is in use by another crom process (lock file {lock})\n  fix: wait for the other run to finish, or point this run at another store with --store DIR")]
    Locked {
        /// Store root.
        root: PathBuf,
        /// Lock file.
        lock: PathBuf,
    },
    /// File-system failure in the store (exit 1).
    #[error("{path}: {action} failed: {source}\n  fix: check permissions and free space of the store (--store DIR or CROM_STORE)")]
    Io {
        /// The path involved.
        path: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An artifact file could not be written or read (exit 1).
    #[error("{path}: {message}\n  fix: {fix}")]
    Artifact {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
        /// How to fix it.
        fix: String,
    },
    /// Some snapshots did not converge; the others are stored (exit 1).
    #[error("{failed} of {total} snapshots of scene `{scene}` failed (the others are stored; downstream stages were skipped):\n{list}\n  table: {}\n  fix: for `no convergence`, raise solver.max_iter (or relax solver.rel_tol) in the scene file; for `infeasible`, change the geometry or the parameter range so that the fixed ends lie on or above the obstacle", table.display())]
    SolveFailures {
        /// Scene name.
        scene: String,
        /// Number of failures.
        failed: usize,
        /// Number of points attempted.
        total: usize,
        /// One line per failed point.
        list: String,
        /// The failure table written for this run.
        table: PathBuf,
    },
    /// A snapshot column did not match its checksum (exit 1 if it happens twice in one run; the
    /// first time the block is quarantined and its points are solved again).
    #[error("{path}: {message}\n  fix: {fix}")]
    CorruptColumns {
        /// The block file.
        path: PathBuf,
        /// The block, relative to the store root.
        block: String,
        /// What did not match.
        message: String,
        /// How to fix it.
        fix: &'static str,
    },
    /// A command-line request that cannot be carried out as given (exit 2).
    #[error("{message}\n  fix: {fix}")]
    Usage {
        /// What is wrong.
        message: String,
        /// How to fix it.
        fix: String,
    },
    /// An executor (the cluster's scheduler, its workers) could not do the work (exit 1).
    #[error("{message}\n  fix: {fix}")]
    Executor {
        /// What went wrong.
        message: String,
        /// How to fix it.
        fix: String,
    },
    /// An external scene's data file that cannot be used as given: missing, of the wrong
    /// shape, or with values the study cannot take (exit 2). Nothing was stored.
    #[error("{path}: {what}: {message}\n  fix: {fix}")]
    Input {
        /// The data file.
        path: PathBuf,
        /// The dataset, field or column in it.
        what: String,
        /// What is wrong.
        message: String,
        /// How to fix it.
        fix: String,
    },
    /// A reduction stage failed numerically (exit 1).
    #[error("stage `{stage}` of scene `{scene}` failed: {message}")]
    Numerical {
        /// Stage name.
        stage: &'static str,
        /// Scene name.
        scene: String,
        /// The typed error's message.
        message: String,
    },
}

impl CromError {
    /// Process exit code: 2 for bad user input, 3 for a busy store, 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        match self {
            CromError::Scene(_)
            | CromError::UnknownScene { .. }
            | CromError::Usage { .. }
            | CromError::Input { .. } => 2,
            CromError::Locked { .. } => 3,
            _ => 1,
        }
    }

    /// An [`CromError::Io`] at `path`.
    pub fn io(path: impl Into<PathBuf>, action: &'static str, source: std::io::Error) -> Self {
        CromError::Io { path: path.into(), action, source }
    }

    /// An [`CromError::Input`] about `what` in the data file `path`.
    pub fn input(
        path: impl Into<PathBuf>,
        what: impl Into<String>,
        message: impl Into<String>,
        fix: impl Into<String>,
    ) -> Self {
        CromError::Input { path: path.into(), what: what.into(), message: message.into(), fix: fix.into() }
    }

    /// An [`CromError::Artifact`] from an HDF5 or Parquet library error.
    pub fn artifact(path: impl Into<PathBuf>, message: impl std::fmt::Display, fix: &str) -> Self {
        CromError::Artifact { path: path.into(), message: message.to_string(), fix: fix.to_string() }
    }
}
