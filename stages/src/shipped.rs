//! The scene files shipped in `data/scenes/`, for this crate's tests and benchmarks (the pipeline
//! finds scene files itself), so scene values live only in those files.

/// The shipped scene file `data/scenes/<name>.toml`, parsed and validated.
pub fn shipped_scene(name: &str) -> Result<crom_schemas::SceneConfig, crom_schemas::SceneError> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes").join(format!("{name}.toml"));
    crom_schemas::SceneConfig::load(&path)
}
