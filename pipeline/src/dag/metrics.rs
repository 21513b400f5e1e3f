//! Metric stages, each its own artifact so that changing one metric's settings recomputes only
//! it: generalization G(m) by leave-one-out (eq. 17, folds in parallel), specificity S(m)
//! (eq. 18, seeded sampling) and the nested-training-set error H(n) (eq. 19).

use std::collections::BTreeMap;

use crom_schemas::artifact::{metrics as names, ArtifactKind};
use crom_stages::cone::NnlsParams;
use crom_stages::metrics::{
    combine_folds, loo_fold_cone, nested_error_cone, nested_error_orth, specificity_cone, specificity_orth, LooOrth,
    MetricCurve, SpecificityParams,
};
use rayon::prelude::*;
use serde_json::json;

use super::convert::view;
use super::{basis, trainset, Ctx};
use crate::cache::{Key, KeySpec};
use crate::error::CromError;
use crate::io::h5::ColMatrix;
use crate::io::table::{Column, Table};

/// Bump when a metric's numbers change.
const ALGORITHM_VERSION: u32 = 1;

fn numerical(scene: &str, stage: &'static str, e: impl std::fmt::Display) -> CromError {
    CromError::Numerical { stage, scene: scene.to_string(), message: e.to_string() }
}

/// G(m) for primal orth, dual orth and dual cone.
pub(crate) fn generalization(ctx: &mut Ctx<'_>, train: &Key) -> Result<Key, CromError> {
    let spec =
        KeySpec::new(ArtifactKind::Generalization, ALGORITHM_VERSION, json!({ "max_m": "N-1" })).input("train", train);
    let scene = ctx.scene.scene.name.clone();
    let store = ctx.store;
    ctx.single(ArtifactKind::Generalization, "generalization", &spec, |staging| {
        let set = trainset::load_from(store, train)?;
        let mut rows = CurveRows::default();
        for (field, s) in [("primal", &set.primal), ("dual", &set.dual)] {
            rows.push(&scene, field, "orth", &loo_orth(s).map_err(|e| numerical(&scene, "generalization", e))?);
        }
        rows.push(&scene, "dual", "cone", &loo_cone(&set.dual).map_err(|e| numerical(&scene, "generalization", e))?);
        rows.table().write_parquet(&staging.path(names::GENERALIZATION))?;
        Ok(BTreeMap::from([("folds".to_string(), json!(set.parameters.len()))]))
    })
}

fn loo_orth(s: &ColMatrix) -> Result<MetricCurve, String> {
    let max_m = s.cols.saturating_sub(1);
    let loo = LooOrth::new(view(s)).map_err(|e| e.to_string())?;
    let folds: Result<Vec<_>, _> = (0..s.cols).into_par_iter().map(|i| loo.fold(i, max_m)).collect();
    Ok(combine_folds(folds.map_err(|e| e.to_string())?, max_m))
}

fn loo_cone(s: &ColMatrix) -> Result<MetricCurve, String> {
    let max_m = s.cols.saturating_sub(1);
    let folds: Result<Vec<_>, _> =
        (0..s.cols).into_par_iter().map(|i| loo_fold_cone(view(s), i, max_m, NnlsParams::default())).collect();
    Ok(combine_folds(folds.map_err(|e| e.to_string())?, max_m))
}

/// S(m) for primal orth, dual orth and dual cone, on the stored bases.
pub(crate) fn specificity(ctx: &mut Ctx<'_>, train: &Key, basis_key: &Key) -> Result<Key, CromError> {
    let params = SpecificityParams { samples: ctx.scene.study.specificity_samples, seed: ctx.scene.study.seed };
    let spec = KeySpec::new(
        ArtifactKind::Specificity,
        ALGORITHM_VERSION,
        json!({ "samples": params.samples, "seed": params.seed }),
    )
    .input("train", train)
    .input("basis", basis_key);
    let scene = ctx.scene.scene.name.clone();
    let store = ctx.store;
    ctx.single(ArtifactKind::Specificity, "specificity", &spec, |staging| {
        let set = trainset::load_from(store, train)?;
        let b = basis::load_from(store, basis_key)?;
        let (p, d, c) = rayon::join(
            || specificity_orth(view(&set.primal), view(&b.primal_pod), params),
            || {
                rayon::join(
                    || specificity_orth(view(&set.dual), view(&b.dual_pod), params),
                    || specificity_cone(view(&set.dual), view(&b.dual_cpg), params, NnlsParams::default()),
                )
            },
        )
        .into_flat();
        let c = c.map_err(|e| numerical(&scene, "specificity", e))?;
        let mut rows = CurveRows::default();
        rows.push(&scene, "primal", "orth", &p);
        rows.push(&scene, "dual", "orth", &d);
        rows.push(&scene, "dual", "cone", &c);
        rows.table().write_parquet(&staging.path(names::SPECIFICITY))?;
        Ok(BTreeMap::from([("samples".to_string(), json!(params.samples)), ("seed".to_string(), json!(params.seed))]))
    })
}

