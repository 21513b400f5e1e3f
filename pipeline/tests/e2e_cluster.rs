//! End-to-end: many writers on one store. Concurrent `crom work` shards — one of
//! them killed mid-way and rerun — leave exactly the store a single local run writes, byte for
//! byte, blocks included; `crom run --dry-run` writes nothing and `crom status` shows a killed
//! worker and, after a run, nothing left to run (the plan's keys are the run's keys); and the
//! same study through a real single-node Slurm (`scripts/slurm-up.sh`), with at least four array
//! tasks at once and one cancelled mid-way, rerun to identical results.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{assert_same_results, crom_cmd, repo, text, variant};

/// Snapshots per block in these tests: small, so that ironing-coarse's 381 points make 96
/// chunks to shard (a storage knob: it changes no key and no result).
const BLOCK_COLUMNS: &str = "4";

fn with_blocks(mut c: Command) -> Command {
    c.env("CROM_BLOCK_COLUMNS", BLOCK_COLUMNS);
    c
}

fn run_ok(c: Command, what: &str) -> String {
    let mut c = c;
    let o = c.output().expect("crom runs");
    assert!(o.status.success(), "{what}: {}", text(&o));
    text(&o)
}

/// The worker record of shard `k` of `n`, once it exists.
fn record(store: &Path, scene: &str, k: usize, n: usize) -> Option<serde_json::Value> {
    let p = store.join(format!("runs/{scene}/work/shard-{k}-of-{n}.json"));
    serde_json::from_str(&std::fs::read_to_string(p).ok()?).ok()
}

/// A local reference run of `scene` (offline study) with the tests' block size.
fn reference(dir: &Path, scene: &str) -> PathBuf {
    let store = dir.join("reference");
    run_ok(with_blocks(crom_cmd(&store, &["--quiet", "run", scene, "--offline"])), "reference run");
    store
}

#[test]
fn workers_by_hand_share_a_store_and_write_what_one_process_writes() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("shared");
    let scene = "ironing-coarse";
    let dry = run_ok(crom_cmd(&store, &["run", scene, "--dry-run"]), "dry run");
    assert!(dry.contains("0 of 381 snapshot points stored"), "{dry}");
    assert!(!store.exists() || std::fs::read_dir(&store).expect("dir").next().is_none(), "a dry run writes nothing");

    // Four workers at once; shard 1 is killed (SIGKILL) as soon as it has started.
    let n = 4;
    let mut workers: Vec<std::process::Child> = (0..n)
        .map(|k| {
            with_blocks(crom_cmd(&store, &["--quiet", "work", scene, "--shard", &format!("{k}/{n}")]))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("spawn a worker")
        })
        .collect();
    let start = Instant::now();
    while record(&store, scene, 1, n).is_none() {
        assert!(start.elapsed() < Duration::from_secs(120), "worker 1 never started");
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(workers[1].try_wait().expect("poll").is_none(), "worker 1 ended before it could be killed");
    workers[1].kill().expect("kill worker 1");
    for w in &mut workers {
        let _ = w.wait();
    }
    let status = run_ok(with_blocks(crom_cmd(&store, &["status", scene])), "status");
    assert!(status.contains("shard 1/4: KILLED"), "the killed worker is visible:\n{status}");
    for k in [0, 2, 3] {
        assert!(status.contains(&format!("shard {k}/4: done")), "worker {k} finished:\n{status}");
    }
    let line = status.lines().find(|l| l.contains("snapshot points stored")).expect("points line");
    let words: Vec<usize> = line.split_whitespace().filter_map(|w| w.parse().ok()).collect();
    assert!(words[0] < words[1], "the kill landed mid-way: {status}");

    // The killed shard again, then the run: every snapshot is reused.
    run_ok(with_blocks(crom_cmd(&store, &["--quiet", "work", scene, "--shard", "1/4"])), "worker 1 again");
    let run = run_ok(with_blocks(crom_cmd(&store, &["run", scene, "--offline"])), "run");
    assert!(run.contains("snapshots: 0 solved"), "{run}");
    let after = run_ok(with_blocks(crom_cmd(&store, &["status", scene])), "status after");
    // Every stage of the offline study is stored under the key the plan predicted; only the
    // online stages (rom, the model, the online views, the report) are not.
    assert!(after.contains("381 of 381 snapshot points stored"), "{after}");
    assert!(after.contains("4 of 29 stages not stored"), "{after}");
    assert_same_results(&reference(tmp.path(), scene), &store, "four workers, one killed, vs one local run");
}

