//! The human names of a finished study (`STORE/scenes/<scene>/…`, see
//! [`crate::store::published`]): which artifact file each name stands for.

use std::collections::BTreeMap;

use crom_schemas::artifact::{
    self as a, published::COMPARISON_DIR, published::NESTED_DIR, published::REPORT, ArtifactKind,
};
use crom_schemas::SceneConfig;

use super::run::RunOutput;
use crate::store::published::{Entry, Study};

/// The names of `out`, the result of a finished run of `scene` (`online`: with the online
/// stage and the report).
pub fn study(scene: &SceneConfig, out: &RunOutput, online: bool) -> Study {
    use ArtifactKind as K;
    let mut e: BTreeMap<String, Entry> = BTreeMap::new();
    let mut put = |name: String, kind: K, key: &crate::cache::Key, file: Option<&str>| {
        e.insert(name, Entry::new(kind, key, file));
    };
    if let Some(mesh) = &out.mesh {
        put("mesh.h5".into(), K::Mesh, mesh, Some(a::mesh::FILE));
        put("mesh.xdmf".into(), K::Mesh, mesh, Some(a::mesh::XDMF));
    }
    let sets = std::iter::once(("train", &out.train)).chain(out.test.as_ref().map(|t| ("test", t)));
    for (set, key) in sets {
        put(format!("{set}.h5"), K::TrainingSet, key, Some(a::trainset::FILE));
        put(format!("{set}_solver_stats.parquet"), K::TrainingSet, key, Some(a::trainset::STATS));
        put(format!("{set}_solver_timings.parquet"), K::TrainingSet, key, Some(a::trainset::TIMINGS));
    }
    for (i, key) in out.nested_sets.iter().enumerate() {
        let level = i + 1;
        put(format!("{NESTED_DIR}/level-{level}.h5"), K::TrainingSet, key, Some(a::trainset::FILE));
        let stats = format!("{NESTED_DIR}/level-{level}_solver_stats.parquet");
        put(stats, K::TrainingSet, key, Some(a::trainset::STATS));
        let timings = format!("{NESTED_DIR}/level-{level}_solver_timings.parquet");
        put(timings, K::TrainingSet, key, Some(a::trainset::TIMINGS));
    }
    put("basis.h5".into(), K::Basis, &out.basis, Some(a::basis::FILE));
    put("compactness.parquet".into(), K::Compactness, &out.compactness, Some(a::compactness::FILE));
    put("generalization.parquet".into(), K::Generalization, &out.generalization, Some(a::metrics::GENERALIZATION));
    put("specificity.parquet".into(), K::Specificity, &out.specificity, Some(a::metrics::SPECIFICITY));
    if let Some(k) = &out.nested {
        put("nested.parquet".into(), K::Nested, k, Some(a::metrics::NESTED));
    }
    if let Some(k) = &out.rom {
        put("rom_errors.parquet".into(), K::Rom, k, Some(a::rom::ERRORS));
        put("tradeoff.parquet".into(), K::Rom, k, Some(a::rom::TRADEOFF));
        put("rom_timings.parquet".into(), K::Rom, k, Some(a::rom::TIMINGS));
        put("tradeoff_timings.parquet".into(), K::Rom, k, Some(a::rom::TRADEOFF_TIMINGS));
        put("online.h5".into(), K::Rom, k, Some(a::rom::ONLINE));
    }
    if let Some(k) = &out.model {
        put("model.h5".into(), K::Model, k, Some(a::model::FILE));
        put("reconstruction.h5".into(), K::Model, k, Some(a::model::RECONSTRUCTION));
        put("model_speed.parquet".into(), K::Model, k, Some(a::model::SPEED));
    }
    let cmp = |file: &str| format!("{COMPARISON_DIR}/{file}");
    if let Some(k) = &out.comparison {
        use a::comparison as c;
        for file in [c::CURVES, c::NESTED, c::CELLS, c::REACHED, c::FACTS, c::TIMINGS] {
            put(cmp(file), K::Comparison, k, Some(file));
        }
    }
    if let Some(k) = &out.online_comparison {
        for file in [a::comparison::ONLINE, a::comparison::ONLINE_TIMINGS] {
            put(cmp(file), K::OnlineComparison, k, Some(file));
        }
    }
    if let Some(k) = &out.report {
        put(REPORT.into(), K::Report, k, None);
    }
    // XDMF files are copied with their references relocated (ParaView does not resolve links).
    let mut xdmf = |name: String, key: &crate::cache::Key, file: &str| {
        e.insert(name, Entry { relocate: true, ..Entry::new(K::Views, key, Some(file)) });
    };
    for (subject, key) in &out.views {
        if subject == "basis" {
            for (group, _) in super::views::BASIS_VIEWS {
                xdmf(format!("basis/{group}.xdmf"), key, &format!("{group}.xdmf"));
            }
        } else if subject == "online" {
            xdmf("online.xdmf".to_string(), key, a::views::ONLINE_XDMF);
        } else if let Some(level) = subject.strip_prefix("nested-") {
            xdmf(format!("{NESTED_DIR}/level-{level}.xdmf"), key, a::views::SET_XDMF);
        } else {
            xdmf(format!("{subject}.xdmf"), key, a::views::SET_XDMF);
        }
    }
    Study {
        layout_version: a::published::LAYOUT_VERSION,
        scene: scene.scene.name.clone(),
        crom_version: env!("CARGO_PKG_VERSION").to_string(),
        created_unix: crate::store::fs::unix_now(),
        online,
        parameter_names: scene.parameter.names().iter().map(|s| s.to_string()).collect(),
        entries: e,
        withdrawn: BTreeMap::new(),
    }
}
