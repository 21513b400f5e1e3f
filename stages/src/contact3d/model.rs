//! The 3-D two-body contact models (`hertz-3d`, `ironing-3d`): everything that does not
//! depend on the parameter — the hex mesh of both bodies, `K`, the Dirichlet and roller
//! conditions, the affine imposed displacement `u_D(mu) = u_D0 + sum_k mu_k u_Dk`, the slave
//! nodes with their tributary areas, and the master surface.

use super::surface::MasterSurface;
use crate::contact::model::{count, material, positive};
use crate::contact::ModelError;
use crate::fem::{CsrMatrix, DofSplit, Material};
use crate::solid::assembly::assemble_stiffness;
use crate::solid::block::{Block, Face};
use crate::solid::mesh::Mesh3d;
use crate::solid::shapes::{ball_octant, cuboid, cylinder_die, Facing};
use crate::solid::symmetry::{free_rigid_modes, roller_dofs, Plane};

/// `hertz-3d`: two equal hemispheres touching at the origin, quarter model (symmetry planes
/// `x = 0` and `y = 0`).
///
/// ```text
///      z = R  ===========  top flat face: u_z = -d          (body 1, slaves on its cap)
///             \         /
///              '-.___.-'     apex (0, 0, 0)
///              .-'   '-.
///             /         \
///     z = -R  ===========  bottom flat face: u_z = 0        (body 0, master facets on its cap)
/// ```
///
/// The flat faces slide freely in their planes (code_aster's SSNV104 imposes only the vertical
/// displacement there): clamping them stiffens the bodies, and at the same approach the force
/// read about 10 % above Hertz's on every mesh tried (the comparison with theory is then one
/// of boundary conditions, not of contact).
#[derive(Debug, Clone, PartialEq)]
pub struct Hertz3dParams {
    /// `R1 = R2 = R`.
    pub radius: f64,
    /// Material of both bodies.
    pub material: Material,
    /// Elements along each lattice direction of each octant.
    pub n: usize,
    /// Grading exponent toward the pole (1: uniform).
    pub grading: f64,
    /// Slave nodes and master facets lie within this distance of the axis (reference).
    pub contact_radius: f64,
    /// Symmetry planes (roller conditions); the quarter model's are `x = 0` and `y = 0`.
    pub planes: Vec<Plane>,
}

/// `ironing-3d`: a die with a cylindrical sole pressed into a block and slid along x, half model
/// (symmetry plane `y = 0`).
///
/// ```text
///            u = (d_x, 0, -d_z) on the die's top
///            +---------+
///            |   die   |   sole: cylinder of radius R, axis along y
///  z = 0 ____ '-.___.-' _______________________ block top (slaves in a box)
///       |                                      |
///  z=-H |______________________________________|  u = 0
///       x = 0                                  x = L        (y from 0 to the block's depth)
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Ironing3dParams {
    /// Block size `(L, depth, H)`: `[0, L] x [0, depth] x [-H, 0]`.
    pub block: [f64; 3],
    /// Block elements along x, y, z.
    pub block_n: [usize; 3],
    /// Block material.
    pub block_material: Material,
    /// Die size `(width, depth, height)`: `x` about `contact_x`, `y in [0, depth]`, height from
    /// the sole's lowest point.
    pub die: [f64; 3],
    /// Die elements along x, y, z.
    pub die_n: [usize; 3],
    /// Die material.
    pub die_material: Material,
    /// Sole radius.
    pub sole_radius: f64,
    /// x of the sole's lowest line in the reference state (it touches the block top there).
    pub contact_x: f64,
    /// Imposed downward displacement of the die's top; `None`: the second parameter component.
    pub d_z: Option<f64>,
    /// The slaves: block-top nodes with `x in [x0, x1]` and `y <= y1`, as `[x0, x1, y1]`.
    pub slave_box: [f64; 3],
    /// Symmetry planes (roller conditions); the half model's is `y = 0`.
    pub planes: Vec<Plane>,
}

