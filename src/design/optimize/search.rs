//! `pidm optimize`'s search (docs/design.md, "How it searches").
//!
//! One objective: differential evolution over the free keys' box
//! (`crate::search::evolution`, feasibility first by Deb's rules) with
//! about 60 % of the budget, then a compass search on rotating directions
//! from its best (`crate::search::pattern`: it polls, it never takes a
//! derivative of a noisy objective) with the rest but what the
//! neighbourhood probe and OPT.png's scans need.
//!
//! Two objectives (a front): non-dominated sorting in the population,
//! GDE3 (`crate::search::front`), over the budget but the neighbourhood
//! probe. The front is the non-dominated set of every steady, feasible
//! run made.
//!
//! Every run is kept ([`Archive`]); the optimum is the best of all of
//! them, so no stage can lose what an earlier one found.

use anyhow::Result;

use super::spec::{Objective, OptimizeScene};
use crate::design::model::{Evaluation, Model};
use crate::design::quantity::{Side, Value};
use crate::laws::status::STATUS_OK;
use crate::search::evolution::{DeOptions, Fitness, Progress, differential_evolution};
use crate::search::front::{FrontOptions, Score, gde3};
use crate::search::pattern::{PatternOptions, compass_search};

/// Points along each free key through the optimum, for OPT.png.
pub const SCAN_POINTS: usize = 11;

/// The front members a round of [`Search::polish_front`] polls.
pub const POLISHED: usize = 16;

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
        let best = self.best(0).map_or(f64::NAN, |i| {
            objective_value(&self.spec.objectives[0], &self.archive.runs[i]).value
        });
        self.archive.progress.push((self.model.runs, best));
        Ok(runs)
    }

    /// The fitness of a run for objective `o` under the constraints.
    pub fn fitness(&self, o: usize, run: &Evaluation) -> Fitness {
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
        Fitness {
            cost: objective.sense.cost(value),
            violation,
        }
        .checked()
    }

    /// The archive's best run for objective `o`, if any ran.
    pub fn best(&self, o: usize) -> Option<usize> {
        let mut best: Option<(usize, Fitness)> = None;
        for (i, run) in self.archive.runs.iter().enumerate() {
            let f = self.fitness(o, run);
            if f.failed() {
                continue;
            }
            if best.is_none_or(|(_, b)| f.beats(&b)) {
                best = Some((i, f));
            }
        }
        best.map(|(i, _)| i)
    }

    /// One single-objective search of `o` with `budget` runs: evolution,
    /// then the compass search from its best.
    pub fn minimise(&mut self, o: usize, budget: usize) -> Result<()> {
        let (lo, hi) = self.bounds();
        let p = lo.len();
        let mut de = DeOptions::for_dimension(p, self.seed);
        de.stop_below = None;
        de.max_generations = ((budget * 3 / 5) / de.population).saturating_sub(1).max(1);
        let start = self.model.runs;
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Fitness>> {
            let runs = self.run(us)?;
            Ok(runs.iter().map(|r| self.fitness(o, r)).collect())
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
                Ok(runs.iter().map(|r| self.fitness(o, r)).collect())
            };
            compass_search(&mut eval, &found.best, &lo, &hi, &opts)?;
        }
        Ok(())
    }

    /// A front with `budget` runs: each objective alone first (a fifth of
    /// the budget each, [`Search::minimise`]: the front's ends, which a
    /// population spread along the front reaches last), then GDE3 over
    /// both with 3/10, then [`Search::polish_front`] with the rest.
    pub fn front_search(&mut self, budget: usize) -> Result<()> {
        let start = self.model.runs;
        self.minimise(0, budget / 5)?;
        self.minimise(1, budget / 5)?;
        let (lo, hi) = self.bounds();
        let opts = FrontOptions::for_dimension(lo.len(), budget * 3 / 10, self.seed);
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Score>> {
            let runs = self.run(us)?;
            Ok(runs.iter().map(|r| self.score(r)).collect())
        };
        gde3(&mut eval, &lo, &hi, &opts)?;
        let used = self.model.runs - start;
        self.polish_front(budget.saturating_sub(used))
    }

    /// A compass search of the front: each round polls, along each key
    /// both ways, the [`POLISHED`] front members with the largest steps
    /// (a twentieth of each key's range at first, clamped to the bounds,
    /// so a front on a bound is reached); a member none of whose polls
    /// dominates it halves its step, and its polls take the step it ends
    /// with (a poll that joins the front goes on from there, not from the
    /// start). Ends when the budget or every step (below a thousandth) is
    /// spent.
    fn polish_front(&mut self, budget: usize) -> Result<()> {
        let (lo, hi) = self.bounds();
        let p = lo.len();
        let start = self.model.runs;
        let mut steps: std::collections::HashMap<usize, f64> = Default::default();
        loop {
            let mut members: Vec<(usize, f64)> = self
                .front()
                .into_iter()
                .map(|i| (i, *steps.entry(i).or_insert(0.05)))
                .filter(|&(_, s)| s >= 1e-3)
                .collect();
            members.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            members.truncate(POLISHED.min((budget + start - self.model.runs) / (2 * p)));
            if members.is_empty() || crate::interrupt::interrupt_requested() {
                return Ok(());
            }
            let mut polls = Vec::new();
            for &(i, step) in &members {
                let at: Vec<f64> = (0..p)
                    .map(|j| self.spec.free[j].coordinate(self.archive.values[i][j]))
                    .collect();
                for j in 0..p {
                    for sign in [-1.0, 1.0] {
                        let mut u = at.clone();
                        u[j] = (u[j] + sign * step * (hi[j] - lo[j])).clamp(lo[j], hi[j]);
                        polls.push(u);
                    }
                }
            }
            let first = self.archive.runs.len();
            self.run(&polls)?;
            for (m, &(i, step)) in members.iter().enumerate() {
                let centre = self.score(&self.archive.runs[i]);
                let polled = first + 2 * p * m..first + 2 * p * (m + 1);
                let improved = polled
                    .clone()
                    .any(|k| self.score(&self.archive.runs[k]).dominates(&centre));
                let next = if improved { step } else { 0.5 * step };
                for k in polled.chain([i]) {
                    steps.insert(k, next);
                }
            }
        }
    }

    /// A run's costs on both objectives and its violation.
    fn score(&self, run: &Evaluation) -> Score {
        let first = self.fitness(0, run);
        if first.failed() {
            return Score::FAILED;
        }
        let second = &self.spec.objectives[1];
        let v = objective_value(second, run).value;
        Score {
            costs: [first.cost, second.sense.cost(v)],
            violation: first.violation,
        }
    }

    /// The non-dominated set of the steady, feasible runs on both
    /// objectives, ordered by the second; indices into the archive. Runs
    /// whose objectives agree to 1e-9 (relative) count once: the first.
    pub fn front(&self) -> Vec<usize> {
        let feasible: Vec<(usize, [f64; 2])> = (0..self.archive.runs.len())
            .filter(|&i| self.fitness(0, &self.archive.runs[i]).violation == 0.0)
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
            let same = |d: [f64; 2]| {
                (0..2).all(|k| (c[k] - d[k]).abs() <= 1e-9 * c[k].abs().max(d[k].abs()))
            };
            if !beaten && !front.iter().any(|&(_, d)| same(d)) {
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
