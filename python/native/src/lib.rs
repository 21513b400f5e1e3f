//! `crom_native`: the native part of the Python package `crom_data` — a stored reduced model
//! (the `model` artifact) loaded and solved from Python with the code `crom query` runs.
//!
//! Users do not import this module: `crom_data.open_store(path).scene(name).rom()` finds the
//! model in the published study, checks its manifest and schema version, and wraps a [`Model`]
//! (`crom_data.rom`). Everything numerical is the pipeline's: [`load_artifact`] loads and
//! verifies the artifact, [`answer`] is the per-point call of `crom query` (the exact online solve
//! with the stored settings, then the indicator and the pressure), and
//! [`crom_pipeline::query::fields::displacement`] reconstructs the displacement from
//! `reconstruction.h5`. So an answer from Python is the query's, bit for bit.
//!
//! Arrays cross the boundary as `bytes` of native-endian `f64`/`u64`/`u8` (NumPy wraps them
//! with `np.frombuffer`, one copy): no NumPy or ndarray crate, and no unsafe code here. The GIL
//! is released while solving; `solve_many` runs the points in parallel on the global rayon pool
//! (the `crom` rule: `RAYON_NUM_THREADS`, else one thread per core) or on a pool of `threads`.
//!
//! Errors are raised as the exception classes of `crom_data.errors` (looked up by name when
//! raised), with messages naming the component and the fix.

mod points;

use std::path::PathBuf;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

use crom_pipeline::cache::Key;
use crom_pipeline::error::CromError;
use crom_pipeline::io::model::Reconstruction;
use crom_pipeline::query::{answer, checked_u_tol, fields, load_artifact, params, Answer, Loaded};
use crom_stages::rom::{QueryModel, ReducedModel, RomOutcome, RomParams, RomWork};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple, PyType};
use rayon::prelude::*;

use points::{Bounds, PointError};

/// The outcomes of an online query, in the order of the codes `solve_many` returns.
const OUTCOMES: [RomOutcome; 4] =
    [RomOutcome::Converged, RomOutcome::Infeasible, RomOutcome::Cycled, RomOutcome::NotConverged];

fn outcome_code(o: RomOutcome) -> u8 {
    OUTCOMES.iter().position(|x| *x == o).map_or(u8::MAX, |i| i as u8)
}

/// A Python exception of class `class` of `crom_data.errors` (a `RuntimeError` naming the class
/// if that module cannot be imported).
fn error(py: Python<'_>, class: &str, message: String) -> PyErr {
    let cls = py
        .import("crom_data.errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
    match cls {
        Ok(cls) => PyErr::from_type(cls, message),
        Err(_) => pyo3::exceptions::PyRuntimeError::new_err(format!("{class}: {message}")),
    }
}

fn point_error(py: Python<'_>, e: PointError) -> PyErr {
    let class = if e.outside { "OutsideDomain" } else { "InvalidPoint" };
    error(py, class, e.message)
}

fn crom_error(py: Python<'_>, e: CromError) -> PyErr {
    let class = match e {
        CromError::Artifact { .. } => "CorruptArtifact",
        _ => "CromDataError",
    };
    error(py, class, e.to_string())
}

/// Values as native-endian bytes, 8 per value, written straight into the Python object (no
/// second buffer); a failed allocation of the object is Python's `MemoryError`.
fn ne_bytes<'py>(py: Python<'py>, values: impl ExactSizeIterator<Item = [u8; 8]>) -> PyResult<Bound<'py, PyBytes>> {
    PyBytes::new_with(py, 8 * values.len(), |buf| {
        buf.chunks_exact_mut(8).zip(values).for_each(|(b, x)| b.copy_from_slice(&x));
        Ok(())
    })
}

/// `v` as native-endian bytes ([`ne_bytes`]).
fn f64_bytes<'py>(py: Python<'py>, v: &[f64]) -> PyResult<Bound<'py, PyBytes>> {
    ne_bytes(py, v.iter().map(|x| x.to_ne_bytes()))
}

/// A stored reduced model, loaded.
#[pyclass(frozen, module = "crom_native")]
struct Model {
    loaded: Loaded,
    params: RomParams,
    bounds: Bounds,
    /// Buffers of `solve` and, for a registered dual basis, the model's copy whose basis is
    /// set per point ([`QueryModel`]), reused from call to call (a concurrent call takes fresh
    /// ones).
    work: Mutex<(RomWork, Option<ReducedModel>)>,
    /// `reconstruction.h5`, read on the first displacement (or the reason it cannot be).
    reconstruction: OnceLock<Result<Reconstruction, String>>,
}

