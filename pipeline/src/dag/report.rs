//! Report stage: keys the report by everything it shows, reads those artifacts into
//! [`ReportData`] and renders it with [`crate::report::render`]. A cached artifact like any
//! other.

use std::collections::BTreeMap;

use crom_schemas::artifact::{
    basis as bnames, compactness as cnames, comparison as cmp_names, mesh as mnames, metrics as metric_names,
    model as model_names, rom as rnames, ArtifactKind,
};
use crom_schemas::SceneConfig;
use crom_stages::rom::ReducedModel;
use serde_json::json;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::inputs::bases;
use super::inputs::loaded::Loaded;
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::h5::H5In;
use crate::io::model::StoredModel;
use crate::io::table::{read_parquet, Column, Table};
use crate::report::{bodies, render, ComparisonData, ModelFacts, ReportData, Surface};
use crate::store::Store;

/// The report is determined by its inputs and by the scene it shows: its name, description,
/// parameter names and settings are text in the report, so an edit of any of them renders it
/// again.
#[derive(Debug, Clone, serde::Serialize)]
pub(crate) struct ReportKey {
    scene: SceneConfig,
    /// Parts of the study not planned, with their reasons (an external scene's), stated in the
    /// report.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    skipped: Vec<String>,
}

impl StageKey for ReportKey {
    const KIND: ArtifactKind = ArtifactKind::REPORT;
    /// Bump when the report's content changes (10: the sampled-surface series of the trade-off
    /// figure; 11: the stored reduced model among the facts; 12: the captions say that times are
    /// over the timed sample of test points, and a full study's report lists what its plan
    /// skipped, and a surface-drawn scene the full-order and online pressure side by side; 13:
    /// the online error figures say how many points a sampled large set shows; 14: a chart's
    /// legend moves to the corner that covers the fewest drawn points, and the online error
    /// figures' caption names the exact solve they show). The scene joined the key without a
    /// bump: the key changed with it.
    const ALGORITHM_VERSION: u32 = 14;
}

/// The artifacts a report shows.
#[derive(Debug, Clone)]
pub struct ReportInputs {
    /// Mesh (none for an external scene without one).
    pub mesh: Option<Key>,
    /// Training set.
    pub train: Key,
    /// Bases.
    pub basis: Key,
    /// Compactness table.
    pub compactness: Key,
    /// Online ROM tables (none for an external scene: no full-order operators).
    pub rom: Option<Key>,
    /// G(m) table.
    pub generalization: Key,
    /// S(m) table.
    pub specificity: Key,
    /// H(n) table, for scenes with nested levels.
    pub nested: Option<Key>,
    /// The dual approximations compared, for scenes with `[comparison]`.
    pub comparison: Option<Key>,
    /// Their online solves, for scenes with `[comparison]`.
    pub online_comparison: Option<Key>,
    /// The stored reduced model (none for an external scene).
    pub model: Option<Key>,
}

/// The report's key spec: the scene and every artifact it shows.
fn spec(key: &ReportKey, inputs: &ReportInputs) -> KeySpec {
    let optional = |spec: KeySpec, name: &str, key: &Option<Key>| match key {
        Some(k) => spec.input(name, k),
        None => spec,
    };
    let spec = optional(KeySpec::of(key), "mesh", &inputs.mesh)
        .input("train", &inputs.train)
        .input("basis", &inputs.basis)
        .input("compactness", &inputs.compactness);
    let spec = optional(spec, "rom", &inputs.rom)
        .input("generalization", &inputs.generalization)
        .input("specificity", &inputs.specificity);
    let spec = match &inputs.nested {
        Some(k) => spec.input("nested", k),
        None => spec,
    };
    let spec = match &inputs.comparison {
        Some(k) => spec.input("comparison", k),
        None => spec,
    };
    let spec = match &inputs.online_comparison {
        Some(k) => spec.input("online-comparison", k),
        None => spec,
    };
    optional(spec, "model", &inputs.model)
}

/// The report over the artifacts it shows.
#[derive(Debug)]
pub(crate) struct ReportStage {
    pub spec: KeySpec,
    pub settings: ReportKey,
    /// The artifacts shown, by role.
    pub shows: ReportInputs,
    /// The same, as the graph's inputs.
    pub inputs: Vec<Input>,
}

impl ReportStage {
    /// The report of `scene`, stating the parts of the study `skipped` (with their reasons);
    /// `inputs`: the nodes it reads (their keys are the ones in `shows`).
    pub(crate) fn plan(scene: &SceneConfig, shows: ReportInputs, inputs: Vec<Input>, skipped: Vec<String>) -> Self {
        let settings = ReportKey { scene: scene.clone(), skipped };
        Self { spec: spec(&settings, &shows), settings, shows, inputs }
    }
}

