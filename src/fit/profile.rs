//! Profile-likelihood intervals (docs/fit.md): for each free key, the
//! values where the misfit, with the other keys refitted, rises by 1
//! (68.3 %) or 3.84 (95 %) above the best where the data's errors are
//! known; by Student's quantiles squared where they are estimated (from
//! repeats or residuals, `super::goodness::rise`), times the reduced chi2
//! where `fit.errors = "scaled"`. Unlike value ± se they follow a kink or
//! a curved valley, and a log-scale key's are not symmetric.
//!
//! Each side of each key is walked outward from the best value in steps
//! of its standard error (1, 2, 3, 4, 6, ... up to 40, then the bound),
//! the other keys refitted at every point by Levenberg-Marquardt, in
//! batches on the backend as the search runs, from two starts: the
//! previous point's values, and where the covariance puts the other keys'
//! best values given this one (their regression on it). The lower end
//! wins: at a kink in the steps one start alone can stop in a valley the
//! other leaves, and a profile too high makes an interval too narrow.
//! The walk stops once the misfit stays above the 95 % threshold for two
//! points, or at the bound. The crossing of each threshold is the
//! outermost one the walk saw, refined by three bisections and a linear
//! interpolation; a side that never rises above it inside the bounds is
//! open (`None`). A candidate that fails or that a scene rule refuses
//! counts as above every threshold.

use anyhow::Result;

use super::jacobian::Eval;
use super::lsq::{self, LmOptions};
use super::spec::Free;

/// The steps of a walk, in standard errors from the best value.
const WALK: [f64; 8] = [1.0, 2.0, 3.0, 4.0, 6.0, 10.0, 20.0, 40.0];

/// A refit stops once a step lowers chi2 by less than this fraction of
/// it (about 0.003 at chi2 30, against thresholds of 1 and 3.84), or
/// after [`REFIT_ITERATIONS`].
const REFIT_FTOL: f64 = 1e-4;
const REFIT_ITERATIONS: usize = 10;

/// Bisections of each crossing.
const BISECTIONS: usize = 3;

/// One key's intervals in its own units; `None` where a side is open.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Interval {
    pub lo68: Option<f64>,
    pub hi68: Option<f64>,
    pub lo95: Option<f64>,
    pub hi95: Option<f64>,
}

impl Interval {
    /// Whether either side of the 68 % interval is open.
    pub fn open68(&self) -> bool {
        self.lo68.is_none() || self.hi68.is_none()
    }
}

/// Every key's intervals, the profiles walked (per key: search coordinate
/// and rise of the misfit, for FIT.png) and the candidates they cost.
#[derive(Clone, Debug, Default)]
pub struct Profiles {
    pub intervals: Vec<Interval>,
    /// The rises of chi2 that bound the 68 % and 95 % intervals.
    pub thresholds: [f64; 2],
    pub curves: Vec<Vec<(f64, f64)>>,
    pub evaluations: usize,
}

/// What a key's refits are guided by: the key, the others' regression on
/// it (d u_j / d u_k), the best misfit and the key's variance (search
/// coordinates), which predict the profile where the misfit is quadratic.
struct Guide {
    k: usize,
    slope: Vec<f64>,
    chi2: f64,
    variance: f64,
}

impl Guide {
    /// The misfit the quadratic model predicts with key k at `u_k`: a
    /// refit that ends at or under it is taken as it is.
    fn expected(&self, u_k: f64, best_k: f64) -> f64 {
        let rise = (u_k - best_k).powi(2) / self.variance;
        self.chi2 + if rise.is_finite() { rise } else { 0.0 }
    }
}

/// A point of a walk: its offset from the best value (search
/// coordinates), the misfit's rise there, and the other keys' values.
#[derive(Clone, Debug)]
struct Point {
    offset: f64,
    rise: f64,
    others: Vec<f64>,
}

/// What profiles are walked with: the candidates' weighted residuals, a
/// batch at a time (the search's own, `super::solve`), and the free keys
/// with their bounds in search coordinates.
pub struct Walker<'w, 'e> {
    pub eval: &'w mut Eval<'e>,
    pub free: &'w [Free],
    pub lo: &'w [f64],
    pub hi: &'w [f64],
}