/// Which 3-D scene a model was built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scene3d {
    /// [`build_hertz3d`].
    Hertz,
    /// [`build_ironing3d`].
    Ironing,
}

/// A 3-D two-body frictionless contact model with parameter-independent stiffness.
#[derive(Debug, Clone)]
pub struct Model3d {
    pub(crate) kind: Scene3d,
    pub(crate) mesh: Mesh3d,
    pub(crate) k: CsrMatrix,
    pub(crate) split: DofSplit,
    /// `u_D = u_d[0] + sum_k mu_k u_d[k + 1]`, full length, zero at free dofs.
    pub(crate) u_d: Vec<Vec<f64>>,
    pub(crate) slaves: Vec<usize>,
    pub(crate) masters: Vec<usize>,
    pub(crate) surface: MasterSurface,
    pub(crate) area: Vec<f64>,
    pub(crate) driven: Vec<usize>,
    pub(crate) support: Vec<usize>,
    pub(crate) planes: Vec<Plane>,
}

/// Tributary area of each node of `nodes` on the quads `quads` (reference configuration): a
/// quarter of each adjacent quad's area (2x2 Gauss of `|x_xi x x_eta|`).
fn tributary_areas(x: &[[f64; 3]], quads: &[[usize; 4]], nodes: &[usize]) -> Vec<f64> {
    let mut at = std::collections::HashMap::new();
    for (i, &n) in nodes.iter().enumerate() {
        at.insert(n, i);
    }
    let mut area = vec![0.0; nodes.len()];
    for q in quads {
        let xf = q.map(|n| x[n]);
        let a: f64 = crate::q1::GAUSS_2X2
            .iter()
            .map(|&[xi, eta]| {
                let (t1, t2) = super::facet::tangents(&xf, [xi, eta]);
                let c = super::facet::cross(t1, t2);
                super::facet::dot(c, c).sqrt()
            })
            .sum();
        for n in q {
            if let Some(&i) = at.get(n) {
                area[i] += 0.25 * a;
            }
        }
    }
    area
}

/// A block of a mesh of several ([`Mesh3d::from_blocks`]): its faces in the mesh's numbering.
struct Placed<'a> {
    block: &'a Block,
    /// The mesh's id of the block's node 0.
    first: usize,
}

impl Placed<'_> {
    fn nodes(&self, face: Face) -> Vec<usize> {
        self.block.face_nodes(face).iter().map(|&n| n + self.first).collect()
    }

    fn quads(&self, face: Face) -> Vec<[usize; 4]> {
        self.block.face_quads(face).iter().map(|q| q.map(|n| n + self.first)).collect()
    }
}

/// Everything of a model but its stiffness: what [`check_hertz3d`] and [`check_ironing3d`]
/// build and check, and the builders assemble.
struct Layout {
    kind: Scene3d,
    mesh: Mesh3d,
    materials: Vec<Material>,
    support: Vec<usize>,
    driven: Vec<usize>,
    /// Dirichlet dofs, rollers included.
    fixed: Vec<usize>,
    u_d: Vec<Vec<f64>>,
    slaves: Vec<usize>,
    slave_quads: Vec<[usize; 4]>,
    master_quads: Vec<[usize; 4]>,
    planes: Vec<Plane>,
}

/// Build the `hertz-3d` model; the parameter is the approach `d` of the top face.
pub fn build_hertz3d(p: &Hertz3dParams) -> Result<Model3d, ModelError> {
    finish(hertz3d_layout(p)?)
}

/// [`build_hertz3d`]'s checks without the assembly: the parameters, every element's Jacobian,
/// a slave in the contact region, and no body free in a rigid motion (cheap: what a scene file
/// is checked with before a run writes anything).
pub fn check_hertz3d(p: &Hertz3dParams) -> Result<(), ModelError> {
    hertz3d_layout(p).map(|_| ())
}

/// [`build_ironing3d`]'s checks without the assembly (see [`check_hertz3d`]).
pub fn check_ironing3d(p: &Ironing3dParams) -> Result<(), ModelError> {
    ironing3d_layout(p).map(|_| ())
}

