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
//! - **The repetitions in rounds.** The first timed run of every point comes first, in order.
//!   The further runs follow in rounds over the points that want them, so a
//!   point's runs are spread over the whole set instead of back to back. This machine slows
//!   down in phases of tens of milliseconds to seconds; back to back, all runs of a point fell
//!   into one such phase, and the median online query of one process read 44–64 µs where, in
//!   rounds, it read 45–46 µs (docs/design-notes.md#what-the-online-stage-times-and-reports).
//!   The number of runs and what is kept are the same; only their order changes.
//! - **Answers on every core, times alone, of a sample.** Every point is solved once, in
//!   parallel, and that run gives its answer. Then [`TIMED_POINTS`] of them, evenly spaced with
//!   both ends ([`timed_points`]; all of a smaller set), are timed alone by the rules above, their
//!   results dropped; the others' times are undefined (NaN, a Parquet null). A speed-up is the
//!   ratio of two medians over the same sample, so it needs the sample, not every point; timing
//!   every point of ironing-fine's 127, each first run with its errors computed on one core
//!   beside an idle one, was 5 of the whole run's 13 s
//!   (docs/design-notes.md#what-the-online-stage-times-and-reports).

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
/// Points of a set that are timed, at most ([`timed_points`]).
pub(crate) const TIMED_POINTS: usize = 16;

/// Which of `n` points are timed: all when `n <= TIMED_POINTS`, else [`TIMED_POINTS`] evenly
/// spaced with both ends (point `k (n - 1) / (TIMED_POINTS - 1)` for k = 0, 1, …;
/// `crom_schemas::scene::spaced_with_ends`).
pub(crate) fn timed_points(n: usize) -> Vec<bool> {
    let mut timed = vec![false; n];
    for k in crom_schemas::scene::spaced_with_ends(TIMED_POINTS, n) {
        timed[k] = true;
    }
    timed
}

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

/// Solve every item and time those of [`timed_points`] by the rules of this module. First every
/// item once, in parallel, each thread a contiguous run of items with one clone of `state`, each solve followed by
/// `keep(state, item, its result)`, whose value is kept; then the timed items alone
/// ([`time_alone`]), their results dropped. Returns, in the order of `items`, the kept value and
/// the fastest timed run in seconds (NaN for an untimed item). `solve` must give the same result
/// whatever ran before it, on whichever clone of `state`, which the online queries and
/// full-order solves do (they read only their model, their point and buffers they overwrite),
/// so the kept values depend neither on the sample nor on the thread count.
pub(crate) fn time_each<I, S, R, T>(
    items: impl IntoIterator<Item = I>,
    state: S,
    solve: impl Fn(&mut S, &I) -> R + Sync,
    solved: impl Fn(&R) -> bool,
    keep: impl Fn(&mut S, &I, R) -> T + Sync,
) -> Vec<(T, f64)>
where
    I: Sync,
    S: Clone + Send + Sync,
    T: Send,
{
    use rayon::prelude::*;
    let items: Vec<I> = items.into_iter().collect();
    // one contiguous run of items per thread, each with one clone of `state` (a reduced model
    // is costly to clone)
    let chunk = items.len().div_ceil(rayon::current_num_threads().max(1)).max(1);
    let kept: Vec<T> = items
        .par_chunks(chunk)
        .map(|run| {
            let mut st = state.clone();
            run.iter()
                .map(|item| {
                    let result = solve(&mut st, item);
                    keep(&mut st, item, result)
                })
                .collect::<Vec<T>>()
        })
        .collect::<Vec<Vec<T>>>()
        .into_iter()
        .flatten()
        .collect();
    let mut state = state;
    let seconds = time_sample(&items, |item| solve(&mut state, item), solved);
    kept.into_iter().zip(seconds).collect()
}

/// The fastest run of `solve(item)` at the items of [`timed_points`] ([`time_alone`]), NaN at
/// the others, which are not solved: one time per item, in the order of `items`.
pub(crate) fn time_sample<I, R>(items: &[I], solve: impl FnMut(&I) -> R, solved: impl Fn(&R) -> bool) -> Vec<f64> {
    let timed = timed_points(items.len());
    let sample: Vec<&I> = items.iter().zip(&timed).filter(|(_, t)| **t).map(|(i, _)| i).collect();
    let mut solve = solve;
    let mut seconds = time_alone(&sample, |item| solve(item), solved).into_iter();
    timed.iter().map(|&t| if t { seconds.next().unwrap_or(f64::NAN) } else { f64::NAN }).collect()
}

