//! The study as data: every stage of a scene's run as a [`Node`] — its name, artifact kind,
//! typed key and the nodes it reads — computed from the scene file alone. Keys are content
//! hashes of a stage's parameters and its inputs' keys ([`crate::cache`]), so the key of every
//! artifact downstream of a snapshot is known before anything is solved. Each node's key comes
//! from the same `spec` function its stage computes with, so the plan and the run cannot
//! disagree (the e2e test `e2e_cluster` checks that a finished run leaves nothing to run).
//!
//! The local executor ([`super::execute`]) walks the nodes in order and runs each node's
//! [`Stage`] with its inputs' keys; `crom run --dry-run` prints the plan against the store
//! (what is stored, what would run); `crom status` prints it for a run in progress or
//! finished, with the sharded workers' records ([`crate::executor`]); the Slurm executor
//! takes the snapshot chunks to solve from it.

use std::path::Path;

use crom_schemas::artifact::{ArtifactKind, MANIFEST};
use crom_schemas::SceneConfig;

use super::snapshots::{self, Sweep};
use super::{
    approximation, approximation_online, basis, compactness, comparison, mesh, metrics, report, rom, trainset, views,
};
use crate::cache::Key;
use crate::error::CromError;

/// What a node runs: the stage function and the subject it is called with (its input keys are
/// the keys of the nodes it names as inputs).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Stage {
    /// The mesh.
    Mesh,
    /// Snapshot sweep `i` of [`Plan::sweeps`] (key: the column family).
    Sweep(usize),
    /// A snapshot set named `set`: `points` are the rows `start..` of sweep `sweep`.
    Set { set: String, points: Vec<Vec<f64>>, sweep: usize, start: usize },
    /// The views of the set `set`.
    SetViews { set: String },
    /// POD and CPG bases.
    Basis,
    /// The views of the bases.
    BasisViews,
    /// C(m).
    Compactness,
    /// G(m).
    Generalization,
    /// S(m).
    Specificity,
    /// H(n) over the nested sets.
    Nested,
    /// Dual approximation `i` of the comparison (in `comparison::items` order).
    Approximation(usize),
    /// The dual approximations side by side.
    Comparison,
    /// The online solve with dual approximation `i`.
    OnlineApproximation(usize),
    /// The online solves side by side.
    OnlineComparison,
    /// The online reduced model.
    Rom,
    /// The views of the online solutions.
    OnlineViews,
    /// The report.
    Report,
}

/// One stage of the study.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Stage and subject, e.g. `trainset train`, `views basis`, `snapshots train+test`.
    pub name: String,
    /// Artifact kind.
    pub kind: ArtifactKind,
    /// The artifact's key (for a sweep: its column family's).
    pub key: Key,
    /// Names of the nodes it reads, in the order its stage takes them.
    pub inputs: Vec<String>,
    /// Part of the online study (not run by `crom run --offline`).
    pub online: bool,
    /// What runs.
    pub(crate) stage: Stage,
}

impl Node {
    /// A snapshot sweep (its points are counted by [`Plan::snapshot_state`], not stored as one
    /// artifact).
    pub fn is_sweep(&self) -> bool {
        matches!(self.stage, Stage::Sweep(_))
    }
}

