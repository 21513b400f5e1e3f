//! Dual approximations: every way crom approximates the contact pressure, behind one interface
//! ("beyond the paper"). POD and the Cone-Projected Greedy basis of the paper are two
//! values of [`Approach`]; the others are the ones the paper names in its *Perspectives* or
//! cites without measuring.
//!
//! An approximation is built from the training pressure snapshots `S = [s_1 .. s_N]` (n x N, the
//! dual field at the n slave nodes) and their parameters `mu_j`; for a pressure `s` at a
//! parameter `mu` and a size `m` it returns the best approximation it can make with m modes (or
//! m active atoms) and the residual `||s - Pi_m(s; mu)||_2`. The size `m` and the parameter
//! enter every approach the same way, so the compactness, the leave-one-out generalization and
//! the test-set error ([`study`]) are computed by the same code for all of them:
//!
//! * **POD** (eq. 9): the leading left singular vectors; `Pi_m` is the orthogonal projection.
//! * **CPG** (Sec. 2.3.1, eq. 12): the tolerance-0 greedy cone basis; `Pi_m` is the projection
//!   onto the cone of the first m generators (non-negative coefficients, NNLS).
//! * **Angle-Greedy** (Burkovska, Haasdonk, Salomon and Wohlmuth 2015, the paper's ref. \[10\]):
//!   the greedy selection by the *angle* to the linear span of the snapshots already chosen,
//!   `j_m = argmax_j ||s_j - P_{V_{m-1}} s_j|| / ||s_j||` ([`angle_greedy`]). Its basis is
//!   the chosen snapshots themselves (non-negative), and the online solve keeps the dual
//!   coefficients non-negative, so `Pi_m` is the cone projection on them, as for CPG: the
//!   two differ only in which snapshots they pick.
//! * **NNMF** of rank m (Lee and Seung 1999; Balajewicz, Amsallem and Farhat 2016, refs. \[25\],
//!   \[11\]): `S ~ W H`, `W >= 0` (n x m), `H >= 0`, by hierarchical alternating least squares
//!   from the NNDSVD start ([`nnmf`]); `Pi_m` is the cone projection on the columns of the
//!   rank-m `W`. Not nested: one factorisation per m.
//! * **Local bases** ([`local`]): the parameter range cut into K cells (with an overlap), one
//!   CPG per cell; `Pi_m(s; mu)` projects on the cone of the cell of `mu`.
//! * **Dictionary** ([`dictionary`]): every training snapshot is an atom; `Pi_m(s)` is the
//!   non-negative combination of at most m atoms chosen by the greedy active-set rule of
//!   Lawson and Hanson (enter the atom most correlated with the residual, re-solve the NNLS on
//!   the chosen atoms). With m unbounded it is the NNLS over all atoms.
//! * **Registration** ([`registration`]): a change of variables `xi = (x - c(mu)) / a(mu)` of the
//!   contact surface pulls every snapshot back to a reference frame, where POD or CPG is built;
//!   `Pi_m(s; mu)` projects `s` on the reference modes pushed forward to `mu`'s frame, so every
//!   error is measured in the physical frame against the original snapshot.

pub mod angle_greedy;
pub mod dictionary;
pub mod local;
pub mod nnmf;
mod prefix;
pub mod registration;
pub mod study;

use faer::{Mat, MatRef};
use thiserror::Error;

use crate::basis::{cpg_prefix, pod_full, CpgPathParams, PodError};
use crate::cone::ConeError;

pub use prefix::{ConePrefix, SpanPrefix};
pub use registration::{Interpolation, MapKind};

/// Which basis a registered approximation builds in its reference frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inner {
    /// Orthogonal modes (POD of the registered snapshots).
    Pod,
    /// Cone generators (CPG of the registered snapshots).
    Cpg,
    /// Per query, the training snapshots nearest in the registered frame
    /// ([`registration::Neighbours`]).
    Neighbours,
    /// Over two parameter components: one POD per interval between consecutive levels of the
    /// second component, of the registered snapshots on its two levels; a point takes the POD of
    /// the interval that holds its second component ([`registration::Levels`]).
    LevelPod,
}

