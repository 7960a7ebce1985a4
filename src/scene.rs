//! Scene files: the TOML description of what to simulate, its validation and
//! its expansion into [`Instance`]s.
//!
//! A scene gives the shared friction interface (`[mechanism]`), the two
//! axes (`[axis.x]`, `[axis.y]`), the run length and integrator settings
//! (`[simulation]`) and what to output (`[output]`). Anything not given is
//! Table 1 of the paper as printed ([`Mechanism::TABLE1`], [`Axis::TABLE1`]),
//! 10 cycles of which 2 settle. Every `axis.y` key defaults to `axis.x`'s
//! value, except the voltage, which defaults to 0 (y undriven).
//!
//! Any numeric value may be a scalar, a list (`[1.0, 2.0]`) or a range
//! (`{ from = 0.0, to = 150.0, steps = 151 }`, endpoints included;
//! `log = true` spaces the values geometrically). Every key with more than
//! one value is a grid axis, in the order the keys appear in the file; the
//! grid is stored row-major with the last axis varying fastest. A grid axis
//! over an `axis.x` key that `axis.y` inherits moves both axes together.
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
//! `trajectory_samples_per_cycle` samples per scene period. `[simulation]` takes `cycles`,
//! `settle` (both integers, per instance) and the scene-wide integrator
//! settings `tolerance` and `max_steps_per_period` (single values only).
//! Integer keys accept lists and linear ranges whose values land on integers.
//!
//! Everything is validated in [`Scene::from_toml`]; errors name the full key
//! path, the offending value, what was expected and where in the file.

use std::fmt::{self, Write as _};
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::Spanned;
use toml::de::{DeTable, DeValue};

use crate::cpu::integrate::Settings;
use crate::model::{AXES, AXIS_NAMES, Axis, Instance, Mechanism};

pub mod trajectories;
pub use trajectories::{DEFAULT_SAMPLES_PER_CYCLE, TrajectoryPoint};

/// Default limit on the memory the output maps of one scene may take.
pub const MAP_MEMORY_BUDGET_BYTES: u64 = 8 << 30;

/// Output maps kept per instance (the 2-DOF results).
pub const MAPS_PER_INSTANCE: u64 = 5;

/// Extra output maps per instance when the 1-DOF baselines are run.
pub const BASELINE_MAPS_PER_INSTANCE: u64 = 2;

/// Bytes per entry of an output map (one f64).
pub const MAP_ENTRY_BYTES: u64 = 8;

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
    /// "m/s", "cycles", "1" (dimensionless) or "rad".
    pub units: &'static str,
}

/// A position in the scene's TOML text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    /// Line, from 1.
    pub line: usize,
    /// Column in characters, from 1.
    pub column: usize,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}, column {}", self.line, self.column)
    }
}

/// Why a scene was refused.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene file {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The text is not valid TOML; the message carries toml's line and column.
    #[error("invalid TOML: {source}")]
    Syntax {
        #[source]
        source: toml::de::Error,
    },
    /// The TOML is valid but the scene is not: a message naming the key, the
    /// value and what was expected, and where it is in the text when known.
    #[error("{message}{}", LocationSuffix(location))]
    Invalid {
        message: String,
        location: Option<Location>,
    },
    /// The output maps would not fit the memory budget.
    #[error("{}", memory_message(shape, *points, *instances, *bytes_per_instance, *budget))]
    Memory {
        /// The grid shape, or the number of points.
        shape: Vec<u64>,
        /// Whether the scene is a list of points.
        points: bool,
        /// Instances in the scene.
        instances: u128,
        /// Output bytes per instance.
        bytes_per_instance: u64,
        /// The budget that was exceeded, in bytes.
        budget: u64,
    },
}

impl SceneError {
    /// Prefixes the message of an [`SceneError::Invalid`] with the point
    /// that caused it.
    fn in_point(self, index: usize, label: &str) -> SceneError {
        match self {
            SceneError::Invalid { message, location } => SceneError::Invalid {
                message: format!("{}: {message}", point_name(index, label)),
                location,
            },
            other => other,
        }
    }
}

/// Formats " (line L, column C)" after an error message when known.
struct LocationSuffix<'a>(&'a Option<Location>);

impl fmt::Display for LocationSuffix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(location) => write!(f, " ({location})"),
            None => Ok(()),
        }
    }
}

/// The message of [`SceneError::Memory`].
fn memory_message(
    shape: &[u64],
    points: bool,
    instances: u128,
    bytes_per_instance: u64,
    budget: u64,
) -> String {
    let layout = if points {
        format!("{instances} points")
    } else if shape.is_empty() {
        "a single instance".to_owned()
    } else {
        let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
        format!("grid {} = {instances} instances", dims.join(" x "))
    };
    let bytes = instances * bytes_per_instance as u128;
    format!(
        "the output maps do not fit the memory budget: {layout} x {bytes_per_instance} bytes \
         per instance = {bytes} bytes ({}), over the budget of {budget} bytes ({}); \
         use a coarser grid",
        human_bytes(bytes as f64),
        human_bytes(budget as f64)
    )
}

/// Formats a byte count with a binary unit, e.g. "8.0 GiB".
fn human_bytes(bytes: f64) -> String {
    const UNITS: [&str; 7] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut value = bytes;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{value:.0} bytes")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// Names a point in error messages: `points[2] ("Fig. 7")`.
fn point_name(index: usize, label: &str) -> String {
    if label.is_empty() {
        format!("points[{index}]")
    } else {
        format!("points[{index}] ({label:?})")
    }
}

// ---------------------------------------------------------------------------
// The keys of a scene.

/// A numeric key of a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Field {
    SliderMass,
    StaticFriction,
    CoulombFriction,
    VelocityBand,
    StageMass,
    Stiffness,
    Damping,
    ResonanceHz,
    QualityFactor,
    Gain,
    Voltage,
    Frequency,
    Duty,
    Phase,
    Cycles,
    Settle,
    Tolerance,
    MaxStepsPerPeriod,
}

/// What values a key accepts. Every rule is an interval (plus integrality),
/// so a monotone range is valid exactly when both its ends are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rule {
    /// A number > 0.
    Positive,
    /// A number >= 0.
    NonNegative,
    /// Any finite number.
    Finite,
    /// A number in (0, 1].
    Duty,
    /// An integer in [1, u32::MAX].
    Count,
    /// An integer in [0, u32::MAX].
    Settle,
}

impl Rule {
    /// Whether `value` (already known to be finite) is accepted.
    fn accepts(self, value: f64) -> bool {
        let integer = value.fract() == 0.0;
        match self {
            Rule::Positive => value > 0.0,
            Rule::NonNegative => value >= 0.0,
            Rule::Finite => true,
            Rule::Duty => value > 0.0 && value <= 1.0,
            Rule::Count => integer && value >= 1.0 && value <= u32::MAX as f64,
            Rule::Settle => integer && value >= 0.0 && value <= u32::MAX as f64,
        }
    }

    /// What the rule expects, for error messages.
    fn expected(self) -> &'static str {
        match self {
            Rule::Positive => "expected a number > 0",
            Rule::NonNegative => "expected a number >= 0",
            Rule::Finite => "expected a finite number",
            Rule::Duty => "expected a number in (0, 1]",
            Rule::Count => "expected an integer from 1 to 4294967295",
            Rule::Settle => "expected an integer from 0 to 4294967295",
        }
    }

    /// Whether the key holds an integer.
    fn integer(self) -> bool {
        matches!(self, Rule::Count | Rule::Settle)
    }
}

