//! Import stage of an external scene: copy its snapshots from the user's files into a column
//! family of the store ([`crate::store::columns`]), block by block, so that the training and
//! test sets are virtual datasets over stored columns exactly as for a native scene, and every
//! stage after them runs unchanged.
//!
//! **Keys.** A column's key is the blake3 of its source files' bytes (dual, and primal if
//! given), their datasets and layout, its column index and its parameter value (and whether
//! negative pressures are clipped): an unchanged file imports nothing, a changed one imports
//! again and changes the keys of exactly what depends on it. The family is keyed by the shapes
//! and the parameter names, so the columns of several external scenes of the same
//! discretisation share it.
//!
//! **Two passes.** The columns missing from the store are read block by block (at most
//! [`super::snapshots::chunk_columns`] columns of `n_dof + n_contact` values in memory). The
//! first pass reads the pressures alone (`n_contact` rows: cheap) and checks them — finite, not
//! below `-tol max |column|` unless the scene clips them — before anything is written. The
//! second reads every field and stores it, checking the displacements as it goes; a non-finite
//! one takes back the blocks this pass committed ([`ColumnFamily::uncommit`]) and the family if
//! this pass created it. A refusal therefore leaves the store as it was. Stored values are the
//! files' values bit for bit (converted to f64), except clipped negatives.

use std::collections::HashSet;

use crom_schemas::artifact::ArtifactKind;
use crom_schemas::external::{ExternalSpec, Layout, ResolvedArray, ResolvedExternal, ResolvedSet};
use crom_schemas::SceneConfig;
use serde::Serialize;

use super::ctx::Ctx;
use super::ctx::PointCounts;
use super::graph::{Input, StageDef};
use super::shared::Columns;
use super::shared::Shared;
use super::snapshots::load_index;
use crate::cache::{params, Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::source::SnapshotArray;
use crate::store::columns::{ColumnFamily, Evidence, FamilyMeta, PendingColumn, COLUMNS_SCHEMA_VERSION};

/// Bump when the import changes the values it stores.
const ALGORITHM_VERSION: u32 = 1;

/// A source array as keyed: its bytes' hash, the dataset and the layout.
#[derive(Debug, Serialize)]
struct SourceKey<'a> {
    blake3: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    dataset: Option<&'a str>,
    layout: Layout,
}

impl<'a> From<&'a ResolvedArray> for SourceKey<'a> {
    fn from(a: &'a ResolvedArray) -> Self {
        Self { blake3: &a.blake3, dataset: a.dataset.as_deref(), layout: a.layout }
    }
}

/// One imported column's key.
#[derive(Debug, Serialize)]
struct ColumnKey<'a> {
    source: &'static str,
    dual: SourceKey<'a>,
    #[serde(skip_serializing_if = "Option::is_none")]
    primal: Option<SourceKey<'a>>,
    column: usize,
    parameters: &'a [f64],
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    clip_negative: bool,
}

impl StageKey for ColumnKey<'_> {
    const KIND: ArtifactKind = ArtifactKind::SNAPSHOT;
    const ALGORITHM_VERSION: u32 = ALGORITHM_VERSION;
}

#[derive(Serialize)]
struct FamilyParams<'a> {
    family: &'static str,
    n_dof: usize,
    n_contact: usize,
    parameters: &'a [String],
}

/// The family of an external scene's columns.
fn family_key(r: &ResolvedExternal, names: &[String]) -> Key {
    let p = FamilyParams { family: "external", n_dof: r.n_dof, n_contact: r.n_contact, parameters: names };
    let mut spec = KeySpec::new(ArtifactKind::SNAPSHOT, ALGORITHM_VERSION, params(&p));
    spec.schema_version = COLUMNS_SCHEMA_VERSION;
    spec.key()
}

/// The keys of a set's columns.
fn column_keys(s: &ResolvedSet, clip: bool) -> Vec<Key> {
    s.columns
        .iter()
        .zip(&s.points)
        .map(|(&column, mu)| {
            KeySpec::of(&ColumnKey {
                source: "external",
                dual: (&s.dual).into(),
                primal: s.primal.as_ref().map(SourceKey::from),
                column,
                parameters: mu,
                clip_negative: clip,
            })
            .key()
        })
        .collect()
}

