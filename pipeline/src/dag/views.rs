//! Views stage: a snapshot set or a basis as an XDMF temporal collection that ParaView opens —
//! scrub through the sweep with the time slider, *Warp By Vector* on `displacement`, colour by
//! `pressure`.
//!
//! Nothing is copied: each step's `displacement` (n_nodes x 3) and `pressure` (n_nodes) in
//! `views.h5` are HDF5 virtual datasets whose pieces are hyperslabs of the stored columns —
//! component c of node i is row `c + i * dofs_per_node` of a primal column; the
//! pressure of contact node k is row k of a dual column, placed at node `contact_nodes[k]`
//! (one piece per run of consecutive contact nodes); unmapped elements (the z component, nodes
//! off the contact surface, the x component of the rope's vertical deflection) read as the fill
//! value 0. Each step is its own dataset because meshio's `TimeSeriesReader`, like most XDMF
//! readers, reads whole datasets only. The parameter enters as the step's time (scalar
//! parameters: the value; vector parameters: the step index) and as one point field per
//! component, constant over the nodes (a dataset of no stored chunk whose fill value is the value),
//! since ParaView colours by point fields. The views of a basis have one step per mode (time =
//! mode number): primal POD modes as `displacement`, dual POD and CPG generators as `pressure`
//! on the contact surface (the truncated CPG basis is a prefix of the full one and is not
//! repeated). The views of the online solutions have one step per test point: the reduced
//! model's fields and their errors (stored by the rom stage in `online.h5`) beside the
//! full-order fields (virtual, onto the snapshot columns) and a `converged` flag.

use std::collections::BTreeMap;

use crom_schemas::artifact::{basis as basis_names, mesh as mesh_names, rom as rom_names, trainset as set_names};
use crom_schemas::artifact::{views as names, ArtifactKind};
use serde::Serialize;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Placement, Published, StageDef};
use super::labels::Labels;
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::{H5In, H5Out, VirtualPiece};
use crate::io::xdmf::{series_xdmf, SeriesAttribute, SeriesMesh, SeriesStep};
use crate::store::Staging;

/// What a view shows (its inputs' keys say of what).
#[derive(Debug, Serialize)]
struct ViewsKey<'a> {
    /// `set`, `basis` or `online`.
    subject: &'static str,
    /// The set's name, for a set.
    #[serde(skip_serializing_if = "Option::is_none")]
    set: Option<&'a str>,
}

impl StageKey for ViewsKey<'_> {
    const KIND: ArtifactKind = ArtifactKind::VIEWS;
    /// Bump when the layout of the views changes (2: the per-step constants stored as fill
    /// values, no chunk written; the same values read).
    const ALGORITHM_VERSION: u32 = 2;
}

/// Every views file sits two directories below the store root (`views/<key>/`, and the staging
/// directory alike), so `../../` reaches the root from either.
const ROOT: &str = "../../";

/// What the views need to know about the mesh.
struct MeshFacts {
    ref_path: String,
    n_nodes: usize,
    n_cells: usize,
    nodes_per_cell: usize,
    /// Coordinates per node in the mesh file (2 or 3).
    dim: usize,
    /// Primal entries per node (0: an external scene without primal snapshots).
    dofs_per_node: usize,
    /// Runs of consecutive contact nodes: (first node, first contact index, length).
    contact_runs: Vec<(usize, usize, usize)>,
}

fn mesh_facts(ctx: &Ctx<'_>, mesh: &Key) -> Result<MeshFacts, CromError> {
    let path = ctx.store.dir(ArtifactKind::MESH, mesh).join(mesh_names::FILE);
    let f = H5In::open(&path)?;
    let node_shape = f.shape(mesh_names::NODES)?;
    let n_nodes = node_shape.first().copied().unwrap_or(0);
    let cells = f.shape(mesh_names::CELLS)?;
    let contact = f.vec_u64(mesh_names::CONTACT_NODES)?;
    let mut contact_runs: Vec<(usize, usize, usize)> = Vec::new();
    for (k, &node) in contact.iter().enumerate() {
        let node = node as usize;
        match contact_runs.last_mut() {
            Some(r) if r.0 + r.2 == node && r.1 + r.2 == k => r.2 += 1,
            _ => contact_runs.push((node, k, 1)),
        }
    }
    Ok(MeshFacts {
        ref_path: format!("{ROOT}{}/{}/{}", ArtifactKind::MESH.name(), mesh.0, mesh_names::FILE),
        n_nodes,
        n_cells: cells.first().copied().unwrap_or(0),
        nodes_per_cell: cells.get(1).copied().unwrap_or(4),
        dim: node_shape.get(1).copied().unwrap_or(2),
        dofs_per_node: f.attr_u64("dofs_per_node")? as usize,
        contact_runs,
    })
}

