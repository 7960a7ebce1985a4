//! Bounded Levenberg-Marquardt with batched finite-difference Jacobians, and the
//! covariance of the fitted parameters.
//!
//! Points live in the search space (`u` coordinates) inside box bounds. The cost of a
//! residual vector `r` is `Σ r_i²` (residuals already divided by their standard errors).
//! Model evaluations go through a batch callback so that an expensive simulation can run
//! all the points of one iteration together: one batch for the Jacobian and one batch of
//! trial steps (several damping values at once) per iteration.

use anyhow::{Result, bail, ensure};

/// Residuals of a batch of candidates, each a point in the search space (u coordinates);
/// None for a candidate that is infeasible or whose evaluation failed.
pub type Batch<'a> = dyn FnMut(&[Vec<f64>]) -> anyhow::Result<Vec<Option<Vec<f64>>>> + 'a;

/// Damping values tried together in one batch, as multiples of the current lambda.
const MULTIPLIERS: [f64; 4] = [0.1, 1.0, 10.0, 100.0];
/// Factor applied to lambda when no trial lowers the cost.
const LAMBDA_UP: f64 = 1e3;
/// A search that finds no lower cost with lambda beyond this is declared stagnant.
const LAMBDA_MAX: f64 = 1e10;
/// Squared weight in dropped eigen directions above which a parameter is not identifiable.
const NULL_WEIGHT: f64 = 1e-6;

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmOptions {
    /// Most iterations (each is one Jacobian batch plus one trial batch).
    pub max_iterations: usize,
    /// Forward-difference step per parameter (u units, positive, below the bounds width).
    pub steps: Vec<f64>,
    /// Stop when an accepted step lowers the cost by less than this fraction of it.
    pub ftol: f64,
    /// Stop when a step moves every parameter by less than this fraction of its bounds width.
    pub xtol: f64,
}

impl LmOptions {
    /// Defaults (50 iterations, ftol 1e-10, xtol 1e-8) with the given steps (u units).
    pub fn new(steps: Vec<f64>) -> LmOptions {
        let (max_iterations, ftol, xtol) = (50, 1e-10, 1e-8);
        LmOptions {
            max_iterations,
            steps,
            ftol,
            xtol,
        }
    }
}

/// Outcome of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmResult {
    /// Best point found (u coordinates, inside the bounds).
    pub u: Vec<f64>,
    /// Residuals at `u`.
    pub residuals: Vec<f64>,
    /// Cost at `u`: sum of squared residuals.
    pub cost: f64,
    /// Iterations performed (one Jacobian each).
    pub iterations: usize,
    /// Points evaluated in all batches, the starting point included.
    pub evaluations: usize,
    /// Points that came back None or with non-finite residuals.
    pub failed: usize,
    /// True when stopped by ftol, xtol, a zero cost, or stagnation (no lower cost found even
    /// with lambda > 1e10: a minimum at the resolution of the finite differences); false when
    /// stopped by `max_iterations` or by the callback.
    pub converged: bool,
    /// Per parameter: whether `u` lies on a bound (within 1e-12 of the bounds width).
    pub at_bound: Vec<bool>,
}

/// Covariance of the fitted parameters and diagnostics of its conditioning.
#[derive(Debug, Clone, PartialEq)]
pub struct Covariance {
    /// `scale · (JᵀJ)⁺` (u units squared): the pseudo-inverse, finite even when rank deficient.
    pub covariance: Vec<Vec<f64>>,
    /// Standard errors (u units): `sqrt(covariance_ii)`, or infinity for a parameter whose
    /// squared weight along the dropped eigen directions exceeds 1e-6 (not identifiable).
    pub standard_errors: Vec<f64>,
    /// Correlation matrix, never NaN: 1 on the diagonal. Between two identifiable parameters
    /// it is `cov_ij / sqrt(cov_ii cov_jj)` (0 when a variance is zero); between two
    /// non-identifiable ones it is the limit for a vanishing ridge, taken from the dropped
    /// eigenvectors (e.g. -1 for two parameters entering only as their sum); 0 between an
    /// identifiable and a non-identifiable parameter.
    pub correlation: Vec<Vec<f64>>,
    /// Singular values of J (square roots of the eigenvalues of JᵀJ), descending.
    pub singular_values: Vec<f64>,
    /// Condition number of J: largest over smallest singular value (infinity if that is 0).
    pub condition: f64,
    /// True when eigenvalues of JᵀJ below 1e-12 times the largest were dropped.
    pub rank_deficient: bool,
}

