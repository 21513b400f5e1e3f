//! `model.h5`: a reduced model a user can run ([`StoredModel`]), and `reconstruction.h5`, the
//! optional bases that turn its answers into fields ([`Reconstruction`]).
//!
//! `model.h5` holds, at its root, one dataset per array of `crom_stages::rom::ModelParts`
//! (1-D, float64 or uint64, named as there; matrices flattened as the parts' doc says) and these
//! attributes: the parts' integer scalars (`surface`, `r_primal`, `r_dual`, `n_contact`,
//! `lift_terms`, `warm_dim`, and Type-2 `n_slaves`, `n_masters`); `schema_version`, `scene`,
//! `cache_key`; the solver settings `algorithm` (`exact` or `exact-sampled`: which rows of the
//! study's trade-off measured it), `dual_basis` (`full` or `truncated`: the study's CPG basis;
//! or the name of a registered approximation, e.g. `registered-translate-nodes-cpg`, whose
//! basis the `reg_*` arrays hold), `max_iter`, `gap_tol`, `u_tol`, `exact_step`; the parameter
//! `parameter_names` (comma-separated) with datasets `parameter_min`, `parameter_max` (the
//! training domain, one value per component); and what the study measured for it at its test
//! points: `measured_points`, `measured_converged`, `measured_median_primal_error`,
//! `measured_p95_primal_error`, `measured_median_dual_error` (absent where the study's table
//! has null). Its size depends on the ranks and the contact surface, never on `n_dof`.
//!
//! Written and read here only; the HDF5 calls go through [`super::h5`] (one thread).

use std::path::Path;

use crom_schemas::artifact::model as names;
use crom_stages::rom::ModelParts;

use super::h5::{ColMatrix, H5In, H5Out};
use crate::error::CromError;

/// What the study measured for the stored model at its test points (a row of `tradeoff.parquet`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measured {
    /// Test points.
    pub points: u64,
    /// Of which converged.
    pub converged: u64,
    /// Median relative H1 error of the displacement over the converged points.
    pub median_primal_error: f64,
    /// Its 95th percentile.
    pub p95_primal_error: f64,
    /// Median relative (tributary-weighted L2) error of the pressure (NaN: undefined).
    pub median_dual_error: f64,
}

impl Measured {
    /// Nothing measured (no test point; undefined errors).
    pub fn none() -> Self {
        Self {
            median_primal_error: f64::NAN,
            p95_primal_error: f64::NAN,
            median_dual_error: f64::NAN,
            ..Self::default()
        }
    }
}

/// A reduced model with what a query needs beside its arrays.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredModel {
    /// The arrays of the online solve.
    pub parts: ModelParts,
    /// Scene name.
    pub scene: String,
    /// `exact` or `exact-sampled`.
    pub algorithm: String,
    /// `full` or `truncated` (the study's CPG basis), or a registered approximation's name.
    pub dual_basis: String,
    /// Solver settings (`crom_stages::rom::RomParams`).
    pub max_iter: u64,
    /// See `RomParams::gap_tol`.
    pub gap_tol: f64,
    /// See `RomParams::u_tol`.
    pub u_tol: f64,
    /// See `RomParams::exact_step` (0: the first-order corrected step).
    pub exact_step: u64,
    /// Parameter component names.
    pub parameter_names: Vec<String>,
    /// Training domain, lower bounds.
    pub parameter_min: Vec<f64>,
    /// Training domain, upper bounds.
    pub parameter_max: Vec<f64>,
    /// What the study measured.
    pub measured: Measured,
}

/// The optional reconstruction part.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstruction {
    /// The primal basis `phi`, `n_dof x r_primal`.
    pub phi: ColMatrix,
    /// The lift's affine terms, `n_dof x (1 + dim)`.
    pub lift: ColMatrix,
}

fn fix_read(path: &Path, message: String) -> CromError {
    CromError::artifact(
        path,
        message,
        "the stored model is damaged or from another version of crom; delete its directory and run `crom run SCENE` again",
    )
}

