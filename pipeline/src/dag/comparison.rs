//! The comparison: the scene's `[comparison]` as a list of dual approximations,
//! each its own stage ([`super::approximation`] offline, [`super::approximation_online`]
//! online), and the two stages that put them side by side. A side-by-side artifact
//! (`comparison`, `online-comparison`) holds every approximation's tables concatenated in the
//! scene file's order, so a pandas user opens one file with an `approximation` column; its key
//! is the keys of the approximations it gathers, so changing one approximation's settings
//! recomputes that approximation and this cheap concatenation, nothing else.

use std::collections::BTreeMap;

use crom_schemas::artifact::{comparison as names, mesh as mnames, ArtifactKind};
use crom_schemas::comparison::{ApproximationSpec, BasisSpec, ComparisonSpec, InterpolationSpec, MapSpec};
use crom_schemas::SceneConfig;
use crom_stages::dual::{Approach, Inner, Interpolation, MapKind};
use serde::Serialize;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5In;
use crate::io::table::{read_parquet, Table};
use crate::store::Store;

/// One approximation of a comparison.
#[derive(Debug, Clone)]
pub(crate) struct Item {
    /// Its settings (a `local` entry with one cell count), part of its stage's key.
    pub spec: ApproximationSpec,
    /// What `crom_stages::dual` builds.
    pub approach: Approach,
    /// Its name in the tables and the plan.
    pub name: String,
}

/// The approximations of a comparison, in table order (a `local` entry gives one per cell
/// count).
pub(crate) fn items(cmp: &ComparisonSpec) -> Vec<Item> {
    cmp.approximations.iter().flat_map(ApproximationSpec::expand).map(|spec| item_of(&spec)).collect()
}

/// The approximation an expanded entry (a `local` entry with one cell count) stands for.
pub(crate) fn item_of(spec: &ApproximationSpec) -> Item {
    Item { approach: approach_of(spec), name: spec.name(), spec: spec.clone() }
}

/// Plan-node name prefixes of an approximation's offline and online stages (`<prefix><name>`);
/// the side-by-side nodes read their parts' names back from them.
pub(crate) const OFFLINE_NODE: &str = "approximation ";
/// See [`OFFLINE_NODE`].
pub(crate) const ONLINE_NODE: &str = "online-approximation ";

/// The scene's comparison settings and its approximation `index` (in [`items`] order); None
/// without `[comparison]` or past its end.
pub(crate) fn item(scene: &SceneConfig, index: usize) -> Option<(&ComparisonSpec, Item)> {
    let cmp = scene.comparison.as_ref()?;
    Some((cmp, items(cmp).into_iter().nth(index)?))
}

/// The approach an expanded entry stands for.
fn approach_of(spec: &ApproximationSpec) -> Approach {
    match spec {
        ApproximationSpec::Pod => Approach::Pod,
        ApproximationSpec::Cpg => Approach::Cpg,
        ApproximationSpec::AngleGreedy => Approach::AngleGreedy,
        ApproximationSpec::Nnmf { iterations } => Approach::Nnmf { iterations: *iterations },
        ApproximationSpec::Local { cells, overlap } => {
            Approach::Local { cells: cells.first().copied().unwrap_or(1), overlap: *overlap }
        }
        ApproximationSpec::Dictionary => Approach::Dictionary,
        ApproximationSpec::Registered { map, interpolation, refine, basis, .. } => {
            let map = match (map, interpolation) {
                (MapSpec::Translate, InterpolationSpec::Nodes) => {
                    MapKind::Translate { interpolation: Interpolation::Nodes }
                }
                (MapSpec::Translate, InterpolationSpec::Linear) => {
                    MapKind::Translate { interpolation: Interpolation::Linear { refine: *refine } }
                }
                (MapSpec::Moments, _) => MapKind::Moments { refine: *refine },
            };
            let inner = match basis {
                BasisSpec::Pod => Inner::Pod,
                BasisSpec::Cpg => Inner::Cpg,
                BasisSpec::Neighbours => Inner::Neighbours,
                BasisSpec::LevelPod => Inner::LevelPod,
            };
            Approach::Registered { map, inner }
        }
    }
}

/// The abscissa of each potential-contact node and, on a 3-D mesh, its coordinate across the
/// travel (y; empty in 2-D), in dual-field order, from the mesh artifact: the registration
/// maps' surface.
pub(crate) fn contact_surface(store: &Store, mesh: &Key) -> Result<(Vec<f64>, Vec<f64>), CromError> {
    let h5 = H5In::open(&store.dir(ArtifactKind::MESH, mesh).join(mnames::FILE))?;
    let nodes = h5.matrix(mnames::NODES)?;
    let contact = h5.vec_u64(mnames::CONTACT_NODES)?;
    let x = contact.iter().map(|&i| nodes.data[i as usize]).collect();
    let across = if nodes.cols == 3 {
        contact.iter().map(|&i| nodes.data[nodes.rows + i as usize]).collect()
    } else {
        Vec::new()
    };
    Ok((x, across))
}

/// What determines a side-by-side artifact besides the approximations it gathers.
#[derive(Debug, Serialize)]
struct GatherKey {
    /// `comparison` or `online-comparison`.
    kind: &'static str,
}

/// The offline side-by-side artifact's key.
#[derive(Debug, Serialize)]
struct ComparisonKey(GatherKey);