/// Dense matrix, row-major.
type Matrix = Vec<Vec<f64>>;
/// Displacement (u units) and residuals of one finite-difference point.
type Probe = (f64, Vec<f64>);
/// A trial step: cost, damping lambda, point and residuals.
type Trial = (f64, f64, Vec<f64>, Vec<f64>);

/// The batch callback of one fit, its box `[lo, hi]`, the residual length `m` once known,
/// and running counts of evaluated and failed points.
struct Fit<'e, 'a> {
    eval: &'e mut Batch<'a>,
    lo: &'e [f64],
    hi: &'e [f64],
    m: Option<usize>,
    evaluations: usize,
    failed: usize,
}

impl<'e, 'a> Fit<'e, 'a> {
    fn new(eval: &'e mut Batch<'a>, lo: &'e [f64], hi: &'e [f64]) -> Self {
        let (m, evaluations, failed) = (None, 0, 0);
        Fit {
            eval,
            lo,
            hi,
            m,
            evaluations,
            failed,
        }
    }

    /// Evaluates one batch; None or non-finite residuals count as failed.
    fn run(&mut self, points: &[Vec<f64>]) -> Result<Vec<Option<Vec<f64>>>> {
        let results = (self.eval)(points)?;
        let n = results.len();
        ensure!(n == points.len(), "{n} results for {} points", points.len());
        self.evaluations += n;
        let mut checked = Vec::with_capacity(n);
        for r in results {
            let r = r.filter(|r| r.iter().all(|x| x.is_finite()));
            if let (Some(r), Some(m)) = (&r, self.m) {
                ensure!(r.len() == m, "{} residuals instead of {m}", r.len());
            }
            self.failed += usize::from(r.is_none());
            checked.push(r);
        }
        Ok(checked)
    }

    /// `u + d` clamped into the box.
    fn project(&self, u: &[f64], d: &[f64]) -> Vec<f64> {
        let (lo, hi) = (self.lo, self.hi);
        (0..u.len())
            .map(|j| (u[j] + d[j]).clamp(lo[j], hi[j]))
            .collect()
    }

    /// Largest coordinate change from `a` to `b` relative to the bounds width.
    fn relative_change(&self, a: &[f64], b: &[f64]) -> f64 {
        let change = |j: usize| (b[j] - a[j]).abs() / (self.hi[j] - self.lo[j]);
        (0..a.len()).map(change).fold(0.0, f64::max)
    }

    /// Evaluates, in one batch, `u` displaced along each parameter j by each of `deltas[j]`
    /// (clamped into the box); returns per parameter the usable displacements and residuals.
    /// Points that fail or that clamping brings back onto `u` are left out.
    fn probe(&mut self, u: &[f64], deltas: &[Vec<f64>]) -> Result<Vec<Vec<Probe>>> {
        let (mut params, mut points) = (Vec::new(), Vec::new());
        for (j, ds) in deltas.iter().enumerate() {
            for d in ds {
                let mut x = u.to_vec();
                x[j] = (u[j] + d).clamp(self.lo[j], self.hi[j]);
                if x[j] != u[j] {
                    params.push(j);
                    points.push(x);
                }
            }
        }
        let mut found = vec![Vec::new(); u.len()];
        let results = match points.is_empty() {
            true => Vec::new(),
            false => self.run(&points)?,
        };
        for ((j, x), r) in params.into_iter().zip(&points).zip(results) {
            found[j].extend(r.map(|r| (x[j] - u[j], r)));
        }
        Ok(found)
    }

    /// Jacobian by forward differences, stepping backwards where `u + h` leaves the box (one
    /// batch; failed points are retried once on the other side in a second batch).
    fn forward_jacobian(&mut self, u: &[f64], r0: &[f64], h: &[f64]) -> Result<Matrix> {
        let side = |j: usize| {
            if u[j] + h[j] <= self.hi[j] {
                h[j]
            } else {
                -h[j]
            }
        };
        let deltas: Vec<Vec<f64>> = (0..u.len()).map(|j| vec![side(j)]).collect();
        let mut found = self.probe(u, &deltas)?;
        let retry = |(j, f): (usize, &Vec<Probe>)| match f.is_empty() {
            true => vec![-side(j)],
            false => Vec::new(),
        };
        let deltas: Vec<Vec<f64>> = found.iter().enumerate().map(retry).collect();
        for (f, again) in found.iter_mut().zip(self.probe(u, &deltas)?) {
            f.extend(again);
        }
        assemble(&found, r0)
    }

