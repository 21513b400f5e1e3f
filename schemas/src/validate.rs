//! Range checks of a parsed scene file. Parsing (serde + TOML) already rejects unknown keys,
//! missing fields and wrong types; this rejects values that parse but make no sense, each with the
//! field's dotted path and a fix.

use std::path::Path;

use crate::comparison::{ApproximationSpec, BasisSpec, ComparisonSpec, InterpolationSpec, MapSpec};
use crate::external::{ArraySource, ExternalSpec, ParameterSource};
use crate::scene::{
    ContactSamplingSpec, Hertz3dSpec, HertzSpec, Ironing3dSpec, IroningSpec, MaterialSpec, Model, RopeSpec,
    SceneConfig, SolverSpec, StudySpec, MODEL_DUAL_CPG, MODEL_DUAL_CPG_SAMPLED, SAMPLED_SUFFIX, WHOLE_NODE_PREFIX,
};
use crate::SceneError;

struct Checker<'a> {
    path: &'a Path,
}

impl Checker<'_> {
    fn fail(&self, field: &str, problem: String, fix: &str) -> SceneError {
        SceneError::Invalid { path: self.path.to_path_buf(), field: field.to_string(), problem, fix: fix.to_string() }
    }

    fn finite(&self, field: &str, v: f64) -> Result<(), SceneError> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(self.fail(field, format!("is {v}, not a finite number"), "give a finite number"))
        }
    }

    fn positive(&self, field: &str, v: f64) -> Result<(), SceneError> {
        self.finite(field, v)?;
        if v > 0.0 {
            Ok(())
        } else {
            Err(self.fail(field, format!("is {v}, must be > 0"), "give a positive number"))
        }
    }

    fn non_negative(&self, field: &str, v: f64) -> Result<(), SceneError> {
        self.finite(field, v)?;
        if v >= 0.0 {
            Ok(())
        } else {
            Err(self.fail(field, format!("is {v}, must be >= 0"), "give 0 (keep everything) or a positive tolerance"))
        }
    }

    fn tolerance(&self, field: &str, v: f64) -> Result<(), SceneError> {
        self.non_negative(field, v)?;
        if v <= 1.0 {
            Ok(())
        } else {
            Err(self.fail(
                field,
                format!("is {v}, a relative tolerance above 1 keeps nothing"),
                "give a relative tolerance in [0, 1]",
            ))
        }
    }

    fn at_least(&self, field: &str, v: usize, min: usize) -> Result<(), SceneError> {
        if v >= min {
            Ok(())
        } else {
            Err(self.fail(field, format!("is {v}, must be at least {min}"), &format!("give an integer >= {min}")))
        }
    }

    /// `min <= v <= max`: every size in a scene file is bounded, so no value can ask for an
    /// allocation the process cannot make (the bounds are far above any study crom runs; the
    /// memory estimate of the pipeline judges what fits the machine).
    fn between(&self, field: &str, v: usize, min: usize, max: usize) -> Result<(), SceneError> {
        self.at_least(field, v, min)?;
        if v <= max {
            Ok(())
        } else {
            Err(self.fail(
                field,
                format!("is {v}, above the largest accepted value {max}"),
                &format!("give an integer <= {max}"),
            ))
        }
    }

    fn material(&self, field: &str, m: &MaterialSpec) -> Result<(), SceneError> {
        self.positive(&format!("{field}.young"), m.young)?;
        self.finite(&format!("{field}.poisson"), m.poisson)?;
        if m.poisson > -1.0 && m.poisson < 0.5 {
            Ok(())
        } else {
            Err(self.fail(
                &format!("{field}.poisson"),
                format!("is {}, must lie in (-1, 0.5) for a stable plane-strain material", m.poisson),
                "give a Poisson ratio such as 0.3",
            ))
        }
    }
}

fn check_slurm(c: &Checker<'_>, s: &crate::scene::SlurmSpec) -> Result<(), SceneError> {
    for (field, v) in
        [("shard_size", s.shard_size), ("max_parallel", s.max_parallel), ("cpus_per_task", s.cpus_per_task)]
    {
        if v == Some(0) {
            return Err(c.fail(
                &format!("executor.slurm.{field}"),
                "is 0".into(),
                "give a positive count, or leave it out",
            ));
        }
    }
    for (field, v) in [("partition", &s.partition), ("time", &s.time), ("mem", &s.mem), ("account", &s.account)] {
        if let Some(v) = v {
            if v.trim().is_empty() || v.chars().any(|ch| ch.is_whitespace() || ch.is_control()) {
                return Err(c.fail(
                    &format!("executor.slurm.{field}"),
                    format!("is {v:?}; an sbatch option value has no spaces"),
                    "give the value sbatch expects (e.g. time = \"01:00:00\", mem = \"4G\"), or leave it out",
                ));
            }
        }
    }
    Ok(())
}

impl SceneConfig {
    /// Check every value's range. Called by [`SceneConfig::from_toml_str`].
    pub(crate) fn validate(&self, path: &Path) -> Result<(), SceneError> {
        let c = Checker { path };
        if self.scene.name.trim().is_empty() {
            return Err(c.fail("scene.name", "is empty".into(), "give the scene a name, e.g. the file stem"));
        }
        // The name becomes a directory and link name in the store (`runs/<name>`, `scenes/<name>`).
        let name = &self.scene.name;
        let safe = name.chars().all(|ch| ch.is_ascii_alphanumeric() || matches!(ch, '-' | '_' | '.'));
        if !safe || name.starts_with('.') || name.len() > 100 {
            return Err(c.fail(
                "scene.name",
                format!("is {name:?}; it names directories in the store, so only letters, digits, '-', '_' and '.' (not first) are allowed, at most 100 characters"),
                "use a plain name such as \"ironing-fine-2\"",
            ));
        }
        if let Model::External(e) = &self.model {
            return self.check_external(&c, e);
        }
        if self.parameter.is_unset() {
            return Err(c.fail(
                "parameter",
                "is missing".into(),
                "add a [parameter] table (name, description, min, max, n_train); see data/scenes/rope.toml",
            ));
        }
        if self.solver.is_unset() {
            return Err(c.fail(
                "solver",
                "is missing".into(),
                "add a [solver] table (rel_tol, max_iter); see data/scenes/rope.toml",
            ));
        }
        self.check_parameter(&c)?;
        check_solver(&c, &self.solver)?;
        check_study(&c, &self.study)?;
        if self.model.is_3d() {
            check_3d_study(&c, self)?;
        }
        if let Some(e) = &self.executor {
            check_slurm(&c, &e.slurm)?;
        }
        if let Some(cmp) = &self.comparison {
            check_comparison(&c, cmp, &self.model, self.parameter.dim(), self.parameter.train_count())?;
        }
        if let Some(cs) = &self.study.contact_sampling {
            check_contact_sampling(&c, cs, &self.model)?;
        }
        if let Some(r) = &self.study.model_ranks {
            for (v, what) in r.iter().zip(["r_primal", "r_dual"]) {
                c.between(&format!("study.model_ranks ({what})"), *v, 1, MAX_COUNT)?;
            }
        }
        if let Some(dual) = &self.study.model_dual {
            check_model_dual(&c, dual, self.comparison.as_ref(), self.study.contact_sampling.is_some())?;
        }
        if let Some(t) = self.study.online_u_tol {
            c.finite("study.online_u_tol", t)?;
            if !crate::scene::is_u_tol(t) {
                return Err(c.fail(
                    "study.online_u_tol",
                    format!("is {t}, not a tolerance in (0, 1)"),
                    "give the online solve's relative stopping distance in (0, 1), e.g. 1e-6, or remove the key for 1e-10",
                ));
            }
        }
        match &self.model {
            Model::Rope(r) => check_rope(&c, r),
            Model::Hertz(h) => check_hertz(&c, h),
            Model::Ironing(i) => check_ironing(&c, i),
            Model::Hertz3d(h) => check_hertz3d(&c, h),
            Model::Ironing3d(i) => check_ironing3d(&c, i),
            Model::External(_) => unreachable!("returned above"),
        }
    }