fn hertz3d_layout(p: &Hertz3dParams) -> Result<Layout, ModelError> {
    positive("radius", p.radius)?;
    positive("contact_radius", p.contact_radius)?;
    material("material", &p.material)?;
    count("n", p.n, 2)?;
    if !(p.grading.is_finite() && p.grading >= 1.0) {
        return Err(ModelError::BadParameter { field: "grading", msg: format!("must be >= 1, got {}", p.grading) });
    }
    let r = p.radius;
    let bottom = ball_octant([0.0, 0.0, -r], r, p.n, p.grading, Facing::Up);
    let top = ball_octant([0.0, 0.0, r], r, p.n, p.grading, Facing::Down);
    let planes = p.planes.clone();
    let within = |x: [f64; 3]| x[0].hypot(x[1]) <= p.contact_radius;
    let (mesh, off) = Mesh3d::from_blocks(&[&bottom, &top]);
    let (bottom, top) = (Placed { block: &bottom, first: off[0] }, Placed { block: &top, first: off[1] });
    let support = bottom.nodes(Face::KMin);
    let driven = top.nodes(Face::KMin);
    let mut u_d1 = vec![0.0; mesh.n_dof()];
    for &n in &driven {
        u_d1[3 * n + 2] = -1.0;
    }
    let slave_quads = top.quads(Face::KMax);
    let slaves: Vec<usize> = top.nodes(Face::KMax).into_iter().filter(|&n| within(mesh.nodes[n])).collect();
    let master_quads: Vec<[usize; 4]> =
        bottom.quads(Face::KMax).into_iter().filter(|q| q.iter().any(|&n| within(mesh.nodes[n]))).collect();
    // the flat faces on vertical rollers (u_z imposed, free to expand laterally: SSNV104's
    // conditions); the symmetry planes hold the lateral rigid motions
    let fixed: Vec<usize> = support.iter().chain(&driven).map(|&n| 3 * n + 2).collect();
    let u_d = vec![vec![0.0; u_d1.len()], u_d1];
    let materials = vec![p.material, p.material];
    checked(Layout {
        kind: Scene3d::Hertz,
        mesh,
        materials,
        support,
        driven,
        fixed,
        u_d,
        slaves,
        slave_quads,
        master_quads,
        planes,
    })
}

/// Build the `ironing-3d` model; the parameter is the die's travel `d_x` (and `d_z` when
/// `d_z` is `None`).
pub fn build_ironing3d(p: &Ironing3dParams) -> Result<Model3d, ModelError> {
    finish(ironing3d_layout(p)?)
}