    /// Trial points `(λ, u + d)` for each damping multiplier, or None when even the
    /// Gauss-Newton step is below `xtol`. Parameters on a bound with an outward gradient
    /// are held fixed.
    fn candidates(
        &self,
        u: &[f64],
        r: &[f64],
        jac: &[Vec<f64>],
        lambda: f64,
        xtol: f64,
    ) -> Option<Vec<(f64, Vec<f64>)>> {
        let (mut a, mut g) = normal_equations(jac, r);
        for j in 0..u.len() {
            if (u[j] <= self.lo[j] && g[j] > 0.0) || (u[j] >= self.hi[j] && g[j] < 0.0) {
                a.iter_mut().for_each(|row| row[j] = 0.0);
                (a[j], g[j]) = (unit(u.len(), j), 0.0);
            }
        }
        let step = |l: f64| self.project(u, &solve_damped(&a, &g, l));
        if self.relative_change(u, &step(0.0)) <= xtol {
            return None;
        }
        Some(MULTIPLIERS.map(|k| (k * lambda, step(k * lambda))).to_vec())
    }

    /// Evaluates the trial points in one batch and returns the one with the lowest cost.
    fn best_trial(&mut self, trials: Vec<(f64, Vec<f64>)>) -> Result<Option<Trial>> {
        let points: Vec<Vec<f64>> = trials.iter().map(|c| c.1.clone()).collect();
        let results = self.run(&points)?;
        let mut best: Option<Trial> = None;
        for ((lambda, u), r) in trials.into_iter().zip(results) {
            let Some(r) = r else { continue };
            let cost = sum_sq(&r);
            if best.as_ref().is_none_or(|t| cost < t.0) {
                best = Some((cost, lambda, u, r));
            }
        }
        Ok(best)
    }
}

/// Bounded Levenberg-Marquardt from `u0` (inside `[lo, hi]`, u coordinates).
///
/// Each iteration evaluates one batch of forward-difference points (stepping backwards where
/// `u + h` would leave the box; a failed point is retried once on the other side in a second
/// small batch) and one batch of trial steps `(JᵀJ + λ D) d = -Jᵀr` for
/// λ ∈ {0.1, 1, 10, 100}·lambda, with `D = diag(JᵀJ)` floored at 1e-12 of its largest entry.
/// Parameters on a bound whose gradient pushes outward are held fixed for the step; the other
/// trial points are clamped into the box. The best trial is taken if it lowers the cost and
/// lambda becomes its damping; otherwise lambda grows 1000-fold. `on_iteration(k, cost, u)` is
/// called after the starting point (k = 0) and after each iteration; returning false stops.
pub fn levenberg_marquardt(
    eval: &mut Batch<'_>,
    lo: &[f64],
    hi: &[f64],
    u0: &[f64],
    opts: &LmOptions,
    on_iteration: &mut dyn FnMut(usize, f64, &[f64]) -> bool,
) -> Result<LmResult> {
    check_problem(lo, hi, u0, &opts.steps)?;
    let (mut fit, mut u) = (Fit::new(eval, lo, hi), u0.to_vec());
    let start = fit.run(std::slice::from_ref(&u))?.pop().flatten();
    let Some(mut r) = start else {
        bail!("the model could not be evaluated at the starting point {u:?}");
    };
    fit.m = Some(r.len());
    let mut cost = sum_sq(&r);
    let (mut lambda, mut iterations, mut converged) = (1e-3, 0, cost == 0.0);
    let mut go_on = on_iteration(0, cost, &u);
    while go_on && !converged && iterations < opts.max_iterations {
        iterations += 1;
        let jac = fit.forward_jacobian(&u, &r, &opts.steps)?;
        let Some(trials) = fit.candidates(&u, &r, &jac, lambda, opts.xtol) else {
            converged = true; // even the Gauss-Newton step is below xtol
            go_on = on_iteration(iterations, cost, &u);
            continue;
        };
        match fit.best_trial(trials)? {
            Some((c, l, v, s)) if c < cost => {
                let small = fit.relative_change(&u, &v) <= opts.xtol;
                converged = small || cost - c <= opts.ftol * cost || c == 0.0;
                (cost, lambda, u, r) = (c, l.max(1e-15), v, s);
            }
            _ => {
                lambda *= LAMBDA_UP;
                converged = lambda > LAMBDA_MAX;
            }
        }
        go_on = on_iteration(iterations, cost, &u);
    }
    let at_bound = (0..u.len())
        .map(|j| (u[j] - lo[j]).min(hi[j] - u[j]) <= 1e-12 * (hi[j] - lo[j]))
        .collect();
    let (evaluations, failed, residuals) = (fit.evaluations, fit.failed, r);
    Ok(LmResult {
        u,
        residuals,
        cost,
        iterations,
        evaluations,
        failed,
        converged,
        at_bound,
    })
}