impl Field {
    /// The key's name within its table.
    fn name(self) -> &'static str {
        match self {
            Field::SliderMass => "slider_mass",
            Field::StaticFriction => "static_friction",
            Field::CoulombFriction => "coulomb_friction",
            Field::VelocityBand => "velocity_band",
            Field::StageMass => "stage_mass",
            Field::Stiffness => "stiffness",
            Field::Damping => "damping",
            Field::ResonanceHz => "resonance_hz",
            Field::QualityFactor => "quality_factor",
            Field::Gain => "gain",
            Field::Voltage => "voltage",
            Field::Frequency => "frequency",
            Field::Duty => "duty",
            Field::Phase => "phase",
            Field::Cycles => "cycles",
            Field::Settle => "settle",
            Field::Tolerance => "tolerance",
            Field::MaxStepsPerPeriod => "max_steps_per_period",
        }
    }

    /// The units of the key's values.
    fn units(self) -> &'static str {
        match self {
            Field::SliderMass | Field::StageMass => "kg",
            Field::StaticFriction | Field::CoulombFriction => "N",
            Field::VelocityBand => "m/s",
            Field::Stiffness => "N/m",
            Field::Damping => "N s/m",
            Field::ResonanceHz | Field::Frequency => "Hz",
            Field::QualityFactor | Field::Duty | Field::MaxStepsPerPeriod => "1",
            Field::Gain => "N/V",
            Field::Voltage => "V",
            Field::Phase | Field::Cycles | Field::Settle => "cycles",
            Field::Tolerance => "rad",
        }
    }

    /// What values the key accepts.
    fn rule(self) -> Rule {
        match self {
            Field::SliderMass
            | Field::StaticFriction
            | Field::VelocityBand
            | Field::StageMass
            | Field::Stiffness
            | Field::ResonanceHz
            | Field::QualityFactor
            | Field::Frequency
            | Field::Tolerance => Rule::Positive,
            Field::CoulombFriction | Field::Damping => Rule::NonNegative,
            Field::Gain | Field::Voltage | Field::Phase => Rule::Finite,
            Field::Duty => Rule::Duty,
            Field::Cycles | Field::MaxStepsPerPeriod => Rule::Count,
            Field::Settle => Rule::Settle,
        }
    }

    /// Whether the key applies to the whole scene (one value, no points).
    fn scene_wide(self) -> bool {
        matches!(self, Field::Tolerance | Field::MaxStepsPerPeriod)
    }
}

/// The keys of `[mechanism]`, in slot order.
const MECHANISM_FIELDS: [Field; 4] = [
    Field::SliderMass,
    Field::StaticFriction,
    Field::CoulombFriction,
    Field::VelocityBand,
];

/// The keys of `[axis.x]` and `[axis.y]`, in slot order.
const AXIS_FIELDS: [Field; 10] = [
    Field::StageMass,
    Field::Stiffness,
    Field::Damping,
    Field::ResonanceHz,
    Field::QualityFactor,
    Field::Gain,
    Field::Voltage,
    Field::Frequency,
    Field::Duty,
    Field::Phase,
];

/// The keys of `[simulation]`, in slot order.
const SIMULATION_FIELDS: [Field; 4] = [
    Field::Cycles,
    Field::Settle,
    Field::Tolerance,
    Field::MaxStepsPerPeriod,
];

/// Indices of the axis keys within [`AXIS_FIELDS`].
const STAGE_MASS: usize = 0;
const STIFFNESS: usize = 1;
const DAMPING: usize = 2;
const RESONANCE: usize = 3;
const QUALITY: usize = 4;
const GAIN: usize = 5;
const VOLTAGE: usize = 6;
const FREQUENCY: usize = 7;
const DUTY: usize = 8;
const PHASE: usize = 9;

/// Raw key slots: the mechanism, then each axis, then the simulation.
const AXIS_SLOTS: usize = MECHANISM_FIELDS.len();
const SIMULATION_SLOTS: usize = AXIS_SLOTS + AXES * AXIS_FIELDS.len();
const SLOTS: usize = SIMULATION_SLOTS + SIMULATION_FIELDS.len();
const CYCLES_SLOT: usize = SIMULATION_SLOTS;
const SETTLE_SLOT: usize = SIMULATION_SLOTS + 1;
const TOLERANCE_SLOT: usize = SIMULATION_SLOTS + 2;
const MAX_STEPS_SLOT: usize = SIMULATION_SLOTS + 3;

/// The raw slot of axis key `index` (into [`AXIS_FIELDS`]) of axis `axis`.
fn axis_slot(axis: usize, index: usize) -> usize {
    AXIS_SLOTS + axis * AXIS_FIELDS.len() + index
}

/// The key held by a raw slot.
fn slot_field(slot: usize) -> Field {
    if slot < AXIS_SLOTS {
        MECHANISM_FIELDS[slot]
    } else if slot < SIMULATION_SLOTS {
        AXIS_FIELDS[(slot - AXIS_SLOTS) % AXIS_FIELDS.len()]
    } else {
        SIMULATION_FIELDS[slot - SIMULATION_SLOTS]
    }
}

/// The full dotted path of a raw slot, e.g. "axis.y.voltage".
fn slot_path(slot: usize) -> String {
    let field = slot_field(slot);
    if slot < AXIS_SLOTS {
        format!("mechanism.{}", field.name())
    } else if slot < SIMULATION_SLOTS {
        let axis = (slot - AXIS_SLOTS) / AXIS_FIELDS.len();
        format!("axis.{}.{}", AXIS_NAMES[axis], field.name())
    } else {
        format!("simulation.{}", field.name())
    }
}

/// Keys of the document root.
const ROOT_KEYS: [&str; 7] = [
    "name",
    "description",
    "mechanism",
    "axis",
    "simulation",
    "output",
    "points",
];

/// Keys of one `[[points]]` entry.
const POINT_KEYS: [&str; 4] = ["label", "mechanism", "axis", "simulation"];

/// Keys of a range table.
const RANGE_KEYS: [&str; 4] = ["from", "to", "steps", "log"];

/// Keys of `[output]`.
const OUTPUT_KEYS: [&str; 3] = ["baselines", "trajectories", "trajectory_samples_per_cycle"];

/// What a numeric key should look like, for type errors.
const NUMERIC_EXPECTED: &str =
    "expected a number, a list of numbers or a range { from, to, steps }";

// ---------------------------------------------------------------------------
// Parsed values.

/// The values given to one key.
#[derive(Clone, Debug)]
enum Values {
    /// A scalar or a list.
    List(Vec<f64>),
    /// A range, endpoints included.
    Range {
        from: f64,
        to: f64,
        steps: u64,
        log: bool,
    },
}

impl Values {
    /// Number of values.
    fn len(&self) -> u64 {
        match self {
            Values::List(values) => values.len() as u64,
            Values::Range { steps, .. } => *steps,
        }
    }

    /// Value `i`, computed without expanding a range.
    fn value(&self, i: u64) -> f64 {
        match *self {
            Values::List(ref values) => values[i as usize],
            Values::Range {
                from,
                to,
                steps,
                log,
            } => {
                if i == 0 || steps == 1 {
                    return from;
                }
                if i == steps - 1 {
                    return to;
                }
                let v = if log {
                    from * (to / from).powf(i as f64 / (steps - 1) as f64)
                } else {
                    // Multiplying before dividing keeps integer grids exact.
                    from + (to - from) * i as f64 / (steps - 1) as f64
                };
                // Rounding must not leave the interval: the checks rely on it.
                v.clamp(from.min(to), from.max(to))
            }
        }
    }