impl Model {
    fn reconstruction(&self) -> Result<&Reconstruction, String> {
        self.reconstruction
            .get_or_init(|| {
                let path = self.loaded.dir.join(crom_schemas::artifact::model::RECONSTRUCTION);
                let rec = self.loaded.reconstruction("run the study again").map_err(|e| e.to_string())?;
                let (r, dim) = (self.loaded.model.ranks().0, self.bounds.names.len());
                if rec.phi.cols != r || rec.lift.rows != rec.phi.rows || rec.lift.cols != 1 + dim {
                    return Err(format!(
                        "{}: phi {} x {} and lift {} x {} do not fit the model's rank {r} and {dim} components",
                        path.display(),
                        rec.phi.rows,
                        rec.phi.cols,
                        rec.lift.rows,
                        rec.lift.cols
                    ));
                }
                Ok(rec)
            })
            .as_ref()
            .map_err(Clone::clone)
    }
}

/// The answer at one point as a tuple (see `crom_data.rom.Result`).
/// `total`: the time of the whole [`answer`] call (solve, indicator, pressure), seconds.
fn answer_tuple<'py>(py: Python<'py>, a: &Answer, extrapolated: bool, total: f64) -> PyResult<Bound<'py, PyTuple>> {
    let i = &a.indicator;
    PyTuple::new(
        py,
        [
            f64_bytes(py, &a.pressure)?.into_any(),
            f64_bytes(py, &a.sol.u_hat)?.into_any(),
            f64_bytes(py, &a.sol.lambda_hat)?.into_any(),
            a.sol.outcome.name().into_pyobject(py)?.into_any(),
            a.sol.iterations.into_pyobject(py)?.into_any(),
            a.sol.linearizations.into_pyobject(py)?.into_any(),
            a.sol.nonzero_dual.into_pyobject(py)?.into_any(),
            i.residual.into_pyobject(py)?.into_any(),
            i.penetration.into_pyobject(py)?.into_any(),
            i.complementarity.into_pyobject(py)?.into_any(),
            i.unpaired_force.into_pyobject(py)?.into_any(),
            pyo3::types::PyBool::new(py, extrapolated).to_owned().into_any(),
            a.seconds.into_pyobject(py)?.into_any(),
            a.indicator_seconds.into_pyobject(py)?.into_any(),
            total.into_pyobject(py)?.into_any(),
        ],
    )
}

#[pymethods]
impl Model {
    /// Load the model artifact `key` of the store at `root`; `fix` is the fix every load error
    /// names. `u_tol`: the re-pairing's stopping distance instead of the model's (`crom query
    /// --u-tol`), in (0, 1).
    #[staticmethod]
    #[pyo3(signature = (root, key, fix, u_tol=None))]
    fn open(py: Python<'_>, root: PathBuf, key: String, fix: String, u_tol: Option<f64>) -> PyResult<Self> {
        let u_tol = checked_u_tol(u_tol).map_err(|t| {
            error(
                py,
                "InvalidSetting",
                format!("u_tol={t}: not a tolerance in (0, 1); give the re-pairing's relative stopping distance, e.g. u_tol=1e-6, or None for the model's own"),
            )
        })?;
        let loaded = py.detach(|| load_artifact(&root, &Key(key), &fix)).map_err(|e| crom_error(py, e))?;
        let s = &loaded.stored;
        let bounds =
            Bounds { names: s.parameter_names.clone(), min: s.parameter_min.clone(), max: s.parameter_max.clone() };
        Ok(Self {
            params: params(s, u_tol),
            bounds,
            loaded,
            work: Mutex::new((RomWork::default(), None)),
            reconstruction: OnceLock::new(),
        })
    }

