//! The study as a graph of cached stages.
//!
//! ```text
//! scene ─► mesh ─► snapshots (one sweep per point set) ─► trainset train, test, nested-k
//!   trainset ─► views (beside the main loop)
//!   trainset train ─► basis ─► views basis
//!   trainset train + basis ─► compactness, specificity
//!   trainset train ─► generalization
//!   trainset nested-1..K ─► nested
//!   trainset train, test, mesh (+ nested) ─► approximation <name> … ─► comparison
//!   trainset train, test, basis ─► rom ─► views online                       (online)
//!   trainset train, basis, rom ─► model (the reduced model `crom query` runs)  (online)
//!   approximation <name> ─► online-approximation <name> … ─► online-comparison (online)
//!   mesh, train, basis, the metrics, rom, comparisons ─► report             (online)
//! ```
//!
//! [`plan::Plan::of`] builds the graph from the scene file alone: each node is a typed stage
//! (`graph::StageDef`) holding its key spec and its named inputs, so the key of every
//! artifact is known before anything runs. Each stage is named by the content hash of its
//! parameters and inputs ([`crate::cache`]); a stage whose artifact is in the store and
//! verifies is not run again. `run::execute` runs the nodes in order with no stage-specific code.
//!
//! **Floors.** The files import downward only: at the bottom what every stage uses (`ctx`, the
//! run's context; `inputs`, the stored artifacts other stages read and the run's cache of them;
//! `shared`, what stages hand each other in memory; `online`, the online stages' shared
//! helpers; `graph`, the stage trait; `labels`, `convert`, `timing`), above them the stage files
//! (one stage each), above those the plan (`plan`), and on top the executor and the entry
//! points (`run`, `beside`) and the published names (`publish`). This file only declares them
//! and names what the rest of the crate uses.

pub(crate) mod approximation;
pub(crate) mod approximation_online;
pub(crate) mod basis;
mod beside;
pub(crate) mod compactness;
pub(crate) mod comparison;
pub(crate) mod convert;
pub(crate) mod ctx;
pub(crate) mod external_mesh;
pub(crate) mod graph;
pub(crate) mod import;
pub(crate) mod inputs;
pub(crate) mod labels;
pub(crate) mod mesh;
pub(crate) mod metrics;
pub(crate) mod model;
pub(crate) mod online;
pub mod plan;
pub mod publish;
pub(crate) mod report;
pub(crate) mod rom;
mod run;
pub(crate) mod shared;
pub(crate) mod snapshots;
#[cfg(test)]
mod throwaway_stage;
pub(crate) mod timing;
pub(crate) mod trainset;
pub(crate) mod views;

pub use ctx::{Ctx, PointCounts, StageRecord};
pub(crate) use online::relative_dual_error;
pub use run::{check_external_values, prepare_sweeps, run_scene, solve_points, work_shard, RunOutput};
pub(crate) use snapshots::{chunk_columns, shard_range};
