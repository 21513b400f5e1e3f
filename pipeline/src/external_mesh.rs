//! The mesh of an external scene (`model.external.mesh`, [`crom_schemas::external::MeshSource`]):
//! read whole when the scene is loaded (a mesh is small beside the snapshots), checked, and
//! recorded with the blake3 of its contents ([`ResolvedMesh::digest`], the mesh artifact's key).
//!
//! Checked, each refusal an input error (exit 2) naming the file, the dataset and the fix:
//! nodes `(n_nodes, d)` with `d` in 1..=3 and finite coordinates; cells `(n_cells, k)` of a
//! known shape for `d` (segments, triangles, quadrilaterals, tetrahedra, hexahedra) whose
//! entries are node indices; one distinct node per dual entry; a primal field of a whole number
//! (1 to 3) of entries per node.

use std::path::Path;

use crom_schemas::external::{MeshSource, ResolvedMesh};

use crate::error::CromError;
use crate::io::array::{read_whole, WholeArray};

const AT: &str = "model.external.mesh";

/// The XDMF topology of cells of `k` nodes in `d` dimensions, or None if not a shape read here.
pub fn topology(k: usize, d: usize) -> Option<&'static str> {
    match (k, d) {
        (2, _) => Some("Polyline"),
        (3, 2 | 3) => Some("Triangle"),
        (4, 1 | 2) => Some("Quadrilateral"),
        (4, 3) => Some("Tetrahedron"),
        (8, 3) => Some("Hexahedron"),
        _ => None,
    }
}

/// Read and check the mesh `src` (relative to `base`) of a scene with `n_contact` dual and
/// `n_dof` primal entries per snapshot.
pub fn resolve(base: &Path, src: &MeshSource, n_contact: usize, n_dof: usize) -> Result<ResolvedMesh, CromError> {
    let file = src.file.as_deref();
    let nodes = read_whole(base, file, &src.nodes, &format!("{AT}.nodes"))?;
    let (n_nodes, dim) = (nodes.rows(), nodes.cols());
    if n_nodes == 0 || !(1..=3).contains(&dim) {
        return Err(CromError::input(
            &nodes.path,
            nodes.what.clone(),
            format!("has shape {:?}; the nodes are an (n_nodes, d) array with d = 1, 2 or 3", nodes.shape),
            "store one row of coordinates per node",
        ));
    }
    if let Some(k) = nodes.data.iter().position(|v| !v.is_finite()) {
        return Err(CromError::input(
            &nodes.path,
            nodes.what.clone(),
            format!("row {}, column {} is {}", k / dim, k % dim, nodes.data[k]),
            "give finite node coordinates",
        ));
    }
    let cells = read_whole(base, file, &src.cells, &format!("{AT}.cells"))?;
    let k = cells.cols();
    if cells.shape.len() != 2 || cells.rows() == 0 || topology(k, dim).is_none() {
        return Err(CromError::input(
            &cells.path,
            cells.what.clone(),
            format!("has shape {:?} with {dim}-D nodes", cells.shape),
            "give an (n_cells, k) array of node indices: k = 2 (segments), 3 (triangles), 4 (quadrilaterals in 2-D, tetrahedra in 3-D) or 8 (hexahedra)",
        ));
    }
    let cell_ids = indices(&cells, n_nodes, "cells")?;
    let dual_nodes = match &src.dual_nodes {
        Some(name) => {
            let a = read_whole(base, file, name, &format!("{AT}.dual_nodes"))?;
            if a.cols() != 1 || a.rows() != n_contact {
                return Err(CromError::input(
                    &a.path,
                    a.what.clone(),
                    format!("has shape {:?}; the dual snapshots have {n_contact} entries", a.shape),
                    "give one node index per dual entry, in the dual snapshots' order",
                ));
            }
            let ids = indices(&a, n_nodes, "dual_nodes")?;
            let mut seen = vec![usize::MAX; n_nodes];
            for (e, &i) in ids.iter().enumerate() {
                let prev = seen[i as usize];
                if prev != usize::MAX {
                    return Err(CromError::input(
                        &a.path,
                        a.what.clone(),
                        format!("gives node {i} to dual entries {prev} and {e}"),
                        "give each dual entry its own node",
                    ));
                }
                seen[i as usize] = e;
            }
            ids
        }
        None if n_contact == n_nodes => (0..n_nodes as u64).collect(),
        None => {
            return Err(CromError::input(
                &nodes.path,
                format!("{AT}.dual_nodes"),
                format!("is missing, and the dual snapshots have {n_contact} entries for {n_nodes} nodes"),
                format!("add {AT}.dual_nodes: an (n_contact,) array of the node of each dual entry"),
            ))
        }
    };
    let dofs_per_node = if n_dof == 0 { 0 } else { n_dof / n_nodes };
    if n_dof > 0 && (!n_dof.is_multiple_of(n_nodes) || !(1..=3).contains(&dofs_per_node)) {
        return Err(CromError::input(
            &nodes.path,
            nodes.what.clone(),
            format!("holds {n_nodes} nodes, and the primal snapshots have {n_dof} entries: not 1, 2 or 3 per node"),
            "give the primal snapshots node-major (entry dofs_per_node * node + component), for every node of the mesh",
        ));
    }
    let mut h = blake3::Hasher::new();
    for v in [dim, k, dofs_per_node, n_nodes, cell_ids.len(), dual_nodes.len()] {
        h.update(&(v as u64).to_le_bytes());
    }
    nodes.data.iter().for_each(|v| {
        h.update(&v.to_bits().to_le_bytes());
    });
    cell_ids.iter().chain(&dual_nodes).for_each(|v| {
        h.update(&v.to_le_bytes());
    });
    Ok(ResolvedMesh {
        nodes: nodes.data,
        dim,
        cells: cell_ids,
        nodes_per_cell: k,
        dual_nodes,
        dofs_per_node,
        digest: h.finalize().to_hex().to_string(),
    })
}

