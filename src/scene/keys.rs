//! The keys of a scene: the numeric keys ([`Field`]) with their names and
//! units, the tables they belong to, and the raw slots that hold their
//! values while a scene is assembled.
//!
//! Raw slots number every numeric key of the scene once: the mechanism
//! first, then each axis, then the simulation.

pub(super) use crate::laws::Law;
use crate::model::{AXES, AXIS_NAMES};

/// A numeric key of a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Field {
    SliderMass,
    StaticFriction,
    CoulombFriction,
    VelocityBand,
    LoadX,
    LoadY,
    BristleStiffness,
    BristleDamping,
    ViscousFriction,
    StribeckVelocity,
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
    FrequencyRatio,
    Rise,
    Hold,
    Fall,
    SlewRate,
    Cycles,
    Settle,
    Tolerance,
    MaxStepsPerPeriod,
    StepTolerance,
    MaxCycles,
}

impl Field {
    /// The key's name within its table.
    pub(super) fn name(self) -> &'static str {
        match self {
            Field::SliderMass => "slider_mass",
            Field::StaticFriction => "static_friction",
            Field::CoulombFriction => "coulomb_friction",
            Field::VelocityBand => "velocity_band",
            Field::LoadX => "load_x",
            Field::LoadY => "load_y",
            Field::BristleStiffness => "bristle_stiffness",
            Field::BristleDamping => "bristle_damping",
            Field::ViscousFriction => "viscous_friction",
            Field::StribeckVelocity => "stribeck_velocity",
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
            Field::FrequencyRatio => "frequency_ratio",
            Field::Rise => "rise",
            Field::Hold => "hold",
            Field::Fall => "fall",
            Field::SlewRate => "slew_rate",
            Field::Cycles => "cycles",
            Field::Settle => "settle",
            Field::Tolerance => "tolerance",
            Field::MaxStepsPerPeriod => "max_steps_per_period",
            Field::StepTolerance => "step_tolerance",
            Field::MaxCycles => "max_cycles",
        }
    }

    /// The units of the key's values.
    pub(super) fn units(self) -> &'static str {
        match self {
            Field::SliderMass | Field::StageMass => "kg",
            Field::StaticFriction | Field::CoulombFriction | Field::LoadX | Field::LoadY => "N",
            Field::VelocityBand | Field::StribeckVelocity => "m/s",
            Field::Stiffness | Field::BristleStiffness => "N/m",
            Field::Damping | Field::BristleDamping | Field::ViscousFriction => "N s/m",
            Field::ResonanceHz | Field::Frequency => "Hz",
            Field::QualityFactor
            | Field::Duty
            | Field::Rise
            | Field::Hold
            | Field::Fall
            | Field::MaxStepsPerPeriod
            | Field::FrequencyRatio => "1",
            Field::Gain => "N/V",
            Field::Voltage => "V",
            Field::SlewRate => "V/s",
            Field::Phase | Field::Cycles | Field::Settle | Field::MaxCycles => "cycles",
            Field::Tolerance => "rad",
            Field::StepTolerance => "m",
        }
    }

    /// The one friction law the key applies to, if it applies to one only
    /// (the law declares it: [`Law::keys`]). A scene with another law
    /// refuses the key.
    pub(super) fn friction(self) -> Option<Law> {
        Law::ALL
            .into_iter()
            .find(|law| law.keys().contains(&self.name()))
    }

    /// The one waveform the key shapes, if it shapes one (`duty` the
    /// sawtooth, `rise`, `hold` and `fall` the trapezoid). An axis with
    /// another waveform refuses the key.
    pub(super) fn waveform(self) -> Option<&'static str> {
        match self {
            Field::Duty => Some("sawtooth"),
            Field::Rise | Field::Hold | Field::Fall => Some("trapezoid"),
            _ => None,
        }
    }

    /// Whether the key applies to the whole scene (one value, no points).
    pub(super) fn scene_wide(self) -> bool {
        matches!(self, Field::Tolerance | Field::MaxStepsPerPeriod)
    }

    /// The one measurement mode the key applies to, if it applies to one
    /// only: `cycles` to a window, `step_tolerance` and `max_cycles` to a
    /// steady measurement. A scene in the other mode refuses the key.
    pub(super) fn mode(self) -> Option<Mode> {
        match self {
            Field::Cycles => Some(Mode::Window),
            Field::StepTolerance | Field::MaxCycles => Some(Mode::Steady),
            _ => None,
        }
    }
}

