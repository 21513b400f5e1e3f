//! XDMF sidecars: small XML files that point ParaView at the HDF5 datasets of a mesh.

use std::path::Path;

use crate::error::CromError;

/// Write `<xdmf>` describing the mesh in `h5_name` (same directory): `nodes` (n x 2, XY) and
/// `cells` (n_cells x nodes_per_cell): 2 → Polyline, 4 → Quadrilateral. `node_fields` are 1-D
/// node datasets shown as attributes (e.g. body ids).
pub fn write_mesh_xdmf(
    path: &Path,
    h5_name: &str,
    n_nodes: usize,
    n_cells: usize,
    nodes_per_cell: usize,
    cell_fields: &[&str],
) -> Result<(), CromError> {
    let topology = match nodes_per_cell {
        2 => "TopologyType=\"Polyline\" NodesPerElement=\"2\"".to_string(),
        _ => "TopologyType=\"Quadrilateral\"".to_string(),
    };
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
      <Geometry GeometryType="XY">
        <DataItem Dimensions="{n_nodes} 2" NumberType="Float" Precision="8" Format="HDF">{h5_name}:/nodes</DataItem>
      </Geometry>
{attrs}    </Grid>
  </Domain>
</Xdmf>
"#
    );
    std::fs::write(path, xml).map_err(|e| CromError::io(path, "writing the XDMF sidecar", e))
}
