//! `crom query`: the stored reduced model of a scene (the `model` artifact), loaded and solved
//! at the user's points — without running the pipeline, and without writing to the store.
//!
//! The model is the one the scene's plan names (its key is computed from the scene file, as for
//! `crom run --dry-run`): absent — the study has not been run, or the scene file changed since —
//! is a usage error whose fix is `crom run SCENE`. Each point is solved with the exact online
//! solve and the settings stored with the model (`ReducedModel::solve_in`, the call the online
//! stage times; a model with a registered dual basis first pushes it to the point, as the
//! online comparison does), then its a-posteriori indicator is evaluated; `--check` also runs the
//! full-order solve there and reports the true relative errors (H1 displacement, reconstructed
//! from `reconstruction.h5`; tributary-weighted L2 pressure, computed as the online stage does).
//!
//! One row per point, in input order: the parameter (one column per component), `extrapolated`,
//! `outcome`, `iterations`, `linearizations`, `r_primal`, `r_dual` (a registered basis: the
//! generators used at the point), the coefficients' summary
//! (`u_hat_norm` = |û|₂, `lambda_hat_norm` = |λ̂|₂, `nonzero_dual`), the pressure's
//! (`max_pressure`, `contact_force` = Σ wᵢ pᵢ, `contact_nodes` with pᵢ > 0), the indicator
//! (`indicator`, `penetration`, `complementarity`, `unpaired_force`), `online_seconds`,
//! `indicator_seconds`, and with `--check` `fom_outcome`, `primal_error`, `dual_error`,
//! `fom_seconds`. A query that does not converge gives its outcome and its (unconverged) values;
//! a full-order solve that fails gives null errors.

pub mod fields;
pub mod points;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crom_schemas::artifact::{model as names, ArtifactKind};
use crom_schemas::SceneConfig;
use crom_stages::rom::{Algorithm, Indicator, QueryModel, ReducedModel, ReducedSolution, RomParams, RomWork};
use rayon::prelude::*;

use crate::cache::Key;
use crate::dag::plan::Plan;
use crate::dag::relative_dual_error;
use crate::error::CromError;
use crate::io::model::{Reconstruction, StoredModel};
use crate::io::table::{Column, Table};
use crate::physics::Physics;
use crate::store::Store;
use points::Domain;

/// What `crom query` was asked.
#[derive(Debug, Clone, Default)]
pub struct Request {
    /// `--at`.
    pub at: Option<String>,
    /// `--points`.
    pub points: Option<PathBuf>,
    /// `--out`.
    pub out: Option<PathBuf>,
    /// `--check`.
    pub check: bool,
    /// `--allow-extrapolation`.
    pub allow_extrapolation: bool,
    /// `--fields`: the reconstructed fields, HDF5 + XDMF.
    pub fields: Option<PathBuf>,
    /// `--u-tol`: the re-pairing's stopping tolerance instead of the model's.
    pub u_tol: Option<f64>,
}

/// A loaded model and where it came from.
#[derive(Debug)]
pub struct Loaded {
    /// The file's contents.
    pub stored: StoredModel,
    /// The model.
    pub model: ReducedModel,
    /// The artifact's directory.
    pub dir: PathBuf,
    /// The key of the scene's mesh artifact (for `--fields`).
    pub mesh: Option<crate::cache::Key>,
    /// The store's root and the model artifact's key (to verify `reconstruction.h5` when it is
    /// read, [`Loaded::reconstruction`]).
    pub root: PathBuf,
    /// The model artifact's key.
    pub key: Key,
}

impl Loaded {
    /// The optional reconstruction part (`reconstruction.h5`), verified against the artifact's
    /// manifest (size and blake3) before it is read: [`load_artifact`] checks it by size only.
    pub fn reconstruction(&self, fix: &str) -> Result<Reconstruction, CromError> {
        let path = self.dir.join(names::RECONSTRUCTION);
        verify_model(&self.root, &self.key, names::RECONSTRUCTION, &path, fix)?;
        Reconstruction::read(&path)
    }
}

/// The model artifact `key` of the store at `root` verified for a reader of its file `read`
/// ([`Store::verify_reading`]); an error names `path` and `fix`.
fn verify_model(root: &Path, key: &Key, read: &str, path: &Path, fix: &str) -> Result<(), CromError> {
    Store::open_read_only(root).verify_reading(ArtifactKind::MODEL, key, &[read]).map_err(|problem| {
        CromError::Artifact {
            path: path.to_path_buf(),
            message: format!("the stored reduced model failed verification: {problem}"),
            fix: fix.to_string(),
        }
    })?;
    Ok(())
}

