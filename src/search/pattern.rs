//! A pattern search on rotating orthogonal directions (as OrthoMADS's
//! polls): the local stage for a noisy cost under constraints (issue 61),
//! where Levenberg-Marquardt's finite differences would difference the
//! noise. It needs no derivative and compares candidates only by Deb's
//! rules ([`Fitness::beats`]), so noise below a step's effect cannot turn
//! it; a step that finds nothing better halves, and the search ends when
//! the step is below its tolerance or the budget is spent.
//!
//! Each iteration polls the 2p points `x ± step (width ⊙ d_j)` (clamped to
//! the box), the d_j the columns of a Householder reflection of a seeded
//! random unit vector, as one batch, so that an expensive simulation runs
//! them together, and moves to the best of them where it beats `x`. Fixed
//! coordinate directions stall where a constraint's boundary curves across
//! them (a compass search stopped at x + y = 1.34 of the unit disc's 1.41);
//! rotating ones do not.

use super::evolution::{Batch, Fitness, scored};
use super::rng::SplitMix64;
use anyhow::{Result, ensure};

/// Settings of [`compass_search`].
#[derive(Debug, Clone, PartialEq)]
pub struct PatternOptions {
    /// The first step, as a fraction of each bound's width.
    pub initial_step: f64,
    /// The search ends when the step is below this fraction of the widths.
    pub tolerance: f64,
    /// The most candidates evaluated, the start included.
    pub max_evaluations: usize,
    /// The seed of the poll directions: the same seed, the same search.
    pub seed: u64,
}

impl Default for PatternOptions {
    /// Steps of a tenth of the box down to a thousandth, at most 400 runs.
    fn default() -> PatternOptions {
        PatternOptions {
            initial_step: 0.1,
            tolerance: 1e-3,
            max_evaluations: 400,
            seed: 1,
        }
    }
}

/// Outcome of [`compass_search`].
#[derive(Debug, Clone, PartialEq)]
pub struct PatternResult {
    /// The best point found and its fitness.
    pub best: Vec<f64>,
    pub fitness: Fitness,
    /// Candidates evaluated, the start included.
    pub evaluations: usize,
    /// Whether the step fell below its tolerance (else the budget ended it).
    pub converged: bool,
}

/// Minimises the batched cost from `start` inside `[lo, hi]`, feasible
/// candidates first.
pub fn compass_search(
    eval: &mut Batch<'_>,
    start: &[f64],
    lo: &[f64],
    hi: &[f64],
    opts: &PatternOptions,
) -> Result<PatternResult> {
    let p = start.len();
    ensure!(
        p > 0 && lo.len() == p && hi.len() == p,
        "bounds and start differ in length"
    );
    ensure!(
        (0..p).all(|j| lo[j] < hi[j] && (lo[j]..=hi[j]).contains(&start[j])),
        "the start is not inside bounds with lo < hi"
    );
    ensure!(
        opts.initial_step > 0.0 && opts.tolerance > 0.0,
        "steps must be positive"
    );
    let width: Vec<f64> = (0..p).map(|j| hi[j] - lo[j]).collect();
    let mut rng = SplitMix64(opts.seed);
    let mut step = opts.initial_step;
    let mut x = start.to_vec();
    let mut fx = scored(eval, &[x.clone()])?[0];
    let mut evaluations = 1;
    while step >= opts.tolerance && evaluations + 2 * p <= opts.max_evaluations {
        let basis = rotation(p, &mut rng);
        let polls: Vec<Vec<f64>> = (0..2 * p)
            .map(|m| {
                let sign = if m % 2 == 0 { 1.0 } else { -1.0 };
                let d = &basis[m / 2];
                (0..p)
                    .map(|j| (x[j] + sign * step * width[j] * d[j]).clamp(lo[j], hi[j]))
                    .collect()
            })
            .collect();
        let scores = scored(eval, &polls)?;
        evaluations += polls.len();
        let mut best = None;
        for (m, s) in scores.iter().enumerate() {
            let leader = best.map_or(fx, |b: usize| scores[b]);
            if s.beats(&leader) && polls[m] != x {
                best = Some(m);
            }
        }
        match best {
            Some(m) => {
                x = polls[m].clone();
                fx = scores[m];
            }
            None => step *= 0.5,
        }
    }
    Ok(PatternResult {
        best: x,
        fitness: fx,
        evaluations,
        converged: step < opts.tolerance,
    })
}

