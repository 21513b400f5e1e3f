//! XDMF sidecars: small XML files that point ParaView at the HDF5 datasets of a mesh.

use std::path::Path;

use crate::error::CromError;

/// The XDMF topology attributes of cells of `nodes_per_cell` nodes in `dim` dimensions: 2 →
/// Polyline, 3 → Triangle, 4 → Quadrilateral (Tetrahedron in 3-D), 8 → Hexahedron.
fn topology(nodes_per_cell: usize, dim: usize) -> String {
    match (nodes_per_cell, dim) {
        (2, _) => "TopologyType=\"Polyline\" NodesPerElement=\"2\"".to_string(),
        (3, _) => "TopologyType=\"Triangle\"".to_string(),
        (4, 3) => "TopologyType=\"Tetrahedron\"".to_string(),
        (8, _) => "TopologyType=\"Hexahedron\"".to_string(),
        _ => "TopologyType=\"Quadrilateral\"".to_string(),
    }
}

/// `GeometryType` of nodes with `dim` coordinates (2: XY, 3: XYZ).
fn geometry(dim: usize) -> &'static str {
    if dim == 3 {
        "XYZ"
    } else {
        "XY"
    }
}

/// Write `<xdmf>` describing the mesh in `h5_name` (same directory): `nodes` (n x dim, XY or
/// XYZ) and `cells` (n_cells x nodes_per_cell, [`topology`]). `cell_fields` are 1-D cell
/// datasets shown as attributes (e.g. body ids).
pub fn write_mesh_xdmf(
    path: &Path,
    h5_name: &str,
    (n_nodes, dim): (usize, usize),
    n_cells: usize,
    nodes_per_cell: usize,
    cell_fields: &[&str],
) -> Result<(), CromError> {
    let topology = topology(nodes_per_cell, dim);
    let geometry = geometry(dim);
    let mut attrs = String::new();
    for f in cell_fields {
        attrs.push_str(&format!(
            "      <Attribute Name=\"{f}\" AttributeType=\"Scalar\" Center=\"Cell\">\n        <DataItem Dimensions=\"{n_cells}\" NumberType=\"UInt\" Precision=\"8\" Format=\"HDF\">{h5_name}:/{f}</DataItem>\n      </Attribute>\n"
        ));
    }
    let xml = format!(
        r#"<?xml version="1.0" ?>
<Xdmf Version="3.0">
  <Domain>
    <Grid Name="mesh" GridType="Uniform">
      <Topology {topology} NumberOfElements="{n_cells}">
        <DataItem Dimensions="{n_cells} {nodes_per_cell}" NumberType="UInt" Precision="8" Format="HDF">{h5_name}:/cells</DataItem>
      </Topology>
      <Geometry GeometryType="{geometry}">
        <DataItem Dimensions="{n_nodes} {dim}" NumberType="Float" Precision="8" Format="HDF">{h5_name}:/nodes</DataItem>
      </Geometry>
{attrs}    </Grid>
  </Domain>
</Xdmf>
"#
    );
    std::fs::write(path, xml).map_err(|e| CromError::io(path, "writing the XDMF sidecar", e))
}

/// One attribute of a time step: a point (`Node`) or cell field stored in an HDF5 dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesAttribute {
    /// Attribute name shown in ParaView.
    pub name: String,
    /// `Scalar` or `Vector`.
    pub kind: &'static str,
    /// `Node` or `Cell`.
    pub center: &'static str,
    /// Dataset dimensions.
    pub dims: Vec<usize>,
    /// `Float` or `UInt`.
    pub number: &'static str,
    /// `file.h5:/path/of/dataset`, the file relative to the XDMF.
    pub reference: String,
}

/// One step of a temporal collection.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesStep {
    /// Grid name (e.g. `gamma=0.25` or `mode 3`).
    pub name: String,
    /// Time value of the step (strictly increasing over the steps).
    pub time: f64,
    /// Its fields.
    pub attributes: Vec<SeriesAttribute>,
}

/// The mesh of a series: `mesh_ref` is the mesh file relative to the XDMF (`nodes`, `cells`).
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesMesh {
    /// Mesh HDF5 file, relative to the XDMF.
    pub mesh_ref: String,
    /// Nodes.
    pub n_nodes: usize,
    /// Cells.
    pub n_cells: usize,
    /// Nodes per cell (the topology with `dim`: see `topology`).
    pub nodes_per_cell: usize,
    /// Coordinates per node in the mesh file (2 or 3).
    pub dim: usize,
}

