//! Differential evolution: the global stage of `pidm fit` (a weighted
//! least-squares cost) and of any search for the best of a scalar cost
//! under constraints.
//!
//! Points live in the search space (`u` coordinates) inside box bounds. A
//! candidate's [`Fitness`] is a cost of any sign and a constraint violation;
//! candidates are ranked feasibility first (Deb's rules, [`Fitness::beats`]).
//! Candidates are evaluated in batches through a callback so that an
//! expensive simulation can run a whole generation together: the initial
//! population is one batch and every later generation is exactly one batch.
//! Everything random comes from a seeded SplitMix64, so a seed reproduces a
//! run bit for bit.

use super::rng::SplitMix64;
use anyhow::{Result, bail, ensure};

/// What a candidate scored: the cost to minimise (any sign) and how far it
/// breaks its constraints (0 where it keeps them all).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fitness {
    pub cost: f64,
    pub violation: f64,
}

impl Fitness {
    /// A candidate that keeps every constraint.
    pub fn feasible(cost: f64) -> Fitness {
        Fitness {
            cost,
            violation: 0.0,
        }
    }

    /// A candidate whose evaluation failed: worse than any other.
    pub const FAILED: Fitness = Fitness {
        cost: f64::INFINITY,
        violation: f64::INFINITY,
    };

    /// A least-squares cost, `Σ r_i²`, of keeping residuals `r`: failed
    /// where they are missing or the sum is not finite.
    pub fn squares(r: Option<&[f64]>) -> Fitness {
        let cost = r.map_or(f64::INFINITY, |r| r.iter().map(|x| x * x).sum());
        if cost.is_finite() {
            Fitness::feasible(cost)
        } else {
            Fitness::FAILED
        }
    }

    /// The fitness as a search ranks it: failed where the cost or the
    /// violation is not finite or the violation is below 0.
    pub fn checked(self) -> Fitness {
        let ok = self.cost.is_finite() && self.violation.is_finite() && self.violation >= 0.0;
        if ok { self } else { Fitness::FAILED }
    }

    /// Whether the evaluation failed.
    pub fn failed(&self) -> bool {
        self.violation.is_infinite()
    }

    /// Deb's rules: a feasible candidate beats an infeasible one; of two
    /// feasible ones the lower cost wins; of two infeasible ones the
    /// smaller violation. Strict: neither beats an equal.
    pub fn beats(&self, other: &Fitness) -> bool {
        match (self.violation == 0.0, other.violation == 0.0) {
            (true, true) => self.cost < other.cost,
            (true, false) => true,
            (false, true) => false,
            (false, false) => self.violation < other.violation,
        }
    }
}

/// Fitness of a batch of candidates, each a point in the search space (u
/// coordinates).
pub type Batch<'a> = dyn FnMut(&[Vec<f64>]) -> anyhow::Result<Vec<Fitness>> + 'a;

/// Settings of [`differential_evolution`].
#[derive(Debug, Clone, PartialEq)]
pub struct DeOptions {
    /// Candidates per generation, i.e. the size of each batch (at least 4).
    pub population: usize,
    /// Generations after the initial population (each one batch).
    pub max_generations: usize,
    /// Seed of the SplitMix64 generator; the same seed gives the same run.
    pub seed: u64,
    /// Stop when the relative cost spread `(worst - best) / (|best| + tiny)` of the
    /// population falls below this (dimensionless); an infeasible member counts as an
    /// infinite cost.
    pub tolerance: f64,
    /// Stop when the best feasible cost falls below this (a least-squares fit: 1e-300,
    /// a perfect fit; a cost of any sign: none).
    pub stop_below: Option<f64>,
    /// Mutation scale F (dimensionless); each trial dithers it uniformly in `[F/2, 3F/2)`.
    pub f: f64,
    /// Crossover probability CR in `[0, 1]`: chance that a coordinate comes from the mutant.
    pub cr: f64,
}

impl DeOptions {
    /// Defaults for a least-squares fit of `p` parameters: population
    /// `clamp(8 p, 12, 40)`, 40 generations, tolerance 1e-3, F 0.7, CR 0.9, stop below
    /// a cost of 1e-300. Sized for a few hundred to ~1600 evaluations, enough to find
    /// the basin that Levenberg-Marquardt then polishes.
    pub fn for_dimension(p: usize, seed: u64) -> DeOptions {
        DeOptions {
            population: (8 * p).clamp(12, 40),
            max_generations: 40,
            seed,
            tolerance: 1e-3,
            stop_below: Some(1e-300),
            f: 0.7,
            cr: 0.9,
        }
    }
}

