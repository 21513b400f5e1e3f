//! From a scene file to a ready-to-solve high-fidelity model: the mesh description for the mesh
//! artifact and a thread-safe `solve(parameter)` for the snapshot stage. Everything costly and
//! parameter-independent (e.g. the factorisation of K) is done once, in [`Physics::build`].

use crom_schemas::scene::Model;
use crom_schemas::SceneConfig;
use crom_stages::contact::{build_hertz, build_ironing, ContactSolveParams, FactoredModel, HertzParams, IroningParams};
use crom_stages::contact3d::{build_hertz3d, build_ironing3d, Factored3d, Hertz3dParams, Ironing3dParams};
use crom_stages::rom::ContactOperator;
use crom_stages::rope::{self, Rope, RopeParams, RopeSolveParams};
use crom_stages::snapshot::Snapshot;

/// The discretisation as stored in the mesh artifact.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshData {
    /// Coordinates per node: 2 (`(x, y)`; 1-D meshes have `y = 0`) or 3.
    pub dim: usize,
    /// Node coordinates, the first `dim` of each used (the rest 0).
    pub nodes: Vec<[f64; 3]>,
    /// Cells, `nodes_per_cell` node ids each.
    pub cells: Vec<Vec<u64>>,
    /// 2 (line), 4 (quad) or 8 (hexahedron).
    pub nodes_per_cell: usize,
    /// Potential-contact nodes, in the order of the dual field.
    pub contact_nodes: Vec<u64>,
    /// Body id of each node.
    pub node_body: Vec<u64>,
    /// Body id of each cell.
    pub cell_body: Vec<u64>,
    /// Degrees of freedom per node.
    pub dofs_per_node: usize,
}

/// A scene's high-fidelity model, ready to solve at any parameter value.
pub enum Physics {
    /// The rope (1-D obstacle problem).
    Rope(Rope, RopeSolveParams),
    /// A 2-D two-body contact problem (hertz, ironing), factored once.
    Contact(Box<FactoredModel>, ContactSolveParams),
    /// A 3-D two-body contact problem (hertz3d, ironing3d), factored once.
    Contact3d(Box<Factored3d>, ContactSolveParams),
}

impl std::fmt::Debug for Physics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Physics::Rope(r, _) => write!(f, "Physics::Rope({} nodes)", r.n_nodes()),
            Physics::Contact(m, _) => write!(f, "Physics::Contact({} dofs)", m.model().n_dof()),
            Physics::Contact3d(m, _) => write!(f, "Physics::Contact3d({} dofs)", m.model().n_dof()),
        }
    }
}

/// Units of the stored fields, per model.
#[derive(Debug, Clone, Copy)]
pub struct Units {
    /// Primal field.
    pub primal: &'static str,
    /// Dual field.
    pub dual: &'static str,
}

impl Physics {
    /// Build the model of a validated scene (meshing, assembly and factorisation happen here).
    /// The stiffness's condition estimate is computed on its first read.
    pub fn build(scene: &SceneConfig) -> Result<Self, String> {
        Self::build_with(scene, false)
    }

    /// [`Self::build`] for the mesh artifact, which states the stiffness's condition estimate:
    /// a 2-D contact model computes it beside its Delassus operator
    /// (`ContactModel::factor_with_condition`).
    pub fn build_with_condition(scene: &SceneConfig) -> Result<Self, String> {
        Self::build_with(scene, true)
    }

    fn build_with(scene: &SceneConfig, with_condition: bool) -> Result<Self, String> {
        match &scene.model {
            Model::Rope(r) => Ok(Physics::Rope(
                Rope::new(RopeParams::from(r)),
                RopeSolveParams { rel_tol: scene.solver.rel_tol, max_iter: scene.solver.max_iter },
            )),
            Model::Hertz(h) => contact(build_hertz(&HertzParams::from(h)), scene, with_condition),
            Model::Ironing(i) => contact(build_ironing(&IroningParams::from(i)), scene, with_condition),
            Model::Hertz3d(h) => contact3d(build_hertz3d(&Hertz3dParams::from(h)), scene),
            Model::Ironing3d(i) => contact3d(build_ironing3d(&Ironing3dParams::from(i)), scene),
            Model::External(_) => {
                Err("an external scene has no full-order model (its snapshots come from files)".to_string())
            }
        }
    }

    /// Units of the primal and dual fields.
    pub fn units(&self) -> Units {
        match self {
            Physics::Rope(..) => {
                Units { primal: "length (vertical displacement)", dual: "force per unit length (contact pressure)" }
            }
            Physics::Contact(..) => Units {
                primal: "length (displacement, (ux, uy) interleaved per node, both bodies)",
                dual: "force per unit length (contact pressure at the slave nodes)",
            },
            Physics::Contact3d(..) => Units {
                primal: "length (displacement, (ux, uy, uz) interleaved per node, both bodies)",
                dual: "force per unit area (contact pressure at the slave nodes)",
            },
        }
    }

