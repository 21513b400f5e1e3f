//! The run's context, which every stage receives: the store, the provenance it records in
//! manifests, the progress display, the run's records and warnings, and the inputs read once
//! per run ([`Loaded`]). It does not carry the scene: a stage computes from its key struct, its
//! inputs and its labels, all fixed at plan time.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use crom_schemas::artifact::ArtifactKind;

use super::inputs::loaded::Loaded;
use crate::cache::{Key, KeySpec};
use crate::error::CromError;
use crate::io::table::{Column, Table};
use crate::progress::Progress;
use crate::store::{Lookup, Manifest, Provenance, Staging, Store};

/// What one stage did in a run.
#[derive(Debug, Clone, PartialEq)]
pub struct StageRecord {
    /// Stage name.
    pub stage: &'static str,
    /// Artifacts computed in this run.
    pub computed: usize,
    /// Artifacts found in the store.
    pub cached: usize,
    /// Directory of the (last) artifact of the stage.
    pub dir: PathBuf,
}

/// Append the parameter values of `points` to a table: `parameter` (the first component) and,
/// for a vector parameter, one column per component named by `names` — the layout of every
/// table that carries parameter values.
pub(crate) fn with_parameters(mut t: Table, names: &[String], points: &[&[f64]]) -> Table {
    t = t.with("parameter", Column::F64(points.iter().map(|p| p[0]).collect()));
    if names.len() > 1 {
        for (c, name) in names.iter().enumerate() {
            t = t.with(name, Column::F64(points.iter().map(|p| p[c]).collect()));
        }
    }
    t
}

/// Snapshot points of a run: solved now, reused from the store, failed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PointCounts {
    /// Solved (or imported from the old layout) in this run.
    pub solved: usize,
    /// Found in the store.
    pub reused: usize,
    /// Failed to converge (missing; the next run tries them again).
    pub failed: usize,
}

impl PointCounts {
    pub(crate) fn add(&mut self, o: PointCounts) {
        self.solved += o.solved;
        self.reused += o.reused;
        self.failed += o.failed;
    }
}

/// Everything a stage needs from the run. It does not carry the scene: a stage computes from
/// its key struct, its inputs and its `Labels`, all fixed at plan time, so a setting it uses
/// cannot be missing from its key.
#[derive(Debug)]
pub struct Ctx<'a> {
    /// The open store.
    pub store: &'a Store,
    /// The scene's name, recorded in manifests.
    pub scene_name: String,
    /// The command line, recorded in manifests.
    pub command: String,
    /// Progress display.
    pub progress: Progress,
    /// What each stage did.
    pub records: Vec<StageRecord>,
    /// Warnings to show in the summary (e.g. quarantined artifacts).
    pub warnings: Vec<String>,
    /// Snapshot points solved, reused and failed.
    pub points: PointCounts,
    /// Inputs already read in this run ([`loaded`]).
    pub(crate) loaded: std::sync::Arc<Loaded>,
}

impl<'a> Ctx<'a> {
    /// A context on `store` for `scene_name`'s run with no warnings yet, recording `command`
    /// in its manifests; `quiet`: no progress output.
    pub fn new(store: &'a Store, scene_name: &str, command: String, quiet: bool) -> Self {
        Ctx {
            store,
            scene_name: scene_name.to_string(),
            command,
            progress: Progress::new(quiet),
            records: Vec::new(),
            warnings: Vec::new(),
            points: PointCounts::default(),
            loaded: Default::default(),
        }
    }

    /// Look an artifact up; on a miss (or a quarantined corrupt one) compute it with `compute`,
    /// which writes its files into the staging directory and returns summary facts.
    pub(crate) fn cached(
        &mut self,
        kind: ArtifactKind,
        spec: &KeySpec,
        compute: impl FnOnce(&Staging) -> Result<BTreeMap<String, serde_json::Value>, CromError>,
    ) -> Result<(Manifest, bool), CromError> {
        let key = spec.key();
        if let Some(m) = self.lookup(kind, &key)? {
            return Ok((m, false));
        }
        let staging = self.store.stage(spec)?;
        let start = Instant::now();
        let summary = compute(&staging)?;
        let m = self.commit(staging, start.elapsed().as_secs_f64(), summary)?;
        Ok((m, true))
    }

    /// A single-artifact stage: through the cache, with its progress line and its line in the
    /// run summary. Inputs are loaded inside `compute`, so a cache hit reads nothing but the
    /// manifest.
    pub(crate) fn single(
        &mut self,
        kind: ArtifactKind,
        label: &'static str,
        spec: &KeySpec,
        compute: impl FnOnce(&Staging) -> Result<BTreeMap<String, serde_json::Value>, CromError>,
    ) -> Result<Key, CromError> {
        let progress = self.progress.stage(label, 1);
        let (manifest, computed) = self.cached(kind, spec, compute)?;
        progress.finish(if computed { "computed" } else { "cached" });
        self.record(label, usize::from(computed), usize::from(!computed), self.store.dir(kind, &manifest.key));
        Ok(manifest.key)
    }

    /// Verified manifest of a stored artifact, or `None` (after quarantining a corrupt one).
    pub(crate) fn lookup(&mut self, kind: ArtifactKind, key: &Key) -> Result<Option<Manifest>, CromError> {
        match self.store.lookup(kind, key)? {
            Lookup::Hit(m) => Ok(Some(*m)),
            Lookup::Miss => Ok(None),
            Lookup::Quarantined(to, why) => {
                self.warnings.push(format!(
                    "{} artifact {} failed verification ({why}); moved to {} and recomputed",
                    kind.name(),
                    key.short(),
                    to.display()
                ));
                Ok(None)
            }
        }
    }

    /// Commit a staged artifact with this run's provenance.
    pub(crate) fn commit(
        &self,
        staging: Staging,
        wall_seconds: f64,
        summary: BTreeMap<String, serde_json::Value>,
    ) -> Result<Manifest, CromError> {
        let prov = Provenance { scene: self.scene_name.clone(), command: self.command.clone(), wall_seconds, summary };
        staging.commit(self.store, prov)
    }

    /// A context for a stage that runs beside the main loop (the executor, `run.rs`): the same store,
    /// scene and loaded inputs, its own records and warnings (merged back by
    /// [`merge`](Self::merge)), and no progress output (its line is printed when it is
    /// joined, so it never breaks into another stage's bar).
    pub(super) fn beside(&self) -> Ctx<'a> {
        Ctx {
            store: self.store,
            scene_name: self.scene_name.clone(),
            command: self.command.clone(),
            progress: self.progress.silent(),
            records: Vec::new(),
            warnings: Vec::new(),
            points: PointCounts::default(),
            loaded: std::sync::Arc::clone(&self.loaded),
        }
    }

    /// Take in what a context from [`beside`](Self::beside) did.
    pub(super) fn merge(&mut self, other: Ctx<'_>) {
        for r in other.records {
            self.record(r.stage, r.computed, r.cached, r.dir);
        }
        self.warnings.extend(other.warnings);
        self.points.add(other.points);
    }

    /// Count a stage's artifacts in the run summary (one line per stage name).
    pub(crate) fn record(&mut self, stage: &'static str, computed: usize, cached: usize, dir: PathBuf) {
        match self.records.iter_mut().find(|r| r.stage == stage) {
            Some(r) => {
                r.computed += computed;
                r.cached += cached;
                r.dir = dir;
            }
            None => self.records.push(StageRecord { stage, computed, cached, dir }),
        }
    }
}