fn ironing3d_layout(p: &Ironing3dParams) -> Result<Layout, ModelError> {
    for (f, v) in [("block.length", p.block[0]), ("block.depth", p.block[1]), ("block.height", p.block[2])] {
        positive(f, v)?;
    }
    for (f, v) in [("die.width", p.die[0]), ("die.depth", p.die[1]), ("die.height", p.die[2])] {
        positive(f, v)?;
    }
    positive("sole_radius", p.sole_radius)?;
    if p.sole_radius <= 0.5 * p.die[0] {
        return Err(ModelError::BadParameter {
            field: "sole_radius",
            msg: format!("must exceed half the die's width ({}), got {}", 0.5 * p.die[0], p.sole_radius),
        });
    }
    for (f, n) in [("block.nx", p.block_n[0]), ("block.ny", p.block_n[1]), ("block.nz", p.block_n[2])] {
        count(f, n, 1)?;
    }
    for (f, n) in [("die.nx", p.die_n[0]), ("die.ny", p.die_n[1]), ("die.nz", p.die_n[2])] {
        count(f, n, 1)?;
    }
    material("block.material", &p.block_material)?;
    material("die.material", &p.die_material)?;
    if !(p.contact_x.is_finite() && p.contact_x > 0.0 && p.contact_x < p.block[0]) {
        return Err(ModelError::BadParameter {
            field: "contact_x",
            msg: format!("must lie on the block (0, {}), got {}", p.block[0], p.contact_x),
        });
    }
    if let Some(d) = p.d_z.filter(|d| !d.is_finite()) {
        return Err(ModelError::BadParameter { field: "d_z", msg: format!("must be finite, got {d}") });
    }
    let block = cuboid([0.0, 0.0, -p.block[2]], p.block, p.block_n);
    let die = cylinder_die(p.contact_x, 0.0, 0.0, p.die, p.sole_radius, p.die_n);
    let (mesh, off) = Mesh3d::from_blocks(&[&block, &die]);
    let (block, die) = (Placed { block: &block, first: off[0] }, Placed { block: &die, first: off[1] });
    let support = block.nodes(Face::KMin);
    let driven = die.nodes(Face::KMax);
    let n_dof = mesh.n_dof();
    let (mut u0, mut ux, mut uz) = (vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]);
    for &n in &driven {
        u0[3 * n + 2] = -p.d_z.unwrap_or(0.0);
        ux[3 * n] = 1.0;
        uz[3 * n + 2] = -1.0;
    }
    let u_d = if p.d_z.is_some() { vec![u0, ux] } else { vec![u0, ux, uz] };
    let [x0, x1, y1] = p.slave_box;
    let slave_quads = block.quads(Face::KMax);
    let slaves: Vec<usize> = block
        .nodes(Face::KMax)
        .into_iter()
        .filter(|&n| {
            let x = mesh.nodes[n];
            x[0] >= x0 && x[0] <= x1 && x[1] <= y1
        })
        .collect();
    let master_quads = die.quads(Face::KMin);
    let planes = p.planes.clone();
    let fixed: Vec<usize> = support.iter().chain(&driven).flat_map(|&n| [3 * n, 3 * n + 1, 3 * n + 2]).collect();
    let materials = vec![p.block_material, p.die_material];
    checked(Layout {
        kind: Scene3d::Ironing,
        mesh,
        materials,
        support,
        driven,
        fixed,
        u_d,
        slaves,
        slave_quads,
        master_quads,
        planes,
    })
}

/// The layout's checks: every element's Jacobian, a slave, each plane a valid axis, and no body
/// free in a rigid motion once the rollers are added to the Dirichlet dofs.
fn checked(mut l: Layout) -> Result<Layout, ModelError> {
    l.mesh.check_jacobians().map_err(|e| ModelError::BadParameter { field: "mesh", msg: e.to_string() })?;
    if l.slaves.is_empty() {
        return Err(ModelError::BadParameter {
            field: "slaves",
            msg: "no slave node lies in the contact region".into(),
        });
    }
    if let Some(p) = l.planes.iter().find(|p| p.axis > 2 || !p.at.is_finite()) {
        return Err(ModelError::BadParameter {
            field: "symmetry",
            msg: format!("{p:?} is not a plane x, y or z = a finite value"),
        });
    }
    let h = mesh_size(&l.mesh);
    let rollers = roller_dofs(&l.mesh.nodes, &l.planes, 1e-9 * h);
    if let Some(p) = l
        .planes
        .iter()
        .find(|p| !rollers.iter().any(|&d| d % 3 == p.axis && (l.mesh.nodes[d / 3][p.axis] - p.at).abs() <= 1e-9 * h))
    {
        let axis = ["x", "y", "z"][p.axis];
        return Err(ModelError::BadParameter {
            field: "symmetry",
            msg: format!("the plane {axis} = {} holds no node of the mesh", p.at),
        });
    }
    l.fixed.extend(rollers);
    let free = free_rigid_modes(&l.mesh.nodes, &l.mesh.node_body, &l.fixed);
    if let Some(&(body, modes)) = free.first() {
        return Err(ModelError::BadParameter {
            field: "symmetry",
            msg: format!("body {body} keeps {modes} rigid-body mode(s) that no Dirichlet face or symmetry plane holds"),
        });
    }
    Ok(l)
}