/// Covariance `scale · (JᵀJ)⁻¹` of parameters with Jacobian `j` (m rows × p columns); `scale`
/// is usually the residual variance `cost / (m - p)`, or 1 for residuals already in units of
/// their known standard errors. Uses a symmetric eigen decomposition of JᵀJ and a
/// pseudo-inverse dropping eigenvalues below 1e-12 times the largest (see [`Covariance`]).
pub fn covariance(j: &[Vec<f64>], scale: f64) -> Covariance {
    let p = j.first().map_or(0, Vec::len);
    let (a, _) = normal_equations(j, &vec![0.0; j.len()]);
    let (values, vectors) = symmetric_eigen(&a);
    let largest = values.first().map_or(0.0, |v| v.max(0.0));
    let (mut cov, mut null) = (vec![vec![0.0; p]; p], vec![vec![0.0; p]; p]);
    let mut rank_deficient = false;
    for (v, &value) in vectors.iter().zip(&values) {
        let keep = value > 1e-12 * largest && value > 0.0;
        rank_deficient |= !keep;
        // Kept directions build the pseudo-inverse, dropped ones the null-space projector.
        let (target, w) = match keep {
            true => (&mut cov, scale / value),
            false => (&mut null, 1.0),
        };
        for (a, &va) in v.iter().enumerate() {
            for (b, &vb) in v.iter().enumerate() {
                target[a][b] += w * va * vb;
            }
        }
    }
    let se = |i: usize| match null[i][i] > NULL_WEIGHT {
        true => f64::INFINITY,
        false => cov[i][i].max(0.0).sqrt(),
    };
    let smallest = values.last().copied().unwrap_or(0.0);
    Covariance {
        standard_errors: (0..p).map(se).collect(),
        correlation: correlation(&cov, &null),
        covariance: cov,
        singular_values: values.iter().map(|v| v.max(0.0).sqrt()).collect(),
        condition: match smallest > 0.0 {
            true => (largest / smallest).sqrt(),
            false => f64::INFINITY,
        },
        rank_deficient,
    }
}

/// Eigen decomposition of the symmetric matrix `a` by cyclic Jacobi rotations (meant for
/// small matrices, p ≤ ~20). Returns the eigenvalues in descending order and, for each,
/// its unit eigenvector: `vectors[k]` belongs to `values[k]`, so `a = Σ λ_k v_k v_kᵀ`.
pub fn symmetric_eigen(a: &[Vec<f64>]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = a.len();
    let mut a = a.to_vec();
    let mut v: Matrix = (0..n).map(|i| unit(n, i)).collect();
    let total: f64 = a.iter().flatten().map(|x| x * x).sum();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&k| k != i).map(move |k| (i, k)))
            .map(|(i, k)| a[i][k] * a[i][k])
            .sum();
        if off <= 1e-30 * total {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                rotate(&mut a, &mut v, p, q);
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| a[y][y].total_cmp(&a[x][x]));
    let vector = |&k: &usize| (0..n).map(|i| v[i][k]).collect();
    let values = order.iter().map(|&k| a[k][k]).collect();
    (values, order.iter().map(vector).collect())
}