    fn check_parameter(&self, c: &Checker<'_>) -> Result<(), SceneError> {
        let p = &self.parameter;
        check_axis(c, "parameter", &p.name, p.min, p.max, p.n_train, p.train_level)?;
        for (i, a) in p.axes.iter().enumerate() {
            check_axis(c, &format!("parameter.axes[{i}]"), &a.name, a.min, a.max, a.n_train, a.train_level)?;
        }
        if p.nested_levels > MAX_LEVEL {
            return Err(c.fail(
                "parameter.nested_levels",
                format!("is {}, i.e. 2^{} + 1 points per level", p.nested_levels, p.nested_levels),
                &format!("use at most {MAX_LEVEL} nested levels"),
            ));
        }
        let names = p.names();
        let allowed: &[&[&str]] = match &self.model {
            Model::Rope(_) => &[&["gamma"]],
            Model::Hertz(_) => &[&["d"]],
            Model::Ironing(_) => &[&["d_x"], &["d_x", "d_y"]],
            Model::Hertz3d(_) => &[&["d"]],
            Model::Ironing3d(_) => &[&["d_x"], &["d_x", "d_z"]],
            Model::External(_) => return Ok(()),
        };
        if !allowed.contains(&names.as_slice()) {
            let field = if names.len() > 1 { "parameter.axes" } else { "parameter.name" };
            let list: Vec<String> = allowed.iter().map(|a| format!("({})", a.join(", "))).collect();
            return Err(c.fail(
                field,
                format!(
                    "makes the parameter ({}), which the {} model does not have",
                    names.join(", "),
                    self.model.kind()
                ),
                &format!("use one of {}", list.join(" or ")),
            ));
        }
        // Every point set is a tensor grid: bound its size (training and nested sets alike).
        let train: f64 = std::iter::once((p.n_train, p.train_level))
            .chain(p.axes.iter().map(|a| (a.n_train, a.train_level)))
            .map(|(n, k)| k.map_or(n.unwrap_or(0) as f64, |k| (1u64 << k) as f64 + 1.0))
            .product();
        let nested = ((1u64 << p.nested_levels) as f64 + 1.0).powi(p.dim() as i32);
        let limit = ((1u64 << MAX_LEVEL) + 1) as f64;
        if train > limit || (p.nested_levels > 0 && nested > limit) {
            return Err(c.fail(
                "parameter",
                format!(
                    "makes {} training points and {} on the finest nested level",
                    train,
                    if p.nested_levels > 0 { nested } else { 0.0 }
                ),
                &format!("keep every point set at most {limit} points (fewer training points, levels or axes)"),
            ));
        }
        // the press of an ironing scene: a fixed value or a parameter axis, exactly one
        let press = match &self.model {
            Model::Ironing(i) => Some(("ironing", "d_y", "iron", i.d_y)),
            Model::Ironing3d(i) => Some(("ironing3d", "d_z", "die", i.d_z)),
            _ => None,
        };
        if let Some((model, axis, body, fixed)) = press {
            let field = format!("model.{model}.{axis}");
            match (fixed, names.contains(&axis)) {
                (Some(_), true) => {
                    let fix = format!("remove {field} (the axis sets it) or the {axis} axis");
                    return Err(c.fail(&field, format!("is given, but {axis} is also a parameter axis"), &fix));
                }
                (None, false) => {
                    let fix = format!(
                        "give the {body}'s downward displacement, e.g. {axis} = 0.04, or make {axis} a parameter axis"
                    );
                    return Err(c.fail(&field, "is missing".into(), &fix));
                }
                _ => {}
            }
        }
        if let Model::Ironing(i) = &self.model {
            // the deepest press of the study, fixed or the d_y axis's upper end
            let (field, deepest) = match (i.d_y, p.axes.iter().position(|a| a.name == "d_y")) {
                (Some(d), _) => ("model.ironing.d_y".to_string(), d),
                (None, Some(k)) => (format!("parameter.axes[{k}].max"), p.axes[k].max),
                (None, None) => unreachable!("checked above"),
            };
            check_press(c, &field, deepest, i)?;
        }
        if let Model::Ironing3d(i) = &self.model {
            // the d_z axis's upper end, the deepest press of the study (a fixed d_z is checked
            // with the model)
            if let (None, Some(k)) = (i.d_z, p.axes.iter().position(|a| a.name == "d_z")) {
                check_die_press(c, &format!("parameter.axes[{k}].max"), p.axes[k].max, i)?;
            }
        }
        Ok(())
    }
}

