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
    /// Standard errors in the keys' units, as reported (`fit.errors`:
    /// the data's as given, or scaled), NaN where unknown (interrupted, or
    /// a key no side could probe).
    pub se: Vec<f64>,
    /// The standard errors scaled by sqrt(reduced chi2), where the p-value
    /// warns or `fit.errors = "scaled"` asks for them.
    pub se_scaled: Option<Vec<f64>>,
    /// The covariance of the free keys in their units (the delta method
    /// for a key searched on a log scale), from the same Jacobian as `se`
    /// and scaled as it is.
    pub covariance: Vec<Vec<f64>>,
    /// The chance of a chi2 this large on `dof` degrees of freedom, where
    /// every measured axis has the data's standard errors (`None` where a
    /// scale came from the residuals, or `dof` <= 0).
    pub p_value: Option<f64>,
    /// The profile-likelihood intervals per key (`None`: skipped with
    /// `--no-intervals`, or interrupted).
    pub intervals: Option<Vec<super::profile::Interval>>,
    /// The profiles walked, per key (search coordinate, rise of chi2).
    pub profiles: Vec<Vec<(f64, f64)>>,
    /// The rises of chi2 that bound the 68 % and 95 % intervals.
    pub thresholds: [f64; 2],
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
        se_scaled: None,
        covariance: vec![vec![f64::NAN; p]; p],
        p_value: None,
        intervals: found.profiles.as_ref().map(|p| p.intervals.clone()),
        profiles: found
            .profiles
            .as_ref()
            .map(|p| p.curves.clone())
            .unwrap_or_default(),
        thresholds: found
            .profiles
            .as_ref()
            .map_or([f64::NAN; 2], |p| p.thresholds),
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
    if dof <= 0 && !found.weights.all_given(&problem.data) {
        answer.warn(format!(
            "{} measured values for {p} free keys and no standard errors in the data: no \
             degree of freedom is left to estimate the data's scale from, so the standard \
             errors say nothing",
            problem.data.measurements()
        ));
    }
    if let Some(sided) = &found.jacobian {
        uncertainty(problem, &found.best.u, sided, &mut answer);
        goodness(problem, &found, &mut answer);
        kinks(problem, &sided.kinks, &mut answer);
        second_minimum(problem, &found, &mut answer);
        wider_than_bounds(problem, &mut answer);
    }
    open_intervals(problem, &mut answer);
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

