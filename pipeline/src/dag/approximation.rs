//! Approximation stage: one dual approximation of the scene's `[comparison]`
//! built from the training pressures and measured by the same metrics as every other —
//! compactness C(m), leave-one-out G(m), the test-set error T(m), specificity S(m) and the
//! nested error H(n) — through `crom_stages::dual`. One artifact per approximation: its key
//! holds that approximation's settings, the comparison's `max_m` and `loo_folds`, and the
//! training set, test set, mesh (whose slave-node abscissae the registration maps use) and
//! nested levels, so changing one approximation recomputes only it. Where the approximation's
//! non-negative basis does not depend on the parameter it is stored (`bases.h5`) for the
//! online stage ([`super::approximation_online`]), which then does not build it again.

use std::collections::BTreeMap;
use std::time::Instant;

use crom_schemas::artifact::{comparison as names, ArtifactKind};
use crom_schemas::comparison::ApproximationSpec;
use crom_schemas::SceneConfig;
use crom_stages::dual::{self, study, Approach, DualApprox};
use crom_stages::running_stats::RunningStats;
use serde::Serialize;
use serde_json::json;

use super::basis::Ticker;
use super::comparison::{self, contact_surface, item};
use super::convert::{self, view};
use super::ctx::Ctx;
use super::graph::{Input, StageDef};
use super::shared::Shared;
use crate::cache::{Key, KeySpec, NnlsKey, StageKey};
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5Out};
use crate::io::table::{Column, Table};
use crate::store::Staging;

/// What determines one approximation's artifact besides its inputs.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct ApproximationKey {
    /// The approximation (a `local` entry with one cell count).
    approximation: ApproximationSpec,
    max_m: usize,
    loo_folds: usize,
    nnls: NnlsKey,
    /// Specificity's samples and seed (the scene's `study` settings).
    specificity_samples: usize,
    seed: u64,
}

impl StageKey for ApproximationKey {
    const KIND: ArtifactKind = ArtifactKind::APPROXIMATION;
    /// Bump when a number of an approximation changes (2: the CPG floor; 3: `bases.h5` also
    /// holds m = 10, the online size of the registered target; 4: NNMF's objective from the
    /// sweep's Gram products, the same sweeps and bases, `relative_residual` to the last bits;
    /// 5: NNMF's products with S over its non-zeros, m = 1's basis to the last bits; 6: NNMF's
    /// W scaled once after the sweeps, its Gram products by fused multiply-adds, to rounding; 7:
    /// NNMF's ranks warm-started from the rank below and stopped at a relative gain of 1e-4; 8:
    /// stopped at 3e-4).
    const ALGORITHM_VERSION: u32 = 8;
}

/// The dual sizes the online solve is run at (those up to the basis size; the dictionary is
/// run once, with all its atoms); `bases.h5` holds the basis of each. 10 is the largest size
/// of the registered online target
/// (docs/design-notes.md#the-registered-approximation-online-the-error-the-multiplier-adds).
pub(crate) const ONLINE_MS: [usize; 8] = [1, 2, 3, 5, 8, 10, 16, 32];

impl ApproximationKey {
    /// The settings of approximation `index` of the scene's comparison (in
    /// `comparison::items` order); None without `[comparison]` or past its end.
    fn of(scene: &SceneConfig, index: usize) -> Option<Self> {
        let (cmp, item) = item(scene, index)?;
        Some(Self {
            approximation: item.spec,
            max_m: cmp.max_m,
            loo_folds: cmp.loo_folds,
            nnls: NnlsKey::used(),
            specificity_samples: scene.study.specificity_samples,
            seed: scene.study.seed,
        })
    }
}

/// Where the abscissae of the contact entries (the registration maps' surface) come from.
#[derive(Debug, Clone)]
pub(crate) enum SurfaceSource {
    /// The slave nodes' x in the mesh artifact (native scenes, external scenes with a mesh).
    Mesh(Input),
    /// Given with the scene (an external scene's `coordinates`, first component), keyed by the
    /// blake3 of their bits.
    Given { x: Vec<f64>, key: Key },
    /// None: an external scene without coordinates (no registered approximation is planned).
    Absent,
}