/// One way of approximating the contact pressure, with its settings.
#[derive(Debug, Clone, PartialEq)]
pub enum Approach {
    /// Proper orthogonal decomposition (eq. 9).
    Pod,
    /// Cone-Projected Greedy basis at tolerance 0 (Sec. 2.3.1).
    Cpg,
    /// Angle-Greedy snapshot selection (ref. \[10\]), cone projection on the chosen snapshots.
    AngleGreedy,
    /// Non-negative matrix factorisation of rank m, `iterations` HALS sweeps at most.
    Nnmf {
        /// Largest number of HALS sweeps per rank.
        iterations: usize,
    },
    /// One CPG per cell of the first parameter's range.
    Local {
        /// Number of cells K.
        cells: usize,
        /// Overlap: a cell also trains on the points within `overlap` cell widths of its edges.
        overlap: f64,
    },
    /// Every training snapshot an atom; at most m atoms per approximation.
    Dictionary,
    /// A change of variables of the contact surface, then POD, CPG or neighbours in the
    /// reference frame.
    Registered {
        /// The map and how it is evaluated.
        map: MapKind,
        /// The basis built in the reference frame.
        inner: Inner,
    },
}

impl Approach {
    /// Whether it has a non-negative dual basis for the online solve
    /// ([`DualApprox::cone_basis`] is `Some`): all but POD and registered POD.
    pub fn has_cone_basis(&self) -> bool {
        !matches!(self, Approach::Pod | Approach::Registered { inner: Inner::Pod | Inner::LevelPod, .. })
    }

    /// The approximation's name in tables and figures (`pod`, `cpg`, `angle-greedy`, `nnmf`,
    /// `local-K`, `dictionary`, `registered-<map>-<basis>`).
    pub fn name(&self) -> String {
        match self {
            Approach::Pod => "pod".into(),
            Approach::Cpg => "cpg".into(),
            Approach::AngleGreedy => "angle-greedy".into(),
            Approach::Nnmf { .. } => "nnmf".into(),
            Approach::Local { cells, .. } => format!("local-{cells}"),
            Approach::Dictionary => "dictionary".into(),
            Approach::Registered { map, inner } => format!(
                "registered-{}-{}",
                map.name(),
                match inner {
                    Inner::Pod => "pod",
                    Inner::Cpg => "cpg",
                    Inner::Neighbours => "neighbours",
                    Inner::LevelPod => "level-pod",
                }
            ),
        }
    }
}

/// Why an approximation could not be built or evaluated.
#[derive(Debug, Clone, Error)]
pub enum DualError {
    /// A cone projection (NNLS) failed.
    #[error(transparent)]
    Cone(#[from] ConeError),
    /// An SVD failed.
    #[error(transparent)]
    Pod(#[from] PodError),
    /// The approach does not apply to these snapshots (the message says why and what to do).
    #[error("{0}")]
    NotApplicable(String),
}

/// What an approximation is built from.
#[derive(Debug, Clone, Copy)]
pub struct Training<'a> {
    /// Pressure snapshots, n x N (one per column).
    pub snapshots: MatRef<'a, f64>,
    /// Parameter point of each snapshot (N entries).
    pub params: &'a [Vec<f64>],
    /// Abscissa `x` of each slave node in the reference configuration, in dual-field order
    /// (used by the registration maps).
    pub surface: &'a [f64],
    /// Coordinate across the travel of each slave node (a 3-D contact area: y), in dual-field
    /// order; empty for a contact curve. The registration maps act along x on each line of
    /// equal coordinate.
    pub across: &'a [f64],
    /// Basis sizes the approximation is asked for, ascending (the curves' m grid).
    pub ms: &'a [usize],
}

impl Training<'_> {
    /// The largest m asked for.
    pub fn max_m(&self) -> usize {
        self.ms.last().copied().unwrap_or(0)
    }

    /// The number of parameter components every training point has (1 without points); `None`
    /// where the points differ.
    pub fn dims(&self) -> Option<usize> {
        let d = self.params.first().map_or(1, Vec::len);
        self.params.iter().all(|p| p.len() == d).then_some(d)
    }

    /// The same training data without snapshot `i` (a leave-one-out fold).
    pub fn without(&self, i: usize) -> (Mat<f64>, Vec<Vec<f64>>) {
        let (n, count) = (self.snapshots.nrows(), self.snapshots.ncols());
        let keep: Vec<usize> = (0..count).filter(|&j| j != i).collect();
        let s = Mat::from_fn(n, keep.len(), |r, c| self.snapshots[(r, keep[c])]);
        (s, keep.iter().map(|&j| self.params[j].clone()).collect())
    }
}