/// The fastest run of `solve(item)` at every item, each run alone on the calling thread, by the
/// rules of this module: the first runs in the order of `items`, then the further runs in
/// rounds; every result is dropped.
pub(crate) fn time_alone<I, R>(items: &[I], mut solve: impl FnMut(&I) -> R, solved: impl Fn(&R) -> bool) -> Vec<f64> {
    let mut clocks = Vec::with_capacity(items.len());
    for item in items {
        let t = Instant::now();
        let result = solve(item);
        let seconds = t.elapsed().as_secs_f64();
        clocks.push(Clock::first(seconds, solved(&result)));
        drop(result);
    }
    while clocks.iter().any(Clock::wants_more) {
        for (item, clock) in items.iter().zip(&mut clocks) {
            if clock.wants_more() {
                let t = Instant::now();
                let result = solve(item);
                clock.add(t.elapsed().as_secs_f64());
                drop(result);
            }
        }
    }
    clocks.into_iter().map(|c| c.best).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// How often `solve` ran per item in [`time_alone`], with each item's first run ok or not
    /// and taking `secs`.
    fn runs(cases: &[(bool, f64)]) -> Vec<usize> {
        let mut n = vec![0; cases.len()];
        let items: Vec<usize> = (0..cases.len()).collect();
        time_alone(
            &items,
            |&k| {
                n[k] += 1;
                std::thread::sleep(Duration::from_secs_f64(cases[k].1));
                cases[k].0
            },
            |&ok| ok,
        );
        n
    }

    /// The sample: all of a set of at most [`TIMED_POINTS`], else exactly [`TIMED_POINTS`] with
    /// both ends, evenly spaced (the gaps between timed points differ by at most one).
    #[test]
    fn the_timed_sample_is_evenly_spaced_with_both_ends() {
        for n in [0, 1, 11, TIMED_POINTS] {
            assert!(timed_points(n).iter().all(|&t| t), "{n}");
        }
        for n in [TIMED_POINTS + 1, 127, 1024] {
            let t = timed_points(n);
            let at: Vec<usize> = (0..n).filter(|&k| t[k]).collect();
            assert_eq!(at.len(), TIMED_POINTS, "{n}");
            assert_eq!((at[0], at[TIMED_POINTS - 1]), (0, n - 1), "{n}");
            let gaps: Vec<usize> = at.windows(2).map(|w| w[1] - w[0]).collect();
            let (lo, hi) = (gaps.iter().min().copied().unwrap_or(0), gaps.iter().max().copied().unwrap_or(0));
            assert!(hi - lo <= 1, "{n}: gaps {lo}..{hi}");
        }
    }

    /// Above [`TIMED_POINTS`] items: every item is solved once on the pool and kept (the kept
    /// values in item order), the untimed ones only then and with a NaN time, the timed ones
    /// again at least [`TIMING_REPEATS`] times with a finite time; and no timed run overlaps any
    /// other call, although the first runs share a pool of two threads.
    #[test]
    fn a_sample_is_timed_alone_and_every_item_is_kept() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        const N: usize = 100;
        let timed = timed_points(N);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool");
        let calls: Vec<AtomicUsize> = (0..N).map(|_| AtomicUsize::new(0)).collect();
        let (running, overlapped) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let out = pool.install(|| {
            time_each(
                0..N,
                0usize,
                |_, &k| {
                    // every call after an item's first is a timed run
                    let again = calls[k].fetch_add(1, Ordering::SeqCst) > 0;
                    let now = running.fetch_add(1, Ordering::SeqCst) + 1;
                    std::thread::sleep(Duration::from_micros(20));
                    if again && (now > 1 || running.load(Ordering::SeqCst) > 1) {
                        overlapped.fetch_add(1, Ordering::SeqCst);
                    }
                    running.fetch_sub(1, Ordering::SeqCst);
                    3 * k
                },
                |_| true,
                |_, _, r| r + 1,
            )
        });
        assert_eq!(overlapped.load(Ordering::SeqCst), 0, "a timed run overlapped another call");
        assert_eq!(out.iter().map(|(v, _)| *v).collect::<Vec<_>>(), (0..N).map(|k| 3 * k + 1).collect::<Vec<_>>());
        for k in 0..N {
            let n = calls[k].load(Ordering::SeqCst);
            if timed[k] {
                assert!(n > TIMING_REPEATS && out[k].1.is_finite() && out[k].1 >= 2e-5, "{k}: {n} {}", out[k].1);
            } else {
                assert!(n == 1 && out[k].1.is_nan(), "{k}: {n} {}", out[k].1);
            }
        }
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

    /// [`time_alone`]'s runs go one at a time, never two at once, even from a pool with two
    /// threads (a parallel loop would overlap the sleeping calls); the first runs come in order,
    /// the further runs in rounds over the set. Each call sleeps 10 µs, so three runs reach
    /// [`MIN_TIMED`] and there are exactly three rounds.
    #[test]
    fn first_runs_in_order_then_rounds_one_call_at_a_time() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        const { assert!(3.0 * 1e-5 >= MIN_TIMED && TIMING_REPEATS == 3) };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool");
        let (running, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let mut log = Vec::new();
        let items: Vec<usize> = (0..5).collect();
        let out = pool.install(|| {
            time_alone(
                &items,
                |&k| {
                    let now = running.fetch_add(1, Ordering::SeqCst) + 1;
                    most.fetch_max(now, Ordering::SeqCst);
                    std::thread::sleep(Duration::from_micros(10));
                    running.fetch_sub(1, Ordering::SeqCst);
                    log.push(k);
                },
                |_| true,
            )
        });
        assert_eq!(most.load(Ordering::SeqCst), 1, "two timed calls overlapped");
        let expected: Vec<usize> = (0..TIMING_REPEATS).flat_map(|_| 0..5).collect();
        assert_eq!(log, expected);
        assert!(out.iter().all(|s| *s >= 1e-5), "{out:?}");
    }
}
