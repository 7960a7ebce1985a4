//! The search of a fit (docs/fit.md): a global stage over the bounds
//! (differential evolution, one batch per generation), a local stage
//! (Levenberg-Marquardt, its Jacobian by finite differences one batch at a
//! time), the per-axis scales re-estimated where the data give no standard
//! errors, and the covariance from a central-difference Jacobian.
//!
//! The measurement's `step_tolerance` is tightened to a tenth of the data's
//! smallest standard error, so that the model's own noise stays well under
//! the data's; it never enters the weights (`super::weights`).

use anyhow::Result;

use super::jacobian;
use super::lsq::{self, LmOptions};
use super::problem::{Problem, RowModel};
use super::ticker::Ticker;
use super::weights::Weights;
use crate::search::evolution::{self as search, DeOptions, Fitness};

/// The tightest step tolerance a fit asks for [m per own drive cycle]:
/// the integrator's own error, 1e-4 um (docs/model.md section 4), below
/// which a tighter measurement buys nothing.
pub const TIGHTEST_STEP_TOLERANCE: f64 = 1e-10;

/// The model's noise allowed against the data's: its step tolerance is
/// this fraction of the data's smallest standard error.
pub const NOISE_FRACTION: f64 = 0.1;

/// How a fit ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The local stage converged.
    Converged,
    /// The local stage ran out of iterations.
    NotConverged,
    /// Ctrl-C: the best point so far, without standard errors.
    Interrupted,
}

/// The best point a fit has seen.
#[derive(Clone, Debug)]
pub struct Best {
    /// Search coordinates.
    pub u: Vec<f64>,
    pub chi2: f64,
    pub models: Vec<RowModel>,
}

/// What a search found, before it is judged (`super::judge`).
pub struct Found {
    pub best: Best,
    pub weights: Weights,
    pub ending: Ending,
    /// The Jacobian at the best point (weighted residuals by search
    /// coordinates, `super::jacobian`); `None` when interrupted.
    pub jacobian: Option<jacobian::Sided>,
    pub generations: usize,
    pub iterations: usize,
    /// Every candidate evaluated (search coordinates) with its rows' model,
    /// for the search for a second minimum (`super::judge`).
    pub history: Vec<(Vec<f64>, Vec<RowModel>)>,
    /// The profile-likelihood intervals (`super::profile`), unless skipped
    /// or interrupted.
    pub profiles: Option<super::profile::Profiles>,
    /// Times the local stage started again from a probe that fit better
    /// than its end.
    pub restarts: usize,
    /// The chi2 of an evaluation that still fit better than the reported
    /// point after the last restart, if one did.
    pub beaten: Option<f64>,
}

/// The global stage's population per free key (from 20 to 60 in all) and
/// its generations: the misfit of impact-drive steps has narrow valleys
/// along kinks (a row whose motion changes), which a smaller population
/// misses in about one fit in twenty (results/fit.md).
const GLOBAL_POPULATION_PER_KEY: usize = 12;
const GLOBAL_GENERATIONS: usize = 60;

/// The global stage's population for `p` free keys.
fn global_population(p: usize) -> usize {
    (GLOBAL_POPULATION_PER_KEY * p).clamp(20, 60)
}

/// About how many candidates a fit of `p` free keys evaluates, for
/// `pidm check`'s estimate: the global stage whole, and each local start
/// about six iterations of `p + 4` candidates.
pub fn expected_candidates(p: usize) -> u64 {
    let global = global_population(p) * (GLOBAL_GENERATIONS + 1);
    let local = STARTS * 6 * (p + 4);
    (global + local) as u64
}

/// Starts of the local stage (`Search::local_from_starts`).
const STARTS: usize = 6;

/// How far apart the local stage's starts lie, at least, in some key
/// [fraction of the bounds' width].
const START_SPACING: f64 = 0.1;

/// Rounds of sizing the difference steps by the standard errors they give
/// before the final Jacobian.
const ERROR_STEP_ROUNDS: usize = 2;

/// Restarts of the local stage from a probe that fit better than its end.
const MAX_RESTARTS: usize = 3;

/// The most memory [`Found::history`] takes [bytes]: about 2,000
/// candidates of 1,000 rows, or all of a fit of 30.
const HISTORY_BYTES: usize = 64 << 20;

