//! How the stages that state speed-ups time their solves ([`time_each`]): the full-order solves
//! ([`super::rom::fom_seconds`]), the online queries of the trade-off and of every online
//! approximation.
//!
//! - **Alone.** One solve at a time, on the calling thread, with nothing beside it (the
//!   executor runs no job beside a stage that times solves). Two solves timed side by side on
//!   the two cores of the machine crom is measured on slowed the online query by about 40 % and
//!   not the full-order solve, so a speed-up measured that way was a property of the pairing
//!   (docs/design-notes.md#what-the-online-stage-times-and-reports).
//! - **The fastest of repeated runs.** A solve faster than [`REPEAT_BELOW`] is run
//!   [`TIMING_REPEATS`] times (more while its runs add up to less than [`MIN_TIMED`], at most
//!   [`MAX_REPEATS`]) and its fastest run is its time. A solve that fails (a query that does not
//!   converge, a full-order solve that errs) is timed by its one run: no speed-up target reads
//!   a failure's time, and repeating the paper algorithm's failures, most of which run to the
//!   iteration cap, tripled that stage.
//! - **The repetitions in rounds.** The first run of every point comes first, in order; it
//!   gives the result. The further runs follow in rounds over the points that want them, so a
//!   point's runs are spread over the whole set instead of back to back. This machine slows
//!   down in phases of tens of milliseconds to seconds; back to back, all runs of a point fell
//!   into one such phase, and the median online query of one process read 44–64 µs where, in
//!   rounds, it read 45–46 µs (docs/design-notes.md#what-the-online-stage-times-and-reports).
//!   The number of runs and what is kept are the same; only their order changes.

use std::time::Instant;

/// Timing repetitions of a solve whose first run took less than [`REPEAT_BELOW`] seconds (the
/// minimum is kept: short solves are otherwise dominated by noise, cold caches first).
pub(crate) const TIMING_REPEATS: usize = 3;
/// Solves slower than this are timed once. It lies well above every shipped scene's
/// full-order solve on the machines crom has been measured on (ironing-fine's takes 3–5 ms on
/// a fast one and 8–18 ms on one about 2.5 times slower), so that both sides of each speed-up
/// are the minimum of repeated runs: with a bound of 2 ms, and again with 10 ms on the slower
/// machine, the full-order side was partly one cold run, slower than the minimum of three,
/// which inflated the speed-ups (docs/design-notes.md#what-the-online-stage-times-and-reports).
pub(crate) const REPEAT_BELOW: f64 = 0.1;
/// A query faster than this in all is repeated beyond [`TIMING_REPEATS`] until its runs add up
/// to it (at most [`MAX_REPEATS`] runs): a microsecond solve (the rope's) timed three times is
/// at the mercy of the first run's cold caches and the clock's granularity; the full-order
/// solves it is compared with are timed by the same rule.
pub(crate) const MIN_TIMED: f64 = 2e-5;
/// Cap on the repetitions of [`MIN_TIMED`].
pub(crate) const MAX_REPEATS: usize = 1000;

/// The runs of one point so far.
struct Clock {
    best: f64,
    total: f64,
    runs: usize,
    /// Whether the first run asks for more ([`REPEAT_BELOW`], a success).
    repeat: bool,
}

impl Clock {
    fn first(seconds: f64, solved: bool) -> Self {
        Self { best: seconds, total: seconds, runs: 1, repeat: solved && seconds < REPEAT_BELOW }
    }

    fn add(&mut self, seconds: f64) {
        self.best = self.best.min(seconds);
        self.total += seconds;
        self.runs += 1;
    }

    fn wants_more(&self) -> bool {
        let enough = self.runs >= TIMING_REPEATS && (self.total >= MIN_TIMED || self.runs >= MAX_REPEATS);
        self.repeat && !enough
    }
}