impl SceneConfig {
    /// An external scene: no `[parameter]`, `[solver]` or contact sampling (its parameter comes
    /// from its files, it solves nothing, and the sampling needs the full-order model); its
    /// comparison as a native scene's; its files named, its column lists consistent.
    fn check_external(&self, c: &Checker<'_>, e: &ExternalSpec) -> Result<(), SceneError> {
        let has = "an external scene reads its snapshots and parameter values from files";
        if !self.parameter.is_unset() {
            return Err(c.fail(
                "parameter",
                format!("is given, but {has}"),
                "remove [parameter]; name the components in model.external.parameters.names",
            ));
        }
        if !self.solver.is_unset() {
            return Err(c.fail("solver", format!("is given, but {has} and solves nothing"), "remove [solver]"));
        }
        if let Some(cmp) = &self.comparison {
            // The training points are known once the files are read: the local bases' cell
            // count is checked against them by the approximation itself.
            let first_axis = e.train.as_ref().map_or(usize::MAX, Vec::len);
            check_comparison(c, cmp, &self.model, e.parameters.names.len(), first_axis)?;
        }
        if self.study.contact_sampling.is_some() {
            return Err(c.fail(
                "study.contact_sampling",
                "is set, but the contact quadrature needs the full-order contact operator, which an external scene does not have".into(),
                "remove study.contact_sampling",
            ));
        }
        if self.study.model_dual.is_some() {
            return Err(c.fail(
                "study.model_dual",
                "is set, but an external scene has no reduced model (it needs the full-order operators)".into(),
                "remove study.model_dual",
            ));
        }
        if self.study.online_u_tol.is_some() {
            return Err(c.fail(
                "study.online_u_tol",
                "is set, but an external scene has no online solve (it needs the full-order operators)".into(),
                "remove study.online_u_tol",
            ));
        }
        check_study(c, &self.study)?;
        if let Some(x) = &self.executor {
            check_slurm(c, &x.slurm)?;
        }
        let at = "model.external";
        check_array(c, &format!("{at}.dual"), &e.dual)?;
        if let Some(p) = &e.primal {
            check_array(c, &format!("{at}.primal"), p)?;
        }
        if let Some(p) = &e.coordinates {
            check_array(c, &format!("{at}.coordinates"), p)?;
        }
        check_parameters(c, &format!("{at}.parameters"), &e.parameters)?;
        if let Some(t) = &e.negative_tolerance {
            c.non_negative(&format!("{at}.negative_tolerance"), *t)?;
        }
        match (&e.test, &e.test_files) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(c.fail(
                    &format!("{at}.test"),
                    "and model.external.test_files: exactly one of them names the test points".into(),
                    "give `test = [columns]` (with `train = [columns]`) or a [model.external.test_files] table",
                ))
            }
            (Some(test), None) => {
                let Some(train) = &e.train else {
                    return Err(c.fail(
                        &format!("{at}.train"),
                        "is missing; with `test` columns the training columns are listed too".into(),
                        "give `train = [columns]`",
                    ));
                };
                check_columns(c, &format!("{at}.train"), train)?;
                // `test = []`: every column trains; the stages that need test points are skipped
                if !test.is_empty() {
                    check_columns(c, &format!("{at}.test"), test)?;
                }
                if let Some(j) = train.iter().find(|j| test.contains(j)) {
                    return Err(c.fail(
                        &format!("{at}.test"),
                        format!("lists column {j}, which is also a training column"),
                        "list every column in at most one of `train` and `test`",
                    ));
                }
            }
            (None, Some(files)) => {
                if let Some(train) = &e.train {
                    check_columns(c, &format!("{at}.train"), train)?;
                }
                let tf = format!("{at}.test_files");
                check_array(c, &format!("{tf}.dual"), &files.dual)?;
                match (&e.primal, &files.primal) {
                    (Some(_), None) | (None, Some(_)) => {
                        return Err(c.fail(
                            &format!("{tf}.primal"),
                            "must be given exactly when model.external.primal is".into(),
                            "give primal snapshots for both sets, or for neither",
                        ))
                    }
                    (Some(_), Some(p)) => check_array(c, &format!("{tf}.primal"), p)?,
                    (None, None) => {}
                }
                check_parameters(c, &format!("{tf}.parameters"), &files.parameters)?;
                if files.parameters.names != e.parameters.names {
                    return Err(c.fail(
                        &format!("{tf}.parameters.names"),
                        format!("is {:?}, the training set's are {:?}", files.parameters.names, e.parameters.names),
                        "give both sets the same parameter names in the same order",
                    ));
                }
            }
        }
        Ok(())
    }
}

fn check_array(c: &Checker<'_>, at: &str, a: &ArraySource) -> Result<(), SceneError> {
    if a.file.as_os_str().is_empty() {
        return Err(c.fail(&format!("{at}.file"), "is empty".into(), "give the path of an HDF5 or .npy file"));
    }
    if a.dataset.as_deref().is_some_and(|d| d.trim().is_empty()) {
        return Err(c.fail(&format!("{at}.dataset"), "is empty".into(), "give the dataset's path, e.g. \"/dual\""));
    }
    Ok(())
}

fn check_parameters(c: &Checker<'_>, at: &str, p: &ParameterSource) -> Result<(), SceneError> {
    if p.file.as_os_str().is_empty() {
        return Err(c.fail(
            &format!("{at}.file"),
            "is empty".into(),
            "give the path of a CSV, Parquet, .npy or HDF5 file",
        ));
    }
    if p.names.is_empty() {
        return Err(c.fail(&format!("{at}.names"), "is empty".into(), "name each component, e.g. names = [\"d_x\"]"));
    }
    for (i, n) in p.names.iter().enumerate() {
        let plain = !n.trim().is_empty() && n.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '_');
        if !plain {
            return Err(c.fail(
                &format!("{at}.names[{i}]"),
                format!("is {n:?}; a component's name is a table column, so letters, digits and '_' only"),
                "use a plain name such as \"d_x\"",
            ));
        }
        if p.names[..i].contains(n) {
            return Err(c.fail(
                &format!("{at}.names[{i}]"),
                format!("repeats {n:?}"),
                "give each component its own name",
            ));
        }
        // Names the tables already use for other columns.
        if ["parameter", "scene", "index", "snapshot_key", "m"].contains(&n.as_str()) {
            return Err(c.fail(
                &format!("{at}.names[{i}]"),
                format!("is {n:?}, a column name crom's tables use"),
                "rename the component",
            ));
        }
    }
    Ok(())
}

fn check_columns(c: &Checker<'_>, at: &str, cols: &[usize]) -> Result<(), SceneError> {
    if cols.is_empty() {
        return Err(c.fail(at, "is empty".into(), "list at least one column (0-based)"));
    }
    let mut seen = std::collections::BTreeSet::new();
    for j in cols {
        if !seen.insert(j) {
            return Err(c.fail(at, format!("lists column {j} twice"), "list each column once"));
        }
    }
    Ok(())
}

/// One axis of the parameter: name, finite non-empty range, exactly one of n_train / train_level.
fn check_axis(
    c: &Checker<'_>,
    at: &str,
    name: &str,
    min: f64,
    max: f64,
    n_train: Option<usize>,
    train_level: Option<u32>,
) -> Result<(), SceneError> {
    if name.trim().is_empty() {
        return Err(c.fail(&format!("{at}.name"), "is empty".into(), "name the parameter, e.g. \"gamma\""));
    }
    c.finite(&format!("{at}.min"), min)?;
    c.finite(&format!("{at}.max"), max)?;
    if max <= min {
        return Err(c.fail(
            &format!("{at}.max"),
            format!("is {max} but {at}.min is {min}: the range is empty or reversed"),
            &format!("make {at}.max greater than {at}.min"),
        ));
    }
    match (n_train, train_level) {
        (Some(n), None) => c.between(&format!("{at}.n_train"), n, 2, (1 << MAX_LEVEL) + 1),
        (None, Some(k)) if (1..=MAX_LEVEL).contains(&k) => Ok(()),
        (None, Some(k)) => Err(c.fail(
            &format!("{at}.train_level"),
            format!("is {k}, i.e. 2^{k} + 1 training points"),
            &format!("use a level from 1 to {MAX_LEVEL}"),
        )),
        (Some(_), Some(_)) => Err(c.fail(
            &format!("{at}.train_level"),
            format!("is given together with {at}.n_train"),
            "keep one: n_train = N for N equidistant points, or train_level = k for 2^k + 1 nested points",
        )),
        (None, None) => Err(c.fail(
            &format!("{at}.n_train"),
            "is missing".into(),
            "give n_train = N (N equidistant training points) or train_level = k (2^k + 1 points)",
        )),
    }
}