/// Load the stored model of `scene` from the store at `root` (read-only, no lock).
pub fn load(root: &Path, scene: &SceneConfig, scene_arg: &str) -> Result<Loaded, CromError> {
    // Before planning: `crom query` reads the scene file without resolving an external scene's
    // data files, and such a scene has no model to plan.
    if scene.model.external().is_some() {
        return Err(external_has_no_model(scene));
    }
    let plan = Plan::of(scene);
    let key = &plan
        .node("model")
        .ok_or_else(|| CromError::Usage {
            message: format!("scene `{}` has no reduced model stage", scene.scene.name),
            fix: "use a scene with an online study".into(),
        })?
        .key;
    // The model's mesh (its key is a function of the scene's model, as the model's own is).
    let mesh = plan.node("mesh").map(|n| n.key.clone());
    let dir = Store::open_read_only(root).dir(ArtifactKind::MODEL, key);
    let run_first =
        || format!("run `crom run {scene_arg}` first (add --store {} if it is not the default)", root.display());
    if !dir.exists() {
        return Err(CromError::Usage {
            message: format!(
                "no reduced model of scene `{}` in the store {} matches its scene file (model {}): the study has not been run, or the scene file changed since",
                scene.scene.name,
                root.display(),
                key.short()
            ),
            fix: run_first(),
        });
    }
    let loaded = load_artifact(root, key, &run_first())?;
    Ok(Loaded { mesh, ..loaded })
}

/// Load the model artifact `key` of the store at `root` (read-only, no lock): verified against
/// its manifest (`model.h5` by size and blake3, the other files by size,
/// [`Store::verify_reading`]), `model.h5` read, the model rebuilt from its parts. `fix` is the fix every error
/// names (how to get a sound artifact back). The entry of every reader of a stored model: `crom
/// query` (through [`load`]) and the Python extension (which finds the key in the published
/// study). `mesh` is left `None`.
pub fn load_artifact(root: &Path, key: &Key, fix: &str) -> Result<Loaded, CromError> {
    let store = Store::open_read_only(root);
    let dir = store.dir(ArtifactKind::MODEL, key);
    verify_model(root, key, names::FILE, &dir, fix)?;
    let stored = StoredModel::read(&dir.join(names::FILE))?;
    let model =
        ReducedModel::from_parts(&stored.parts).map_err(|e| CromError::artifact(dir.join(names::FILE), e, fix))?;
    if model.parameter_dim() != stored.parameter_names.len() {
        return Err(CromError::artifact(
            dir.join(names::FILE),
            format!(
                "{} parameter names for a model of {} components",
                stored.parameter_names.len(),
                model.parameter_dim()
            ),
            fix,
        ));
    }
    Ok(Loaded { stored, model, dir, mesh: None, root: root.to_path_buf(), key: key.clone() })
}

/// A re-pairing tolerance given in place of the model's (`crom query --u-tol`, Python's
/// `Scene.rom(u_tol=…)`), as given; `Err` with the value unless it lies in (0, 1).
pub fn checked_u_tol(u_tol: Option<f64>) -> Result<Option<f64>, f64> {
    match u_tol {
        Some(t) if !crom_schemas::scene::is_u_tol(t) => Err(t),
        other => Ok(other),
    }
}

/// The exact online solve's settings stored with the model, with `u_tol` in place of the stored
/// one where given (checked by [`checked_u_tol`]).
pub fn params(stored: &StoredModel, u_tol: Option<f64>) -> RomParams {
    RomParams {
        algorithm: Algorithm::Exact,
        max_iter: usize::try_from(stored.max_iter).unwrap_or(usize::MAX),
        gap_tol: stored.gap_tol,
        u_tol: u_tol.unwrap_or(stored.u_tol),
        exact_step: usize::try_from(stored.exact_step).unwrap_or(0),
    }
}

/// The answer at one point: what a row of `crom query` (and a Python `rom.solve`) reports.
#[derive(Debug, Clone)]
pub struct Answer {
    /// The reduced solution (coefficients, outcome, iterations).
    pub sol: ReducedSolution,
    /// The pressure on the contact surface, `Theta λ̂` (one value per contact node).
    pub pressure: Vec<f64>,
    /// The a-posteriori indicator.
    pub indicator: Indicator,
    /// The dual rank of the answer: the model's, or for a registered dual basis the generators
    /// it used at this point (its first `m` that are not zero there).
    pub r_dual: usize,
    /// Time of the online solve (a registered basis pushed to the point, then `solve_in`),
    /// seconds.
    pub seconds: f64,
    /// Time of the indicator, seconds.
    pub indicator_seconds: f64,
}