    /// The mesh artifact's content.
    pub fn mesh(&self) -> MeshData {
        match self {
            Physics::Rope(r, _) => {
                let n = r.n_nodes();
                MeshData {
                    dim: 2,
                    nodes: r.x.iter().map(|&x| [x, 0.0, 0.0]).collect(),
                    cells: (0..n as u64 - 1).map(|i| vec![i, i + 1]).collect(),
                    nodes_per_cell: 2,
                    contact_nodes: (0..n as u64).collect(),
                    node_body: vec![0; n],
                    cell_body: vec![0; n - 1],
                    dofs_per_node: 1,
                }
            }
            Physics::Contact(f, _) => {
                let model = f.model();
                let m = model.mesh();
                MeshData {
                    dim: 2,
                    nodes: m.nodes.iter().map(|p| [p[0], p[1], 0.0]).collect(),
                    cells: m.quads.iter().map(|q| q.iter().map(|&i| i as u64).collect()).collect(),
                    nodes_per_cell: 4,
                    contact_nodes: model.slave_nodes().iter().map(|&i| i as u64).collect(),
                    node_body: m.node_body.iter().map(|&b| b as u64).collect(),
                    cell_body: m.element_body.iter().map(|&b| b as u64).collect(),
                    dofs_per_node: 2,
                }
            }
            Physics::Contact3d(f, _) => {
                let model = f.model();
                let m = model.mesh();
                MeshData {
                    dim: 3,
                    nodes: m.nodes.clone(),
                    cells: m.hexes.iter().map(|h| h.iter().map(|&i| i as u64).collect()).collect(),
                    nodes_per_cell: 8,
                    contact_nodes: model.slave_nodes().iter().map(|&i| i as u64).collect(),
                    node_body: m.node_body.iter().map(|&b| b as u64).collect(),
                    cell_body: m.element_body.iter().map(|&b| b as u64).collect(),
                    dofs_per_node: 3,
                }
            }
        }
    }

    /// The model as the online reduced solve sees it.
    pub fn operator(&self) -> &dyn ContactOperator {
        match self {
            Physics::Rope(r, _) => r,
            Physics::Contact(f, _) => f.as_ref(),
            Physics::Contact3d(f, _) => f.as_ref(),
        }
    }

    /// Rows of the primal and dual fields (n_dof, n_contact).
    pub fn mesh_rows(&self) -> (usize, usize) {
        match self {
            Physics::Rope(r, _) => (r.n_nodes(), r.n_nodes()),
            Physics::Contact(f, _) => (f.model().n_dof(), f.model().slave_nodes().len()),
            Physics::Contact3d(f, _) => (f.model().n_dof(), f.model().slave_nodes().len()),
        }
    }

    /// Solve at one parameter point (one value per component of the scene's parameter).
    pub fn solve(&self, mu: &[f64]) -> Result<Snapshot, String> {
        match self {
            Physics::Rope(r, p) => match mu {
                [gamma] => rope::solve(r, *gamma, p).map_err(|e| e.to_string()),
                _ => Err(format!("the rope has one parameter, got {}", mu.len())),
            },
            Physics::Contact(f, p) => f.solve(mu, p).map_err(|e| e.to_string()),
            Physics::Contact3d(f, p) => f.solve(mu, p).map_err(|e| e.to_string()),
        }
    }
}

/// The checks of a 3-D model that need its mesh but not its stiffness — every element's
/// Jacobian, the contact region holding a slave, every symmetry plane holding nodes and no body
/// left free in a rigid motion — made when the scene is loaded, before anything is written: a
/// failure is the scene file's (exit 2, naming the field). Nothing for other models (their
/// validation covers them).
pub fn check_geometry(scene: &SceneConfig, path: &std::path::Path) -> Result<(), crate::error::CromError> {
    use crom_stages::contact::ModelError;
    let (kind, checked) = match &scene.model {
        Model::Hertz3d(h) => ("hertz3d", crom_stages::contact3d::check_hertz3d(&Hertz3dParams::from(h))),
        Model::Ironing3d(i) => ("ironing3d", crom_stages::contact3d::check_ironing3d(&Ironing3dParams::from(i))),
        _ => return Ok(()),
    };
    let Err(e) = checked else { return Ok(()) };
    let (field, fix) = match &e {
        ModelError::BadParameter { field: "symmetry", .. } => (
            format!("model.{kind}.symmetry"),
            "declare the symmetry planes of the model (hertz3d: x = 0 and y = 0; ironing3d: y = 0), each through nodes of the mesh",
        ),
        ModelError::BadParameter { field: "slaves", .. } => (
            format!("model.{kind}.{}", if kind == "hertz3d" { "contact_radius" } else { "slaves" }),
            "enlarge the contact region so that it holds slave nodes",
        ),
        ModelError::BadParameter { field, .. } => (format!("model.{kind}.{field}"), "change this value"),
        _ => (format!("model.{kind}"), "check the model's sizes"),
    };
    let problem = match e {
        ModelError::BadParameter { msg, .. } => msg,
        other => other.to_string(),
    };
    Err(crate::error::CromError::Scene(crom_schemas::SceneError::Invalid {
        path: path.to_path_buf(),
        field,
        problem,
        fix: fix.to_string(),
    }))
}

fn contact3d(
    built: Result<crom_stages::contact3d::Model3d, crom_stages::contact::ModelError>,
    scene: &SceneConfig,
) -> Result<Physics, String> {
    let factored = built.and_then(|m| m.factor()).map_err(|e| e.to_string())?;
    let params = ContactSolveParams { rel_tol: scene.solver.rel_tol, max_iter: scene.solver.max_iter };
    Ok(Physics::Contact3d(Box::new(factored), params))
}

fn contact(
    built: Result<crom_stages::contact::ContactModel, crom_stages::contact::ModelError>,
    scene: &SceneConfig,
    with_condition: bool,
) -> Result<Physics, String> {
    let factor =
        |m: crom_stages::contact::ContactModel| if with_condition { m.factor_with_condition() } else { m.factor() };
    let factored = built.and_then(factor).map_err(|e| e.to_string())?;
    let params = ContactSolveParams { rel_tol: scene.solver.rel_tol, max_iter: scene.solver.max_iter };
    Ok(Physics::Contact(Box::new(factored), params))
}