/// Standard errors, correlations and the Jacobian's condition, of the
/// keys some side could probe (`sided.probed`); the others' stay unknown
/// (NaN, null in FIT.json), with a warning.
fn uncertainty(problem: &Problem, u: &[f64], sided: &super::jacobian::Sided, answer: &mut Answer) {
    let (j, probed) = (&sided.j, &sided.probed);
    let cov = super::lsq::covariance(j, 1.0);
    for (c, &i) in probed.iter().enumerate() {
        let (free, se_u) = (&problem.free[i], cov.standard_errors[c]);
        answer.se[i] = if free.log {
            free.value(u[i]) * se_u
        } else {
            se_u
        };
    }
    let p = problem.free.len();
    answer.correlation = vec![vec![f64::NAN; p]; p];
    // d value / d coordinate: the value itself on a log scale.
    let slope = |i: usize| match problem.free[i].log {
        true => problem.free[i].value(u[i]),
        false => 1.0,
    };
    for (a, &i) in probed.iter().enumerate() {
        for (b, &k) in probed.iter().enumerate() {
            answer.correlation[i][k] = cov.correlation[a][b];
            answer.covariance[i][k] = cov.covariance[a][b] * slope(i) * slope(k);
        }
    }
    for (i, free) in problem.free.iter().enumerate() {
        if !probed.contains(&i) {
            answer.warn(format!(
                "`{}` could be probed on neither side of its best value (the model failed or a                  scene rule refused both): its standard error is unknown",
                free.key
            ));
        }
    }
    let widths: Vec<f64> = probed
        .iter()
        .map(|&i| {
            let [lo, hi] = problem.free[i].coordinate_bounds();
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

/// The p-value of the misfit where the data give every standard error,
/// its warning below [`super::goodness::P_WARN`] with the scaled standard
/// errors beside, and the scaled ones reported where `fit.errors` asks.
fn goodness(problem: &Problem, found: &Found, answer: &mut Answer) {
    use super::goodness::{P_WARN, p_value};
    use super::spec::Errors;
    if found.weights.all_given(&problem.data) {
        answer.p_value = p_value(answer.chi2, answer.dof);
    }
    let reduced = (answer.dof > 0).then(|| answer.chi2 / answer.dof as f64);
    let scaled = |factor: f64| -> Vec<f64> { answer.se.iter().map(|se| se * factor).collect() };
    let warned = answer.p_value.is_some_and(|p| p < P_WARN);
    match (problem.errors, reduced) {
        (Errors::Scaled, Some(r)) => {
            let factor = r.sqrt();
            answer.se_scaled = Some(scaled(factor));
            answer.se = scaled(factor);
            for row in answer.covariance.iter_mut() {
                row.iter_mut().for_each(|c| *c *= r);
            }
            answer.notes.push(format!(
                "fit.errors = \"scaled\": the standard errors are scaled by sqrt(reduced chi2) \
                 = {factor:.4} (lmfit's scale_covar)"
            ));
        }
        (Errors::Scaled, None) => answer.warn(
            "fit.errors = \"scaled\" needs at least one degree of freedom: the standard errors \
             are the data's as given"
                .into(),
        ),
        (Errors::Given, Some(r)) if warned => {
            answer.se_scaled = Some(scaled(r.sqrt()));
            answer.warnings.push(format!(
                "chi2 {:.4e} on {} degrees of freedom has p = {:.2e}: the data's standard \
                 errors are too small for the misfit (or the model misses the data); the \
                 standard errors scaled by sqrt(reduced chi2) = {:.3} are given beside \
                 (fit.errors = \"scaled\" reports them)",
                answer.chi2,
                answer.dof,
                answer.p_value.unwrap_or(f64::NAN),
                r.sqrt()
            ));
        }
        _ => {}
    }
}

/// Not identifiable where a key's 68 % profile interval is open: the
/// misfit never rises by the 68 % threshold inside its bounds
/// on some side.
fn open_intervals(problem: &Problem, answer: &mut Answer) {
    let Some(intervals) = answer.intervals.clone() else {
        return;
    };
    for (free, interval) in problem.free.iter().zip(intervals) {
        let sides: Vec<&str> = [("lower", interval.lo68), ("upper", interval.hi68)]
            .into_iter()
            .filter(|(_, v)| v.is_none())
            .map(|(side, _)| side)
            .collect();
        if !sides.is_empty() {
            answer.warn(format!(
                "`{}`: its 68 % interval is open on the {} side: the misfit never rises by \
                 {:.3} there inside the bounds, so the data do not bound it",
                free.key,
                sides.join(" and "),
                answer.thresholds[0]
            ));
        }
    }
}

/// Not identifiable where a key's standard error is wider than its bounds:
/// the data barely constrain it inside them.
fn wider_than_bounds(problem: &Problem, answer: &mut Answer) {
    for (i, free) in problem.free.iter().enumerate() {
        let [lo, hi] = free.bounds;
        let se = answer.se[i];
        if se.is_finite() && se > hi - lo {
            answer.warn(format!(
                "`{}`: its standard error ({se:.3e} {}) is wider than its bounds ({lo} to {hi}): \
                 the data barely constrain it",
                free.key, free.units
            ));
        }
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
    if let Some(profiles) = &found.profiles {
        notes.push(format!(
            "the profile-likelihood intervals bound rises of chi2 by {:.3} (68 %) and {:.3} \
             (95 %; 1 and 3.84 where the data's errors are known, Student's quantiles squared \
             where repeats or residuals estimate them) and cost {} candidates ({} for the \
             whole fit; --no-intervals skips them)",
            profiles.thresholds[0],
            profiles.thresholds[1],
            profiles.evaluations,
            problem.evaluations
        ));
    }
    if found.restarts > 0 {
        notes.push(format!(
            "the local stage started again {} time(s) from a probe that fit better than its \
             end: the values, chi2, rows and standard errors are all at the final point",
            found.restarts
        ));
    }
    if let Some(chi2) = found.beaten {
        notes.push(format!(
            "an evaluation next to the final point fit slightly better (chi2 {chi2:.6e}) after \
             the last restart; the values reported are the local stage's end"
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
/// data's at some row (it never enters the weights, so a noisy model only
/// shows as scatter in the misfit).
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