    /// All values.
    fn expand(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.value(i)).collect()
    }

    /// The values a validity check must look at: all of a list, the two ends
    /// of a (monotone) range.
    fn extremes(&self) -> Vec<(u64, f64)> {
        match self {
            Values::List(values) => values
                .iter()
                .copied()
                .enumerate()
                .map(|(i, v)| (i as u64, v))
                .collect(),
            Values::Range { from, steps: 1, .. } => vec![(0, *from)],
            Values::Range {
                from, to, steps, ..
            } => vec![(0, *from), (steps - 1, *to)],
        }
    }

    /// The smallest and largest value.
    fn min_max(&self) -> (f64, f64) {
        self.extremes()
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, v)| {
                (lo.min(v), hi.max(v))
            })
    }
}

/// One key as given in the file.
#[derive(Clone, Debug)]
struct Entry {
    /// Its values.
    values: Values,
    /// Where its value is in the text.
    span: Range<usize>,
}

/// The keys given at one level (the base, or one point), by raw slot.
#[derive(Clone, Debug)]
struct Layer {
    entries: [Option<Entry>; SLOTS],
}

impl Default for Layer {
    fn default() -> Self {
        Layer {
            entries: std::array::from_fn(|_| None),
        }
    }
}

impl Layer {
    /// Which keys of axis `axis` are given.
    fn axis_given(&self, axis: usize) -> [bool; AXIS_FIELDS.len()] {
        std::array::from_fn(|j| self.entries[axis_slot(axis, j)].is_some())
    }
}

/// One `[[points]]` entry.
#[derive(Debug)]
struct PointSpec {
    label: String,
    layer: Layer,
}

/// The document, parsed but not yet checked as a whole.
#[derive(Debug, Default)]
struct Parsed {
    name: Option<String>,
    description: Option<String>,
    base: Layer,
    baselines: bool,
    trajectories: Vec<trajectories::SpecAt>,
    samples_per_cycle: Option<u32>,
    points: Option<Vec<PointSpec>>,
}

// ---------------------------------------------------------------------------
// From raw key values to instances.

/// Where a parameter's value comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Src {
    /// A raw key slot (given in the file, possibly by the other axis).
    Slot(usize),
    /// A default.
    Const(f64),
}

impl Src {
    fn get(self, raw: &[f64; SLOTS]) -> f64 {
        match self {
            Src::Slot(slot) => raw[slot],
            Src::Const(value) => value,
        }
    }

    /// Names the source in messages about derived values.
    fn describe(self, field: Field) -> String {
        match self {
            Src::Slot(slot) => slot_path(slot),
            Src::Const(value) => format!("the default {} {}", field.name(), fmt_num(value)),
        }
    }
}

/// How an axis' stage mass and stiffness are obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
enum StagePlan {
    /// Both given (or defaulted).
    MassStiffness { mass: Src, stiffness: Src },
    /// The mass follows from the resonance and the stiffness (eq. 6).
    ResonanceStiffness { resonance: Src, stiffness: Src },
    /// The stiffness follows from the resonance and the mass (eq. 6).
    ResonanceMass { resonance: Src, mass: Src },
}

/// How an axis' damping is obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
enum DampingPlan {
    /// Given (or defaulted).
    Damping(Src),
    /// From the quality factor (eq. 7).
    Quality(Src),
}

/// Where every parameter of one axis comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
struct AxisPlan {
    stage: StagePlan,
    damping: DampingPlan,
    gain: Src,
    voltage: Src,
    frequency: Src,
    duty: Src,
    phase: Src,
}

/// Where every parameter of an instance comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Plan {
    mechanism: [Src; 4],
    axes: [AxisPlan; AXES],
    cycles: Src,
    settle: Src,
}

/// Which keys of a lower layer survive under an upper layer: those the upper
/// one does not give, as long as they do not over-determine the stage. The
/// voltage is kept only when `voltage` is set (a point over the base, not
/// `axis.y` over `axis.x`).
fn kept_from_lower(
    upper: &[bool; AXIS_FIELDS.len()],
    lower: &[bool; AXIS_FIELDS.len()],
    voltage: bool,
) -> [bool; AXIS_FIELDS.len()] {
    let mut kept = [false; AXIS_FIELDS.len()];
    for j in [GAIN, VOLTAGE, FREQUENCY, DUTY, PHASE] {
        kept[j] = lower[j] && !upper[j];
    }
    kept[VOLTAGE] &= voltage;
    let triple = [RESONANCE, STIFFNESS, STAGE_MASS];
    let mut count = triple.iter().filter(|&&j| upper[j]).count();
    for j in triple {
        if lower[j] && !upper[j] && count < 2 {
            kept[j] = true;
            count += 1;
        }
    }
    if !upper[DAMPING] && !upper[QUALITY] {
        kept[DAMPING] = lower[DAMPING];
        kept[QUALITY] = lower[QUALITY];
    }
    kept
}

impl Plan {
    /// The plan for a set of given keys (after points are overlaid).
    fn build(given: &[bool; SLOTS]) -> Plan {
        let own = |axis: usize| -> [bool; AXIS_FIELDS.len()] {
            std::array::from_fn(|j| given[axis_slot(axis, j)])
        };
        let x = own(0);
        let y = own(1);
        let kept = kept_from_lower(&y, &x, false);
        let x_sources: [Option<usize>; AXIS_FIELDS.len()] =
            std::array::from_fn(|j| x[j].then(|| axis_slot(0, j)));
        let y_sources: [Option<usize>; AXIS_FIELDS.len()] = std::array::from_fn(|j| {
            if y[j] {
                Some(axis_slot(1, j))
            } else if kept[j] {
                Some(axis_slot(0, j))
            } else {
                None
            }
        });
        let mechanism_defaults = [
            Mechanism::TABLE1.slider_mass,
            Mechanism::TABLE1.static_friction,
            Mechanism::TABLE1.coulomb_friction,
            Mechanism::TABLE1.velocity_band,
        ];
        let or_default = |slot: usize, default: f64| {
            if given[slot] {
                Src::Slot(slot)
            } else {
                Src::Const(default)
            }
        };
        Plan {
            mechanism: std::array::from_fn(|i| or_default(i, mechanism_defaults[i])),
            axes: [
                AxisPlan::build(&x_sources, Axis::TABLE1.voltage),
                AxisPlan::build(&y_sources, 0.0),
            ],
            cycles: or_default(CYCLES_SLOT, Instance::TABLE1.cycles as f64),
            settle: or_default(SETTLE_SLOT, Instance::TABLE1.settle as f64),
        }
    }

    /// The instance for a set of raw key values.
    fn resolve(&self, raw: &[f64; SLOTS]) -> Instance {
        let [
            slider_mass,
            static_friction,
            coulomb_friction,
            velocity_band,
        ] = self.mechanism.map(|src| src.get(raw));
        Instance {
            mechanism: Mechanism {
                slider_mass,
                static_friction,
                coulomb_friction,
                velocity_band,
            },
            axes: [self.axes[0].resolve(raw), self.axes[1].resolve(raw)],
            cycles: self.cycles.get(raw) as u32,
            settle: self.settle.get(raw) as u32,
        }
    }
}

