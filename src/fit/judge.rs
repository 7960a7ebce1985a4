//! What a fit's answer is worth: standard errors and correlations from the
//! Jacobian at the best point, and the warnings that say when the data do
//! not determine some parameter (a near-singular Jacobian, a correlation
//! beyond [`MAX_CORRELATION`], a value at its bound).

use super::problem::{Problem, RowModel};
use super::solve::{Ending, Found};
use super::weights::Weights;
use crate::model::AXIS_NAMES;

/// Beyond this, two parameters' correlation says the data determine a
/// combination of them, not each.
pub const MAX_CORRELATION: f64 = 0.99;

/// Beyond this condition number of the Jacobian (its columns scaled by the
/// bounds' widths), some combination of the free keys barely moves any
/// measured step.
pub const MAX_CONDITION: f64 = 1e7;

/// A value this close to a bound (a fraction of the bounds' width) is at it.
const AT_BOUND: f64 = 1e-4;

/// A fit's answer.
#[derive(Clone, Debug)]
pub struct Answer {
    /// The free keys, in `[fit]`'s order.
    pub keys: Vec<String>,
    pub values: Vec<f64>,
    /// Standard errors in the keys' units (NaN when unknown: interrupted).
    pub se: Vec<f64>,
    /// Correlation matrix in `keys`' order (of the search coordinates: the
    /// logarithm of a key searched on a log scale).
    pub correlation: Vec<Vec<f64>>,
    pub chi2: f64,
    /// Measured values less free keys.
    pub dof: i64,
    pub identifiable: bool,
    pub warnings: Vec<String>,
    /// What the fit did that a reader should know (weights, tolerance).
    pub notes: Vec<String>,
    pub ending: Ending,
    pub weights: Weights,
    /// The model at the best point, per data row.
    pub models: Vec<RowModel>,
    pub condition: f64,
    pub generations: usize,
    pub iterations: usize,
}

/// Judges what a search found.
pub fn judge(problem: &Problem, found: Found) -> Answer {
    let p = problem.free.len();
    let values: Vec<f64> = problem
        .free
        .iter()
        .zip(&found.best.u)
        .map(|(f, &u)| f.value(u))
        .collect();
    let dof = problem.data.measurements() as i64 - p as i64;
    let mut answer = Answer {
        keys: problem.free.iter().map(|f| f.key.clone()).collect(),
        se: vec![f64::NAN; p],
        correlation: identity(p),
        chi2: found.best.chi2,
        dof,
        identifiable: true,
        warnings: Vec::new(),
        notes: notes(problem, &found),
        ending: found.ending,
        weights: found.weights,
        models: found.best.models.clone(),
        condition: f64::NAN,
        generations: found.generations,
        iterations: found.iterations,
        values,
    };
    if dof < 0 {
        answer.warn(format!(
            "{} measured values for {p} free keys: the data cannot determine them all",
            problem.data.measurements()
        ));
    }
    if let Some(sided) = &found.jacobian {
        uncertainty(problem, &found.best.u, &sided.j, &mut answer);
        kinks(problem, &sided.kinks, &mut answer);
        second_minimum(problem, &found, &mut answer);
    }
    bounds(problem, &found.best.u, &mut answer);
    model_noise(problem, &found, &mut answer);
    if found.ending == Ending::Interrupted {
        answer
            .warnings
            .push("interrupted (Ctrl-C): the best point so far, without standard errors".into());
    }
    answer
}

impl Answer {
    fn warn(&mut self, warning: String) {
        self.identifiable = false;
        self.warnings.push(warning);
    }
}

