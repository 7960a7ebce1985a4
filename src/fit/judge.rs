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
    if let Some(j) = &found.jacobian {
        uncertainty(problem, &found.best.u, j, &mut answer);
    }
    bounds(problem, &found.best.u, &mut answer);
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