/// Largest nested or training level: 2^17 + 1 = 131 073 points (the largest study measured is
/// level 16: 65 537 training and 65 536 test points).
const MAX_LEVEL: u32 = 17;

/// Largest element count along one edge of a mesh (rope, Hertz arc, ironing slab and iron).
pub const MAX_ELEMENTS_PER_EDGE: usize = 100_000;
/// Elements along one edge of a 3-D block (the memory estimate of the pipeline judges what fits).
pub const MAX_ELEMENTS_PER_EDGE_3D: usize = 2_000;
/// Largest number of rope elements.
pub const MAX_ROPE_ELEMENTS: usize = 10_000_000;
/// Largest iteration budget, specificity sample count, basis size or fold count.
pub const MAX_COUNT: usize = 100_000_000;

fn check_solver(c: &Checker<'_>, s: &SolverSpec) -> Result<(), SceneError> {
    c.positive("solver.rel_tol", s.rel_tol)?;
    if s.rel_tol >= 1.0 {
        return Err(c.fail("solver.rel_tol", format!("is {}, must be < 1", s.rel_tol), "use e.g. 1e-10"));
    }
    c.between("solver.max_iter", s.max_iter, 1, MAX_COUNT)
}

fn check_study(c: &Checker<'_>, s: &StudySpec) -> Result<(), SceneError> {
    c.tolerance("study.primal_tol", s.primal_tol)?;
    c.tolerance("study.dual_orth_tol", s.dual_orth_tol)?;
    c.tolerance("study.dual_cone_tol", s.dual_cone_tol)?;
    c.tolerance("study.dual_cone_tol_truncated", s.dual_cone_tol_truncated)?;
    c.between("study.specificity_samples", s.specificity_samples, 1, MAX_COUNT)?;
    if let Some(m) = s.max_rank {
        c.between("study.max_rank", m, 0, MAX_COUNT)?;
    }
    if let Some(f) = s.loo_folds {
        c.between("study.loo_folds", f, 0, MAX_COUNT)?;
    }
    if s.loo_folds == Some(0) {
        return Err(c.fail(
            "study.loo_folds",
            "is 0: the generalization curve would average no fold".into(),
            "give the number of leave-one-out folds (>= 1), or remove the key to use every fold up to 256 snapshots",
        ));
    }
    match s.max_rank {
        Some(0) => Err(c.fail(
            "study.max_rank",
            "is 0: the metric curves would have no basis size at all".into(),
            "give the largest basis size m to compute (>= 1), or remove the key to compute every m up to 256",
        )),
        _ => Ok(()),
    }
}

fn check_contact_sampling(c: &Checker<'_>, cs: &ContactSamplingSpec, model: &Model) -> Result<(), SceneError> {
    if let Model::Rope(_) = model {
        return Err(c.fail(
            "study.contact_sampling",
            "is set for the rope, whose contact constraints are fixed rows (assembled once offline, no per-query work to sample)".into(),
            "remove study.contact_sampling; it applies to the scenes whose pairs change per query (hertz, ironing and their 3-D kin)",
        ));
    }
    c.finite("study.contact_sampling.tol", cs.tol)?;
    if !(0.0..1.0).contains(&cs.tol) {
        return Err(c.fail(
            "study.contact_sampling.tol",
            format!("is {}, must be in [0, 1)", cs.tol),
            "give the fit's relative residual, e.g. 3e-2 (0 fits the exact sums)",
        ));
    }
    if cs.ranks.is_empty() || cs.ranks.len() > 64 {
        return Err(c.fail(
            "study.contact_sampling.ranks",
            format!("has {} rank pairs, must have 1 to 64", cs.ranks.len()),
            "give [r_primal, r_dual] pairs, e.g. ranks = [[32, 32], [128, 60]]",
        ));
    }
    for (i, r) in cs.ranks.iter().enumerate() {
        for (v, what) in r.iter().zip(["r_primal", "r_dual"]) {
            c.between(&format!("study.contact_sampling.ranks[{i}] ({what})"), *v, 1, MAX_COUNT)?;
        }
    }
    Ok(())
}

fn check_rope(c: &Checker<'_>, r: &RopeSpec) -> Result<(), SceneError> {
    c.positive("model.rope.length", r.length)?;
    c.between("model.rope.n_elements", r.n_elements, 2, MAX_ROPE_ELEMENTS)?;
    c.positive("model.rope.nu", r.nu)?;
    c.finite("model.rope.f", r.f)?;
    let o = &r.obstacle;
    if o.modes.len() != o.amplitudes.len() {
        return Err(c.fail(
            "model.rope.obstacle.amplitudes",
            format!("has {} entries but modes has {}", o.amplitudes.len(), o.modes.len()),
            "give one amplitude per sine mode",
        ));
    }
    for (i, m) in o.modes.iter().enumerate() {
        c.finite(&format!("model.rope.obstacle.modes[{i}]"), *m)?;
    }
    for (i, a) in o.amplitudes.iter().enumerate() {
        c.finite(&format!("model.rope.obstacle.amplitudes[{i}]"), *a)?;
    }
    c.finite("model.rope.obstacle.offset", o.offset)
}

fn check_hertz(c: &Checker<'_>, h: &HertzSpec) -> Result<(), SceneError> {
    c.positive("model.hertz.radius", h.radius)?;
    c.material("model.hertz.material", &h.material)?;
    c.between("model.hertz.n_arc", h.n_arc, 6, MAX_ELEMENTS_PER_EDGE)
}

/// The rise of the iron's circular sole over its half width, `R - sqrt(R^2 - (w/2)^2)`: pressed
/// deeper than this into the undeformed slab, the block's lower corners — not its sole — would
/// meet the slab. The contact model has the sole as its only master surface
/// (docs/scenes.md#ironing-coarse-and-ironing-fine), so such a press cannot be solved: the slab
/// would pass through the block's sides, and the active-set loop, which sees nothing there,
/// cycles until its iteration cap.
pub fn sole_rise(i: &IroningSpec) -> f64 {
    let (r, h) = (i.iron.sole_radius, 0.5 * i.iron.width);
    r - (r * r - h * h).max(0.0).sqrt()
}