/// An XDMF 3 temporal collection in the layout of meshio's `TimeSeriesWriter` (which ParaView
/// and meshio's `TimeSeriesReader` read): the collection, then one uniform grid `mesh` whose
/// topology and geometry every step includes by `xi:include`.
pub fn series_xdmf(name: &str, mesh: &SeriesMesh, steps: &[SeriesStep]) -> String {
    use std::fmt::Write as _;
    let esc = |s: &str| s.replace('&', "&amp;").replace('"', "&quot;").replace('<', "&lt;").replace('>', "&gt;");
    let (n_nodes, n_cells, npc, m) = (mesh.n_nodes, mesh.n_cells, mesh.nodes_per_cell, &mesh.mesh_ref);
    let topology = topology(npc, mesh.dim);
    let (geometry, dim) = (geometry(mesh.dim), mesh.dim);
    let mut x = String::new();
    let _ = writeln!(x, "<?xml version=\"1.0\" ?>");
    let _ = writeln!(x, "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">");
    let _ = writeln!(x, "  <Domain>");
    let _ = writeln!(x, "    <Grid Name=\"{}\" GridType=\"Collection\" CollectionType=\"Temporal\">", esc(name));
    for s in steps {
        let _ = writeln!(x, "      <Grid Name=\"{}\" GridType=\"Uniform\">", esc(&s.name));
        let _ = writeln!(
            x,
            "        <xi:include xpointer=\"xpointer(//Grid[@Name=&quot;mesh&quot;]/*[self::Topology or self::Geometry])\" />"
        );
        let _ = writeln!(x, "        <Time Value=\"{:e}\" />", s.time);
        for a in &s.attributes {
            let dims: Vec<String> = a.dims.iter().map(usize::to_string).collect();
            let _ = writeln!(
                x,
                "        <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"{}\">\n          <DataItem Dimensions=\"{}\" NumberType=\"{}\" Precision=\"8\" Format=\"HDF\">{}</DataItem>\n        </Attribute>",
                esc(&a.name),
                a.kind,
                a.center,
                dims.join(" "),
                a.number,
                esc(&a.reference)
            );
        }
        let _ = writeln!(x, "      </Grid>");
    }
    let _ = writeln!(x, "    </Grid>");
    let _ = writeln!(x, "    <Grid Name=\"mesh\" GridType=\"Uniform\">");
    let _ = writeln!(x, "      <Topology {topology} NumberOfElements=\"{n_cells}\">");
    let _ = writeln!(
        x,
        "        <DataItem Dimensions=\"{n_cells} {npc}\" NumberType=\"UInt\" Precision=\"8\" Format=\"HDF\">{}:/cells</DataItem>",
        esc(m)
    );
    let _ = writeln!(x, "      </Topology>");
    let _ = writeln!(x, "      <Geometry GeometryType=\"{geometry}\">");
    let _ = writeln!(
        x,
        "        <DataItem Dimensions=\"{n_nodes} {dim}\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">{}:/nodes</DataItem>",
        esc(m)
    );
    let _ = writeln!(x, "      </Geometry>");
    let _ = writeln!(x, "    </Grid>");
    let _ = writeln!(x, "  </Domain>");
    let _ = writeln!(x, "</Xdmf>");
    x
}

/// The XDMF `text` of a file in the directory `from` (relative to the store root), rewritten
/// for a copy placed `depth` directories below the store root: every HDF5 reference
/// (`>file.h5:/path<`) is made relative to the new place. ParaView resolves references against
/// the path it was given, so an XDMF reached through a symbolic link needs its own copy.
pub fn relocate(text: &str, from: &str, depth: usize) -> String {
    let up = "../".repeat(depth);
    let mut out = String::with_capacity(text.len() + 64);
    let mut rest = text;
    while let Some(open) = rest.find("Format=\"HDF\">") {
        let start = open + "Format=\"HDF\">".len();
        out.push_str(&rest[..start]);
        rest = &rest[start..];
        let end = rest.find('<').unwrap_or(rest.len());
        let item = &rest[..end];
        match item.split_once(":/") {
            Some((file, path)) => {
                out.push_str(&up);
                out.push_str(&normalize(&format!("{from}/{file}")));
                out.push_str(":/");
                out.push_str(path);
            }
            None => out.push_str(item),
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// `a/b/../c` → `a/c` (lexically; the paths here never go above the store root).
fn normalize(path: &str) -> String {
    let mut parts: Vec<&str> = Vec::new();
    for p in path.split('/') {
        match p {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            _ => parts.push(p),
        }
    }
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relocated_references_reach_the_same_files() {
        let text = "<DataItem Format=\"HDF\">views.h5:/steps/00000/pressure</DataItem>\n<DataItem Format=\"HDF\">../../mesh/k/mesh.h5:/nodes</DataItem>";
        let out = relocate(text, "views/abc", 3);
        assert!(out.contains(">../../../views/abc/views.h5:/steps/00000/pressure<"), "{out}");
        assert!(out.contains(">../../../mesh/k/mesh.h5:/nodes<"), "{out}");
        // Unchanged apart from the references.
        assert_eq!(relocate("<a>no data items</a>", "x/y", 3), "<a>no data items</a>");
    }
}
