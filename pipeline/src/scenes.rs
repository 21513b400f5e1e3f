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

/// Bulk-to-shear ratio `lambda / mu = 2 nu / (1 - 2 nu)` above which a fully integrated Q1 body
/// is warned about: 49, i.e. `nu > 0.49`. The volumetric stiffness then dominates the shear
/// stiffness by two orders, and the 2x2-integrated Q1 element, which cannot represent an
/// isochoric bending field, locks: displacements and contact widths come out too small and
/// pressures too high, the more so as `nu -> 1/2` (Hughes, *The Finite Element Method*, 4.5).
pub const LOCKING_RATIO: f64 = 49.0;

/// Warnings about a valid scene that will give poor answers: bodies of nearly incompressible
/// material with fully integrated Q1 elements (the indicator is [`LOCKING_RATIO`]), each naming
/// the field and the remedy.
pub fn warnings(scene: &crom_schemas::SceneConfig) -> Vec<String> {
    use crom_schemas::scene::{Integration, Model};
    let bodies: Vec<(&str, &crom_schemas::scene::MaterialSpec)> = match &scene.model {
        Model::Rope(_) | Model::External(_) => vec![],
        Model::Hertz(h) => vec![("model.hertz.material", &h.material)],
        Model::Ironing(i) => {
            vec![("model.ironing.slab.material", &i.slab.material), ("model.ironing.iron.material", &i.iron.material)]
        }
    };
    bodies
        .into_iter()
        .filter(|(_, m)| m.integration == Integration::Full)
        .filter_map(|(field, m)| {
            let ratio = 2.0 * m.poisson / (1.0 - 2.0 * m.poisson);
            (ratio > LOCKING_RATIO).then(|| {
                format!(
                    "{field}: poisson = {} makes lambda/mu = {ratio:.0} (> {LOCKING_RATIO}): fully integrated Q1 elements \
                     lock (too stiff: displacements and contact widths too small, pressures too high); fix: add \
                     integration = \"selective\" to this material (selective reduced integration of the volumetric term)",
                    m.poisson
                )
            })
        })
        .collect()
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
