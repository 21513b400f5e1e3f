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

/// Warnings about a valid scene: bodies of nearly incompressible material with fully
/// integrated Q1 elements, which will give poor answers (the indicator is [`LOCKING_RATIO`]),
/// and metric settings larger than the training set, which are clamped ([`clamped_settings`]);
/// each names the field and what to do.
pub fn warnings(scene: &crom_schemas::SceneConfig) -> Vec<String> {
    let mut out = locking(scene);
    out.extend(clamped_settings(scene));
    out
}

/// `study.max_rank` and `study.loo_folds` above the N training snapshots are valid and clamped
/// (the curves stop at N, leave-one-out at N - 1; the folds are every fold): the run states the
/// value it used and how to silence the warning.
pub fn clamped_settings(scene: &crom_schemas::SceneConfig) -> Vec<String> {
    let n = scene.parameter.train_points().len();
    let mut out = Vec::new();
    if let Some(m) = scene.study.max_rank.filter(|&m| m > n) {
        out.push(format!(
            "study.max_rank = {m} is more than the {n} training snapshots: the metric curves stop at m = {n} at \
             most (leave-one-out at m = {}); set max_rank = {n} to silence this",
            n.saturating_sub(1)
        ));
    }
    if let Some(f) = scene.study.loo_folds.filter(|&f| f > n) {
        out.push(format!(
            "study.loo_folds = {f} is more than the {n} training snapshots: G(m) averages all {n} folds; set \
             loo_folds = {n} to silence this"
        ));
    }
    out
}

/// Bodies of nearly incompressible material with fully integrated Q1 elements.
fn locking(scene: &crom_schemas::SceneConfig) -> Vec<String> {
    use crom_schemas::scene::{Integration, Model};
    let bodies: Vec<(&str, &crom_schemas::scene::MaterialSpec)> = match &scene.model {
        Model::Rope(_) | Model::External(_) => vec![],
        Model::Hertz(h) => vec![("model.hertz.material", &h.material)],
        Model::Ironing(i) => {
            vec![("model.ironing.slab.material", &i.slab.material), ("model.ironing.iron.material", &i.iron.material)]
        }
        Model::Hertz3d(h) => vec![("model.hertz3d.material", &h.material)],
        Model::Ironing3d(i) => vec![
            ("model.ironing3d.block.material", &i.block.material),
            ("model.ironing3d.die.material", &i.die.material),
        ],
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
