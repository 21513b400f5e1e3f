//! crom: the contact low-rank study pipeline — store, cache, HDF5/Parquet I/O, the DAG of stages
//! and the CLI. The numerics live in `crom-stages`; this crate does all the I/O.
//!
//! Every artifact is named by a content key ([`cache`]): blake3 of the canonical JSON of what
//! determines it. A snapshot's key, for instance, is its parameter value and solver settings on
//! its mesh — the recipe a reader of the store can reproduce (`docs/store-format.md`):
//!
//! ```
//! use crom_pipeline::cache::{Key, KeySpec};
//! use crom_schemas::artifact::ArtifactKind;
//!
//! let mesh = Key("ab".repeat(32));
//! let params = serde_json::json!({ "parameter": 0.5, "solver": { "rel_tol": 1e-10, "max_iter": 100 } });
//! let spec = KeySpec::new(ArtifactKind::SNAPSHOT, 3, params).input("mesh", &mesh);
//! // blake3 of {"stage":"snapshot","algorithm_version":3,"schema_version":1,"params":{...},"inputs":{"mesh":"abab…"}}
//! assert_eq!(spec.key().0, "1a568b277142cd8d2282f6798fdf69e5eb18fe2e9865946860109ea8bd9bc6a5");
//! ```
//!
//! [`main_with_args`] is the whole command line. A small rope study, run into a fresh store:
//!
//! ```
//! let dir = crom_pipeline::scratch::tempdir()?;
//! let scene = dir.path().join("rope-small.toml");
//! std::fs::write(
//!     &scene,
//!     r#"
//! [scene]
//! name = "rope-small"
//! description = "a rope on a sloped obstacle"
//! [model.rope]
//! length = 1.0
//! n_elements = 20
//! nu = 30.0
//! f = 250.0
//! obstacle = { modes = [1.0, 3.0], amplitudes = [-0.2, 0.2], offset = -0.5 }
//! [parameter]
//! name = "gamma"
//! description = "slope of the obstacle"
//! min = -0.5
//! max = 0.5
//! n_train = 5
//! [solver]
//! rel_tol = 1e-10
//! max_iter = 100
//! [study]
//! primal_tol = 0.0
//! dual_orth_tol = 0.0
//! dual_cone_tol = 0.0
//! dual_cone_tol_truncated = 0.2
//! specificity_samples = 100
//! seed = 1
//! "#,
//! )?;
//! let store = dir.path().join("store");
//! let args = ["crom", "-q", "--store", store.to_str().unwrap(), "run", scene.to_str().unwrap()];
//! assert_eq!(crom_pipeline::main_with_args(args.map(std::ffi::OsString::from)), 0);
//! // The study's files under stable names, and the catalog of every artifact.
//! assert!(store.join("scenes/rope-small/train.h5").exists());
//! assert!(store.join("scenes/rope-small/report/index.html").exists());
//! assert!(store.join("catalog.parquet").exists());
//! // A second run finds everything in the store.
//! assert_eq!(crom_pipeline::main_with_args(args.map(std::ffi::OsString::from)), 0);
//! # Ok::<(), std::io::Error>(())
//! ```

pub mod cache;
pub mod cli;
pub mod dag;
pub mod error;
pub mod executor;
pub mod external;
pub mod external_mesh;
pub mod import_scene;
pub mod io;
pub mod physics;
pub mod progress;
pub mod query;
pub mod report;
pub mod resources;
pub mod scenes;
pub mod scratch;
mod status;
pub mod store;
mod summary;

use std::ffi::OsString;
use std::time::Instant;

use clap::Parser;
use crom_schemas::SceneConfig;

use crate::cli::{Cli, Command};
use crate::error::CromError;
use crate::progress::Progress;
use crate::store::Store;