/// Outcome of [`differential_evolution`].
#[derive(Debug, Clone, PartialEq)]
pub struct DeResult {
    /// Best candidate found (u coordinates, inside the bounds).
    pub best: Vec<f64>,
    /// Cost of `best` (for a fit: the sum of squared residuals).
    pub best_cost: f64,
    /// How far `best` breaks its constraints: 0 where it keeps them.
    pub best_violation: f64,
    /// Generations run after the initial population.
    pub generations: usize,
    /// Candidates evaluated in all batches, the initial population included.
    pub evaluations: usize,
    /// Candidates whose evaluation failed ([`Fitness::FAILED`]).
    pub failed: usize,
}

/// Answer of the per-generation callback: `Stop` ends the search early (e.g. on Ctrl-C)
/// and returns the best candidate found so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// Keep searching.
    Continue,
    /// Stop now and return the best so far.
    Stop,
}

/// Counts of evaluated and failed candidates.
#[derive(Default)]
struct Tally {
    evaluations: usize,
    failed: usize,
}

/// Global minimisation of the batched cost inside `[lo, hi]` (u coordinates), feasible
/// candidates first.
///
/// Strategy: "current-to-best/1/bin" with per-trial dither of F. With a budget of only
/// tens of generations, pulling every member toward the best converges several times
/// faster than "rand/1/bin"; the premature-convergence risk this brings is reduced by the
/// dither and the difference vector, and is acceptable because a local Levenberg-Marquardt
/// stage polishes the result. Mutants leaving the box bounce back to a random point between
/// the parent and the bound. Selection is greedy (a trial replaces its parent unless the
/// parent beats it, [`Fitness::beats`]); a failed evaluation loses to every other.
/// `on_generation(g, best_cost, best_u)` is called after the initial population (g = 0)
/// and after each generation.
pub fn differential_evolution(
    eval: &mut Batch<'_>,
    lo: &[f64],
    hi: &[f64],
    opts: &DeOptions,
    on_generation: &mut dyn FnMut(usize, f64, &[f64]) -> Progress,
) -> Result<DeResult> {
    check_inputs(lo, hi, opts)?;
    let mut rng = SplitMix64(opts.seed);
    let mut tally = Tally::default();
    let mut pop = latin_hypercube(lo, hi, opts.population, &mut rng);
    let mut costs = evaluate(eval, &pop, &mut tally)?;
    if costs.iter().all(Fitness::failed) {
        bail!(
            "no candidate in the bounds could be evaluated: all {} initial candidates failed",
            pop.len()
        );
    }
    let mut best = argmin(&costs);
    let mut generations = 0;
    let mut stop = on_generation(0, costs[best].cost, &pop[best]) == Progress::Stop
        || converged(&costs, best, opts);
    while !stop && generations < opts.max_generations {
        let trials: Vec<Vec<f64>> = (0..pop.len())
            .map(|i| trial(&pop, i, best, lo, hi, opts, &mut rng))
            .collect();
        let trial_costs = evaluate(eval, &trials, &mut tally)?;
        for (i, (t, c)) in trials.into_iter().zip(trial_costs).enumerate() {
            if !costs[i].beats(&c) {
                pop[i] = t;
                costs[i] = c;
            }
        }
        best = argmin(&costs);
        generations += 1;
        stop = on_generation(generations, costs[best].cost, &pop[best]) == Progress::Stop
            || converged(&costs, best, opts);
    }
    Ok(DeResult {
        best: pop.swap_remove(best),
        best_cost: costs[best].cost,
        best_violation: costs[best].violation,
        generations,
        evaluations: tally.evaluations,
        failed: tally.failed,
    })
}

/// Rejects empty or inverted bounds and unusable settings.
fn check_inputs(lo: &[f64], hi: &[f64], opts: &DeOptions) -> Result<()> {
    ensure!(!lo.is_empty(), "no parameters to search");
    ensure!(
        lo.len() == hi.len(),
        "{} lower bounds but {} upper bounds",
        lo.len(),
        hi.len()
    );
    for (j, (l, h)) in lo.iter().zip(hi).enumerate() {
        ensure!(
            l.is_finite() && h.is_finite() && l < h,
            "bounds of parameter {j} are not finite with lo < hi: [{l}, {h}]"
        );
    }
    ensure!(opts.population >= 4, "population must be at least 4");
    ensure!(opts.f > 0.0 && opts.f.is_finite(), "F must be positive");
    ensure!((0.0..=1.0).contains(&opts.cr), "CR must lie in [0, 1]");
    Ok(())
}

