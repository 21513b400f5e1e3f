//! Mesh stage: the scene's discretisation as `mesh.h5` + `mesh.xdmf`.

use std::collections::BTreeMap;

use crom_schemas::artifact::{mesh as names, ArtifactKind};
use serde::Serialize;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::labels::Labels;
use super::shared::LazyPhysics;
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5Out;
use crate::io::xdmf::write_mesh_xdmf;

/// The mesh artifact's key: the whole model specification (geometry, mesh sizes, materials —
/// the materials are not used by the mesh but by everything keyed on it downstream).
#[derive(Debug, Serialize)]
#[serde(transparent)]
struct MeshKey<'a>(&'a crom_schemas::scene::Model);

impl StageKey for MeshKey<'_> {
    const KIND: ArtifactKind = ArtifactKind::MESH;
    /// Bump when the mesh generators change their output.
    const ALGORITHM_VERSION: u32 = 1;
}

/// The mesh artifact's key spec.
pub(crate) fn spec(scene: &crom_schemas::SceneConfig) -> KeySpec {
    KeySpec::of(&MeshKey(&scene.model))
}

/// The mesh stage: the scene's model (its key spec), no input.
#[derive(Debug)]
pub(crate) struct MeshStage {
    pub spec: KeySpec,
    pub labels: Labels,
}

impl MeshStage {
    pub(crate) fn plan(scene: &crom_schemas::SceneConfig) -> Self {
        Self { spec: spec(scene), labels: Labels::of(scene) }
    }
}

impl StageDef for MeshStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::MESH
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        Vec::new()
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file("mesh.h5", names::FILE), Published::file("mesh.xdmf", names::XDMF)]
    }

    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        run(ctx, &mut shared.physics, &self.spec, &self.labels)
    }
}

/// The mesh of the model `physics` builds, keyed `spec`; `physics` is built from the scene's
/// model, which is the key.
pub(crate) fn run(
    ctx: &mut Ctx<'_>,
    physics: &mut LazyPhysics<'_>,
    spec: &KeySpec,
    labels: &Labels,
) -> Result<Key, CromError> {
    let key = spec.key();
    let scene = &labels.scene;
    ctx.single(ArtifactKind::MESH, "mesh", spec, |staging| {
        let phys = physics.get_with_condition()?;
        let m = phys.mesh();
        let condition = phys.operator().stiffness_condition();
        let path = staging.path(names::FILE);
        let f = H5Out::create(&path)?;
        f.attr_str("scene", scene)?;
        f.attr_str("kind", "mesh")?;
        f.attr_u64("schema_version", u64::from(ArtifactKind::MESH.schema_version()))?;
        f.attr_str("cache_key", &key.0)?;
        f.attr_u64("dofs_per_node", m.dofs_per_node as u64)?;
        if let Some(c) = condition {
            f.attr_f64(names::STIFFNESS_LAMBDA_MAX, c.lambda_max)?;
            f.attr_f64(names::STIFFNESS_LAMBDA_MIN, c.lambda_min)?;
            f.attr_f64(names::STIFFNESS_CONDITION, c.ratio())?;
        }
        let flat: Vec<f64> = m.nodes.iter().flat_map(|p| p[..m.dim].iter().copied()).collect();
        f.table_f64(names::NODES, m.nodes.len(), m.dim, &flat, "length")?;
        let cells: Vec<u64> = m.cells.iter().flatten().copied().collect();
        f.table_u64(names::CELLS, m.cells.len(), m.nodes_per_cell, &cells)?;
        f.vec_u64(names::CONTACT_NODES, &m.contact_nodes)?;
        f.vec_u64(names::NODE_BODY, &m.node_body)?;
        f.vec_u64(names::CELL_BODY, &m.cell_body)?;
        drop(f);
        write_mesh_xdmf(
            &staging.path(names::XDMF),
            names::FILE,
            (m.nodes.len(), m.dim),
            m.cells.len(),
            m.nodes_per_cell,
            &[names::CELL_BODY],
        )?;
        Ok(BTreeMap::from([
            ("nodes".to_string(), json!(m.nodes.len())),
            ("cells".to_string(), json!(m.cells.len())),
            ("contact_nodes".to_string(), json!(m.contact_nodes.len())),
        ]))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_key_keeps_the_layout_existing_stores_were_keyed_with() {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/hertz.toml"))
            .expect("hertz.toml");
        let scene = crom_schemas::SceneConfig::from_toml_str(&text, std::path::Path::new("hertz.toml")).expect("scene");
        let before = KeySpec::new(ArtifactKind::MESH, 1, crate::cache::params(&scene.model)).key();
        assert_eq!(KeySpec::of(&MeshKey(&scene.model)).key(), before);
    }

    /// Full integration is the default and stays out of the key: a scene that says so has the
    /// key it had before the setting existed; selective integration is a different mesh key.
    #[test]
    fn the_integration_setting_keys_only_when_it_changes_something() {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/hertz.toml"))
            .expect("hertz.toml");
        let parse =
            |t: &str| crom_schemas::SceneConfig::from_toml_str(t, std::path::Path::new("h.toml")).expect("scene");
        let key = |t: &str| KeySpec::of(&MeshKey(&parse(t).model)).key();
        let shipped = "material = { young = 1.0, poisson = 0.3 }";
        assert!(text.contains(shipped), "hertz.toml changed: update this test");
        let full = text.replace(shipped, "material = { young = 1.0, poisson = 0.3, integration = \"full\" }");
        let sri = text.replace(shipped, "material = { young = 1.0, poisson = 0.3, integration = \"selective\" }");
        assert_eq!(key(&full), key(&text));
        assert_ne!(key(&sri), key(&text));
    }
}
