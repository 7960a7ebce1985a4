//! `pidm optimize`'s search (docs/design.md, "How it searches").
//!
//! One objective: differential evolution over the free keys' box
//! (`crate::search::evolution`, feasibility first by Deb's rules) with
//! about 60 % of the budget, then a compass search on rotating directions
//! from its best (`crate::search::pattern`: it polls, it never takes a
//! derivative of a noisy objective) with the rest but what the
//! neighbourhood probe and OPT.png's scans need.
//!
//! Two objectives (a front): a series of ε-constraint problems. The first
//! objective (the one maximized) alone, the second alone, then the first
//! with the second bounded by each of `front_points - 2` levels evenly
//! between the two extremes; each with an equal share of the budget. The
//! front is the non-dominated set of every steady, feasible run made.
//!
//! Every run is kept ([`Archive`]); the optimum is the best of all of
//! them, so no stage can lose what an earlier one found.

use anyhow::Result;

use super::spec::{Objective, OptimizeScene, Sense};
use crate::design::model::{Evaluation, Model};
use crate::design::quantity::{Side, Value};
use crate::laws::status::STATUS_OK;
use crate::search::evolution::{DeOptions, Fitness, Progress, differential_evolution};
use crate::search::pattern::{PatternOptions, compass_search};

/// Points along each free key through the optimum, for OPT.png.
pub const SCAN_POINTS: usize = 11;

/// The neighbourhood probe's offset, a fraction of each key's range.
pub const PROBE: f64 = 0.01;

/// Every run made: the keys' values and what came of them.
#[derive(Default)]
pub struct Archive {
    pub values: Vec<Vec<f64>>,
    pub runs: Vec<Evaluation>,
    /// After each batch: the runs so far and the best feasible first
    /// objective (NaN before there is one).
    pub progress: Vec<(usize, f64)>,
}

/// An ε-constraint on the second objective: it may be at most `eps`
/// (minimized) or at least `eps` (maximized).
#[derive(Clone, Copy, Debug)]
pub struct Epsilon {
    pub eps: f64,
}

/// The search over a model.
pub struct Search<'s, 'm, 'a> {
    pub spec: &'s OptimizeScene,
    pub model: &'m mut Model<'a>,
    pub archive: Archive,
    pub seed: u64,
    pub done: &'s (dyn Fn(u64) + Sync),
}

