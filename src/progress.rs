//! The progress of a run on stderr (`pidm run --progress`): the indicatif
//! bar for people, one JSON object per line for programs (the Python
//! package reads them), or nothing.
//!
//! A JSON line is `{"done": N, "total": N, "elapsed_s": S, "eta_s": S,
//! "instances_per_s": R}`: instances finished and in all (a resumed run
//! counts those of its checkpoint as done from the start), seconds since
//! the sweep began, the seconds still to go at this run's rate (`null`
//! until an instance has finished) and that rate. The first line comes as
//! the sweep starts (done may be 0), then at most one line every
//! [`JSON_INTERVAL_S`], and, when the sweep finished, a last line with
//! done == total. Other stderr lines (what pidm says about the run, an
//! error) are plain text and never start with `{`.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

/// How a run shows its progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ProgressMode {
    /// A bar with the rate and an estimate of the time left (drawn only
    /// when stderr is a terminal).
    Bar,
    /// One JSON object per line on stderr.
    Jsonl,
    /// Nothing.
    #[value(name = "none")]
    Off,
}

impl ProgressMode {
    /// The mode when none is asked for: the bar on a terminal, else nothing.
    pub fn default_for_stderr() -> ProgressMode {
        if std::io::stderr().is_terminal() {
            ProgressMode::Bar
        } else {
            ProgressMode::Off
        }
    }
}

/// The least time between two JSON lines [s] (the last line comes anyway).
pub const JSON_INTERVAL_S: f64 = 0.25;

/// The progress of one sweep, shown in one [`ProgressMode`].
pub struct Progress {
    kind: Kind,
}

enum Kind {
    Bar(ProgressBar),
    Json(JsonLines),
    Off,
}

struct JsonLines {
    total: u64,
    /// Instances done before the sweep began (from a checkpoint).
    before: u64,
    /// Instances done, `before` included.
    done: AtomicU64,
    started: Instant,
    /// When the last line was written [s since `started`]; the lock also
    /// keeps two lines from interleaving.
    last: Mutex<f64>,
}

impl JsonLines {
    /// The line of `done` of `total` instances.
    fn line_of(&self, done: u64, total: u64) -> String {
        let elapsed = self.started.elapsed().as_secs_f64();
        let new = done.saturating_sub(self.before);
        let rate = if elapsed > 0.0 {
            new as f64 / elapsed
        } else {
            0.0
        };
        let eta = if done >= total {
            Some(0.0)
        } else if new > 0 && rate > 0.0 {
            Some((total - done) as f64 / rate)
        } else {
            None
        };
        serde_json::json!({
            "done": done,
            "total": total,
            "elapsed_s": elapsed,
            "eta_s": eta,
            "instances_per_s": rate,
        })
        .to_string()
    }

    /// Writes a line now (`force`) or when the interval has passed.
    fn emit(&self, done: u64, force: bool) {
        self.emit_of(done, self.total, force);
    }

    /// [`JsonLines::emit`] of `done` of `total`.
    fn emit_of(&self, done: u64, total: u64, force: bool) {
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        let now = self.started.elapsed().as_secs_f64();
        if !force && now - *last < JSON_INTERVAL_S {
            return;
        }
        *last = now;
        let line = self.line_of(done, total);
        // A closed stderr must not end the run: the lines are advisory.
        let _ = writeln!(std::io::stderr().lock(), "{line}");
    }
}

impl Progress {
    /// Progress over `total` instances of which `before` are done already;
    /// the bar counts only the `total - before` this run computes.
    pub fn new(mode: ProgressMode, before: u64, total: u64) -> Progress {
        let kind = match mode {
            ProgressMode::Off => Kind::Off,
            ProgressMode::Bar => Kind::Bar(bar(total - before)),
            ProgressMode::Jsonl => {
                let lines = JsonLines {
                    total,
                    before,
                    done: AtomicU64::new(before),
                    started: Instant::now(),
                    last: Mutex::new(0.0),
                };
                lines.emit(before, true);
                Kind::Json(lines)
            }
        };
        Progress { kind }
    }

    /// `n` more instances finished. Ignored once a stop was asked for: a
    /// backend then reports the instances it abandoned as finished too.
    pub fn inc(&self, n: u64) {
        if crate::interrupt::interrupt_requested() {
            return;
        }
        match &self.kind {
            Kind::Bar(bar) => bar.inc(n),
            Kind::Json(lines) => {
                let done = lines.done.fetch_add(n, Ordering::Relaxed) + n;
                lines.emit(done.min(lines.total), false);
            }
            Kind::Off => {}
        }
    }

    /// The sweep finished: the bar is cleared, and JSON lines end with
    /// done == total.
    pub fn finish(&self) {
        match &self.kind {
            Kind::Bar(bar) => bar.finish_and_clear(),
            Kind::Json(lines) => lines.emit(lines.total, true),
            Kind::Off => {}
        }
    }

    /// A search that may end before its budget finished after `done`
    /// instances: the bar is cleared, and the last JSON line says `done` of
    /// `done` (the budget was a bound, not a count).
    pub fn finish_at(&self, done: u64) {
        match &self.kind {
            Kind::Bar(bar) => bar.finish_and_clear(),
            Kind::Json(lines) => lines.emit_of(done, done, true),
            Kind::Off => {}
        }
    }

    /// The sweep failed or was interrupted: the bar is cleared, and no
    /// further JSON line is written.
    pub fn abandon(&self) {
        if let Kind::Bar(bar) = &self.kind {
            bar.finish_and_clear();
        }
    }

    /// Ends the progress of a sweep with its result: finished, or abandoned
    /// with the error saying that the finished instances are kept in the
    /// checkpoint at `checkpoint` and `--resume` continues.
    pub fn conclude<T>(&self, result: anyhow::Result<T>, checkpoint: &Path) -> anyhow::Result<T> {
        match &result {
            Ok(_) => self.finish(),
            Err(_) => self.abandon(),
        }
        result.with_context(|| {
            format!(
                "the finished instances are kept in {}; the same command with --resume \
                 continues the run",
                checkpoint.display()
            )
        })
    }
}

fn bar(total: u64) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} instances ({per_sec}, eta {eta})",
        )
        .expect("valid progress template")
        .progress_chars("=> "),
    );
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(total: u64, before: u64) -> JsonLines {
        JsonLines {
            total,
            before,
            done: AtomicU64::new(before),
            started: Instant::now(),
            last: Mutex::new(0.0),
        }
    }

    #[test]
    fn a_json_line_has_the_documented_fields() {
        let l = lines(10, 4);
        let start: serde_json::Value = serde_json::from_str(&l.line_of(4, l.total)).unwrap();
        assert_eq!(start["done"], 4);
        assert_eq!(start["total"], 10);
        // No instance of this run finished yet: no estimate.
        assert!(start["eta_s"].is_null(), "{start}");
        assert!(start["elapsed_s"].as_f64().unwrap() >= 0.0);
        std::thread::sleep(std::time::Duration::from_millis(5));
        let later: serde_json::Value = serde_json::from_str(&l.line_of(7, l.total)).unwrap();
        let rate = later["instances_per_s"].as_f64().unwrap();
        assert!(rate > 0.0, "{later}");
        let eta = later["eta_s"].as_f64().unwrap();
        assert!((eta - 3.0 / rate).abs() < 1e-9 * eta.max(1.0), "{later}");
        let end: serde_json::Value = serde_json::from_str(&l.line_of(10, l.total)).unwrap();
        assert_eq!(end["eta_s"], 0.0);
    }
}
