//! Command-line interface of `crom`.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

use crate::executor::Executor;

/// crom: can contact-mechanics solutions be compressed into a low-rank model, and at what cost?
#[derive(Debug, Parser)]
#[command(name = "crom", version, about, long_about = None)]
pub struct Cli {
    /// Artifact store directory.
    #[arg(long, global = true, env = "CROM_STORE", default_value = "data/store")]
    pub store: PathBuf,
    /// Directory of scene files (`NAME.toml`).
    #[arg(long, global = true, env = "CROM_SCENES", default_value = "data/scenes")]
    pub scenes: PathBuf,
    /// Only errors and the final summary.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// Memory a run may use (e.g. `8G`, `512M`); a scene whose estimated need exceeds it is
    /// refused before anything is written. Default: the machine's available memory.
    #[arg(long, global = true, env = "CROM_MAX_MEMORY", value_parser = crate::resources::parse_size)]
    pub max_memory: Option<f64>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run (or resume) the whole study of a scene; cached stages are not recomputed.
    Run {
        /// Scene name (a file in the scenes directory) or path to a scene TOML file.
        scene: String,
        /// Stop before the online reduced solve and the report (the offline study only).
        #[arg(long)]
        offline: bool,
        /// Print what is stored and what would run; write nothing.
        #[arg(long)]
        dry_run: bool,
        /// Where the snapshot sweeps run: this process, or a Slurm job array of `crom work`
        /// workers on this store (which must be on a file system the compute nodes share).
        #[arg(long, value_enum, default_value_t = Executor::Local)]
        executor: Executor,
        /// Slurm settings (override the scene's `[executor.slurm]`).
        #[command(flatten)]
        slurm: SlurmFlags,
    },
    /// Solve the missing points of shard K of N of a scene's snapshot sweeps into the store,
    /// as one of many concurrent workers (the Slurm executor's array task; usable from any
    /// scheduler). Does not run the other stages: `crom run` does, once all shards are done.
    Work {
        /// Scene name or path to a scene TOML file.
        scene: String,
        /// Which shard: `K/N` with 0 <= K < N.
        #[arg(long, value_parser = parse_shard)]
        shard: (usize, usize),
    },
    /// Write an external scene file from snapshot arrays computed elsewhere, after checking
    /// them as `crom run` would (nothing is stored).
    Import(crate::import_scene::ImportArgs),
    /// Show where a scene's study stands: each stage stored or not, the snapshot points stored,
    /// the sharded workers (done, failed, killed) and the Slurm job's queue.
    Status {
        /// Scene name or path to a scene TOML file.
        scene: String,
    },
    /// Solve every snapshot of a scene's study (training, test and nested points) into the
    /// store and stop; `crom run` then finds them there. An external scene's snapshots are
    /// imported.
    Solve {
        /// Scene name or path to a scene TOML file.
        scene: String,
    },
    /// Solve the scene's stored reduced model at new parameter points (without running the
    /// pipeline; `crom run SCENE` stores the model): one row per point — coefficients'
    /// and pressure summaries, error indicator, outcome, iterations, time — as CSV on standard
    /// output, or into --out.
    Query {
        /// Scene name or path to a scene TOML file.
        scene: String,
        /// One point: `NAME=VALUE[,NAME=VALUE…]`, every parameter component once (e.g. `d_x=1.2345`).
        #[arg(long, conflicts_with = "points")]
        at: Option<String>,
        /// A file of points: CSV with a header line of parameter names, or Parquet.
        #[arg(long)]
        points: Option<PathBuf>,
        /// Write the rows to this `.csv` or `.parquet` file instead of standard output.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also run the full-order solve at each point and report the true errors.
        #[arg(long)]
        check: bool,
        /// Also write the reconstructed displacement and pressure fields of every point to this
        /// `.h5` file, with an XDMF file beside it for ParaView.
        #[arg(long)]
        fields: Option<PathBuf>,
        /// Solve points outside the training domain too (their rows say `extrapolated`);
        /// without it they are refused.
        #[arg(long)]
        allow_extrapolation: bool,
        /// The re-pairing's stopping distance to its fixed point, relative to the reduced
        /// coordinates (a number in (0, 1); default: the model's own, 1e-10). Larger answers
        /// sooner and moves each answer by about this much (docs/user-guide.md#querying-the-reduced-model).
        #[arg(long, value_name = "TOL")]
        u_tol: Option<f64>,
    },
    /// Bring a scene's study up to date (cached stages are not recomputed) and print where its
    /// report is.
    Report {
        /// Scene name or path to a scene TOML file.
        scene: String,
    },
    /// List the artifacts in the store: a table for people, or the catalog's rows as CSV, JSON
    /// or Parquet for programs.
    Ls {
        /// Only this stage (columns, mesh, trainset, basis, compactness, generalization,
        /// specificity, nested, rom, report).
        #[arg(long)]
        stage: Option<String>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = LsFormat::Text)]
        format: LsFormat,
        /// Write to this file instead of standard output (atomically).
        #[arg(long, short)]
        output: Option<PathBuf>,
    },
    /// Rebuild the store's `catalog.parquet` from the artifacts' manifests and print its path.
    Catalog,
    /// List the available scenes.
    Scenes,
    /// Re-hash every artifact and every snapshot block of the store; what fails is moved to the
    /// quarantine (and recomputed by the next run). Exit 1 if anything failed.
    Verify,
}

/// The `sbatch` settings of `crom run --executor slurm`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SlurmFlags {
    /// sbatch --partition.
    #[arg(long)]
    pub partition: Option<String>,
    /// sbatch --time of one array task (e.g. 01:00:00).
    #[arg(long)]
    pub time: Option<String>,
    /// sbatch --mem of one array task (e.g. 4G).
    #[arg(long)]
    pub mem: Option<String>,
    /// sbatch --account.
    #[arg(long)]
    pub account: Option<String>,
    /// Snapshot points per array task (rounded to whole blocks).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub shard_size: Option<u64>,
    /// At most this many array tasks at once.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub max_parallel: Option<u64>,
    /// CPUs (worker threads) per array task.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub cpus_per_task: Option<u64>,
}

impl SlurmFlags {
    /// As the scene file's table.
    pub fn spec(&self) -> crom_schemas::scene::SlurmSpec {
        let n = |v: Option<u64>| v.map(|v| v as usize);
        crom_schemas::scene::SlurmSpec {
            partition: self.partition.clone(),
            time: self.time.clone(),
            mem: self.mem.clone(),
            account: self.account.clone(),
            shard_size: n(self.shard_size),
            max_parallel: n(self.max_parallel),
            cpus_per_task: n(self.cpus_per_task),
        }
    }
}

/// `K/N` with `0 <= K < N`.
fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("'{s}' is not a shard; give K/N with 0 <= K < N, e.g. 0/4");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (k.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok((k, n))
}

/// Output formats of `crom ls`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LsFormat {
    /// Aligned columns for people.
    Text,
    /// The catalog's rows as CSV (header line first).
    Csv,
    /// The catalog's rows as a JSON array of objects.
    Json,
    /// The catalog's rows as Parquet (the layout of `catalog.parquet`).
    Parquet,
}
