//! Reduced bases built from snapshot matrices (n x N, one snapshot per column).
//!
//! * Primal and "dual orth" bases: POD, the left singular vectors of the snapshot matrix
//!   truncated by a relative Frobenius tolerance `delta` (paper eq. 9): keep the smallest m with
//!   `sqrt(sum_{i>m} s_i^2) / sqrt(sum_i s_i^2) <= delta` (never more than the numerical rank).
//! * "Dual cone" basis: the Cone-Projected Greedy (CPG) selection of snapshots (paper
//!   Sec. 2.3.1, eq. 12), stopped when the compactness `C(m)` of eq. 16 is at most the
//!   tolerance; generators are the selected snapshots scaled to unit norm, so every
//!   non-negative combination is a non-negative pressure field (eq. 10).

mod cpg;
mod cpg_reference;
mod frame;
mod gram_condition;
mod gram_pod;
mod lazy;
mod pick;
mod pod;

pub use cpg::{
    cpg, cpg_path, cpg_path_refined, cpg_prefix, Cpg, CpgParams, CpgPath, CpgPathParams, DENSE_CURVE_MAX, GRID_START,
};
pub use cpg_reference::cpg_reference;
pub use frame::{frame, frame_pays_up_to, frame_within, frame_within_blocks, large_frame, Frame, FRAME_BLOCK};
pub use gram_condition::gram_condition_path;
pub use gram_pod::{pod_by_gram, GRAM_CUT};
pub use pick::CPG_FLOOR;

pub(crate) use lazy::LazyGreedy;
pub use pod::{
    numerical_rank, pod, pod_blocks, pod_blocks_framed, pod_direct, pod_frame, pod_full, pod_of_frame, tail_energies,
    truncation_rank, Pod, PodError, PodParams, POD_FRAME_ABOVE,
};
