//! Command-line interface of `crom`.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

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
    },
    /// Solve every snapshot of a scene's study (training, test and nested points) into the
    /// store and stop; `crom run` then finds them there.
    Solve {
        /// Scene name or path to a scene TOML file.
        scene: String,
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