/// Whether the command line `args` runs study stages (`run`, `work`, `import`, `solve`,
/// `report`, `verify`), the commands that start with bounded malloc arenas
/// ([`resources::bound_malloc_arenas`]). The others (`query`, `status`, `ls`, `catalog`,
/// `scenes`, and a command line that does not parse) allocate little, and bounding the arenas
/// costs them a second process start: about 6 ms of a one-point `crom query`'s 47.
pub fn runs_stages(args: &[OsString]) -> bool {
    Cli::try_parse_from(args).is_ok_and(|cli| {
        !matches!(
            cli.command,
            Command::Query { .. } | Command::Status { .. } | Command::Ls { .. } | Command::Catalog | Command::Scenes
        )
    })
}

/// Run `crom` with these arguments; returns the process exit code.
pub fn main_with_args(args: impl IntoIterator<Item = OsString>) -> u8 {
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    match run(&cli) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

/// Execute a parsed command line.
pub fn run(cli: &Cli) -> Result<(), CromError> {
    match &cli.command {
        Command::Run { scene, offline, dry_run, executor, slurm } => {
            if *dry_run {
                let scene = load_scene(cli, scene)?;
                print!("{}", status::render(&cli.store, &scene, status::View::DryRun { online: !offline })?);
                return Ok(());
            }
            if *executor == executor::Executor::Slurm {
                slurm_sweep(cli, scene, slurm)?;
            } else if slurm.spec() != Default::default() {
                return Err(CromError::Usage {
                    message: "--partition, --time, --mem, --account, --shard-size, --max-parallel and --cpus-per-task \
                              are settings of the Slurm executor, and this run is local"
                        .into(),
                    fix: "add --executor slurm, or leave the Slurm settings out".into(),
                });
            }
            run_scene(cli, scene, !offline).map(|_| ())
        }
        Command::Work { scene, shard } => work(cli, scene, shard.0, shard.1),
        Command::Status { scene } => {
            let path = scenes::resolve(scene, &cli.scenes)?;
            let mut scene = SceneConfig::load(&path)?;
            external::resolve(&mut scene, &path)?;
            print!("{}", status::render(&cli.store, &scene, status::View::Status)?);
            Ok(())
        }
        Command::Solve { scene } => solve_scene(cli, scene),
        Command::Import(args) => {
            let path = import_scene::run(args, &Progress::new(cli.quiet))?;
            println!("{}\n  run it with: crom run {}", path.display(), path.display());
            Ok(())
        }
        Command::Query { scene, at, points, out, check, fields, allow_extrapolation, u_tol } => {
            let config = SceneConfig::load(&scenes::resolve(scene, &cli.scenes)?)?;
            let req = query::Request {
                at: at.clone(),
                points: points.clone(),
                out: out.clone(),
                check: *check,
                allow_extrapolation: *allow_extrapolation,
                fields: fields.clone(),
                u_tol: *u_tol,
            };
            query::run(&cli.store, &config, scene, &req)
        }
        Command::Report { scene } => {
            let out = run_scene(cli, scene, true)?;
            if let Some(report) = out.key("report") {
                let index = store::Store::open_read_only(&cli.store)
                    .dir(crom_schemas::artifact::ArtifactKind::REPORT, report)
                    .join("index.html");
                println!("{}", index.display());
            }
            Ok(())
        }
        Command::Ls { stage, format, output } => {
            summary::ls(&Store::open_read_only(&cli.store), stage.as_deref(), *format, output.as_deref())
        }
        Command::Catalog => {
            let store = Store::open(&cli.store)?;
            println!("{}", store::catalog::refresh(store.root())?.display());
            Ok(())
        }
        Command::Verify => summary::verify(&Store::open(&cli.store)?),
        Command::Scenes => {
            for name in scenes::available(&cli.scenes) {
                println!("{name}");
            }
            Ok(())
        }
    }
}

/// A run's context on an open store.
fn new_ctx<'a>(cli: &Cli, store: &'a Store, scene: &'a SceneConfig) -> dag::Ctx<'a> {
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    dag::Ctx { warnings: scenes::warnings(scene), ..dag::Ctx::new(store, &scene.scene.name, command, cli.quiet) }
}

/// Load a scene file and refuse it, before anything is written, when its estimated memory need
/// exceeds the limit ([`resources`]).
fn load_scene(cli: &Cli, scene_arg: &str) -> Result<SceneConfig, CromError> {
    let path = scenes::resolve(scene_arg, &cli.scenes)?;
    let mut scene = SceneConfig::load(&path)?;
    external::resolve(&mut scene, &path)?;
    physics::check_geometry(&scene, &path)?;
    let limit = match cli.max_memory {
        Some(b) => Some((b, "the --max-memory setting allows")),
        None => resources::available_bytes().map(|b| (b, "are available on this machine (MemAvailable)")),
    };
    let Some((limit, source)) = limit else { return Ok(scene) };
    let terms = resources::estimate(&scene);
    let total: f64 = terms.iter().map(|t| t.bytes).sum();
    if total <= limit {
        return Ok(scene);
    }
    // The field to change: the first term (mesh, contact surface, then the snapshot sets) that
    // alone exceeds the limit — a mesh that cannot be factored is not fixed by fewer points,
    // though its snapshot sets may be the larger term — else the largest term.
    let big = terms
        .iter()
        .find(|t| t.bytes > limit)
        .or_else(|| terms.iter().max_by(|a, b| a.bytes.total_cmp(&b.bytes)))
        .expect("estimate has terms");
    Err(CromError::Scene(crom_schemas::SceneError::Invalid {
        path,
        field: big.field.to_string(),
        problem: format!(
            "makes the run need an estimated {} (of which {}: {}), but {} {}",
            resources::human(total),
            big.what,
            resources::human(big.bytes),
            resources::human(limit),
            source
        ),
        fix: "reduce this size; or, if the machine can hold it, raise the limit with --max-memory (e.g. --max-memory 64G)"
            .to_string(),
    }))
}

fn solve_scene(cli: &Cli, scene_arg: &str) -> Result<(), CromError> {
    let start = Instant::now();
    let scene = load_scene(cli, scene_arg)?;
    let store = Store::open(&cli.store)?;
    let mut ctx = new_ctx(cli, &store, &scene);
    let result = dag::solve_points(&mut ctx, &scene);
    summary::print_run(&ctx, &scene, start.elapsed().as_secs_f64(), result.is_ok(), None);
    result
}

/// `crom work SCENE --shard K/N`: one worker of a sharded sweep, under the store's shared lock,
/// leaving a record of what it did ([`executor::tasks`]).
fn work(cli: &Cli, scene_arg: &str, k: usize, n: usize) -> Result<(), CromError> {
    let start = Instant::now();
    let scene = load_scene(cli, scene_arg)?;
    // Under Slurm, as many threads as the task was given CPUs (unless set explicitly).
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        if let Some(c) = std::env::var("SLURM_CPUS_PER_TASK").ok().and_then(|v| v.parse::<usize>().ok()) {
            let _ = rayon::ThreadPoolBuilder::new().num_threads(c.max(1)).build_global();
        }
    }
    let store = Store::open_shared(&cli.store)?;
    let name = scene.scene.name.clone();
    let mut record = executor::tasks::TaskRecord::start(k, n);
    record.write(store.root(), &name)?;
    let mut ctx = new_ctx(cli, &store, &scene);
    for w in &ctx.warnings {
        eprintln!("warning: {w}");
    }
    let result = dag::work_shard(&mut ctx, &scene, k, n);
    let p = ctx.points;
    record.solved = p.solved;
    record.reused = p.reused;
    record.failed = p.failed;
    record.ended = Some(store::fs::unix_now());
    record.state = if result.is_ok() { executor::tasks::TaskState::Done } else { executor::tasks::TaskState::Failed };
    record.error = result.as_ref().err().map(|e| e.to_string().lines().next().unwrap_or_default().to_string());
    record.write(store.root(), &name)?;
    println!(
        "crom work {name} --shard {k}/{n}: {} in {:.2} s: {} solved, {} reused, {} failed",
        if result.is_ok() { "done" } else { "stopped" },
        start.elapsed().as_secs_f64(),
        p.solved,
        p.reused,
        p.failed
    );
    result.map(|_| ())
}

