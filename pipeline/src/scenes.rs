//! Finding a scene file from what the user typed.

use std::path::{Path, PathBuf};

use crate::error::CromError;

/// Names of the `*.toml` files in `dir`, sorted.
pub fn available(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

/// `NAME` → `<dir>/NAME.toml`; anything that looks like a path (has a separator or ends in
/// `.toml`) is used as given.
pub fn resolve(arg: &str, dir: &Path) -> Result<PathBuf, CromError> {
    let as_path = Path::new(arg);
    if arg.ends_with(".toml") || arg.contains(std::path::MAIN_SEPARATOR) {
        return Ok(as_path.to_path_buf());
    }
    let candidate = dir.join(format!("{arg}.toml"));
    if candidate.is_file() {
        return Ok(candidate);
    }
    let names = available(dir);
    let available = if names.is_empty() {
        format!("none found in {} (use --scenes DIR or run from the repository root)", dir.display())
    } else {
        names.join(", ")
    };
    Err(CromError::UnknownScene { name: arg.to_string(), path: candidate, available })
}
