//! Scene-level two-body contact models (docs/scenes.md: hertz, ironing) and their builders.
//!
//! A [`ContactModel`] holds everything that does not depend on the scene parameter `mu`: the
//! mesh of both bodies, the global stiffness `K`, the Dirichlet partition, the imposed
//! displacement `u_D(mu) = u_D0 + sum_k mu_k u_Dk` (affine in the parameter), the slave nodes (one
//! Lagrange multiplier each, with its tributary length) and the master polyline.

use super::error::ModelError;
use crate::fem::{assemble_stiffness, CsrMatrix, DofSplit, Material};
use crate::mesh::{half_disk, iron, rectangle, HalfDiskParams, IronGeometry, Mesh2d};

/// Hertz scene (docs/scenes.md#hertz-and-hertz-fine): two half-disks of radius `R` touching at
/// the origin.
///
/// ```text
///        y = R  ===========  top flat face: u = (0, -d)      (body 1, slave arc)
///               \         /
///                '-.___.-'     <- slave nodes (top body's arc)
///                .-'   '-.     <- master segments (bottom body's arc)
///               /         \
///       y = -R  ===========  bottom flat face: u = 0          (body 0)
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct HertzParams {
    /// `R1 = R2 = R` (shipped scenes: 1).
    pub radius: f64,
    /// Material of both bodies (shipped scenes: E = 1, nu = 0.3).
    pub material: Material,
    /// Elements on each curved edge (shipped scenes: 78; hertz-fine 312); >= 3.
    pub n_arc: usize,
    /// Element layers between flat face and arc (the Coons patch's short sides, see
    /// [`crate::mesh::half_disk`]); `None` = `round(7 n_arc / 78)`, giving 520 nodes per body at
    /// `n_arc = 78` and 7453 at 312.
    pub n_side: Option<usize>,
}

/// Ironing scene (docs/scenes.md#ironing-coarse-and-ironing-fine).
///
/// ```text
///                 u = (d_x, -d_y) on the iron's top
///                 +---------+
///                 |  iron   |  (body 1, master: sole)
///   y = 0 ________ '-.___.-' _______________________________ slab top (slave nodes)
///         |                (contact_x, 0)                   |
///         |  slab (body 0)                                  |
///  y = -H |_________________________________________________|  u = 0
///         x = 0                                          x = L
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct IroningParams {
    /// Slab length `L` (5).
    pub slab_length: f64,
    /// Slab height `H` (1).
    pub slab_height: f64,
    /// Slab elements along x (100 coarse, 200 fine).
    pub slab_nx: usize,
    /// Slab elements along y (20 coarse, 40 fine).
    pub slab_ny: usize,
    /// Slab material (E = 1, nu = 0.3).
    pub slab: Material,
    /// Iron width (1).
    pub iron_width: f64,
    /// Iron height from the sole's lowest point to its flat top (1).
    pub iron_height: f64,
    /// Sole radius (2).
    pub sole_radius: f64,
    /// Iron elements along x (30 / 60).
    pub iron_nx: usize,
    /// Iron elements along y (30 / 60).
    pub iron_ny: usize,
    /// Iron material (E = 10, nu = 0.3).
    pub iron: Material,
    /// x where the sole's lowest point touches the slab top in the reference state (1.0).
    pub contact_x: f64,
    /// Imposed downward displacement of the iron's top (0.04); `None` makes it the second
    /// parameter component, `mu = (d_x, d_y)`.
    pub d_y: Option<f64>,
}

/// Which scene a model was built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneKind {
    /// [`build_hertz`]: parameter `d`, top face `u = (0, -d)`.
    Hertz,
    /// [`build_ironing`]: parameter `d_x` (or `(d_x, d_y)`), iron top `u = (d_x, -d_y)`.
    Ironing,
}

/// A two-body frictionless contact model with parameter-independent stiffness.
#[derive(Debug, Clone)]
pub struct ContactModel {
    pub(crate) kind: SceneKind,
    pub(crate) mesh: Mesh2d,
    pub(crate) k: CsrMatrix,
    pub(crate) split: DofSplit,
    /// `u_D = u_d[0] + sum_k mu_k u_d[k + 1]`, full length, zero at free dofs.
    pub(crate) u_d: Vec<Vec<f64>>,
    pub(crate) slaves: Vec<usize>,
    pub(crate) masters: Vec<usize>,
    pub(crate) tributary: Vec<f64>,
    pub(crate) driven: Vec<usize>,
    pub(crate) support: Vec<usize>,
}

/// A finite, positive parameter.
pub(crate) fn positive(field: &'static str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ModelError::BadParameter { field, msg: format!("must be a positive number, got {v}") })
    }
}