/// Column `col` of a stored `(rows x cols)` matrix `dataset` in `file` (relative to views.h5).
struct Column {
    file: String,
    dataset: String,
    shape: (usize, usize),
    col: usize,
}

/// How a stored column is shown: a primal column as a displacement vector, a dual column as
/// a pressure scalar on the contact nodes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Shape {
    Displacement,
    Pressure,
}

/// One step: its name, time, fields (name, how, source) and constant fields (parameter values,
/// flags).
struct Step {
    name: String,
    time: f64,
    fields: Vec<(String, Shape, Column)>,
    constants: Vec<(String, f64)>,
}

/// Write the step datasets into the group `steps` of `h5` (whose path in `views.h5` is
/// `path`) and return the XDMF steps.
fn write_steps(h5: &H5Out, path: &str, mesh: &MeshFacts, steps: &[Step]) -> Result<Vec<SeriesStep>, CromError> {
    let group = h5.group(names::STEPS)?;
    let n = mesh.n_nodes;
    let mut out = Vec::with_capacity(steps.len());
    for (j, s) in steps.iter().enumerate() {
        let label = format!("{j:05}");
        let g = group.group(&label)?;
        let at = |field: &str| format!("{}:/{path}{}/{label}/{field}", names::FILE, names::STEPS);
        let mut attributes = Vec::new();
        for (field, shape, c) in &s.fields {
            match shape {
                Shape::Displacement if mesh.dofs_per_node == 0 => {}
                Shape::Displacement => {
                    // One piece: the whole column, in dof order `dofs_per_node * node +
                    // component`, is the row-major order of the (n_nodes x dofs_per_node) block
                    // of the view, so both selections are plain hyperslabs (strided source
                    // selections make HDF5's virtual datasets read element by element: seconds
                    // per step instead of milliseconds). The rope's one dof per node is its
                    // vertical deflection: the y column; one dof per node of a surface or
                    // volume mesh (an external scene's membrane, say) is the z column.
                    let first = match (mesh.dofs_per_node, mesh.nodes_per_cell) {
                        (1, 2) => 1,
                        (1, _) => 2,
                        _ => 0,
                    };
                    let pieces = [VirtualPiece {
                        file: c.file.clone(),
                        dataset: c.dataset.clone(),
                        source_shape: vec![c.shape.0, c.shape.1],
                        source: vec![(0, 1, n * mesh.dofs_per_node), (c.col, 1, 1)],
                        target: vec![(0, 1, n), (first, 1, mesh.dofs_per_node)],
                    }];
                    g.virtual_dataset(field, &[n, 3], &pieces)?;
                    attributes.push(attr(field, "Vector", "Node", vec![n, 3], "Float", at(field)));
                }
                Shape::Pressure => {
                    let pieces: Vec<VirtualPiece> = mesh
                        .contact_runs
                        .iter()
                        .map(|&(node, k, len)| VirtualPiece {
                            file: c.file.clone(),
                            dataset: c.dataset.clone(),
                            source_shape: vec![c.shape.0, c.shape.1],
                            source: vec![(k, 1, len), (c.col, 1, 1)],
                            target: vec![(node, 1, len)],
                        })
                        .collect();
                    g.virtual_dataset(field, &[n], &pieces)?;
                    attributes.push(attr(field, "Scalar", "Node", vec![n], "Float", at(field)));
                }
            }
        }
        for (name, value) in &s.constants {
            g.constant_f64(name, n, *value, "constant over the nodes: a value of this step")?;
            attributes.push(attr(name, "Scalar", "Node", vec![n], "Float", at(name)));
        }
        let m = &mesh.ref_path;
        attributes.push(attr(
            "node_body",
            "Scalar",
            "Node",
            vec![n],
            "UInt",
            format!("{m}:/{}", mesh_names::NODE_BODY),
        ));
        let cells = vec![mesh.n_cells];
        attributes.push(attr("cell_body", "Scalar", "Cell", cells, "UInt", format!("{m}:/{}", mesh_names::CELL_BODY)));
        out.push(SeriesStep { name: s.name.clone(), time: s.time, attributes });
    }
    Ok(out)
}

fn attr(
    name: &str,
    kind: &'static str,
    center: &'static str,
    dims: Vec<usize>,
    number: &'static str,
    r: String,
) -> SeriesAttribute {
    SeriesAttribute { name: name.to_string(), kind, center, dims, number, reference: r }
}

