//! The scene files shipped in `data/scenes/`, for this crate's tests and benchmarks (the pipeline
//! finds scene files itself), so scene values live only in those files.

/// The shipped scene file `data/scenes/<name>.toml`, parsed and validated.
pub fn shipped_scene(name: &str) -> Result<crom_schemas::SceneConfig, crom_schemas::SceneError> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes").join(format!("{name}.toml"));
    crom_schemas::SceneConfig::load(&path)
}

/// The contact model of the shipped 2-D scene `name` (Hertz or ironing), built from its file;
/// panics for another kind of scene or an unreadable file (for examples and benchmarks).
pub fn shipped_contact_model(name: &str) -> crate::contact::ContactModel {
    use crate::contact::{build_hertz, build_ironing, HertzParams, IroningParams};
    use crom_schemas::Model;
    let scene = shipped_scene(name).unwrap_or_else(|e| panic!("{e}"));
    match &scene.model {
        Model::Hertz(h) => build_hertz(&HertzParams::from(h)).expect("hertz scene"),
        Model::Ironing(i) => build_ironing(&IroningParams::from(i)).expect("ironing scene"),
        _ => panic!("{name} is not a 2-D contact scene"),
    }
}
