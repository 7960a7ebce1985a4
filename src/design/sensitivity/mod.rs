//! `pidm sensitivity` (docs/design.md): which inputs a quantity's spread
//! across units of a design comes from, and how wide that spread is.
//!
//! The sample is Saltelli's scheme without second-order indices
//! (`crate::search::sobol`): base matrices A and B of N rows drawn from
//! the unit cube, and for each of the k inputs AB_i (A with column i from
//! B), N (k + 2) runs in SALib's row order; each coordinate becomes the
//! input's value by its distribution's quantile, truncated to the key's
//! valid range ([`spec::Input::value`]). Every run is one instance of the
//! scene with the inputs set, integrated in batches on one backend
//! (`crate::design::model`).
//!
//! A base row is dropped, for every output, when any of its k + 2 runs
//! failed or a scene rule refused it; a run that is "not steady" (status
//! 6) keeps its estimate. The indices are then conditioned on the rows
//! kept, and SENS.json says how many were dropped.

pub mod report;
pub mod spec;

use anyhow::Result;

use super::model::{Evaluation, Model};
use super::quantity::Quantity;
use crate::measurement::keeps_values;
use crate::search::distributions::{NOISE_WARNING, Spread, spread};
use crate::search::sobol::{self, Indices, RESAMPLES};

/// Runs per batch handed to the backend: large enough to fill every
/// worker, small enough that Ctrl-C is seen within a batch.
pub const BATCH_RUNS: usize = 4096;

/// The bootstrap's seed is the sample's, moved by this constant, so that
/// the resamples do not replay the sample's draws.
const BOOTSTRAP_SEED: u64 = 0x5eed_b007_5742_a9e1;

/// The study's runs: each sample's input values and its evaluation, in
/// SALib's row order.
pub struct Samples {
    /// The inputs' values per run.
    pub values: Vec<Vec<f64>>,
    pub runs: Vec<Evaluation>,
}

/// One output's analysis.
pub struct Analysis {
    pub quantity: Quantity,
    /// The Sobol' indices, or why there are none (an output that does not
    /// vary over the rows kept, too few rows kept).
    pub indices: std::result::Result<Indices, String>,
    /// The spread over the A and B rows kept (2 N' independent units of
    /// the design), or why there is none.
    pub spread: std::result::Result<Spread, String>,
}

impl Analysis {
    /// Whether the model's noise is above [`NOISE_WARNING`] of the
    /// output's variance.
    pub fn noisy(&self) -> bool {
        self.spread.as_ref().is_ok_and(|s| s.noise > NOISE_WARNING)
    }
}

/// The whole study.
pub struct Study {
    pub samples: Samples,
    /// Base rows, and those dropped because a run of theirs failed.
    pub rows: usize,
    pub dropped: usize,
    /// Runs that failed or were refused, and the first few reasons.
    pub failed: usize,
    pub reasons: Vec<String>,
    pub analyses: Vec<Analysis>,
}

/// Draws the sample and runs it: `n` base rows of the `inputs`, from
/// `seed`; `done(n)` reports finished runs.
pub fn run_samples(
    model: &mut Model,
    inputs: &[spec::Input],
    n: usize,
    seed: u64,
    done: &(dyn Fn(u64) + Sync),
) -> Result<Samples> {
    let k = inputs.len();
    let values: Vec<Vec<f64>> = sobol::saltelli_sample(n, k, seed)
        .into_iter()
        .map(|u| inputs.iter().zip(u).map(|(i, u)| i.value(u)).collect())
        .collect();
    let mut runs = Vec::with_capacity(values.len());
    for batch in values.chunks(BATCH_RUNS) {
        runs.extend(model.evaluate(batch, done)?);
    }
    Ok(Samples { values, runs })
}

/// Whether a run counts: it ran and its status keeps its values.
fn kept(run: &Evaluation) -> bool {
    run.as_ref().is_ok_and(|r| keeps_values(r.record.status))
}

/// Analyses the sample of `k` inputs for each output.
pub fn analyse(samples: Samples, k: usize, outputs: &[Quantity], seed: u64) -> Study {
    let width = k + 2;
    let rows = samples.runs.len() / width;
    let good: Vec<usize> = (0..rows)
        .filter(|r| samples.runs[r * width..(r + 1) * width].iter().all(kept))
        .collect();
    let failed = samples.runs.iter().filter(|r| !kept(r)).count();
    let mut reasons: Vec<String> = Vec::new();
    for run in &samples.runs {
        let why = match run {
            Err(why) => why.clone(),
            Ok(r) if !keeps_values(r.record.status) => format!(
                "status {} ({})",
                r.record.status,
                crate::measurement::status::Status::describe(r.record.status)
            ),
            Ok(_) => continue,
        };
        if reasons.len() < 5 && !reasons.contains(&why) {
            reasons.push(why);
        }
    }
    let analyses = outputs
        .iter()
        .map(|q| analyse_one(&samples, k, &good, q, seed))
        .collect();
    Study {
        samples,
        rows,
        dropped: rows - good.len(),
        failed,
        reasons,
        analyses,
    }
}

/// One output over the rows kept.
fn analyse_one(samples: &Samples, k: usize, good: &[usize], q: &Quantity, seed: u64) -> Analysis {
    let width = k + 2;
    let value = |i: usize| match &samples.runs[i] {
        Ok(run) => q.value(&run.record, run.frequency),
        Err(_) => unreachable!("only rows whose runs all ran are kept"),
    };
    let y: Vec<f64> = good
        .iter()
        .flat_map(|r| (r * width..(r + 1) * width).map(|i| value(i).value))
        .collect();
    let indices = if good.len() < 2 {
        Err(format!(
            "{} base rows kept of the sample: the estimators need 2 or more",
            good.len()
        ))
    } else {
        sobol::analyze(&y, k, RESAMPLES, seed ^ BOOTSTRAP_SEED).map_err(|e| e.to_string())
    };
    let ends: Vec<(f64, f64)> = good
        .iter()
        .flat_map(|r| [r * width, r * width + k + 1])
        .map(|i| {
            let v = value(i);
            (v.value, v.se)
        })
        .collect();
    let (ys, ses): (Vec<f64>, Vec<f64>) = ends.into_iter().unzip();
    Analysis {
        quantity: q.clone(),
        indices,
        spread: spread(&ys, &ses).map_err(|e| e.to_string()),
    }
}