/// A fit in progress: the problem, the weights and the best point.
pub struct Search<'p, 'a> {
    pub problem: &'p mut Problem<'a>,
    pub weights: Weights,
    pub best: Option<Best>,
    history: Vec<(Vec<f64>, Vec<RowModel>)>,
    ticker: Ticker,
    widths: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Whether the profile-likelihood intervals are walked (`--no-intervals`
    /// skips them).
    pub intervals: bool,
}

impl<'p, 'a> Search<'p, 'a> {
    pub fn new(problem: &'p mut Problem<'a>, ticker: Ticker) -> Search<'p, 'a> {
        let weights = Weights::initial(&problem.data);
        let lo: Vec<f64> = problem
            .free
            .iter()
            .map(|f| f.coordinate_bounds()[0])
            .collect();
        let hi: Vec<f64> = problem
            .free
            .iter()
            .map(|f| f.coordinate_bounds()[1])
            .collect();
        let widths = lo.iter().zip(&hi).map(|(l, h)| h - l).collect();
        Search {
            problem,
            weights,
            best: None,
            history: Vec::new(),
            ticker,
            widths,
            lo,
            hi,
            intervals: true,
        }
    }

    /// The free keys' values at search coordinates `u`.
    pub fn values(&self, u: &[f64]) -> Vec<f64> {
        self.problem
            .free
            .iter()
            .zip(u)
            .map(|(f, &u)| f.value(u))
            .collect()
    }

    /// Runs the whole search with `seed`; on Ctrl-C, the best point so far.
    pub fn run(mut self, seed: u64) -> Result<Found> {
        let result = self.stages(seed);
        self.ticker.finish();
        match result {
            Ok(found) => Ok(found),
            Err(_) if crate::interrupt::interrupt_requested() && self.best.is_some() => Ok(Found {
                best: self.best.clone().expect("checked"),
                weights: self.weights,
                ending: Ending::Interrupted,
                jacobian: None,
                generations: 0,
                iterations: 0,
                history: Vec::new(),
                profiles: None,
                restarts: 0,
                beaten: None,
            }),
            Err(e) => Err(e),
        }
    }

    fn stages(&mut self, seed: u64) -> Result<Found> {
        self.size_tolerance();
        let de = self.global(seed)?;
        let mut steps: Vec<f64> = self.widths.iter().map(|w| 1e-3 * w).collect();
        let mut lm = self.local_from_starts(&de.best, &steps)?;
        if self.weights.estimated() {
            // The scales the residuals show, then the fit again with them
            // (and with the measurement sized against them).
            let models = self.best_models();
            self.weights = self
                .weights
                .reestimated(&self.problem.data, &models, steps.len());
            self.size_tolerance();
            self.best = None;
            steps = self.error_steps(&lm.u, &steps)?;
            let u = lm.u.clone();
            lm = self.local(&u, &steps)?;
        }
        // One point: values, chi2, rows and standard errors all at the
        // local stage's end; where an evaluation since (a probe) fit
        // better, the local stage starts again from there.
        let mut restarts = 0;
        let (jacobian, point, profiles) = loop {
            self.ticker.stage("errors");
            for _ in 0..ERROR_STEP_ROUNDS {
                steps = self.error_steps(&lm.u, &steps)?;
            }
            let point = self.point(&lm.u)?;
            let jacobian = self.jacobian(&lm.u, &lm.residuals, &steps)?;
            let profiles = match self.intervals {
                true => Some(self.profiles_at(&lm.u, &point, &jacobian)?),
                false => None,
            };
            let best = self.best.clone().expect("the point was evaluated");
            if best.chi2 < point.chi2 * (1.0 - 1e-9) && restarts < MAX_RESTARTS {
                restarts += 1;
                lm = self.local(&best.u, &steps)?;
                continue;
            }
            break (jacobian, point, profiles);
        };
        Ok(Found {
            profiles,
            restarts,
            beaten: self
                .best
                .as_ref()
                .filter(|b| b.chi2 < point.chi2 * (1.0 - 1e-9))
                .map(|b| b.chi2),
            best: point,
            weights: self.weights,
            ending: if lm.converged {
                Ending::Converged
            } else {
                Ending::NotConverged
            },
            jacobian: Some(jacobian),
            generations: de.generations,
            iterations: lm.iterations,
            history: std::mem::take(&mut self.history),
        })
    }

