//! `crom run SCENE --executor slurm`: the snapshot sweeps of a study as a Slurm job array of
//! `crom work` workers writing into one shared store, then the remaining stages here.
//!
//! 1. **Plan** (under the store's exclusive lock): the mesh stage runs here, and the plan
//!    ([`crate::dag::plan`]) lists the chunks of the sweeps whose points are not all stored.
//! 2. **Submit** (lock released): the chunks are split into `N` contiguous shards of about
//!    `shard_size` points ([`crate::dag::plan::Plan`] numbering); only the shards that hold a
//!    missing chunk are submitted, as one `sbatch --array` whose task `K` runs
//!    `crom work SCENE --shard K/N` (shared lock, appends blocks). The job is recorded in
//!    `<store>/runs/<scene>/slurm/job.json`, the tasks' output goes next to it.
//! 3. **Wait** with a progress bar fed by the store's index (the points stored so far), until
//!    the job has left the queue. A rerun while the recorded job is still queued waits for it
//!    instead of submitting again.
//! 4. **Check**: a point still missing (a task killed, failed or timed out) is an error naming
//!    the shards and their logs; rerunning submits exactly the shards with missing points.
//!    Otherwise `crom run` goes on locally, finds every snapshot stored, and runs the rest.
//!
//! The leave-one-out folds run in the local part: at the sizes this machine kind runs they
//! take seconds (the metrics' rank grids and downdate folds); a second array for them is future work.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crom_schemas::scene::SlurmSpec;
use crom_schemas::SceneConfig;
use serde::{Deserialize, Serialize};

use crate::dag::plan::Plan;
use crate::dag::shard_range;
use crate::error::CromError;
use crate::progress::Progress;
use crate::store::fs::{named_dir, write_atomic};

/// Snapshot points per array task when neither the scene nor a flag says.
pub const DEFAULT_SHARD_SIZE: usize = 512;

/// The submitted job (`runs/<scene>/slurm/job.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    /// Slurm job id of the array.
    pub job_id: String,
    /// Array task indices submitted (shards).
    pub tasks: Vec<usize>,
    /// Number of shards the sweeps were split into.
    pub of: usize,
    /// Submission time, seconds since the Unix epoch.
    pub submitted: u64,
    /// The batch script.
    pub script: PathBuf,
}

/// Directory of a scene's Slurm job record, script and task logs.
pub fn dir(root: &Path, scene: &str) -> Result<PathBuf, CromError> {
    Ok(named_dir(root, "runs", scene)?.join("slurm"))
}

/// The recorded job of `scene`, if any.
pub fn job_record(root: &Path, scene: &str) -> Option<JobRecord> {
    let text = std::fs::read_to_string(dir(root, scene).ok()?.join("job.json")).ok()?;
    serde_json::from_str(&text).ok()
}

/// `sbatch` settings: the scene's `[executor.slurm]`, overridden by command-line flags.
pub fn options(scene: &SceneConfig, flags: &SlurmSpec) -> SlurmSpec {
    let base = scene.executor.as_ref().map(|e| e.slurm.clone()).unwrap_or_default();
    SlurmSpec {
        partition: flags.partition.clone().or(base.partition),
        time: flags.time.clone().or(base.time),
        mem: flags.mem.clone().or(base.mem),
        account: flags.account.clone().or(base.account),
        shard_size: flags.shard_size.or(base.shard_size),
        max_parallel: flags.max_parallel.or(base.max_parallel),
        cpus_per_task: flags.cpus_per_task.or(base.cpus_per_task),
    }
}

/// The array tasks of `of` shards over `total` chunks that hold one of the `missing` chunks.
pub fn tasks_for(total: usize, of: usize, missing: &[usize]) -> Vec<usize> {
    (0..of).filter(|&k| missing.iter().any(|c| shard_range(total, k, of).contains(c))).collect()
}

/// Shards for `total` chunks of `chunk_columns` points each, about `shard_size` points a shard.
pub fn shard_count(total: usize, chunk_columns: usize, shard_size: usize) -> usize {
    let per = shard_size.div_ceil(chunk_columns.max(1)).max(1);
    total.div_ceil(per).max(1)
}

/// Refuse, before anything is written, when the Slurm client commands are not on `PATH`.
pub fn check_client() -> Result<(), CromError> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for cmd in ["sbatch", "squeue"] {
        if !std::env::split_paths(&path).any(|d| d.join(cmd).is_file()) {
            return Err(CromError::Executor {
                message: format!("`{cmd}` is not on PATH: --executor slurm needs the Slurm client commands"),
                fix: "run on a machine with Slurm (a login node; `scripts/slurm-up.sh start` makes this machine a \
                      one-node cluster), or use --executor local (the default)"
                    .into(),
            });
        }
    }
    Ok(())
}