/// `simulation.measure`: how a scene measures its steps (docs/model.md section
/// 4), one mode for the whole scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum Mode {
    /// The steady step (the default): `settle`, `step_tolerance`,
    /// `max_cycles`.
    #[default]
    Steady,
    /// The paper's fixed window: `cycles`, `settle`.
    Window,
}

impl Mode {
    /// Every mode, in the order messages list them.
    pub(super) const ALL: [Mode; 2] = [Mode::Steady, Mode::Window];

    /// The mode's value of `simulation.measure`.
    pub(super) fn name(self) -> &'static str {
        match self {
            Mode::Steady => "steady",
            Mode::Window => "window",
        }
    }

    /// The mode a value of `simulation.measure` names.
    pub(super) fn from_name(name: &str) -> Option<Mode> {
        Mode::ALL.into_iter().find(|mode| mode.name() == name)
    }

    /// What a scene in this mode takes instead of a key of the other
    /// mode, for the refusal of that key.
    pub(super) fn instead(self) -> &'static str {
        match self {
            Mode::Steady => {
                "a steady measurement takes simulation.max_cycles (the most periods it may run)"
            }
            Mode::Window => {
                "a window measurement runs simulation.cycles periods and takes no \
                 step_tolerance or max_cycles"
            }
        }
    }
}

/// Why `pidm run` refuses a scene with `[fit]` (`crate::fit`).
pub(super) const FIT_SCENE: &str = "[fit] makes this a fit scene, which calibrates the model to \
     measured steps: run it with `pidm fit SCENE --out FIT.json` (`pidm run` maps a scene \
     without [fit])";

/// Why `pidm run` refuses a scene with `[optimize]` (`crate::design`).
pub(super) const OPTIMIZE_SCENE: &str = "[optimize] makes this an optimize scene, which searches \
     its free keys: run it with `pidm optimize SCENE --out OPT.json` (docs/design.md; `pidm run` \
     maps a scene without [optimize])";

/// Why `pidm run` refuses a scene with `[sensitivity]` (`crate::design`).
pub(super) const SENSITIVITY_SCENE: &str = "[sensitivity] makes this a sensitivity scene, which \
     samples its inputs: run it with `pidm sensitivity SCENE --out SENS.json` (docs/design.md; \
     `pidm run` maps a scene without [sensitivity])";

/// The waveforms an axis may name (`model::Shape::name`), the default
/// first, each with the keys that shape it.
pub(super) const WAVEFORMS: [(&str, &str); 3] = [
    ("sawtooth", "duty"),
    ("trapezoid", "rise, hold and fall"),
    ("table", "table"),
];

/// An axis' string key: its waveform.
pub(super) const WAVEFORM_KEY: &str = "waveform";
/// An axis' table of `[u, level]` entries (`waveform = "table"`).
pub(super) const TABLE_KEY: &str = "table";

/// `[mechanism]`'s string key: the friction law, scene-wide.
pub(super) const FRICTION_KEY: &str = "friction";

/// The keys of `[mechanism]`, in slot order.
pub(super) const MECHANISM_FIELDS: [Field; 10] = [
    Field::SliderMass,
    Field::StaticFriction,
    Field::CoulombFriction,
    Field::VelocityBand,
    Field::LoadX,
    Field::LoadY,
    Field::BristleStiffness,
    Field::BristleDamping,
    Field::ViscousFriction,
    Field::StribeckVelocity,
];

/// The raw slot (and index in [`MECHANISM_FIELDS`]) of
/// `mechanism.coulomb_friction`.
pub(super) const COULOMB_SLOT: usize = 2;
/// The raw slots (and indices in [`MECHANISM_FIELDS`]) of `mechanism.load_x`
/// and `mechanism.load_y`.
pub(super) const LOAD_SLOTS: [usize; 2] = [4, 5];

