//! Scene files: the TOML description of what to simulate, its validation and
//! its expansion into [`Instance`]s.
//!
//! A scene gives the shared friction interface (`[mechanism]`), the two
//! axes (`[axis.x]`, `[axis.y]`), the run length and integrator settings
//! (`[simulation]`) and what to output (`[output]`). Anything not given is
//! Table 1 of the paper as printed ([`Mechanism::TABLE1`](crate::model::Mechanism::TABLE1),
//! [`Axis::TABLE1`](crate::model::Axis::TABLE1)),
//! measured steady (see below). Every `axis.y` key defaults to `axis.x`'s
//! value, except the voltage, which defaults to 0 (y undriven).
//!
//! Any numeric value may be a scalar, a list (`[1.0, 2.0]`) or a range
//! (`{ from = 0.0, to = 150.0, steps = 151 }`, endpoints included;
//! `log = true` spaces the values geometrically). Every key with more than
//! one value is a grid axis, in the order the keys appear in the file; the
//! grid is stored row-major with the last axis varying fastest. A grid axis
//! over an `axis.x` key that `axis.y` inherits moves both axes together.
//!
//! A grid of exactly two range axes may carry `[refine]` (`levels`,
//! `tolerance`): the scene's grid is then the coarse grid of an adaptive
//! regime map, and the validated [`Scene`] holds the finest grid (each
//! range with `(steps - 1) * 2^levels + 1` values) with [`Scene::refine`]
//! set; `crate::refine` decides which of its instances are integrated.
//!
//! Instead of a grid, a scene may list `[[points]]`: partial scenes of
//! single values applied on top of the base, each with an optional `label`.
//!
//! A stage may be given by its resonance and quality factor instead of its
//! mass and damping (paper eqs. 6-7): `resonance_hz` with `stage_mass` or
//! `stiffness` (the other follows; with neither, the stiffness is Table 1's),
//! and `quality_factor` instead of `damping`. An overriding layer (`axis.y`
//! over `axis.x`, a point over the base) keeps its own stage keys and takes
//! from the layer below only those that do not over-determine the stage,
//! preferring `resonance_hz`, then `stiffness`, then `stage_mass`.
//!
//! The top level takes `name` (the file stem by default), an optional free
//! text `description`, and `[output] baselines = true` to also run the two
//! 1-DOF counterparts of every instance. `[output] trajectories = [...]`
//! records the motion of chosen instances over time (see
//! [`trajectories`] for the entries) with
//! `trajectory_samples_per_cycle` samples per scene period.
//!
//! `[simulation] measure` says how the steps are measured (docs/model.md section
//! 4), one string for the whole scene: `"steady"` (the default) runs each
//! instance until its steady step is known, with `settle` (the least
//! periods discarded, default [`Measure::DEFAULT_SETTLE`]), `step_tolerance`
//! (the standard error allowed on each axis' step [m per own drive cycle],
//! default [`Measure::DEFAULT_STEP_TOLERANCE`]) and `max_cycles` (the most
//! scene periods it may run, default [`Measure::DEFAULT_MAX_CYCLES`]);
//! `"window"` is the paper's fixed window, `cycles` periods (default 10) of
//! which the first `settle` (default 2) are discarded. A key of the other
//! mode (`cycles` in a steady scene, `step_tolerance` or `max_cycles` in a
//! window) is refused, never ignored. `cycles`, `max_cycles`, `settle` and
//! `step_tolerance` are per instance (grid axes and points may set them);
//! `measure` and the integrator settings `tolerance` and
//! `max_steps_per_period` apply to the whole scene (single values only).
//! Integer keys accept lists and linear ranges whose values land on integers.
//!
//! [`Measure::DEFAULT_SETTLE`]: crate::model::Measure::DEFAULT_SETTLE
//! [`Measure::DEFAULT_STEP_TOLERANCE`]: crate::model::Measure::DEFAULT_STEP_TOLERANCE
//! [`Measure::DEFAULT_MAX_CYCLES`]: crate::model::Measure::DEFAULT_MAX_CYCLES
//!
//! A range with `steps = 1` must have `from = to`, and `steps` is at most
//! [`MAX_RANGE_STEPS`]. Beyond its sign and interval, every numeric key must
//! lie within generous physical bounds that keep every run finite (see the
//! private `rules` module for each bound and why): a frequency of 1e300 Hz
//! or a voltage of 1e308 V is refused here instead of ending in status 2.
//!
//! `name` is a name, not a path (see [`MAX_NAME_BYTES`] and the `name`
//! module): it makes the default output file `results/<name>.h5`, so it may
//! hold no `/` or `\`, no control characters, and may not start with `.`
//! or `-`. A scene file is read with a bound of [`MAX_SCENE_BYTES`] and
//! must be UTF-8 text.
//!
//! Everything is validated in [`Scene::from_toml`]; errors name the full key
//! path, the offending value, what was expected and where in the file.
//!
//! The module is split by concern: `error` (why a scene was refused),
//! `file` (reading a scene file), `name` (the name rule), `keys` (the
//! numeric keys, their tables and raw slots), `rules` (what values each key
//! accepts), `values` (scalars, lists and ranges), `parser` (the TOML
//! document into layers of keys), `numbers` (a numeric key's values read
//! and checked), `suggest` (hints for unknown keys),
//! `layer` (what an upper layer takes from the one below), `plan` (from raw
//! key values to instances), `refine` (the `[refine]` table and the finest
//! grid), `assemble` (the validated scene), `memory` (the
//! output budget), `describe` (the human summary), `format` (numbers in
//! messages) and [`trajectories`].

