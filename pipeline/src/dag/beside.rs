//! One worker thread beside the executor's main loop ([`super::execute`]).
//!
//! Light stages that need one core and no numerics (the views: HDF5 metadata over stored
//! columns) are handed to this worker as soon as their inputs exist; the main loop goes on
//! with the heavy stages, whose sequential parts leave a core idle. The jobs run one after the
//! other on the one thread, in the order they were handed over, so at most one of them holds
//! memory at a time (several threads would each keep their own allocator arena and HDF5
//! working set). A job is waited for ([`Beside::wait_for`]) before any node that reads its
//! artifact and at the end ([`Beside::finish`]); every artifact is the same as when the jobs
//! run in the main loop, only the order of the progress lines changes.

use std::sync::mpsc::{channel, Receiver, Sender};
use std::thread::{Scope, ScopedJoinHandle};
use std::time::Instant;

use super::ctx::Ctx;
use super::plan::Node;
use crate::cache::Key;
use crate::error::CromError;

/// A job's work: its stage run with its own context.
pub(super) type Work<'p, 'a> = Box<dyn FnOnce(&mut Ctx<'a>) -> Result<Key, CromError> + Send + 'p>;

/// What a finished job hands back: its stage result, its context and its wall time (seconds).
pub(super) type Done<'a> = (Result<Key, CromError>, Ctx<'a>, f64);

struct Job<'p, 'a> {
    work: Work<'p, 'a>,
    ctx: Ctx<'a>,
    done: Sender<Done<'a>>,
}

/// The worker and the jobs handed to it that have not been waited for.
pub(super) struct Beside<'scope, 'p, 'a> {
    scope: &'scope Scope<'scope, 'p>,
    jobs: Option<Sender<Job<'p, 'a>>>,
    worker: Option<ScopedJoinHandle<'scope, ()>>,
    pending: Vec<(&'p Node, Receiver<Done<'a>>)>,
}

impl<'scope, 'p, 'a: 'p> Beside<'scope, 'p, 'a> {
    /// No worker yet (it starts with the first job).
    pub(super) fn new(scope: &'scope Scope<'scope, 'p>) -> Self {
        Self { scope, jobs: None, worker: None, pending: Vec::new() }
    }

    /// Hand `node`'s `work` to the worker, to run with `ctx` (a context from
    /// [`Ctx::beside`]).
    pub(super) fn hand(&mut self, node: &'p Node, ctx: Ctx<'a>, work: Work<'p, 'a>) {
        if self.jobs.is_none() {
            let (tx, rx) = channel::<Job<'p, 'a>>();
            self.worker = Some(self.scope.spawn(move || {
                for mut job in rx {
                    let start = Instant::now();
                    let key = (job.work)(&mut job.ctx);
                    // The receiver is gone only when the main loop has stopped on an error.
                    let _ = job.done.send((key, job.ctx, start.elapsed().as_secs_f64()));
                }
            }));
            self.jobs = Some(tx);
        }
        let (done, rx) = channel();
        if let Some(jobs) = &self.jobs {
            // A send fails only when the worker has panicked: `wait_for` resumes that panic.
            let _ = jobs.send(Job { work, ctx, done });
        }
        self.pending.push((node, rx));
    }

    /// The pending jobs among the nodes named `names`, waited for in the order they were handed
    /// over.
    pub(super) fn wait_for(&mut self, names: &[String]) -> Vec<(&'p Node, Done<'a>)> {
        let mut out = Vec::new();
        while let Some(i) = self.pending.iter().position(|(n, _)| names.contains(&n.name)) {
            let (node, rx) = self.pending.remove(i);
            out.push((node, self.receive(&rx)));
        }
        out
    }

    /// Every pending job, the worker kept for later ones.
    pub(super) fn drain(&mut self) -> Vec<(&'p Node, Done<'a>)> {
        let pending = std::mem::take(&mut self.pending);
        pending.into_iter().map(|(node, rx)| (node, self.receive(&rx))).collect()
    }

    /// Every pending job, then the worker's end.
    pub(super) fn finish(mut self) -> Vec<(&'p Node, Done<'a>)> {
        let pending = std::mem::take(&mut self.pending);
        let out = pending.into_iter().map(|(node, rx)| (node, self.receive(&rx))).collect();
        self.jobs = None;
        if let Some(worker) = self.worker.take() {
            worker.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        }
        out
    }

    /// A job's result; a panic on the worker goes on as a panic here.
    fn receive(&mut self, rx: &Receiver<Done<'a>>) -> Done<'a> {
        match rx.recv() {
            Ok(done) => done,
            Err(_) => {
                self.jobs = None;
                let worker = self.worker.take().expect("a job was handed to a started worker");
                match worker.join() {
                    Err(panic) => std::panic::resume_unwind(panic),
                    Ok(()) => unreachable!("the worker answers every job it receives before it ends"),
                }
            }
        }
    }
}