/// A press `d` (the field `field`) must stay below the sole's rise ([`sole_rise`]).
fn check_press(c: &Checker<'_>, field: &str, d: f64, i: &IroningSpec) -> Result<(), SceneError> {
    let rise = sole_rise(i);
    if d.is_finite() && d >= rise {
        return Err(c.fail(
            field,
            format!(
                "is {d}, not below the rise {rise:.4} of the iron's sole (sole_radius {}, width {}): the block's corners, not its sole, would meet the slab, and the contact model has only the sole",
                i.iron.sole_radius, i.iron.width
            ),
            &format!("press less than {rise:.4} (d_y), or give the sole more rise (a smaller model.ironing.iron.sole_radius or a wider iron)"),
        ));
    }
    Ok(())
}

fn check_ironing(c: &Checker<'_>, i: &IroningSpec) -> Result<(), SceneError> {
    c.positive("model.ironing.slab.length", i.slab.length)?;
    c.positive("model.ironing.slab.height", i.slab.height)?;
    c.between("model.ironing.slab.nx", i.slab.nx, 1, MAX_ELEMENTS_PER_EDGE)?;
    c.between("model.ironing.slab.ny", i.slab.ny, 1, MAX_ELEMENTS_PER_EDGE)?;
    c.material("model.ironing.slab.material", &i.slab.material)?;
    c.positive("model.ironing.iron.width", i.iron.width)?;
    c.positive("model.ironing.iron.height", i.iron.height)?;
    c.positive("model.ironing.iron.sole_radius", i.iron.sole_radius)?;
    if i.iron.sole_radius <= 0.5 * i.iron.width {
        return Err(c.fail(
            "model.ironing.iron.sole_radius",
            format!("is {}, but the sole spans the width {}", i.iron.sole_radius, i.iron.width),
            "give a sole radius larger than half the iron's width",
        ));
    }
    c.finite("model.ironing.iron.contact_x", i.iron.contact_x)?;
    c.between("model.ironing.iron.nx", i.iron.nx, 1, MAX_ELEMENTS_PER_EDGE)?;
    c.between("model.ironing.iron.ny", i.iron.ny, 1, MAX_ELEMENTS_PER_EDGE)?;
    c.material("model.ironing.iron.material", &i.iron.material)?;
    match i.d_y {
        Some(d) => c.finite("model.ironing.d_y", d),
        None => Ok(()),
    }
}

fn check_hertz3d(c: &Checker<'_>, h: &Hertz3dSpec) -> Result<(), SceneError> {
    let at = "model.hertz3d";
    c.positive(&format!("{at}.radius"), h.radius)?;
    c.material(&format!("{at}.material"), &h.material)?;
    c.between(&format!("{at}.n"), h.n, 2, MAX_ELEMENTS_PER_EDGE_3D)?;
    c.finite(&format!("{at}.grading"), h.grading)?;
    if !(1.0..=6.0).contains(&h.grading) {
        return Err(c.fail(
            &format!("{at}.grading"),
            format!("is {}; it is the exponent that clusters elements toward the pole", h.grading),
            "give a value from 1 (uniform) to 6, e.g. 3",
        ));
    }
    check_planes(c, &format!("{at}.symmetry"), &h.symmetry)?;
    c.positive(&format!("{at}.contact_radius"), h.contact_radius)?;
    if h.contact_radius > h.radius {
        return Err(c.fail(
            &format!("{at}.contact_radius"),
            format!("is {}, beyond the radius {}", h.contact_radius, h.radius),
            "give a contact radius at most the radius (a few times the largest contact radius a(d) = sqrt(R d / 2))",
        ));
    }
    Ok(())
}

fn check_ironing3d(c: &Checker<'_>, i: &Ironing3dSpec) -> Result<(), SceneError> {
    let (b, d, s) = (&i.block, &i.die, &i.slaves);
    check_planes(c, "model.ironing3d.symmetry", &i.symmetry)?;
    for (f, v) in [("block.length", b.length), ("block.depth", b.depth), ("block.height", b.height)] {
        c.positive(&format!("model.ironing3d.{f}"), v)?;
    }
    for (f, n) in [
        ("block.nx", b.nx),
        ("block.ny", b.ny),
        ("block.nz", b.nz),
        ("die.nx", d.nx),
        ("die.ny", d.ny),
        ("die.nz", d.nz),
    ] {
        c.between(&format!("model.ironing3d.{f}"), n, 1, MAX_ELEMENTS_PER_EDGE_3D)?;
    }
    c.material("model.ironing3d.block.material", &b.material)?;
    for (f, v) in
        [("die.width", d.width), ("die.depth", d.depth), ("die.height", d.height), ("die.sole_radius", d.sole_radius)]
    {
        c.positive(&format!("model.ironing3d.{f}"), v)?;
    }
    c.material("model.ironing3d.die.material", &d.material)?;
    if d.sole_radius <= 0.5 * d.width {
        return Err(c.fail(
            "model.ironing3d.die.sole_radius",
            format!("is {}, but the sole spans the width {}", d.sole_radius, d.width),
            "give a sole radius larger than half the die's width",
        ));
    }
    if d.depth > b.depth {
        return Err(c.fail(
            "model.ironing3d.die.depth",
            format!("is {}, deeper than the block ({})", d.depth, b.depth),
            "give the die a depth at most the block's",
        ));
    }
    let rise = die_rise(i);
    if d.height <= rise {
        return Err(c.fail(
            "model.ironing3d.die.height",
            format!(
                "is {}, not above the sole's rise {rise:.4} at the die's edges: its elements there would be inverted",
                d.height
            ),
            "give the die a height above the sole's rise (a larger height or sole_radius)",
        ));
    }
    c.finite("model.ironing3d.die.contact_x", d.contact_x)?;
    if !(d.contact_x > 0.0 && d.contact_x < b.length) {
        return Err(c.fail(
            "model.ironing3d.die.contact_x",
            format!("is {}, off the block [0, {}]", d.contact_x, b.length),
            "put the sole's lowest line over the block",
        ));
    }
    for (f, v) in [("slaves.x_min", s.x_min), ("slaves.x_max", s.x_max), ("slaves.y_max", s.y_max)] {
        c.finite(&format!("model.ironing3d.{f}"), v)?;
    }
    if s.x_max <= s.x_min || s.y_max <= 0.0 {
        return Err(c.fail(
            "model.ironing3d.slaves",
            format!("is the box x in [{}, {}], y <= {}: empty", s.x_min, s.x_max, s.y_max),
            "give x_min < x_max and y_max > 0, covering the block top the die travels over",
        ));
    }
    if let Some(dz) = i.d_z {
        c.finite("model.ironing3d.d_z", dz)?;
        check_die_press(c, "model.ironing3d.d_z", dz, i)?;
    }
    Ok(())
}