use std::path::Path;

use crate::laws::{Law, Settings};
use crate::model::{AXES, Instance};

mod assemble;
mod describe;
mod error;
mod file;
mod format;
pub mod free;
mod keys;
mod layer;
mod memory;
mod name;
mod numbers;
mod parser;
mod plan;
mod random;
mod refine;
mod rules;
mod stall;
mod suggest;
mod ties;
pub mod trajectories;
mod values;
mod waveform;

pub use describe::drive_words;
pub use error::{Location, SceneError};
pub use file::{MAX_SCENE_BYTES, read as read_text};
pub use keys::{KeyRange, instance_key, instance_key_range};
pub use memory::MAP_MEMORY_BUDGET_BYTES;
pub use name::MAX_NAME_BYTES;
pub use refine::{DEFAULT_REFINE_TOLERANCE_M, MAX_REFINE_LEVELS, Refine};
pub use stall::{BRACKET, DEFAULT_TOLERANCE_N, Stall};
pub use trajectories::{DEFAULT_SAMPLES_PER_CYCLE, TrajectoryPoint};
pub use values::MAX_RANGE_STEPS;

use keys::SLOTS;
use plan::Plan;

/// The shipped scenes that commands take by default (`pidm report`,
/// `accuracy`, `bench`), built into the binary: their path in the
/// checkout and their text.
pub const SHIPPED: [(&str, &str); 2] = [
    ("sweeps/paper.toml", include_str!("../../sweeps/paper.toml")),
    (
        "sweeps/paper_text.toml",
        include_str!("../../sweeps/paper_text.toml"),
    ),
];

/// A validated scene, ready to be expanded instance by instance.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene's name (`name`, or the file stem when loaded from a file).
    pub name: String,
    /// The TOML source as read.
    pub text: String,
    /// How the instances are laid out: a grid or a list of points.
    pub layout: Layout,
    /// Whether the two 1-DOF counterparts of every instance are run too.
    pub baselines: bool,
    /// Scene-wide integrator settings.
    pub settings: Settings,
    /// Instances whose motion over time is recorded (`output.trajectories`).
    pub trajectories: Vec<TrajectoryPoint>,
    /// Samples per scene period of each trajectory
    /// (`output.trajectory_samples_per_cycle`).
    pub trajectory_samples_per_cycle: u32,
    /// The optional free-text `description`.
    description: Option<String>,
    /// How the raw key values become an instance.
    plan: Plan,
    /// `[refine]`: when set, the grid is the finest grid of an adaptive
    /// refinement of the scene's own (coarse) grid, which `crate::refine`
    /// integrates only where the regimes change.
    pub refine: Option<Refine>,
    /// `[stall]`: when set, the run also searches every instance's stall
    /// load along one axis (`crate::stall`), which the scene does not set.
    pub stall: Option<Stall>,
    /// The raw key values of the base (grid slots hold their first value).
    raw: [f64; SLOTS],
    /// For each grid axis, the raw slot it sets.
    grid_slots: Vec<usize>,
    /// The instances of a point scene, in point order.
    points: Vec<Instance>,
    /// For each point, the keys it sets, as "key = value", in file order.
    point_keys: Vec<String>,
    /// Whether each axis is driven in at least one instance.
    driven: [bool; AXES],
}

/// How the instances of a scene are arranged.
#[derive(Clone, Debug, PartialEq)]
pub enum Layout {
    /// A row-major grid over the axes, in file order, the last fastest; no
    /// axes means a single instance.
    Grid { axes: Vec<GridAxis> },
    /// A list of points, one label per instance ("" when none was given).
    Points { labels: Vec<String> },
}

/// One axis of a grid: a key given more than one value.
#[derive(Clone, Debug, PartialEq)]
pub struct GridAxis {
    /// Full dotted key path, e.g. "axis.y.voltage".
    pub key: String,
    /// The values, in order.
    pub values: Vec<f64>,
    /// Units of the values: "V", "Hz", "kg", "N/m", "N s/m", "N/V", "N",
    /// "m/s", "m", "cycles", "1" (dimensionless) or "rad".
    pub units: &'static str,
}

