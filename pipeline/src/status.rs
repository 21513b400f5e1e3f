//! `crom run --dry-run` and `crom status`: a scene's plan ([`crate::dag::plan`]) against the
//! store — what is stored, what would run — and, for `status`, the sharded workers' records and
//! the Slurm job's queue. Reads only; takes no lock.

use std::fmt::Write as _;
use std::path::Path;

use crate::dag::plan::{stored, Plan};
use crate::error::CromError;
use crate::executor::{slurm, tasks};

/// What to show.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum View {
    /// `crom run --dry-run` (with `--offline`: the online stages are not part of the run).
    DryRun { online: bool },
    /// `crom status`.
    Status,
}

/// The text of the plan of `scene` against the store at `root`.
pub(crate) fn render(root: &Path, scene: &crom_schemas::SceneConfig, view: View) -> Result<String, CromError> {
    render_plan(root, scene, &Plan::of(scene), view)
}

/// [`render`] of the plan `plan` of `scene`.
pub(crate) fn render_plan(
    root: &Path,
    scene: &crom_schemas::SceneConfig,
    plan: &Plan,
    view: View,
) -> Result<String, CromError> {
    let state = plan.snapshot_state(root)?;
    let name = &scene.scene.name;
    let mut out = String::new();
    let to_run = if matches!(view, View::DryRun { .. }) { "would run" } else { "not stored" };
    match view {
        View::DryRun { .. } => {
            let _ = writeln!(out, "crom run {name} --dry-run: nothing is written (store {})", root.display());
        }
        View::Status => {
            let _ = writeln!(out, "crom status {name} (store {})", root.display());
        }
    }
    let _ = writeln!(out, "  {:<20} {:<14} state", "stage", "key");
    for (sweep, points, done) in &state.sweeps {
        let what = if done == points {
            "stored".to_string()
        } else if matches!(view, View::DryRun { .. }) {
            let verb = if sweep == "import" { "imported" } else { "solved" };
            format!("{} would be {verb}", points - done)
        } else {
            format!("{} missing", points - done)
        };
        let _ = writeln!(out, "  {:<20} {:<14} {done} of {points} points stored; {what}", "snapshots", sweep);
    }
    let mut missing = 0;
    let stages: Vec<_> = plan.nodes.iter().filter(|n| !n.is_sweep()).collect();
    for node in &stages {
        let skipped = node.online && matches!(view, View::DryRun { online: false });
        let state = if stored(root, node) {
            "stored"
        } else if skipped {
            "not part of an --offline run"
        } else {
            missing += 1;
            to_run
        };
        let _ = writeln!(out, "  {:<20} {:<14} {state}", node.name, node.key.short());
    }
    let _ = writeln!(
        out,
        "  {} of {} snapshot points stored ({} of {} blocks of work complete); {missing} of {} stages {to_run}",
        state.stored,
        state.points,
        state.chunks - state.missing_chunks.len(),
        state.chunks,
        stages.len()
    );
    if view == View::Status {
        levels(&mut out, root, scene)?;
        workers(&mut out, root, name)?;
    }
    Ok(out)
}

/// A scene whose training set is a nested level (`train_level = k`): one line per level
/// 1..=k — its training points, its study's snapshot points stored and its offline stages
/// stored — so a study grown level by level shows which levels it has.
fn levels(out: &mut String, root: &Path, scene: &crom_schemas::SceneConfig) -> Result<(), CromError> {
    let Some(k) = scene.parameter.train_level else { return Ok(()) };
    let _ = writeln!(out, "  levels (train_level = {k}; each level's study as a scene with that train_level):");
    // Every level's snapshots are in one column family (same mesh, solver and names): its index
    // is read once.
    let mut index: Option<(crate::cache::Key, crate::store::columns::Index)> = None;
    for level in 1..=k {
        let mut at = scene.clone();
        at.parameter.train_level = Some(level);
        let plan = Plan::of(&at);
        if index.as_ref().is_none_or(|(family, _)| *family != plan.family) {
            index = Some((plan.family.clone(), plan.index(root)?));
        }
        let state = plan.snapshot_state_in(&index.as_ref().expect("read above").1);
        let offline: Vec<_> = plan.nodes.iter().filter(|n| !n.is_sweep() && !n.online).collect();
        let done = offline.iter().filter(|n| stored(root, n)).count();
        let study = if done == offline.len() {
            "studied".to_string()
        } else {
            format!("{done} of {} offline stages stored", offline.len())
        };
        let _ = writeln!(
            out,
            "    level {level:>2}: {:>6} training points; {} of {} points stored; {study}",
            at.parameter.train_points().len(),
            state.stored,
            state.points,
        );
    }
    Ok(())
}

/// The worker records and the Slurm job of `scene`.
fn workers(out: &mut String, root: &Path, name: &str) -> Result<(), CromError> {
    let job = slurm::job_record(root, name);
    let queue = match &job {
        Some(j) => slurm::queued(&j.job_id).ok(),
        None => None,
    };
    if let Some(j) = &job {
        let q = match &queue {
            Some(q) if q.is_empty() => "has left the queue".to_string(),
            Some(q) => {
                let running = q.iter().filter(|t| t.1 == "RUNNING").count();
                format!("{running} tasks running, {} waiting", q.len() - running)
            }
            None => "queue unknown (squeue not available)".to_string(),
        };
        let _ = writeln!(
            out,
            "  slurm job {}: {} of {} shards submitted; {q}; logs in {}",
            j.job_id,
            j.tasks.len(),
            j.of,
            slurm::dir(root, name)?.display()
        );
    }
    let records = tasks::read_all(root, name);
    if records.is_empty() {
        return Ok(());
    }
    let _ = writeln!(out, "  workers ({}):", tasks::dir(root, name)?.display());
    for r in records {
        let queued = |t: &str| queue.as_ref().map(|q| q.iter().any(|(id, _)| id == t));
        let state = match r.state {
            tasks::TaskState::Running => match (r.slurm_task.as_deref().and_then(queued), r.process_gone()) {
                (Some(false), _) | (None, Some(true)) => "KILLED (started, never finished; rerun to finish its points)",
                _ => "running",
            },
            tasks::TaskState::Done => "done",
            tasks::TaskState::Failed => "FAILED",
        };
        let took = r.ended.map(|e| format!(" in {} s", e.saturating_sub(r.started))).unwrap_or_default();
        let task = r.slurm_task.as_deref().map(|t| format!(" slurm task {t},")).unwrap_or_default();
        let _ = writeln!(
            out,
            "    shard {}/{}: {state}{took} —{task} host {} pid {}; {} solved, {} reused, {} failed{}",
            r.shard,
            r.of,
            r.host,
            r.pid,
            r.solved,
            r.reused,
            r.failed,
            r.error.as_deref().map(|e| format!("; error: {e}")).unwrap_or_default()
        );
    }
    Ok(())
}
