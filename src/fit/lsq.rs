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
        LmOptions {
            max_iterations: 50,
            steps,
            ftol: 1e-10,
            xtol: 1e-8,
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
    /// Standard errors (u units): `sqrt(covariance_ii)`, or infinity for a parameter with a
    /// non-negligible component (squared weight > 1e-6) along a dropped eigen direction.
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

/// Displacement (u units) and residuals of one finite-difference point.
type Probe = (f64, Vec<f64>);

/// Counts of evaluated and failed points.
#[derive(Default)]
struct Tally {
    evaluations: usize,
    failed: usize,
}

/// A trial step: its damping, point, residuals and cost.
struct Trial {
    lambda: f64,
    u: Vec<f64>,
    r: Vec<f64>,
    cost: f64,
}

/// The box `[lo, hi]` in u coordinates.
struct Bounds<'b> {
    lo: &'b [f64],
    hi: &'b [f64],
}

impl Bounds<'_> {
    /// `u + d` clamped into the box.
    fn project(&self, u: &[f64], d: &[f64]) -> Vec<f64> {
        (0..u.len())
            .map(|j| (u[j] + d[j]).clamp(self.lo[j], self.hi[j]))
            .collect()
    }

    /// Largest coordinate change from `a` to `b` relative to the bounds width.
    fn relative_change(&self, a: &[f64], b: &[f64]) -> f64 {
        (0..a.len())
            .map(|j| (b[j] - a[j]).abs() / (self.hi[j] - self.lo[j]))
            .fold(0.0, f64::max)
    }
}