/// Solve `model` at `mu` with `params` in the workspace `w`, then evaluate the indicator and the
/// pressure: the call the online stage times (for a registered dual basis, the online
/// comparison: the basis pushed to `mu`, then the solve), and the one every query answer comes
/// from. `model` is one thread's ([`QueryModel::new`]).
pub fn answer(model: &mut QueryModel<'_>, params: &RomParams, mu: &[f64], w: &mut RomWork) -> Answer {
    let t = Instant::now();
    let model = model.at(mu);
    let info = model.solve_in(mu, params, w);
    let seconds = t.elapsed().as_secs_f64();
    let sol = w.solution(&info);
    let t = Instant::now();
    let indicator = model.indicator(mu, w);
    let indicator_seconds = t.elapsed().as_secs_f64();
    let pressure = model.pressure(&sol.lambda_hat);
    Answer { sol, pressure, indicator, r_dual: model.ranks().1, seconds, indicator_seconds }
}

/// An external scene has no full-order operators, so no reduced model.
fn external_has_no_model(scene: &SceneConfig) -> CromError {
    CromError::Usage {
        message: format!(
            "scene `{}` is external: its snapshots come from another solver, and a reduced model \
             needs the full-order operators, which an external scene does not have",
            scene.scene.name
        ),
        fix: "query a native scene (rope, hertz, ironing); an external scene's study is its bases and metrics".into(),
    }
}

/// One answered point.
struct Row {
    point: Vec<f64>,
    extrapolated: bool,
    r_dual: usize,
    sol: ReducedSolution,
    pressure: Vec<f64>,
    indicator: Indicator,
    seconds: f64,
    indicator_seconds: f64,
    check: Option<Check>,
}

/// The full-order solve at a point and the true errors.
struct Check {
    outcome: String,
    primal_error: f64,
    dual_error: f64,
    seconds: f64,
}

/// `crom query`: answer the request and print (or write) the table.
pub fn run(root: &Path, scene: &SceneConfig, scene_arg: &str, req: &Request) -> Result<(), CromError> {
    if let Some(p) = req.fields.as_ref().filter(|p| p.extension().and_then(|e| e.to_str()) != Some("h5")) {
        return Err(CromError::Usage {
            message: format!("--fields {}: not an .h5 file", p.display()),
            fix: "name the fields file FILE.h5 (FILE.xdmf is written beside it)".into(),
        });
    }
    let u_tol = checked_u_tol(req.u_tol).map_err(|t| CromError::Usage {
        message: format!("--u-tol {t}: not a tolerance in (0, 1)"),
        fix: "give the re-pairing's relative stopping distance in (0, 1), e.g. --u-tol 1e-6, or leave it out for the model's own".into(),
    })?;
    let out_kind = match &req.out {
        None => None,
        Some(p) => match p.extension().and_then(|e| e.to_str()) {
            Some(e @ ("csv" | "parquet")) => Some(e.to_string()),
            _ => {
                return Err(CromError::Usage {
                    message: format!("--out {}: not a .csv or .parquet file", p.display()),
                    fix: "name the output FILE.csv or FILE.parquet".into(),
                })
            }
        },
    };
    let loaded = load(root, scene, scene_arg)?;
    let s = &loaded.stored;
    let domain =
        Domain { names: s.parameter_names.clone(), min: s.parameter_min.clone(), max: s.parameter_max.clone() };
    let points: Vec<Vec<f64>> = match (&req.at, &req.points) {
        (Some(at), None) => vec![domain.parse_at(at)?],
        (None, Some(file)) => domain.read_points(file)?,
        _ => {
            return Err(CromError::Usage {
                message: "crom query needs the points: --at NAME=VALUE[,…] or --points FILE (one of them)".into(),
                fix: format!("e.g. crom query {scene_arg} --at {}=…", domain.names[0]),
            })
        }
    };
    let mut flags = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        let at = match (&req.at, &req.points) {
            (Some(a), _) => format!("--at `{a}`"),
            (_, Some(f)) => format!("{} row {}", f.display(), i + 1),
            _ => String::new(),
        };
        flags.push(domain.check(p, &at, req.allow_extrapolation)?);
    }
    let params = params(s, u_tol);
    let model = &loaded.model;
    let mut rows: Vec<Row> = points
        .par_iter()
        .zip(&flags)
        .map_init(
            || (QueryModel::new(model), RomWork::default()),
            |(q, w), (mu, &extrapolated)| {
                let Answer { sol, pressure, indicator, r_dual, seconds, indicator_seconds } = answer(q, &params, mu, w);
                let point = mu.clone();
                Row { point, extrapolated, r_dual, sol, pressure, indicator, seconds, indicator_seconds, check: None }
            },
        )
        .collect();
    if req.check {
        check(scene, &loaded, &mut rows)?;
    }
    if let Some(path) = &req.fields {
        fields::write(path, root, scene, &loaded, &rows)?;
    }
    let table = table(&loaded, &rows, req.check);
    match (&req.out, out_kind.as_deref()) {
        (Some(p), Some("parquet")) => table.write_parquet(p),
        (Some(p), _) => table.write_csv(p),
        (None, _) => {
            print!("{}", table.to_csv());
            Ok(())
        }
    }
}