    fn best_models(&self) -> Vec<RowModel> {
        self.best
            .as_ref()
            .map(|b| b.models.clone())
            .unwrap_or_default()
    }

    /// Tightens the steady measurement's tolerance to [`NOISE_FRACTION`] of
    /// the data's smallest standard error (at most the scene's, at least
    /// [`TIGHTEST_STEP_TOLERANCE`]).
    fn size_tolerance(&mut self) {
        let Some(scene) = self.problem.scene_step_tolerance else {
            return;
        };
        let wanted = NOISE_FRACTION * self.weights.smallest_se(&self.problem.data);
        self.problem.step_tolerance = Some(scene.min(wanted).max(TIGHTEST_STEP_TOLERANCE));
    }

    /// The global stage.
    fn global(&mut self, seed: u64) -> Result<search::DeResult> {
        self.ticker.stage("global");
        let p = self.lo.len();
        let opts = DeOptions {
            population: global_population(p),
            max_generations: GLOBAL_GENERATIONS,
            ..DeOptions::for_dimension(p, seed)
        };
        let (lo, hi) = (self.lo.clone(), self.hi.clone());
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Fitness>> {
            let residuals = self.residuals(us)?;
            Ok(residuals
                .iter()
                .map(|r| Fitness::squares(r.as_deref()))
                .collect())
        };
        search::differential_evolution(&mut eval, &lo, &hi, &opts, &mut |_, _, _| {
            search::Progress::Continue
        })
    }

    /// The local stage from the global stage's best point and from up to
    /// [`STARTS`]` - 1` more: the candidates of lowest misfit that lie at
    /// least [`START_SPACING`] of the bounds' width from every start chosen
    /// (a narrow valley the population did not settle in); the best end.
    fn local_from_starts(&mut self, best: &[f64], steps: &[f64]) -> Result<lsq::LmResult> {
        let mut ranked: Vec<(f64, Vec<f64>)> = self
            .history
            .iter()
            .map(|(u, models)| {
                let r = self.weights.residuals(&self.problem.data, models);
                (r.iter().map(|x| x * x).sum(), u.clone())
            })
            .collect();
        ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut starts = vec![best.to_vec()];
        for (_, u) in ranked {
            if starts.len() == STARTS {
                break;
            }
            let far = |s: &Vec<f64>| {
                (0..u.len()).any(|j| (u[j] - s[j]).abs() >= START_SPACING * self.widths[j])
            };
            if starts.iter().all(far) {
                starts.push(u);
            }
        }
        let mut found: Option<lsq::LmResult> = None;
        for start in starts {
            let lm = self.local(&start, steps)?;
            if found.as_ref().is_none_or(|f| lm.cost < f.cost) {
                found = Some(lm);
            }
        }
        Ok(found.expect("at least one start"))
    }

    /// The local stage from `u0`.
    fn local(&mut self, u0: &[f64], steps: &[f64]) -> Result<lsq::LmResult> {
        self.ticker.stage("local");
        let opts = LmOptions::new(steps.to_vec());
        let (lo, hi) = (self.lo.clone(), self.hi.clone());
        let mut eval = |us: &[Vec<f64>]| self.residuals(us);
        lsq::levenberg_marquardt(&mut eval, &lo, &hi, u0, &opts, &mut |_, _, _| true)
    }

    /// Difference steps sized by the standard errors at `u`: one each (a
    /// step that moves the misfit by about 1, a secant across the
    /// confidence region, which a kink in the steps, such as the onset of
    /// motion at some row, cannot shrink to a tangent), within 1e-6 and
    /// 5e-2 of the bounds' width.
    fn error_steps(&mut self, u: &[f64], steps: &[f64]) -> Result<Vec<f64>> {
        let r0 = self.residuals(&[u.to_vec()])?.pop().flatten();
        let Some(r0) = r0 else {
            anyhow::bail!("the model failed at the best point");
        };
        let j = self.jacobian(u, &r0, steps)?;
        let cov = lsq::covariance(&j.j, 1.0);
        // A key no side could probe keeps its step.
        let mut out = steps.to_vec();
        for (&k, se) in j.probed.iter().zip(&cov.standard_errors) {
            out[k] = se.clamp(1e-6 * self.widths[k], 5e-2 * self.widths[k]);
        }
        Ok(out)
    }