/// Time `solve(state, item)` at every item by the rules of this module: the first runs in the
/// order of `items`, each followed (untimed) by `keep(state, item, its result)`, whose value is
/// kept; then the further runs in rounds, their results dropped. Returns, in the order of
/// `items`, the kept value and the fastest run in seconds. One `state` (a work buffer) serves
/// every call; `solve` must give the same result whatever ran before it, which the online
/// queries and full-order solves do (they read only their model, their point and buffers they
/// overwrite).
pub(crate) fn time_each<I, S, R, T>(
    items: impl IntoIterator<Item = I>,
    mut state: S,
    mut solve: impl FnMut(&mut S, &I) -> R,
    solved: impl Fn(&R) -> bool,
    mut keep: impl FnMut(&mut S, &I, R) -> T,
) -> Vec<(T, f64)> {
    let items: Vec<I> = items.into_iter().collect();
    let mut kept = Vec::with_capacity(items.len());
    let mut clocks = Vec::with_capacity(items.len());
    for item in &items {
        let t = Instant::now();
        let result = solve(&mut state, item);
        let seconds = t.elapsed().as_secs_f64();
        clocks.push(Clock::first(seconds, solved(&result)));
        kept.push(keep(&mut state, item, result));
    }
    while clocks.iter().any(Clock::wants_more) {
        for (item, clock) in items.iter().zip(&mut clocks) {
            if clock.wants_more() {
                let t = Instant::now();
                let result = solve(&mut state, item);
                clock.add(t.elapsed().as_secs_f64());
                drop(result);
            }
        }
    }
    kept.into_iter().zip(clocks).map(|(k, c)| (k, c.best)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// How often `solve` ran per item, with each item's first run ok or not and taking `secs`.
    fn runs(cases: &[(bool, f64)]) -> Vec<usize> {
        let mut n = vec![0; cases.len()];
        time_each(
            0..cases.len(),
            (),
            |(), &k| {
                n[k] += 1;
                std::thread::sleep(Duration::from_secs_f64(cases[k].1));
                cases[k].0
            },
            |&ok| ok,
            |(), _, _| (),
        );
        n
    }

    /// A fast query that succeeds is timed [`TIMING_REPEATS`] times at least, and a slow one
    /// once; a failure is not repeated, whatever its time.
    #[test]
    fn only_fast_successes_are_repeated() {
        // ironing-fine's full-order solve on a slow machine (8–18 ms) is repeated
        let n = runs(&[(true, 0.0), (true, 0.02), (true, REPEAT_BELOW), (false, 0.0)]);
        assert!(n[0] >= TIMING_REPEATS && n[1] >= TIMING_REPEATS, "{n:?}");
        assert_eq!((n[2], n[3]), (1, 1), "{n:?}");
    }

    /// The calls run one at a time, never two at once, even from a pool with two threads (a
    /// parallel loop would overlap the sleeping calls); the first runs come in order, each
    /// followed by its `keep`, which sees that run's result; the further runs come in rounds
    /// over the set. Each call sleeps 10 µs, so three runs reach [`MIN_TIMED`] and there are
    /// exactly three rounds.
    #[test]
    fn first_runs_in_order_then_rounds_one_call_at_a_time() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        const { assert!(3.0 * 1e-5 >= MIN_TIMED && TIMING_REPEATS == 3) };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool");
        let (running, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let log = std::sync::Mutex::new(Vec::new());
        let out = pool.install(|| {
            time_each(
                0..5usize,
                0usize,
                |calls, &k| {
                    let now = running.fetch_add(1, Ordering::SeqCst) + 1;
                    most.fetch_max(now, Ordering::SeqCst);
                    std::thread::sleep(Duration::from_micros(10));
                    running.fetch_sub(1, Ordering::SeqCst);
                    *calls += 1;
                    log.lock().expect("log").push(('s', k));
                    (k, *calls)
                },
                |_| true,
                |_, &k, result| {
                    log.lock().expect("log").push(('k', k));
                    result
                },
            )
        });
        assert_eq!(most.load(Ordering::SeqCst), 1, "two timed calls overlapped");
        let firsts: Vec<(usize, usize)> = out.iter().map(|(r, _)| *r).collect();
        assert_eq!(firsts, (0..5).map(|k| (k, k + 1)).collect::<Vec<_>>(), "keep sees the first run");
        let mut expected: Vec<(char, usize)> = (0..5).flat_map(|k| [('s', k), ('k', k)]).collect();
        for _ in 1..TIMING_REPEATS {
            expected.extend((0..5).map(|k| ('s', k)));
        }
        assert_eq!(log.into_inner().expect("log"), expected);
        assert!(out.iter().all(|(_, s)| *s >= 1e-5), "{out:?}");
    }
}