impl SurfaceSource {
    /// The abscissae given with the scene, keyed by their bits.
    pub(crate) fn given(x: Vec<f64>) -> Self {
        let mut h = blake3::Hasher::new();
        for v in &x {
            h.update(&v.to_bits().to_le_bytes());
        }
        Self::Given { key: Key(h.finalize().to_hex().to_string()), x }
    }
}

/// The key spec of the approximation `key`; `nested` are the nested levels' sets (level n at
/// index n - 1), for H(n).
fn spec(key: &ApproximationKey, train: &Key, test: Option<&Key>, surface: &SurfaceSource, nested: &[Key]) -> KeySpec {
    let mut spec = KeySpec::of(key).input("train", train);
    if let Some(test) = test {
        spec = spec.input("test", test);
    }
    spec = match surface {
        SurfaceSource::Mesh(mesh) => spec.input("mesh", &mesh.key),
        SurfaceSource::Given { key, .. } => spec.input("surface", key),
        SurfaceSource::Absent => spec,
    };
    for (i, k) in nested.iter().enumerate() {
        spec = spec.input(&format!("level{}", i + 1), k);
    }
    spec
}

/// Dual approximation `index` of the comparison (in `comparison::items` order), measured
/// offline, computed from its key ([`ApproximationKey`]).
#[derive(Debug)]
pub(crate) struct ApproximationStage {
    pub spec: KeySpec,
    pub settings: ApproximationKey,
    /// The scene's name, in the tables.
    pub scene: String,
    pub train: Input,
    /// The test set; `None` when every point trains (an external scene with `test = []`: no
    /// test error T(m)).
    pub test: Option<Input>,
    /// The contact entries' abscissae.
    pub surface: SurfaceSource,
    /// The nested levels' sets (level n at index n - 1), for H(n).
    pub nested: Vec<Input>,
}

impl ApproximationStage {
    /// None where the scene has no approximation `index`.
    pub(crate) fn plan(
        scene: &SceneConfig,
        index: usize,
        train: Input,
        test: Option<Input>,
        surface: SurfaceSource,
        nested: Vec<Input>,
    ) -> Option<Self> {
        let keys: Vec<Key> = nested.iter().map(|l| l.key.clone()).collect();
        let settings = ApproximationKey::of(scene, index)?;
        let spec = spec(&settings, &train.key, test.as_ref().map(|t| &t.key), &surface, &keys);
        Some(Self { spec, settings, scene: scene.scene.name.clone(), train, test, surface, nested })
    }
}

impl StageDef for ApproximationStage {
    fn kind(&self) -> ArtifactKind {
        ArtifactKind::APPROXIMATION
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        let mut inputs = vec![&self.train];
        inputs.extend(&self.test);
        if let SurfaceSource::Mesh(mesh) = &self.surface {
            inputs.push(mesh);
        }
        inputs.extend(&self.nested);
        inputs
    }
    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        let keys: Vec<Key> = self.nested.iter().map(|l| l.key.clone()).collect();
        let test = self.test.as_ref().map(|t| &t.key);
        run(ctx, &self.spec, (&self.settings, &self.scene), &self.train.key, test, &self.surface, &keys)
    }
}

