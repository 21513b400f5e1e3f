//! The human names of a finished study (`STORE/scenes/<scene>/…`, see
//! [`crate::store::published`]): which artifact file each name stands for.

use std::collections::BTreeMap;

use crom_schemas::artifact::published::LAYOUT_VERSION;
use crom_schemas::SceneConfig;

use super::run::RunOutput;
use crate::store::published::{Entry, Study};

/// The names of `out`, the result of a finished run of `scene` (`online`: with the online
/// stage and the report): each node's published names, as its stage declares them.
pub fn study(scene: &SceneConfig, out: &RunOutput, online: bool) -> Study {
    let mut entries: BTreeMap<String, Entry> = BTreeMap::new();
    for node in &out.nodes {
        for p in &node.published {
            let entry = Entry { relocate: p.relocate, ..Entry::new(node.kind, &node.key, p.file.as_deref()) };
            entries.insert(p.name.clone(), entry);
        }
    }
    Study {
        layout_version: LAYOUT_VERSION,
        scene: scene.scene.name.clone(),
        crom_version: env!("CARGO_PKG_VERSION").to_string(),
        created_unix: crate::store::fs::unix_now(),
        online,
        parameter_names: scene.parameter.names().iter().map(|s| s.to_string()).collect(),
        entries,
        withdrawn: BTreeMap::new(),
    }
}
