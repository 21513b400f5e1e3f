//! Mesh stage of an external scene with `model.external.mesh`: the mesh read when the scene was
//! loaded ([`crate::external_mesh`]) written as a mesh artifact in the native layout
//! (`mesh.h5` + `mesh.xdmf`), so the views and the report read it as they read a native mesh.
//!
//! `nodes` is `(n_nodes, 2)` (1-D and 2-D meshes, a 1-D mesh with y = 0) or `(n_nodes, 3)`;
//! `contact_nodes` is the map from dual entries to nodes (`dual_nodes`); every node and cell is
//! body 0; the attribute `dofs_per_node` says how the primal column is laid out (node-major; 0
//! without primal snapshots) and `source = "external"` marks it. No stiffness estimate: there is
//! no operator.

use std::collections::BTreeMap;

use crom_schemas::artifact::{mesh as names, ArtifactKind};
use crom_schemas::external::ResolvedMesh;
use serde::Serialize;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5Out;
use crate::io::xdmf::write_mesh_xdmf;

/// The key of an external mesh: the blake3 of its contents.
#[derive(Debug, Serialize)]
struct ExternalMeshKey<'a> {
    source: &'static str,
    digest: &'a str,
}

impl StageKey for ExternalMeshKey<'_> {
    const KIND: ArtifactKind = ArtifactKind::MESH;
    /// Bump when the artifact's layout changes.
    const ALGORITHM_VERSION: u32 = 1;
}

/// The mesh artifact of an external scene.
#[derive(Debug)]
pub(crate) struct ExternalMeshStage {
    spec: KeySpec,
    mesh: ResolvedMesh,
    scene: String,
}

impl ExternalMeshStage {
    /// The mesh stage of `scene`, if it is external with a resolved mesh.
    pub(crate) fn plan(scene: &crom_schemas::SceneConfig) -> Option<Self> {
        let mesh = scene.model.external()?.resolved.as_ref()?.mesh.clone()?;
        let spec = KeySpec::of(&ExternalMeshKey { source: "external", digest: &mesh.digest });
        Some(Self { spec, mesh, scene: scene.scene.name.clone() })
    }
}

impl StageDef for ExternalMeshStage {
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

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        let key = self.spec.key();
        let m = &self.mesh;
        ctx.single(ArtifactKind::MESH, "mesh", &self.spec, |staging| {
            let (n_nodes, n_cells) = (m.n_nodes(), m.n_cells());
            let dim = m.dim.max(2);
            let f = H5Out::create(&staging.path(names::FILE))?;
            f.attr_str("scene", &self.scene)?;
            f.attr_str("kind", "mesh")?;
            f.attr_str("source", "external")?;
            f.attr_u64("schema_version", u64::from(ArtifactKind::MESH.schema_version()))?;
            f.attr_str("cache_key", &key.0)?;
            f.attr_u64("dofs_per_node", m.dofs_per_node as u64)?;
            let nodes: Vec<f64> = (0..n_nodes)
                .flat_map(|i| (0..dim).map(move |c| if c < m.dim { m.nodes[i * m.dim + c] } else { 0.0 }))
                .collect();
            f.table_f64(names::NODES, n_nodes, dim, &nodes, "1")?;
            f.table_u64(names::CELLS, n_cells, m.nodes_per_cell, &m.cells)?;
            f.vec_u64(names::CONTACT_NODES, &m.dual_nodes)?;
            f.vec_u64(names::NODE_BODY, &vec![0; n_nodes])?;
            f.vec_u64(names::CELL_BODY, &vec![0; n_cells])?;
            drop(f);
            let xdmf = staging.path(names::XDMF);
            write_mesh_xdmf(&xdmf, names::FILE, (n_nodes, dim), n_cells, m.nodes_per_cell, &[names::CELL_BODY])?;
            Ok(BTreeMap::from([
                ("nodes".to_string(), json!(n_nodes)),
                ("cells".to_string(), json!(n_cells)),
                ("contact_nodes".to_string(), json!(m.dual_nodes.len())),
            ]))
        })
    }
}
