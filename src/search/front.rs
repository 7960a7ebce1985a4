//! A front between two costs: generalized differential evolution, GDE3
//! (Kukkonen and Lampinen, 2005), feasibility first. Each generation makes
//! one rand/1/bin trial per member; a trial that constraint-dominates its
//! parent replaces it, one its parent constraint-dominates is dropped,
//! and where neither dominates both stay; the population is then cut back
//! to its size by non-dominated sorting and crowding distance (NSGA-II's).
//!
//! Constraint-domination (Deb): a feasible point beats an infeasible one,
//! of two infeasible ones the smaller violation wins, of two feasible ones
//! the one no worse in both costs and better in one. The front itself is
//! the caller's: it keeps every point it scored.

use super::rng::SplitMix64;
use anyhow::{Result, ensure};

/// Two costs to minimise and a constraint violation (0: feasible; not
/// finite: the evaluation failed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    pub costs: [f64; 2],
    pub violation: f64,
}

impl Score {
    /// A failed evaluation: beaten by every other.
    pub const FAILED: Score = Score {
        costs: [f64::INFINITY; 2],
        violation: f64::INFINITY,
    };

    /// Whether `self` constraint-dominates `other`.
    pub fn dominates(&self, other: &Score) -> bool {
        match (self.violation == 0.0, other.violation == 0.0) {
            (true, false) => true,
            (false, true) => false,
            (false, false) => self.violation < other.violation,
            (true, true) => {
                let (a, b) = (self.costs, other.costs);
                a[0] <= b[0] && a[1] <= b[1] && (a[0] < b[0] || a[1] < b[1])
            }
        }
    }
}

/// Scores of a batch of points (u coordinates).
pub type Batch2<'a> = dyn FnMut(&[Vec<f64>]) -> Result<Vec<Score>> + 'a;

/// Settings of [`gde3`].
#[derive(Clone, Debug, PartialEq)]
pub struct FrontOptions {
    pub population: usize,
    /// The most points scored, the first population included.
    pub max_evaluations: usize,
    pub seed: u64,
    /// DE's scale factor and crossover rate (GDE3's defaults for two
    /// objectives).
    pub f: f64,
    pub cr: f64,
}

impl FrontOptions {
    /// 10 members per key (at least 20, at most 60), F 0.5, CR 0.9.
    pub fn for_dimension(p: usize, max_evaluations: usize, seed: u64) -> FrontOptions {
        FrontOptions {
            population: (10 * p).clamp(20, 60),
            max_evaluations,
            seed,
            f: 0.5,
            cr: 0.9,
        }
    }
}

/// Runs GDE3 inside `[lo, hi]`; returns the points scored.
pub fn gde3(eval: &mut Batch2<'_>, lo: &[f64], hi: &[f64], opts: &FrontOptions) -> Result<usize> {
    let p = lo.len();
    ensure!(p > 0 && hi.len() == p, "bounds differ in length");
    ensure!(opts.population >= 5, "a population of at least 5");
    let mut rng = SplitMix64(opts.seed);
    let mut pop: Vec<Vec<f64>> = (0..opts.population)
        .map(|_| (0..p).map(|j| rng.uniform(lo[j], hi[j])).collect())
        .collect();
    let mut scores = eval(&pop)?;
    let mut evaluations = pop.len();
    while evaluations + opts.population <= opts.max_evaluations {
        if crate::interrupt::interrupt_requested() {
            break;
        }
        let trials: Vec<Vec<f64>> = (0..pop.len())
            .map(|i| trial(&pop, i, lo, hi, opts, &mut rng))
            .collect();
        let trial_scores = eval(&trials)?;
        evaluations += trials.len();
        let (mut next, mut next_scores) = (Vec::new(), Vec::new());
        for (i, (t, s)) in trials.into_iter().zip(trial_scores).enumerate() {
            let parent = scores[i];
            if !s.dominates(&parent) {
                next.push(pop[i].clone());
                next_scores.push(parent);
            }
            if !parent.dominates(&s) {
                next.push(t);
                next_scores.push(s);
            }
        }
        let keep = survivors(&next_scores, opts.population);
        pop = keep.iter().map(|&k| next[k].clone()).collect();
        scores = keep.iter().map(|&k| next_scores[k]).collect();
    }
    Ok(evaluations)
}

/// rand/1/bin: three other members' difference, crossed with member i,
/// kept inside the bounds by a bounce to a random point before them.
fn trial(
    pop: &[Vec<f64>],
    i: usize,
    lo: &[f64],
    hi: &[f64],
    opts: &FrontOptions,
    rng: &mut SplitMix64,
) -> Vec<f64> {
    let n = pop.len();
    let mut pick = |taken: &[usize]| loop {
        let k = rng.below(n);
        if !taken.contains(&k) {
            break k;
        }
    };
    let a = pick(&[i]);
    let b = pick(&[i, a]);
    let c = pick(&[i, a, b]);
    let p = lo.len();
    let forced = rng.below(p);
    (0..p)
        .map(|j| {
            if j != forced && rng.unit() >= opts.cr {
                return pop[i][j];
            }
            let v = pop[a][j] + opts.f * (pop[b][j] - pop[c][j]);
            if v < lo[j] {
                lo[j] + rng.unit() * (pop[i][j] - lo[j])
            } else if v > hi[j] {
                hi[j] - rng.unit() * (hi[j] - pop[i][j])
            } else {
                v
            }
        })
        .collect()
}