fn series_mesh(mesh: &MeshFacts) -> SeriesMesh {
    SeriesMesh {
        mesh_ref: mesh.ref_path.clone(),
        n_nodes: mesh.n_nodes,
        n_cells: mesh.n_cells,
        nodes_per_cell: mesh.nodes_per_cell,
        dim: mesh.dim,
    }
}

/// One step per column of a stored set (its `solver_stats.parquet` rows): `displacement` and
/// `pressure` onto the set's snapshot columns, the parameter components as constants, the
/// parameter value as time when it is a scalar increasing over the steps (else the step index).
fn set_steps(
    root: &std::path::Path,
    stats: &std::path::Path,
    names_of: &[String],
    (n_dof, n_contact): (usize, usize),
) -> Result<Vec<Step>, CromError> {
    let rows = super::inputs::sets::rows_of(stats)?;
    let widths = super::inputs::sets::block_columns(root, &rows)?;
    let scalar = names_of.len() == 1;
    let increasing = rows.windows(2).all(|w| w[0].parameters[0] < w[1].parameters[0]);
    Ok(rows
        .iter()
        .enumerate()
        .map(|(j, r)| {
            let width = widths.get(&r.block).copied().unwrap_or(0);
            let column = |dataset: &str, rows: usize| Column {
                file: format!("{ROOT}{}", r.block),
                dataset: dataset.to_string(),
                shape: (rows, width),
                col: r.column,
            };
            let parameters: Vec<(String, f64)> = names_of.iter().cloned().zip(r.parameters.iter().copied()).collect();
            let label: Vec<String> = parameters.iter().map(|(n, v)| format!("{n}={v}")).collect();
            Step {
                name: label.join(","),
                time: if scalar && increasing { r.parameters[0] } else { j as f64 },
                fields: vec![
                    (names::DISPLACEMENT.to_string(), Shape::Displacement, column("primal", n_dof)),
                    (names::PRESSURE.to_string(), Shape::Pressure, column("dual", n_contact)),
                ],
                constants: parameters,
            }
        })
        .collect())
}

/// Write `views.h5` (with the attribute `about`) and the XDMF `xdmf` of the temporal
/// collection `name` into the staging directory.
fn write_series(
    staging: &Staging,
    about: (&str, &str),
    mesh: &MeshFacts,
    steps: &[Step],
    xdmf: &str,
    name: &str,
) -> Result<BTreeMap<String, serde_json::Value>, CromError> {
    let h5 = H5Out::create(&staging.path(names::FILE))?;
    h5.attr_str("kind", "views")?;
    h5.attr_str(about.0, about.1)?;
    h5.attr_str("cache_key", &staging.key().0)?;
    let series = write_steps(&h5, "", mesh, steps)?;
    drop(h5);
    let path = staging.path(xdmf);
    std::fs::write(&path, series_xdmf(name, &series_mesh(mesh), &series))
        .map_err(|e| CromError::io(&path, "writing an XDMF file", e))?;
    Ok(BTreeMap::from([("steps".to_string(), json!(steps.len()))]))
}

/// Key spec of the views of the snapshot set `set` stored as `set_key`.
fn set_spec(set: &str, set_key: &Key, mesh: &Key) -> KeySpec {
    KeySpec::of(&ViewsKey { subject: "set", set: Some(set) }).input("set", set_key).input("mesh", mesh)
}

/// Key spec of the views of the basis artifact `basis`.
fn basis_spec(basis: &Key, mesh: &Key) -> KeySpec {
    KeySpec::of(&ViewsKey { subject: "basis", set: None }).input("basis", basis).input("mesh", mesh)
}

/// Key spec of the views of the online solutions.
fn online_spec(rom: &Key, test: &Key, mesh: &Key) -> KeySpec {
    KeySpec::of(&ViewsKey { subject: "online", set: None }).input("rom", rom).input("test", test).input("mesh", mesh)
}

/// What a views stage shows.
#[derive(Debug)]
pub(crate) enum Subject {
    /// The snapshot set `set` (its node is the input `of`).
    Set { set: String, of: Input },
    /// The bases (the input `of`).
    Basis { of: Input },
    /// The online solutions of the rom `of` at the points of the test set `test`.
    Online { of: Input, test: Input },
}

/// The views (XDMF over stored columns) of a subject on the mesh: run beside the main loop.
#[derive(Debug)]
pub(crate) struct ViewsStage {
    pub spec: KeySpec,
    pub subject: Subject,
    pub mesh: Input,
    /// The parameter's component names, in the steps' attributes.
    pub names: Vec<String>,
}