/// The rise of the die's cylindrical sole at its edges above its lowest line,
/// `R - sqrt(R^2 - (w/2)^2)`.
pub fn die_rise(i: &Ironing3dSpec) -> f64 {
    let d = &i.die;
    d.sole_radius - (d.sole_radius * d.sole_radius - 0.25 * d.width * d.width).max(0.0).sqrt()
}

/// A press `dz` (the field `field`: `d_z`, or the `d_z` axis's upper end) must stay below the
/// die's rise ([`die_rise`]).
fn check_die_press(c: &Checker<'_>, field: &str, dz: f64, i: &Ironing3dSpec) -> Result<(), SceneError> {
    let rise = die_rise(i);
    if dz.is_finite() && dz >= rise {
        return Err(c.fail(
            field,
            format!("is {dz}, not below the rise {rise:.4} of the die's sole: its edges, not its sole, would meet the block, and the contact model has only the sole"),
            &format!("press less than {rise:.4} (d_z), or give the sole more rise (a smaller model.ironing3d.die.sole_radius or a wider die)"),
        ));
    }
    Ok(())
}

/// Symmetry planes: finite positions, no plane twice.
fn check_planes(c: &Checker<'_>, at: &str, planes: &[crate::scene::PlaneSpec]) -> Result<(), SceneError> {
    for (i, p) in planes.iter().enumerate() {
        c.finite(&format!("{at}[{i}].at"), p.at)?;
        if planes[..i].iter().any(|q| q.axis == p.axis && q.at.to_bits() == p.at.to_bits()) {
            return Err(c.fail(&format!("{at}[{i}]"), "repeats an earlier plane".into(), "list each plane once"));
        }
    }
    Ok(())
}

/// A 3-D scene: no primal translates (of a 2-D slab). The registered maps, the neighbours' whole-node shifts included, act along x on each
/// line of the contact area.
fn check_3d_study(c: &Checker<'_>, scene: &SceneConfig) -> Result<(), SceneError> {
    let entries = scene.comparison.as_ref().map_or(&[][..], |cmp| cmp.approximations.as_slice());
    for (i, a) in entries.iter().enumerate() {
        if matches!(a, ApproximationSpec::Registered { primal_translates: Some(_), .. }) {
            return Err(c.fail(
                &format!("comparison.approximations[{i}].primal_translates"),
                "is set, but the translates shift a 2-D slave slab by whole columns; a 3-D scene's registered bases are solved online on the study's own primal space".into(),
                "remove primal_translates from a 3-D scene's registered entries",
            ));
        }
        if matches!(scene.model, Model::Hertz3d(_)) && matches!(a, ApproximationSpec::Registered { .. }) {
            // measured on the shipped mesh: the moments map's registered POD reads a test error
            // of 0.88 or more at every m (the plain POD 5e-3 at 11 modes), its CPG 13 to 20
            // (relative) online
            return Err(c.fail(
                &format!("comparison.approximations[{i}].map"),
                "is set on hertz3d, whose contact area is a disc that widens with d; the registered maps \
                 shift or stretch lines of slaves along one axis (the die's travel on ironing3d's block), \
                 which the nodes of a hemisphere's cap do not form, so no map registers it"
                    .into(),
                "remove the registered entries from this scene's [comparison]",
            ));
        }
    }
    Ok(())
}

/// `study.model_dual`: `cpg`, `cpg-sampled` (with `study.contact_sampling`) or the name of a
/// registered CPG approximation of `[comparison]`.
fn check_model_dual(
    c: &Checker<'_>,
    dual: &str,
    cmp: Option<&ComparisonSpec>,
    sampling: bool,
) -> Result<(), SceneError> {
    if dual == MODEL_DUAL_CPG_SAMPLED {
        return match sampling {
            true => Ok(()),
            false => Err(c.fail(
                "study.model_dual",
                format!("is \"{dual}\", but the study samples no contact surface"),
                "add study.contact_sampling (e.g. contact_sampling = { tol = 1e-6, ranks = [[40, 48]] }) with the ranks to store in study.model_ranks, or use \"cpg\"",
            )),
        };
    }
    let registered: Vec<String> = cmp
        .map(|cmp| cmp.approximations.iter().filter(|a| a.storable()).map(ApproximationSpec::name).collect())
        .unwrap_or_default();
    if dual == MODEL_DUAL_CPG || registered.iter().any(|n| n == dual) {
        return Ok(());
    }
    if let Some(base) = dual.strip_suffix(SAMPLED_SUFFIX).filter(|b| registered.iter().any(|n| n == b)) {
        if !base.starts_with(WHOLE_NODE_PREFIX) {
            return Err(c.fail(
                "study.model_dual",
                format!("is \"{dual}\": a quadrature in the reference frame needs whole-node shifts"),
                &format!("sample a {WHOLE_NODE_PREFIX}… approximation, or name \"{base}\" without {SAMPLED_SUFFIX}"),
            ));
        }
        if !sampling {
            return Err(c.fail(
                "study.model_dual",
                format!("is \"{dual}\", but the study samples no contact surface"),
                "add study.contact_sampling (e.g. contact_sampling = { tol = 1e-3, ranks = [[32, 8]] }), or name the approximation without -sampled",
            ));
        }
        return Ok(());
    }
    let fix = if registered.is_empty() {
        format!(
            "use \"{MODEL_DUAL_CPG}\" (the study's CPG basis), or add a registered CPG approximation to \
             [comparison] (e.g. {{ kind = \"registered\", map = \"translate\", interpolation = \"nodes\", \
             basis = \"cpg\" }}) and name it here (registered-translate-nodes-cpg); or remove study.model_dual"
        )
    } else {
        format!(
            "use \"{MODEL_DUAL_CPG}\" (the study's CPG basis) or one of this scene's registered CPG approximations: {}; \
             or remove study.model_dual (the most accurate is stored)",
            registered.join(", ")
        )
    };
    Err(c.fail("study.model_dual", format!("is \"{dual}\": not a dual approximation a stored model can carry"), &fix))
}

