//! A fit's model: the scene without `[fit]`, the free keys and the data
//! rows, turned into candidate scenes (one point per row) and integrated
//! a batch of candidates at a time on one backend.
//!
//! Every candidate is a scene of its own, validated by the scene's rules
//! ([`Scene::from_toml`]): a candidate a rule refuses (a load at or beyond
//! the Coulomb force, say) is infeasible, not an error.

use anyhow::{Result, bail};

use super::data::{Data, Row};
use super::spec::{FitScene, Free};
use crate::backend::Backend;
use crate::laws::status::STATUS_OK;
use crate::measurement::status;
use crate::model::motion::Motion;
use crate::model::{AXES, Instance};
use crate::scene::free::{bare_message as message, pin_replicas as fixed_replicas, set_key as set};
use crate::scene::{Layout, Scene, SceneError};

/// Top-level scene tables a fit scene may not hold, and why.
const REFUSED: [(&str, &str); 5] = [
    ("points", "the data's rows are the fit's points"),
    ("random", "the data's rows are the fit's instances"),
    ("stall", "a fit measures steps, not stall loads"),
    ("refine", "a fit has no map to refine"),
    (
        "output",
        "a fit writes FIT.json, FIT.toml and FIT.png, not a map",
    ),
];

/// What the model gives for one row: each axis' step [m per own drive
/// cycle] and its standard error [m].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RowModel {
    pub step: [f64; AXES],
    pub se: [f64; AXES],
}

/// One candidate's result: its rows' model, or why it has none.
pub type Evaluation = std::result::Result<Vec<RowModel>, String>;

/// A fit's model and its evaluations so far.
pub struct Problem<'a> {
    base: toml::Table,
    pub free: Vec<Free>,
    pub data: Data,
    backend: Option<&'a dyn Backend>,
    /// The keys each data row sets ([`Problem::row_keys`]), the points of
    /// every candidate's scene.
    points: Vec<Vec<(String, f64)>>,
    /// The steady measurement's `step_tolerance` every candidate runs with
    /// [m per own drive cycle]; `None` for a fixed window.
    pub step_tolerance: Option<f64>,
    /// The scene's own `step_tolerance` (or the default).
    pub scene_step_tolerance: Option<f64>,
    /// Which standard errors the fit reports (`fit.errors`).
    pub errors: super::spec::Errors,
    /// Candidates evaluated, and of those infeasible or failed.
    pub evaluations: usize,
    pub infeasible: usize,
    pub failed: usize,
    /// The first few reasons a candidate was infeasible or failed.
    pub reasons: Vec<String>,
}