/// A number describing a built approximation (e.g. NNMF's iterations at rank m).
#[derive(Debug, Clone, PartialEq)]
pub struct Fact {
    /// What it is, e.g. `iterations`, `relative_residual`, `round_trip_error_max`.
    pub name: String,
    /// The basis size it belongs to, if any.
    pub m: Option<usize>,
    /// Its value.
    pub value: f64,
}

impl Fact {
    pub(crate) fn new(name: &str, m: Option<usize>, value: f64) -> Self {
        Self { name: name.to_string(), m, value }
    }
}

/// A built dual approximation: residuals of its best approximation for each asked m.
pub trait DualApprox: Send + Sync {
    /// `out[k] = ||s - Pi_{ms[k]}(s; mu)||_2` for each `ms[k]` of the training's m grid (or a
    /// prefix of it). A size beyond what the approximation holds uses all of it (the `Psi[:m]`
    /// slicing of the paper's notation).
    fn residuals(&self, s: &[f64], mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError>;

    /// Number of modes, generators or atoms it holds (the most any m can use).
    fn size(&self) -> usize;

    /// Numbers describing the build (stored in the artifact).
    fn facts(&self) -> Vec<Fact> {
        Vec::new()
    }

    /// The non-negative dual basis of at most `m` columns the online solve uses at `mu`
    /// (`n x k`, no zero column), or `None` where the approximation's modes are signed (POD, a
    /// registered POD): the online solve keeps the dual coefficients non-negative, which keeps
    /// the pressure non-negative only on a non-negative basis. The dictionary gives all its
    /// atoms whatever `m` (the online active-set method chooses among them).
    fn cone_basis(&self, _mu: &[f64], _m: usize) -> Option<Mat<f64>> {
        None
    }

    /// [`cone_basis`](Self::cone_basis) as its columns, concatenated (column-major), with
    /// their count: what the online solve sets per query. The default copies the matrix.
    fn cone_columns(&self, mu: &[f64], m: usize) -> Option<(Vec<f64>, usize)> {
        let b = self.cone_basis(mu, m)?;
        let k = b.ncols();
        let b = b.as_ref();
        Some(((0..k).flat_map(|j| b.col(j).iter().copied()).collect(), k))
    }

    /// Whether [`cone_basis`](Self::cone_basis) depends on the parameter (then the online
    /// solve sets it per query, inside the timed region).
    fn depends_on_mu(&self) -> bool {
        false
    }

    /// Specificity's coordinates (eq. 18) of `s` at `mu` on the first `m` modes: the group
    /// whose modes they refer to (a local basis' cell; 0 elsewhere) and the coefficients in the
    /// approximation's own coordinates (POD: orthogonal; cone bases: the NNLS coefficients; a
    /// registered basis: those of the pulled-back snapshot on the reference modes). `None`
    /// where there are no modes (the dictionary).
    fn coefficients(&self, _s: &[f64], _mu: &[f64], _m: usize) -> Result<Option<(usize, Vec<f64>)>, DualError> {
        Ok(None)
    }

    /// The member with coefficients `alpha` (of group `group`'s first `m` modes) at `mu`, in
    /// the physical frame, into `out`.
    fn member(&self, _group: usize, _alpha: &[f64], _mu: &[f64], _m: usize, out: &mut [f64]) {
        out.fill(0.0);
    }

    /// Whether the coefficients are non-negative (their sampling interval is clipped at 0).
    fn nonnegative(&self) -> bool {
        true
    }

    /// The cell of `mu` for an approximation made of local parts (local bases), `None`
    /// otherwise: the metrics are then also reported per cell.
    fn cell_of(&self, _mu: &[f64]) -> Option<usize> {
        None
    }
}

/// The first `m` columns of `b` that are not zero.
pub(crate) fn nonzero_prefix(b: MatRef<'_, f64>, m: usize) -> Mat<f64> {
    let keep: Vec<usize> = (0..b.ncols()).filter(|&j| b.col(j).iter().any(|&v| v != 0.0)).take(m).collect();
    Mat::from_fn(b.nrows(), keep.len(), |i, c| b[(i, keep[c])])
}

/// Build `approach` from `training`.
pub fn build(approach: &Approach, training: &Training<'_>) -> Result<Box<dyn DualApprox>, DualError> {
    let s = training.snapshots;
    check_finite(s)?;
    Ok(match approach {
        Approach::Pod => Box::new(SpanPrefix::new(pod_modes(s, training.max_m())?.as_ref())),
        Approach::Cpg => Box::new(ConePrefix::new(cpg_generators(s, training.max_m())?.as_ref())),
        Approach::AngleGreedy => {
            let chosen = angle_greedy::select(s, training.max_m());
            Box::new(ConePrefix::new(angle_greedy::unit_columns(s, &chosen.selected).as_ref()))
        }
        Approach::Nnmf { iterations } => Box::new(nnmf::NnmfFamily::build(s, training.ms, *iterations)?),
        Approach::Local { cells, overlap } => Box::new(local::LocalBases::build(training, *cells, *overlap)?),
        Approach::Dictionary => Box::new(dictionary::Dictionary::new(s)),
        Approach::Registered { map, inner } => Box::new(registration::Registered::build(training, *map, *inner)?),
    })
}

/// The first `max_m` POD modes of `s` (at most its numerical rank).
pub(crate) fn pod_modes(s: MatRef<'_, f64>, max_m: usize) -> Result<Mat<f64>, DualError> {
    let pod = pod_full(s)?;
    let k = pod.modes.ncols().min(max_m);
    Ok(pod.modes.subcols(0, k).to_owned())
}

/// The first `max_m` generators of the tolerance-0 CPG path of `s`.
pub(crate) fn cpg_generators(s: MatRef<'_, f64>, max_m: usize) -> Result<Mat<f64>, DualError> {
    Ok(cpg_prefix(s, max_m, CpgPathParams::default().nnls)?)
}

fn check_finite(s: MatRef<'_, f64>) -> Result<(), DualError> {
    if (0..s.ncols()).any(|j| s.col(j).iter().any(|v| !v.is_finite())) {
        return Err(DualError::Pod(PodError::NonFinite));
    }
    Ok(())
}

/// The m grid of the comparison curves: every m up to 16, every 4th up to 32, every 16th
/// beyond, capped at `max_m` (always included).
pub fn m_grid(max_m: usize) -> Vec<usize> {
    let mut ms: Vec<usize> = (1..=max_m).filter(|&m| m <= 16 || (m <= 32 && m % 4 == 0) || m % 16 == 0).collect();
    if ms.last() != Some(&max_m) && max_m > 0 {
        ms.push(max_m);
    }
    ms
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_m_grid_is_dense_where_the_targets_are() {
        assert_eq!(m_grid(5), vec![1, 2, 3, 4, 5]);
        let g = m_grid(70);
        assert_eq!(&g[..16], &(1..=16).collect::<Vec<_>>()[..]);
        assert_eq!(&g[16..], &[20, 24, 28, 32, 48, 64, 70]);
        assert!(m_grid(0).is_empty());
    }

    /// The plan's `has_cone_basis` agrees with what the built approximation answers, on a
    /// small translated-bump training set every approach can be built from.
    #[test]
    fn has_cone_basis_matches_the_built_approximation() {
        let (n, count) = (40, 12);
        let surface: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let params: Vec<Vec<f64>> = (0..count).map(|j| vec![j as f64]).collect();
        let s = Mat::from_fn(n, count, |i, j| (4.0 - (i as f64 - 10.0 - j as f64).powi(2)).max(0.0));
        let ms = [1, 2, 3];
        let training = Training { snapshots: s.as_ref(), params: &params, surface: &surface, across: &[], ms: &ms };
        for a in all_approaches() {
            let built = build(&a, &training).expect("build");
            assert_eq!(a.has_cone_basis(), built.cone_basis(&params[3], 2).is_some(), "{}", a.name());
        }
    }

    fn all_approaches() -> Vec<Approach> {
        let nodes = MapKind::Translate { interpolation: Interpolation::Nodes };
        vec![
            Approach::Pod,
            Approach::Cpg,
            Approach::AngleGreedy,
            Approach::Nnmf { iterations: 10 },
            Approach::Local { cells: 2, overlap: 0.0 },
            Approach::Dictionary,
            Approach::Registered { map: nodes, inner: Inner::Pod },
            Approach::Registered { map: nodes, inner: Inner::Cpg },
            Approach::Registered { map: nodes, inner: Inner::Neighbours },
        ]
    }

    #[test]
    fn names_are_distinct() {
        let mut all = all_approaches();
        all.push(Approach::Registered {
            map: MapKind::Translate { interpolation: Interpolation::Linear { refine: 2 } },
            inner: Inner::Cpg,
        });
        let names: std::collections::BTreeSet<String> = all.iter().map(Approach::name).collect();
        assert_eq!(names.len(), all.len());
    }
}