trait IntoFlat<A, B, C> {
    fn into_flat(self) -> (A, B, C);
}

impl<A, B, C> IntoFlat<A, B, C> for (A, (B, C)) {
    fn into_flat(self) -> (A, B, C) {
        (self.0, self.1 .0, self.1 .1)
    }
}

/// H(n), n = 1..levels-1, from the nested sets (level n at index n-1).
pub(crate) fn nested(ctx: &mut Ctx<'_>, levels: &[Key]) -> Result<Key, CromError> {
    let mut spec = KeySpec::new(ArtifactKind::Nested, ALGORITHM_VERSION, json!({ "levels": levels.len() }));
    for (i, k) in levels.iter().enumerate() {
        spec = spec.input(&format!("level{}", i + 1), k);
    }
    let scene = ctx.scene.scene.name.clone();
    let store = ctx.store;
    ctx.single(ArtifactKind::Nested, "nested", &spec, |staging| {
        let sets: Vec<_> = levels.iter().map(|k| trainset::load_from(store, k)).collect::<Result<_, _>>()?;
        let mut t = NestedRows::default();
        let n_levels = sets.len();
        let h: Vec<[f64; 3]> = (1..n_levels)
            .into_par_iter()
            .map(|n| -> Result<[f64; 3], String> {
                let (lo, hi) = (&sets[n - 1], &sets[n]);
                Ok([
                    nested_error_orth(view(&lo.primal), view(&hi.primal)).map_err(|e| e.to_string())?,
                    nested_error_orth(view(&lo.dual), view(&hi.dual)).map_err(|e| e.to_string())?,
                    nested_error_cone(view(&lo.dual), view(&hi.dual), NnlsParams::default())
                        .map_err(|e| e.to_string())?,
                ])
            })
            .collect::<Result<_, _>>()
            .map_err(|e| numerical(&scene, "nested", e))?;
        for (i, v) in h.iter().enumerate() {
            let hi = &sets[i + 1];
            let zero = (0..hi.dual.cols).filter(|&j| hi.dual.col(j).iter().all(|x| x.abs() <= 0.0)).count();
            for ((field, basis), value) in [("primal", "orth"), ("dual", "orth"), ("dual", "cone")].iter().zip(v) {
                t.push(
                    &scene,
                    field,
                    basis,
                    i + 1,
                    *value,
                    hi.parameters.len(),
                    if *field == "dual" { zero } else { 0 },
                );
            }
        }
        t.table().write_parquet(&staging.path(names::NESTED))?;
        Ok(BTreeMap::from([("levels".to_string(), json!(n_levels))]))
    })
}

#[derive(Default)]
struct CurveRows {
    s: [Vec<String>; 3],
    m: Vec<u64>,
    mean: Vec<f64>,
    std: Vec<f64>,
    ints: [Vec<u64>; 3],
}

impl CurveRows {
    fn push(&mut self, scene: &str, field: &str, basis: &str, c: &MetricCurve) {
        for k in 0..c.len() {
            self.s[0].push(scene.to_string());
            self.s[1].push(field.to_string());
            self.s[2].push(basis.to_string());
            self.m.push(k as u64 + 1);
            self.mean.push(c.mean[k]);
            self.std.push(c.std[k]);
            self.ints[0].push(c.count[k] as u64);
            self.ints[1].push(c.padded[k] as u64);
            self.ints[2].push(c.n_zero as u64);
        }
    }

    fn table(self) -> Table {
        let [scene, field, basis] = self.s;
        let [count, padded, n_zero] = self.ints;
        Table::default()
            .with("scene", Column::Str(scene))
            .with("field", Column::Str(field))
            .with("basis", Column::Str(basis))
            .with("m", Column::U64(self.m))
            .with("mean", Column::F64(self.mean))
            .with("std", Column::F64(self.std))
            .with("count", Column::U64(count))
            .with("padded", Column::U64(padded))
            .with("n_zero", Column::U64(n_zero))
    }
}

#[derive(Default)]
struct NestedRows {
    s: [Vec<String>; 3],
    n: Vec<u64>,
    value: Vec<f64>,
    snaps: Vec<u64>,
    zero: Vec<u64>,
}

impl NestedRows {
    #[allow(clippy::too_many_arguments)]
    fn push(&mut self, scene: &str, field: &str, basis: &str, n: usize, value: f64, snaps: usize, zero: usize) {
        self.s[0].push(scene.to_string());
        self.s[1].push(field.to_string());
        self.s[2].push(basis.to_string());
        self.n.push(n as u64);
        self.value.push(value);
        self.snaps.push(snaps as u64);
        self.zero.push(zero as u64);
    }

    fn table(self) -> Table {
        let [scene, field, basis] = self.s;
        Table::default()
            .with("scene", Column::Str(scene))
            .with("field", Column::Str(field))
            .with("basis", Column::Str(basis))
            .with("n", Column::U64(self.n))
            .with("value", Column::F64(self.value))
            .with("snapshots", Column::U64(self.snaps))
            .with("n_zero", Column::U64(self.zero))
    }
}