/// The model of a checked layout: its stiffness, Dirichlet partition, master surface and the
/// slaves' tributary areas.
fn finish(l: Layout) -> Result<Model3d, ModelError> {
    let Layout { kind, mesh, materials, support, driven, fixed, u_d, slaves, slave_quads, master_quads, planes } = l;
    let k = assemble_stiffness(&mesh, &materials)
        .map_err(|e| ModelError::BadParameter { field: "mesh", msg: e.to_string() })?;
    let h = mesh_size(&mesh);
    let split = DofSplit::new(mesh.n_dof(), &fixed);
    // master-local ids: the master nodes in order of first appearance in the facets
    let mut masters: Vec<usize> = Vec::new();
    let mut local = std::collections::HashMap::new();
    let facets: Vec<[usize; 4]> = master_quads
        .iter()
        .map(|q| {
            q.map(|n| {
                *local.entry(n).or_insert_with(|| {
                    masters.push(n);
                    masters.len() - 1
                })
            })
        })
        .collect();
    let x_ref: Vec<[f64; 3]> = masters.iter().map(|&n| mesh.nodes[n]).collect();
    let surface = MasterSurface::new(facets, &x_ref, &planes, 1e-9 * h);
    let area = tributary_areas(&mesh.nodes, &slave_quads, &slaves);
    Ok(Model3d { kind, mesh, k, split, u_d, slaves, masters, surface, area, driven, support, planes })
}

/// The largest coordinate extent of the mesh (a length scale for tolerances).
fn mesh_size(mesh: &Mesh3d) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for x in &mesh.nodes {
        for c in 0..3 {
            lo[c] = lo[c].min(x[c]);
            hi[c] = hi[c].max(x[c]);
        }
    }
    (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max)
}

impl Model3d {
    /// The mesh of both bodies (body 0 first: hertz's bottom hemisphere, the ironing block).
    pub fn mesh(&self) -> &Mesh3d {
        &self.mesh
    }
    /// Which scene.
    pub fn kind(&self) -> Scene3d {
        self.kind
    }
    /// Slave nodes (global ids): the order of the pressure field.
    pub fn slave_nodes(&self) -> &[usize] {
        &self.slaves
    }
    /// Master nodes (global ids), in master-local order.
    pub fn master_nodes(&self) -> &[usize] {
        &self.masters
    }
    /// Tributary area of each slave (reference configuration): `pressure = force / area`.
    pub fn tributary_areas(&self) -> &[f64] {
        &self.area
    }
    /// The master surface.
    pub fn surface(&self) -> &MasterSurface {
        &self.surface
    }
    /// Nodes driven by the parameter.
    pub fn driven_nodes(&self) -> &[usize] {
        &self.driven
    }
    /// Nodes held at zero.
    pub fn support_nodes(&self) -> &[usize] {
        &self.support
    }
    /// Symmetry planes.
    pub fn planes(&self) -> &[Plane] {
        &self.planes
    }
    /// Number of dofs (all).
    pub fn n_dof(&self) -> usize {
        self.mesh.n_dof()
    }
    /// Number of free dofs.
    pub fn n_free(&self) -> usize {
        self.split.n_free()
    }
    /// Number of parameter components.
    pub fn n_params(&self) -> usize {
        self.u_d.len() - 1
    }
    /// The global stiffness.
    pub fn stiffness(&self) -> &CsrMatrix {
        &self.k
    }
    /// The reaction `sum_n (K u)_n` over `nodes` (3 components).
    pub fn resultant(&self, u: &[f64], nodes: &[usize]) -> [f64; 3] {
        let mut f = [0.0; 3];
        for &n in nodes {
            for (c, fc) in f.iter_mut().enumerate() {
                let (cols, vals) = self.k.row(3 * n + c);
                *fc += cols.iter().zip(vals).map(|(&j, &v)| v * u[j]).sum::<f64>();
            }
        }
        f
    }
}
