//! The study as data: every stage of a scene's run as a [`Node`] — its name, artifact kind,
//! typed key and the nodes it reads — computed from the scene file alone. Keys are content
//! hashes of a stage's parameters and its inputs' keys ([`crate::cache`]), so the key of every
//! artifact downstream of a snapshot is known before anything is solved. Each node's key comes
//! from the same `spec` function its stage computes with, so the plan and the run cannot
//! disagree (the e2e test `e2e_cluster` checks that a finished run leaves nothing to run).
//!
//! Each node holds its stage as a typed value (`graph::StageDef`): its key spec,
//! computed here once, and its inputs as named fields. The local executor (`dag::run::execute`)
//! walks the nodes in order and runs each node's stage; `crom run --dry-run` prints the plan against the store
//! (what is stored, what would run); `crom status` prints it for a run in progress or
//! finished, with the sharded workers' records ([`crate::executor`]); the Slurm executor
//! takes the snapshot chunks to solve from it.

use std::path::Path;
use std::sync::Arc;

use crom_schemas::artifact::{ArtifactKind, MANIFEST};
use crom_schemas::comparison::ApproximationSpec;
use crom_schemas::SceneConfig;

use super::approximation::{ApproximationStage, SurfaceSource};
use super::approximation_online::OnlineApproximationStage;
use super::basis::BasisStage;
use super::compactness::CompactnessStage;
use super::comparison::{self, GatherStage};
use super::external_mesh::ExternalMeshStage;
use super::graph::{Input, StageDef};
use super::import::ImportStage;
use super::labels::Labels;
use super::mesh;
use super::metrics::{GeneralizationStage, NestedStage, SpecificityStage};
use super::model::ModelStage;
use super::report::{self, ReportStage};
use super::rom::RomStage;
use super::snapshots::{self, Sweep, SweepStage};
use super::trainset::SetStage;
use super::views::{Subject, ViewsStage};
use crate::cache::Key;
use crate::error::CromError;

/// One stage of the study.
#[derive(Debug, Clone)]
pub struct Node {
    /// Stage and subject, e.g. `trainset train`, `views basis`, `snapshots train+test`.
    pub name: String,
    /// Artifact kind.
    pub kind: ArtifactKind,
    /// The artifact's key (for a sweep: its column family's).
    pub key: Key,
    /// Names of the nodes it reads.
    pub inputs: Vec<String>,
    /// Part of the online study (not run by `crom run --offline`).
    pub online: bool,
    /// What runs.
    pub(crate) stage: Arc<dyn StageDef>,
}

impl PartialEq for Node {
    /// Two nodes are the same node when they agree on everything the plan shows.
    fn eq(&self, o: &Self) -> bool {
        (&self.name, self.kind, &self.key, &self.inputs, self.online) == (&o.name, o.kind, &o.key, &o.inputs, o.online)
    }
}

impl Node {
    /// A snapshot sweep (its points are counted by [`Plan::snapshot_state`], not stored as one
    /// artifact).
    pub fn is_sweep(&self) -> bool {
        self.kind == ArtifactKind::SNAPSHOT
    }
}

/// A scene's study as data.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The snapshot sweeps (their chunks are the units of sharded work).
    pub(crate) sweeps: Vec<Sweep>,
    /// The column family the snapshots go to.
    pub family: Key,
    /// An external scene's imported columns (training, then test; none for a native scene).
    pub(crate) imported: Vec<Key>,
    /// Every stage, in an order that respects their inputs.
    pub nodes: Vec<Node>,
    /// Parts of the study not planned, each with its reason (an external scene's
    /// approximations that need what it does not give).
    pub skipped: Vec<String>,
}

/// The nodes of a plan as they are added: each node's inputs must already be there.
#[derive(Default)]
struct Nodes(Vec<Node>);