impl StageDef for ReportStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::REPORT
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        self.inputs.iter().collect()
    }
    fn published(&self) -> Vec<Published> {
        vec![Published { name: crom_schemas::artifact::published::REPORT.into(), file: None, relocate: false }]
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        run(ctx, &self.spec, &self.settings, &self.shows)
    }
}

/// Build (or find) the report of `scene`; returns its key.
fn run(ctx: &mut Ctx<'_>, spec: &KeySpec, settings: &ReportKey, inputs: &ReportInputs) -> Result<Key, CromError> {
    let (store, loaded) = (ctx.store, std::sync::Arc::clone(&ctx.loaded));
    let scene = &settings.scene;
    ctx.single(ArtifactKind::REPORT, "report", spec, |staging| {
        let mut data = gather(store, &loaded, inputs)?;
        data.skipped.clone_from(&settings.skipped);
        let figures = render(scene, &data, &staging.path(""))?;
        Ok(BTreeMap::from([("figures".to_string(), json!(figures))]))
    })
}

/// The online pressure at every test point of `online.h5`, its error against the full-order one
/// and the points; `None` without test points.
fn online_pressure(path: &std::path::Path) -> Result<Option<crate::report::OnlinePressure>, CromError> {
    let h5 = H5In::open(path)?;
    let (online, error) = (h5.matrix("dual")?, h5.matrix("dual_error")?);
    if online.cols == 0 || error.cols != online.cols || error.rows != online.rows {
        return Ok(None);
    }
    let parameters: Vec<Vec<f64>> = match h5.shape("parameters")?.len() {
        1 => h5.vec_f64("parameters")?.into_iter().map(|v| vec![v]).collect(),
        _ => {
            let p = h5.matrix("parameters")?;
            (0..p.rows).map(|i| (0..p.cols).map(|j| p.data[i + j * p.rows]).collect()).collect()
        }
    };
    Ok(Some(crate::report::OnlinePressure { parameters, online, error }))
}