impl Scene {
    /// Parses and validates a scene. `default_name` is used when the text has
    /// no `name` (the file stem, when loading a file); it must be a valid
    /// name too.
    pub fn from_toml(text: &str, default_name: Option<&str>) -> Result<Scene, SceneError> {
        assemble::scene(text, default_name)
    }

    /// Reads and validates a scene file; its stem is the default name. The
    /// file is read with a bound of [`MAX_SCENE_BYTES`] and must be text.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = file::read(path)?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
        Scene::from_toml(&text, stem.as_deref())
    }

    /// The grid shape (file order), or `[n]` for n points; `[]` for a
    /// single-instance grid.
    pub fn shape(&self) -> Vec<usize> {
        match &self.layout {
            Layout::Grid { axes } => axes.iter().map(|a| a.values.len()).collect(),
            Layout::Points { labels } => vec![labels.len()],
        }
    }

    /// Number of instances.
    pub fn instance_count(&self) -> u64 {
        self.shape().iter().map(|&n| n as u64).product()
    }

    /// `simulation.tolerance` and what it means for the scene's friction
    /// law: Karnopp's direction error [rad], or LuGre's local error per
    /// step (`laws::lugre::LENGTH_PER_TOLERANCE`).
    pub fn tolerance_text(&self) -> String {
        let tolerance = self.settings.tolerance;
        format!(
            "tolerance {tolerance:e} {}",
            self.law().tolerance_unit(tolerance)
        )
    }

    /// The scene's friction law (`mechanism.friction`, scene-wide, so
    /// instance 0 says it; the default for a scene of no instances).
    pub fn law(&self) -> Law {
        match self.instance_count() {
            0 => Law::default(),
            _ => Law::of_instance(&self.instance(0)),
        }
    }

    /// Instance `index`, row-major over the grid axes (the last fastest), or
    /// point `index`. Cheap: no allocation.
    pub fn instance(&self, index: u64) -> Instance {
        match &self.layout {
            Layout::Points { .. } => self.points[index as usize],
            Layout::Grid { axes } => {
                let mut raw = self.raw;
                let mut rest = index;
                for (axis, &slot) in axes.iter().zip(&self.grid_slots).rev() {
                    let n = axis.values.len() as u64;
                    raw[slot] = axis.values[(rest % n) as usize];
                    rest /= n;
                }
                debug_assert_eq!(rest, 0, "instance index out of range");
                self.plan.resolve(&raw)
            }
        }
    }

    /// A scene shipped in `sweeps/` and built into the binary, by its path
    /// there (`"sweeps/paper.toml"`), so that the commands whose default is
    /// a shipped scene work from any directory; `None` for a path that is
    /// not built in.
    pub fn shipped(path: &str) -> Option<Result<Scene, SceneError>> {
        let (_, text) = SHIPPED.iter().find(|(p, _)| *p == path)?;
        let stem = Path::new(path).file_stem()?.to_string_lossy().into_owned();
        Some(Scene::from_toml(text, Some(&stem)))
    }

    /// Why `--backend auto` keeps this scene on the CPU without weighing
    /// it, if it does: its law's reason (`Law::auto_on_cpu`).
    pub fn auto_on_cpu(&self) -> Option<&'static str> {
        self.law().auto_on_cpu()
    }

    /// Whether axis `axis` has a non-zero voltage in at least one instance.
    pub fn axis_ever_driven(&self, axis: usize) -> bool {
        self.driven.get(axis).copied().unwrap_or(false)
    }
}

impl Scene {
    /// The result file's layout of this scene's results, run on `backend`
    /// (its description) in `precision` by the integrator `variant`
    /// (`crate::output::FileInfo`; here, so that the output layer needs
    /// nothing of scenes).
    pub fn file_info(
        &self,
        backend: String,
        precision: String,
        variant: String,
    ) -> crate::output::FileInfo {
        let (axes, labels) = match &self.layout {
            Layout::Grid { axes } => (
                axes.iter()
                    .map(|a| crate::output::AxisInfo {
                        key: a.key.clone(),
                        values: a.values.clone(),
                        units: a.units.to_string(),
                    })
                    .collect(),
                None,
            ),
            Layout::Points { labels } => (Vec::new(), Some(labels.clone())),
        };
        crate::output::FileInfo {
            name: self.name.clone(),
            scene_text: self.text.clone(),
            shape: self.shape(),
            axes,
            labels,
            baselines: self.baselines,
            backward: self.settings.backward,
            backend,
            precision,
            variant,
            tolerance: self.settings.tolerance,
            friction: self.law().name().to_owned(),
            // The default law's own parameters are the mechanism's keys.
            friction_parameters: (self.law() != Law::default())
                .then(|| describe::law_parameters(&self.instance(0).mechanism)),
            verify_tolerance: None,
            shard: None,
            stall: self.stall.map(|stall| stall.axis),
        }
    }
}
