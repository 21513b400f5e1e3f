//! From the scene files' specifications (`crom-schemas`) to the stage parameters, so that the
//! pipeline, the benchmarks and the tests all build the scenes from `data/scenes/*.toml`.

use crom_schemas::scene::{HertzSpec, IroningSpec, MaterialSpec};

use super::{HertzParams, IroningParams, Material};

impl From<&MaterialSpec> for Material {
    fn from(m: &MaterialSpec) -> Self {
        Material {
            young: m.young,
            poisson: m.poisson,
            selective: m.integration == crom_schemas::scene::Integration::Selective,
        }
    }
}

impl From<&HertzSpec> for HertzParams {
    fn from(h: &HertzSpec) -> Self {
        HertzParams { radius: h.radius, material: (&h.material).into(), n_arc: h.n_arc, n_side: None }
    }
}

impl From<&IroningSpec> for IroningParams {
    fn from(i: &IroningSpec) -> Self {
        IroningParams {
            slab_length: i.slab.length,
            slab_height: i.slab.height,
            slab_nx: i.slab.nx,
            slab_ny: i.slab.ny,
            slab: (&i.slab.material).into(),
            iron_width: i.iron.width,
            iron_height: i.iron.height,
            sole_radius: i.iron.sole_radius,
            iron_nx: i.iron.nx,
            iron_ny: i.iron.ny,
            iron: (&i.iron.material).into(),
            contact_x: i.iron.contact_x,
            d_y: i.d_y,
        }
    }
}