/// Run a scheduler command; its standard output, or an [`CromError::Executor`].
fn scheduler(cmd: &str, args: &[String], fix: &str) -> Result<String, CromError> {
    let out = Command::new(cmd).args(args).output().map_err(|e| CromError::Executor {
        message: format!("`{cmd}` could not be started ({e}): --executor slurm needs the Slurm client commands"),
        fix: "run on a machine with Slurm (a login node), or use --executor local (the default)".into(),
    })?;
    if !out.status.success() {
        return Err(CromError::Executor {
            message: format!(
                "`{cmd} {}` failed ({}): {}",
                args.join(" "),
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            ),
            fix: fix.to_string(),
        });
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The tasks of job `job` still in the queue, as `(task id, state)`; empty once it has left.
pub fn queued(job: &str) -> Result<Vec<(String, String)>, CromError> {
    let args: Vec<String> = ["-h", "-r", "-j", job, "-o", "%i %T"].iter().map(|s| s.to_string()).collect();
    let out = match scheduler("squeue", &args, "check that slurmctld is reachable (`sinfo`)") {
        Ok(o) => o,
        // A job that has left slurmctld's memory is reported as invalid: it is not queued.
        Err(CromError::Executor { message, .. }) if message.contains("Invalid job id") => String::new(),
        Err(e) => return Err(e),
    };
    Ok(out
        .lines()
        .filter_map(|l| l.split_once(' '))
        .map(|(id, state)| (id.trim().to_string(), state.trim().to_string()))
        .collect())
}

/// Everything the driver needs.
#[derive(Debug)]
pub struct Submission<'a> {
    /// Store root (absolute).
    pub root: &'a Path,
    /// Scene file (absolute), read by the workers.
    pub scene_file: &'a Path,
    /// The scene.
    pub scene: &'a SceneConfig,
    /// Its plan.
    pub plan: &'a Plan,
    /// Points per chunk (`crate::dag::chunk_columns`).
    pub chunk_columns: usize,
    /// sbatch settings.
    pub options: SlurmSpec,
    /// Progress display.
    pub progress: Progress,
}

/// Submit the shards with missing points (unless the recorded job is still queued), wait for
/// the job to leave the queue, and check that every point is stored.
pub fn sweep(s: &Submission<'_>) -> Result<(), CromError> {
    let name = &s.scene.scene.name;
    let state = s.plan.snapshot_state(s.root)?;
    if state.missing_chunks.is_empty() {
        return Ok(());
    }
    let job = match job_record(s.root, name) {
        Some(j) if !queued(&j.job_id)?.is_empty() => {
            eprintln!("slurm: job {} of an earlier run is still queued; waiting for it", j.job_id);
            j
        }
        _ => submit(s, &state.missing_chunks)?,
    };
    wait(s, &job, state.stored, state.points)?;
    let after = s.plan.snapshot_state(s.root)?;
    if after.missing_chunks.is_empty() {
        return Ok(());
    }
    let records = super::tasks::read_all(s.root, name);
    let unfinished: Vec<String> = tasks_for(s.plan.chunks(), job.of, &after.missing_chunks)
        .iter()
        .map(|k| {
            let r = records.iter().find(|r| r.of == job.of && r.shard == *k);
            let what = match r {
                None => "never started".to_string(),
                Some(r) => match (&r.state, &r.error) {
                    (_, Some(e)) => format!("failed: {e}"),
                    (super::tasks::TaskState::Running, _) => "killed (started, never finished)".to_string(),
                    _ => format!("{:?}", r.state).to_lowercase(),
                },
            };
            format!("  shard {k}/{} (task {}_{k}): {what}", job.of, job.job_id)
        })
        .collect();
    let logs = dir(s.root, name)?;
    Err(CromError::Executor {
        message: format!(
            "{} of {} snapshot points of `{name}` are still missing after Slurm job {}:\n{}\n  task logs: {}",
            after.points - after.stored,
            after.points,
            job.job_id,
            unfinished.join("\n"),
            logs.display()
        ),
        fix: format!(
            "rerun `crom run {name} --executor slurm`: it submits only the shards with missing points (for a failed \
             point, see its error above)"
        ),
    })
}

fn submit(s: &Submission<'_>, missing: &[usize]) -> Result<JobRecord, CromError> {
    let name = &s.scene.scene.name;
    let total = s.plan.chunks();
    let shard_size = s.options.shard_size.unwrap_or(DEFAULT_SHARD_SIZE);
    let of = shard_count(total, s.chunk_columns, shard_size);
    let tasks = tasks_for(total, of, missing);
    let dir = dir(s.root, name)?;
    std::fs::create_dir_all(&dir).map_err(|e| CromError::io(&dir, "creating the job directory", e))?;
    let exe = std::env::current_exe().map_err(|e| CromError::io("crom", "finding the crom executable", e))?;
    let quote = |p: &Path| format!("'{}'", p.display().to_string().replace('\'', "'\\''"));
    let script = dir.join("job.sh");
    // The chunk size the plan was made with, explicitly: a site that submits with
    // `SBATCH_EXPORT=NONE` (no inherited environment) must still shard the same chunks.
    let text = format!(
        "#!/bin/sh\n# crom: shard $SLURM_ARRAY_TASK_ID of {of} of the snapshot sweeps of {name}\nexport CROM_BLOCK_COLUMNS={}\nexec {} --store {} work {} --shard \"$SLURM_ARRAY_TASK_ID/{of}\"\n",
        s.chunk_columns,
        quote(&exe),
        quote(s.root),
        quote(s.scene_file)
    );
    write_atomic(&script, text.as_bytes())?;
    let list = tasks.iter().map(usize::to_string).collect::<Vec<_>>().join(",");
    let array = match s.options.max_parallel {
        Some(p) => format!("{list}%{p}"),
        None => list,
    };
    let o = &s.options;
    let mut args = vec![
        "--parsable".to_string(),
        format!("--job-name=crom-{name}"),
        format!("--array={array}"),
        format!("--output={}", dir.join("%A_%a.out").display()),
        format!("--cpus-per-task={}", o.cpus_per_task.unwrap_or(1)),
    ];
    for (flag, v) in [("partition", &o.partition), ("time", &o.time), ("mem", &o.mem), ("account", &o.account)] {
        if let Some(v) = v {
            args.push(format!("--{flag}={v}"));
        }
    }
    args.push(script.display().to_string());
    let out = scheduler(
        "sbatch",
        &args,
        "check the [executor.slurm] settings of the scene file (or the --partition/--time/--mem/--account flags) against `sinfo`",
    )?;
    // --parsable prints `jobid` or `jobid;cluster`.
    let job_id = out.trim().split(';').next().unwrap_or_default().to_string();
    if job_id.is_empty() || !job_id.chars().all(|c| c.is_ascii_digit()) {
        return Err(CromError::Executor {
            message: format!("sbatch printed {:?}, not a job id", out.trim()),
            fix: "check the Slurm installation (`sbatch --version`)".into(),
        });
    }
    let record = JobRecord { job_id, tasks, of, submitted: crate::store::fs::unix_now(), script };
    write_atomic(&dir.join("job.json"), serde_json::to_string_pretty(&record).unwrap_or_default().as_bytes())?;
    eprintln!(
        "slurm: job {} submitted: {} of {of} shards (array tasks {}), logs in {}",
        record.job_id,
        record.tasks.len(),
        array,
        dir.display()
    );
    Ok(record)
}

/// Poll the queue (and the store's index, for the progress bar) until the job has left it.
fn wait(s: &Submission<'_>, job: &JobRecord, stored: usize, points: usize) -> Result<(), CromError> {
    let mut bar = s.progress.stage("slurm", points - stored);
    let mut shown = stored;
    // The index is read at most every 2 s, and never more than a tenth of the time: at 10^5
    // and more snapshots a read takes seconds (docs/design-notes.md#what-limits-a-sweep-at-a-million-snapshots).
    let mut last_index = Instant::now() - Duration::from_secs(60);
    let mut read_time = Duration::ZERO;
    loop {
        let q = queued(&job.job_id)?;
        if last_index.elapsed() >= Duration::from_secs(2).max(read_time * 10) || q.is_empty() {
            let t = Instant::now();
            let now = s.plan.snapshot_state(s.root)?.stored;
            read_time = t.elapsed();
            let running = q.iter().filter(|t| t.1 == "RUNNING").count();
            let msg = format!("{running} running, {} queued", q.len() - running);
            while shown < now {
                bar.inc(&msg);
                shown += 1;
            }
            last_index = Instant::now();
        }
        if q.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    bar.finish(&format!("job {} left the queue: {} of {points} points stored", job.job_id, shown));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shards cover the chunks exactly once, and only shards with missing chunks are submitted.
    #[test]
    fn shards_partition_the_chunks() {
        for total in [1usize, 2, 7, 64, 1000] {
            for of in 1..=9usize.min(total) {
                let mut seen = vec![0; total];
                for k in 0..of {
                    for c in shard_range(total, k, of) {
                        seen[c] += 1;
                    }
                }
                assert!(seen.iter().all(|&n| n == 1), "total {total}, {of} shards: {seen:?}");
            }
        }
        assert_eq!(tasks_for(10, 5, &[0, 1, 9]), vec![0, 4]);
        assert_eq!(tasks_for(10, 5, &[]), Vec::<usize>::new());
        // 255 points in chunks of 16: 16 chunks; 64 points a shard = 4 chunks: 4 shards.
        assert_eq!(shard_count(16, 16, 64), 4);
        assert_eq!(shard_count(16, 16, 1), 16);
        assert_eq!(shard_count(16, 128, 512), 4);
        assert_eq!(shard_count(0, 16, 64), 1);
    }
}