/// The Slurm part of `crom run --executor slurm`: the mesh here (exclusive lock), then the
/// snapshot sweeps as a job array ([`executor::slurm`]); `crom run` then goes on locally.
fn slurm_sweep(cli: &Cli, scene_arg: &str, flags: &cli::SlurmFlags) -> Result<(), CromError> {
    let path = scenes::resolve(scene_arg, &cli.scenes)?;
    let scene = load_scene(cli, scene_arg)?;
    executor::slurm::check_client()?;
    std::fs::create_dir_all(&cli.store).map_err(|e| CromError::io(&cli.store, "creating the store", e))?;
    let root = cli.store.canonicalize().map_err(|e| CromError::io(&cli.store, "resolving the store path", e))?;
    let scene_file = path.canonicalize().map_err(|e| CromError::io(&path, "resolving the scene path", e))?;
    match Store::open(&root) {
        Ok(store) => {
            let mut ctx = new_ctx(cli, &store, &scene);
            dag::prepare_sweeps(&mut ctx, &scene)?;
        }
        // Workers of an earlier submission hold the store: wait for that job (sweep does).
        Err(CromError::Locked { .. })
            if executor::slurm::job_record(&root, &scene.scene.name)
                .is_some_and(|j| executor::slurm::queued(&j.job_id).is_ok_and(|q| !q.is_empty())) => {}
        Err(e) => return Err(e),
    }
    let plan = dag::plan::Plan::of(&scene);
    executor::slurm::sweep(&executor::slurm::Submission {
        root: &root,
        scene_file: &scene_file,
        scene: &scene,
        plan: &plan,
        chunk_columns: dag::chunk_columns(&scene),
        options: executor::slurm::options(&scene, &flags.spec()),
        progress: Progress::new(cli.quiet),
    })
}

