//! Errors a user can cause with a scene file. Each names the file, the field and the fix.

use std::path::PathBuf;

/// A scene file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read scene file: {source}\n  fix: check that the file exists and is readable")]
    Read {
        /// The scene file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// TOML syntax error, unknown key, missing field or wrong type.
    #[error("{path}: {message}\n  fix: {fix}")]
    Parse {
        /// The scene file.
        path: PathBuf,
        /// The parser's message (line, column and the offending key).
        message: String,
        /// How to fix it.
        fix: String,
    },
    /// A value that parses but is out of range.
    #[error("{path}: field `{field}` {problem}\n  fix: {fix}")]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// Dotted path of the field, e.g. `model.rope.n_elements`.
        field: String,
        /// What is wrong with the value.
        problem: String,
        /// How to fix it.
        fix: String,
    },
}