/// Build and measure the approximation `settings`; returns the artifact's key.
fn run(
    ctx: &mut Ctx<'_>,
    spec: &KeySpec,
    (settings, scene): (&ApproximationKey, &str),
    train: &Key,
    test: Option<&Key>,
    surface: &SurfaceSource,
    nested: &[Key],
) -> Result<Key, CromError> {
    let item = comparison::item_of(&settings.approximation);
    let (samples, seed) = (settings.specificity_samples, settings.seed);
    let (max_m, loo_folds) = (settings.max_m, settings.loo_folds);
    let (store, loaded, progress) = (ctx.store, std::sync::Arc::clone(&ctx.loaded), ctx.progress);
    ctx.single(ArtifactKind::APPROXIMATION, "approximation", spec, |staging| {
        let set = loaded.level(store, train)?;
        let tset = test.map(|t| loaded.level(store, t)).transpose()?;
        let (surface, across) = match surface {
            SurfaceSource::Mesh(mesh) => contact_surface(store, &mesh.key)?,
            SurfaceSource::Given { x, .. } => (x.clone(), Vec::new()),
            SurfaceSource::Absent => (Vec::new(), Vec::new()),
        };
        let n_train = set.parameters.len();
        let ms = dual::m_grid(max_m.min(n_train));
        let folds = crom_schemas::scene::spaced_folds(loo_folds.min(n_train), n_train);
        let training = convert::training((&set.dual, &set.parameters), &surface, &across, &ms);
        // The nested levels' pressures and parameters (small: n_contact x (2^n + 1) each).
        let levels = nested.iter().map(|k| loaded.level(store, k)).collect::<Result<Vec<_>, _>>()?;
        let bar = Ticker::new(progress, &format!("approximation {}", item.name), folds.len() + 2);
        let mut out = Rows { scene: scene.to_string(), ..Rows::default() };
        {
            let a = &item.approach;
            let name = item.name.clone();
            let fail = |e: dual::DualError| CromError::Numerical {
                stage: "approximation",
                scene: scene.to_string(),
                message: format!("{name}: {e}"),
            };
            let t0 = Instant::now();
            let model = dual::build(a, &training).map_err(fail)?;
            let build_seconds = t0.elapsed().as_secs_f64();
            bar.tick(&name);
            let t1 = Instant::now();
            let c = study::compactness(model.as_ref(), &training).map_err(fail)?;
            let loo = study::leave_one_out(a, &training, &folds, &|| bar.tick(&name)).map_err(fail)?;
            let (g, g_zero) = study::stats(&loo, &ms);
            let errs = match &tset {
                Some(tset) => {
                    study::relative_errors(model.as_ref(), view(&tset.dual), &tset.parameters, &ms).map_err(fail)?
                }
                None => Vec::new(),
            };
            let (t, t_zero) = study::stats(&errs, &ms);
            // Local bases: the test error and G(m) per cell as well.
            if model.cell_of(&set.parameters[0]).is_some() {
                let mut by_cell: BTreeMap<(usize, &'static str), Vec<Option<Vec<f64>>>> = BTreeMap::new();
                let test_points = tset.as_ref().map_or(&[][..], |t| &t.parameters[..]);
                for (j, e) in errs.iter().enumerate() {
                    let c = model.cell_of(&test_points[j]).unwrap_or(0);
                    by_cell.entry((c, "test")).or_default().push(e.clone());
                }
                for (k, e) in folds.iter().zip(&loo) {
                    let c = model.cell_of(&set.parameters[*k]).unwrap_or(0);
                    by_cell.entry((c, "generalization")).or_default().push(e.clone());
                }
                for ((c, metric), errors) in by_cell {
                    let (st, _) = study::stats(&errors, &ms);
                    for (&m, s) in ms.iter().zip(&st) {
                        out.cells.push((name.clone(), c, metric, m, s.mean(), s.count()));
                    }
                }
            }
            if let Some(sp) = study::specificity(model.as_ref(), &training, samples, seed).map_err(fail)? {
                out.stats(&name, "specificity", &ms, &sp, 0);
            }
            for (n, pair) in levels.windows(2).enumerate() {
                let (lo, hi) = (&pair[0], &pair[1]);
                let lo_ms = dual::m_grid(max_m.min(lo.parameters.len()));
                let lower = convert::training((&lo.dual, &lo.parameters), &surface, &across, &lo_ms);
                // A level too small for the approach (a local basis with more cells than the
                // level has points) has no H(n): no row, counted in the facts.
                match study::nested_error(a, &lower, view(&hi.dual), &hi.parameters) {
                    Ok(h) => out.nested.push((name.clone(), n + 1, lo_ms.last().copied().unwrap_or(0), h)),
                    Err(dual::DualError::NotApplicable(_)) => {
                        out.facts.push((name.clone(), "nested_level_skipped".into(), None, (n + 1) as f64))
                    }
                    Err(e) => return Err(fail(e)),
                }
            }
            bar.tick(&name);
            let metrics_seconds = t1.elapsed().as_secs_f64();
            out.curve(&name, "compactness", &ms, &c, n_train);
            out.stats(&name, "generalization", &ms, &g, g_zero);
            // no test points (every point trains): no test rows
            let mut metrics = vec![("generalization", &g)];
            if tset.is_some() {
                out.stats(&name, "test", &ms, &t, t_zero);
                metrics.push(("test", &t));
            }
            for (metric, st) in metrics {
                for th in names::THRESHOLDS {
                    let m = ms.iter().zip(st.iter()).find(|(_, s)| s.count() > 0 && s.mean() <= th).map(|(&m, _)| m);
                    out.reached.push((name.clone(), metric, th, m));
                }
            }
            for fact in model.facts() {
                out.facts.push((name.clone(), fact.name, fact.m, fact.value));
            }
            out.times.push((name.clone(), build_seconds, metrics_seconds));
            if !model.depends_on_mu() && a.has_cone_basis() && !matches!(a, Approach::Dictionary) {
                write_bases(staging, scene, model.as_ref(), &set.parameters[0])?;
            }
        }
        bar.finish(&format!("{}, m <= {}", item.name, ms.last().copied().unwrap_or(0)));
        out.write(staging)?;
        Ok(BTreeMap::from([
            ("approximation".to_string(), json!(item.name)),
            ("folds".to_string(), json!(folds.len())),
            ("max_m".to_string(), json!(ms.last().copied().unwrap_or(0))),
        ]))
    })
}

/// `bases.h5`: the basis of each online size m (up to the approximation's size), dataset
/// `m<k>`; a basis without a column (all-zero training pressures) is not written.
fn write_bases(staging: &Staging, scene: &str, model: &dyn DualApprox, mu: &[f64]) -> Result<(), CromError> {
    let f = H5Out::create(&staging.path(names::BASES))?;
    f.attr_str("scene", scene)?;
    f.attr_str("kind", "approximation")?;
    f.attr_u64("schema_version", u64::from(ArtifactKind::APPROXIMATION.schema_version()))?;
    f.attr_str("cache_key", &staging.key().0)?;
    for m in ONLINE_MS.into_iter().filter(|&m| m <= model.size()) {
        let Some(b) = model.cone_basis(mu, m) else { continue };
        if b.ncols() == 0 {
            continue;
        }
        let cols: Vec<Vec<f64>> = (0..b.ncols()).map(|j| b.col(j).iter().copied().collect()).collect();
        let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        f.matrix(
            &format!("m{m}"),
            &ColMatrix::from_columns(b.nrows(), &refs),
            "non-negative generators, one per column",
        )?;
    }
    Ok(())
}

/// One point of a curve.
struct CurveRow {
    name: String,
    metric: &'static str,
    m: usize,
    mean: f64,
    std: f64,
    count: usize,
    zero: usize,
}

/// The tables' rows, collected per approximation and written at the end.
#[derive(Default)]
struct Rows {
    scene: String,
    curves: Vec<CurveRow>,
    /// (approximation, metric, threshold, m reaching it).
    reached: Vec<(String, &'static str, f64, Option<usize>)>,
    /// (approximation, fact, rank, value).
    facts: Vec<(String, String, Option<usize>, f64)>,
    /// (approximation, build seconds, metrics seconds).
    times: Vec<(String, f64, f64)>,
    /// (approximation, level n, modes used, H(n)).
    nested: Vec<(String, usize, usize, f64)>,
    /// (approximation, cell, metric, m, mean, count): local bases per cell.
    cells: Vec<(String, usize, &'static str, usize, f64, usize)>,
}

impl Rows {
    fn curve(&mut self, name: &str, metric: &'static str, ms: &[usize], values: &[f64], count: usize) {
        for (&m, &mean) in ms.iter().zip(values) {
            self.curves.push(CurveRow { name: name.into(), metric, m, mean, std: f64::NAN, count, zero: 0 });
        }
    }

    fn stats(&mut self, name: &str, metric: &'static str, ms: &[usize], st: &[RunningStats], zero: usize) {
        for (&m, s) in ms.iter().zip(st) {
            let (mean, std, count) = (s.mean(), s.std(), s.count());
            self.curves.push(CurveRow { name: name.into(), metric, m, mean, std, count, zero });
        }
    }

    fn write(self, staging: &Staging) -> Result<(), CromError> {
        let scene = |n: usize| Column::Str(vec![self.scene.clone(); n]);
        let c = &self.curves;
        let strs = |f: &dyn Fn(&CurveRow) -> String| Column::Str(c.iter().map(f).collect());
        Table::default()
            .with("scene", scene(c.len()))
            .with("approximation", strs(&|r| r.name.clone()))
            .with("metric", strs(&|r| r.metric.to_string()))
            .with("m", Column::U64(c.iter().map(|r| r.m as u64).collect()))
            .with("mean", Column::F64(c.iter().map(|r| r.mean).collect()))
            .with("std", Column::F64(c.iter().map(|r| r.std).collect()))
            .with("count", Column::U64(c.iter().map(|r| r.count as u64).collect()))
            .with("n_zero", Column::U64(c.iter().map(|r| r.zero as u64).collect()))
            .write_parquet(&staging.path(names::CURVES))?;
        // A null m ("never within the curve", "not per rank") is written for a non-finite value.
        let opt = |m: &Option<usize>| m.map_or(f64::NAN, |m| m as f64);
        let r = &self.reached;
        Table::default()
            .with("scene", scene(r.len()))
            .with("approximation", Column::Str(r.iter().map(|x| x.0.clone()).collect()))
            .with("metric", Column::Str(r.iter().map(|x| x.1.to_string()).collect()))
            .with("threshold", Column::F64(r.iter().map(|x| x.2).collect()))
            .with("m", Column::F64(r.iter().map(|x| opt(&x.3)).collect()))
            .write_parquet(&staging.path(names::REACHED))?;
        let f = &self.facts;
        Table::default()
            .with("scene", scene(f.len()))
            .with("approximation", Column::Str(f.iter().map(|x| x.0.clone()).collect()))
            .with("name", Column::Str(f.iter().map(|x| x.1.clone()).collect()))
            .with("m", Column::F64(f.iter().map(|x| opt(&x.2)).collect()))
            .with("value", Column::F64(f.iter().map(|x| x.3).collect()))
            .write_parquet(&staging.path(names::FACTS))?;
        let h = &self.nested;
        Table::default()
            .with("scene", scene(h.len()))
            .with("approximation", Column::Str(h.iter().map(|x| x.0.clone()).collect()))
            .with("n", Column::U64(h.iter().map(|x| x.1 as u64).collect()))
            .with("m", Column::U64(h.iter().map(|x| x.2 as u64).collect()))
            .with("value", Column::F64(h.iter().map(|x| x.3).collect()))
            .write_parquet(&staging.path(names::NESTED))?;
        let c = &self.cells;
        Table::default()
            .with("scene", scene(c.len()))
            .with("approximation", Column::Str(c.iter().map(|x| x.0.clone()).collect()))
            .with("cell", Column::U64(c.iter().map(|x| x.1 as u64).collect()))
            .with("metric", Column::Str(c.iter().map(|x| x.2.to_string()).collect()))
            .with("m", Column::U64(c.iter().map(|x| x.3 as u64).collect()))
            .with("mean", Column::F64(c.iter().map(|x| x.4).collect()))
            .with("count", Column::U64(c.iter().map(|x| x.5 as u64).collect()))
            .write_parquet(&staging.path(names::CELLS))?;
        let t = &self.times;
        Table::default()
            .with("scene", scene(t.len()))
            .with("approximation", Column::Str(t.iter().map(|x| x.0.clone()).collect()))
            .with("build_seconds", Column::F64(t.iter().map(|x| x.1).collect()))
            .with("metrics_seconds", Column::F64(t.iter().map(|x| x.2).collect()))
            .write_parquet(&staging.path(names::TIMINGS))
    }
}