impl Nodes {
    /// Add the stage `stage` as the node `name`; returns it as an input for later nodes.
    fn add(&mut self, name: &str, online: bool, stage: impl StageDef + 'static) -> Input {
        let key = stage.key();
        let inputs: Vec<String> = stage.inputs().iter().map(|i| i.node.clone()).collect();
        debug_assert!(inputs.iter().all(|i| self.0.iter().any(|n| &n.name == i)), "{name}: an input after it");
        self.0.push(Node {
            name: name.to_string(),
            kind: stage.kind(),
            key: key.clone(),
            inputs,
            online,
            stage: Arc::new(stage),
        });
        Input::new(name, &key)
    }
}

/// The offline study's nodes a report without online stages shows.
struct Offline {
    mesh: Option<Input>,
    train: Input,
    basis: Input,
    compactness: Input,
    generalization: Input,
    specificity: Input,
}

impl Nodes {
    /// The report of a study without online stages (an external or a 3-D scene), with the lines
    /// of what it skipped.
    fn offline_report(&mut self, scene: &SceneConfig, o: Offline, optional: [Option<Input>; 2], skipped: &[String]) {
        let [nested, comparison] = optional;
        let shows = report::ReportInputs {
            mesh: o.mesh.as_ref().map(|m| m.key.clone()),
            train: o.train.key.clone(),
            basis: o.basis.key.clone(),
            compactness: o.compactness.key.clone(),
            rom: None,
            generalization: o.generalization.key.clone(),
            specificity: o.specificity.key.clone(),
            nested: nested.as_ref().map(|n| n.key.clone()),
            comparison: comparison.as_ref().map(|n| n.key.clone()),
            online_comparison: None,
            model: None,
        };
        let mut inputs: Vec<Input> = o.mesh.into_iter().collect();
        inputs.extend([o.train, o.basis, o.compactness, o.generalization, o.specificity]);
        inputs.extend([nested, comparison].into_iter().flatten());
        self.add("report", true, ReportStage::plan(scene, shows, inputs, skipped.to_vec()));
    }
}

/// The one line an external scene's run prints about the stages it does not have
/// (`has_mesh`: the scene gives a mesh).
pub fn external_skips(has_mesh: bool) -> &'static str {
    if has_mesh {
        "external scene: the online reduced solve, the trade-off and the online comparison need the full-order operators, which an external scene does not have; skipped"
    } else {
        "external scene: the online reduced solve, the trade-off and the online comparison need the full-order operators, which an external scene does not have, and the views and the report's pictures need a mesh (model.external.mesh); skipped"
    }
}

/// The one line an external scene with `test = []` prints about what it does not have.
pub const NO_TEST: &str = "external scene with test = []: every column trains; the test error T(m) of the comparison and the test views need test points; skipped";

/// The abscissae of an external scene's contact entries, for the registered approximations: the
/// x of their mesh nodes (with a mesh), else the first coordinate of `coordinates`; or why there
/// are none to use. The registration maps act along a contact curve parametrised by x, so the
/// entries' abscissae must be distinct.
fn external_surface(scene: &SceneConfig, mesh: Option<&Input>) -> Result<SurfaceSource, String> {
    let r = scene.model.external().and_then(|e| e.resolved.as_ref());
    let Some(coordinates) = r.and_then(|r| r.coordinates.as_ref()) else {
        return Err("skipped: the registered maps need the contact entries' coordinates, and the scene gives neither model.external.coordinates nor model.external.mesh".into());
    };
    let x: Vec<f64> = coordinates.iter().map(|p| p.first().copied().unwrap_or(0.0)).collect();
    let mut sorted = x.clone();
    sorted.sort_by(f64::total_cmp);
    // Distinct to 1e-12 of the extent (a contact area, not a curve, repeats abscissae exactly).
    let extent = sorted.last().copied().unwrap_or(0.0) - sorted.first().copied().unwrap_or(0.0);
    let tol = crom_stages::float_cmp::Tol { abs: 1e-12 * extent.abs(), rel: 0.0 };
    if sorted.windows(2).any(|w| crom_stages::float_cmp::close(w[0], w[1], tol)) {
        return Err("skipped: the registered maps act along a contact curve parametrised by x, and two of this scene's contact entries share an abscissa (a contact area, not a curve)".into());
    }
    Ok(match mesh {
        Some(m) => SurfaceSource::Mesh(m.clone()),
        None => SurfaceSource::given(x),
    })
}

