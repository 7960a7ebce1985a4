//! A design command's model: the scene without its `[optimize]` or
//! `[sensitivity]` table, one instance, whose keys a candidate sets.
//!
//! Every candidate is a scene of its own, validated by the scene's rules
//! ([`Scene::from_toml`]): a candidate a rule refuses (a trapezoid whose
//! fractions sum past 1, a load at the Coulomb force) is infeasible, not
//! an error. A batch of candidates is integrated at once on one backend,
//! and every run is counted.

use anyhow::{Result, bail};

use crate::backend::{Backend, Workload};
use crate::model::{AXES, Instance};
use crate::scene::free::{bare_message as message, pin_replicas as fixed_replicas, set_key as set};
use crate::scene::{Layout, Scene, SceneError};
use crate::sweep::Record;

/// Top-level tables a design scene may not hold, and why.
const REFUSED: [(&str, &str); 4] = [
    ("points", "the command's candidates are its instances"),
    ("random", "the command's candidates are its instances"),
    ("stall", "a design command measures steps, not stall loads"),
    ("refine", "a design command has no map to refine"),
];

/// One candidate's run: its map entries and its axes' own frequencies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    pub record: Record,
    /// Each axis' own drive frequency [Hz] (a velocity's SE is the
    /// step's times it).
    pub frequency: [f64; AXES],
}

/// A candidate's run, or why it has none ("infeasible: ..." where a scene
/// rule refuses it).
pub type Evaluation = std::result::Result<Run, String>;

/// The model and its runs so far.
pub struct Model<'a> {
    base: toml::Table,
    /// The dotted keys a candidate sets, in its order.
    pub keys: Vec<String>,
    /// Whether the scene writes the backward maps (`[output] backward`).
    pub backward: bool,
    backend: Option<&'a dyn Backend>,
    /// Instances integrated so far (every run of the budget).
    pub runs: usize,
}

impl<'a> Model<'a> {
    /// The model of `base_text` (the scene without the command's table,
    /// `section`), whose candidates set `keys`; `middle` is a candidate
    /// the scene must accept.
    pub fn new(base_text: &str, section: &str, keys: Vec<String>, middle: &[f64]) -> Result<Self> {
        let scene = Scene::from_toml(base_text, Some(section))?;
        if let Layout::Grid { axes } = &scene.layout
            && let Some(axis) = axes.first()
        {
            bail!(
                "`{}` has {} values: a scene with [{section}] gives every key one value (the \
                 command chooses the candidates)",
                axis.key,
                axis.values.len()
            );
        }
        let base: toml::Table = toml::from_str(base_text)?;
        for (key, why) in REFUSED {
            if base.contains_key(key) {
                bail!("a scene with [{section}] takes no `{key}`: {why}");
            }
        }
        let output = base.get("output").and_then(|o| o.as_table());
        if let Some(key) = output.and_then(|o| o.keys().find(|k| *k != "backward")) {
            bail!(
                "a scene with [{section}] takes `[output] backward` only, not `output.{key}`: \
                 the command writes its own files, not a map"
            );
        }
        let backward = output
            .and_then(|o| o.get("backward"))
            .and_then(|b| b.as_bool())
            == Some(true);
        let model = Model {
            base,
            keys,
            backward,
            backend: None,
            runs: 0,
        };
        model
            .scene(middle)
            .map_err(|e| anyhow::anyhow!("{section}: with the keys at {middle:?}: {e}"))?;
        Ok(model)
    }

    /// The backend every run is on.
    pub fn on(&mut self, backend: &'a dyn Backend) {
        self.backend = Some(backend);
    }

    /// The scene's TOML with the keys at `values` (runnable with `pidm
    /// run`).
    pub fn scene_text(&self, values: &[f64]) -> String {
        let mut table = self.base.clone();
        for (key, &value) in self.keys.iter().zip(values) {
            set(&mut table, key, value);
        }
        fixed_replicas(&mut table);
        toml::to_string(&table).expect("a TOML table serialises")
    }

    /// The scene with the keys at `values`.
    pub fn scene(&self, values: &[f64]) -> Result<Scene, SceneError> {
        Scene::from_toml(&self.scene_text(values), Some("design"))
    }

    /// What `--backend auto` weighs the command by: the instance at
    /// `values`, `runs` times.
    pub fn workload(&self, values: &[f64], runs: u64) -> Result<Workload> {
        let scene = self.scene(values)?;
        Ok(Workload {
            integrations: runs,
            stall: false,
            law: scene.law(),
            candidates: vec![scene.instance(0)],
            settings: scene.settings,
        })
    }

    /// Runs every candidate (each the keys' values) in one batch; `done(n)`
    /// reports n more finished runs.
    pub fn evaluate(
        &mut self,
        candidates: &[Vec<f64>],
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Evaluation>> {
        let scenes: Vec<std::result::Result<Scene, String>> = candidates
            .iter()
            .map(|c| {
                self.scene(c)
                    .map_err(|e| format!("infeasible: {}", message(&e)))
            })
            .collect();
        let instances: Vec<Instance> = scenes.iter().flatten().map(|s| s.instance(0)).collect();
        let settings = scenes.iter().flatten().next().map(|s| s.settings);
        let backend = self.backend.expect("a backend is set before running");
        let outcomes = match settings {
            Some(settings) => backend.run(&instances, &settings, done)?,
            None => Vec::new(),
        };
        if crate::interrupt::interrupt_requested() {
            bail!("stopped");
        }
        self.runs += instances.len();
        let mut runs = outcomes.iter().zip(&instances);
        Ok(scenes
            .into_iter()
            .map(|scene| {
                scene?;
                let (outcome, inst) = runs.next().expect("one outcome per instance");
                Ok(Run {
                    record: crate::sweep::record(inst, outcome),
                    frequency: std::array::from_fn(|a| inst.axes[a].frequency),
                })
            })
            .collect())
    }
}