fn identity(p: usize) -> Vec<Vec<f64>> {
    (0..p)
        .map(|i| (0..p).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect()
}

/// Standard errors, correlations and the Jacobian's condition.
fn uncertainty(problem: &Problem, u: &[f64], j: &[Vec<f64>], answer: &mut Answer) {
    let cov = super::lsq::covariance(j, 1.0);
    for (i, free) in problem.free.iter().enumerate() {
        let se_u = cov.standard_errors[i];
        answer.se[i] = if free.log {
            free.value(u[i]) * se_u
        } else {
            se_u
        };
    }
    answer.correlation = cov.correlation.clone();
    let widths: Vec<f64> = problem
        .free
        .iter()
        .map(|f| {
            let [lo, hi] = f.coordinate_bounds();
            hi - lo
        })
        .collect();
    let scaled: Vec<Vec<f64>> = j
        .iter()
        .map(|row| row.iter().zip(&widths).map(|(d, w)| d * w).collect())
        .collect();
    answer.condition = super::lsq::covariance(&scaled, 1.0).condition;
    if cov.rank_deficient || answer.condition.is_nan() || answer.condition > MAX_CONDITION {
        answer.warn(format!(
            "the Jacobian is near-singular (condition {:.3e}): some combination of the free \
             keys moves no measured step, so the data do not determine them all",
            answer.condition
        ));
    }
    for a in 0..answer.keys.len() {
        for b in a + 1..answer.keys.len() {
            let c = answer.correlation[a][b];
            if c.abs() > MAX_CORRELATION {
                answer.warn(format!(
                    "`{}` and `{}` are correlated at {c:+.4}: the data determine a combination \
                     of the two, not each",
                    answer.keys[a], answer.keys[b]
                ));
            }
        }
    }
}

/// The chi-square distribution's 95 % quantile for 1 to 12 degrees of
/// freedom: a candidate whose misfit is within this of the best one's is
/// inside the joint 95 % confidence region of the free keys.
const CHI2_95: [f64; 12] = [
    3.841, 5.991, 7.815, 9.488, 11.070, 12.592, 14.067, 15.507, 16.919, 18.307, 19.675, 21.026,
];

/// How much farther than the standard errors allow a candidate inside the
/// confidence region may lie before the region is not the ellipse they
/// describe: on a quadratic misfit a candidate `d` above the best lies at
/// most `sqrt(d)` standard errors from it in any key.
const SECOND_MINIMUM_RATIO: f64 = 2.0;

/// A warning when a candidate the search evaluated fits the data about as
/// well as the best point (its misfit within [`CHI2_95`]) yet lies more
/// than [`SECOND_MINIMUM_RATIO`] times farther from it, in some key, than
/// the standard errors allow for its misfit: a second minimum or a curved
/// valley, which the standard errors do not describe.
fn second_minimum(problem: &Problem, found: &Found, answer: &mut Answer) {
    let p = problem.free.len();
    let best = found.best.chi2;
    let limit = best + CHI2_95[p.clamp(1, CHI2_95.len()) - 1];
    let se_u: Vec<f64> = problem
        .free
        .iter()
        .zip(&answer.se)
        .zip(&answer.values)
        .map(|((f, se), v)| if f.log { se / v } else { *se })
        .collect();
    let mut farthest: Option<(f64, f64, usize, &[f64], f64)> = None;
    for (u, models) in &found.history {
        let r = answer.weights.residuals(&problem.data, models);
        let chi2: f64 = r.iter().map(|x| x * x).sum();
        if chi2 > limit {
            continue;
        }
        let allowed = (chi2 - best).max(1.0).sqrt();
        for j in 0..p {
            let distance = (u[j] - found.best.u[j]).abs() / se_u[j];
            let ratio = distance / allowed;
            if ratio.is_finite() && farthest.is_none_or(|f| ratio > f.0) {
                farthest = Some((ratio, distance, j, u, chi2));
            }
        }
    }
    if let Some((ratio, distance, j, u, chi2)) = farthest
        && ratio > SECOND_MINIMUM_RATIO
    {
        let free = &problem.free[j];
        answer.warn(format!(
            "the data fit almost as well (chi2 {chi2:.4e} against {best:.4e}) with `{}` = \
             {:.6e} {}, {distance:.1} standard errors from the best value: a second minimum or \
             a curved valley, which the standard errors do not describe",
            free.key,
            free.value(u[j]),
            free.units
        ));
    }
}

/// A warning for each key whose misfit has a kink at the best point
/// (`super::jacobian`), naming the data line where the sides differ most.
fn kinks(problem: &Problem, kinks: &[Option<usize>], answer: &mut Answer) {
    let measured = problem.data.measured_rows();
    for (free, kink) in problem.free.iter().zip(kinks) {
        if let Some(&(row, axis)) = kink.and_then(|i| measured.get(i)) {
            answer.warnings.push(format!(
                "the misfit has a kink at the best `{}`: step_{} of line {} changes abruptly \
                 there (a change of motion); its standard error is the gentler side's",
                free.key, AXIS_NAMES[axis], problem.data.rows[row].line
            ));
        }
    }
}

/// A warning for each value at a bound.
fn bounds(problem: &Problem, u: &[f64], answer: &mut Answer) {
    for (free, &u) in problem.free.iter().zip(u) {
        let [lo, hi] = free.coordinate_bounds();
        let near = AT_BOUND * (hi - lo);
        let side = if u - lo <= near {
            Some(("lower", free.bounds[0]))
        } else if hi - u <= near {
            Some(("upper", free.bounds[1]))
        } else {
            None
        };
        if let Some((side, bound)) = side {
            answer.warn(format!(
                "`{}` is at its {side} bound ({bound} {}): the data would move it further; \
                 its standard error assumes it is free",
                free.key, free.units
            ));
        }
    }
}

/// The notes: how each axis was weighed, the measurement's tolerance, and
/// which free `axis.x` keys move axis y too.
fn notes(problem: &Problem, found: &Found) -> Vec<String> {
    let mut notes = Vec::new();
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        if problem.data.measured_on(a) > 0 && !found.weights.known[a] {
            notes.push(format!(
                "step_{name} has no standard errors: its scale, {:.4e} m per cycle, was \
                 estimated from the residuals",
                found.weights.scale[a]
            ));
        }
    }
    if let (Some(scene), Some(fit)) = (problem.scene_step_tolerance, problem.step_tolerance) {
        let worst = worst_model_noise(problem, found);
        notes.push(format!(
            "step_tolerance {fit:.3e} m per cycle ({:.3} times the scene's {scene:.3e}), sized \
             against the data; the model's own standard error is at most {:.1} % of the data's",
            fit / scene,
            100.0 * worst
        ));
    }
    notes.extend(problem.inherited_notes());
    notes
}

/// Beyond this ratio of the model's standard error to the data's, the
/// model's own noise (a steady measurement that stopped at `max_cycles`,
/// say) weighs in the fit: a warning says so.
pub const MAX_MODEL_NOISE: f64 = 0.3;

/// A warning when the model's own standard error is not well under the
/// data's at some row (it counts in the weights either way).
fn model_noise(problem: &Problem, found: &Found, answer: &mut Answer) {
    let worst = worst_model_noise(problem, found);
    if worst > MAX_MODEL_NOISE {
        answer.warnings.push(format!(
            "the model's own standard error reaches {:.0} % of the data's at some row (the \
             steady measurement did not converge that far within max_cycles): raise \
             [simulation] max_cycles for a sharper fit",
            100.0 * worst
        ));
    }
}

/// The largest ratio of the model's standard error to the data's.
fn worst_model_noise(problem: &Problem, found: &Found) -> f64 {
    let mut worst = 0.0f64;
    for (row, model) in problem.data.rows.iter().zip(&found.best.models) {
        for a in 0..crate::model::AXES {
            if row.step[a].is_some() {
                worst = worst.max(model.se[a] / found.weights.data_se(row.se[a], a));
            }
        }
    }
    worst
}