/// Where a scene's snapshots come from, as [`Plan::of`] plans the rest on it: the mesh node (an
/// external scene may have none), the nodes that make the snapshot columns (a native scene's
/// sweeps: training and test points, then the nested levels; an external scene's import), the
/// snapshot keys of the training and test sets and of each nested level with where its rows
/// start, and the contact surface the registered approximations map.
struct Source {
    mesh: Option<Input>,
    /// The nodes a set's rows come from, by sweep number.
    sweep_nodes: Vec<Input>,
    train_keys: Vec<Key>,
    test_keys: Vec<Key>,
    levels: Vec<Level>,
    surface: Result<SurfaceSource, String>,
    sweeps: Vec<Sweep>,
    family: Key,
    /// An external scene's imported columns (training, then test).
    imported: Vec<Key>,
    skipped: Vec<String>,
}

/// A nested level's training set as its source gives it.
struct Level {
    points: Vec<Vec<f64>>,
    /// The points' snapshot keys.
    keys: Vec<Key>,
    /// The sweep number its rows come from and its first row there.
    at: (usize, usize),
}

impl Source {
    /// A native scene: its mesh, then one sweep per point set (training and test points, then
    /// the nested levels' new points).
    fn native(scene: &SceneConfig, nodes: &mut Nodes, labels: &Labels) -> Self {
        let mesh_stage = mesh::MeshStage::plan(scene);
        let mesh_key = mesh_stage.key();
        let mesh = nodes.add("mesh", false, mesh_stage);
        let sweeps = snapshots::sweeps(scene, &mesh_key);
        let family = snapshots::scene_family(scene, &mesh_key);
        let mut sweep_nodes = Vec::new();
        for (number, sweep) in sweeps.iter().enumerate() {
            let name = format!("snapshots {}", sweep.name);
            let (sweep, mesh, family, labels) = (sweep.clone(), mesh.clone(), family.clone(), labels.clone());
            sweep_nodes.push(nodes.add(&name, false, SweepStage { number, sweep, mesh, family, labels }));
        }
        let p = &scene.parameter;
        let n_train = p.train_points().len();
        let (train_keys, test_keys) = sweeps[0].keys.split_at(n_train);
        let mut levels = Vec::new();
        let mut at = 0;
        for n in 1..=p.nested_levels {
            let pts = p.nested_points(n);
            let keys = sweeps[1].keys[at..at + pts.len()].to_vec();
            let len = pts.len();
            levels.push(Level { points: pts, keys, at: (1, at) });
            at += len;
        }
        Self {
            surface: Ok(SurfaceSource::Mesh(mesh.clone())),
            mesh: Some(mesh),
            sweep_nodes,
            train_keys: train_keys.to_vec(),
            test_keys: test_keys.to_vec(),
            levels,
            sweeps,
            family,
            imported: Vec::new(),
            skipped: Vec::new(),
        }
    }

    /// An external scene: its import in place of the sweeps, its mesh (if it gives one) in place
    /// of the native mesh; its nested levels, when the training points form them, are training
    /// columns again, each level's rows after the test set's in the import's columns.
    fn external(scene: &SceneConfig, import: ImportStage, nodes: &mut Nodes) -> Self {
        let (train_keys, test_keys) = (import.keys().0.to_vec(), import.keys().1.to_vec());
        let family = import.key();
        let level_positions = import.levels().to_vec();
        let sweep = nodes.add("import", false, import);
        let mesh = ExternalMeshStage::plan(scene).map(|stage| nodes.add("mesh", false, stage));
        let train_points = scene.parameter.train_points();
        let mut at = train_keys.len() + test_keys.len();
        let mut levels = Vec::new();
        for positions in &level_positions {
            let pts: Vec<Vec<f64>> = positions.iter().map(|&i| train_points[i].clone()).collect();
            let keys: Vec<Key> = positions.iter().map(|&i| train_keys[i].clone()).collect();
            levels.push(Level { points: pts, keys, at: (0, at) });
            at += positions.len();
        }
        let skipped = if test_keys.is_empty() { vec![NO_TEST.to_string()] } else { Vec::new() };
        Self {
            surface: external_surface(scene, mesh.as_ref()),
            mesh,
            sweep_nodes: vec![sweep],
            imported: train_keys.iter().chain(&test_keys).cloned().collect(),
            train_keys,
            test_keys,
            levels,
            sweeps: Vec::new(),
            family,
            skipped,
        }
    }
}