impl AxisPlan {
    /// The plan of one axis from the slots its keys come from.
    fn build(sources: &[Option<usize>; AXIS_FIELDS.len()], voltage: f64) -> AxisPlan {
        let t = Axis::TABLE1;
        let src = |j: usize, default: f64| sources[j].map_or(Src::Const(default), Src::Slot);
        let stage = match (sources[STAGE_MASS], sources[STIFFNESS], sources[RESONANCE]) {
            (_, _, None) => StagePlan::MassStiffness {
                mass: src(STAGE_MASS, t.stage_mass),
                stiffness: src(STIFFNESS, t.stiffness),
            },
            (Some(mass), None, Some(resonance)) => StagePlan::ResonanceMass {
                resonance: Src::Slot(resonance),
                mass: Src::Slot(mass),
            },
            // Three stage keys never reach here: layers are checked, and
            // inheritance keeps at most two.
            (_, _, Some(resonance)) => StagePlan::ResonanceStiffness {
                resonance: Src::Slot(resonance),
                stiffness: src(STIFFNESS, t.stiffness),
            },
        };
        let damping = match sources[QUALITY] {
            Some(quality) => DampingPlan::Quality(Src::Slot(quality)),
            None => DampingPlan::Damping(src(DAMPING, t.damping)),
        };
        AxisPlan {
            stage,
            damping,
            gain: src(GAIN, t.gain),
            voltage: src(VOLTAGE, voltage),
            frequency: src(FREQUENCY, t.frequency),
            duty: src(DUTY, t.duty),
            phase: src(PHASE, t.phase),
        }
    }

    fn resolve(&self, raw: &[f64; SLOTS]) -> Axis {
        let (stage_mass, stiffness) = match self.stage {
            StagePlan::MassStiffness { mass, stiffness } => (mass.get(raw), stiffness.get(raw)),
            StagePlan::ResonanceStiffness {
                resonance,
                stiffness,
            } => {
                let k = stiffness.get(raw);
                (Axis::mass_from_resonance(resonance.get(raw), k), k)
            }
            StagePlan::ResonanceMass { resonance, mass } => {
                let m = mass.get(raw);
                (m, Axis::stiffness_from_resonance(resonance.get(raw), m))
            }
        };
        let damping = match self.damping {
            DampingPlan::Damping(c) => c.get(raw),
            DampingPlan::Quality(q) => {
                Axis::damping_from_quality(q.get(raw), stiffness, stage_mass)
            }
        };
        Axis {
            stage_mass,
            stiffness,
            damping,
            gain: self.gain.get(raw),
            voltage: self.voltage.get(raw),
            frequency: self.frequency.get(raw),
            duty: self.duty.get(raw),
            phase: self.phase.get(raw),
        }
    }
}

/// The raw slots an error may be located by, most relevant first.
type Culprits = [Option<usize>; 2];

/// The slot of a source, when it comes from the file.
fn src_slot(src: Src) -> Option<usize> {
    match src {
        Src::Slot(slot) => Some(slot),
        Src::Const(_) => None,
    }
}

/// Checks what per-key checks cannot: derived stage quantities and
/// settle < cycles. Returns the message and the slots to locate it by.
fn check_instance(instance: &Instance, plan: &Plan) -> Result<(), (String, Culprits)> {
    for (a, (axis, axis_plan)) in instance.axes.iter().zip(&plan.axes).enumerate() {
        let name = AXIS_NAMES[a];
        let derived = match axis_plan.stage {
            StagePlan::MassStiffness { .. } => None,
            StagePlan::ResonanceStiffness {
                resonance,
                stiffness,
            } => Some((
                Field::StageMass,
                axis.stage_mass,
                resonance,
                format!(
                    "{} and {}",
                    resonance.describe(Field::ResonanceHz),
                    stiffness.describe(Field::Stiffness)
                ),
            )),
            StagePlan::ResonanceMass { resonance, mass } => Some((
                Field::Stiffness,
                axis.stiffness,
                resonance,
                format!(
                    "{} and {}",
                    resonance.describe(Field::ResonanceHz),
                    mass.describe(Field::StageMass)
                ),
            )),
        };
        if let Some((field, value, resonance, from)) = derived
            && !(value.is_finite() && value > 0.0)
        {
            return Err((
                format!(
                    "axis.{name}.{} = {} (derived from {from}): expected a finite number > 0",
                    field.name(),
                    fmt_num(value)
                ),
                [src_slot(resonance), None],
            ));
        }
        if let DampingPlan::Quality(quality) = axis_plan.damping
            && !(axis.damping.is_finite() && axis.damping >= 0.0)
        {
            return Err((
                format!(
                    "axis.{name}.damping = {} (derived from {}, the stiffness and the stage \
                     mass): expected a finite number >= 0",
                    fmt_num(axis.damping),
                    quality.describe(Field::QualityFactor)
                ),
                [src_slot(quality), None],
            ));
        }
    }
    if instance.settle >= instance.cycles {
        return Err((
            format!(
                "simulation.settle = {} with simulation.cycles = {}: expected settle < cycles \
                 (the settle periods are discarded before measuring)",
                instance.settle, instance.cycles
            ),
            [src_slot(plan.settle), src_slot(plan.cycles)],
        ));
    }
    Ok(())
}

/// Formats a number for messages: integers without a fraction, others in
/// their shortest round-trip form, non-finite values as TOML writes them.
fn fmt_num(value: f64) -> String {
    if value.is_nan() {
        "nan".to_owned()
    } else if value.is_infinite() {
        if value > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else if value.fract() == 0.0 && value.abs() < 1e16 {
        format!("{value:.0}")
    } else {
        format!("{value:?}")
    }
}

/// Formats a number for summaries: integers as they are, others to six
/// significant digits.
fn fmt_short(value: f64) -> String {
    if !value.is_finite() || value == 0.0 || (value.fract() == 0.0 && value.abs() < 1e16) {
        return fmt_num(value);
    }
    let magnitude = value.abs().log10().floor();
    let text = if (-3.0..7.0).contains(&magnitude) {
        let decimals = (5.0 - magnitude).max(0.0) as usize;
        format!("{value:.decimals$}")
    } else {
        format!("{value:.5e}")
    };
    // Trailing zeros of the mantissa carry nothing.
    let (mantissa, exponent) = match text.find('e') {
        Some(e) => text.split_at(e),
        None => (text.as_str(), ""),
    };
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    format!("{mantissa}{exponent}")
}

// ---------------------------------------------------------------------------
// Parsing.

/// Whether keys are read for the base scene or for one point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Context {
    Base,
    Point,
}

/// Reads a parsed TOML document into layers, checking every key and value.
struct Parser<'t> {
    text: &'t str,
}

type Value<'a> = Spanned<DeValue<'a>>;
type Key<'a> = Spanned<std::borrow::Cow<'a, str>>;