/// `--check`: the full-order solve at every point (in parallel) and the true errors.
fn check(scene: &SceneConfig, loaded: &Loaded, rows: &mut [Row]) -> Result<(), CromError> {
    let numerical =
        |message: String| CromError::Numerical { stage: "query --check", scene: scene.scene.name.clone(), message };
    let phys = Physics::build(scene).map_err(numerical)?;
    let rec = loaded.reconstruction("run `crom run SCENE` again")?;
    let op = phys.operator();
    if rec.phi.rows != op.n_dof() || rec.phi.cols != loaded.model.ranks().0 {
        return Err(CromError::artifact(
            loaded.dir.join(names::RECONSTRUCTION),
            format!(
                "phi is {} x {}, the model needs {} x {}",
                rec.phi.rows,
                rec.phi.cols,
                op.n_dof(),
                loaded.model.ranks().0
            ),
            "run `crom run SCENE` again",
        ));
    }
    rows.par_iter_mut().for_each(|row| {
        let t = Instant::now();
        let fom = phys.solve(&row.point);
        let seconds = t.elapsed().as_secs_f64();
        row.check = Some(match fom {
            Ok(snap) => {
                let u = ReducedModel::displacement(op, &rec.phi.data, &row.point, &row.sol.u_hat);
                let diff: Vec<f64> = u.iter().zip(&snap.u).map(|(a, b)| a - b).collect();
                let den = op.primal_norm_sq(&snap.u);
                let primal_error = if den > 0.0 { (op.primal_norm_sq(&diff) / den).sqrt() } else { f64::NAN };
                let dual_error = relative_dual_error(op.weights(), &row.pressure, &snap.pressure);
                Check { outcome: "converged".into(), primal_error, dual_error, seconds }
            }
            Err(e) => Check { outcome: format!("failed: {e}"), primal_error: f64::NAN, dual_error: f64::NAN, seconds },
        });
    });
    Ok(())
}

fn table(loaded: &Loaded, rows: &[Row], check: bool) -> Table {
    let s = &loaded.stored;
    let w = loaded.model.weights();
    let ru = loaded.model.ranks().0;
    let f = |g: &dyn Fn(&Row) -> f64| Column::F64(rows.iter().map(g).collect());
    let u = |g: &dyn Fn(&Row) -> u64| Column::U64(rows.iter().map(g).collect());
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let mut t = Table::default();
    for (c, name) in s.parameter_names.iter().enumerate() {
        t = t.with(name, f(&|r| r.point[c]));
    }
    t = t
        .with("extrapolated", Column::Str(rows.iter().map(|r| r.extrapolated.to_string()).collect()))
        .with("outcome", Column::Str(rows.iter().map(|r| r.sol.outcome.name().to_string()).collect()))
        .with("iterations", u(&|r| r.sol.iterations as u64))
        .with("linearizations", u(&|r| r.sol.linearizations as u64))
        .with("r_primal", u(&|_| ru as u64))
        .with("r_dual", u(&|r| r.r_dual as u64))
        .with("u_hat_norm", f(&|r| norm(&r.sol.u_hat)))
        .with("lambda_hat_norm", f(&|r| norm(&r.sol.lambda_hat)))
        .with("nonzero_dual", u(&|r| r.sol.nonzero_dual as u64))
        .with("max_pressure", f(&|r| r.pressure.iter().fold(0.0f64, |m, p| m.max(*p))))
        .with("contact_force", f(&|r| r.pressure.iter().zip(w).map(|(p, w)| p * w).sum()))
        .with("contact_nodes", u(&|r| r.pressure.iter().filter(|p| **p > 0.0).count() as u64))
        .with("indicator", f(&|r| r.indicator.residual))
        .with("penetration", f(&|r| r.indicator.penetration))
        .with("complementarity", f(&|r| r.indicator.complementarity))
        .with("unpaired_force", f(&|r| r.indicator.unpaired_force))
        .with("online_seconds", f(&|r| r.seconds))
        .with("indicator_seconds", f(&|r| r.indicator_seconds));
    if check {
        let c = |g: &dyn Fn(&Check) -> f64| f(&|r: &Row| r.check.as_ref().map_or(f64::NAN, g));
        t = t
            .with(
                "fom_outcome",
                Column::Str(
                    rows.iter().map(|r| r.check.as_ref().map_or(String::new(), |c| c.outcome.clone())).collect(),
                ),
            )
            .with("primal_error", c(&|c| c.primal_error))
            .with("dual_error", c(&|c| c.dual_error))
            .with("fom_seconds", c(&|c| c.seconds));
    }
    t
}