impl<'a> Problem<'a> {
    /// Checks a fit scene against its data: the scene without `[fit]` is
    /// valid, a single instance, and every row makes a valid instance with
    /// the free keys in the middle of their bounds.
    pub fn new(fit: &FitScene, data: Data) -> Result<Problem<'a>> {
        let scene = Scene::from_toml(&fit.base_text, Some("fit"))?;
        if let Layout::Grid { axes } = &scene.layout
            && let Some(axis) = axes.first()
        {
            bail!(
                "`{}` has {} values: a fit scene gives every key one value (the data's rows \
                 say where to measure)",
                axis.key,
                axis.values.len()
            );
        }
        let base: toml::Table = toml::from_str(&fit.base_text)?;
        for (key, why) in REFUSED {
            if base.contains_key(key) {
                bail!("a fit scene takes no `{key}`: {why}");
            }
        }
        for free in &fit.free {
            if data.keys.contains(&free.key) {
                bail!(
                    "`{}` is both free in [fit] and a column of {}: the data set it, so it \
                     cannot be fitted",
                    free.key,
                    data.path.display()
                );
            }
        }
        let window = base
            .get("simulation")
            .and_then(|s| s.get("measure"))
            .and_then(|m| m.as_str())
            == Some("window");
        let scene_tol = (!window).then(|| scene.instance(0).measure.step_tolerance());
        let mut problem = Problem {
            base,
            free: fit.free.clone(),
            data,
            backend: None,
            points: Vec::new(),
            step_tolerance: scene_tol,
            scene_step_tolerance: scene_tol,
            errors: fit.errors,
            evaluations: 0,
            infeasible: 0,
            failed: 0,
            reasons: Vec::new(),
        };
        problem.points = problem.rows_as_points();
        problem.check_rows()?;
        // Velocities become steps at each line's own frequency, then the
        // lines of one setting are pooled (docs/fit.md, "The data").
        if !problem.data.velocity_axes().is_empty() {
            let scene_at = |values: &[f64]| {
                problem
                    .scene(values, problem.points())
                    .map_err(|e| message(&e))
            };
            let frequencies = super::velocity::frequencies(
                &problem.data,
                &problem.free,
                &problem.middle(),
                &scene_at,
            )?;
            problem.data.to_steps(&frequencies);
        }
        problem.data.pool_repeats();
        problem.points = problem.rows_as_points();
        Ok(problem)
    }

    /// The backend every evaluation runs on.
    pub fn on(&mut self, backend: &'a dyn Backend) {
        self.backend = Some(backend);
    }

    /// What `--backend auto` weighs the fit by: the rows at the middle of
    /// the bounds, as many times as a fit of its size evaluates candidates
    /// (about a thousand).
    pub fn workload(&self) -> Result<crate::backend::Workload> {
        let scene = self.scene(&self.middle(), &self.points)?;
        let candidates: Vec<Instance> = (0..scene.instance_count())
            .map(|i| scene.instance(i))
            .collect();
        Ok(crate::backend::Workload {
            integrations: candidates.len() as u64 * 1000,
            stall: false,
            law: scene.law(),
            candidates,
            settings: scene.settings,
        })
    }

    /// The data rows as points: the keys each sets.
    pub fn points(&self) -> &[Vec<(String, f64)>] {
        &self.points
    }

    /// The middle of the bounds (geometric on a log scale).
    pub fn middle(&self) -> Vec<f64> {
        crate::scene::free::middle(&self.free)
    }

    /// Every row, alone, makes a valid instance at the middle of the bounds
    /// (before repeats are pooled: an error names the row's own line).
    fn check_rows(&self) -> Result<()> {
        let middle = self.middle();
        for row in &self.data.rows {
            if let Err(e) = self.scene(&middle, &[self.row_keys(row)]) {
                bail!(
                    "{} line {}: {} (with the free keys in the middle of their bounds)",
                    self.data.path.display(),
                    row.line,
                    message(&e)
                );
            }
        }
        Ok(())
    }

    /// Every data row's keys, in order.
    fn rows_as_points(&self) -> Vec<Vec<(String, f64)>> {
        self.data.rows.iter().map(|r| self.row_keys(r)).collect()
    }

    /// The keys a row sets.
    pub fn row_keys(&self, row: &Row) -> Vec<(String, f64)> {
        self.data
            .keys
            .iter()
            .zip(&row.keys)
            .map(|(k, &v)| (k.clone(), v))
            .collect()
    }

    /// The scene of the free keys at `values` with one point per entry of
    /// `points` (the keys it sets).
    pub fn scene(
        &self,
        values: &[f64],
        points: &[Vec<(String, f64)>],
    ) -> Result<Scene, SceneError> {
        let mut table = self.base.clone();
        for (free, &value) in self.free.iter().zip(values) {
            set(&mut table, &free.key, value);
        }
        if let Some(tol) = self.step_tolerance {
            set(&mut table, "simulation.step_tolerance", tol);
            fixed_replicas(&mut table);
        }
        let points = points
            .iter()
            .map(|keys| {
                let mut point = toml::Table::new();
                for (key, value) in keys {
                    set(&mut point, key, *value);
                }
                toml::Value::Table(point)
            })
            .collect();
        table.insert("points".into(), toml::Value::Array(points));
        let text = toml::to_string(&table).expect("a TOML table serialises");
        Scene::from_toml(&text, Some("fit"))
    }

    /// The fitted scene's TOML: the scene without `[fit]` with the free
    /// keys at `values` (the scene's own step tolerance kept).
    pub fn fitted_scene(&self, values: &[f64]) -> String {
        let mut table = self.base.clone();
        for (free, &value) in self.free.iter().zip(values) {
            set(&mut table, &free.key, value);
        }
        toml::to_string(&table).expect("a TOML table serialises")
    }

    /// Evaluates candidates (each the free keys' values) at the data's rows,
    /// all in one batch on the backend.
    pub fn evaluate(&mut self, candidates: &[Vec<f64>]) -> Result<Vec<Evaluation>> {
        let evaluations = self.evaluate_at(candidates, &self.points)?;
        for e in &evaluations {
            self.evaluations += 1;
            if let Err(why) = e {
                if why.starts_with("infeasible") {
                    self.infeasible += 1;
                } else {
                    self.failed += 1;
                }
                if self.reasons.len() < 5 && !self.reasons.contains(why) {
                    self.reasons.push(why.clone());
                }
            }
        }
        Ok(evaluations)
    }

    /// Evaluates candidates at any points (the data's rows, or a curve's).
    pub fn evaluate_at(
        &self,
        candidates: &[Vec<f64>],
        points: &[Vec<(String, f64)>],
    ) -> Result<Vec<Evaluation>> {
        let scenes: Vec<Result<Scene, String>> = candidates
            .iter()
            .map(|c| {
                self.scene(c, points)
                    .map_err(|e| format!("infeasible: {}", message(&e)))
            })
            .collect();
        let runs = self.run_scenes(scenes.iter().flatten())?;
        let mut runs = runs.into_iter();
        Ok(scenes
            .into_iter()
            .map(|scene| {
                scene?;
                let rows = runs.next().expect("one run per scene");
                rows.into_iter().collect()
            })
            .collect())
    }

    /// The model at each point for the free keys at `values`, `None` where
    /// a point's instance failed (all `None` when a rule refuses them).
    pub fn evaluate_points(
        &self,
        values: &[f64],
        points: &[Vec<(String, f64)>],
    ) -> Result<Vec<Option<RowModel>>> {
        let Ok(scene) = self.scene(values, points) else {
            return Ok(vec![None; points.len()]);
        };
        let runs = self.run_scenes([&scene])?;
        Ok(runs.into_iter().flatten().map(|r| r.ok()).collect())
    }

    /// Integrates every instance of `scenes` in one batch; per scene, each
    /// instance's model or why it failed.
    fn run_scenes<'s>(
        &self,
        scenes: impl IntoIterator<Item = &'s Scene>,
    ) -> Result<Vec<Vec<Result<RowModel, String>>>> {
        let mut instances: Vec<Instance> = Vec::new();
        let mut counts = Vec::new();
        let mut settings = None;
        for scene in scenes {
            instances.extend((0..scene.instance_count()).map(|i| scene.instance(i)));
            counts.push(scene.instance_count() as usize);
            settings.get_or_insert(scene.settings);
        }
        let backend = self.backend.expect("a backend is set before evaluating");
        let outcomes = match settings {
            Some(settings) => backend.run(&instances, &settings, &|_| {})?,
            None => Vec::new(),
        };
        if crate::interrupt::interrupt_requested() {
            bail!("stopped");
        }
        let mut next = outcomes.iter().zip(&instances).enumerate();
        Ok(counts
            .into_iter()
            .map(|n| {
                let first = next.clone().next().map_or(0, |(i, _)| i);
                next.by_ref()
                    .take(n)
                    .map(|(i, (o, inst))| row_model(i - first, o, inst))
                    .collect()
            })
            .collect())
    }
}