impl Parser<'_> {
    /// The line and column of a byte offset.
    fn locate(&self, offset: usize) -> Location {
        let before = self.text.get(..offset).unwrap_or(self.text);
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        Location {
            line: before.matches('\n').count() + 1,
            column: before[line_start..].chars().count() + 1,
        }
    }

    /// An [`SceneError::Invalid`] located at `span`.
    fn invalid(&self, span: Range<usize>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            message: message.into(),
            location: Some(self.locate(span.start)),
        }
    }

    /// The source text of a value, shortened for messages.
    fn source(&self, span: Range<usize>) -> String {
        let text = self.text.get(span).unwrap_or("").trim();
        let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
        if text.chars().count() > 60 {
            let short: String = text.chars().take(57).collect();
            format!("{short}...")
        } else {
            text
        }
    }

    /// Describes a value of the wrong type: "a string \"abc\"".
    fn found(&self, value: &Value<'_>) -> String {
        match value.get_ref() {
            DeValue::String(s) => format!("a string {:?}", s.as_ref()),
            DeValue::Integer(_) => format!("an integer {}", self.source(value.span())),
            DeValue::Float(_) => format!("a float {}", self.source(value.span())),
            DeValue::Boolean(b) => format!("a boolean {b}"),
            DeValue::Datetime(d) => format!("a date-time {d}"),
            DeValue::Array(_) => format!("a list {}", self.source(value.span())),
            DeValue::Table(_) => "a table".to_owned(),
        }
    }

    /// A wrong-type error.
    fn wrong_type(&self, path: &str, expected: &str, value: &Value<'_>) -> SceneError {
        self.invalid(
            value.span(),
            format!("{path}: {expected}, found {}", self.found(value)),
        )
    }

    /// An unknown-key error, with the closest valid key or the table the key
    /// belongs to.
    fn unknown_key(&self, key: &Key<'_>, prefix: &str, candidates: &[&str]) -> SceneError {
        let name = key.get_ref().as_ref();
        let path = join(prefix, name);
        let hint = match home_of(name) {
            Some(home) => format!(" (`{name}` belongs in {home})"),
            None => match suggest(name, candidates) {
                Some(best) => format!(" (did you mean `{best}`?)"),
                None => format!(" (expected one of: {})", candidates.join(", ")),
            },
        };
        self.invalid(key.span(), format!("unknown key `{path}`{hint}"))
    }

    /// A table value.
    fn table<'v, 'a>(
        &self,
        path: &str,
        expected: &str,
        value: &'v Value<'a>,
    ) -> Result<&'v DeTable<'a>, SceneError> {
        match value.get_ref() {
            DeValue::Table(table) => Ok(table),
            _ => Err(self.wrong_type(path, expected, value)),
        }
    }

    /// A string value.
    fn string(&self, path: &str, value: &Value<'_>) -> Result<String, SceneError> {
        match value.get_ref() {
            DeValue::String(s) => Ok(s.to_string()),
            _ => Err(self.wrong_type(path, "expected a string", value)),
        }
    }

    /// A number (integer or float, possibly non-finite).
    fn number(value: &DeValue<'_>) -> Option<f64> {
        match value {
            DeValue::Integer(i) => i128::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|n| n as f64),
            DeValue::Float(f) => {
                let text = f.as_str();
                text.parse::<f64>().ok().or_else(|| {
                    let lower = text.to_ascii_lowercase();
                    if lower.contains("nan") {
                        Some(f64::NAN)
                    } else if lower.contains("inf") {
                        Some(if lower.starts_with('-') {
                            f64::NEG_INFINITY
                        } else {
                            f64::INFINITY
                        })
                    } else {
                        None
                    }
                })
            }
            _ => None,
        }
    }

    /// A single finite number.
    fn finite(&self, path: &str, value: &Value<'_>) -> Result<f64, SceneError> {
        let number = Self::number(value.get_ref())
            .ok_or_else(|| self.wrong_type(path, "expected a number", value))?;
        if !number.is_finite() {
            return Err(self.invalid(
                value.span(),
                format!("{path} = {}: expected a finite number", fmt_num(number)),
            ));
        }
        Ok(number)
    }

    /// The document root.
    fn root(&self, table: &DeTable<'_>) -> Result<Parsed, SceneError> {
        let mut parsed = Parsed::default();
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "name" => parsed.name = Some(self.string("name", value)?),
                "description" => parsed.description = Some(self.string("description", value)?),
                "mechanism" => self.group(
                    value,
                    "mechanism",
                    &MECHANISM_FIELDS,
                    0,
                    &mut parsed.base,
                    Context::Base,
                )?,
                "axis" => self.axes(value, &mut parsed.base, Context::Base)?,
                "simulation" => self.group(
                    value,
                    "simulation",
                    &SIMULATION_FIELDS,
                    SIMULATION_SLOTS,
                    &mut parsed.base,
                    Context::Base,
                )?,
                "output" => self.output(value, &mut parsed)?,
                "points" => parsed.points = Some(self.points(value)?),
                _ => return Err(self.unknown_key(key, "", &ROOT_KEYS)),
            }
        }
        self.check_stage_keys(&parsed.base)?;
        Ok(parsed)
    }

    /// `[axis]`: the tables `x` and `y`.
    fn axes(
        &self,
        value: &Value<'_>,
        layer: &mut Layer,
        context: Context,
    ) -> Result<(), SceneError> {
        let table = self.table(
            "axis",
            "expected a table of axes ([axis.x], [axis.y])",
            value,
        )?;
        for (key, value) in table.iter() {
            let name = key.get_ref().as_ref();
            let Some(axis) = AXIS_NAMES.iter().position(|&n| n == name) else {
                return Err(self.unknown_key(key, "axis", &AXIS_NAMES));
            };
            self.group(
                value,
                &format!("axis.{name}"),
                &AXIS_FIELDS,
                axis_slot(axis, 0),
                layer,
                context,
            )?;
        }
        Ok(())
    }

    /// A table of numeric keys: `[mechanism]`, `[axis.*]` or `[simulation]`.
    fn group(
        &self,
        value: &Value<'_>,
        path: &str,
        fields: &[Field],
        slot_base: usize,
        layer: &mut Layer,
        context: Context,
    ) -> Result<(), SceneError> {
        let table = self.table(path, "expected a table", value)?;
        let names: Vec<&str> = fields.iter().map(|f| f.name()).collect();
        for (key, value) in table.iter() {
            let name = key.get_ref().as_ref();
            let Some(index) = names.iter().position(|&n| n == name) else {
                return Err(self.unknown_key(key, path, &names));
            };
            let field = fields[index];
            let key_path = format!("{path}.{name}");
            if field.scene_wide() && context == Context::Point {
                return Err(self.invalid(
                    key.span(),
                    format!(
                        "{key_path} cannot be set per point: the integrator settings apply to \
                         the whole scene (set them in the base [simulation])"
                    ),
                ));
            }
            let values = self.values(&key_path, field, value)?;
            if values.len() > 1 && (field.scene_wide() || context == Context::Point) {
                let why = if context == Context::Point {
                    "a point's values must be single numbers (points give a list of instances, \
                     not a grid)"
                } else {
                    "it applies to the whole scene and cannot be a grid axis"
                };
                return Err(self.invalid(
                    value.span(),
                    format!(
                        "{key_path} = {}: expected a single value, found {} values; {why}",
                        self.source(value.span()),
                        values.len()
                    ),
                ));
            }
            layer.entries[slot_base + index] = Some(Entry {
                values,
                span: value.span(),
            });
        }
        Ok(())
    }

    /// The values of a numeric key, each checked against the key's rule.
    fn values(&self, path: &str, field: Field, value: &Value<'_>) -> Result<Values, SceneError> {
        let values = match value.get_ref() {
            DeValue::Integer(_) | DeValue::Float(_) => {
                Values::List(vec![Self::number(value.get_ref()).unwrap_or(f64::NAN)])
            }
            DeValue::Array(items) => {
                if items.is_empty() {
                    return Err(self.invalid(
                        value.span(),
                        format!("{path} = []: expected at least one value (an empty list gives no instances)"),
                    ));
                }
                let mut numbers = Vec::with_capacity(items.len());
                for (i, item) in items.iter().enumerate() {
                    match Self::number(item.get_ref()) {
                        Some(number) => numbers.push(number),
                        None => {
                            return Err(self.wrong_type(
                                &format!("{path}[{i}]"),
                                "expected a number",
                                item,
                            ));
                        }
                    }
                }
                Values::List(numbers)
            }
            DeValue::Table(table) => self.range(path, field, value.span(), table)?,
            _ => return Err(self.wrong_type(path, NUMERIC_EXPECTED, value)),
        };
        let rule = field.rule();
        let source = self.source(value.span());
        for (i, number) in values.extremes() {
            let context = match &values {
                Values::List(list) if list.len() == 1 => String::new(),
                Values::List(_) => format!(" (value {} of {source})", i + 1),
                Values::Range { .. } => format!(" (in the range {source})"),
            };
            if !number.is_finite() {
                return Err(self.invalid(
                    value.span(),
                    format!(
                        "{path} = {}: expected a finite number{context}",
                        fmt_num(number)
                    ),
                ));
            }
            if !rule.accepts(number) {
                return Err(self.invalid(
                    value.span(),
                    format!("{path} = {}: {}{context}", fmt_num(number), rule.expected()),
                ));
            }
        }
        Ok(values)
    }

    /// A range table `{ from, to, steps, log }`.
    fn range(
        &self,
        path: &str,
        field: Field,
        span: Range<usize>,
        table: &DeTable<'_>,
    ) -> Result<Values, SceneError> {
        let (mut from, mut to, mut steps, mut log) = (None, None, None, false);
        for (key, value) in table.iter() {
            let key_path = format!("{path}.{}", key.get_ref());
            match key.get_ref().as_ref() {
                "from" => from = Some(self.finite(&key_path, value)?),
                "to" => to = Some(self.finite(&key_path, value)?),
                "steps" => {
                    let number = Self::number(value.get_ref()).ok_or_else(|| {
                        self.wrong_type(&key_path, "expected an integer >= 1", value)
                    })?;
                    if !(number >= 1.0 && number.fract() == 0.0 && number < 2f64.powi(63)) {
                        return Err(self.invalid(
                            value.span(),
                            format!("{key_path} = {}: expected an integer >= 1", fmt_num(number)),
                        ));
                    }
                    steps = Some(number as u64);
                }
                "log" => match value.get_ref() {
                    DeValue::Boolean(b) => log = *b,
                    _ => {
                        return Err(self.wrong_type(
                            &key_path,
                            "expected a boolean (true or false)",
                            value,
                        ));
                    }
                },
                _ => return Err(self.unknown_key(key, path, &RANGE_KEYS)),
            }
        }
        let source = self.source(span.clone());
        let missing = [
            ("from", from.is_none()),
            ("to", to.is_none()),
            ("steps", steps.is_none()),
        ];
        if let Some((name, _)) = missing.iter().find(|(_, missing)| *missing) {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: a range needs `from`, `to` and `steps`, but `{name}` is missing"
                ),
            ));
        }
        let (from, to, steps) = (from.unwrap_or(0.0), to.unwrap_or(0.0), steps.unwrap_or(1));
        let rule = field.rule();
        if log && rule.integer() {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: an integer key cannot take a log range; give a list of integers"
                ),
            ));
        }
        if log && !(from > 0.0 && to > 0.0) {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: a log range needs from > 0 and to > 0, found from = {} and to = {}",
                    fmt_num(from),
                    fmt_num(to)
                ),
            ));
        }
        if rule.integer() && steps > 1 {
            let step = (to - from) / (steps - 1) as f64;
            if step.fract() != 0.0 {
                return Err(self.invalid(
                    span,
                    format!(
                        "{path} = {source}: the values do not land on integers (step {}); \
                         choose steps so that (to - from) / (steps - 1) is an integer",
                        fmt_num(step)
                    ),
                ));
            }
        }
        Ok(Values::Range {
            from,
            to,
            steps,
            log,
        })
    }

    /// `[output]`.
    fn output(&self, value: &Value<'_>, parsed: &mut Parsed) -> Result<(), SceneError> {
        let table = self.table("output", "expected a table", value)?;
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "trajectories" => parsed.trajectories = self.trajectories(value)?,
                "trajectory_samples_per_cycle" => {
                    parsed.samples_per_cycle = Some(self.samples_per_cycle(value)?);
                }
                "baselines" => match value.get_ref() {
                    DeValue::Boolean(b) => parsed.baselines = *b,
                    _ => {
                        return Err(self.wrong_type(
                            "output.baselines",
                            "expected a boolean (true or false)",
                            value,
                        ));
                    }
                },
                _ => return Err(self.unknown_key(key, "output", &OUTPUT_KEYS)),
            }
        }
        Ok(())
    }

    /// `[[points]]`.
    fn points(&self, value: &Value<'_>) -> Result<Vec<PointSpec>, SceneError> {
        let DeValue::Array(items) = value.get_ref() else {
            return Err(self.wrong_type("points", "expected a list of tables ([[points]])", value));
        };
        if items.is_empty() {
            return Err(self.invalid(value.span(), "points = []: expected at least one point"));
        }
        let mut points = Vec::with_capacity(items.len());
        for (index, item) in items.iter().enumerate() {
            let DeValue::Table(table) = item.get_ref() else {
                return Err(self.wrong_type(&format!("points[{index}]"), "expected a table", item));
            };
            let label = match table.get("label") {
                Some(label) => self
                    .string("label", label)
                    .map_err(|e| e.in_point(index, ""))?,
                None => String::new(),
            };
            let layer = self.point(table).map_err(|e| e.in_point(index, &label))?;
            points.push(PointSpec { label, layer });
        }
        Ok(points)
    }

    /// One point's keys.
    fn point(&self, table: &DeTable<'_>) -> Result<Layer, SceneError> {
        let mut layer = Layer::default();
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "label" => {}
                "mechanism" => self.group(
                    value,
                    "mechanism",
                    &MECHANISM_FIELDS,
                    0,
                    &mut layer,
                    Context::Point,
                )?,
                "axis" => self.axes(value, &mut layer, Context::Point)?,
                "simulation" => self.group(
                    value,
                    "simulation",
                    &SIMULATION_FIELDS,
                    SIMULATION_SLOTS,
                    &mut layer,
                    Context::Point,
                )?,
                name @ ("name" | "description" | "output" | "points") => {
                    return Err(self.invalid(
                        key.span(),
                        format!("`{name}` cannot be set per point: it applies to the whole scene"),
                    ));
                }
                _ => return Err(self.unknown_key(key, "", &POINT_KEYS)),
            }
        }
        self.check_stage_keys(&layer)?;
        Ok(layer)
    }

    /// Refuses a layer whose stage keys over-determine a stage.
    fn check_stage_keys(&self, layer: &Layer) -> Result<(), SceneError> {
        for (axis, name) in AXIS_NAMES.iter().enumerate() {
            let given = layer.axis_given(axis);
            let span = |j: usize| {
                layer.entries[axis_slot(axis, j)]
                    .as_ref()
                    .map_or(0..0, |e| e.span.clone())
            };
            if given[STAGE_MASS] && given[STIFFNESS] && given[RESONANCE] {
                return Err(self.invalid(
                    span(RESONANCE),
                    format!(
                        "axis.{name}: stage_mass, stiffness and resonance_hz over-determine the \
                         stage (f_r = sqrt(k/m) / (2 pi)); give two of them"
                    ),
                ));
            }
            if given[DAMPING] && given[QUALITY] {
                return Err(self.invalid(
                    span(QUALITY),
                    format!(
                        "axis.{name}: damping and quality_factor both set the damping \
                         (c = sqrt(k m) / Q); give one of them"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Joins a table path and a key.
fn join(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_owned()
    } else {
        format!("{prefix}.{name}")
    }
}

/// The table a key belongs in, when it is a valid key somewhere.
fn home_of(name: &str) -> Option<&'static str> {
    let is = |fields: &[Field]| fields.iter().any(|f| f.name() == name);
    if is(&MECHANISM_FIELDS) {
        Some("[mechanism]")
    } else if is(&AXIS_FIELDS) {
        Some("[axis.x] or [axis.y]")
    } else if is(&SIMULATION_FIELDS) {
        Some("[simulation]")
    } else if OUTPUT_KEYS.contains(&name) {
        Some("[output]")
    } else if AXIS_NAMES.contains(&name) {
        Some("[axis], as [axis.x] and [axis.y]")
    } else if name == "label" {
        Some("[[points]]")
    } else if ROOT_KEYS.contains(&name) {
        Some("the top level of the scene")
    } else {
        None
    }
}

/// The candidate closest to `name`: a prefix or container of it, or one
/// within a few edits.
fn suggest<'c>(name: &str, candidates: &[&'c str]) -> Option<&'c str> {
    let lower = name.to_ascii_lowercase();
    let best = candidates
        .iter()
        .map(|&c| (edit_distance(&lower, c), c))
        .min_by_key(|&(d, _)| d)?;
    let length = lower.chars().count();
    if best.0 < length && best.0 <= (length / 3).max(1) {
        return Some(best.1);
    }
    if length >= 3 {
        return candidates
            .iter()
            .copied()
            .find(|c| c.contains(lower.as_str()));
    }
    None
}

/// Optimal-string-alignment edit distance (insertions, deletions,
/// substitutions and transpositions of neighbours).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = best;
        }
    }
    d[a.len()][b.len()]
}