/// The keys of `[axis.x]` and `[axis.y]`, in slot order. `frequency_ratio`
/// has a slot on both axes but only `axis.y` accepts it (the parser refuses
/// it on `axis.x`).
pub(super) const AXIS_FIELDS: [Field; 15] = [
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
    Field::FrequencyRatio,
    Field::Rise,
    Field::Hold,
    Field::Fall,
    Field::SlewRate,
];

/// The numeric keys of `[simulation]`, in slot order. `measure`, its one
/// string key, is read apart ([`MEASURE_KEY`]).
pub(super) const SIMULATION_FIELDS: [Field; 6] = [
    Field::Cycles,
    Field::Settle,
    Field::Tolerance,
    Field::MaxStepsPerPeriod,
    Field::StepTolerance,
    Field::MaxCycles,
];

/// `[simulation]`'s string key: how the step is measured, scene-wide.
pub(super) const MEASURE_KEY: &str = "measure";

/// `[simulation]`'s key of replicas, "auto" or a whole number, scene-wide
/// (`crate::replicas`).
pub(super) const REPLICAS_KEY: &str = "replicas";

/// The most replicas `simulation.replicas` may ask for one instance: far
/// beyond what pays (`crate::replicas::MAX_AUTO`), for studies.
pub(super) const MAX_REPLICAS: u32 = 64;

/// Every key of `[simulation]`, for hints on unknown keys.
pub(super) const SIMULATION_KEYS: [&str; 8] = [
    "cycles",
    "settle",
    "tolerance",
    "max_steps_per_period",
    "step_tolerance",
    "max_cycles",
    MEASURE_KEY,
    REPLICAS_KEY,
];

// Indices of the axis keys within `AXIS_FIELDS`.

/// Index of `stage_mass`.
pub(super) const STAGE_MASS: usize = 0;
/// Index of `stiffness`.
pub(super) const STIFFNESS: usize = 1;
/// Index of `damping`.
pub(super) const DAMPING: usize = 2;
/// Index of `resonance_hz`.
pub(super) const RESONANCE: usize = 3;
/// Index of `quality_factor`.
pub(super) const QUALITY: usize = 4;
/// Index of `gain`.
pub(super) const GAIN: usize = 5;
/// Index of `voltage`.
pub(super) const VOLTAGE: usize = 6;
/// Index of `frequency`.
pub(super) const FREQUENCY: usize = 7;
/// Index of `duty`.
pub(super) const DUTY: usize = 8;
/// Index of `phase`.
pub(super) const PHASE: usize = 9;
/// Index of `frequency_ratio`: f_y = frequency_ratio x f_x, `axis.y` only.
pub(super) const FREQUENCY_RATIO: usize = 10;
/// Index of `rise`, `hold` and `fall` (the trapezoid's).
pub(super) const RISE: usize = 11;
pub(super) const HOLD: usize = 12;
pub(super) const FALL: usize = 13;
/// Index of `slew_rate`.
pub(super) const SLEW_RATE: usize = 14;
/// The keys that shape a waveform (indices into [`AXIS_FIELDS`]).
pub(super) const SHAPE_KEYS: [usize; 4] = [DUTY, RISE, HOLD, FALL];

/// The drive keys one axis may tie to the same key of the other axis with
/// `{ same_as = "axis.<other>.<key>" }` (indices into [`AXIS_FIELDS`]).
pub(super) const TIEABLE: [usize; 9] = [
    GAIN, VOLTAGE, FREQUENCY, DUTY, PHASE, RISE, HOLD, FALL, SLEW_RATE,
];

/// The first raw slot of the axes (the mechanism's come before).
pub(super) const AXIS_SLOTS: usize = MECHANISM_FIELDS.len();
/// The first raw slot of `[simulation]`.
pub(super) const SIMULATION_SLOTS: usize = AXIS_SLOTS + AXES * AXIS_FIELDS.len();
/// Number of raw slots.
pub(super) const SLOTS: usize = SIMULATION_SLOTS + SIMULATION_FIELDS.len();
/// The raw slot of `simulation.cycles`.
pub(super) const CYCLES_SLOT: usize = SIMULATION_SLOTS;
/// The raw slot of `simulation.settle`.
pub(super) const SETTLE_SLOT: usize = SIMULATION_SLOTS + 1;
/// The raw slot of `simulation.tolerance`.
pub(super) const TOLERANCE_SLOT: usize = SIMULATION_SLOTS + 2;
/// The raw slot of `simulation.max_steps_per_period`.
pub(super) const MAX_STEPS_SLOT: usize = SIMULATION_SLOTS + 3;
/// The raw slot of `simulation.step_tolerance`.
pub(super) const STEP_TOLERANCE_SLOT: usize = SIMULATION_SLOTS + 4;
/// The raw slot of `simulation.max_cycles`.
pub(super) const MAX_CYCLES_SLOT: usize = SIMULATION_SLOTS + 5;