/// The import of an external scene: the node that stands where a native scene's mesh and
/// sweeps are. Hands the training columns, then the test columns, on as sweep 0.
#[derive(Debug)]
pub(crate) struct ImportStage {
    family: Key,
    /// The training set, then the test set, with their columns' keys.
    sets: [(ResolvedSet, Vec<Key>); 2],
    n_dof: usize,
    n_contact: usize,
    names: Vec<String>,
    units: [String; 2],
    clip: bool,
    tolerance: f64,
    /// Columns per block (`snapshots::chunk_columns` of the scene).
    per_block: usize,
    /// The scene's name, in the column family's metadata.
    scene: String,
    /// The nested levels: positions in the training set ([`ResolvedExternal::levels`]).
    levels: Vec<Vec<usize>>,
}

impl ImportStage {
    /// The import of `scene`'s external data; None for a native scene or an unresolved one.
    pub(crate) fn plan(scene: &SceneConfig) -> Option<Self> {
        let ext: &ExternalSpec = scene.model.external()?;
        let r = ext.resolved.as_ref()?;
        let names = ext.parameters.names.clone();
        let clip = ext.clip_negative;
        Some(Self {
            family: family_key(r, &names),
            sets: [(r.train.clone(), column_keys(&r.train, clip)), (r.test.clone(), column_keys(&r.test, clip))],
            n_dof: r.n_dof,
            n_contact: r.n_contact,
            names,
            units: ext.units.clone().unwrap_or_else(|| ["1".to_string(), "1".to_string()]),
            clip,
            tolerance: ext.negative_tolerance(),
            per_block: super::snapshots::chunk_columns(scene),
            scene: scene.scene.name.clone(),
            levels: r.levels.clone(),
        })
    }

    /// The keys of the training columns, then the test columns.
    pub(crate) fn keys(&self) -> (&[Key], &[Key]) {
        (&self.sets[0].1, &self.sets[1].1)
    }

    /// The nested levels (positions in the training set); their rows follow the test set's in
    /// the columns this stage hands on.
    pub(crate) fn levels(&self) -> &[Vec<usize>] {
        &self.levels
    }
}

impl StageDef for ImportStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::SNAPSHOT
    }
    fn key(&self) -> Key {
        self.family.clone()
    }
    fn inputs(&self) -> Vec<&Input> {
        Vec::new()
    }
    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError> {
        let mut columns = self.import(ctx)?;
        // The nested levels are training columns again, each level after the test set.
        let train = columns.rows[..self.sets[0].1.len()].to_vec();
        for level in &self.levels {
            columns.rows.extend(level.iter().map(|&i| train[i].clone()));
        }
        shared.columns.insert(0, columns);
        Ok(self.family.clone())
    }
}

/// One column to import: which set, which position in it.
#[derive(Debug, Clone, Copy)]
struct Todo {
    set: usize,
    at: usize,
}