/// Latin hypercube sample of `n` points: each coordinate visits each of `n` equal strata once.
fn latin_hypercube(lo: &[f64], hi: &[f64], n: usize, rng: &mut SplitMix64) -> Vec<Vec<f64>> {
    let mut points = vec![vec![0.0; lo.len()]; n];
    for (j, (&l, &h)) in lo.iter().zip(hi).enumerate() {
        let mut strata: Vec<usize> = (0..n).collect();
        for k in (1..n).rev() {
            strata.swap(k, rng.below(k + 1));
        }
        for (point, &s) in points.iter_mut().zip(&strata) {
            point[j] = (l + (h - l) * (s as f64 + rng.unit()) / n as f64).min(h);
        }
    }
    points
}

/// Evaluates one batch ([`scored`]), counting it.
fn evaluate(eval: &mut Batch<'_>, points: &[Vec<f64>], tally: &mut Tally) -> Result<Vec<Fitness>> {
    let costs = scored(eval, points)?;
    tally.evaluations += points.len();
    tally.failed += costs.iter().filter(|c| c.failed()).count();
    Ok(costs)
}

/// One batch's fitness, one per point, each [`Fitness::checked`]: every
/// search's one call of its evaluator.
pub(super) fn scored(eval: &mut Batch<'_>, points: &[Vec<f64>]) -> Result<Vec<Fitness>> {
    let results = eval(points)?;
    ensure!(
        results.len() == points.len(),
        "the batch evaluator returned {} results for {} candidates",
        results.len(),
        points.len()
    );
    Ok(results.into_iter().map(Fitness::checked).collect())
}

/// Index of the best candidate (the first one on ties).
fn argmin(costs: &[Fitness]) -> usize {
    let mut best = 0;
    for (i, c) in costs.iter().enumerate() {
        if c.beats(&costs[best]) {
            best = i;
        }
    }
    best
}

/// True when the population's relative cost spread is below the tolerance (every member
/// feasible) or the best cost is below `stop_below`.
fn converged(costs: &[Fitness], best: usize, opts: &DeOptions) -> bool {
    let b = costs[best];
    let feasible = b.violation == 0.0;
    if feasible && opts.stop_below.is_some_and(|floor| b.cost < floor) {
        return true;
    }
    let cost = |f: &Fitness| {
        if f.violation == 0.0 {
            f.cost
        } else {
            f64::INFINITY
        }
    };
    let worst = costs.iter().map(cost).fold(b.cost, f64::max);
    feasible && (worst - b.cost) / (b.cost.abs() + 1e-300) < opts.tolerance
}

/// Trial vector for member `i`: current-to-best/1 mutation, binomial crossover, bounce-back.
fn trial(
    pop: &[Vec<f64>],
    i: usize,
    best: usize,
    lo: &[f64],
    hi: &[f64],
    opts: &DeOptions,
    rng: &mut SplitMix64,
) -> Vec<f64> {
    let (r1, r2) = two_others(pop.len(), i, rng);
    let f = opts.f * (0.5 + rng.unit());
    let forced = rng.below(lo.len());
    let mut out = pop[i].clone();
    for (j, x) in out.iter_mut().enumerate() {
        if j != forced && rng.unit() >= opts.cr {
            continue;
        }
        let v = *x + f * (pop[best][j] - *x) + f * (pop[r1][j] - pop[r2][j]);
        *x = if v < lo[j] {
            lo[j] + rng.unit() * (*x - lo[j])
        } else if v > hi[j] {
            hi[j] - rng.unit() * (hi[j] - *x)
        } else {
            v
        };
    }
    out
}