fn check_comparison(
    c: &Checker<'_>,
    cmp: &ComparisonSpec,
    model: &Model,
    dims: usize,
    first_axis: usize,
) -> Result<(), SceneError> {
    c.between("comparison.max_m", cmp.max_m, 1, 4096)?;
    c.between("comparison.loo_folds", cmp.loo_folds, 1, MAX_COUNT)?;
    if cmp.approximations.is_empty() {
        return Err(c.fail(
            "comparison.approximations",
            "is empty: there is nothing to compare".into(),
            "list approximations, e.g. [{ kind = \"pod\" }, { kind = \"cpg\" }], or remove [comparison]",
        ));
    }
    let mut seen = std::collections::BTreeSet::new();
    for (i, a) in cmp.approximations.iter().enumerate() {
        let field = format!("comparison.approximations[{i}]");
        let key = format!("{a:?}");
        if !seen.insert(key) {
            return Err(c.fail(&field, "repeats an earlier entry".into(), "list each approximation once"));
        }
        match a {
            ApproximationSpec::Nnmf { iterations } => {
                c.between(&format!("{field}.iterations"), *iterations, 1, 1_000_000)?
            }
            ApproximationSpec::Local { cells, overlap } => {
                if cells.is_empty() {
                    return Err(c.fail(
                        &format!("{field}.cells"),
                        "is empty".into(),
                        "give cell counts, e.g. [2, 4, 8]",
                    ));
                }
                for (k, &n) in cells.iter().enumerate() {
                    c.between(&format!("{field}.cells[{k}]"), n, 1, 4096)?;
                    // Evenly spaced training points fill every one of K cells iff K <= N - 1.
                    if n + 1 > first_axis {
                        return Err(c.fail(
                            &format!("{field}.cells[{k}]"),
                            format!(
                                "is {n}, but the training set has {first_axis} points along its first axis, so a cell would hold none"
                            ),
                            &format!("use at most {} cells", first_axis.saturating_sub(1).max(1)),
                        ));
                    }
                }
                c.finite(&format!("{field}.overlap"), *overlap)?;
                if !(0.0..=10.0).contains(overlap) {
                    return Err(c.fail(
                        &format!("{field}.overlap"),
                        format!("is {overlap}; it is a fraction of a cell's width on each side"),
                        "give a value in [0, 10], e.g. 0.1",
                    ));
                }
            }
            ApproximationSpec::Registered { map, interpolation, refine, basis, primal_translates } => {
                c.between(&format!("{field}.refine"), *refine, 1, 64)?;
                if *basis == BasisSpec::LevelPod && dims != 2 {
                    return Err(c.fail(
                        &format!("{field}.basis"),
                        format!(
                            "is \"level-pod\", one POD per interval between the levels of a second parameter \
                             component; this scene has {dims} parameter component(s)"
                        ),
                        "use basis = \"pod\"",
                    ));
                }
                if let Some(k) = primal_translates {
                    if matches!(basis, BasisSpec::Pod | BasisSpec::LevelPod) {
                        return Err(c.fail(
                            &format!("{field}.primal_translates"),
                            "is set for a registered POD, which has no online solve (its modes are signed)".into(),
                            "remove primal_translates, or use basis = \"cpg\" or \"neighbours\"",
                        ));
                    }
                    if *map != MapSpec::Translate {
                        return Err(c.fail(
                            &format!("{field}.primal_translates"),
                            "is set with map = \"moments\"; translates of the responses follow a master that \
                             travels along a regular slave body, which a translation map describes"
                                .into(),
                            "use map = \"translate\", or remove primal_translates",
                        ));
                    }
                    c.between(&format!("{field}.primal_translates"), *k, 1, 10_000)?;
                    if matches!(model, Model::Hertz(_)) {
                        return Err(c.fail(
                            &format!("{field}.primal_translates"),
                            "is set for hertz, whose slave surface is an arc: its translates are not \
                             responses of anything (they need a slave body meshed as a regular grid along x)"
                                .into(),
                            "remove primal_translates from this entry",
                        ));
                    }
                }
                if matches!(model, Model::Rope(_)) {
                    return Err(c.fail(
                        &format!("{field}.map"),
                        "is set for the rope, which has no natural map: both ends of its contact set move with \
                         the load in ways no translation or dilation of one profile follows"
                            .into(),
                        "remove the registered entry from the rope's comparison",
                    ));
                }
                if *interpolation == InterpolationSpec::Nodes && *map != MapSpec::Translate {
                    return Err(c.fail(
                        &format!("{field}.interpolation"),
                        "is \"nodes\", which only a translation can use (a dilation does not map nodes to nodes)"
                            .into(),
                        "use interpolation = \"linear\" with map = \"moments\"",
                    ));
                }
                if *basis == BasisSpec::Neighbours
                    && (*map != MapSpec::Translate || *interpolation != InterpolationSpec::Nodes)
                {
                    return Err(c.fail(
                        &format!("{field}.basis"),
                        "is \"neighbours\", which orders the training snapshots by the part of a node spacing \
                         that whole-node shifts leave"
                            .into(),
                        "use map = \"translate\" with interpolation = \"nodes\", or basis = \"cpg\"",
                    ));
                }
                if *basis == BasisSpec::Neighbours && dims > 2 {
                    return Err(c.fail(
                        &format!("{field}.basis"),
                        format!(
                            "is \"neighbours\", which orders the training snapshots by the travel and at most one \
                             more component; this scene has {dims} parameter components"
                        ),
                        "use basis = \"cpg\"",
                    ));
                }
            }
            ApproximationSpec::Pod
            | ApproximationSpec::Cpg
            | ApproximationSpec::AngleGreedy
            | ApproximationSpec::Dictionary => {}
        }
    }
    // Every approximation is a stage and a row label: two entries may not share a name.
    let mut names: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    for (i, a) in cmp.approximations.iter().enumerate() {
        for e in a.expand() {
            if let Some(first) = names.insert(e.name(), i) {
                if first == i {
                    return Err(c.fail(
                        &format!("comparison.approximations[{i}].cells"),
                        format!("lists a cell count twice (`{}`)", e.name()),
                        "list each cell count once",
                    ));
                }
                return Err(c.fail(
                    &format!("comparison.approximations[{i}]"),
                    format!(
                        "is named `{}` in the tables, as entry [{first}] is (entries differing only in iterations, \
                         refine or overlap share a name)",
                        e.name()
                    ),
                    "keep one of the two entries (run the other setting in a copy of the scene file)",
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::error::SceneError;
    use crate::scene::SceneConfig;
    use std::path::Path;

    /// A scene name becomes a directory and a link in the store (`runs/<name>`,
    /// `scenes/<name>`): every attempt to leave the store through it, or to hide it, is refused
    /// with an error naming the field; plain names pass.
    /// An iron pressed deeper than its sole's rise is a setting that cannot work (exit 2 naming
    /// the field), fixed or as the d_y axis; the rise is `R - sqrt(R^2 - (w/2)^2)`, 0.0635 for
    /// the shipped sole (R = 2, w = 1).
    #[test]
    fn an_iron_pressed_past_its_sole_is_refused() {
        let ironing = include_str!("../../data/scenes/ironing-coarse.toml");
        let parse = |from: &str, to: &str| {
            assert!(ironing.contains(from), "ironing-coarse.toml changed: update this test");
            SceneConfig::from_toml_str(&ironing.replacen(from, to, 1), Path::new("i.toml"))
        };
        assert!(parse("d_y = 0.04", "d_y = 0.063").is_ok());
        for deep in ["d_y = 0.0636", "d_y = 0.4"] {
            match parse("d_y = 0.04", deep) {
                Err(SceneError::Invalid { field, problem, .. }) => {
                    assert_eq!(field, "model.ironing.d_y");
                    assert!(problem.contains("0.0635"), "{problem}");
                }
                other => panic!("{deep}: {other:?}"),
            }
        }
        let two_d = include_str!("../../data/scenes/ironing-fine-2d.toml");
        let axis_max = two_d.lines().find(|l| l.trim_start().starts_with("max = 0.06")).expect("d_y axis max");
        let text = two_d.replacen(axis_max, "max = 0.07", 1);
        match SceneConfig::from_toml_str(&text, Path::new("i2.toml")) {
            Err(SceneError::Invalid { field, .. }) => assert_eq!(field, "parameter.axes[0].max"),
            other => panic!("d_y axis to 0.07: {other:?}"),
        }
    }

    /// The same for the 3-D die (rise 0.0635 for the shipped sole, R = 2, w = 1) when `d_z` is
    /// a parameter axis: its upper end is refused naming the axis, a shallower one passes.
    #[test]
    fn a_die_pressed_past_its_sole_by_the_d_z_axis_is_refused() {
        let three_d = include_str!("../../data/scenes/ironing-3d.toml");
        let parse = |max: &str| {
            assert!(
                three_d.contains("d_z = 0.04\n") && three_d.contains("train_level = 7\n"),
                "ironing-3d.toml changed"
            );
            let text = three_d.replacen("d_z = 0.04\n", "", 1).replacen(
                "train_level = 7\n",
                &format!("train_level = 5\n\n[[parameter.axes]]\nname = \"d_z\"\ndescription = \"downward displacement of the die\"\nmin = 0.02\nmax = {max}\ntrain_level = 2\n"),
                1,
            );
            SceneConfig::from_toml_str(&text, Path::new("i3.toml"))
        };
        assert!(parse("0.06").is_ok(), "{:?}", parse("0.06"));
        match parse("0.07") {
            Err(SceneError::Invalid { field, problem, .. }) => {
                assert_eq!(field, "parameter.axes[0].max");
                assert!(problem.contains("0.0635"), "{problem}");
            }
            other => panic!("d_z axis to 0.07: {other:?}"),
        }
    }

    /// `study.model_dual`: `cpg` everywhere, a registered CPG approximation of the scene's
    /// `[comparison]`; anything else refused naming the field, with the names the scene allows
    /// (or, without one, how to add a registered approximation).
    #[test]
    fn model_dual_names_a_dual_basis_the_scene_measures() {
        let parse = |scene: &str, dual: &str| {
            let text = match scene {
                "hertz" => include_str!("../../data/scenes/hertz.toml"),
                _ => include_str!("../../data/scenes/rope.toml"),
            };
            let seed = if scene == "hertz" { "seed = 20232" } else { "seed = 20231" };
            assert!(text.contains(seed), "{scene}.toml changed: update this test");
            let edited = text.replacen(seed, &format!("{seed}\nmodel_dual = {dual:?}"), 1);
            SceneConfig::from_toml_str(&edited, Path::new("s.toml"))
        };
        for (scene, ok) in [("hertz", "cpg"), ("hertz", "registered-moments-cpg"), ("rope", "cpg")] {
            assert!(parse(scene, ok).is_ok(), "{scene}: {ok}");
        }
        // the sampled surface's rows only where the study samples the surface
        let sampled = include_str!("../../data/scenes/hertz.toml").replacen(
            "seed = 20232",
            "seed = 20232\nmodel_dual = \"cpg-sampled\"\ncontact_sampling = { tol = 0.0, ranks = [[12, 12]] }",
            1,
        );
        assert!(SceneConfig::from_toml_str(&sampled, Path::new("s.toml")).is_ok(), "cpg-sampled with sampling");
        // a registered basis sampled in its reference frame: whole-node shifts, with sampling
        match parse("hertz", "registered-moments-cpg-sampled") {
            Err(SceneError::Invalid { field, fix, .. }) => {
                assert_eq!(field, "study.model_dual");
                assert!(fix.contains("registered-translate-nodes-"), "{fix}");
            }
            other => panic!("a moments map sampled: {other:?}"),
        }
        let ironing = include_str!("../../data/scenes/ironing-3d.toml");
        assert!(SceneConfig::from_toml_str(ironing, Path::new("s.toml")).is_ok(), "the shipped sampled neighbours");
        let unsampled = ironing.replace("contact_sampling = { tol = 5e-4, ranks = [[129, 8]] }\n", "");
        assert!(unsampled.len() < ironing.len(), "ironing-3d.toml changed: update this test");
        match SceneConfig::from_toml_str(&unsampled, Path::new("s.toml")) {
            Err(SceneError::Invalid { field, fix, .. }) => {
                assert_eq!(field, "study.model_dual");
                assert!(fix.contains("study.contact_sampling"), "{fix}");
            }
            other => panic!("sampled neighbours without sampling: {other:?}"),
        }
        match parse("hertz", "cpg-sampled") {
            Err(SceneError::Invalid { field, fix, .. }) => {
                assert_eq!(field, "study.model_dual");
                assert!(fix.contains("study.contact_sampling"), "{fix}");
            }
            other => panic!("cpg-sampled without sampling: {other:?}"),
        }
        for (scene, bad, fix_says) in [
            ("hertz", "registered-moments-pod", "registered-moments-cpg"),
            ("hertz", "nnmf", "registered-moments-cpg"),
            ("rope", "registered-moments-cpg", "add a registered CPG approximation"),
        ] {
            match parse(scene, bad) {
                Err(SceneError::Invalid { field, fix, .. }) => {
                    assert_eq!(field, "study.model_dual", "{scene}: {bad}");
                    assert!(fix.contains(fix_says), "{scene}: {bad}: {fix}");
                }
                other => panic!("{scene}: {bad}: {other:?}"),
            }
        }
    }

    #[test]
    fn scene_names_cannot_leave_the_store() {
        let rope = include_str!("../../data/scenes/rope.toml");
        assert!(rope.contains("name = \"rope\""), "rope.toml changed: update this test");
        let parse = |name: &str| {
            let text = rope.replacen("name = \"rope\"", &format!("name = {name:?}"), 1);
            SceneConfig::from_toml_str(&text, Path::new("rope.toml"))
        };
        for bad in ["../../../escaped", "..", ".", "a/b", "a\\b", "/abs", ".hidden", "", " ", "x y", "é", "a:b"] {
            match parse(bad) {
                Err(SceneError::Invalid { field, .. }) => assert_eq!(field, "scene.name", "{bad:?}"),
                other => panic!("{bad:?}: {other:?}"),
            }
        }
        for good in ["rope", "rope-2", "ironing_fine.v2"] {
            assert!(parse(good).is_ok(), "{good:?} refused");
        }
    }
}