/// The raw slot of axis key `index` (into [`AXIS_FIELDS`]) of axis `axis`.
pub(super) fn axis_slot(axis: usize, index: usize) -> usize {
    AXIS_SLOTS + axis * AXIS_FIELDS.len() + index
}

/// The key held by a raw slot.
pub(super) fn slot_field(slot: usize) -> Field {
    if slot < AXIS_SLOTS {
        MECHANISM_FIELDS[slot]
    } else if slot < SIMULATION_SLOTS {
        AXIS_FIELDS[(slot - AXIS_SLOTS) % AXIS_FIELDS.len()]
    } else {
        SIMULATION_FIELDS[slot - SIMULATION_SLOTS]
    }
}

/// The full dotted path of a raw slot, e.g. "axis.y.voltage".
pub(super) fn slot_path(slot: usize) -> String {
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

/// The root key that says phases of a whole cycle or more are meant.
pub(super) const PHASE_UNITS_KEY: &str = "phase_units";

/// Keys of the document root.
pub(super) const ROOT_KEYS: [&str; 11] = [
    "name",
    "description",
    PHASE_UNITS_KEY,
    "mechanism",
    "axis",
    "simulation",
    "output",
    "points",
    "refine",
    "stall",
    "random",
];

/// Keys of `[random]`.
pub(super) const RANDOM_KEYS: [&str; 2] = ["seed", "count"];

/// Keys of `[refine]`.
pub(super) const REFINE_KEYS: [&str; 2] = ["levels", "tolerance"];

/// Keys of `[stall]`.
pub(super) const STALL_KEYS: [&str; 2] = ["axis", "tolerance"];

/// Keys of one `[[points]]` entry.
pub(super) const POINT_KEYS: [&str; 4] = ["label", "mechanism", "axis", "simulation"];

/// The one key of a tie's table, `{ same_as = "axis.x.voltage" }`.
pub(super) const SAME_AS_KEY: &str = "same_as";

/// Keys of a range table.
pub(super) const RANGE_KEYS: [&str; 4] = ["from", "to", "steps", "log"];

/// Keys of `[output]`.
pub(super) const OUTPUT_KEYS: [&str; 4] = [
    "baselines",
    "backward",
    "trajectories",
    "trajectory_samples_per_cycle",
];

/// What a numeric key should look like, for type errors.
pub(super) const NUMERIC_EXPECTED: &str =
    "expected a number, a list of numbers or a range { from, to, steps }";

/// What a dotted scene key is, for a fit's free keys and data columns
/// (`crate::fit`): its units when it is a real-valued key an instance may
/// set (a point could), else why not. The scene's own rules still judge
/// its values.
pub fn instance_key(path: &str) -> Result<&'static str, &'static str> {
    let field = match path.split('.').collect::<Vec<_>>()[..] {
        ["mechanism", name] => MECHANISM_FIELDS.iter().find(|f| f.name() == name),
        ["axis", "x" | "y", name] => AXIS_FIELDS.iter().find(|f| f.name() == name),
        ["simulation", name] => SIMULATION_FIELDS.iter().find(|f| f.name() == name),
        _ => None,
    };
    let Some(&field) = field else {
        return Err("no numeric scene key of that name");
    };
    if path == "axis.x.frequency_ratio" {
        return Err("only axis.y takes frequency_ratio");
    }
    if field.scene_wide() {
        return Err("it applies to the whole scene, not to one instance");
    }
    if field.rule().integer() {
        return Err("it holds an integer (a count of periods)");
    }
    Ok(field.units())
}

/// The values a real-valued instance key accepts (its rule and its
/// plausible bounds, `crate::scene::rules`), for the design commands'
/// bounds and distributions (`crate::design`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyRange {
    /// The key's units ("N", "1", ...).
    pub units: &'static str,
    /// The smallest and largest plausible values.
    pub low: f64,
    pub high: f64,
    /// Whether `low` itself is refused (a key that must be above 0 whose
    /// plausible range starts at 0).
    pub low_open: bool,
}