/// Bounded Levenberg-Marquardt from `u0` (clamped into `[lo, hi]`, u coordinates).
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
    let b = Bounds { lo, hi };
    let mut tally = Tally::default();
    let mut u = b.project(u0, &vec![0.0; u0.len()]);
    let start = run(eval, std::slice::from_ref(&u), None, &mut tally)?;
    let Some(mut r) = start.into_iter().next().flatten() else {
        bail!("the model could not be evaluated at the starting point {u:?}");
    };
    let mut cost = sum_sq(&r);
    let (mut lambda, mut iterations, mut converged) = (1e-3, 0, cost == 0.0);
    let mut go_on = on_iteration(0, cost, &u);
    while go_on && !converged && iterations < opts.max_iterations {
        iterations += 1;
        let jac = jacobian_forward(eval, &b, &u, &r, &opts.steps, &mut tally)?;
        let Some(trials) = candidates(&b, &u, &r, &jac, lambda, opts.xtol) else {
            converged = true; // even the Gauss-Newton step is below xtol
            go_on = on_iteration(iterations, cost, &u);
            continue;
        };
        match best_trial(eval, trials, r.len(), &mut tally)? {
            Some(t) if t.cost < cost => {
                converged = cost - t.cost <= opts.ftol * cost
                    || b.relative_change(&u, &t.u) <= opts.xtol
                    || t.cost == 0.0;
                (u, r, cost, lambda) = (t.u, t.r, t.cost, t.lambda.max(1e-15));
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
    let (evaluations, failed) = (tally.evaluations, tally.failed);
    Ok(LmResult {
        u,
        residuals: r,
        cost,
        iterations,
        evaluations,
        failed,
        converged,
        at_bound,
    })
}

/// Jacobian (m rows × p columns) at `u` (inside `[lo, hi]`, residuals `r0`) by central
/// differences with steps `steps` (u units), all 2p points in ONE batch. Where `u ± h` would
/// leave the box, or one of the two points fails, it falls back to a one-sided difference
/// against `r0`; it errors when no point is usable for a parameter.
pub fn jacobian_central(
    eval: &mut Batch<'_>,
    lo: &[f64],
    hi: &[f64],
    u: &[f64],
    r0: &[f64],
    steps: &[f64],
) -> Result<Vec<Vec<f64>>> {
    check_problem(lo, hi, u, steps)?;
    ensure!(
        u.iter()
            .zip(lo.iter().zip(hi))
            .all(|(x, (l, h))| l <= x && x <= h),
        "u is outside the bounds"
    );
    let mut probes = Vec::new();
    for (j, &h) in steps.iter().enumerate() {
        let (up, down) = (u[j] + h <= hi[j], u[j] - h >= lo[j]);
        if up || !down && hi[j] - u[j] >= u[j] - lo[j] {
            probes.push((j, h));
        }
        if down || !up && hi[j] - u[j] < u[j] - lo[j] {
            probes.push((j, -h));
        }
    }
    let found = probe_batch(
        eval,
        &Bounds { lo, hi },
        u,
        &probes,
        r0.len(),
        &mut Tally::default(),
    )?;
    let mut per_param: Vec<Vec<Probe>> = vec![Vec::new(); u.len()];
    for (&(j, _), f) in probes.iter().zip(found) {
        per_param[j].extend(f);
    }
    let columns = (0..u.len())
        .map(|j| difference(j, &per_param[j], r0))
        .collect::<Result<Vec<_>>>()?;
    Ok((0..r0.len())
        .map(|i| columns.iter().map(|c| c[i]).collect())
        .collect())
}

/// Covariance `scale · (JᵀJ)⁻¹` of parameters with Jacobian `j` (m rows × p columns); `scale`
/// is usually the residual variance `cost / (m - p)`, or 1 for residuals already in units of
/// their known standard errors. Uses a symmetric eigen decomposition of JᵀJ and a
/// pseudo-inverse dropping eigenvalues below 1e-12 times the largest (see [`Covariance`]).
pub fn covariance(j: &[Vec<f64>], scale: f64) -> Covariance {
    let p = j.first().map_or(0, Vec::len);
    let (a, _) = normal_equations(j, &vec![0.0; j.len()]);
    let (values, vectors) = symmetric_eigen(&a);
    let largest = values.first().copied().unwrap_or(0.0).max(0.0);
    let kept: Vec<bool> = values
        .iter()
        .map(|&v| v > 1e-12 * largest && v > 0.0)
        .collect();
    let mut cov = vec![vec![0.0; p]; p];
    let mut null_weight = vec![0.0; p];
    for ((v, &value), &keep) in vectors.iter().zip(&values).zip(&kept) {
        for (a, &va) in v.iter().enumerate() {
            if !keep {
                null_weight[a] += va * va;
                continue;
            }
            for (b, &vb) in v.iter().enumerate() {
                cov[a][b] += scale * va * vb / value;
            }
        }
    }
    let free: Vec<bool> = null_weight.iter().map(|&w| w > 1e-6).collect();
    let standard_errors = (0..p)
        .map(|i| {
            if free[i] {
                f64::INFINITY
            } else {
                cov[i][i].max(0.0).sqrt()
            }
        })
        .collect();
    let correlation = correlation(&cov, &vectors, &kept, &null_weight, &free);
    let smallest = values.last().copied().unwrap_or(0.0);
    let condition = if smallest > 0.0 {
        (largest / smallest).sqrt()
    } else {
        f64::INFINITY
    };
    Covariance {
        covariance: cov,
        standard_errors,
        correlation,
        singular_values: values.iter().map(|v| v.max(0.0).sqrt()).collect(),
        condition,
        rank_deficient: kept.iter().any(|k| !k),
    }
}

/// Eigen decomposition of the symmetric matrix `a` by cyclic Jacobi rotations (meant for
/// small matrices, p ≤ ~20). Returns the eigenvalues in descending order and, for each,
/// its unit eigenvector: `vectors[k]` belongs to `values[k]`, so `a = Σ λ_k v_k v_kᵀ`.
pub fn symmetric_eigen(a: &[Vec<f64>]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = a.len();
    let mut a = a.to_vec();
    let mut v: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|k| f64::from(u8::from(i == k))).collect())
        .collect();
    let norm: f64 = a.iter().flatten().map(|x| x * x).sum();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|p| (0..n).filter(move |&q| q != p).map(move |q| (p, q)))
            .map(|(p, q)| a[p][q] * a[p][q])
            .sum();
        if off <= 1e-30 * norm || off == 0.0 {
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
    let values = order.iter().map(|&k| a[k][k]).collect();
    let vectors = order
        .iter()
        .map(|&k| (0..n).map(|i| v[i][k]).collect())
        .collect();
    (values, vectors)
}