/// The entries of `a` as node indices below `n_nodes`, or an error naming the first that is
/// not one.
fn indices(a: &WholeArray, n_nodes: usize, what: &str) -> Result<Vec<u64>, CromError> {
    let cols = a.cols();
    a.data
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            if v >= 0.0 && v.fract() == 0.0 && v < n_nodes as f64 {
                Ok(v as u64)
            } else {
                let at = if a.shape.len() == 2 {
                    format!("row {}, column {}", k / cols, k % cols)
                } else {
                    format!("entry {k}")
                };
                Err(CromError::input(
                    &a.path,
                    a.what.clone(),
                    format!("{at} is {v}, not a node index (0 to {})", n_nodes - 1),
                    format!("give {what} as 0-based indices of the mesh's {n_nodes} nodes"),
                ))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::npy::tests::write_npy;

    /// Two triangles on the unit square:
    /// ```text
    /// 3 --- 2
    /// |  \  |
    /// 0 --- 1
    /// ```
    fn square(dir: &Path) {
        write_npy(&dir.join("nodes.npy"), &[4, 2], false, &[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
        write_npy(&dir.join("cells.npy"), &[2, 3], false, &[0.0, 1.0, 3.0, 1.0, 2.0, 3.0]);
    }

    fn src(dual: Option<&str>) -> MeshSource {
        MeshSource {
            file: None,
            nodes: "nodes.npy".into(),
            cells: "cells.npy".into(),
            dual_nodes: dual.map(str::to_string),
        }
    }

    #[test]
    fn a_square_of_triangles_reads_with_its_map() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        square(dir.path());
        write_npy(&dir.path().join("dual.npy"), &[2], false, &[3.0, 2.0]);
        let m = resolve(dir.path(), &src(Some("dual.npy")), 2, 8).expect("mesh");
        assert_eq!((m.n_nodes(), m.dim, m.n_cells(), m.nodes_per_cell, m.dofs_per_node), (4, 2, 2, 3, 2));
        assert_eq!(m.dual_nodes, vec![3, 2]);
        // The digest follows the contents: another map, another key.
        write_npy(&dir.path().join("dual.npy"), &[2], false, &[0.0, 1.0]);
        let other = resolve(dir.path(), &src(Some("dual.npy")), 2, 8).expect("mesh");
        assert_ne!(m.digest, other.digest);
    }

    #[test]
    fn bad_maps_and_cells_are_refused_naming_the_file() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        square(dir.path());
        let msg = |e: CromError| {
            assert_eq!(e.exit_code(), 2);
            e.to_string()
        };
        // No map, and fewer dual entries than nodes.
        let e = msg(resolve(dir.path(), &src(None), 2, 0).expect_err("no map"));
        assert!(e.contains("dual_nodes") && e.contains("nodes.npy"), "{e}");
        // A node given twice.
        write_npy(&dir.path().join("dual.npy"), &[2], false, &[1.0, 1.0]);
        let e = msg(resolve(dir.path(), &src(Some("dual.npy")), 2, 0).expect_err("twice"));
        assert!(e.contains("dual.npy") && e.contains("node 1"), "{e}");
        // An index out of range.
        write_npy(&dir.path().join("dual.npy"), &[2], false, &[1.0, 4.0]);
        let e = msg(resolve(dir.path(), &src(Some("dual.npy")), 2, 0).expect_err("range"));
        assert!(e.contains("entry 1 is 4"), "{e}");
        // A primal field that is not whole per node.
        let e = msg(resolve(dir.path(), &src(None), 4, 6).expect_err("dofs"));
        assert!(e.contains("6 entries"), "{e}");
        // A cell index out of range.
        write_npy(&dir.path().join("cells.npy"), &[2, 3], false, &[0.0, 1.0, 3.0, 1.0, 2.0, 7.0]);
        let e = msg(resolve(dir.path(), &src(None), 4, 0).expect_err("cells"));
        assert!(e.contains("cells.npy") && e.contains("row 1, column 2 is 7"), "{e}");
    }
}