impl KeyRange {
    /// Whether the key accepts `value`.
    pub fn accepts(&self, value: f64) -> bool {
        value.is_finite()
            && value <= self.high
            && (value > self.low || (value == self.low && !self.low_open))
    }

    /// What the key accepts, for error messages.
    pub fn expected(&self) -> String {
        let unit = if self.units == "1" {
            String::new()
        } else {
            format!(" {}", self.units)
        };
        let open = if self.low_open { " (excluded)" } else { "" };
        format!(
            "a value from {}{open} to {}{unit}",
            super::format::fmt_num(self.low),
            super::format::fmt_num(self.high)
        )
    }
}

/// The range of an instance key ([`instance_key`]'s keys), or why it has
/// none.
pub fn instance_key_range(path: &str) -> Result<KeyRange, &'static str> {
    let units = instance_key(path)?;
    let name = path.rsplit('.').next().unwrap_or(path);
    let field = MECHANISM_FIELDS
        .iter()
        .chain(AXIS_FIELDS.iter())
        .chain(SIMULATION_FIELDS.iter())
        .find(|f| f.name() == name)
        .copied()
        .ok_or("no numeric scene key of that name")?;
    let bounds = field
        .bounds()
        .ok_or("it holds an integer (a count of periods)")?;
    let rule = field.rule();
    Ok(KeyRange {
        units,
        low: bounds.min,
        high: bounds.max,
        low_open: !rule.accepts(bounds.min),
    })
}

/// What `mechanism.friction` takes: every law's name, the default first,
/// each with the section of docs/model.md that defines it.
pub(super) fn expected_law() -> String {
    let names: Vec<String> = Law::ALL
        .iter()
        .map(|law| {
            let default = if *law == Law::default() {
                "the default, "
            } else {
                ""
            };
            format!(
                "{:?} ({default}docs/model.md section {})",
                law.name(),
                law.section()
            )
        })
        .collect();
    format!("expected {}", names.join(" or "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_read_back_by_name_and_steady_is_the_default() {
        for mode in Mode::ALL {
            assert_eq!(Mode::from_name(mode.name()), Some(mode));
        }
        assert_eq!(Mode::default(), Mode::Steady);
        for name in ["forever", "Window", " steady", ""] {
            assert_eq!(Mode::from_name(name), None, "{name:?}");
        }
    }

    #[test]
    fn each_mode_key_belongs_to_one_mode_and_has_a_slot() {
        assert_eq!(Field::Cycles.mode(), Some(Mode::Window));
        assert_eq!(Field::StepTolerance.mode(), Some(Mode::Steady));
        assert_eq!(Field::MaxCycles.mode(), Some(Mode::Steady));
        assert_eq!(Field::Settle.mode(), None);
        assert_eq!(slot_path(STEP_TOLERANCE_SLOT), "simulation.step_tolerance");
        assert_eq!(slot_path(MAX_CYCLES_SLOT), "simulation.max_cycles");
        assert_eq!(slot_path(CYCLES_SLOT), "simulation.cycles");
        assert_eq!(slot_path(SETTLE_SLOT), "simulation.settle");
        assert_eq!(Field::StepTolerance.units(), "m");
        assert_eq!(Field::MaxCycles.units(), "cycles");
        // Every numeric key of [simulation], `measure` and `replicas` are
        // hinted.
        for field in SIMULATION_FIELDS {
            assert!(SIMULATION_KEYS.contains(&field.name()), "{field:?}");
        }
        assert!(SIMULATION_KEYS.contains(&MEASURE_KEY));
        assert!(SIMULATION_KEYS.contains(&REPLICAS_KEY));
        assert_eq!(SIMULATION_KEYS.len(), SIMULATION_FIELDS.len() + 2);
    }
}
