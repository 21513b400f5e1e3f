//! What names things in a stage's artifact but never changes one of its numbers.
//!
//! A stage computes from its key struct and its inputs alone; it cannot read the scene (the
//! run's [`super::Ctx`] does not carry it). The scene's name and its parameter's names are the
//! one exception: they label tables and files, so a stage holds them as [`Labels`], taken from
//! the scene at plan time. They are not in any key: two scenes that differ only in names share
//! every artifact, which then carries the names of the scene that computed it first.

use crom_schemas::SceneConfig;

/// The scene's labels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Labels {
    /// The scene's name.
    pub scene: String,
    /// The parameter's name (for a vector parameter: the first component's).
    pub parameter: String,
    /// The parameter's component names (one for a scalar parameter).
    pub names: Vec<String>,
}

impl Labels {
    /// The labels of `scene`.
    pub(crate) fn of(scene: &SceneConfig) -> Self {
        Self {
            scene: scene.scene.name.clone(),
            parameter: scene.parameter.name.clone(),
            names: scene.parameter.names().iter().map(|s| s.to_string()).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::plan::Plan;
    use crom_schemas::artifact::ArtifactKind;
    use crom_schemas::SceneConfig;

    fn scene(text: &str) -> SceneConfig {
        SceneConfig::from_toml_str(text, std::path::Path::new("hertz.toml")).expect("scene")
    }

    /// Renaming a scene and rewording its description change only the report, the one stage
    /// that shows them as text; every other artifact, snapshots included, is shared.
    #[test]
    fn names_change_no_key_but_the_reports() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/hertz.toml");
        let text = std::fs::read_to_string(path).expect("hertz.toml");
        let renamed = text.replacen("name = \"hertz\"", "name = \"hertz-renamed\"", 1).replacen(
            "description = \"",
            "description = \"Reworded: ",
            1,
        );
        assert_ne!(text, renamed, "the scene file's name or description line moved");
        let (a, b) = (Plan::of(&scene(&text)), Plan::of(&scene(&renamed)));
        assert_eq!(a.nodes.len(), b.nodes.len());
        for (x, y) in a.nodes.iter().zip(&b.nodes) {
            assert_eq!(x.name, y.name);
            if x.kind == ArtifactKind::REPORT {
                assert_ne!(x.key, y.key, "the report shows the name and description");
            } else {
                assert_eq!(x.key, y.key, "{}: a label in its key", x.name);
            }
        }
    }
}