impl StageKey for ComparisonKey {
    const KIND: ArtifactKind = ArtifactKind::COMPARISON;
    /// Bump when the concatenation changes.
    const ALGORITHM_VERSION: u32 = 3;
}

/// The online side-by-side artifact's key.
#[derive(Debug, Serialize)]
struct OnlineComparisonKey(GatherKey);

impl StageKey for OnlineComparisonKey {
    const KIND: ArtifactKind = ArtifactKind::ONLINE_COMPARISON;
    /// Bump when the concatenation changes.
    const ALGORITHM_VERSION: u32 = 4;
}

/// The tables a side-by-side artifact concatenates.
fn files(kind: ArtifactKind) -> &'static [&'static str] {
    match kind {
        ArtifactKind::COMPARISON => {
            &[names::CURVES, names::NESTED, names::CELLS, names::REACHED, names::FACTS, names::TIMINGS]
        }
        _ => &[names::ONLINE, names::ONLINE_TIMINGS],
    }
}

/// The key spec of a side-by-side artifact of `kind` over `parts`: (approximation name, key of
/// its `approximation` or `online-approximation` artifact), in table order.
fn gather_spec(kind: ArtifactKind, parts: &[(String, Key)]) -> KeySpec {
    let mut spec = if kind == ArtifactKind::COMPARISON {
        KeySpec::of(&ComparisonKey(GatherKey { kind: "comparison" }))
    } else {
        KeySpec::of(&OnlineComparisonKey(GatherKey { kind: "online-comparison" }))
    };
    for (name, key) in parts {
        spec = spec.input(name, key);
    }
    spec
}

/// The approximations side by side (`kind`: the offline comparison or the online one), one
/// part per approximation (its name, and its artifact of kind `part_kind`).
#[derive(Debug)]
pub(crate) struct GatherStage {
    pub spec: KeySpec,
    pub kind: ArtifactKind,
    pub part_kind: ArtifactKind,
    pub parts: Vec<(String, Input)>,
}

impl GatherStage {
    pub(crate) fn plan(kind: ArtifactKind, part_kind: ArtifactKind, parts: Vec<(String, Input)>) -> Self {
        let keys: Vec<(String, Key)> = parts.iter().map(|(n, i)| (n.clone(), i.key.clone())).collect();
        Self { spec: gather_spec(kind, &keys), kind, part_kind, parts }
    }
}

impl StageDef for GatherStage {
    fn kind(&self) -> ArtifactKind {
        self.kind
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        self.parts.iter().map(|(_, i)| i).collect()
    }
    /// The side-by-side tables under `comparison/`.
    fn published(&self) -> Vec<Published> {
        let dir = crom_schemas::artifact::published::COMPARISON_DIR;
        files(self.kind).iter().map(|f| Published::file(format!("{dir}/{f}"), f)).collect()
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        let parts: Vec<(String, Key)> = self.parts.iter().map(|(n, i)| (n.clone(), i.key.clone())).collect();
        gather(ctx, &self.spec, self.kind, self.part_kind, &parts)
    }
}

/// Concatenate the tables of `parts` (artifacts of kind `part_kind`) into one artifact of
/// `kind`; returns its key.
fn gather(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    kind: ArtifactKind,
    part_kind: ArtifactKind,
    parts: &[(String, Key)],
) -> Result<Key, CromError> {
    let store = ctx.store;
    let label = if kind == ArtifactKind::COMPARISON { "comparison" } else { "online-comparison" };
    ctx.single(kind, label, spec, |staging| {
        for file in files(kind) {
            let mut all = Table::default();
            for (name, key) in parts {
                let path = store.dir(part_kind, key).join(file);
                all.append(read_parquet(&path)?).map_err(|why| {
                    CromError::artifact(
                        &path,
                        format!("its table does not match the other approximations' ({why}; `{name}`)"),
                        "delete the artifact directory and rerun to recompute it",
                    )
                })?;
            }
            all.write_parquet(&staging.path(file))?;
        }
        Ok(BTreeMap::from([("approximations".to_string(), json!(parts.len()))]))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The schema's names (the plan's and the tables') are the names `crom_stages::dual`
    /// gives the approaches they build.
    #[test]
    fn item_names_are_the_approaches_names() {
        let reg = |map, interpolation, basis| ApproximationSpec::Registered {
            map,
            interpolation,
            refine: 4,
            basis,
            primal_translates: None,
        };
        let cmp = ComparisonSpec {
            max_m: 8,
            loo_folds: 4,
            approximations: vec![
                ApproximationSpec::Pod,
                ApproximationSpec::Cpg,
                ApproximationSpec::AngleGreedy,
                ApproximationSpec::Nnmf { iterations: 7 },
                ApproximationSpec::Local { cells: vec![2, 5], overlap: 0.1 },
                ApproximationSpec::Dictionary,
                reg(MapSpec::Translate, InterpolationSpec::Nodes, BasisSpec::Pod),
                reg(MapSpec::Translate, InterpolationSpec::Linear, BasisSpec::Cpg),
                reg(MapSpec::Moments, InterpolationSpec::Linear, BasisSpec::Cpg),
            ],
        };
        let list = items(&cmp);
        assert_eq!(list.len(), 10);
        for item in &list {
            assert_eq!(item.name, item.approach.name());
        }
        assert_eq!(list[4].approach, Approach::Local { cells: 2, overlap: 0.1 });
        assert_eq!(list[5].spec, ApproximationSpec::Local { cells: vec![5], overlap: 0.1 });
    }
}