impl ViewsStage {
    /// The views of `subject` on `mesh`.
    pub(crate) fn plan(subject: Subject, mesh: Input, labels: &Labels) -> Self {
        let spec = match &subject {
            Subject::Set { set, of } => set_spec(set, &of.key, &mesh.key),
            Subject::Basis { of } => basis_spec(&of.key, &mesh.key),
            Subject::Online { of, test } => online_spec(&of.key, &test.key, &mesh.key),
        };
        Self { spec, subject, mesh, names: labels.names.clone() }
    }
}

impl StageDef for ViewsStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::VIEWS
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        match &self.subject {
            Subject::Set { of, .. } | Subject::Basis { of } => vec![of, &self.mesh],
            Subject::Online { of, test } => vec![of, test, &self.mesh],
        }
    }
    fn placement(&self) -> Placement {
        Placement::Beside
    }
    /// `train.xdmf`, `basis/<group>.xdmf`, `online.xdmf`, `nested/level-K.xdmf`.
    fn published(&self) -> Vec<Published> {
        let nested = crom_schemas::artifact::published::NESTED_DIR;
        match &self.subject {
            Subject::Basis { .. } => BASIS_VIEWS
                .iter()
                .map(|(g, _)| Published::xdmf(format!("basis/{g}.xdmf"), &format!("{g}.xdmf")))
                .collect(),
            Subject::Online { .. } => vec![Published::xdmf("online.xdmf", names::ONLINE_XDMF)],
            Subject::Set { set, .. } => match set.strip_prefix("nested-") {
                Some(level) => vec![Published::xdmf(format!("{nested}/level-{level}.xdmf"), names::SET_XDMF)],
                None => vec![Published::xdmf(format!("{set}.xdmf"), names::SET_XDMF)],
            },
        }
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        let mesh = &self.mesh.key;
        match &self.subject {
            Subject::Set { set: name, of } => set(ctx, &self.spec, (name, &self.names), &of.key, mesh),
            Subject::Basis { of } => basis(ctx, &self.spec, &of.key, mesh),
            Subject::Online { of, test } => online(ctx, &self.spec, &of.key, (&test.key, &self.names), mesh),
        }
    }
}

/// The views of the snapshot set `set` (train, test, nested-k) stored as `set_key`.
fn set(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    (set, names_of): (&str, &[String]),
    set_key: &Key,
    mesh: &Key,
) -> Result<Key, CromError> {
    let root = ctx.store.root().to_path_buf();
    let stats = ctx.store.dir(ArtifactKind::TRAINING_SET, set_key).join(set_names::STATS);
    let mesh_facts = mesh_facts(ctx, mesh)?;
    let shape = super::inputs::sets::set_shape(ctx.store, set_key, &super::inputs::sets::rows_of(&stats)?)?;
    ctx.single(ArtifactKind::VIEWS, "views", spec, |staging| {
        let steps = set_steps(&root, &stats, names_of, shape)?;
        write_series(staging, ("set", set), &mesh_facts, &steps, names::SET_XDMF, set)
    })
}

/// The basis groups that get a view: (group, XDMF file, primal?).
pub(crate) const BASIS_VIEWS: [(&str, bool); 3] =
    [(basis_names::PRIMAL_POD, true), (basis_names::DUAL_POD, false), (basis_names::DUAL_CPG, false)];

/// The views of the basis artifact `basis`: one XDMF per group of [`BASIS_VIEWS`].
fn basis(ctx: &mut Ctx<'_>, spec: &KeySpec, basis: &Key, mesh: &Key) -> Result<Key, CromError> {
    let mesh_facts = mesh_facts(ctx, mesh)?;
    let basis_file = ctx.store.dir(ArtifactKind::BASIS, basis).join(basis_names::FILE);
    ctx.single(ArtifactKind::VIEWS, "views", spec, |staging| {
        let f = H5In::open(&basis_file)?;
        let h5 = H5Out::create(&staging.path(names::FILE))?;
        h5.attr_str("kind", "views")?;
        h5.attr_str("basis", &basis.0)?;
        h5.attr_str("cache_key", &staging.key().0)?;
        let mut summary = BTreeMap::new();
        for (group, primal) in BASIS_VIEWS {
            let dataset = format!("{group}/{}", basis_names::MODES);
            let shape = f.shape(&dataset)?;
            let (rows, modes) = (shape.first().copied().unwrap_or(0), shape.get(1).copied().unwrap_or(0));
            let steps: Vec<Step> = (0..modes)
                .map(|k| {
                    let c = Column {
                        file: format!("{ROOT}{}/{}/{}", ArtifactKind::BASIS.name(), basis.0, basis_names::FILE),
                        dataset: dataset.clone(),
                        shape: (rows, modes),
                        col: k,
                    };
                    let field = if primal {
                        (names::DISPLACEMENT.to_string(), Shape::Displacement, c)
                    } else {
                        (names::PRESSURE.to_string(), Shape::Pressure, c)
                    };
                    Step {
                        name: format!("mode {}", k + 1),
                        time: (k + 1) as f64,
                        fields: vec![field],
                        constants: vec![],
                    }
                })
                .collect();
            let series = write_steps(&h5.group(group)?, &format!("{group}/"), &mesh_facts, &steps)?;
            let xdmf = staging.path(&format!("{group}.xdmf"));
            std::fs::write(&xdmf, series_xdmf(group, &series_mesh(&mesh_facts), &series))
                .map_err(|e| CromError::io(&xdmf, "writing an XDMF file", e))?;
            summary.insert(format!("{group}_modes"), json!(modes));
        }
        Ok(summary)
    })
}

