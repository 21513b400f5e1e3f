//! The numerics of crom: meshes, finite elements, contact solvers, cone projection, reduced
//! bases, metrics and the online reduced solve. Nothing here opens a file or hashes anything:
//! every function is a pure function of its inputs (the pipeline does the I/O and the caching).
//!
//! The two bases of the study on three non-negative "pressure" snapshots, one per column, the
//! third the mean of the first two: the POD (an orthonormal basis of their span) and the
//! Cone-Projected Greedy basis (a few of the snapshots themselves, whose non-negative
//! combinations reproduce the rest), each with its compactness `C(m)` (the paper's eq. 16):
//!
//! ```
//! use crom_stages::basis::{cpg, pod, CpgParams, PodParams};
//! use crom_stages::metrics::compactness_orth;
//! use faer::Mat;
//!
//! let columns = [[2.0, 1.0, 0.0], [0.0, 1.0, 2.0], [1.0, 1.0, 1.0]];
//! let s = Mat::from_fn(3, 3, |i, j| columns[j][i]);
//!
//! // POD: the snapshots span a plane, so two modes reproduce them.
//! let p = pod(s.as_ref(), PodParams::default())?;
//! assert_eq!(p.rank, 2);
//! let c = compactness_orth(s.as_ref(), p.modes.as_ref());
//! assert_eq!(c[0], 1.0);
//! assert!(c[1] > 0.1 && c[2] < 1e-12);
//!
//! // CPG: the greedy picks the first snapshot (a tie broken by norm, then index), then the one
//! // farthest from its cone; the third is inside the cone of those two and is never picked.
//! let cone = cpg(s.as_ref(), CpgParams::default())?;
//! assert_eq!(cone.selected, [0, 1]);
//! assert_eq!(cone.compactness.len(), 3);
//! assert!(cone.compactness[2] < 1e-12);
//! // Its generators are unit-norm snapshots, so they stay non-negative.
//! assert!((0..2).all(|j| (0..3).all(|i| cone.basis[(i, j)] >= 0.0)));
//! assert!((cone.basis.col(0).norm_l2() - 1.0).abs() < 1e-15);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod basis;
pub mod blocks;
pub mod condition;
pub mod cone;
pub mod contact;
pub mod contact3d;
pub mod dual;
pub mod fem;
pub mod float_cmp;
pub mod full_order;
pub mod kernels;
pub mod mesh;
pub mod metrics;
pub mod mu;
pub mod q1;
pub mod rng;
pub mod rom;
pub mod rope;
pub mod running_stats;
pub mod shipped;
pub mod snapshot;
pub mod solid;
#[cfg(test)]
mod testing;