// ---------------------------------------------------------------------------
// The scene.

impl Scene {
    /// Parses and validates a scene. `default_name` is used when the text has
    /// no `name` (the file stem, when loading a file).
    pub fn from_toml(text: &str, default_name: Option<&str>) -> Result<Scene, SceneError> {
        let document = DeTable::parse(text).map_err(|source| SceneError::Syntax { source })?;
        let parser = Parser { text };
        let parsed = parser.root(document.get_ref())?;

        let name = match parsed.name {
            Some(name) => name,
            None => default_name
                .map(str::to_owned)
                .ok_or_else(|| SceneError::Invalid {
                    message: "name: missing; a scene read from text needs `name = \"...\"`"
                        .to_owned(),
                    location: None,
                })?,
        };
        if name.trim().is_empty() {
            return Err(SceneError::Invalid {
                message: format!("name = {name:?}: expected a non-empty string"),
                location: None,
            });
        }

        let base = &parsed.base;
        let mut settings = Settings::default();
        if let Some(entry) = &base.entries[TOLERANCE_SLOT] {
            settings.tolerance = entry.values.value(0);
        }
        if let Some(entry) = &base.entries[MAX_STEPS_SLOT] {
            settings.max_steps_per_period = entry.values.value(0) as u32;
        }

        let mut raw = [0.0; SLOTS];
        let mut given = [false; SLOTS];
        for (slot, entry) in base.entries.iter().enumerate() {
            if let Some(entry) = entry {
                given[slot] = true;
                raw[slot] = entry.values.value(0);
            }
        }
        let mut grid: Vec<(usize, &Entry)> = base
            .entries
            .iter()
            .enumerate()
            .filter_map(|(slot, entry)| entry.as_ref().map(|e| (slot, e)))
            .filter(|(_, entry)| entry.values.len() > 1)
            .collect();
        grid.sort_by_key(|(_, entry)| entry.span.start);

        let plan = Plan::build(&given);
        // Locates an error by the first culprit found, layer by layer (the
        // point first).
        let locate_slot = |culprits: Culprits, layers: &[&Layer]| {
            layers.iter().find_map(|layer| {
                culprits
                    .iter()
                    .flatten()
                    .find_map(|&slot| layer.entries[slot].as_ref())
                    .map(|entry| parser.locate(entry.span.start))
            })
        };

        let mut scene = Scene {
            name,
            text: text.to_owned(),
            layout: Layout::Grid { axes: Vec::new() },
            baselines: parsed.baselines,
            settings,
            trajectories: Vec::new(),
            trajectory_samples_per_cycle: parsed
                .samples_per_cycle
                .unwrap_or(DEFAULT_SAMPLES_PER_CYCLE),
            description: parsed.description,
            plan,
            raw,
            grid_slots: Vec::new(),
            points: Vec::new(),
            point_keys: Vec::new(),
            driven: [false; AXES],
        };

        if let Some(points) = parsed.points {
            if let Some((slot, entry)) = grid.first() {
                return Err(parser.invalid(
                    entry.span.clone(),
                    format!(
                        "{} has {} values, but a scene with [[points]] cannot have grid axes: \
                         give each point its own value, or drop [[points]]",
                        slot_path(*slot),
                        entry.values.len()
                    ),
                ));
            }
            let mut labels = Vec::with_capacity(points.len());
            for (index, point) in points.iter().enumerate() {
                let mut point_given = given;
                let mut point_raw = raw;
                for (slot, entry) in point.layer.entries.iter().enumerate() {
                    if let Some(entry) = entry {
                        point_given[slot] = true;
                        point_raw[slot] = entry.values.value(0);
                    }
                }
                for axis in 0..AXES {
                    let upper = point.layer.axis_given(axis);
                    let lower = base.axis_given(axis);
                    let kept = kept_from_lower(&upper, &lower, true);
                    for j in 0..AXIS_FIELDS.len() {
                        point_given[axis_slot(axis, j)] = upper[j] || kept[j];
                    }
                }
                let point_plan = Plan::build(&point_given);
                let instance = point_plan.resolve(&point_raw);
                check_instance(&instance, &point_plan).map_err(|(message, slot)| {
                    SceneError::Invalid {
                        message: format!("{}: {message}", point_name(index, &point.label)),
                        location: locate_slot(slot, &[&point.layer, base]),
                    }
                })?;
                scene.points.push(instance);
                labels.push(point.label.clone());
                let mut keys: Vec<(usize, String)> = point
                    .layer
                    .entries
                    .iter()
                    .enumerate()
                    .filter_map(|(slot, entry)| {
                        entry.as_ref().map(|entry| {
                            let value = fmt_short(entry.values.value(0));
                            (entry.span.start, format!("{} = {value}", slot_path(slot)))
                        })
                    })
                    .collect();
                keys.sort();
                let keys: Vec<String> = keys.into_iter().map(|(_, key)| key).collect();
                scene.point_keys.push(if keys.is_empty() {
                    "the base".to_owned()
                } else {
                    keys.join(", ")
                });
            }
            scene.layout = Layout::Points { labels };
            scene.trajectories = parser.resolve_trajectories(&parsed.trajectories, &scene)?;
            scene.check_memory(MAP_MEMORY_BUDGET_BYTES)?;
            for (a, driven) in scene.driven.iter_mut().enumerate() {
                *driven = scene.points.iter().any(|p| p.axes[a].is_driven());
            }
            return Ok(scene);
        }

        // Refuse oversized grids before expanding any range.
        let shape: Vec<u64> = grid.iter().map(|(_, entry)| entry.values.len()).collect();
        check_memory(&shape, false, scene.baselines, MAP_MEMORY_BUDGET_BYTES)?;

        // Per-key checks covered every value; derived quantities and
        // settle < cycles are monotone in each key, so the corners of the
        // grid over the keys involved cover every instance.
        let involved: Vec<(usize, f64, f64)> = grid
            .iter()
            .filter(|(slot, _)| {
                let field = slot_field(*slot);
                matches!(
                    field,
                    Field::StageMass
                        | Field::Stiffness
                        | Field::ResonanceHz
                        | Field::QualityFactor
                        | Field::Cycles
                        | Field::Settle
                )
            })
            .map(|(slot, entry)| {
                let (lo, hi) = entry.values.min_max();
                (*slot, lo, hi)
            })
            .collect();
        for corner in 0..1u64 << involved.len() {
            let mut corner_raw = raw;
            for (bit, &(slot, lo, hi)) in involved.iter().enumerate() {
                corner_raw[slot] = if (corner >> bit) & 1 == 1 { hi } else { lo };
            }
            let instance = plan.resolve(&corner_raw);
            check_instance(&instance, &plan).map_err(|(message, slot)| SceneError::Invalid {
                message,
                location: locate_slot(slot, &[base]),
            })?;
        }

        let axes: Vec<GridAxis> = grid
            .iter()
            .map(|(slot, entry)| GridAxis {
                key: slot_path(*slot),
                values: entry.values.expand(),
                units: slot_field(*slot).units(),
            })
            .collect();
        scene.grid_slots = grid.iter().map(|(slot, _)| *slot).collect();
        for a in 0..AXES {
            scene.driven[a] = match plan.axes[a].voltage {
                Src::Const(v) => v != 0.0,
                Src::Slot(slot) => match scene.grid_slots.iter().position(|&s| s == slot) {
                    Some(g) => axes[g].values.iter().any(|&v| v != 0.0),
                    None => raw[slot] != 0.0,
                },
            };
        }
        scene.layout = Layout::Grid { axes };
        scene.trajectories = parser.resolve_trajectories(&parsed.trajectories, &scene)?;
        Ok(scene)
    }