/// The views of the online solutions (`online.h5` of the rom artifact `rom`) at the points of
/// the test set `test`: per test point the online fields, their errors and the full-order
/// fields (onto the snapshot columns), the parameter and whether the query converged.
fn online(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    rom: &Key,
    (test, names_of): (&Key, &[String]),
    mesh: &Key,
) -> Result<Key, CromError> {
    let root = ctx.store.root().to_path_buf();
    let mesh_facts = mesh_facts(ctx, mesh)?;
    let stats = ctx.store.dir(ArtifactKind::TRAINING_SET, test).join(set_names::STATS);
    let online_file = ctx.store.dir(ArtifactKind::ROM, rom).join(rom_names::ONLINE);
    ctx.single(ArtifactKind::VIEWS, "views", spec, |staging| {
        let f = H5In::open(&online_file)?;
        let (n_dof, k) = {
            let s = f.shape("primal")?;
            (s.first().copied().unwrap_or(0), s.get(1).copied().unwrap_or(0))
        };
        let n_contact = f.shape("dual")?.first().copied().unwrap_or(0);
        let converged = f.vec_u64("converged")?;
        // a sample of a large test set: the test set's column of each solution
        let columns =
            if f.contains(rom_names::TEST_COLUMNS) { Some(f.vec_u64(rom_names::TEST_COLUMNS)?) } else { None };
        drop(f);
        // The test set's own steps give the full-order fields, renamed, and the parameter.
        let mut steps = set_steps(&root, &stats, names_of, (n_dof, n_contact))?;
        if let Some(columns) = &columns {
            let n = steps.len();
            if columns.len() != k || columns.iter().any(|&c| c as usize >= n) {
                return Err(CromError::artifact(
                    &online_file,
                    format!("{} test columns for {k} online solutions of {n} test points", columns.len()),
                    "delete the rom artifact and rerun",
                ));
            }
            let mut all: Vec<Option<Step>> = steps.into_iter().map(Some).collect();
            steps = columns.iter().filter_map(|&c| all[c as usize].take()).collect();
        }
        if k != steps.len() || converged.len() != k {
            return Err(CromError::artifact(
                &online_file,
                format!("{k} online solutions for {} test points", steps.len()),
                "delete the rom artifact and rerun",
            ));
        }
        let here = format!("{ROOT}{}/{}/{}", ArtifactKind::ROM.name(), rom.0, rom_names::ONLINE);
        for (j, step) in steps.iter_mut().enumerate() {
            let online = |dataset: &str, rows: usize| Column {
                file: here.clone(),
                dataset: dataset.to_string(),
                shape: (rows, k),
                col: j,
            };
            let (d, p) = (Shape::Displacement, Shape::Pressure);
            let mut fields = vec![
                (names::DISPLACEMENT.to_string(), d, online("primal", n_dof)),
                (names::PRESSURE.to_string(), p, online("dual", n_contact)),
                ("displacement_error".to_string(), d, online("primal_error", n_dof)),
                ("pressure_error".to_string(), p, online("dual_error", n_contact)),
            ];
            for (name, shape, column) in step.fields.drain(..) {
                fields.push((format!("{name}_fom"), shape, column));
            }
            step.fields = fields;
            step.constants.push(("converged".to_string(), converged[j] as f64));
        }
        write_series(staging, ("rom", &rom.0), &mesh_facts, &steps, names::ONLINE_XDMF, "online")
    })
}