/// Where the snapshot sweeps stand in a store.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SnapshotState {
    /// Distinct points of the study.
    pub points: usize,
    /// Of which stored.
    pub stored: usize,
    /// Chunks (blocks of work), numbered over all sweeps in order.
    pub chunks: usize,
    /// The chunks with at least one point missing.
    pub missing_chunks: Vec<usize>,
    /// Per sweep: its name, its new points, of which stored.
    pub sweeps: Vec<(String, usize, usize)>,
}

impl Plan {
    /// The plan of `scene`'s study, in an order that respects every node's inputs: where its
    /// snapshots come from ([`Source`]: a native scene's mesh and sweeps, an external scene's
    /// import and its mesh if it gives one), then the sets, the basis, the metrics, the nested
    /// levels and the comparison alike for every scene, then the online stages where the
    /// full-order operators allow them (native 2-D scenes) and the report.
    pub fn of(scene: &SceneConfig) -> Self {
        let mut nodes = Nodes::default();
        let labels = Labels::of(scene);
        let mut source = match ImportStage::plan(scene) {
            Some(import) => Source::external(scene, import, &mut nodes),
            None => Source::native(scene, &mut nodes, &labels),
        };
        let mesh = source.mesh.clone();
        let p = &scene.parameter;
        let (train_points, test_points) = (p.train_points(), p.test_points());
        let set = |name: &str, points: &[Vec<f64>], keys: &[Key], (sweep, at): (usize, usize)| {
            let keys: Vec<&Key> = keys.iter().collect();
            SetStage::plan(name, (points, &keys), source.sweep_nodes[sweep].clone(), (sweep, at), &labels)
        };
        let train = nodes.add("trainset train", false, set("train", &train_points, &source.train_keys, (0, 0)));
        // an external scene with `test = []`: every column trains, and nothing that needs test
        // points is planned
        let test = (!test_points.is_empty()).then(|| {
            let at = (0, train_points.len());
            nodes.add("trainset test", false, set("test", &test_points, &source.test_keys, at))
        });
        if let Some(mesh) = &mesh {
            let sets = std::iter::once(("train", &train)).chain(test.as_ref().map(|t| ("test", t)));
            for (name, of) in sets {
                let subject = Subject::Set { set: name.to_string(), of: of.clone() };
                nodes.add(&format!("views {name}"), false, ViewsStage::plan(subject, mesh.clone(), &labels));
            }
        }
        let basis_stage = BasisStage::plan(scene, train.clone());
        let basis_settings = basis_stage.settings.clone();
        let basis = nodes.add("basis", false, basis_stage);
        if let Some(mesh) = &mesh {
            let views = ViewsStage::plan(Subject::Basis { of: basis.clone() }, mesh.clone(), &labels);
            nodes.add("views basis", false, views);
        }
        let stage = CompactnessStage::plan(train.clone(), basis.clone(), &basis_settings, &labels);
        let compactness = nodes.add("compactness", false, stage);
        let stage = GeneralizationStage::plan(scene, train.clone(), &labels);
        let generalization = nodes.add("generalization", false, stage);
        let stage = SpecificityStage::plan(scene, train.clone(), basis.clone(), &labels);
        let specificity = nodes.add("specificity", false, stage);
        let mut levels: Vec<Input> = Vec::new();
        for (n, level) in source.levels.iter().enumerate() {
            let name = format!("nested-{}", n + 1);
            let level = nodes.add(&format!("trainset {name}"), false, set(&name, &level.points, &level.keys, level.at));
            if let Some(mesh) = &mesh {
                let subject = Subject::Set { set: name.clone(), of: level.clone() };
                nodes.add(&format!("views {name}"), false, ViewsStage::plan(subject, mesh.clone(), &labels));
            }
            levels.push(level);
        }
        let nested =
            (!levels.is_empty()).then(|| nodes.add("nested", false, NestedStage::plan(levels.clone(), &labels)));
        // The comparison: one node per approximation, then the side-by-side artifact; the same
        // online.
        let items = scene.comparison.as_ref().map(comparison::items).unwrap_or_default();
        let mut parts: Vec<(String, Input)> = Vec::new();
        for (i, item) in items.iter().enumerate() {
            let registered = matches!(item.approach, crom_stages::dual::Approach::Registered { .. });
            let surface = match (&source.surface, registered) {
                (Err(reason), true) => {
                    source.skipped.push(format!("approximation {}: {reason}", item.name));
                    continue;
                }
                (Ok(s), _) => s.clone(),
                (Err(_), false) => SurfaceSource::Absent,
            };
            let Some(stage) = ApproximationStage::plan(scene, i, train.clone(), test.clone(), surface, levels.clone())
            else {
                continue;
            };
            let node = nodes.add(&format!("{}{}", comparison::OFFLINE_NODE, item.name), false, stage);
            parts.push((item.name.clone(), node));
        }
        let comparison = (!parts.is_empty()).then(|| {
            let stage = GatherStage::plan(ArtifactKind::COMPARISON, ArtifactKind::APPROXIMATION, parts.clone());
            nodes.add("comparison", false, stage)
        });
        let Source { sweeps, family, imported, skipped, .. } = source;
        let (Some(mesh), Some(test), true) = (mesh.clone(), test.clone(), imported.is_empty()) else {
            // no online stage: an external scene has no full-order operators ([`external_skips`])
            let offline = Offline { mesh, train, basis, compactness, generalization, specificity };
            nodes.offline_report(scene, offline, [nested, comparison], &skipped);
            return Self { sweeps, family, nodes: nodes.0, imported, skipped };
        };
        let rom = nodes.add("rom", true, RomStage::plan(scene, train.clone(), test.clone(), basis.clone(), &labels));
        let mut online_parts: Vec<(String, Input)> = Vec::new();
        let mut online_specs: Vec<(ApproximationSpec, Input)> = Vec::new();
        for (i, item) in items.iter().enumerate() {
            let Some((_, offline)) = parts.iter().find(|(n, _)| *n == item.name) else { continue };
            let (t, te, m, a) = (train.clone(), test.clone(), mesh.clone(), offline.clone());
            let Some(stage) = OnlineApproximationStage::plan(scene, i, t, te, m, a) else { continue };
            let name = format!("{}{}", comparison::ONLINE_NODE, item.name);
            let online = nodes.add(&name, true, stage);
            online_specs.push((item.spec.clone(), online.clone()));
            online_parts.push((item.name.clone(), online));
        }
        // after the online comparison: a registered approximation measured there is a candidate
        let inputs = (train.clone(), basis.clone(), rom.clone(), mesh.clone());
        let model = nodes.add("model", true, ModelStage::plan(scene, inputs, &online_specs, &labels));
        let online_comparison = (!online_parts.is_empty()).then(|| {
            let stage =
                GatherStage::plan(ArtifactKind::ONLINE_COMPARISON, ArtifactKind::ONLINE_APPROXIMATION, online_parts);
            nodes.add("online-comparison", true, stage)
        });
        let subject = Subject::Online { of: rom.clone(), test: test.clone() };
        nodes.add("views online", true, ViewsStage::plan(subject, mesh.clone(), &labels));
        let shows = report::ReportInputs {
            mesh: Some(mesh.key.clone()),
            train: train.key.clone(),
            basis: basis.key.clone(),
            compactness: compactness.key.clone(),
            rom: Some(rom.key.clone()),
            generalization: generalization.key.clone(),
            specificity: specificity.key.clone(),
            nested: nested.as_ref().map(|n| n.key.clone()),
            comparison: comparison.as_ref().map(|n| n.key.clone()),
            online_comparison: online_comparison.as_ref().map(|n| n.key.clone()),
            model: Some(model.key.clone()),
        };
        let mut inputs = vec![mesh, train, basis, compactness, rom, generalization, specificity, model];
        inputs.extend([nested, comparison, online_comparison].into_iter().flatten());
        // the report lists what the plan skipped
        nodes.add("report", true, ReportStage::plan(scene, shows, inputs, skipped.clone()));
        Self { sweeps, family, nodes: nodes.0, imported, skipped }
    }

