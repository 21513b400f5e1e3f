//! Progress display: an indicatif bar per stage on a terminal, plain lines otherwise (CI, pipes).

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// Chooses bars or lines once per run.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    tty: bool,
    quiet: bool,
}

impl Progress {
    /// Bars when stdout is a terminal, lines otherwise; nothing when `quiet`.
    pub fn new(quiet: bool) -> Self {
        Self { tty: std::io::stdout().is_terminal(), quiet }
    }

    /// The same display with nothing printed (a stage run beside another, whose line is
    /// printed by [`line`](Self::line) when it is joined).
    pub fn silent(self) -> Self {
        Self { quiet: true, ..self }
    }

    /// The closing line of a stage that ran elsewhere: `name outcome (secs s)`.
    pub fn line(&self, name: &str, outcome: &str, secs: f64) {
        if !self.quiet {
            eprintln!("{name:>12} {outcome} ({secs:.2} s)");
        }
    }

    /// A line of its own about the run (not about one stage).
    pub fn note(&self, text: &str) {
        if !self.quiet {
            eprintln!("{text}");
        }
    }

    /// Start a stage of `len` items.
    pub fn stage(&self, name: &str, len: usize) -> StageProgress {
        let bar = if self.tty && !self.quiet {
            let bar = ProgressBar::new(len as u64);
            let style =
                ProgressStyle::with_template("{prefix:>12.bold} [{bar:32}] {pos}/{len} {msg} ({elapsed}, ETA {eta})")
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> ");
            bar.set_style(style);
            bar.set_prefix(name.to_string());
            bar.enable_steady_tick(Duration::from_millis(200));
            Some(bar)
        } else {
            None
        };
        StageProgress {
            name: name.to_string(),
            len,
            done: 0,
            bar,
            quiet: self.quiet,
            start: Instant::now(),
            last_line: Instant::now(),
        }
    }
}

/// Progress of one stage.
#[derive(Debug)]
pub struct StageProgress {
    name: String,
    len: usize,
    done: usize,
    bar: Option<ProgressBar>,
    quiet: bool,
    start: Instant,
    last_line: Instant,
}

impl StageProgress {
    /// One more item done.
    pub fn inc(&mut self, what: &str) {
        self.done += 1;
        if let Some(b) = &self.bar {
            b.set_message(what.to_string());
            b.inc(1);
        } else if !self.quiet && (self.last_line.elapsed() >= Duration::from_secs(2) || self.done == self.len) {
            // ETA from the mean time per item so far.
            let per_item = self.start.elapsed().as_secs_f64() / self.done as f64;
            let eta = per_item * self.len.saturating_sub(self.done) as f64;
            eprintln!("{:>12} {}/{} {what} (ETA {eta:.0} s)", self.name, self.done, self.len);
            self.last_line = Instant::now();
        }
    }

    /// Close the stage with a one-line outcome.
    pub fn finish(self, outcome: &str) {
        let secs = self.start.elapsed().as_secs_f64();
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
        if !self.quiet {
            eprintln!("{:>12} {outcome} ({secs:.2} s)", self.name);
        }
    }
}