/// One Jacobi rotation zeroing `a[p][q]` (p < q); accumulates it into the columns of `v`.
fn rotate(a: &mut [Vec<f64>], v: &mut [Vec<f64>], p: usize, q: usize) {
    if a[p][q] == 0.0 {
        return;
    }
    let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
    let t = match theta.abs() > 1e150 {
        true => 0.5 / theta,
        false => theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt()),
    };
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    for row in a.iter_mut().chain(v.iter_mut()) {
        let (x, y) = (row[p], row[q]);
        (row[p], row[q]) = (c * x - s * y, s * x + c * y);
    }
    let (upper, lower) = a.split_at_mut(q);
    for (x, y) in upper[p].iter_mut().zip(lower[0].iter_mut()) {
        (*x, *y) = (c * *x - s * *y, s * *x + c * *y);
    }
}

/// Correlation matrix as documented on [`Covariance::correlation`], from the covariance and
/// the projector onto the dropped eigen directions.
fn correlation(cov: &[Vec<f64>], null: &[Vec<f64>]) -> Matrix {
    let free = |i: usize| null[i][i] > NULL_WEIGHT;
    let ratio = |m: &[Vec<f64>], i: usize, j: usize| m[i][j] / (m[i][i] * m[j][j]).sqrt();
    let entry = |i: usize, j: usize| {
        let c = match (free(i), free(j)) {
            _ if i == j => 1.0,
            (true, true) => ratio(null, i, j),
            (false, false) => ratio(cov, i, j),
            _ => 0.0,
        };
        if c.is_nan() { 0.0 } else { c.clamp(-1.0, 1.0) }
    };
    let n = cov.len();
    (0..n)
        .map(|i| (0..n).map(|j| entry(i, j)).collect())
        .collect()
}

/// Rejects mismatched lengths, empty or inverted bounds, points outside, and unusable steps.
fn check_problem(lo: &[f64], hi: &[f64], u: &[f64], steps: &[f64]) -> Result<()> {
    let p = lo.len();
    let same = hi.len() == p && u.len() == p && steps.len() == p;
    ensure!(
        p > 0 && same,
        "bounds, point and steps need the same length > 0"
    );
    for j in 0..p {
        let (l, h, x, s) = (lo[j], hi[j], u[j], steps[j]);
        ensure!(l < h && (h - l).is_finite(), "bounds {j}: [{l}, {h}]");
        ensure!(l <= x && x <= h, "parameter {j} = {x} outside [{l}, {h}]");
        ensure!(s > 0.0 && s < h - l, "step {j} not in (0, hi - lo): {s}");
    }
    Ok(())
}

/// Jacobian (m rows × p columns) from each parameter's probes: central difference from two,
/// one-sided against `r0` from one; an error when a parameter has none.
fn assemble(found: &[Vec<Probe>], r0: &[f64]) -> Result<Matrix> {
    let mut jac = vec![vec![0.0; found.len()]; r0.len()];
    for (j, probes) in found.iter().enumerate() {
        let (d, r, base) = match probes.as_slice() {
            [(d1, r1), (d2, r2)] => (d1 - d2, r1, r2.as_slice()),
            [(d, r)] => (*d, r, r0),
            _ => bail!(
                "the model failed near the optimum for parameter {j} (index from 0): \
                 no finite-difference point could be evaluated on either side"
            ),
        };
        for (row, (a, b)) in jac.iter_mut().zip(r.iter().zip(base)) {
            row[j] = (a - b) / d;
        }
    }
    Ok(jac)
}

/// `(JᵀJ, Jᵀr)` for J with m rows × p columns.
fn normal_equations(jac: &[Vec<f64>], r: &[f64]) -> (Matrix, Vec<f64>) {
    let p = jac.first().map_or(0, Vec::len);
    let (mut a, mut g) = (vec![vec![0.0; p]; p], vec![0.0; p]);
    for (row, &ri) in jac.iter().zip(r) {
        for (i, &x) in row.iter().enumerate() {
            g[i] += x * ri;
            for (k, &y) in row.iter().enumerate() {
                a[i][k] += x * y;
            }
        }
    }
    (a, g)
}