impl Walker<'_, '_> {
    /// The profiles through `best` (search coordinates, misfit `chi2`),
    /// walked in steps of the standard errors `cov` gives (search
    /// coordinates; a hundredth of the bounds where unknown), up to the
    /// rises `thresholds` (68 % and 95 %, `super::goodness::rise`). The
    /// caller counts their candidates.
    pub fn profiles(
        &mut self,
        best: &[f64],
        chi2: f64,
        cov: &[Vec<f64>],
        thresholds: [f64; 2],
    ) -> Result<Profiles> {
        let se: Vec<f64> = (0..best.len()).map(|k| cov[k][k].max(0.0).sqrt()).collect();
        let mut out = Profiles::default();
        for k in 0..best.len() {
            let [lo, hi] = self.free[k].coordinate_bounds();
            let unit = match se[k].is_finite() && se[k] > 0.0 {
                true => se[k].min(hi - lo),
                false => 0.01 * (hi - lo),
            };
            // The others' regression on key k: d u_j / d u_k given the rest.
            let guide = Guide {
                k,
                slope: others(&cov[k], k)
                    .iter()
                    .map(|c| match c / cov[k][k] {
                        s if s.is_finite() => s,
                        _ => 0.0,
                    })
                    .collect(),
                chi2,
                variance: cov[k][k],
            };
            let mut curve = Vec::new();
            let mut sides = [[None; 2]; 2];
            for (side, sign) in [-1.0f64, 1.0].into_iter().enumerate() {
                let room = if sign < 0.0 {
                    best[k] - lo
                } else {
                    hi - best[k]
                };
                let walk = self.walk(best, &guide, (sign, unit, room), thresholds[1])?;
                curve.extend(
                    walk.points
                        .iter()
                        .map(|p| (best[k] + sign * p.offset, p.rise)),
                );
                for (t, threshold) in thresholds.into_iter().enumerate() {
                    sides[t][side] = match walk.crossing(threshold) {
                        Some((a, b)) => {
                            let at = self.bisect(best, &guide, sign, (a, b), threshold)?;
                            Some(self.free[k].value(best[k] + sign * at))
                        }
                        None => None,
                    };
                }
            }
            curve.sort_by(|a, b| a.0.total_cmp(&b.0));
            out.curves.push(curve);
            out.intervals.push(Interval {
                lo68: sides[0][0],
                hi68: sides[0][1],
                lo95: sides[1][0],
                hi95: sides[1][1],
            });
        }
        out.thresholds = thresholds;
        Ok(out)
    }

    /// One side of key `k`'s profile: points outward until the misfit stays
    /// above the 95 % threshold for two points or the side's `room` ends.
    fn walk(
        &mut self,
        best: &[f64],
        guide: &Guide,
        (sign, unit, room): (f64, f64, f64),
        top: f64,
    ) -> Result<Walk> {
        let (k, chi2) = (guide.k, guide.chi2);
        let mut walk = Walk {
            points: vec![Point {
                offset: 0.0,
                rise: 0.0,
                others: others(best, k),
            }],
            reached_bound: false,
        };
        let mut above = 0;
        for g in WALK.iter().map(|g| g * unit).chain([room]) {
            let offset = g.min(room);
            if offset <= walk.points.last().map_or(0.0, |p| p.offset) {
                continue;
            }
            let start = walk
                .points
                .last()
                .map(|p| p.others.clone())
                .unwrap_or_default();
            let (cost, others) = self.refit(best, guide, best[k] + sign * offset, &start)?;
            let rise = cost - chi2;
            walk.points.push(Point {
                offset,
                rise,
                others,
            });
            above = if rise > top { above + 1 } else { 0 };
            if offset >= room {
                walk.reached_bound = true;
                break;
            }
            if above >= 2 {
                break;
            }
        }
        Ok(walk)
    }

    /// The crossing of `threshold` inside `(a, b)` (offsets from the best
    /// value, the misfit below it at `a` and above at `b`): bisected, then
    /// interpolated linearly in the rise.
    fn bisect(
        &mut self,
        best: &[f64],
        guide: &Guide,
        sign: f64,
        (mut a, mut b): (Point, Point),
        threshold: f64,
    ) -> Result<f64> {
        let (k, chi2) = (guide.k, guide.chi2);
        for _ in 0..BISECTIONS {
            let offset = 0.5 * (a.offset + b.offset);
            let (cost, others) = self.refit(best, guide, best[k] + sign * offset, &a.others)?;
            let mid = Point {
                offset,
                rise: cost - chi2,
                others,
            };
            if mid.rise > threshold {
                b = mid;
            } else {
                a = mid;
            }
        }
        if !b.rise.is_finite() {
            return Ok(0.5 * (a.offset + b.offset));
        }
        let t = ((threshold - a.rise) / (b.rise - a.rise)).clamp(0.0, 1.0);
        Ok(a.offset + t * (b.offset - a.offset))
    }

