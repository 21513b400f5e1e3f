//! Compactness stage: C(m) of eq. 16 for every m, for primal orth, dual orth and dual cone
//! (the cone's on a rank grid above `crom_stages::basis::DENSE_CURVE_MAX` training snapshots:
//! every m up to max(max_rank, 256), then doubling ranks, the last generator and the ranks the
//! scene's cone tolerances reach; the table's `m` column says which).

use std::collections::BTreeMap;

use crom_schemas::artifact::{compactness as names, ArtifactKind};
use crom_stages::blocks::modal_pass;
use crom_stages::metrics::{compactness_orth, compactness_orth_modal};
use serde::Serialize;
use serde_json::json;

use super::basis::{self, BasisKey};
use super::convert::view;
use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::inputs::streamed::MetricSet;
use super::labels::Labels;
use super::shared::Shared;
use crate::cache::{Key, KeySpec, NnlsKey, StageKey};
use crate::error::CromError;
use crate::io::table::{Column, Table};

/// What determines C(m) besides the training set and the bases (inputs).
#[derive(Debug, Serialize)]
struct CompactnessKey {
    /// C(m) of the cone comes from the CPG path's NNLS solves.
    nnls: NnlsKey,
}

impl StageKey for CompactnessKey {
    const KIND: ArtifactKind = ArtifactKind::COMPACTNESS;
    /// Bump when the compactness computation changes (2: the NNLS settings in the key; 3: the
    /// cone curve on a rank grid above `DENSE_CURVE_MAX` training snapshots).
    const ALGORITHM_VERSION: u32 = 3;
}

/// The compactness artifact's key spec.
fn spec(train: &Key, basis_key: &Key) -> KeySpec {
    KeySpec::of(&CompactnessKey { nnls: NnlsKey::used() }).input("train", train).input("basis", basis_key)
}

/// C(m) of the training set on its bases. The cone's curve is the basis stage's greedy path,
/// read with the basis' own settings (`basis_settings`, the key struct its input key hashes).
#[derive(Debug)]
pub(crate) struct CompactnessStage {
    pub spec: KeySpec,
    pub train: Input,
    pub basis: Input,
    pub basis_settings: BasisKey,
    pub labels: Labels,
}

impl CompactnessStage {
    pub(crate) fn plan(train: Input, basis: Input, basis_settings: &BasisKey, labels: &Labels) -> Self {
        let spec = spec(&train.key, &basis.key);
        Self { spec, train, basis, basis_settings: basis_settings.clone(), labels: labels.clone() }
    }
}

impl StageDef for CompactnessStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::COMPACTNESS
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.train, &self.basis]
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file("compactness.parquet", crom_schemas::artifact::compactness::FILE)]
    }

    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        self.compute(ctx)
    }
}

impl CompactnessStage {
    fn compute(&self, ctx: &mut Ctx<'_>) -> Result<Key, CromError> {
        let (spec, train, basis_key) = (&self.spec, &self.train.key, &self.basis.key);
        let (store, loaded) = (ctx.store, std::sync::Arc::clone(&ctx.loaded));
        let scene = &self.labels.scene;
        let (progress, max_rank) = (ctx.progress, self.basis_settings.max_rank());
        let tols = self.basis_settings.cone_tols();
        let streams = self.basis_settings.streams_primal();
        ctx.single(ArtifactKind::COMPACTNESS, "compactness", spec, |staging| {
            let numerical =
                |message: String| CromError::Numerical { stage: "compactness", scene: scene.clone(), message };
            let set = loaded.metric_set(store, train, streams)?;
            let b = loaded.bases(store, basis_key)?;
            let primal = match &set {
                MetricSet::Whole(s) => compactness_orth(view(&s.primal), view(&b.primal_pod)),
                MetricSet::Streamed(s) => compactness_orth_modal(
                    &modal_pass(&s.primal, view(&b.primal_pod)).map_err(|e| s.primal.error_or(|| numerical(e.0)))?,
                ),
            };
            let dual = compactness_orth(view(set.dual()), view(&b.dual_pod));
            // C(m) of the stored cone basis: the prefix of the CPG path's curve (the same pass).
            let path = basis::dual_path(progress, &tols, train, set.dual(), max_rank).map_err(numerical)?;
            let cone = path.compactness[..=b.dual_cpg.cols.min(path.len())].to_vec();
            let mut t = Rows::default();
            t.push(scene, "primal", "orth", &primal);
            t.push(scene, "dual", "orth", &dual);
            t.push(scene, "dual", "cone", &cone);
            let rows = t.m.len();
            t.table().write_parquet(&staging.path(names::FILE))?;
            Ok(BTreeMap::from([("rows".to_string(), json!(rows))]))
        })
    }
}

#[derive(Default)]
struct Rows {
    scene: Vec<String>,
    field: Vec<String>,
    basis: Vec<String>,
    m: Vec<u64>,
    value: Vec<f64>,
}

impl Rows {
    fn push(&mut self, scene: &str, field: &str, basis: &str, values: &[f64]) {
        // NaN: a rank off the grid of a large training set's cone curve (no row).
        for (m, v) in values.iter().enumerate().filter(|(_, v)| !v.is_nan()) {
            self.scene.push(scene.to_string());
            self.field.push(field.to_string());
            self.basis.push(basis.to_string());
            self.m.push(m as u64);
            self.value.push(*v);
        }
    }

    fn table(self) -> Table {
        Table::default()
            .with("scene", Column::Str(self.scene))
            .with("field", Column::Str(self.field))
            .with("basis", Column::Str(self.basis))
            .with("m", Column::U64(self.m))
            .with("value", Column::F64(self.value))
    }
}