/// Solves `(A + λ D) d = -g` with `D = diag(A)` floored at 1e-12 of its largest entry; if the
/// matrix is not positive definite a growing ridge is added. Zero step if all attempts fail.
fn solve_damped(a: &[Vec<f64>], g: &[f64], lambda: f64) -> Vec<f64> {
    let largest = (0..g.len()).map(|i| a[i][i]).fold(0.0, f64::max);
    let floor = if largest > 0.0 { 1e-12 * largest } else { 1.0 };
    let rhs: Vec<f64> = g.iter().map(|x| -x).collect();
    let mut ridge = 0.0;
    for _ in 0..20 {
        let mut m = a.to_vec();
        for (i, row) in m.iter_mut().enumerate() {
            row[i] += (lambda + ridge) * row[i].max(floor);
        }
        if let Some(d) = cholesky_solve(&m, &rhs) {
            return d;
        }
        ridge = if ridge == 0.0 { 1e-12 } else { ridge * 100.0 };
    }
    vec![0.0; g.len()]
}

/// Solves `m x = b` for symmetric positive definite `m` by Cholesky; None if not PD.
#[allow(clippy::needless_range_loop)]
fn cholesky_solve(m: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    let n = b.len();
    let mut l = vec![vec![0.0; n]; n];
    for i in 0..n {
        for k in 0..=i {
            let s = m[i][k] - (0..k).map(|t| l[i][t] * l[k][t]).sum::<f64>();
            if i != k {
                l[i][k] = s / l[k][k];
            } else if s > 0.0 && s.is_finite() {
                l[i][i] = s.sqrt();
            } else {
                return None;
            }
        }
    }
    let mut x = vec![0.0; n];
    for i in 0..n {
        x[i] = (b[i] - (0..i).map(|t| l[i][t] * x[t]).sum::<f64>()) / l[i][i];
    }
    for i in (0..n).rev() {
        x[i] = (x[i] - (i + 1..n).map(|t| l[t][i] * x[t]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

/// Unit vector `e_k` of length `n`.
fn unit(n: usize, k: usize) -> Vec<f64> {
    (0..n).map(|i| if i == k { 1.0 } else { 0.0 }).collect()
}

/// Sum of squares.
fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    type Model = fn(&[f64]) -> Option<Vec<f64>>;
    type Calls = RefCell<Vec<usize>>;
    type Out = Result<Vec<Option<Vec<f64>>>>;
    const SIGMA: f64 = 0.1;

    /// Batch evaluator from a pointwise model, recording the size of each batch.
    fn batched(model: Model, calls: &Calls) -> impl FnMut(&[Vec<f64>]) -> Out {
        move |pts| {
            calls.borrow_mut().push(pts.len());
            Ok(pts.iter().map(|u| model(u)).collect())
        }
    }

    /// LM with steps 1e-7 in [lo, hi]^p; returns the result and the batch sizes.
    fn fit(model: Model, lo: f64, hi: f64, u0: &[f64]) -> (Result<LmResult>, Vec<usize>) {
        let (calls, p) = (RefCell::default(), u0.len());
        let opts = LmOptions::new(vec![1e-7; p]);
        let mut eval = batched(model, &calls);
        let (lo, hi) = (vec![lo; p], vec![hi; p]);
        let res = levenberg_marquardt(&mut eval, &lo, &hi, u0, &opts, &mut |_, _, _| true);
        (res, calls.take())
    }

    /// The fit's Jacobian (`super::super::jacobian::sided`: central where both sides fit
    /// in [lo, hi]^p, one-sided at a bound) with step h, checking it is one batch.
    fn central(model: Model, lo: f64, hi: f64, u: &[f64], h: f64) -> Matrix {
        let (r0, calls, p) = (model(u).unwrap(), RefCell::default(), u.len());
        let mut eval = batched(model, &calls);
        let bounds = (&vec![lo; p][..], &vec![hi; p][..]);
        let jac = super::super::jacobian::sided(&mut eval, bounds, u, &r0, &vec![h; p]);
        assert_eq!(calls.take().len(), 1);
        jac.unwrap().j
    }

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.iter().zip(b).all(|(a, b)| (a - b).abs() <= tol)
    }

    /// Design matrix rows (1, x, x²) and data y = 1 + 2x - 0.5x² + fixed pseudo-noise.
    fn data() -> (Matrix, Vec<f64>) {
        let x = |i: usize| i as f64 * 0.5;
        let noise = |i: usize| SIGMA * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
        let y = (0..21).map(|i| 1.0 + 2.0 * x(i) - 0.5 * x(i) * x(i) + noise(i));
        let design = (0..21).map(|i| vec![1.0, x(i), x(i) * x(i)]);
        (design.collect(), y.collect())
    }

    fn quadratic(u: &[f64]) -> Option<Vec<f64>> {
        let (x, y) = data();
        let fitted = x.iter().map(|x| u[0] * x[0] + u[1] * x[1] + u[2] * x[2]);
        Some(fitted.zip(y).map(|(f, y)| f - y).collect())
    }

    fn rosenbrock(u: &[f64]) -> Option<Vec<f64>> {
        Some(vec![10.0 * (u[1] - u[0] * u[0]), 1.0 - u[0]])
    }

    #[test]
    fn linear_regression_matches_normal_equations_and_covariance() {
        let res = fit(quadratic, -10.0, 10.0, &[0.0; 3]).0.unwrap();
        let (x, y) = data();
        let (xtx, xty) = normal_equations(&x, &y);
        assert!(res.converged && close(&res.u, &cholesky_solve(&xtx, &xty).unwrap(), 1e-8));
        let c = covariance(
            &central(quadratic, -10.0, 10.0, &res.u, 1e-3),
            SIGMA * SIGMA,
        );
        assert!(!c.rank_deficient && c.condition.is_finite() && c.condition > 1.0);
        for (k, col) in c.covariance.iter().enumerate() {
            let want = cholesky_solve(&xtx, &unit(3, k)).unwrap();
            let want: Vec<f64> = want.iter().map(|w| SIGMA * SIGMA * w).collect();
            assert!(
                col.iter()
                    .zip(&want)
                    .all(|(a, b)| (a - b).abs() <= 1e-6 * b.abs())
            );
            assert_eq!(c.standard_errors[k], c.covariance[k][k].sqrt());
            assert_eq!(c.correlation[k][k], 1.0);
        }
    }

    #[test]
    fn rosenbrock_with_at_most_two_batches_per_iteration() {
        let (calls, mut seen) = (RefCell::default(), Vec::new());
        let (mut eval, opts) = (batched(rosenbrock, &calls), LmOptions::new(vec![1e-7; 2]));
        let (lo, hi, u0) = ([-2.0; 2], [2.0; 2], [-1.2, 1.0]);
        let mut log = |k: usize, c: f64, _: &[f64]| {
            seen.push((k, c));
            true
        };
        let res = levenberg_marquardt(&mut eval, &lo, &hi, &u0, &opts, &mut log).unwrap();
        let calls = calls.take();
        assert!(res.converged && close(&res.u, &[1.0, 1.0], 1e-6), "{res:?}");
        assert!(calls.len() <= 1 + 2 * res.iterations && calls.iter().all(|&n| n <= 4));
        assert_eq!(res.evaluations, calls.iter().sum::<usize>());
        assert_eq!(seen.len(), res.iterations + 1);
        assert!(
            seen.windows(2)
                .all(|w| w[1].1 <= w[0].1 && w[1].0 == w[0].0 + 1)
        );
        let mut stop = |k: usize, _: f64, _: &[f64]| k < 2;
        let res = levenberg_marquardt(&mut eval, &lo, &hi, &u0, &opts, &mut stop).unwrap();
        assert!(res.iterations == 2 && !res.converged);
    }

    #[test]
    fn bounds_are_respected_and_flagged() {
        // Unconstrained optimum (5/3, 4/3); in [0, 1]² the constrained one is the corner (1, 1).
        let model: Model = |u| Some(vec![u[0] + u[1] - 3.0, u[0] - 2.0 * u[1] + 1.0]);
        let res = fit(model, 0.0, 1.0, &[0.2, 0.2]).0.unwrap();
        assert!(res.converged && res.u == [1.0, 1.0] && res.at_bound == [true, true]);
        // Unconstrained optimum (2, 1.5); constrained: u0 = 1 on its bound, u1 = 0.5 inside.
        let model: Model = |u| Some(vec![2.0 - u[0], u[0] - 0.5 - u[1]]);
        let res = fit(model, 0.0, 1.0, &[0.2, 0.2]).0.unwrap();
        assert!(
            res.converged && res.u[0] == 1.0 && (res.u[1] - 0.5).abs() < 1e-7,
            "{res:?}"
        );
        assert_eq!(res.at_bound, [true, false]);
    }

    #[test]
    fn rank_deficient_sum_of_two_parameters() {
        // r_i = (a + b - 3 - 0.01 x_i) x_i: best a + b = 3 + 0.01 Σx³/Σx² = 3 + 1/30.
        let model: Model = |u| {
            Some(
                (1..5)
                    .map(|x| (u[0] + u[1] - 3.0 - 0.01 * x as f64) * x as f64)
                    .collect(),
            )
        };
        let res = fit(model, -5.0, 5.0, &[0.0, 0.0]).0.unwrap();
        assert!(
            (res.u[0] + res.u[1] - 3.0 - 1.0 / 30.0).abs() < 1e-6,
            "{res:?}"
        );
        let c = covariance(&central(model, -5.0, 5.0, &res.u, 1e-4), 1.0);
        assert!(c.rank_deficient && c.condition > 1e6, "{c:?}");
        assert_eq!(c.standard_errors, [f64::INFINITY; 2]);
        assert!((c.correlation[0][1] + 1.0).abs() < 1e-9, "{c:?}");
        let zero = covariance(&[vec![0.0, 0.0], vec![0.0, 0.0]], 1.0);
        assert!(zero.rank_deficient && zero.condition.is_infinite());
        assert_eq!(zero.standard_errors, [f64::INFINITY; 2]);
        assert!(zero.correlation.iter().flatten().all(|x| x.is_finite()));
    }

    #[test]
    fn failed_difference_points_are_retried_then_reported() {
        // The model fails just above the optimum u0 = 1, so forward points there fail.
        let model: Model = |u| (u[0] <= 1.0 + 1e-9).then(|| rosenbrock(u)).flatten();
        let (res, calls) = fit(model, -2.0, 2.0, &[-1.2, 1.0]);
        let res = res.unwrap();
        assert!(res.failed > 0 && calls.len() <= 1 + 3 * res.iterations);
        assert!(close(&res.u, &[1.0, 1.0], 1e-6), "{res:?}");
        let only_start: Model = |u| (u[1] == 0.5).then(|| vec![u[0] - 1.0, u[1]]);
        let err = fit(only_start, 0.0, 2.0, &[0.2, 0.5])
            .0
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("the model failed near the optimum for parameter 1"),
            "{err}"
        );
        let err = fit(|_| None, 0.0, 2.0, &[0.2, 0.5])
            .0
            .unwrap_err()
            .to_string();
        assert!(err.contains("starting point"), "{err}");
    }

    #[test]
    fn central_jacobian_is_one_sided_at_bounds() {
        let model: Model = |u| Some(vec![u[0] * u[0], u[0] * u[1], u[1].sin()]);
        let jac = central(model, 0.0, 1.0, &[1.0, 0.3], 1e-6);
        let want = [2.0, 0.0, 0.3, 1.0, 0.0, 0.3f64.cos()];
        assert!(close(&jac.concat(), &want, 1e-5), "{jac:?}");
    }

    #[test]
    fn symmetric_eigen_decomposes() {
        let (values, vectors) = symmetric_eigen(&[vec![2.0, 1.0], vec![1.0, 2.0]]);
        assert!(close(&values, &[3.0, 1.0], 1e-14));
        assert!((vectors[0][0] * vectors[0][1] - 0.5).abs() < 1e-14);
        let n = 7;
        let b = |i: usize, k: usize| ((i * k + i + k) as f64 * 0.37).sin();
        let a: Matrix = (0..n)
            .map(|i| (0..n).map(|k| b(i, k) + b(k, i)).collect())
            .collect();
        let (values, vectors) = symmetric_eigen(&a);
        assert!(values.windows(2).all(|w| w[0] >= w[1]));
        for (i, k) in (0..n).flat_map(|i| (0..n).map(move |k| (i, k))) {
            let rebuilt: f64 = (0..n)
                .map(|e| values[e] * vectors[e][i] * vectors[e][k])
                .sum();
            let dot: f64 = (0..n).map(|e| vectors[i][e] * vectors[k][e]).sum();
            assert!((rebuilt - a[i][k]).abs() < 1e-12 && (dot - unit(n, i)[k]).abs() < 1e-12);
        }
    }
}