/// Three workers on the same shard at once (all points solved three times, the same block names
/// written concurrently) and readers polling the index meanwhile: every read sees a consistent
/// index (no error, the stored count never falls), and the store ends with one row per point
/// and the files of a single local run.
#[test]
fn duplicate_workers_and_concurrent_readers_leave_one_consistent_store() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("dup");
    let scene = "ironing-coarse";
    let mut workers: Vec<std::process::Child> = (0..3)
        .map(|_| {
            with_blocks(crom_cmd(&store, &["--quiet", "work", scene, "--shard", "0/1"]))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("spawn a worker")
        })
        .collect();
    let mut last = 0usize;
    let mut reads = 0;
    while workers.iter_mut().any(|w| w.try_wait().expect("poll").is_none()) {
        let o = with_blocks(crom_cmd(&store, &["status", scene])).output().expect("status");
        assert!(o.status.success(), "a read during the writes failed: {}", text(&o));
        let t = text(&o);
        let line = t.lines().find(|l| l.contains("snapshot points stored")).expect("points line");
        let stored: usize = line.split_whitespace().next().and_then(|w| w.parse().ok()).expect("count");
        assert!(stored >= last, "the stored count fell from {last} to {stored}");
        last = stored;
        reads += 1;
    }
    for w in &mut workers {
        assert!(w.wait().expect("wait").success(), "a duplicate worker failed");
    }
    assert!(reads >= 2, "the readers never overlapped the writers");
    let run = run_ok(with_blocks(crom_cmd(&store, &["run", scene, "--offline"])), "run");
    assert!(run.contains("snapshots: 0 solved"), "{run}");
    // One row per point in the compacted index, every fragment folded into it.
    let st = crom_pipeline::store::Store::open_read_only(&store);
    let fam = st.families().pop().expect("one family");
    let index = crom_pipeline::io::table::read_parquet(&fam.dir().join("index.parquet")).expect("index");
    assert_eq!(index.rows(), 381);
    let fragments = std::fs::read_dir(fam.dir().join("index")).expect("fragments").count();
    assert_eq!(fragments, 0, "every fragment compacted");
    assert_same_results(&reference(tmp.path(), scene), &store, "three duplicate workers vs one local run");
}

/// The plan predicts every key a full run writes (online stages included), on a scene with
/// nested levels and on hertz.
#[test]
fn after_a_run_the_plan_has_nothing_left_to_run() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let nested =
        variant(tmp.path(), "rope", "rope-nested.toml", &[("n_train = 10", "n_train = 10\nnested_levels = 3")]);
    for scene in [nested.to_str().expect("utf8"), "hertz"] {
        let store = tmp.path().join(scene.replace('/', "_"));
        let dry = run_ok(crom_cmd(&store, &["run", scene, "--dry-run"]), "dry run");
        let stages = dry.lines().filter(|l| l.ends_with("would run") && !l.contains(" stages ")).count();
        assert!(dry.contains(&format!("{stages} of {stages} stages would run")), "{dry}");
        assert!(stages >= 13, "{dry}");
        run_ok(crom_cmd(&store, &["--quiet", "run", scene]), "run");
        let status = run_ok(crom_cmd(&store, &["status", scene]), "status");
        assert!(status.contains(&format!("0 of {stages} stages not stored")), "{scene}:\n{status}");
        let unwritten = status.lines().filter(|l| l.ends_with("not stored") && !l.contains(" stages ")).count();
        assert_eq!(unwritten, 0, "{scene}: a stage the plan names was not written:\n{status}");
    }
}

/// Bad requests are refused before anything is written, with the field or flag and the fix.
#[test]
fn bad_cluster_requests_are_refused_before_anything_is_written() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let zero =
        variant(tmp.path(), "rope", "rope-zero.toml", &[("[study]", "[executor.slurm]\nshard_size = 0\n\n[study]")]);
    let typo =
        variant(tmp.path(), "rope", "rope-typo.toml", &[("[study]", "[executor.slurm]\npartitoin = \"x\"\n\n[study]")]);
    let spaced =
        variant(tmp.path(), "rope", "rope-space.toml", &[("[study]", "[executor.slurm]\ntime = \"1 h\"\n\n[study]")]);
    let cases: Vec<(Vec<&str>, Option<&str>, i32, &str)> = vec![
        (vec!["work", "rope", "--shard", "4/4"], None, 2, "give K/N with 0 <= K < N"),
        (vec!["work", "rope", "--shard", "1"], None, 2, "give K/N with 0 <= K < N"),
        (vec!["run", "rope", "--partition", "x"], None, 2, "add --executor slurm"),
        (vec!["run", zero.to_str().expect("utf8"), "--executor", "slurm"], None, 2, "executor.slurm.shard_size"),
        (vec!["run", typo.to_str().expect("utf8"), "--executor", "slurm"], None, 2, "partitoin"),
        (vec!["run", spaced.to_str().expect("utf8"), "--executor", "slurm"], None, 2, "executor.slurm.time"),
        // No Slurm client on PATH.
        (vec!["run", "rope", "--executor", "slurm"], Some("/nonexistent"), 1, "`sbatch` is not on PATH"),
    ];
    for (args, path, code, says) in cases {
        let mut c = crom_cmd(&store, &args);
        if let Some(p) = path {
            c.env("PATH", p);
        }
        let o = c.output().expect("crom runs");
        assert_eq!(o.status.code(), Some(code), "{args:?}: {}", text(&o));
        // Every message says what to do: a `fix:` line, or (command-line syntax) "give …".
        let t = text(&o);
        assert!(t.contains(says) && (t.contains("fix") || t.contains("give ")), "{args:?} should say {says:?}: {t}");
        assert!(!store.exists(), "{args:?} wrote into the store");
    }
}