/// The `size` best of `scores`: whole non-dominated layers, then the last
/// layer's most isolated members (largest crowding distance).
fn survivors(scores: &[Score], size: usize) -> Vec<usize> {
    let mut left: Vec<usize> = (0..scores.len()).collect();
    let mut keep = Vec::with_capacity(size);
    while keep.len() < size && !left.is_empty() {
        let layer: Vec<usize> = left
            .iter()
            .copied()
            .filter(|&a| !left.iter().any(|&b| scores[b].dominates(&scores[a])))
            .collect();
        left.retain(|k| !layer.contains(k));
        if keep.len() + layer.len() <= size {
            keep.extend(layer);
        } else {
            let crowding = crowding(scores, &layer);
            let mut order: Vec<usize> = (0..layer.len()).collect();
            order.sort_by(|&x, &y| crowding[y].total_cmp(&crowding[x]).then(x.cmp(&y)));
            keep.extend(order.into_iter().take(size - keep.len()).map(|k| layer[k]));
        }
    }
    keep
}

/// NSGA-II's crowding distance of each member of a layer (infinite at
/// either end of each cost); infeasible layers are spread by violation.
fn crowding(scores: &[Score], layer: &[usize]) -> Vec<f64> {
    let mut d = vec![0.0; layer.len()];
    let feasible = layer.iter().all(|&k| scores[k].violation == 0.0);
    let keys: Vec<Box<dyn Fn(usize) -> f64>> = if feasible {
        vec![
            Box::new(|k| scores[k].costs[0]),
            Box::new(|k| scores[k].costs[1]),
        ]
    } else {
        vec![Box::new(|k| -scores[k].violation)]
    };
    for key in keys {
        let mut order: Vec<usize> = (0..layer.len()).collect();
        order.sort_by(|&x, &y| key(layer[x]).total_cmp(&key(layer[y])));
        let (first, last) = (order[0], order[order.len() - 1]);
        let span = key(layer[last]) - key(layer[first]);
        d[first] = f64::INFINITY;
        d[last] = f64::INFINITY;
        if span > 0.0 && span.is_finite() {
            for w in order.windows(3) {
                d[w[1]] += (key(layer[w[2]]) - key(layer[w[0]])) / span;
            }
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ZDT1 in two keys: f1 = x, f2 = g (1 - sqrt(x / g)), g = 1 + 9 y;
    /// the front is y = 0, f2 = 1 - sqrt(f1). A constraint f1 >= 0.2
    /// cuts its left end. Every feasible non-dominated point found lies
    /// within 0.02 of the front, and the points span it.
    #[test]
    fn gde3_finds_a_known_front() {
        let mut all: Vec<Score> = Vec::new();
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Score>> {
            let s: Vec<Score> = us
                .iter()
                .map(|u| {
                    let g = 1.0 + 9.0 * u[1];
                    Score {
                        costs: [u[0], g * (1.0 - (u[0] / g).sqrt())],
                        violation: (0.2 - u[0]).max(0.0),
                    }
                })
                .collect();
            all.extend(&s);
            Ok(s)
        };
        let opts = FrontOptions::for_dimension(2, 2000, 7);
        let n = gde3(&mut eval, &[0.0, 0.0], &[1.0, 1.0], &opts).unwrap();
        assert!(n <= 2000 && n == all.len());
        let front: Vec<&Score> = all
            .iter()
            .filter(|a| a.violation == 0.0 && !all.iter().any(|b| b.dominates(a)))
            .collect();
        assert!(front.len() >= 20, "{}", front.len());
        for s in &front {
            assert!(
                (s.costs[1] - (1.0 - s.costs[0].sqrt())).abs() < 0.02,
                "{s:?}"
            );
        }
        let (lo, hi) = front.iter().fold((1.0f64, 0.0f64), |(l, h), s| {
            (l.min(s.costs[0]), h.max(s.costs[0]))
        });
        assert!(lo < 0.21 && hi > 0.95, "{lo} {hi}");
    }

    #[test]
    fn constraint_domination_ranks_feasible_first() {
        let f = |c0, c1, v| Score {
            costs: [c0, c1],
            violation: v,
        };
        assert!(f(5.0, 5.0, 0.0).dominates(&f(0.0, 0.0, 0.1)));
        assert!(f(0.0, 0.0, 0.1).dominates(&f(0.0, 0.0, 0.2)));
        assert!(f(1.0, 1.0, 0.0).dominates(&f(1.0, 2.0, 0.0)));
        assert!(!f(1.0, 2.0, 0.0).dominates(&f(2.0, 1.0, 0.0)));
        assert!(!f(1.0, 1.0, 0.0).dominates(&f(1.0, 1.0, 0.0)));
        assert!(f(0.0, 0.0, 0.0).dominates(&Score::FAILED));
    }
}
