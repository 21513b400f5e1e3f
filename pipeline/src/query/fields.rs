//! `crom query --fields OUT.h5`: the fields of the answered points, for h5py and ParaView.
//!
//! `OUT.h5` is self-contained: the scene's mesh (`nodes`, n_nodes x 2; `cells`), `parameters`
//! (k x dim), `converged` (k), and per point j the group `steps/<j:05>` with `displacement`
//! (n_nodes x 3, z = 0; the rope's one dof per node is its y component) and `pressure`
//! (n_nodes, zero off the contact surface). The displacement is reconstructed from the optional
//! part of the model (`reconstruction.h5`): `u = lift[:, 0] + sum_k mu_k lift[:, k + 1] + phi û`;
//! the pressure is the model's `Theta λ̂` on the contact nodes. `OUT.xdmf`, beside it, is an
//! XDMF temporal collection over the points (time = point index) that ParaView opens.

use std::path::Path;

use crom_schemas::artifact::{mesh as mesh_names, model as names, ArtifactKind};
use crom_schemas::SceneConfig;

use super::{Loaded, Row};
use crate::error::CromError;
use crate::io::h5::{H5In, H5Out};
use crate::io::model::Reconstruction;
use crate::io::xdmf::{series_xdmf, SeriesAttribute, SeriesMesh, SeriesStep};
use crate::store::Store;

/// Write `path` (`.h5`) and its `.xdmf` for the answered `rows`.
pub(super) fn write(
    path: &Path,
    root: &Path,
    scene: &SceneConfig,
    loaded: &Loaded,
    rows: &[Row],
) -> Result<(), CromError> {
    let mesh_key = loaded.mesh.as_ref().ok_or_else(|| CromError::Usage {
        message: format!("scene `{}` has no mesh", scene.scene.name),
        fix: "query a native scene".into(),
    })?;
    let mesh_path = Store::open_read_only(root).dir(ArtifactKind::MESH, mesh_key).join(mesh_names::FILE);
    let mesh = H5In::open(&mesh_path)?;
    let nodes = mesh.matrix(mesh_names::NODES)?; // n_nodes x 2, column-major
    let cells_shape = mesh.shape(mesh_names::CELLS)?;
    let cells = mesh.vec_u64(mesh_names::CELLS)?;
    let contact = mesh.vec_u64(mesh_names::CONTACT_NODES)?;
    let dofs_per_node = mesh.attr_u64("dofs_per_node")? as usize;
    let rec_path = loaded.dir.join(names::RECONSTRUCTION);
    let rec = loaded.reconstruction("run `crom run SCENE` again")?;
    let n = nodes.rows;
    let (r, dim) = (loaded.model.ranks().0, loaded.stored.parameter_names.len());
    let damaged = |what: String| CromError::artifact(&rec_path, what, "run `crom run SCENE` again");
    if rec.phi.rows != n * dofs_per_node
        || rec.phi.cols != r
        || rec.lift.rows != rec.phi.rows
        || rec.lift.cols != 1 + dim
    {
        return Err(damaged(format!(
            "phi {} x {} and lift {} x {} do not fit the mesh's {} dofs and the model's rank {r}, {dim} components",
            rec.phi.rows,
            rec.phi.cols,
            rec.lift.rows,
            rec.lift.cols,
            n * dofs_per_node
        )));
    }
    if contact.iter().any(|&c| c as usize >= n)
        || contact.len() != rows.first().map_or(contact.len(), |r| r.pressure.len())
    {
        return Err(damaged("the mesh's contact nodes do not match the model's pressure".into()));
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| CromError::io(dir, "creating the directory of --fields", e))?;
    }
    let f = H5Out::create(path)?;
    f.attr_str("kind", "query fields")?;
    f.attr_str("scene", &scene.scene.name)?;
    f.attr_str("parameter_names", &loaded.stored.parameter_names.join(","))?;
    let flat: Vec<f64> = (0..n).flat_map(|i| [nodes.data[i], nodes.data[i + n]]).collect();
    f.table_f64("nodes", n, 2, &flat, "length")?;
    let per = cells_shape.get(1).copied().unwrap_or(4);
    f.table_u64("cells", cells_shape.first().copied().unwrap_or(0), per, &cells)?;
    let params: Vec<f64> = rows.iter().flat_map(|r| r.point.iter().copied()).collect();
    f.table_f64("parameters", rows.len(), dim, &params, "parameter")?;
    let converged: Vec<u64> = rows.iter().map(|r| u64::from(r.sol.outcome.name() == "converged")).collect();
    f.vec_u64("converged", &converged)?;
    let steps = f.group("steps")?;
    let file = path.file_name().and_then(|s| s.to_str()).unwrap_or("fields.h5").to_string();
    let mut series = Vec::with_capacity(rows.len());
    for (j, row) in rows.iter().enumerate() {
        let u = displacement(&rec, &row.point, &row.sol.u_hat);
        let mut vec3 = vec![0.0; 3 * n];
        for i in 0..n {
            match dofs_per_node {
                1 => vec3[3 * i + 1] = u[i],
                d => (0..d.min(3)).for_each(|c| vec3[3 * i + c] = u[d * i + c]),
            }
        }
        let mut p = vec![0.0; n];
        for (k, &c) in contact.iter().enumerate() {
            p[c as usize] = row.pressure[k];
        }
        let label = format!("{j:05}");
        let g = steps.group(&label)?;
        g.table_f64("displacement", n, 3, &vec3, "length")?;
        g.vec_f64("pressure", &p, "pressure")?;
        let at = |field: &str| format!("{file}:/steps/{label}/{field}");
        let attr = |name: &str, kind, dims: Vec<usize>| SeriesAttribute {
            name: name.to_string(),
            kind,
            center: "Node",
            dims,
            number: "Float",
            reference: at(name),
        };
        let name = loaded
            .stored
            .parameter_names
            .iter()
            .zip(&row.point)
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(",");
        series.push(SeriesStep {
            name,
            time: j as f64,
            attributes: vec![attr("displacement", "Vector", vec![n, 3]), attr("pressure", "Scalar", vec![n])],
        });
    }
    drop(steps);
    drop(f);
    let mesh = SeriesMesh {
        mesh_ref: file,
        n_nodes: n,
        n_cells: cells_shape.first().copied().unwrap_or(0),
        nodes_per_cell: per,
        dim: 2,
    };
    let xdmf = path.with_extension("xdmf");
    std::fs::write(&xdmf, series_xdmf("query", &mesh, &series))
        .map_err(|e| CromError::io(&xdmf, "writing the XDMF file", e))
}

/// `lift[:, 0] + sum_k mu_k lift[:, k + 1] + phi û` on every dof (the fields `--fields` writes
/// and the Python extension's lazy displacement). The caller checks the shapes: `lift` has
/// `1 + mu.len()` columns, `phi` as many rows as `lift` and `u_hat.len()` columns.
pub fn displacement(rec: &Reconstruction, mu: &[f64], u_hat: &[f64]) -> Vec<f64> {
    let n = rec.lift.rows;
    let mut u = rec.lift.col(0).to_vec();
    for (k, m) in mu.iter().enumerate() {
        u.iter_mut().zip(rec.lift.col(k + 1)).for_each(|(a, b)| *a += m * b);
    }
    for (k, c) in u_hat.iter().enumerate() {
        u.iter_mut().zip(&rec.phi.data[k * n..(k + 1) * n]).for_each(|(a, b)| *a += c * b);
    }
    u
}
