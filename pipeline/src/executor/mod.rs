//! Where a study's work runs (`crom run --executor`).
//!
//! - `local` (the default): this process walks the plan's nodes (`crate::dag::run::execute`); the
//!   snapshot sweeps and the metrics spread over the cores with rayon.
//! - `slurm`: the snapshot sweeps as a job array of `crom work --shard K/N` workers writing
//!   into one shared store, then the remaining stages locally ([`slurm`]).
//!
//! `crom work` is the worker entry point and works under any scheduler (or by hand): it takes
//! the store's shared lock, solves the missing points of its shard's chunks, appends their
//! blocks, and leaves a record of what it did ([`tasks`]).

pub mod slurm;
pub mod tasks;

use clap::ValueEnum;

/// `crom run --executor`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum Executor {
    /// This process, all cores.
    #[default]
    Local,
    /// A Slurm job array for the snapshot sweeps (`sbatch`), the rest locally.
    Slurm,
}