/// A valid material.
pub(crate) fn material(field: &'static str, m: &Material) -> Result<(), ModelError> {
    m.validate().map_err(|msg| ModelError::BadParameter { field, msg })
}

/// A count of at least `min`.
pub(crate) fn count(field: &'static str, n: usize, min: usize) -> Result<(), ModelError> {
    if n >= min {
        Ok(())
    } else {
        Err(ModelError::BadParameter { field, msg: format!("must be >= {min}, got {n}") })
    }
}

/// Tributary lengths of a chain of nodes (half of each adjacent edge, reference configuration).
fn tributary_lengths(mesh: &Mesh2d, chain: &[usize]) -> Vec<f64> {
    let mut t = vec![0.0; chain.len()];
    for (i, w) in chain.windows(2).enumerate() {
        let (a, b) = (mesh.nodes[w[0]], mesh.nodes[w[1]]);
        let l = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        t[i] += 0.5 * l;
        t[i + 1] += 0.5 * l;
    }
    t
}

/// Build the Hertz model; the solve parameter is the approach `d` of the top face.
pub fn build_hertz(p: &HertzParams) -> Result<ContactModel, ModelError> {
    positive("radius", p.radius)?;
    material("material", &p.material)?;
    count("n_arc", p.n_arc, 3)?;
    let n_side = p.n_side.unwrap_or_else(|| HalfDiskParams::default_n_side(p.n_arc));
    if n_side == 0 || 2 * n_side >= p.n_arc {
        return Err(ModelError::BadParameter {
            field: "n_side",
            msg: format!("needs 1 <= n_side < n_arc / 2 = {}, got {n_side}", p.n_arc as f64 / 2.0),
        });
    }
    let r = p.radius;
    let hd = |center: [f64; 2], arc_up: bool| {
        half_disk(&HalfDiskParams { center, radius: r, n_arc: p.n_arc, n_side, arc_up })
    };
    let bottom = hd([0.0, -r], true)?;
    let top = hd([0.0, r], false)?;
    let (mesh, off) = Mesh2d::from_grids(&[&bottom.grid, &top.grid]);
    mesh.check_jacobians()?;
    let k = assemble_stiffness(&mesh, &[p.material, p.material])?;
    let support: Vec<usize> = bottom.flat.iter().map(|&n| n + off[0]).collect();
    let driven: Vec<usize> = top.flat.iter().map(|&n| n + off[1]).collect();
    let mut u_d1 = vec![0.0; mesh.n_dof()];
    for &n in &driven {
        u_d1[2 * n + 1] = -1.0;
    }
    let slaves: Vec<usize> = top.arc.iter().map(|&n| n + off[1]).collect();
    let masters: Vec<usize> = bottom.arc.iter().map(|&n| n + off[0]).collect();
    finish(SceneKind::Hertz, mesh, k, support, driven, vec![vec![0.0; u_d1.len()], u_d1], slaves, masters)
}

/// Build the ironing model; the solve parameter is the iron's travel `d_x`.
pub fn build_ironing(p: &IroningParams) -> Result<ContactModel, ModelError> {
    positive("slab_length", p.slab_length)?;
    positive("slab_height", p.slab_height)?;
    positive("iron_width", p.iron_width)?;
    positive("iron_height", p.iron_height)?;
    positive("sole_radius", p.sole_radius)?;
    count("slab_nx", p.slab_nx, 1)?;
    count("slab_ny", p.slab_ny, 1)?;
    count("iron_nx", p.iron_nx, 2)?;
    count("iron_ny", p.iron_ny, 1)?;
    material("slab", &p.slab)?;
    material("iron", &p.iron)?;
    if let Some(d_y) = p.d_y.filter(|d| !d.is_finite()) {
        return Err(ModelError::BadParameter { field: "d_y", msg: format!("must be finite, got {d_y}") });
    }
    if !(p.contact_x.is_finite() && p.contact_x > 0.0 && p.contact_x < p.slab_length) {
        return Err(ModelError::BadParameter {
            field: "contact_x",
            msg: format!("must lie on the slab (0, {}), got {}", p.slab_length, p.contact_x),
        });
    }
    let slab = rectangle(0.0, -p.slab_height, p.slab_length, p.slab_height, p.slab_nx, p.slab_ny)?;
    let geom = IronGeometry {
        contact_x: p.contact_x,
        contact_y: 0.0,
        width: p.iron_width,
        height: p.iron_height,
        sole_radius: p.sole_radius,
    };
    let ir = iron(&geom, p.iron_nx, p.iron_ny)?;
    let (mesh, off) = Mesh2d::from_grids(&[&slab, &ir]);
    mesh.check_jacobians()?;
    let k = assemble_stiffness(&mesh, &[p.slab, p.iron])?;
    let support: Vec<usize> = slab.bottom().iter().map(|&n| n + off[0]).collect();
    let driven: Vec<usize> = ir.top().iter().map(|&n| n + off[1]).collect();
    let (mut u_d0, mut u_dx, mut u_dy) = (vec![0.0; mesh.n_dof()], vec![0.0; mesh.n_dof()], vec![0.0; mesh.n_dof()]);
    for &n in &driven {
        u_d0[2 * n + 1] = -p.d_y.unwrap_or(0.0);
        u_dx[2 * n] = 1.0;
        u_dy[2 * n + 1] = -1.0;
    }
    let u_d = if p.d_y.is_some() { vec![u_d0, u_dx] } else { vec![u_d0, u_dx, u_dy] };
    let slaves: Vec<usize> = slab.top().iter().map(|&n| n + off[0]).collect();
    let masters: Vec<usize> = ir.bottom().iter().map(|&n| n + off[1]).collect();
    finish(SceneKind::Ironing, mesh, k, support, driven, u_d, slaves, masters)
}