    /// Add the stage `stage` as the node `name` after every other (its inputs must be nodes of
    /// the plan already); returns it as an input for a later node. `Plan::of` adds each stage
    /// of the study with one such line; this one adds a stage outside it (the throw-away stage's
    /// test).
    #[cfg(test)]
    pub(crate) fn add(&mut self, name: &str, online: bool, stage: impl StageDef + 'static) -> Input {
        let mut nodes = Nodes(std::mem::take(&mut self.nodes));
        let input = nodes.add(name, online, stage);
        self.nodes = nodes.0;
        input
    }

    /// Whether this is an external scene's plan (no mesh: its snapshots were imported).
    pub fn is_external(&self) -> bool {
        self.node("import").is_some()
    }

    /// The node named `name`.
    pub fn node(&self, name: &str) -> Option<&Node> {
        self.nodes.iter().find(|n| n.name == name)
    }

    /// Total chunks over all sweeps.
    pub fn chunks(&self) -> usize {
        self.sweeps.iter().map(|s| s.chunks.len()).sum()
    }

    /// Where the snapshots stand in the store at `root` (read-only).
    pub fn snapshot_state(&self, root: &Path) -> Result<SnapshotState, CromError> {
        Ok(self.snapshot_state_in(&self.index(root)?))
    }

