//! From the scene files' 3-D specifications (`crom-schemas`) to the model parameters.

use crom_schemas::scene::{Hertz3dSpec, Ironing3dSpec, PlaneSpec};

use crate::solid::symmetry::Plane;

fn planes(specs: &[PlaneSpec]) -> Vec<Plane> {
    specs.iter().map(|p| Plane { axis: p.axis.index(), at: p.at }).collect()
}

use super::{Hertz3dParams, Ironing3dParams};

impl From<&Hertz3dSpec> for Hertz3dParams {
    fn from(h: &Hertz3dSpec) -> Self {
        Hertz3dParams {
            radius: h.radius,
            material: (&h.material).into(),
            n: h.n,
            grading: h.grading,
            contact_radius: h.contact_radius,
            planes: planes(&h.symmetry),
        }
    }
}

impl From<&Ironing3dSpec> for Ironing3dParams {
    fn from(i: &Ironing3dSpec) -> Self {
        let (b, d) = (&i.block, &i.die);
        Ironing3dParams {
            block: [b.length, b.depth, b.height],
            block_n: [b.nx, b.ny, b.nz],
            block_material: (&b.material).into(),
            die: [d.width, d.depth, d.height],
            die_n: [d.nx, d.ny, d.nz],
            die_material: (&d.material).into(),
            sole_radius: d.sole_radius,
            contact_x: d.contact_x,
            d_z: i.d_z,
            slave_box: [i.slaves.x_min, i.slaves.x_max, i.slaves.y_max],
            planes: planes(&i.symmetry),
        }
    }
}