impl Search<'_, '_, '_> {
    /// The keys' values at search coordinates `u`.
    pub fn values(&self, u: &[f64]) -> Vec<f64> {
        self.spec
            .free
            .iter()
            .zip(u)
            .map(|(f, &u)| f.value(u))
            .collect()
    }

    /// The search box in coordinates.
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let b: Vec<[f64; 2]> = self
            .spec
            .free
            .iter()
            .map(|f| f.coordinate_bounds())
            .collect();
        (
            b.iter().map(|b| b[0]).collect(),
            b.iter().map(|b| b[1]).collect(),
        )
    }

    /// Runs candidates at coordinates `us`, archiving them.
    pub fn run(&mut self, us: &[Vec<f64>]) -> Result<Vec<Evaluation>> {
        let values: Vec<Vec<f64>> = us.iter().map(|u| self.values(u)).collect();
        let runs = self.model.evaluate(&values, self.done)?;
        self.archive.values.extend(values);
        self.archive.runs.extend(runs.iter().cloned());
        let best = self.best(0, None).map_or(f64::NAN, |i| {
            objective_value(&self.spec.objectives[0], &self.archive.runs[i]).value
        });
        self.archive.progress.push((self.model.runs, best));
        Ok(runs)
    }

    /// The fitness of a run for objective `o`, under the constraints and
    /// `eps` on the other objective.
    pub fn fitness(&self, o: usize, eps: Option<Epsilon>, run: &Evaluation) -> Fitness {
        let Ok(r) = run else {
            return Fitness::FAILED;
        };
        if r.record.status != STATUS_OK {
            return Fitness::FAILED;
        }
        let objective = &self.spec.objectives[o];
        let value = objective.quantity.value(&r.record, r.frequency).value;
        let mut violation = 0.0;
        for c in &self.spec.constraints {
            let slack = c.slack(&r.record, r.frequency);
            violation += (-slack.value).max(0.0) / scale(c, &r.record, r.frequency);
        }
        if let Some(Epsilon { eps }) = eps {
            let other = &self.spec.objectives[1 - o];
            let v = other.quantity.value(&r.record, r.frequency).value;
            let over = match other.sense {
                Sense::Minimize => v - eps,
                Sense::Maximize => eps - v,
            };
            violation += over.max(0.0) / eps.abs().max(f64::MIN_POSITIVE);
        }
        Fitness {
            cost: objective.sense.cost(value),
            violation,
        }
        .checked()
    }

    /// The archive's best run for objective `o` (under `eps`), if any ran.
    pub fn best(&self, o: usize, eps: Option<Epsilon>) -> Option<usize> {
        let mut best: Option<(usize, Fitness)> = None;
        for (i, run) in self.archive.runs.iter().enumerate() {
            let f = self.fitness(o, eps, run);
            if f.failed() {
                continue;
            }
            if best.is_none_or(|(_, b)| f.beats(&b)) {
                best = Some((i, f));
            }
        }
        best.map(|(i, _)| i)
    }

    /// One single-objective search of `o` under `eps` with `budget` runs:
    /// evolution, then the compass search from its best.
    pub fn minimise(&mut self, o: usize, eps: Option<Epsilon>, budget: usize) -> Result<()> {
        let (lo, hi) = self.bounds();
        let p = lo.len();
        let mut de = DeOptions::for_dimension(p, self.seed);
        de.stop_below = None;
        de.max_generations = ((budget * 3 / 5) / de.population).saturating_sub(1).max(1);
        let start = self.model.runs;
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Fitness>> {
            let runs = self.run(us)?;
            Ok(runs.iter().map(|r| self.fitness(o, eps, r)).collect())
        };
        let found = differential_evolution(&mut eval, &lo, &hi, &de, &mut |_, _, _| {
            if crate::interrupt::interrupt_requested() {
                Progress::Stop
            } else {
                Progress::Continue
            }
        })?;
        let used = self.model.runs - start;
        let rest = budget.saturating_sub(used);
        if rest > 2 * p {
            let opts = PatternOptions {
                initial_step: 0.05,
                tolerance: 1e-3,
                max_evaluations: rest,
                seed: self.seed,
            };
            let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Fitness>> {
                let runs = self.run(us)?;
                Ok(runs.iter().map(|r| self.fitness(o, eps, r)).collect())
            };
            compass_search(&mut eval, &found.best, &lo, &hi, &opts)?;
        }
        Ok(())
    }

    /// The non-dominated set of the steady, feasible runs on both
    /// objectives, ordered by the second; indices into the archive.
    pub fn front(&self) -> Vec<usize> {
        let feasible: Vec<(usize, [f64; 2])> = (0..self.archive.runs.len())
            .filter(|&i| self.fitness(0, None, &self.archive.runs[i]).violation == 0.0)
            .map(|i| {
                let run = &self.archive.runs[i];
                let cost = |o: usize| {
                    let obj = &self.spec.objectives[o];
                    obj.sense.cost(objective_value(obj, run).value)
                };
                (i, [cost(0), cost(1)])
            })
            .collect();
        let dominated =
            |a: [f64; 2], b: [f64; 2]| b[0] <= a[0] && b[1] <= a[1] && (b[0] < a[0] || b[1] < a[1]);
        let mut front: Vec<(usize, [f64; 2])> = Vec::new();
        for &(i, c) in &feasible {
            let beaten = feasible.iter().any(|&(_, d)| dominated(c, d));
            if !beaten && !front.iter().any(|&(_, d)| d == c) {
                front.push((i, c));
            }
        }
        front.sort_by(|a, b| a.1[1].total_cmp(&b.1[1]));
        front.into_iter().map(|(i, _)| i).collect()
    }
}

/// An objective's value in a run that ran.
pub fn objective_value(o: &Objective, run: &Evaluation) -> Value {
    match run {
        Ok(r) => o.quantity.value(&r.record, r.frequency),
        Err(_) => Value {
            value: f64::NAN,
            se: f64::NAN,
        },
    }
}

/// What a constraint's violation is measured against: its number's size,
/// or, between two quantities, their mean size (so that constraints of
/// different units add up to a violation Deb's rules can rank).
fn scale(
    c: &crate::design::quantity::Constraint,
    record: &crate::sweep::Record,
    frequency: [f64; 2],
) -> f64 {
    let number = [&c.left, &c.right].into_iter().find_map(|s| match s {
        Side::Number(v) if *v != 0.0 => Some(v.abs()),
        _ => None,
    });
    number.unwrap_or_else(|| {
        let size: f64 = c
            .quantities()
            .map(|q| q.value(record, frequency).value.abs())
            .sum();
        size.max(f64::MIN_POSITIVE)
    })
}