impl StoredModel {
    /// Write `model.h5` at `path` (`key`: the artifact's cache key).
    pub fn write(&self, path: &Path, key: &str) -> Result<(), CromError> {
        let f = H5Out::create(path)?;
        f.attr_u64("schema_version", u64::from(names::SCHEMA_VERSION))?;
        f.attr_str("scene", &self.scene)?;
        f.attr_str("kind", "model")?;
        f.attr_str("cache_key", key)?;
        f.attr_str("algorithm", &self.algorithm)?;
        f.attr_str("dual_basis", &self.dual_basis)?;
        f.attr_u64("max_iter", self.max_iter)?;
        f.attr_f64("gap_tol", self.gap_tol)?;
        f.attr_f64("u_tol", self.u_tol)?;
        f.attr_u64("exact_step", self.exact_step)?;
        f.attr_str("parameter_names", &self.parameter_names.join(","))?;
        f.vec_f64("parameter_min", &self.parameter_min, "lower bound of each parameter component")?;
        f.vec_f64("parameter_max", &self.parameter_max, "upper bound of each parameter component")?;
        let m = &self.measured;
        f.attr_u64("measured_points", m.points)?;
        f.attr_u64("measured_converged", m.converged)?;
        // an undefined value (no converged point, no contact) is an absent attribute, never NaN
        for (name, v) in [
            ("measured_median_primal_error", m.median_primal_error),
            ("measured_p95_primal_error", m.p95_primal_error),
            ("measured_median_dual_error", m.median_dual_error),
        ] {
            if v.is_finite() {
                f.attr_f64(name, v)?;
            }
        }
        for (name, v) in &self.parts.scalars {
            f.attr_u64(name, *v)?;
        }
        for (name, v) in &self.parts.floats {
            f.vec_f64(name, v, "see docs/store-format.md, the model artifact")?;
        }
        for (name, v) in &self.parts.ints {
            f.vec_u64(name, v)?;
        }
        Ok(())
    }

    /// Read `model.h5` at `path`; a file of another schema version is refused before anything
    /// else is read.
    pub fn read(path: &Path) -> Result<Self, CromError> {
        let f = H5In::open(path)?;
        let version = f.attr_u64("schema_version")?;
        if version < u64::from(names::SCHEMA_VERSION) {
            return Err(CromError::artifact(
                path,
                format!(
                    "model schema version {version}, written by an older crom; this crom reads version {}",
                    names::SCHEMA_VERSION
                ),
                "run `crom run SCENE` again: it writes the model in the current layout (the old one can be deleted)",
            ));
        }
        if version != u64::from(names::SCHEMA_VERSION) {
            return Err(fix_read(
                path,
                format!("model schema version {version}; this crom reads version {}", names::SCHEMA_VERSION),
            ));
        }
        let mut parts = ModelParts::default();
        for name in ModelParts::SCALARS {
            if f.contains_attr(name) {
                parts.scalars.push((name, f.attr_u64(name)?));
            }
        }
        for name in ModelParts::FLOATS {
            if f.contains(name) {
                parts.floats.push((name, f.vec_f64(name)?));
            }
        }
        for name in ModelParts::INTS {
            if f.contains(name) {
                parts.ints.push((name, f.vec_u64(name)?));
            }
        }
        let names_attr = f.attr_str("parameter_names")?;
        let optional = |name: &str| if f.contains_attr(name) { f.attr_f64(name) } else { Ok(f64::NAN) };
        let model = Self {
            parts,
            scene: f.attr_str("scene")?,
            algorithm: f.attr_str("algorithm")?,
            dual_basis: f.attr_str("dual_basis")?,
            max_iter: f.attr_u64("max_iter")?,
            gap_tol: f.attr_f64("gap_tol")?,
            u_tol: f.attr_f64("u_tol")?,
            exact_step: f.attr_u64("exact_step")?,
            parameter_names: names_attr.split(',').map(str::to_string).collect(),
            parameter_min: f.vec_f64("parameter_min")?,
            parameter_max: f.vec_f64("parameter_max")?,
            measured: Measured {
                points: f.attr_u64("measured_points")?,
                converged: f.attr_u64("measured_converged")?,
                median_primal_error: optional("measured_median_primal_error")?,
                p95_primal_error: optional("measured_p95_primal_error")?,
                median_dual_error: optional("measured_median_dual_error")?,
            },
        };
        if model.exact_step > crom_stages::rom::MAX_EXACT_STEP as u64 {
            return Err(fix_read(
                path,
                format!(
                    "exact_step is {}; the corrected step takes at most {}",
                    model.exact_step,
                    crom_stages::rom::MAX_EXACT_STEP
                ),
            ));
        }
        let dim = model.parameter_names.len();
        if model.parameter_min.len() != dim || model.parameter_max.len() != dim {
            return Err(fix_read(path, format!("{dim} parameter names but {} bounds", model.parameter_min.len())));
        }
        Ok(model)
    }
}

