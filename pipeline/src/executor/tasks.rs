//! The records sharded workers leave in the store, so that a finished, failed or killed task is
//! visible (`crom status`): `<store>/runs/<scene>/work/shard-<K>-of-<N>.json`, written
//! atomically when the worker starts (`running`) and again when it ends (`done` or `failed`).
//! A worker killed by the scheduler (`scancel`, a time limit, a lost node) never writes its
//! end: its record stays `running`, and `crom status` tells it from a live one by the
//! scheduler's queue or, on this host, by its process id.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::CromError;
use crate::store::fs::{named_dir, write_atomic};

/// State of a worker's task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TaskState {
    /// Started, no end recorded (running, or killed).
    Running,
    /// Finished: every point of its shard is stored.
    Done,
    /// Ended with an error (named in `error`).
    Failed,
}

/// One worker's record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskRecord {
    /// Shard index.
    pub shard: usize,
    /// Number of shards.
    pub of: usize,
    /// State.
    pub state: TaskState,
    /// Host name.
    pub host: String,
    /// Process id on that host.
    pub pid: u32,
    /// `SLURM_ARRAY_JOB_ID_SLURM_ARRAY_TASK_ID` when run by Slurm.
    pub slurm_task: Option<String>,
    /// Start, seconds since the Unix epoch.
    pub started: u64,
    /// End, seconds since the Unix epoch.
    pub ended: Option<u64>,
    /// Points solved.
    pub solved: usize,
    /// Points found stored.
    pub reused: usize,
    /// Points that failed.
    pub failed: usize,
    /// The error of a failed task.
    pub error: Option<String>,
}

/// Directory of the worker records of `scene`.
pub fn dir(root: &Path, scene: &str) -> Result<PathBuf, CromError> {
    Ok(named_dir(root, "runs", scene)?.join("work"))
}

impl TaskRecord {
    /// A record for a worker starting now on shard `shard` of `of`.
    pub fn start(shard: usize, of: usize) -> Self {
        let slurm_task = match (std::env::var("SLURM_ARRAY_JOB_ID"), std::env::var("SLURM_ARRAY_TASK_ID")) {
            (Ok(j), Ok(t)) => Some(format!("{j}_{t}")),
            _ => std::env::var("SLURM_JOB_ID").ok(),
        };
        Self {
            shard,
            of,
            state: TaskState::Running,
            host: crate::store::fs::host_name(),
            pid: std::process::id(),
            slurm_task,
            started: crate::store::fs::unix_now(),
            ended: None,
            solved: 0,
            reused: 0,
            failed: 0,
            error: None,
        }
    }

    /// Write (replace) the record under the store `root`.
    pub fn write(&self, root: &Path, scene: &str) -> Result<(), CromError> {
        let dir = dir(root, scene)?;
        std::fs::create_dir_all(&dir).map_err(|e| CromError::io(&dir, "creating the worker records", e))?;
        let path = dir.join(format!("shard-{}-of-{}.json", self.shard, self.of));
        let text = serde_json::to_string_pretty(self).unwrap_or_default();
        write_atomic(&path, text.as_bytes())
    }

    /// Whether the process of a `running` record is gone, as far as this host can tell: `Some`
    /// for a record of this host, `None` for another host's.
    pub fn process_gone(&self) -> Option<bool> {
        (self.host == crate::store::fs::host_name()).then(|| !Path::new(&format!("/proc/{}", self.pid)).exists())
    }
}

/// Every worker record of `scene` (unreadable ones skipped), ordered by shard count, shard.
pub fn read_all(root: &Path, scene: &str) -> Vec<TaskRecord> {
    let Ok(dir) = dir(root, scene) else { return Vec::new() };
    let mut v: Vec<TaskRecord> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".json"))
        .filter_map(|e| std::fs::read_to_string(e.path()).ok())
        .filter_map(|t| serde_json::from_str(&t).ok())
        .collect();
    v.sort_by_key(|r| (r.of, r.shard));
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_replace() {
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let mut r = TaskRecord::start(2, 5);
        r.write(tmp.path(), "s").expect("write");
        r.state = TaskState::Done;
        r.solved = 7;
        r.write(tmp.path(), "s").expect("rewrite");
        TaskRecord::start(0, 5).write(tmp.path(), "s").expect("another");
        let all = read_all(tmp.path(), "s");
        assert_eq!(all.len(), 2);
        assert_eq!((all[0].shard, all[0].state), (0, TaskState::Running));
        assert_eq!(all[1], r);
        assert_eq!(all[0].process_gone(), Some(false), "this test's own process is alive");
        assert!(dir(tmp.path(), "../x").is_err(), "a scene name cannot leave the store");
    }
}