/// One Jacobi rotation zeroing `a[p][q]`; accumulates it into the columns of `v`.
fn rotate(a: &mut [Vec<f64>], v: &mut [Vec<f64>], p: usize, q: usize) {
    let apq = a[p][q];
    if apq == 0.0 {
        return;
    }
    let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
    let t = if theta.abs() > 1e150 {
        0.5 / theta
    } else {
        theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
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

/// Correlation matrix as documented on [`Covariance::correlation`].
fn correlation(
    cov: &[Vec<f64>],
    vectors: &[Vec<f64>],
    kept: &[bool],
    null_weight: &[f64],
    free: &[bool],
) -> Vec<Vec<f64>> {
    let p = cov.len();
    let null_dot = |i: usize, j: usize| -> f64 {
        vectors
            .iter()
            .zip(kept)
            .filter(|(_, k)| !**k)
            .map(|(v, _)| v[i] * v[j])
            .sum()
    };
    let entry = |i: usize, j: usize| -> f64 {
        if i == j {
            1.0
        } else if free[i] && free[j] {
            (null_dot(i, j) / (null_weight[i] * null_weight[j]).sqrt()).clamp(-1.0, 1.0)
        } else if free[i] || free[j] || cov[i][i] <= 0.0 || cov[j][j] <= 0.0 {
            0.0
        } else {
            (cov[i][j] / (cov[i][i] * cov[j][j]).sqrt()).clamp(-1.0, 1.0)
        }
    };
    (0..p)
        .map(|i| (0..p).map(|j| entry(i, j)).collect())
        .collect()
}

/// Rejects mismatched lengths, empty or inverted bounds, and unusable steps.
fn check_problem(lo: &[f64], hi: &[f64], u: &[f64], steps: &[f64]) -> Result<()> {
    let p = lo.len();
    ensure!(p > 0, "no parameters to fit");
    ensure!(
        hi.len() == p && u.len() == p && steps.len() == p,
        "bounds, point and steps must all have {p} entries"
    );
    for j in 0..p {
        let width = hi[j] - lo[j];
        ensure!(
            lo[j].is_finite() && hi[j].is_finite() && width > 0.0,
            "bounds of parameter {j} are not finite with lo < hi"
        );
        ensure!(u[j].is_finite(), "parameter {j} is not finite: {}", u[j]);
        ensure!(
            steps[j] > 0.0 && steps[j] < width,
            "step of parameter {j} must be positive and below the bounds width"
        );
    }
    Ok(())
}

/// Evaluates one batch; None or non-finite residuals count as failed. Residual vectors must
/// have length `m` when it is given.
fn run(
    eval: &mut Batch<'_>,
    points: &[Vec<f64>],
    m: Option<usize>,
    tally: &mut Tally,
) -> Result<Vec<Option<Vec<f64>>>> {
    let results = eval(points)?;
    ensure!(
        results.len() == points.len(),
        "the batch evaluator returned {} results for {} points",
        results.len(),
        points.len()
    );
    tally.evaluations += points.len();
    let mut checked = Vec::with_capacity(results.len());
    for r in results {
        let r = r.filter(|r| r.iter().all(|x| x.is_finite()));
        if let (Some(r), Some(m)) = (&r, m) {
            ensure!(
                r.len() == m,
                "the model returned {} residuals instead of {m}",
                r.len()
            );
        }
        tally.failed += usize::from(r.is_none());
        checked.push(r);
    }
    Ok(checked)
}

/// Evaluates `u + delta e_j` (clamped) for each `(j, delta)` in one batch; returns the actual
/// displacement and residuals, or None when the point failed or coincides with `u`.
fn probe_batch(
    eval: &mut Batch<'_>,
    b: &Bounds,
    u: &[f64],
    probes: &[(usize, f64)],
    m: usize,
    tally: &mut Tally,
) -> Result<Vec<Option<Probe>>> {
    let mut displacement = |&(j, delta): &(usize, f64)| {
        let mut d = vec![0.0; u.len()];
        d[j] = delta;
        b.project(u, &d)
    };
    let points: Vec<Vec<f64>> = probes.iter().map(&mut displacement).collect();
    let results = run(eval, &points, Some(m), tally)?;
    let out = probes
        .iter()
        .zip(&points)
        .zip(results)
        .map(|((&(j, _), x), r)| {
            let delta = x[j] - u[j];
            r.filter(|_| delta != 0.0).map(|r| (delta, r))
        });
    Ok(out.collect())
}

/// Jacobian by forward differences (one batch; failed points retried once on the other side).
fn jacobian_forward(
    eval: &mut Batch<'_>,
    b: &Bounds,
    u: &[f64],
    r0: &[f64],
    steps: &[f64],
    tally: &mut Tally,
) -> Result<Vec<Vec<f64>>> {
    let probes: Vec<(usize, f64)> = (0..u.len())
        .map(|j| {
            (
                j,
                if u[j] + steps[j] <= b.hi[j] {
                    steps[j]
                } else {
                    -steps[j]
                },
            )
        })
        .collect();
    let mut found = probe_batch(eval, b, u, &probes, r0.len(), tally)?;
    let retry: Vec<(usize, f64)> = probes
        .iter()
        .filter(|&&(j, _)| found[j].is_none())
        .map(|&(j, d)| (j, -d))
        .collect();
    if !retry.is_empty() {
        let again = probe_batch(eval, b, u, &retry, r0.len(), tally)?;
        for (&(j, _), f) in retry.iter().zip(again) {
            found[j] = f;
        }
    }
    let columns = found
        .iter()
        .enumerate()
        .map(|(j, f)| difference(j, f.as_slice(), r0))
        .collect::<Result<Vec<_>>>()?;
    Ok((0..r0.len())
        .map(|i| columns.iter().map(|c| c[i]).collect())
        .collect())
}

/// Jacobian column from one (one-sided against `r0`) or two (central) displaced evaluations.
fn difference(j: usize, found: &[Probe], r0: &[f64]) -> Result<Vec<f64>> {
    match found {
        [(d1, r1), (d2, r2)] => Ok(r1
            .iter()
            .zip(r2)
            .map(|(a, b)| (a - b) / (d1 - d2))
            .collect()),
        [(d, r)] => Ok(r.iter().zip(r0).map(|(a, b)| (a - b) / d).collect()),
        _ => bail!(
            "the model failed near the optimum for parameter {j} (index from 0): no finite-difference point could be evaluated on either side"
        ),
    }
}

/// `(JᵀJ, Jᵀr)` for J with m rows × p columns.
fn normal_equations(jac: &[Vec<f64>], r: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
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

/// Trial points for each damping multiplier, or None when even the Gauss-Newton step is
/// below `xtol`. Parameters on a bound with an outward gradient are held fixed.
fn candidates(
    b: &Bounds,
    u: &[f64],
    r: &[f64],
    jac: &[Vec<f64>],
    lambda: f64,
    xtol: f64,
) -> Option<Vec<(f64, Vec<f64>)>> {
    let (mut a, mut g) = normal_equations(jac, r);
    for j in 0..u.len() {
        if (u[j] <= b.lo[j] && g[j] > 0.0) || (u[j] >= b.hi[j] && g[j] < 0.0) {
            a.iter_mut().for_each(|row| row[j] = 0.0);
            a[j].iter_mut().for_each(|x| *x = 0.0);
            (a[j][j], g[j]) = (1.0, 0.0);
        }
    }
    let gauss_newton = b.project(u, &solve_damped(&a, &g, 0.0));
    if b.relative_change(u, &gauss_newton) <= xtol {
        return None;
    }
    Some(
        MULTIPLIERS
            .iter()
            .map(|k| (k * lambda, b.project(u, &solve_damped(&a, &g, k * lambda))))
            .collect(),
    )
}

/// Evaluates the trial points in one batch and returns the one with the lowest cost.
fn best_trial(
    eval: &mut Batch<'_>,
    candidates: Vec<(f64, Vec<f64>)>,
    m: usize,
    tally: &mut Tally,
) -> Result<Option<Trial>> {
    let points: Vec<Vec<f64>> = candidates.iter().map(|c| c.1.clone()).collect();
    let results = run(eval, &points, Some(m), tally)?;
    let mut best: Option<Trial> = None;
    for ((lambda, u), r) in candidates.into_iter().zip(results) {
        let Some(r) = r else { continue };
        let cost = sum_sq(&r);
        if best.as_ref().is_none_or(|t| cost < t.cost) {
            best = Some(Trial { lambda, u, r, cost });
        }
    }
    Ok(best)
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
    let mut y = vec![0.0; n];
    for i in 0..n {
        y[i] = (b[i] - (0..i).map(|t| l[i][t] * y[t]).sum::<f64>()) / l[i][i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        x[i] = (y[i] - (i + 1..n).map(|t| l[t][i] * x[t]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

/// Sum of squares.
fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    type Out = anyhow::Result<Vec<Option<Vec<f64>>>>;

    /// Batch evaluator from a pointwise model, recording the size of each batch.
    fn batched<'a>(
        model: impl Fn(&[f64]) -> Option<Vec<f64>> + 'a,
        calls: &'a RefCell<Vec<usize>>,
    ) -> impl FnMut(&[Vec<f64>]) -> Out + 'a {
        move |pts: &[Vec<f64>]| {
            calls.borrow_mut().push(pts.len());
            Ok(pts.iter().map(|u| model(u)).collect())
        }
    }

    fn fit(
        model: impl Fn(&[f64]) -> Option<Vec<f64>>,
        lo: &[f64],
        hi: &[f64],
        u0: &[f64],
    ) -> (Result<LmResult>, Vec<usize>) {
        let calls = RefCell::new(Vec::new());
        let mut eval = batched(model, &calls);
        let opts = LmOptions::new(vec![1e-7; u0.len()]);
        let res = levenberg_marquardt(&mut eval, lo, hi, u0, &opts, &mut |_, _, _| true);
        drop(eval);
        (res, calls.into_inner())
    }

    const SIGMA: f64 = 0.1;

    fn xs() -> Vec<f64> {
        (0..21).map(|i| i as f64 * 0.5).collect()
    }

    /// y = 1 + 2x - 0.5x² plus fixed pseudo-noise of scale SIGMA.
    fn ys() -> Vec<f64> {
        let noise = |i: usize| SIGMA * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
        xs().iter()
            .enumerate()
            .map(|(i, x)| 1.0 + 2.0 * x - 0.5 * x * x + noise(i))
            .collect()
    }

    fn quadratic(u: &[f64]) -> Option<Vec<f64>> {
        Some(
            xs().iter()
                .zip(ys())
                .map(|(x, y)| u[0] + u[1] * x + u[2] * x * x - y)
                .collect(),
        )
    }

    /// (XᵀX)⁻¹ and the least-squares solution from the normal equations.
    fn normal_solution() -> (Vec<Vec<f64>>, Vec<f64>) {
        let x: Vec<Vec<f64>> = xs().iter().map(|x| vec![1.0, *x, x * x]).collect();
        let (xtx, xty) = normal_equations(&x, &ys());
        let inverse: Vec<Vec<f64>> = (0..3)
            .map(|k| cholesky_solve(&xtx, &[0, 1, 2].map(|i| f64::from(u8::from(i == k)))).unwrap())
            .collect();
        (inverse, cholesky_solve(&xtx, &xty).unwrap())
    }

    fn rosenbrock(u: &[f64]) -> Option<Vec<f64>> {
        Some(vec![10.0 * (u[1] - u[0] * u[0]), 1.0 - u[0]])
    }

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn linear_regression_matches_normal_equations_and_covariance() {
        let (lo, hi) = ([-10.0; 3], [10.0; 3]);
        let (res, _) = fit(quadratic, &lo, &hi, &[0.0, 0.0, 0.0]);
        let res = res.unwrap();
        let (inverse, exact) = normal_solution();
        assert!(res.converged);
        for (a, b) in res.u.iter().zip(&exact) {
            assert!((a - b).abs() < 1e-8, "{:?} vs {exact:?}", res.u);
        }
        let calls = RefCell::default();
        let mut eval = batched(quadratic, &calls);
        let jac =
            jacobian_central(&mut eval, &lo, &hi, &res.u, &res.residuals, &[1e-3; 3]).unwrap();
        let c = covariance(&jac, SIGMA * SIGMA);
        assert!(!c.rank_deficient && c.condition.is_finite());
        for i in 0..3 {
            for k in 0..3 {
                let want = SIGMA * SIGMA * inverse[i][k];
                assert!(
                    (c.covariance[i][k] - want).abs() <= 1e-6 * want.abs(),
                    "{i} {k}"
                );
            }
            assert!((c.standard_errors[i] - c.covariance[i][i].sqrt()).abs() < 1e-15);
            assert_eq!(c.correlation[i][i], 1.0);
        }
    }

    #[test]
    fn rosenbrock_from_the_classic_start() {
        let (res, _) = fit(rosenbrock, &[-2.0, -2.0], &[2.0, 2.0], &[-1.2, 1.0]);
        let res = res.unwrap();
        assert!(res.converged, "{res:?}");
        assert!(
            (res.u[0] - 1.0).abs() < 1e-6 && (res.u[1] - 1.0).abs() < 1e-6,
            "{res:?}"
        );
    }

    #[test]
    fn bounds_are_respected_and_flagged() {
        // Unconstrained optimum (1.5, 1.5); with u0 <= 1 the constrained one is (1, 1.5).
        let model = |u: &[f64]| Some(vec![u[0] + u[1] - 3.0, u[0] - u[1]]);
        let (res, _) = fit(model, &[0.0, 0.0], &[1.0, 2.0], &[0.2, 0.2]);
        let res = res.unwrap();
        assert!(res.converged, "{res:?}");
        assert_eq!(res.u[0], 1.0);
        assert!((res.u[1] - 1.5).abs() < 1e-7, "{res:?}");
        assert_eq!(res.at_bound, vec![true, false]);
    }

    #[test]
    fn rank_deficient_sum_of_two_parameters() {
        let x = [1.0, 2.0, 3.0, 4.0];
        let model = move |u: &[f64]| {
            Some(
                x.iter()
                    .map(|x| (u[0] + u[1]) * x - 3.0 * x - 0.01 * x * x)
                    .collect(),
            )
        };
        let (lo, hi) = ([-5.0; 2], [5.0; 2]);
        let (res, _) = fit(model, &lo, &hi, &[0.0, 0.0]);
        let res = res.unwrap();
        let best_sum = 3.0 + 0.01 * 30.0 / 10.0 * 10.0 / 10.0; // Σx³/Σx² = 100/30
        assert!(
            (res.u[0] + res.u[1] - (3.0 + 0.01 * 100.0 / 30.0)).abs() < 1e-6,
            "{res:?} {best_sum}"
        );
        let calls = RefCell::default();
        let mut eval = batched(model, &calls);
        let jac =
            jacobian_central(&mut eval, &lo, &hi, &res.u, &res.residuals, &[1e-4; 2]).unwrap();
        let c = covariance(&jac, 1.0);
        assert!(c.rank_deficient);
        assert_eq!(c.standard_errors, vec![f64::INFINITY; 2]);
        assert!((c.correlation[0][1] + 1.0).abs() < 1e-9, "{c:?}");
        assert!(c.condition > 1e6, "{c:?}");
    }

    #[test]
    fn at_most_two_batches_per_iteration() {
        let calls = RefCell::new(Vec::new());
        let mut eval = batched(rosenbrock, &calls);
        let opts = LmOptions::new(vec![1e-7; 2]);
        let mut seen = Vec::new();
        let res = levenberg_marquardt(
            &mut eval,
            &[-2.0; 2],
            &[2.0; 2],
            &[-1.2, 1.0],
            &opts,
            &mut |k, c, _| {
                seen.push((k, c));
                true
            },
        );
        let res = res.unwrap();
        let calls = calls.take();
        assert!(
            calls.len() <= 1 + 2 * res.iterations,
            "{} calls, {} iterations",
            calls.len(),
            res.iterations
        );
        assert!(
            calls
                .iter()
                .all(|&n| n == 1 || n == 2 || n == MULTIPLIERS.len())
        );
        assert_eq!(res.evaluations, calls.iter().sum::<usize>());
        assert_eq!(seen.len(), res.iterations + 1);
        assert!(seen.windows(2).all(|w| w[1].1 <= w[0].1));
    }

    #[test]
    fn callback_can_stop() {
        let calls = RefCell::default();
        let mut eval = batched(rosenbrock, &calls);
        let opts = LmOptions::new(vec![1e-7; 2]);
        let res = levenberg_marquardt(
            &mut eval,
            &[-2.0; 2],
            &[2.0; 2],
            &[-1.2, 1.0],
            &opts,
            &mut |k, _, _| k < 2,
        );
        let res = res.unwrap();
        assert_eq!(res.iterations, 2);
        assert!(!res.converged);
    }

    #[test]
    fn failed_difference_point_is_retried_on_the_other_side() {
        // The model fails just above the optimum of u0 (= 1), so forward points there fail.
        let model = |u: &[f64]| {
            if u[0] > 1.0 + 1e-9 {
                None
            } else {
                rosenbrock(u)
            }
        };
        let (res, calls) = fit(model, &[-2.0; 2], &[2.0; 2], &[-1.2, 1.0]);
        let res = res.unwrap();
        assert!(res.failed > 0 && calls.len() <= 1 + 3 * res.iterations);
        assert!(
            (res.u[0] - 1.0).abs() < 1e-6 && (res.u[1] - 1.0).abs() < 1e-6,
            "{res:?}"
        );
    }

    #[test]
    fn failure_on_both_sides_is_an_error() {
        let model = |u: &[f64]| {
            if u[1] == 0.5 {
                Some(vec![u[0] - 1.0, u[1]])
            } else {
                None
            }
        };
        let (res, _) = fit(model, &[0.0; 2], &[2.0; 2], &[0.2, 0.5]);
        let msg = res.unwrap_err().to_string();
        assert!(
            msg.contains("the model failed near the optimum for parameter 1"),
            "{msg}"
        );
        let (res, _) = fit(|_| None, &[0.0; 2], &[2.0; 2], &[0.2, 0.5]);
        assert!(res.unwrap_err().to_string().contains("starting point"));
    }

    #[test]
    fn central_jacobian_is_one_batch_and_one_sided_at_bounds() {
        let model = |u: &[f64]| Some(vec![u[0] * u[0], u[0] * u[1], u[1].sin()]);
        let calls = RefCell::new(Vec::new());
        let mut eval = batched(model, &calls);
        let u = [1.0, 0.3];
        let r0 = model(&u).unwrap();
        let jac =
            jacobian_central(&mut eval, &[0.0, 0.0], &[1.0, 1.0], &u, &r0, &[1e-6; 2]).unwrap();
        assert_eq!(calls.take(), vec![3]);
        let want = [[2.0, 0.0], [0.3, 1.0], [0.0, 0.3f64.cos()]];
        for (row, w) in jac.iter().zip(want) {
            for (a, b) in row.iter().zip(w) {
                assert!((a - b).abs() < 1e-5, "{jac:?}");
            }
        }
    }

    #[test]
    fn symmetric_eigen_decomposes() {
        let (values, vectors) = symmetric_eigen(&[vec![2.0, 1.0], vec![1.0, 2.0]]);
        assert!((values[0] - 3.0).abs() < 1e-14 && (values[1] - 1.0).abs() < 1e-14);
        assert!((vectors[0][0] * vectors[0][1] - 0.5).abs() < 1e-14);
        let n = 7;
        let a: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|k| ((i * k + i + k) as f64 * 0.37).sin() + if i == k { 2.0 } else { 0.0 })
                    .collect()
            })
            .collect();
        let a: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|k| a[i][k] + a[k][i]).collect())
            .collect();
        let (values, vectors) = symmetric_eigen(&a);
        assert!(values.windows(2).all(|w| w[0] >= w[1]));
        for i in 0..n {
            for k in 0..n {
                let rebuilt: f64 = (0..n)
                    .map(|e| values[e] * vectors[e][i] * vectors[e][k])
                    .sum();
                let dot: f64 = (0..n).map(|e| vectors[i][e] * vectors[k][e]).sum();
                assert!((rebuilt - a[i][k]).abs() < 1e-12);
                assert!((dot - f64::from(u8::from(i == k))).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn covariance_of_a_zero_jacobian_is_fully_undetermined() {
        let c = covariance(&[vec![0.0, 0.0], vec![0.0, 0.0]], 1.0);
        assert!(c.rank_deficient && c.condition.is_infinite());
        assert_eq!(c.standard_errors, vec![f64::INFINITY; 2]);
        assert!(c.correlation.iter().flatten().all(|x| x.is_finite()));
    }
}