/// Stops the daemons `slurm-up.sh start` started, when the test ends (pass or fail).
struct Daemons(PathBuf);

impl Drop for Daemons {
    fn drop(&mut self) {
        let _ = Command::new("bash").arg(repo().join("scripts/slurm-up.sh")).arg("stop").arg(&self.0).status();
    }
}

/// Whether this machine can install and run Slurm (root and Debian's apt), else why not.
fn slurm_possible() -> Result<(), String> {
    let root = Command::new("id").arg("-u").output().map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    if !root.unwrap_or(false) {
        return Err("not root: scripts/slurm-up.sh needs root to install and start Slurm".into());
    }
    let has = |c: &str| {
        Command::new("sh").args(["-c", &format!("command -v {c}")]).output().is_ok_and(|o| o.status.success())
    };
    if !has("sbatch") && !has("apt-get") {
        return Err("no Slurm and no apt-get to install it".into());
    }
    Ok(())
}

fn queued_running(job: &str) -> usize {
    Command::new("squeue")
        .args(["-h", "-r", "-j", job, "-t", "RUNNING", "-o", "%i"])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).lines().count())
        .unwrap_or(0)
}

#[test]
fn a_slurm_array_with_a_cancelled_task_reruns_to_the_local_results() {
    if let Err(why) = slurm_possible() {
        eprintln!("SKIPPED a_slurm_array_with_a_cancelled_task_reruns_to_the_local_results: {why}");
        return;
    }
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let pids = tmp.path().join("slurm.pids");
    let up = Command::new("bash")
        .arg(repo().join("scripts/slurm-up.sh"))
        .arg("start")
        .arg(&pids)
        .env("CROM_SLURM_CPUS", "4")
        .output()
        .expect("slurm-up.sh runs");
    let _daemons = Daemons(pids);
    assert!(up.status.success(), "scripts/slurm-up.sh start failed: {}", text(&up));

    let scene = "ironing-coarse";
    let store = tmp.path().join("slurm");
    // 381 points in 96 chunks of 4; 64 points a task: 6 array tasks, 4 at once.
    let args = ["run", scene, "--offline", "--executor", "slurm", "--shard-size", "64", "--cpus-per-task", "1"];
    let mut driver =
        with_blocks(crom_cmd(&store, &args)).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("driver");
    let start = Instant::now();
    let job_file = store.join(format!("runs/{scene}/slurm/job.json"));
    let job = loop {
        if let Some(j) = std::fs::read_to_string(&job_file)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["job_id"].as_str().map(str::to_string))
        {
            break j;
        }
        assert!(start.elapsed() < Duration::from_secs(300), "no job was submitted");
        assert!(driver.try_wait().expect("poll").is_none(), "the driver ended before submitting");
        std::thread::sleep(Duration::from_millis(5));
    };
    // Cancel task 0 as soon as its worker has started; meanwhile count the running tasks.
    let mut most = 0;
    while record(&store, scene, 0, 6).is_none() {
        most = most.max(queued_running(&job));
        assert!(start.elapsed() < Duration::from_secs(300), "task 0 never started");
        std::thread::sleep(Duration::from_millis(5));
    }
    let cancel = Command::new("scancel").arg(format!("{job}_0")).output().expect("scancel");
    assert!(cancel.status.success(), "{}", text(&cancel));
    while driver.try_wait().expect("poll").is_none() {
        most = most.max(queued_running(&job));
        std::thread::sleep(Duration::from_millis(20));
    }
    let first = driver.wait_with_output().expect("driver output");
    assert!(most >= 4, "at most {most} array tasks ran at once");
    assert_eq!(first.status.code(), Some(1), "a cancelled task leaves points missing: {}", text(&first));
    assert!(text(&first).contains("shard 0/6"), "the error names the unfinished shard: {}", text(&first));
    let status = run_ok(crom_cmd(&store, &["status", scene]), "status");
    assert!(status.contains("shard 0/6: KILLED"), "{status}");

    // The batch script pins the planner's chunk size (tasks need not inherit the environment).
    let script = std::fs::read_to_string(store.join(format!("runs/{scene}/slurm/job.sh"))).expect("job.sh");
    assert!(script.contains(&format!("export CROM_BLOCK_COLUMNS={BLOCK_COLUMNS}\n")), "{script}");
    // Rerun as a site that exports no environment to its jobs: the tasks shard the same chunks.
    let mut again = with_blocks(crom_cmd(&store, &args));
    again.env("SBATCH_EXPORT", "NONE");
    let rerun = run_ok(again, "rerun");
    assert!(rerun.contains("submitted: 1 of 6 shards"), "only the cancelled shard is submitted again: {rerun}");
    assert!(rerun.contains("snapshots: 0 solved"), "{rerun}");
    assert_same_results(&reference(tmp.path(), scene), &store, "slurm array with a cancelled task vs a local run");
}
