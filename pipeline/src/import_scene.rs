//! `crom import`: write an external scene file ([`crom_schemas::external`]) from the arrays a
//! user points to, after checking them as `crom run` would — the files, datasets, shapes,
//! column counts, parameter values (distinct, finite) and every snapshot value (finite,
//! pressures not below the tolerance) — so that the scene it writes runs. Nothing goes into a
//! store; the scene file is written only when every check passes (atomically).
//!
//! The test points are every `K`-th column (`--test-every K`, default 2: alternate columns, so
//! with snapshots in parameter order each test point lies between two training points), the
//! training points the others; `--test-every 0` trains on every column (`test = []`: the
//! metrics on all of them, and nothing that needs test points). Paths in the scene are absolute. The `[study]` table takes the
//! defaults below; edit the file to change them.

use std::path::{Path, PathBuf};

use clap::Args;
use crom_schemas::external::{ArraySource, ExternalSpec, Layout, ParameterSource};
use crom_schemas::SceneConfig;

use crate::error::CromError;

/// `crom import` arguments.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// Scene name (also the default file name, NAME.toml).
    #[arg(long)]
    pub name: String,
    /// Contact pressures: FILE.npy, or FILE.h5:DATASET.
    #[arg(long)]
    pub dual: String,
    /// Displacements (optional): FILE.npy, or FILE.h5:DATASET.
    #[arg(long)]
    pub primal: Option<String>,
    /// One snapshot per row (shape (N, rows)) instead of per column, for both arrays.
    #[arg(long)]
    pub rows: bool,
    /// Parameter values: FILE.csv, FILE.parquet, FILE.npy, or FILE.h5:DATASET.
    #[arg(long)]
    pub parameters: String,
    /// Names of the parameter's components, comma-separated (CSV / Parquet: the columns).
    #[arg(long, value_delimiter = ',')]
    pub names: Vec<String>,
    /// Every K-th column is a test point (K >= 2), the others training points; 0: every column
    /// trains (no test points: the comparison's test error T(m) and the test views are then
    /// skipped, and the metrics on all N columns are the paper's C, G, S and H).
    #[arg(long, default_value_t = 2, value_parser = test_every)]
    pub test_every: u64,
    /// Set negative pressures to zero on import (else they are refused).
    #[arg(long)]
    pub clip_negative: bool,
    /// Where to write the scene file (default NAME.toml in the current directory).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
}

/// `--test-every`: 0, or at least 2 (1 would leave no training column).
fn test_every(s: &str) -> Result<u64, String> {
    match s.parse::<u64>() {
        Ok(1) => Err("1 would make every column a test point; give 0 (every column trains) or K >= 2".into()),
        Ok(k) => Ok(k),
        Err(_) => Err(format!("'{s}' is not a number; give 0 or K >= 2")),
    }
}

/// `FILE` or `FILE:DATASET` (split at the last `:` whose left part is an existing file).
fn source(arg: &str, layout: Layout) -> ArraySource {
    if let Some((file, dataset)) = arg.rsplit_once(':') {
        if Path::new(file).is_file() && !Path::new(arg).exists() {
            return ArraySource { file: absolute(file), dataset: Some(dataset.to_string()), layout };
        }
    }
    ArraySource { file: absolute(arg), dataset: None, layout }
}

fn absolute(p: &str) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| PathBuf::from(p))
}

/// Check the arrays and write the scene file; returns its path.
pub fn run(args: &ImportArgs, progress: &crate::progress::Progress) -> Result<PathBuf, CromError> {
    let layout = if args.rows { Layout::Rows } else { Layout::Columns };
    let dual = source(&args.dual, layout);
    let primal = args.primal.as_deref().map(|p| source(p, layout));
    let p = source(&args.parameters, Layout::Columns);
    let parameters =
        ParameterSource { file: p.file, dataset: p.dataset, names: args.names.clone(), description: String::new() };
    // The column count, to list the sets (the scene is checked as a whole below).
    let n = crate::io::source::SnapshotArray::open(Path::new(""), &dual, "model.external.dual")?.cols;
    let k = args.test_every as usize;
    let (test, train): (Vec<usize>, Vec<usize>) = (0..n).partition(|j| k > 0 && j % k == k - 1);
    let ext = ExternalSpec {
        dual,
        primal,
        parameters,
        train: Some(train),
        test: Some(test),
        test_files: None,
        coordinates: None,
        mesh: None,
        negative_tolerance: None,
        clip_negative: args.clip_negative,
        units: None,
        resolved: None,
    };
    let out = args.output.clone().unwrap_or_else(|| PathBuf::from(format!("{}.toml", args.name)));
    let text = scene_text(&args.name, &ext);
    // Check as `crom run` would: parse and validate, resolve the files, read every value.
    let mut scene = SceneConfig::from_toml_str(&text, &out)?;
    crate::external::resolve(&mut scene, &out)?;
    crate::dag::check_external_values(&scene, progress)?;
    crate::store::fs::write_atomic(&out, text.as_bytes())?;
    Ok(out)
}

/// A TOML basic string (paths and names: quotes and backslashes escaped, as JSON does).
fn quoted(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_default()
}

/// An array source as an inline table.
fn inline(a: &ArraySource) -> String {
    let mut t = format!("{{ file = {}", quoted(&a.file.to_string_lossy()));
    if let Some(d) = &a.dataset {
        t.push_str(&format!(", dataset = {}", quoted(d)));
    }
    if a.layout == Layout::Rows {
        t.push_str(", layout = \"rows\"");
    }
    t + " }"
}

/// The scene file's text.
fn scene_text(name: &str, ext: &ExternalSpec) -> String {
    let list = |v: &Option<Vec<usize>>| {
        format!("[{}]", v.as_deref().unwrap_or_default().iter().map(|j| j.to_string()).collect::<Vec<_>>().join(", "))
    };
    let p = &ext.parameters;
    let mut params = format!("{{ file = {}", quoted(&p.file.to_string_lossy()));
    if let Some(d) = &p.dataset {
        params.push_str(&format!(", dataset = {}", quoted(d)));
    }
    let names: Vec<String> = p.names.iter().map(|n| quoted(n)).collect();
    params.push_str(&format!(", names = [{}] }}", names.join(", ")));
    let mut model = format!("dual = {}\n", inline(&ext.dual));
    if let Some(pr) = &ext.primal {
        model.push_str(&format!("primal = {}\n", inline(pr)));
    }
    model.push_str(&format!("parameters = {params}\ntrain = {}\ntest = {}\n", list(&ext.train), list(&ext.test)));
    if ext.clip_negative {
        model.push_str("clip_negative = true\n");
    }
    let name = quoted(name);
    format!(
        "# Written by `crom import`: snapshots computed elsewhere (docs/user-guide.md, \"Bring your own snapshots\").\n\
         [scene]\nname = {name}\ndescription = \"snapshots imported by crom import\"\n\n[model.external]\n{model}\n\
         [study]\nprimal_tol = 0.0\ndual_orth_tol = 0.0\ndual_cone_tol = 0.0\ndual_cone_tol_truncated = 0.05\n\
         specificity_samples = 1000\nseed = 1\n"
    )
}