#[allow(clippy::too_many_arguments)]
fn finish(
    kind: SceneKind,
    mesh: Mesh2d,
    k: CsrMatrix,
    support: Vec<usize>,
    driven: Vec<usize>,
    u_d: Vec<Vec<f64>>,
    slaves: Vec<usize>,
    masters: Vec<usize>,
) -> Result<ContactModel, ModelError> {
    let fixed: Vec<usize> = support.iter().chain(&driven).flat_map(|&n| [2 * n, 2 * n + 1]).collect();
    let split = DofSplit::new(mesh.n_dof(), &fixed);
    let tributary = tributary_lengths(&mesh, &slaves);
    Ok(ContactModel { kind, mesh, k, split, u_d, slaves, masters, tributary, driven, support })
}

impl ContactModel {
    /// The mesh of both bodies (nodes of body 0 first). Hertz: body 0 = bottom half-disk
    /// (master), body 1 = top half-disk (slave). Ironing: body 0 = slab (slave), body 1 = iron
    /// (master).
    pub fn mesh(&self) -> &Mesh2d {
        &self.mesh
    }
    /// Which scene this is.
    pub fn kind(&self) -> SceneKind {
        self.kind
    }
    /// Slave nodes (global ids); the order of `Snapshot::pressure`. Hertz: the top body's arc
    /// left to right; ironing: the slab's top edge left to right.
    pub fn slave_nodes(&self) -> &[usize] {
        &self.slaves
    }
    /// Master polyline nodes (global ids), counter-clockwise around the master body.
    pub fn master_nodes(&self) -> &[usize] {
        &self.masters
    }
    /// Tributary length of each slave node (reference configuration); `pressure = force / it`.
    pub fn tributary_lengths(&self) -> &[f64] {
        &self.tributary
    }
    /// Nodes whose displacement is driven by the parameter (Hertz: top flat face; ironing: iron
    /// top).
    pub fn driven_nodes(&self) -> &[usize] {
        &self.driven
    }
    /// Nodes held at zero displacement (Hertz: bottom flat face; ironing: slab bottom).
    pub fn support_nodes(&self) -> &[usize] {
        &self.support
    }
    /// Number of displacement dofs of both bodies (Dirichlet ones included).
    pub fn n_dof(&self) -> usize {
        self.mesh.n_dof()
    }
    /// Number of free (non-Dirichlet) dofs, the size of the factored system.
    pub fn n_free(&self) -> usize {
        self.split.n_free()
    }
    /// The global stiffness matrix over all dofs.
    pub fn stiffness(&self) -> &CsrMatrix {
        &self.k
    }
    /// Number of parameter components the model is driven by.
    pub fn n_params(&self) -> usize {
        self.u_d.len() - 1
    }
    /// Resultant `sum_n (K u)_n` over `nodes`: for Dirichlet nodes this is the reaction force
    /// the support exerts on the body.
    pub fn resultant(&self, u: &[f64], nodes: &[usize]) -> [f64; 2] {
        assert_eq!(u.len(), self.n_dof(), "displacement length");
        let mut f = [0.0; 2];
        for &n in nodes {
            for (c, fc) in f.iter_mut().enumerate() {
                let (cols, vals) = self.k.row(2 * n + c);
                *fc += cols.iter().zip(vals).map(|(&j, &v)| v * u[j]).sum::<f64>();
            }
        }
        f
    }
}
