//! The cone greedy's pick rule, shared by the lazy selection ([`super::lazy`]), the CPG path
//! ([`super::cpg`]) and the direct method kept for tests ([`super::cpg_reference`]): which
//! candidate wins a step ([`scan`]: the largest error, ties within a relative 1e-12 to the larger
//! norm, then to the lower index), when a snapshot counts as represented by the cone
//! ([`CPG_FLOOR`]), and how far below the best fresh error a stale bound must lie to be skipped
//! ([`BAND_REL`], [`BAND_ABS`]).

use crate::float_cmp::{close, Tol};

/// A snapshot whose relative cone-projection error is at most this is represented by the cone
/// and never selected: the relative accuracy of crom's pressure snapshots. Their equilibrium
/// backward error is verified to 1e-8 (the stress matrix and the solver tests), and the
/// pressure follows from the equilibrium; a generator that lowers some snapshot's error below
/// that only fits solver noise. Measured on 1 025 near-duplicate ironing-coarse snapshots (d_x
/// in [1.5, 1.5001], dual POD rank 3 at 1e-10): with the floor at round-off (1e-12) or at the
/// solver's rel_tol (1e-10) the greedy selected 1 025 and 924 of them, each a snapshot sticking
/// out of the others' cone by noise, at C(m) < 1e-10 for the last 349 and 248; at 1e-8 it
/// selects 21. In every shipped scene each selection happens at an error above 1e-3, so the
/// floor changes none of their numbers (docs/design-notes.md#a-floor-under-the-cone-greedy).
pub const CPG_FLOOR: f64 = 1e-8;

/// Relative tie tolerance between two candidates' errors (and norms).
const TIE_REL_TOL: f64 = 1e-12;

/// Relative width of the refresh band below the best fresh error. A tie chain (each link
/// within `TIE_REL_TOL`) through N candidates spans at most `N * 1e-12`, inside `1e-8` for any
/// N up to 10^4.
pub(super) const BAND_REL: f64 = 1e-8;

/// Absolute width added to the band: the round-off of a recomputed relative error (the
/// [`IN_CONE_REL_TOL`](crate::cone::IN_CONE_REL_TOL) level), by which a fresh error can exceed an older bound.
pub(super) const BAND_ABS: f64 = 1e-12;

/// The scan of the direct method over `(index, error)` candidates in ascending index order,
/// without `skip`: the largest error, ties within a relative 1e-12 to the larger norm, then to
/// the lower index (the first seen).
pub(crate) fn scan(
    candidates: impl IntoIterator<Item = (usize, f64)>,
    norms: &[f64],
    skip: Option<usize>,
) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (j, err) in candidates {
        if Some(j) == skip {
            continue;
        }
        let better = match best {
            None => true,
            Some((b, berr)) if close(err, berr, Tol::rel(TIE_REL_TOL)) => {
                !close(norms[j], norms[b], Tol::rel(TIE_REL_TOL)) && norms[j] > norms[b]
            }
            Some((_, berr)) => err > berr,
        };
        if better {
            best = Some((j, err));
        }
    }
    best.map(|(j, _)| j)
}

/// Every index that is the running best at some point of [`scan`] (the winner last).
pub(super) fn scan_trajectory(candidates: &[(usize, f64)], norms: &[f64]) -> Vec<usize> {
    let mut out = Vec::new();
    for q in 0..candidates.len() {
        if let Some(b) = scan(candidates[..=q].iter().copied(), norms, None) {
            if out.last() != Some(&b) {
                out.push(b);
            }
        }
    }
    out
}