/// A scene's study as data.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The snapshot sweeps (their chunks are the units of sharded work).
    pub(crate) sweeps: Vec<Sweep>,
    /// The column family the snapshots go to.
    pub family: Key,
    /// Every stage, in an order that respects their inputs.
    pub nodes: Vec<Node>,
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
    /// The plan of `scene`'s study, in an order that respects every node's inputs.
    pub fn of(scene: &SceneConfig) -> Self {
        let mesh_key = mesh::spec(scene).key();
        let sweeps = snapshots::sweeps(scene, &mesh_key);
        let family = snapshots::scene_family(scene, &mesh_key);
        let mut nodes: Vec<Node> = Vec::new();
        let mut add = |name: &str, kind: ArtifactKind, key: Key, inputs: &[&str], online: bool, stage: Stage| {
            nodes.push(Node {
                name: name.to_string(),
                kind,
                key: key.clone(),
                inputs: inputs.iter().map(|s| s.to_string()).collect(),
                online,
                stage,
            });
            key
        };
        let mesh = add("mesh", ArtifactKind::Mesh, mesh_key.clone(), &[], false, Stage::Mesh);
        for (i, sweep) in sweeps.iter().enumerate() {
            let name = format!("snapshots {}", sweep.name);
            add(&name, ArtifactKind::Snapshot, family.clone(), &["mesh"], false, Stage::Sweep(i));
        }
        let p = &scene.parameter;
        let (train_points, test_points) = (p.train_points(), p.test_points());
        let first = &sweeps[0];
        let keys: Vec<&Key> = first.keys.iter().collect();
        let (train_keys, test_keys) = keys.split_at(train_points.len());
        let sweep0 = format!("snapshots {}", first.name);
        let set_stage = |set: &str, points: &[Vec<f64>], sweep: usize, start: usize| Stage::Set {
            set: set.to_string(),
            points: points.to_vec(),
            sweep,
            start,
        };
        let train = add(
            "trainset train",
            ArtifactKind::TrainingSet,
            trainset::spec("train", &train_points, train_keys).key(),
            &[&sweep0],
            false,
            set_stage("train", &train_points, 0, 0),
        );
        let test = add(
            "trainset test",
            ArtifactKind::TrainingSet,
            trainset::spec("test", &test_points, test_keys).key(),
            &[&sweep0],
            false,
            set_stage("test", &test_points, 0, train_points.len()),
        );
        for (set, key) in [("train", &train), ("test", &test)] {
            let inputs = [format!("trainset {set}"), "mesh".to_string()];
            let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
            let stage = Stage::SetViews { set: set.to_string() };
            add(
                &format!("views {set}"),
                ArtifactKind::Views,
                views::set_spec(set, key, &mesh).key(),
                &inputs,
                false,
                stage,
            );
        }
        let basis = add(
            "basis",
            ArtifactKind::Basis,
            basis::spec(scene, &train).key(),
            &["trainset train"],
            false,
            Stage::Basis,
        );
        let key = views::basis_spec(&basis, &mesh).key();
        add("views basis", ArtifactKind::Views, key, &["basis", "mesh"], false, Stage::BasisViews);
        let compactness = add(
            "compactness",
            ArtifactKind::Compactness,
            compactness::spec(&train, &basis).key(),
            &["trainset train", "basis"],
            false,
            Stage::Compactness,
        );
        let generalization = add(
            "generalization",
            ArtifactKind::Generalization,
            metrics::generalization_spec(scene, &train).key(),
            &["trainset train"],
            false,
            Stage::Generalization,
        );
        let specificity = add(
            "specificity",
            ArtifactKind::Specificity,
            metrics::specificity_spec(scene, &train, &basis).key(),
            &["trainset train", "basis"],
            false,
            Stage::Specificity,
        );
        let mut nested_sets: Vec<Key> = Vec::new();
        let nested = if p.nested_levels > 0 {
            let sweep = &sweeps[1];
            let sweep_name = format!("snapshots {}", sweep.name);
            let mut at = 0;
            let mut sets = Vec::new();
            let mut names = Vec::new();
            for n in 1..=p.nested_levels {
                let pts = p.nested_points(n);
                let keys: Vec<&Key> = sweep.keys[at..at + pts.len()].iter().collect();
                let name = format!("nested-{n}");
                let set = add(
                    &format!("trainset {name}"),
                    ArtifactKind::TrainingSet,
                    trainset::spec(&name, &pts, &keys).key(),
                    &[&sweep_name],
                    false,
                    set_stage(&name, &pts, 1, at),
                );
                at += pts.len();
                let inputs = [format!("trainset {name}"), "mesh".to_string()];
                let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
                add(
                    &format!("views {name}"),
                    ArtifactKind::Views,
                    views::set_spec(&name, &set, &mesh).key(),
                    &inputs,
                    false,
                    Stage::SetViews { set: name.clone() },
                );
                names.push(format!("trainset {name}"));
                sets.push(set);
            }
            let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
            nested_sets.clone_from(&sets);
            let key = metrics::nested_spec(&sets).key();
            Some(add("nested", ArtifactKind::Nested, key, &inputs, false, Stage::Nested))
        } else {
            None
        };
        // The comparison: one node per approximation, then the side-by-side artifact.
        let items = scene.comparison.as_ref().map(comparison::items).unwrap_or_default();
        let mut parts: Vec<(String, Key)> = Vec::new();
        for (i, item) in items.iter().enumerate() {
            let Some(spec) = approximation::spec(scene, i, &train, &test, &mesh, &nested_sets) else { continue };
            let mut inputs = vec!["trainset train".to_string(), "trainset test".to_string(), "mesh".to_string()];
            inputs.extend((1..=nested_sets.len()).map(|n| format!("trainset nested-{n}")));
            let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
            let name = format!("{}{}", comparison::OFFLINE_NODE, item.name);
            let key = add(&name, ArtifactKind::Approximation, spec.key(), &inputs, false, Stage::Approximation(i));
            parts.push((item.name.clone(), key));
        }
        let comparison = (!parts.is_empty()).then(|| {
            let names: Vec<String> = parts.iter().map(|(n, _)| format!("{}{n}", comparison::OFFLINE_NODE)).collect();
            let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
            let key = comparison::gather_spec(ArtifactKind::Comparison, &parts).key();
            add("comparison", ArtifactKind::Comparison, key, &inputs, false, Stage::Comparison)
        });
        let rom = add(
            "rom",
            ArtifactKind::Rom,
            rom::spec(scene, &train, &test, &basis).key(),
            &["trainset train", "trainset test", "basis"],
            true,
            Stage::Rom,
        );
        let mut online_parts: Vec<(String, Key)> = Vec::new();
        for (i, item) in items.iter().enumerate() {
            let Some((_, offline)) = parts.iter().find(|(n, _)| *n == item.name) else { continue };
            let Some(spec) = approximation_online::spec(scene, i, &train, &test, &mesh, offline) else { continue };
            let offline_node = format!("{}{}", comparison::OFFLINE_NODE, item.name);
            let inputs = ["trainset train", "trainset test", "mesh", offline_node.as_str()];
            let name = format!("{}{}", comparison::ONLINE_NODE, item.name);
            let kind = ArtifactKind::OnlineApproximation;
            let key = add(&name, kind, spec.key(), &inputs, true, Stage::OnlineApproximation(i));
            online_parts.push((item.name.clone(), key));
        }
        let online_comparison = (!online_parts.is_empty()).then(|| {
            let names: Vec<String> =
                online_parts.iter().map(|(n, _)| format!("{}{n}", comparison::ONLINE_NODE)).collect();
            let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
            let key = comparison::gather_spec(ArtifactKind::OnlineComparison, &online_parts).key();
            add("online-comparison", ArtifactKind::OnlineComparison, key, &inputs, true, Stage::OnlineComparison)
        });
        add(
            "views online",
            ArtifactKind::Views,
            views::online_spec(&rom, &test, &mesh).key(),
            &["rom", "trainset test", "mesh"],
            true,
            Stage::OnlineViews,
        );
        let inputs = report::ReportInputs {
            mesh,
            train,
            basis,
            compactness,
            rom,
            generalization,
            specificity,
            nested: nested.clone(),
            comparison: comparison.clone(),
            online_comparison: online_comparison.clone(),
        };
        let mut report_inputs =
            vec!["mesh", "trainset train", "basis", "compactness", "rom", "generalization", "specificity"];
        if nested.is_some() {
            report_inputs.push("nested");
        }
        if comparison.is_some() {
            report_inputs.push("comparison");
        }
        if online_comparison.is_some() {
            report_inputs.push("online-comparison");
        }
        add("report", ArtifactKind::Report, report::spec(&inputs).key(), &report_inputs, true, Stage::Report);
        Self { sweeps, family, nodes }
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
        let (_, index) = snapshots::load_index(root, &self.family)?;
        let mut state = SnapshotState { chunks: self.chunks(), ..SnapshotState::default() };
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
        Ok(state)
    }
}

/// Whether the artifact of `node` is in the store at `root` (its manifest exists; `crom run`
/// verifies it when it reads it).
pub fn stored(root: &Path, node: &Node) -> bool {
    root.join(node.kind.name()).join(&node.key.0).join(MANIFEST).exists()
}