    /// Reads and validates a scene file; its stem is the default name.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_owned(),
            source,
        })?;
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

    /// Whether axis `axis` has a non-zero voltage in at least one instance.
    pub fn axis_ever_driven(&self, axis: usize) -> bool {
        self.driven.get(axis).copied().unwrap_or(false)
    }

    /// Output bytes per instance: 5 maps of f64, plus 2 with baselines.
    pub fn bytes_per_instance(&self) -> u64 {
        bytes_per_instance(self.baselines)
    }

    /// Refuses the scene when its output maps exceed `budget_bytes`.
    pub fn check_memory(&self, budget_bytes: u64) -> Result<(), SceneError> {
        let shape: Vec<u64> = self.shape().iter().map(|&n| n as u64).collect();
        let points = matches!(self.layout, Layout::Points { .. });
        check_memory(&shape, points, self.baselines, budget_bytes)
    }

    /// A multi-line human summary: name, grid axes or points, instance
    /// count, baselines, settings and the first instance's parameters.
    pub fn describe(&self) -> String {
        let mut out = String::new();
        let count = self.instance_count();
        let _ = writeln!(out, "scene {:?}", self.name);
        if let Some(description) = &self.description {
            let _ = writeln!(out, "  {}", description.trim());
        }
        match &self.layout {
            Layout::Grid { axes } if axes.is_empty() => {
                let _ = writeln!(out, "single instance");
            }
            Layout::Grid { axes } => {
                let dims: Vec<String> = axes.iter().map(|a| a.values.len().to_string()).collect();
                let _ = writeln!(
                    out,
                    "grid {} = {count} instances (row-major, last axis fastest):",
                    dims.join(" x ")
                );
                let width = axes.iter().map(|a| a.key.len()).max().unwrap_or(0);
                for axis in axes {
                    let _ = writeln!(
                        out,
                        "  {:width$}  {}",
                        axis.key,
                        describe_values(&axis.values, axis.units)
                    );
                }
            }
            Layout::Points { labels } => {
                let _ = writeln!(out, "{count} points:");
                for (i, (label, keys)) in labels.iter().zip(&self.point_keys).enumerate() {
                    let label = if label.is_empty() {
                        String::new()
                    } else {
                        format!("{label}: ")
                    };
                    let _ = writeln!(out, "  [{i}] {label}{keys}");
                }
            }
        }
        let _ = writeln!(
            out,
            "baselines: {}",
            if self.baselines {
                "yes (the two 1-DOF runs of every instance)"
            } else {
                "no"
            }
        );
        if !self.trajectories.is_empty() {
            let names: Vec<&str> = self.trajectories.iter().map(|t| t.name.as_str()).collect();
            let _ = writeln!(
                out,
                "trajectories ({} samples per period): {}",
                self.trajectory_samples_per_cycle,
                names.join("; ")
            );
        }
        let _ = writeln!(
            out,
            "integrator: tolerance {} rad, at most {} steps per period",
            fmt_short(self.settings.tolerance),
            self.settings.max_steps_per_period
        );
        let bytes = count as u128 * self.bytes_per_instance() as u128;
        let human = human_bytes(bytes as f64);
        if bytes < 1024 {
            let _ = writeln!(out, "output maps: {human}");
        } else {
            let _ = writeln!(out, "output maps: {human} ({bytes} bytes)");
        }
        if count > 0 {
            let first = self.instance(0);
            let m = first.mechanism;
            let _ = writeln!(out, "instance 0:");
            let _ = writeln!(
                out,
                "  mechanism: slider_mass {} kg, static_friction {} N, coulomb_friction {} N, velocity_band {} m/s",
                fmt_short(m.slider_mass),
                fmt_short(m.static_friction),
                fmt_short(m.coulomb_friction),
                fmt_short(m.velocity_band)
            );
            for (axis, name) in first.axes.iter().zip(AXIS_NAMES) {
                let _ = writeln!(
                    out,
                    "  axis.{name}: stage_mass {} kg, stiffness {} N/m, damping {} N s/m \
                     (resonance {:.4} Hz, Q {:.4}), gain {} N/V, voltage {} V, frequency {} Hz, \
                     duty {}, phase {} cycles",
                    fmt_short(axis.stage_mass),
                    fmt_short(axis.stiffness),
                    fmt_short(axis.damping),
                    axis.resonance_hz(),
                    axis.quality_factor(),
                    fmt_short(axis.gain),
                    fmt_short(axis.voltage),
                    fmt_short(axis.frequency),
                    fmt_short(axis.duty),
                    fmt_short(axis.phase)
                );
            }
            let _ = writeln!(
                out,
                "  simulation: cycles {}, settle {}",
                first.cycles, first.settle
            );
        }
        out
    }
}