    fn jacobian(&mut self, u: &[f64], r0: &[f64], steps: &[f64]) -> Result<jacobian::Sided> {
        let (lo, hi) = (self.lo.clone(), self.hi.clone());
        let mut eval = |us: &[Vec<f64>]| self.residuals(us);
        jacobian::sided(&mut eval, (&lo, &hi), u, r0, steps)
    }

    /// The profiles through the final point `u`, walked in steps of the
    /// standard errors its Jacobian gives, up to Student's rises where the
    /// errors are estimated, scaled by the reduced chi2 where `fit.errors =
    /// "scaled"`.
    fn profiles_at(
        &mut self,
        u: &[f64],
        point: &Best,
        jacobian: &jacobian::Sided,
    ) -> Result<super::profile::Profiles> {
        let cov = lsq::covariance(&jacobian.j, 1.0);
        let mut full = vec![vec![f64::NAN; u.len()]; u.len()];
        for (a, &i) in jacobian.probed.iter().enumerate() {
            for (b, &j) in jacobian.probed.iter().enumerate() {
                full[i][j] = cov.covariance[a][b];
            }
            // Infinite for a key the data do not determine.
            full[i][i] = cov.standard_errors[a].powi(2);
        }
        use super::goodness::{LEVEL_68, estimated_dof, rise};
        let dof = self.problem.data.measurements() as i64 - u.len() as i64;
        let mut nu = estimated_dof(&self.problem.data, dof);
        let scale = match (self.problem.errors, dof > 0) {
            (super::spec::Errors::Scaled, true) => {
                // The residuals then estimate the errors' scale too.
                nu = Some(nu.map_or(dof as f64, |n| n.min(dof as f64)));
                point.chi2 / dof as f64
            }
            _ => 1.0,
        };
        let thresholds = [rise(LEVEL_68, nu) * scale, rise(0.95, nu) * scale];
        self.ticker.stage("intervals");
        let before = self.problem.evaluations;
        let (free, lo, hi) = (self.problem.free.clone(), self.lo.clone(), self.hi.clone());
        let mut eval = |us: &[Vec<f64>]| self.residuals(us);
        let mut walker = super::profile::Walker {
            eval: &mut eval,
            free: &free,
            lo: &lo,
            hi: &hi,
        };
        let mut profiles = walker.profiles(u, point.chi2, &full, thresholds)?;
        profiles.evaluations = self.problem.evaluations - before;
        Ok(profiles)
    }

    /// The point `u` evaluated: its chi2 and its rows' model.
    fn point(&mut self, u: &[f64]) -> Result<Best> {
        let values = self.values(u);
        let Some(Ok(models)) = self.problem.evaluate(&[values])?.pop() else {
            anyhow::bail!("the model failed at the fit's final point");
        };
        let r = self.weights.residuals(&self.problem.data, &models);
        Ok(Best {
            u: u.to_vec(),
            chi2: r.iter().map(|x| x * x).sum(),
            models,
        })
    }

    /// The weighted residuals of candidates (search coordinates), one batch;
    /// keeps the best point and ticks the progress.
    fn residuals(&mut self, us: &[Vec<f64>]) -> Result<Vec<Option<Vec<f64>>>> {
        let values: Vec<Vec<f64>> = us.iter().map(|u| self.values(u)).collect();
        let evaluations = self.problem.evaluate(&values)?;
        let mut out = Vec::with_capacity(us.len());
        for (u, evaluation) in us.iter().zip(evaluations) {
            let Ok(models) = evaluation else {
                out.push(None);
                continue;
            };
            let r = self.weights.residuals(&self.problem.data, &models);
            let chi2: f64 = r.iter().map(|x| x * x).sum();
            let entry = std::mem::size_of_val(&models[..]) + std::mem::size_of_val(&u[..]);
            if (self.history.len() + 1) * entry <= HISTORY_BYTES {
                self.history.push((u.clone(), models.clone()));
            }
            if self.best.as_ref().is_none_or(|b| chi2 < b.chi2) {
                self.best = Some(Best {
                    u: u.clone(),
                    chi2,
                    models,
                });
            }
            out.push(Some(r));
        }
        let best = self.best.as_ref().map_or(f64::INFINITY, |b| b.chi2);
        self.ticker.tick(self.problem.evaluations, best);
        Ok(out)
    }
}
