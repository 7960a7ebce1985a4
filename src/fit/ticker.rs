//! A fit's progress on stderr: a bar with the stage and the best misfit so
//! far for people, one JSON object per batch for programs (`{"stage":
//! "global", "batch": 12, "evaluations": 300, "best_chi2": 41.2}`), or
//! nothing.

use std::io::Write;

use indicatif::{ProgressBar, ProgressStyle};

use crate::progress::ProgressMode;

/// The progress of one fit.
pub struct Ticker {
    mode: ProgressMode,
    bar: Option<ProgressBar>,
    stage: &'static str,
    batch: u64,
}

impl Ticker {
    pub fn new(mode: ProgressMode) -> Ticker {
        let bar = (mode == ProgressMode::Bar).then(|| {
            let bar = ProgressBar::new_spinner();
            bar.set_style(
                ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}")
                    .expect("a valid template"),
            );
            bar
        });
        Ticker {
            mode,
            bar,
            stage: "global",
            batch: 0,
        }
    }

    /// A new stage: "global", "local" or "errors".
    pub fn stage(&mut self, stage: &'static str) {
        self.stage = stage;
    }

    /// One more batch done, with the evaluations so far and the best misfit.
    pub fn tick(&mut self, evaluations: usize, best_chi2: f64) {
        self.batch += 1;
        match self.mode {
            ProgressMode::Bar => {
                if let Some(bar) = &self.bar {
                    bar.set_message(format!(
                        "{} search, batch {}, {} candidates, best chi2 {:.5e}",
                        self.stage, self.batch, evaluations, best_chi2
                    ));
                    bar.tick();
                }
            }
            ProgressMode::Jsonl => {
                let line = serde_json::json!({
                    "stage": self.stage,
                    "batch": self.batch,
                    "evaluations": evaluations,
                    "best_chi2": best_chi2.is_finite().then_some(best_chi2),
                });
                let _ = writeln!(std::io::stderr().lock(), "{line}");
            }
            ProgressMode::Off => {}
        }
    }

    /// The fit ended: the bar is cleared.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