    /// Parameter component names, in the model's order.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.bounds.names.clone()
    }

    /// Lower bounds of the training domain.
    #[getter]
    fn min(&self) -> Vec<f64> {
        self.bounds.min.clone()
    }

    /// Upper bounds of the training domain.
    #[getter]
    fn max(&self) -> Vec<f64> {
        self.bounds.max.clone()
    }

    /// `(r_primal, r_dual)`; for a registered dual basis `r_dual` is its most generators per
    /// point, `m`.
    #[getter]
    fn ranks(&self) -> (usize, usize) {
        self.loaded.model.stored_ranks()
    }

    /// Contact nodes (the length of a pressure).
    #[getter]
    fn n_contact(&self) -> usize {
        self.loaded.model.weights().len()
    }

    /// The contact nodes' tributary weights, `bytes` of `f64`.
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        f64_bytes(py, self.loaded.model.weights())
    }

    /// The re-pairing's stopping distance the solves use (the model's unless `open` was given
    /// another).
    #[getter]
    fn u_tol(&self) -> f64 {
        self.params.u_tol
    }

    /// The stored settings and measurements: a dict of `algorithm`, `dual_basis`, `max_iter`,
    /// `gap_tol`, `u_tol`, `exact_step`, `measured_points`, `measured_converged`,
    /// `measured_median_primal_error`, `measured_p95_primal_error`, `measured_median_dual_error`.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let s = &self.loaded.stored;
        let d = pyo3::types::PyDict::new(py);
        d.set_item("algorithm", &s.algorithm)?;
        d.set_item("dual_basis", &s.dual_basis)?;
        d.set_item("max_iter", s.max_iter)?;
        d.set_item("gap_tol", s.gap_tol)?;
        d.set_item("u_tol", s.u_tol)?;
        d.set_item("exact_step", s.exact_step)?;
        let m = &s.measured;
        d.set_item("measured_points", m.points)?;
        d.set_item("measured_converged", m.converged)?;
        d.set_item("measured_median_primal_error", m.median_primal_error)?;
        d.set_item("measured_p95_primal_error", m.p95_primal_error)?;
        d.set_item("measured_median_dual_error", m.median_dual_error)?;
        Ok(d)
    }

    /// Solve at one point (`point`: the keyword arguments of `crom_data`'s `rom.solve`, a dict
    /// of every component by name; `None` if a name is missing or extra, which the Python layer
    /// then words, knowing the arguments as given — checked here so that a call costs one
    /// crossing of the boundary and no Python-side list); a tuple
    /// (pressure, û, λ̂ as bytes; outcome; iterations; linearizations; nonzero_dual; indicator,
    /// penetration, complementarity, unpaired_force; extrapolated; seconds, indicator_seconds;
    /// the time of the whole answer: solve, indicator and pressure).
    fn solve<'py>(
        &self,
        py: Python<'py>,
        point: &Bound<'py, PyDict>,
        allow_extrapolation: bool,
    ) -> PyResult<Option<Bound<'py, PyTuple>>> {
        let names = &self.bounds.names;
        if point.len() != names.len() {
            return Ok(None);
        }
        let mut mu = Vec::with_capacity(names.len());
        for (c, name) in names.iter().enumerate() {
            let Some(item) = point.get_item(name)? else { return Ok(None) };
            mu.push(
                item.extract::<f64>().map_err(|_| point_error(py, self.bounds.not_a_number(c, &item.to_string())))?,
            );
        }
        let extrapolated = self.bounds.check(&mu, None, allow_extrapolation).map_err(|e| point_error(py, e))?;
        let (a, total) = py.detach(|| {
            let t = Instant::now();
            let model = &self.loaded.model;
            let a = match self.work.try_lock() {
                Ok(mut guard) => {
                    let (w, copy) = &mut *guard;
                    // a registered basis: this call's copy of the model (kept between calls)
                    let mut q = match copy.take() {
                        Some(m) => QueryModel::Own(Box::new(m)),
                        None => QueryModel::new(model),
                    };
                    let a = answer(&mut q, &self.params, &mu, w);
                    if let QueryModel::Own(m) = q {
                        *copy = Some(*m);
                    }
                    a
                }
                Err(_) => answer(&mut QueryModel::new(model), &self.params, &mu, &mut RomWork::default()),
            };
            (a, t.elapsed().as_secs_f64())
        });
        answer_tuple(py, &a, extrapolated, total).map(Some)
    }

    /// Solve at `n` points (`points`: `n x p` row-major `f64` bytes) in parallel; a tuple of bytes:
    /// pressure (n x n_contact f64), û (n x r_primal), λ̂ (n x r_dual; a registered basis that
    /// used fewer generators at a point has zeros after them), outcome codes (u8, see
    /// `OUTCOMES`), iterations, linearizations, nonzero_dual (u64), indicator, penetration,
    /// complementarity, unpaired_force (f64), extrapolated (u8), seconds, indicator_seconds (f64).
    #[pyo3(signature = (points, n, allow_extrapolation, threads=None))]
    fn solve_many<'py>(
        &self,
        py: Python<'py>,
        points: &[u8],
        n: usize,
        allow_extrapolation: bool,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let p = self.bounds.names.len();
        if points.len() != 8 * n * p {
            return Err(point_error(py, self.bounds.bad_buffer(points.len(), n)));
        }
        let flat: Vec<f64> = points
            .chunks_exact(8)
            .map(|b| f64::from_ne_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
            .collect();
        let rows: Vec<&[f64]> = if p == 0 { vec![&[]; n] } else { flat.chunks_exact(p).collect() };
        let mut flags = Vec::with_capacity(n);
        for (j, mu) in rows.iter().enumerate() {
            flags.push(self.bounds.check(mu, Some(j), allow_extrapolation).map_err(|e| point_error(py, e))?);
        }
        let (model, params) = (&self.loaded.model, &self.params);
        let run = || -> Vec<Answer> {
            rows.par_iter()
                .map_init(|| (QueryModel::new(model), RomWork::default()), |(q, w), mu| answer(q, params, mu, w))
                .collect()
        };
        let answers = match threads {
            None => py.detach(run),
            Some(k) => {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(k.max(1))
                    .build()
                    .map_err(|e| error(py, "CromDataError", format!("cannot start {k} threads: {e}")))?;
                py.detach(|| pool.install(run))
            }
        };
        let cat = |f: &dyn Fn(&Answer) -> &[f64]| {
            let v: Vec<f64> = answers.iter().flat_map(|a| f(a).iter().copied()).collect();
            f64_bytes(py, &v).map(Bound::into_any)
        };
        let each =
            |f: &dyn Fn(&Answer) -> f64| ne_bytes(py, answers.iter().map(|a| f(a).to_ne_bytes())).map(Bound::into_any);
        let count = |f: &dyn Fn(&Answer) -> usize| {
            ne_bytes(py, answers.iter().map(|a| (f(a) as u64).to_ne_bytes())).map(Bound::into_any)
        };
        let codes: Vec<u8> = answers.iter().map(|a| outcome_code(a.sol.outcome)).collect();
        let extrapolated: Vec<u8> = flags.iter().map(|&f| u8::from(f)).collect();
        PyTuple::new(
            py,
            [
                cat(&|a| &a.pressure)?,
                cat(&|a| &a.sol.u_hat)?,
                {
                    // a registered basis may use fewer than its m generators at a point: zeros
                    let rl = self.loaded.model.stored_ranks().1;
                    let v: Vec<f64> = answers
                        .iter()
                        .flat_map(|a| a.sol.lambda_hat.iter().copied().chain(std::iter::repeat(0.0)).take(rl))
                        .collect();
                    f64_bytes(py, &v)?.into_any()
                },
                PyBytes::new(py, &codes).into_any(),
                count(&|a| a.sol.iterations)?,
                count(&|a| a.sol.linearizations)?,
                count(&|a| a.sol.nonzero_dual)?,
                each(&|a| a.indicator.residual)?,
                each(&|a| a.indicator.penetration)?,
                each(&|a| a.indicator.complementarity)?,
                each(&|a| a.indicator.unpaired_force)?,
                PyBytes::new(py, &extrapolated).into_any(),
                each(&|a| a.seconds)?,
                each(&|a| a.indicator_seconds)?,
            ],
        )
    }

    /// The displacement on every dof at `point` for the coefficients `u_hat` (bytes of f64),
    /// reconstructed from `reconstruction.h5` (read on first use): bytes of n_dof f64.
    fn displacement<'py>(&self, py: Python<'py>, point: Vec<f64>, u_hat: &[u8]) -> PyResult<Bound<'py, PyBytes>> {
        let coefficients: Vec<f64> = u_hat
            .chunks_exact(8)
            .map(|b| f64::from_ne_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
            .collect();
        if point.len() != self.bounds.names.len() || coefficients.len() != self.loaded.model.ranks().0 {
            return Err(error(
                py,
                "InvalidPoint",
                format!(
                    "a displacement needs {} components and {} coefficients, got {} and {}",
                    self.bounds.names.len(),
                    self.loaded.model.ranks().0,
                    point.len(),
                    coefficients.len()
                ),
            ));
        }
        let u =
            py.detach(|| self.reconstruction().map(|rec| fields::displacement(rec, &point, &coefficients))).map_err(
                |m| error(py, "CorruptArtifact", format!("{m}; run `crom verify`, then `crom run SCENE` again")),
            )?;
        f64_bytes(py, &u)
    }
}

/// The module.
#[pymodule]
fn crom_native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Model>()?;
    m.add("OUTCOMES", OUTCOMES.iter().map(|o| o.name()).collect::<Vec<_>>())?;
    m.add("VERSION", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