fn run_scene(cli: &Cli, scene_arg: &str, online: bool) -> Result<dag::RunOutput, CromError> {
    let start = Instant::now();
    let scene = load_scene(cli, scene_arg)?;
    let store = Store::open(&cli.store)?;
    let mut ctx = new_ctx(cli, &store, &scene);
    let mut result = dag::run_scene(&mut ctx, &scene, online);
    // A snapshot column that fails its checksum: move its block aside and run again, which
    // solves exactly that block's points and rewrites the sets that referred to it.
    if let Err(CromError::CorruptColumns { block, message, .. }) = &result {
        let to = store.quarantine_block(block)?;
        ctx.warnings.push(format!("{message}; block moved to {} and its points solved again", to.display()));
        ctx.records.clear();
        ctx.points = dag::PointCounts::default();
        result = dag::run_scene(&mut ctx, &scene, online);
    }
    // Only a finished run names its artifacts; a failed one leaves the previous names.
    if let Ok(out) = &result {
        let study = dag::publish::study(&scene, out, online);
        store::published::publish(store.root(), &study)?;
    }
    // Best effort on failure too: the catalog then also shows the blocks this run committed.
    let refreshed = store::catalog::refresh(store.root());
    if result.is_ok() {
        refreshed?;
    }
    let report = result
        .as_ref()
        .ok()
        .and_then(|o| o.key("report"))
        .map(|r| store.dir(crom_schemas::artifact::ArtifactKind::REPORT, r));
    summary::print_run(&ctx, &scene, start.elapsed().as_secs_f64(), result.is_ok(), report.as_deref());
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(a: &[&str]) -> Vec<OsString> {
        a.iter().map(OsString::from).collect()
    }

    /// The commands that run stages start with bounded arenas; a query, a listing and a
    /// command line that does not parse do not, whatever the store is called.
    #[test]
    fn only_the_commands_that_run_stages_bound_the_arenas() {
        for a in
            [&["crom", "run", "rope"][..], &["crom", "--store", "query", "run", "rope"], &["crom", "solve", "rope"]]
        {
            assert!(runs_stages(&args(a)), "{a:?}");
        }
        for a in [
            &["crom", "query", "rope", "--at", "gamma=0.1"][..],
            &["crom", "--store", "run", "status", "rope"],
            &["crom", "scenes"],
            &["crom", "--version"],
            &["crom", "--no-such-flag"],
        ] {
            assert!(!runs_stages(&args(a)), "{a:?}");
        }
    }
}