/// A row's model from its outcome, or why it failed: an instance that did
/// not finish normally or was labelled multistable.
fn row_model(
    index: usize,
    outcome: &crate::measurement::Outcome,
    inst: &Instance,
) -> std::result::Result<RowModel, String> {
    if outcome.status != STATUS_OK {
        return Err(format!(
            "failed: row {} ended with status {} ({})",
            index + 1,
            outcome.status,
            status::Status::describe(outcome.status)
        ));
    }
    if outcome.motion == Motion::Multistable {
        return Err(format!("failed: row {} is multistable", index + 1));
    }
    Ok(RowModel {
        step: std::array::from_fn(|a| outcome.step(inst, a)),
        se: outcome.se,
    })
}

impl Problem<'_> {
    /// A note for each free `axis.x` key that axis y copies (the scene's
    /// `[axis.y]` does not set its own): the fit moves both axes.
    pub fn inherited_notes(&self) -> Vec<String> {
        let y = self
            .base
            .get("axis")
            .and_then(|a| a.get("y"))
            .and_then(|y| y.as_table());
        self.free
            .iter()
            .filter_map(|f| f.key.strip_prefix("axis.x."))
            .filter(|name| *name != "voltage" && !y.is_some_and(|y| y.contains_key(*name)))
            .map(|name| {
                format!(
                    "axis.y copies axis.x.{name} (the scene's axis.y sets no {name} of its own): \
                     the fit moves both axes' {name}; free axis.y.{name} to fit it apart"
                )
            })
            .collect()
    }
}