/// The p columns of `I - 2 v vᵀ` for a random unit vector v: an
/// orthonormal basis, another each iteration.
fn rotation(p: usize, rng: &mut SplitMix64) -> Vec<Vec<f64>> {
    let mut v: Vec<f64> = (0..p).map(|_| rng.unit() - 0.5).collect();
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm > 0.0 {
        v.iter_mut().for_each(|x| *x /= norm);
    }
    (0..p)
        .map(|j| {
            (0..p)
                .map(|i| f64::from(u8::from(i == j)) - 2.0 * v[i] * v[j])
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    type Out = anyhow::Result<Vec<Fitness>>;

    fn search(
        score: impl Fn(&[f64]) -> Fitness,
        start: &[f64],
        lo: &[f64],
        hi: &[f64],
        opts: &PatternOptions,
    ) -> (PatternResult, Vec<usize>) {
        let mut batches = Vec::new();
        let mut eval = |pts: &[Vec<f64>]| -> Out {
            batches.push(pts.len());
            Ok(pts.iter().map(|u| score(u)).collect())
        };
        let res = compass_search(&mut eval, start, lo, hi, opts).unwrap();
        (res, batches)
    }

    /// A bowl: the minimum within the tolerance, every poll one batch of
    /// 2p, every run counted.
    #[test]
    fn a_bowl_is_found_in_batches_of_polls() {
        let bowl = |u: &[f64]| Fitness::feasible((u[0] - 0.3).powi(2) + 4.0 * (u[1] + 0.7).powi(2));
        let opts = PatternOptions::default();
        let (res, batches) = search(bowl, &[0.9, 0.9], &[-1.0; 2], &[1.0; 2], &opts);
        assert!(res.converged, "{res:?}");
        assert!(
            (res.best[0] - 0.3).abs() < 4e-3 && (res.best[1] + 0.7).abs() < 4e-3,
            "{res:?}"
        );
        assert_eq!(batches[0], 1);
        assert!(batches[1..].iter().all(|&n| n == 4));
        assert_eq!(res.evaluations, batches.iter().sum::<usize>());
        assert!(res.evaluations <= opts.max_evaluations);
        // The same seed, the same search; another seed, another path.
        assert_eq!(
            search(bowl, &[0.9, 0.9], &[-1.0; 2], &[1.0; 2], &opts).0,
            res
        );
        let other = PatternOptions { seed: 2, ..opts };
        assert_ne!(
            search(bowl, &[0.9, 0.9], &[-1.0; 2], &[1.0; 2], &other)
                .0
                .best,
            res.best
        );
    }

    /// The largest x + y on the unit disc, from inside, by Deb's rules:
    /// it ends on the boundary near (1, 1) / sqrt 2, feasible.
    #[test]
    fn a_constrained_maximum_ends_feasible_on_the_boundary() {
        let score = |u: &[f64]| Fitness {
            cost: -(u[0] + u[1]),
            violation: (u[0] * u[0] + u[1] * u[1] - 1.0).max(0.0),
        };
        let opts = PatternOptions {
            tolerance: 1e-6,
            max_evaluations: 4000,
            ..PatternOptions::default()
        };
        let (res, _) = search(score, &[0.0, 0.0], &[-2.0; 2], &[2.0; 2], &opts);
        assert_eq!(res.fitness.violation, 0.0);
        assert!(
            res.fitness.cost < -std::f64::consts::SQRT_2 + 0.02,
            "{res:?}"
        );
    }

    /// Noise of 1e-4 on a bowl of curvature 1: the search settles within
    /// the noise's reach of the minimum, never leaves the box, and stops
    /// at its budget when the tolerance is out of reach.
    #[test]
    fn noise_and_bounds_and_the_budget_are_respected() {
        let noisy = |u: &[f64]| {
            let bits = (u[0].to_bits() ^ u[1].to_bits().rotate_left(17))
                .wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let noise = 1e-4 * ((bits >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            Fitness::feasible((u[0] - 2.0).powi(2) + (u[1] - 0.5).powi(2) + noise)
        };
        let opts = PatternOptions::default();
        let (res, _) = search(noisy, &[0.0, 0.0], &[-1.0, -1.0], &[1.0, 1.0], &opts);
        assert_eq!(res.best[0], 1.0, "{res:?}");
        assert!((res.best[1] - 0.5).abs() < 0.02, "{res:?}");
        let tight = PatternOptions {
            tolerance: 1e-12,
            max_evaluations: 41,
            ..opts
        };
        let (res, batches) = search(noisy, &[0.0, 0.0], &[-1.0, -1.0], &[1.0, 1.0], &tight);
        assert!(
            !res.converged && res.evaluations <= 41 && batches.len() == 11,
            "{res:?}"
        );
    }
}