    /// The index of this plan's column family in the store at `root` (read-only; empty when the
    /// family does not exist yet).
    pub(crate) fn index(&self, root: &Path) -> Result<crate::store::columns::Index, CromError> {
        Ok(snapshots::load_index(root, &self.family)?.1)
    }

    /// [`Self::snapshot_state`] against an index already read (that of [`Self::family`]).
    pub(crate) fn snapshot_state_in(&self, index: &crate::store::columns::Index) -> SnapshotState {
        let mut state = SnapshotState { chunks: self.chunks(), ..SnapshotState::default() };
        if !self.imported.is_empty() {
            let distinct: std::collections::HashSet<&Key> = self.imported.iter().collect();
            state.points = distinct.len();
            state.stored = distinct.iter().filter(|k| index.rows.contains_key(**k)).count();
            state.sweeps.push(("import".to_string(), state.points, state.stored));
        }
        let mut first = 0;
        for sweep in &self.sweeps {
            let (mut points, mut stored_points) = (0, 0);
            for (c, chunk) in sweep.chunks.iter().enumerate() {
                let stored = chunk.iter().filter(|&&i| index.rows.contains_key(&sweep.keys[i])).count();
                points += chunk.len();
                stored_points += stored;
                if stored < chunk.len() {
                    state.missing_chunks.push(first + c);
                }
            }
            state.points += points;
            state.stored += stored_points;
            state.sweeps.push((sweep.name.to_string(), points, stored_points));
            first += sweep.chunks.len();
        }
        state
    }
}

/// Whether the artifact of `node` is in the store at `root` (its manifest exists; `crom run`
/// verifies it when it reads it).
pub fn stored(root: &Path, node: &Node) -> bool {
    root.join(node.kind.name()).join(&node.key.0).join(MANIFEST).exists()
}