fn gather(store: &Store, loaded: &Loaded, inputs: &ReportInputs) -> Result<ReportData, CromError> {
    let train = loaded.set(store, &inputs.train)?;
    let mesh = match &inputs.mesh {
        Some(k) => Some(H5In::open(&store.dir(ArtifactKind::MESH, k).join(mnames::FILE))?),
        None => None,
    };
    let mut contact_x: Vec<f64> = (0..train.dual.rows).map(|i| i as f64).collect();
    let (mut line_x, mut geometry, mut surface, mut profile) = (Vec::new(), None, None, None);
    if let Some(mesh) = &mesh {
        let nodes = mesh.matrix(mnames::NODES)?; // n x dim, column-major
        let contact = mesh.vec_u64(mnames::CONTACT_NODES)?;
        let cells = mesh.shape(mnames::CELLS)?;
        let per = cells.get(1).copied().unwrap_or(4).max(1);
        let external = mesh.contains_attr("source");
        contact_x = contact.iter().map(|&i| nodes.data[i as usize]).collect();
        if per == 2 {
            line_x = nodes.col(0).to_vec();
        }
        let planar = nodes.cols == 2 && per > 2;
        let xy = || (0..nodes.rows).map(|i| [nodes.data[i], nodes.data[i + nodes.rows]]).collect::<Vec<_>>();
        let cells_of = || -> Result<Vec<Vec<usize>>, CromError> {
            let flat = mesh.vec_u64(mnames::CELLS)?;
            Ok(flat.chunks(per).map(|c| c.iter().map(|&i| i as usize).collect()).collect())
        };
        if mesh.attr_u64("dofs_per_node")? == 2 && (!external || planar) {
            geometry = Some(bodies::Geometry {
                nodes: xy(),
                cells: cells_of()?,
                cell_body: mesh.vec_u64(mnames::CELL_BODY)?,
                node_body: mesh.vec_u64(mnames::NODE_BODY)?,
                contact: contact.iter().map(|&i| i as usize).collect(),
            });
        }
        if external && planar {
            surface = Some(Surface {
                nodes: xy(),
                cells: cells_of()?,
                contact: contact.iter().map(|&i| i as usize).collect(),
            });
        }
        if nodes.cols == 3 && per == 8 {
            // a native 3-D scene: the slave facets (hexahedron faces whose four nodes are all
            // slaves) seen from above, as the contact surface to draw the pressure on, and the
            // profile along the symmetry plane through the lowest y of the slaves
            let is_slave: std::collections::BTreeSet<usize> = contact.iter().map(|&i| i as usize).collect();
            let faces = [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];
            let cells: Vec<Vec<usize>> = cells_of()?
                .iter()
                .flat_map(|h| faces.iter().map(move |f| f.iter().map(|&k| h[k]).collect::<Vec<usize>>()))
                .filter(|q| q.iter().all(|n| is_slave.contains(n)))
                .collect();
            surface = Some(Surface { nodes: xy(), cells, contact: contact.iter().map(|&i| i as usize).collect() });
            let y = |i: u64| nodes.data[i as usize + nodes.rows];
            let low = contact.iter().map(|&i| y(i)).fold(f64::INFINITY, f64::min);
            let extent = contact.iter().map(|&i| y(i)).fold(f64::NEG_INFINITY, f64::max) - low;
            profile = Some(
                (0..contact.len()).filter(|&k| (y(contact[k]) - low).abs() <= 1e-9 * extent.abs().max(1.0)).collect(),
            );
        }
    }
    let conditioning = conditioning(mesh.as_ref(), store, &inputs.basis)?;
    let b = bases::load_full(store, &inputs.basis)?;
    let table = read_parquet(&store.dir(ArtifactKind::COMPACTNESS, &inputs.compactness).join(cnames::FILE))?;
    let mut compactness: BTreeMap<(String, String), Vec<f64>> = BTreeMap::new();
    if let (Some(f), Some(bs), Some(v)) = (table.strs("field"), table.strs("basis"), table.f64s("value")) {
        for ((f, b), v) in f.iter().zip(bs).zip(v) {
            compactness.entry((f.clone(), b.clone())).or_default().push(*v);
        }
    }
    let (rom_errors, tradeoff) = match &inputs.rom {
        Some(k) => {
            let rom_dir = store.dir(ArtifactKind::ROM, k);
            (
                joined(&rom_dir, rnames::ERRORS, rnames::TIMINGS, &QUERY_KEYS)?,
                joined(&rom_dir, rnames::TRADEOFF, rnames::TRADEOFF_TIMINGS, &TRADE_KEYS)?,
            )
        }
        None => (Table::default(), Table::default()),
    };
    let model = match &inputs.model {
        Some(k) => Some(model_facts(store, k)?),
        None => None,
    };
    let online_pressure = match (&inputs.rom, &surface) {
        (Some(k), Some(_)) => online_pressure(&store.dir(ArtifactKind::ROM, k).join(rnames::ONLINE))?,
        _ => None,
    };
    Ok(ReportData {
        model,
        online_pressure,
        contact_x,
        profile,
        line_x,
        geometry,
        surface,
        online: inputs.rom.is_some(),
        skipped: Vec::new(),
        mesh: inputs.mesh.is_some(),
        train,
        primal_sv: b.primal_sv,
        dual_sv: b.dual_sv,
        ranks: b.ranks,
        compactness,
        rom_errors,
        tradeoff,
        generalization: read_parquet(
            &store.dir(ArtifactKind::GENERALIZATION, &inputs.generalization).join(metric_names::GENERALIZATION),
        )?,
        specificity: read_parquet(
            &store.dir(ArtifactKind::SPECIFICITY, &inputs.specificity).join(metric_names::SPECIFICITY),
        )?,
        nested: match &inputs.nested {
            Some(k) => Some(read_parquet(&store.dir(ArtifactKind::NESTED, k).join(metric_names::NESTED))?),
            None => None,
        },
        comparison: match &inputs.comparison {
            Some(k) => {
                let dir = store.dir(ArtifactKind::COMPARISON, k);
                Some(ComparisonData {
                    curves: read_parquet(&dir.join(cmp_names::CURVES))?,
                    reached: read_parquet(&dir.join(cmp_names::REACHED))?,
                    facts: read_parquet(&dir.join(cmp_names::FACTS))?,
                    timings: read_parquet(&dir.join(cmp_names::TIMINGS))?,
                    nested: read_parquet(&dir.join(cmp_names::NESTED))?,
                    cells: read_parquet(&dir.join(cmp_names::CELLS))?,
                    online: match &inputs.online_comparison {
                        Some(k) => {
                            let dir = store.dir(ArtifactKind::ONLINE_COMPARISON, k);
                            Some(joined(
                                &dir,
                                cmp_names::ONLINE,
                                cmp_names::ONLINE_TIMINGS,
                                &["scene", "approximation", "m"],
                            )?)
                        }
                        None => None,
                    },
                })
            }
            None => None,
        },
        conditioning,
    })
}