/// Two distinct indices in `0..n`, both different from `i` (`n >= 3`).
fn two_others(n: usize, i: usize, rng: &mut SplitMix64) -> (usize, usize) {
    let mut r1 = rng.below(n);
    while r1 == i {
        r1 = rng.below(n);
    }
    let mut r2 = rng.below(n);
    while r2 == i || r2 == r1 {
        r2 = rng.below(n);
    }
    (r1, r2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    type Out = anyhow::Result<Vec<Fitness>>;

    /// Batch evaluator of least squares from a pointwise model of residuals,
    /// counting calls.
    fn batched<'a>(
        model: impl Fn(&[f64]) -> Option<Vec<f64>> + 'a,
        calls: &'a RefCell<Vec<usize>>,
    ) -> impl FnMut(&[Vec<f64>]) -> Out + 'a {
        move |pts: &[Vec<f64>]| {
            calls.borrow_mut().push(pts.len());
            Ok(pts
                .iter()
                .map(|u| Fitness::squares(model(u).as_deref()))
                .collect())
        }
    }

    fn rosenbrock(u: &[f64]) -> Option<Vec<f64>> {
        Some(vec![10.0 * (u[1] - u[0] * u[0]), 1.0 - u[0]])
    }

    fn run(
        model: impl Fn(&[f64]) -> Option<Vec<f64>>,
        lo: &[f64],
        hi: &[f64],
        opts: &DeOptions,
    ) -> (Result<DeResult>, Vec<usize>) {
        let calls = RefCell::new(Vec::new());
        let mut eval = batched(model, &calls);
        let out =
            differential_evolution(&mut eval, lo, hi, opts, &mut |_, _, _| Progress::Continue);
        drop(eval);
        (out, calls.into_inner())
    }

    #[test]
    fn rosenbrock_finds_the_valley_minimum() {
        let mut opts = DeOptions::for_dimension(2, 42);
        opts.max_generations = 300;
        let (res, _) = run(rosenbrock, &[-2.0, -2.0], &[2.0, 2.0], &opts);
        let res = res.unwrap();
        assert!((res.best[0] - 1.0).abs() < 1e-2, "{res:?}");
        assert!((res.best[1] - 1.0).abs() < 1e-2, "{res:?}");
    }

    /// y = 1 + 2x - 0.5x² plus fixed pseudo-noise, 21 points.
    fn regression(u: &[f64]) -> Option<Vec<f64>> {
        let r = (0..21).map(|i| {
            let x = i as f64 * 0.5;
            let noise = 0.1 * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
            let y = 1.0 + 2.0 * x - 0.5 * x * x + noise;
            u[0] + u[1] * x + u[2] * x * x - y
        });
        Some(r.collect())
    }

    #[test]
    fn linear_regression_three_parameters() {
        let opts = DeOptions::for_dimension(3, 1);
        let (res, _) = run(regression, &[-5.0; 3], &[5.0; 3], &opts);
        let res = res.unwrap();
        let truth = [1.0, 2.0, -0.5];
        for (b, t) in res.best.iter().zip(truth) {
            assert!((b - t).abs() < 0.3, "{res:?}");
        }
        let reference: f64 = regression(&truth).unwrap().iter().map(|x| x * x).sum();
        assert!(res.best_cost < 1.5 * reference, "{res:?} vs {reference}");
    }

    #[test]
    fn same_seed_is_bit_identical_and_seeds_differ() {
        let opts = DeOptions::for_dimension(2, 99);
        let (a, _) = run(rosenbrock, &[-2.0, -2.0], &[2.0, 2.0], &opts);
        let (b, _) = run(rosenbrock, &[-2.0, -2.0], &[2.0, 2.0], &opts);
        let (a, b) = (a.unwrap(), b.unwrap());
        assert_eq!(a.best_cost.to_bits(), b.best_cost.to_bits());
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.best), bits(&b.best));
        assert_eq!(
            (a.generations, a.evaluations),
            (b.generations, b.evaluations)
        );
        let other = DeOptions { seed: 100, ..opts };
        let (c, _) = run(rosenbrock, &[-2.0, -2.0], &[2.0, 2.0], &other);
        assert_ne!(bits(&a.best), bits(&c.unwrap().best));
    }

    #[test]
    fn infeasible_candidates_are_never_selected() {
        // Optimum of the unconstrained problem (1, 1) lies in the infeasible region x > 0.5.
        let model = |u: &[f64]| if u[0] > 0.5 { None } else { rosenbrock(u) };
        let mut opts = DeOptions::for_dimension(2, 3);
        opts.max_generations = 200;
        let (res, _) = run(model, &[-2.0, -2.0], &[2.0, 2.0], &opts);
        let res = res.unwrap();
        assert!(res.failed > 0 && res.best_cost.is_finite());
        assert!(res.best[0] <= 0.5 && res.best[0] > 0.45, "{res:?}");
    }

    #[test]
    fn all_infeasible_is_an_error() {
        let opts = DeOptions::for_dimension(2, 3);
        let (res, calls) = run(|_| None, &[0.0, 0.0], &[1.0, 1.0], &opts);
        let msg = res.unwrap_err().to_string();
        assert!(
            msg.contains("no candidate in the bounds could be evaluated"),
            "{msg}"
        );
        assert_eq!(calls.len(), 1);
    }

    #[test]
    fn one_batch_per_generation() {
        let opts = DeOptions {
            tolerance: 0.0,
            ..DeOptions::for_dimension(2, 5)
        };
        let (res, calls) = run(rosenbrock, &[-2.0, -2.0], &[2.0, 2.0], &opts);
        let res = res.unwrap();
        assert_eq!(res.generations, 40);
        assert_eq!(calls.len(), res.generations + 1);
        assert!(calls.iter().all(|&n| n == opts.population));
        assert_eq!(res.evaluations, 41 * opts.population);
    }

    #[test]
    fn stop_from_the_callback_returns_best_so_far() {
        let calls = RefCell::new(Vec::new());
        let mut eval = batched(rosenbrock, &calls);
        let opts = DeOptions::for_dimension(2, 8);
        let mut seen = Vec::new();
        let res =
            differential_evolution(&mut eval, &[-2.0; 2], &[2.0; 2], &opts, &mut |g, c, _| {
                seen.push((g, c));
                if g == 3 {
                    Progress::Stop
                } else {
                    Progress::Continue
                }
            });
        let res = res.unwrap();
        assert_eq!(res.generations, 3);
        assert_eq!(seen.len(), 4);
        assert!(seen.windows(2).all(|w| w[1].1 <= w[0].1));
        assert_eq!(res.best_cost, seen[3].1);
    }

    #[test]
    fn latin_hypercube_fills_each_stratum_once() {
        let mut rng = SplitMix64(11);
        let pts = latin_hypercube(&[0.0, -1.0], &[1.0, 1.0], 10, &mut rng);
        for (j, (l, w)) in [(0.0, 1.0), (-1.0, 2.0)].into_iter().enumerate() {
            let mut cells: Vec<usize> = pts
                .iter()
                .map(|p| ((p[j] - l) / w * 10.0) as usize)
                .collect();
            cells.sort_unstable();
            assert_eq!(cells, (0..10).collect::<Vec<_>>());
        }
    }

    /// A cost of any sign under a constraint, feasibility first: the
    /// largest x + y (cost -(x + y)) on the disc x² + y² <= 1 (violation
    /// x² + y² - 1 outside it) is at (1, 1) / √2; no infeasible candidate
    /// is ever the best once a feasible one is seen.
    #[test]
    fn deb_rules_find_a_constrained_maximum_of_any_sign() {
        let score = |u: &[f64]| Fitness {
            cost: -(u[0] + u[1]),
            violation: (u[0] * u[0] + u[1] * u[1] - 1.0).max(0.0),
        };
        let mut feasible_seen = false;
        let mut eval = |pts: &[Vec<f64>]| -> Out { Ok(pts.iter().map(|u| score(u)).collect()) };
        let opts = DeOptions {
            max_generations: 200,
            stop_below: None,
            tolerance: 1e-9,
            ..DeOptions::for_dimension(2, 17)
        };
        let res =
            differential_evolution(&mut eval, &[-2.0; 2], &[2.0; 2], &opts, &mut |_, _, u| {
                let inside = score(u).violation == 0.0;
                assert!(
                    inside || !feasible_seen,
                    "an infeasible best after a feasible one"
                );
                feasible_seen |= inside;
                Progress::Continue
            })
            .unwrap();
        assert_eq!(res.best_violation, 0.0);
        let r = std::f64::consts::FRAC_1_SQRT_2;
        assert!(
            (res.best[0] - r).abs() < 1e-3 && (res.best[1] - r).abs() < 1e-3,
            "{res:?}"
        );
        assert!(
            (res.best_cost + std::f64::consts::SQRT_2).abs() < 1e-6,
            "{res:?}"
        );
    }

    /// Deb's rules, case by case; a failed evaluation loses to every other.
    #[test]
    fn feasible_beats_infeasible_then_cost_then_violation() {
        let f = Fitness::feasible;
        let bad = |v| Fitness {
            cost: -1e9,
            violation: v,
        };
        assert!(f(5.0).beats(&bad(1e-12)));
        assert!(!bad(1e-12).beats(&f(5.0)));
        assert!(f(-3.0).beats(&f(-2.0)) && !f(-2.0).beats(&f(-2.0)));
        assert!(bad(0.1).beats(&bad(0.2)));
        assert!(bad(1e300).beats(&Fitness::FAILED) && !Fitness::FAILED.beats(&Fitness::FAILED));
        assert_eq!(Fitness::squares(Some(&[3.0, 4.0])), f(25.0));
        assert!(Fitness::squares(Some(&[f64::NAN])).failed() && Fitness::squares(None).failed());
    }
}