impl Reconstruction {
    /// Write `reconstruction.h5` at `path`.
    pub fn write(&self, path: &Path, key: &str) -> Result<(), CromError> {
        let f = H5Out::create(path)?;
        f.attr_u64("schema_version", u64::from(names::SCHEMA_VERSION))?;
        f.attr_str("cache_key", key)?;
        f.matrix_raw("phi", &self.phi, "primal basis, one mode per column")?;
        f.matrix_raw("lift", &self.lift, "affine terms of the lift u0(mu), one per column")
    }

    /// Read `reconstruction.h5` at `path`.
    pub fn read(path: &Path) -> Result<Self, CromError> {
        let f = H5In::open(path)?;
        Ok(Self { phi: f.matrix("phi")?, lift: f.matrix("lift")? })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model written and read back is the same value: every array bit for bit (floats with
    /// NaN and signed zero included: compared by `to_bits`), every attribute, and a file of
    /// another schema version is refused.
    #[test]
    fn write_read_round_trip_is_exact() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let path = tmp.path().join("model.h5");
        let floats: Vec<f64> =
            (0..300).map(|k| (k as f64 * 0.37).sin() / 3.0).chain([-0.0, f64::MIN_POSITIVE]).collect();
        let parts = ModelParts {
            scalars: vec![("surface", 1), ("r_primal", 3), ("n_slaves", 7)],
            floats: vec![("khat_l", floats.clone()), ("quad", Vec::new())],
            ints: vec![("theta_start", vec![0, 5, u64::MAX]), ("supp", vec![1, 2, 3])],
        };
        let model = StoredModel {
            parts,
            scene: "s".into(),
            algorithm: "exact".into(),
            dual_basis: "full".into(),
            max_iter: 100,
            gap_tol: 1e-12,
            u_tol: 1e-10,
            exact_step: 2,
            parameter_names: vec!["d_x".into(), "d_y".into()],
            parameter_min: vec![0.0, -0.1],
            parameter_max: vec![3.0, 0.1],
            measured: Measured {
                points: 9,
                converged: 8,
                median_primal_error: 1e-3,
                p95_primal_error: 2e-3,
                median_dual_error: f64::NAN,
            },
        };
        model.write(&path, "k").expect("write");
        let back = StoredModel::read(&path).expect("read");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(back.parts.float("khat_l")), bits(&floats));
        assert!(back.measured.median_dual_error.is_nan());
        let mut same = back.clone();
        same.measured.median_dual_error = 0.0;
        let mut orig = model.clone();
        orig.measured.median_dual_error = 0.0;
        assert_eq!(same, orig);
        // another schema version
        let other = tmp.path().join("other.h5");
        let f = H5Out::create(&other).expect("create");
        f.attr_u64("schema_version", 99).expect("attr");
        drop(f);
        let e = StoredModel::read(&other).expect_err("refused").to_string();
        assert!(e.contains("schema version 99"), "{e}");
    }
}