impl ImportStage {
    fn import(&self, ctx: &mut Ctx<'_>) -> Result<Columns, CromError> {
        let root = ctx.store.root().to_path_buf();
        let (mut family, mut index) = load_index(&root, &self.family)?;
        if let Some(f) = &family {
            f.clean_orphans()?;
        }
        let uncompacted = index.fragments;
        // The columns not stored yet, each once.
        let mut seen: HashSet<&Key> = HashSet::new();
        let mut todo: Vec<Todo> = Vec::new();
        let mut reused = 0;
        for (set, (_, keys)) in self.sets.iter().enumerate() {
            for (at, k) in keys.iter().enumerate() {
                if !seen.insert(k) {
                    continue;
                }
                if index.rows.contains_key(k) {
                    reused += 1;
                } else {
                    todo.push(Todo { set, at });
                }
            }
        }
        let per_block = self.per_block;
        let mut progress = ctx.progress.stage("import", 2 * todo.len());
        // Pass 1: the pressures (small: n_contact rows), checked before anything is stored.
        for set in 0..2 {
            let mine: Vec<Todo> = todo.iter().copied().filter(|t| t.set == set).collect();
            self.check_pressures(set, &mine, (per_block, false), &mut || progress.inc("checked"))?;
        }
        // Pass 2: every field, one block of the family per read block; a non-finite primal value
        // takes back the blocks this pass committed, so a refusal leaves nothing stored.
        let mut committed: Vec<String> = Vec::new();
        let created = family.is_none();
        let stored = self.store_all(&root, &todo, per_block, &mut family, &mut index, &mut committed, &mut progress);
        if let Err(e) = stored {
            if let Some(f) = &family {
                for block in &committed {
                    f.uncommit(block)?;
                }
                if created {
                    let dir = f.dir();
                    std::fs::remove_dir_all(dir)
                        .map_err(|e| CromError::io(dir, "removing an empty column family", e))?;
                }
            }
            return Err(e);
        }
        let committed = committed.len();
        if let (Some(f), true) = (&family, committed + uncompacted > 0) {
            f.compact(&index)?;
        }
        progress.finish(&format!("{} imported, {reused} reused", todo.len()));
        let dir = family.as_ref().map(|f| f.dir().to_path_buf()).unwrap_or_default();
        ctx.record("snapshot", todo.len(), reused, dir);
        ctx.points.add(PointCounts { solved: todo.len(), reused, failed: 0 });
        let family = family.ok_or_else(|| {
            CromError::artifact(ctx.store.root(), "no snapshot was stored for this scene", "rerun the scene")
        })?;
        let rows = self
            .sets
            .iter()
            .flat_map(|(_, keys)| keys.iter())
            .map(|k| {
                index.rows.get(k).cloned().ok_or_else(|| {
                    CromError::artifact(family.dir(), format!("snapshot {} is not in the index", k.short()), "rerun")
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Columns { rows, shape: (self.n_dof, self.n_contact) })
    }

    /// Pass 2 of [`Self::import`]: read, check and commit the columns `todo`; the blocks
    /// committed go to `committed`.
    #[allow(clippy::too_many_arguments)]
    fn store_all(
        &self,
        root: &std::path::Path,
        todo: &[Todo],
        per_block: usize,
        family: &mut Option<ColumnFamily>,
        index: &mut crate::store::columns::Index,
        committed: &mut Vec<String>,
        progress: &mut crate::progress::StageProgress,
    ) -> Result<(), CromError> {
        for set in 0..2 {
            let mine: Vec<Todo> = todo.iter().copied().filter(|t| t.set == set).collect();
            let mut pending: Vec<PendingColumn> = Vec::new();
            for chunk in mine.chunks(per_block) {
                self.stream(set, chunk, per_block, true, |t, primal, dual| {
                    progress.inc("stored");
                    let s = &self.sets[set];
                    let mut dual = dual.to_vec();
                    if self.clip {
                        dual.iter_mut().filter(|v| **v < 0.0).for_each(|v| *v = 0.0);
                    }
                    let min_lambda = dual.iter().copied().fold(f64::INFINITY, f64::min);
                    pending.push(PendingColumn {
                        key: s.1[t.at].clone(),
                        parameters: s.0.points[t.at].clone(),
                        primal: primal.to_vec(),
                        dual,
                        evidence: Evidence { min_lambda, ..Evidence::default() },
                    });
                    Ok(())
                })?;
                if family.is_none() {
                    let meta = FamilyMeta {
                        schema_version: COLUMNS_SCHEMA_VERSION,
                        family: self.family.clone(),
                        scene: self.scene.clone(),
                        n_dof: self.n_dof,
                        n_contact: self.n_contact,
                        parameter_names: self.names.clone(),
                        units: self.units.clone(),
                    };
                    *family = Some(ColumnFamily::open(root, meta)?);
                }
                let fam = family.as_ref().expect("opened above");
                let rows = fam.commit_block(&pending)?;
                if let Some(r) = rows.first() {
                    committed.push(r.block.clone());
                }
                for row in rows {
                    index.rows.insert(row.key.clone(), row);
                }
                pending.clear();
            }
        }
        Ok(())
    }

    /// The refusal of the columns of set `set` with pressures below the tolerance.
    fn negative_error(&self, set: usize, negative: &[(usize, f64)]) -> CromError {
        let s = &self.sets[set].0;
        let list: Vec<String> = negative.iter().take(20).map(|(j, v)| format!("{j} ({v:.3e})")).collect();
        CromError::input(
            &s.dual.path,
            s.dual.dataset.clone().unwrap_or_else(|| "the dual array".to_string()),
            format!(
                "{} column(s) hold pressures below -{:e} x max |column| (the cone methods assume non-negative multipliers): columns (most negative value) {}{}",
                negative.len(),
                self.tolerance,
                list.join(", "),
                if negative.len() > 20 { ", ..." } else { "" }
            ),
            "check the sign convention of the pressures (compression positive); or set model.external.clip_negative = true to set negative values to zero on import, or raise model.external.negative_tolerance",
        )
    }

    /// Read every column of both sets and check its values (finite; pressures not below the
    /// tolerance unless clipped), storing nothing: `crom import`'s check.
    pub(crate) fn check_all(&self, progress: &crate::progress::Progress) -> Result<(), CromError> {
        let per_block = 128;
        let n: usize = self.sets.iter().map(|s| s.0.columns.len()).sum();
        let mut bar = progress.stage("check", n);
        for set in 0..2 {
            let all: Vec<Todo> = (0..self.sets[set].0.columns.len()).map(|at| Todo { set, at }).collect();
            self.check_pressures(set, &all, (per_block, true), &mut || bar.inc("checked"))?;
        }
        bar.finish("every value checked");
        Ok(())
    }

    /// The most negative value of a pressure column if it is below `-tol max |column|`.
    fn most_negative(&self, dual: &[f64]) -> Option<f64> {
        let scale = dual.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let min = dual.iter().copied().fold(f64::INFINITY, f64::min);
        (min < -self.tolerance * scale).then_some(min)
    }

    /// Read the columns `todo` of set `set` (sorted by source column) in blocks of at most
    /// `per_block` source columns, checking that every value is finite, and hand each to `f`
    /// as (primal, dual); without `with_primal` the primal is not read (an empty slice).
    /// Read the columns `todo` of set `set` (`(per_block, with_primal)`: as [`Self::stream`]
    /// reads them; a non-finite value is an error there) and refuse pressures below the
    /// tolerance unless the scene clips them; `tick` once per column.
    fn check_pressures(
        &self,
        set: usize,
        todo: &[Todo],
        (per_block, with_primal): (usize, bool),
        tick: &mut dyn FnMut(),
    ) -> Result<(), CromError> {
        let mut negative: Vec<(usize, f64)> = Vec::new();
        self.stream(set, todo, per_block, with_primal, |t, _primal, dual| {
            tick();
            if let Some(v) = self.most_negative(dual) {
                negative.push((self.sets[set].0.columns[t.at], v));
            }
            Ok(())
        })?;
        if !negative.is_empty() && !self.clip {
            return Err(self.negative_error(set, &negative));
        }
        Ok(())
    }

    fn stream(
        &self,
        set: usize,
        todo: &[Todo],
        per_block: usize,
        with_primal: bool,
        mut f: impl FnMut(Todo, &[f64], &[f64]) -> Result<(), CromError>,
    ) -> Result<(), CromError> {
        if todo.is_empty() {
            return Ok(());
        }
        let s = &self.sets[set].0;
        let open = |a: &ResolvedArray, field: &str| {
            let src = crom_schemas::external::ArraySource {
                file: a.path.clone(),
                dataset: a.dataset.clone(),
                layout: a.layout,
            };
            SnapshotArray::open(std::path::Path::new(""), &src, field)
        };
        let dual = open(&s.dual, "model.external.dual")?;
        let primal = s.primal.as_ref().filter(|_| with_primal).map(|p| open(p, "model.external.primal")).transpose()?;
        // Source columns in file order, so that each block is one range read.
        let mut order: Vec<Todo> = todo.to_vec();
        order.sort_by_key(|t| s.columns[t.at]);
        let mut i = 0;
        while i < order.len() {
            let j0 = s.columns[order[i].at];
            // The run of wanted columns within per_block source columns from j0.
            let mut end = i;
            while end < order.len() && s.columns[order[end].at] < j0 + per_block {
                end += 1;
            }
            let j1 = s.columns[order[end - 1].at] + 1;
            let d = dual.block(j0, j1)?;
            let p = primal.as_ref().map(|p| p.block(j0, j1)).transpose()?;
            let (nc, nd) = (self.n_contact, primal.as_ref().map_or(0, |p| p.rows));
            for t in &order[i..end] {
                let k = s.columns[t.at] - j0;
                let dcol = &d[k * nc..(k + 1) * nc];
                let pcol = p.as_ref().map_or(&[][..], |p| &p[k * nd..(k + 1) * nd]);
                finite(&dual, dcol, j0 + k)?;
                if let Some(pa) = &primal {
                    finite(pa, pcol, j0 + k)?;
                }
                f(*t, pcol, dcol)?;
            }
            i = end;
        }
        Ok(())
    }
}

/// Every value of column `j` of `a` is finite, or an error naming the first bad one.
fn finite(a: &SnapshotArray, col: &[f64], j: usize) -> Result<(), CromError> {
    match col.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(row) => Err(CromError::input(
            a.path(),
            a.what().to_string(),
            format!("{} is {} (the first value of the array that is not finite)", a.position(j, row), col[row]),
            "give finite values only: drop the snapshot (from the column lists) or correct the solver output",
        )),
    }
}
