//! The numerics of crom: meshes, finite elements, contact solvers, cone projection, reduced
//! bases, metrics and the online reduced solve. Nothing here opens a file or hashes anything:
//! every function is a pure function of its inputs (the pipeline does the I/O and the caching).

pub mod basis;
pub mod condition;
pub mod cone;
pub mod contact;
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
#[cfg(test)]
mod testing;