/// Output bytes per instance.
fn bytes_per_instance(baselines: bool) -> u64 {
    let maps = MAPS_PER_INSTANCE
        + if baselines {
            BASELINE_MAPS_PER_INSTANCE
        } else {
            0
        };
    maps * MAP_ENTRY_BYTES
}

/// Refuses a layout whose output maps exceed `budget`.
fn check_memory(
    shape: &[u64],
    points: bool,
    baselines: bool,
    budget: u64,
) -> Result<(), SceneError> {
    let instances = shape
        .iter()
        .try_fold(1u128, |acc, &n| acc.checked_mul(n as u128))
        .unwrap_or(u128::MAX);
    let per = bytes_per_instance(baselines);
    if instances.saturating_mul(per as u128) > budget as u128 {
        return Err(SceneError::Memory {
            shape: shape.to_vec(),
            points,
            instances,
            bytes_per_instance: per,
            budget,
        });
    }
    Ok(())
}

/// Describes the values of a grid axis: all of them when few, else the
/// count, ends and spacing.
fn describe_values(values: &[f64], units: &str) -> String {
    let unit = if units == "1" {
        String::new()
    } else {
        format!(" {units}")
    };
    let n = values.len();
    if n <= 6 {
        let list: Vec<String> = values.iter().map(|&v| fmt_short(v)).collect();
        return format!("[{}]{unit}", list.join(", "));
    }
    let (first, last) = (values[0], values[n - 1]);
    let step = (last - first) / (n - 1) as f64;
    let linear = values
        .iter()
        .enumerate()
        .all(|(i, &v)| (v - (first + step * i as f64)).abs() <= 1e-9 * first.abs().max(last.abs()));
    let spacing = if linear {
        format!("linear, step {}", fmt_short(step))
    } else if first > 0.0 && last > 0.0 {
        let ratio = (last / first).powf(1.0 / (n - 1) as f64);
        let log = values
            .iter()
            .enumerate()
            .all(|(i, &v)| (v / (first * ratio.powi(i as i32)) - 1.0).abs() <= 1e-9);
        if log {
            format!("log, ratio {ratio:.6}")
        } else {
            "list".to_owned()
        }
    } else {
        "list".to_owned()
    };
    format!(
        "{n} values from {}{unit} to {}{unit} ({spacing})",
        fmt_short(first),
        fmt_short(last)
    )
}