    /// The misfit with the guide's key held at `u_k` and the others
    /// refitted from `start` (their values in order, the key left out);
    /// where that ends above the quadratic model's expectation, also from
    /// the others' regression on the key, the lower of the two. Infinite
    /// where every candidate fails.
    fn refit(
        &mut self,
        best: &[f64],
        guide: &Guide,
        u_k: f64,
        start: &[f64],
    ) -> Result<(f64, Vec<f64>)> {
        let (k, slope) = (guide.k, &guide.slope);
        if best.len() == 1 {
            return self.refit_from(best, k, u_k, start);
        }
        let (lo, hi) = (others(self.lo, k), others(self.hi, k));
        let guess: Vec<f64> = others(best, k)
            .iter()
            .zip(slope)
            .enumerate()
            .map(|(j, (b, s))| (b + s * (u_k - best[k])).clamp(lo[j], hi[j]))
            .collect();
        let warm = self.refit_from(best, k, u_k, start)?;
        if guess == start || warm.0 <= guide.expected(u_k, best[k]) {
            return Ok(warm);
        }
        let guided = self.refit_from(best, k, u_k, &guess)?;
        Ok(if guided.0 < warm.0 { guided } else { warm })
    }

    /// [`Walker::refit`] from one start.
    fn refit_from(
        &mut self,
        best: &[f64],
        k: usize,
        u_k: f64,
        start: &[f64],
    ) -> Result<(f64, Vec<f64>)> {
        let full = |others: &[f64]| -> Vec<f64> {
            let mut u = others.to_vec();
            u.insert(k, u_k);
            u
        };
        if best.len() == 1 {
            let r = (self.eval)(&[full(&[])])?.pop().flatten();
            let cost = r.map_or(f64::INFINITY, |r| r.iter().map(|x| x * x).sum());
            return Ok((cost, Vec::new()));
        }
        let (lo, hi) = (others(self.lo, k), others(self.hi, k));
        let steps: Vec<f64> = lo.iter().zip(&hi).map(|(l, h)| 1e-3 * (h - l)).collect();
        let opts = LmOptions {
            max_iterations: REFIT_ITERATIONS,
            ftol: REFIT_FTOL,
            ..LmOptions::new(steps)
        };
        let mut eval = |us: &[Vec<f64>]| {
            let full: Vec<Vec<f64>> = us.iter().map(|u| full(u)).collect();
            (self.eval)(&full)
        };
        match lsq::levenberg_marquardt(&mut eval, &lo, &hi, start, &opts, &mut |_, _, _| true) {
            Ok(lm) => Ok((lm.cost, lm.u)),
            Err(_) if !crate::interrupt::interrupt_requested() => {
                Ok((f64::INFINITY, start.to_vec()))
            }
            Err(e) => Err(e),
        }
    }
}

/// A side's walk: its points, the best value first.
struct Walk {
    points: Vec<Point>,
    reached_bound: bool,
}

impl Walk {
    /// The outermost step across `threshold`: the last point at or below
    /// it and the next, above; `None` where the walk ends below it (at the
    /// bound: the side is open).
    fn crossing(&self, threshold: f64) -> Option<(Point, Point)> {
        if self.points.last()?.rise <= threshold {
            return None;
        }
        let below = self.points.iter().rposition(|p| p.rise <= threshold)?;
        Some((self.points[below].clone(), self.points[below + 1].clone()))
    }
}

/// `values` without entry `k`.
fn others(values: &[f64], k: usize) -> Vec<f64> {
    values
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != k)
        .map(|(_, v)| *v)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walk(rises: &[f64], reached_bound: bool) -> Walk {
        Walk {
            points: rises
                .iter()
                .enumerate()
                .map(|(i, &rise)| Point {
                    offset: i as f64,
                    rise,
                    others: Vec::new(),
                })
                .collect(),
            reached_bound,
        }
    }

    /// The outermost crossing; none where the walk ends below the
    /// threshold at the bound.
    #[test]
    fn the_crossing_is_the_outermost_one() {
        let check = |rises: &[f64], bound: bool, want: Option<(f64, f64)>| {
            let got = walk(rises, bound)
                .crossing(1.0)
                .map(|(a, b)| (a.offset, b.offset));
            assert_eq!(got, want, "{rises:?}");
        };
        check(&[0.0, 0.5, 2.0, 5.0, 6.0], false, Some((1.0, 2.0)));
        // Up, down again, up for good: the outer crossing.
        check(&[0.0, 2.0, 0.5, 3.0, 9.0, 9.0], false, Some((2.0, 3.0)));
        // Never above at the bound: open.
        check(&[0.0, 0.2, 0.4], true, None);
        // A refused candidate counts as above.
        check(&[0.0, 0.3, f64::INFINITY], false, Some((1.0, 2.0)));
    }
}