/// The conditioning table: the stiffness estimate from the mesh artifact and, per CPG basis,
/// the Gram's condition estimate after the last selection and its largest over the steps.
fn conditioning(mesh: Option<&H5In>, store: &Store, basis: &Key) -> Result<Table, CromError> {
    let mut rows: Vec<(String, String, f64)> = Vec::new();
    for (name, what) in [
        (mnames::STIFFNESS_CONDITION, "condition estimate lambda_max / lambda_min (a lower bound on kappa_2)"),
        (mnames::STIFFNESS_LAMBDA_MAX, "largest eigenvalue estimate"),
        (mnames::STIFFNESS_LAMBDA_MIN, "smallest eigenvalue estimate"),
    ] {
        if let Some(mesh) = mesh.filter(|m| m.contains_attr(name)) {
            rows.push(("stiffness K_FF".into(), what.into(), mesh.attr_f64(name)?));
        }
    }
    let h5 = H5In::open(&store.dir(ArtifactKind::BASIS, basis).join(bnames::FILE))?;
    for group in [bnames::DUAL_CPG, bnames::DUAL_CPG_TRUNCATED] {
        let path = format!("{group}/{}", bnames::GRAM_RCOND);
        let rcond = h5.vec_f64(&path)?;
        // kappa = 1 / rcond; a zero rcond (a dependent generator) is reported as such, not as inf.
        let kappa = |r: f64| if r > 0.0 { 1.0 / r } else { f64::NAN };
        if let Some(&last) = rcond.last() {
            let subject = format!("CPG Gram, {group} ({} generators)", rcond.len());
            rows.push((subject.clone(), "kappa_1 estimate after the last selection".into(), kappa(last)));
            let worst = rcond.iter().copied().fold(f64::INFINITY, f64::min);
            rows.push((subject, "largest kappa_1 estimate over the selections".into(), kappa(worst)));
        }
    }
    Ok(Table::default()
        .with("subject", Column::Str(rows.iter().map(|r| r.0.clone()).collect()))
        .with("quantity", Column::Str(rows.iter().map(|r| r.1.clone()).collect()))
        .with("value", Column::F64(rows.iter().map(|r| r.2).collect())))
}

/// Columns that identify a row of the rom stage's query tables (with the parameter columns).
const QUERY_KEYS: [&str; 6] = ["scene", "set", "dual_basis", "algorithm", "r_primal", "r_dual"];
/// Columns that identify a row of the trade-off tables.
const TRADE_KEYS: [&str; 5] = ["scene", "algorithm", "dual_basis", "r_primal", "r_dual"];

/// A results table with its timings table (same rows) beside it.
fn joined(dir: &std::path::Path, results: &str, timings: &str, keys: &[&str]) -> Result<Table, CromError> {
    let a = read_parquet(&dir.join(results))?;
    let b = read_parquet(&dir.join(timings))?;
    a.join_rows(b, keys).ok_or_else(|| {
        CromError::artifact(
            dir.join(timings),
            format!("its rows do not match those of {results}"),
            "delete the rom artifact and rerun",
        )
    })
}

/// The stored model's facts: `model.h5`'s attributes and the measured speed-up.
fn model_facts(store: &Store, key: &Key) -> Result<ModelFacts, CromError> {
    let dir = store.dir(ArtifactKind::MODEL, key);
    let file = dir.join(model_names::FILE);
    let m = StoredModel::read(&file)?;
    let speed = read_parquet(&dir.join(model_names::SPEED))?;
    // the ranks as `crom query` reports them (a registered basis: its most generators per query)
    let ranks = ReducedModel::from_parts(&m.parts)
        .map_err(|e| CromError::artifact(&file, e, "run `crom run SCENE` again: it rebuilds the model"))?
        .stored_ranks();
    Ok(ModelFacts {
        dual_basis: m.dual_basis.clone(),
        algorithm: m.algorithm.clone(),
        ranks,
        points: m.measured.points,
        converged: m.measured.converged,
        median_dual_error: m.measured.median_dual_error,
        median_primal_error: m.measured.median_primal_error,
        speedup: speed.f64s("speedup").and_then(|v| v.first().copied()).filter(|v| v.is_finite()),
        example: m
            .parameter_names
            .iter()
            .zip(m.parameter_min.iter().zip(&m.parameter_max))
            .map(|(n, (lo, hi))| (n.clone(), 0.5 * (lo + hi)))
            .collect(),
    })
}
