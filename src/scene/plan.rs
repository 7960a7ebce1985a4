//! From raw key values to instances: the [`Plan`] says where every parameter
//! of an instance comes from (a raw slot or a default, directly or through
//! the stage relations of paper eqs. 6-7), and [`check_instance`] checks what
//! the per-key checks cannot.

use super::format::{fmt_num, fmt_short};
use super::keys::{
    AXIS_FIELDS, COULOMB_SLOT, CYCLES_SLOT, DAMPING, DUTY, FALL, FREQUENCY, FREQUENCY_RATIO, Field,
    GAIN, HOLD, LOAD_SLOTS, Law, MAX_CYCLES_SLOT, MECHANISM_FIELDS, Mode, PHASE, QUALITY,
    RESONANCE, RISE, SETTLE_SLOT, SLEW_RATE, SLOTS, STAGE_MASS, STEP_TOLERANCE_SLOT, STIFFNESS,
    TIEABLE, VOLTAGE, axis_slot, slot_path,
};
use super::layer::kept_from_lower;
use crate::model::{
    AXES, AXIS_NAMES, Axis, Instance, Lugre, Measure, Mechanism, NO_SLEW_LIMIT, Shape,
};

/// Where a parameter's value comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Src {
    /// A raw key slot (given in the file, possibly by the other axis).
    Slot(usize),
    /// A default.
    Const(f64),
    /// A raw slot (`axis.y.frequency_ratio`) times another source that is a
    /// slot (`base`, when given) or a default (`default`).
    Ratio {
        ratio: usize,
        base: Option<usize>,
        default: f64,
    },
}

impl Src {
    /// The value, in its key's units, for a set of raw key values.
    pub(super) fn get(self, raw: &[f64; SLOTS]) -> f64 {
        match self {
            Src::Slot(slot) => raw[slot],
            Src::Const(value) => value,
            Src::Ratio {
                ratio,
                base,
                default,
            } => raw[ratio] * base.map_or(default, |slot| raw[slot]),
        }
    }

    /// `ratio` (a raw slot) times this source, which is a slot or a
    /// default.
    fn times(self, ratio: usize) -> Src {
        let (base, default) = match self {
            Src::Slot(slot) => (Some(slot), 0.0),
            Src::Const(value) => (None, value),
            // No source is scaled twice: only axis.y's frequency is a
            // ratio, of axis.x's, which never is.
            Src::Ratio { .. } => unreachable!("a ratio of a ratio"),
        };
        Src::Ratio {
            ratio,
            base,
            default,
        }
    }

    /// Names the source in messages about derived values.
    pub(super) fn describe(self, field: Field) -> String {
        match self {
            Src::Slot(slot) => slot_path(slot),
            Src::Const(value) => format!("the default {} {}", field.name(), fmt_num(value)),
            Src::Ratio {
                ratio,
                base,
                default,
            } => {
                let base = match base {
                    Some(slot) => Src::Slot(slot),
                    None => Src::Const(default),
                };
                format!("{} x {}", slot_path(ratio), base.describe(field))
            }
        }
    }
}

/// How an axis' stage mass and stiffness are obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum StagePlan {
    /// Both given (or defaulted).
    MassStiffness { mass: Src, stiffness: Src },
    /// The mass follows from the resonance and the stiffness (eq. 6).
    ResonanceStiffness { resonance: Src, stiffness: Src },
    /// The stiffness follows from the resonance and the mass (eq. 6).
    ResonanceMass { resonance: Src, mass: Src },
}

/// How an axis' damping is obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum DampingPlan {
    /// Given (or defaulted).
    Damping(Src),
    /// From the quality factor (eq. 7).
    Quality(Src),
}

/// Where every parameter of one axis comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct AxisPlan {
    /// Stage mass and stiffness.
    pub(super) stage: StagePlan,
    /// Stage damping.
    pub(super) damping: DampingPlan,
    /// Piezo gain [N/V].
    pub(super) gain: Src,
    /// Drive amplitude [V].
    pub(super) voltage: Src,
    /// Drive frequency [Hz].
    pub(super) frequency: Src,
    /// Duty of the sawtooth [1].
    pub(super) duty: Src,
    /// Phase offset [cycles].
    pub(super) phase: Src,
    /// The waveform, and the trapezoid's fractions [1] (0 unless given).
    pub(super) shape: Shape,
    pub(super) rise: Src,
    pub(super) hold: Src,
    pub(super) fall: Src,
    /// The amplifier's slew limit [V/s] (none unless given).
    pub(super) slew_rate: Src,
}

/// Where every parameter of an instance comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Plan {
    /// The `[mechanism]` keys, in slot order.
    pub(super) mechanism: [Src; MECHANISM_FIELDS.len()],
    /// The friction law (`mechanism.friction`, scene-wide).
    pub(super) friction: Law,
    /// Each axis.
    pub(super) axes: [AxisPlan; AXES],
    /// How the steps are measured (`simulation.measure`, scene-wide).
    pub(super) mode: Mode,
    /// Periods run (a window's `cycles`) or the most that may be run (a
    /// steady measurement's `max_cycles`) [cycles].
    pub(super) cycles: Src,
    /// Periods discarded before measuring (at least, when steady) [cycles].
    pub(super) settle: Src,
    /// Standard error allowed on each axis' steady step [m per own drive
    /// cycle]; unused by a window.
    pub(super) step_tolerance: Src,
}

impl Plan {
    /// The plan for a set of given keys (after points are overlaid) in a
    /// measurement mode. The keys of the other mode were refused by the
    /// parser, so none is given here.
    ///
    /// `ties` holds, for each tied raw slot, the slot it is tied to (checked
    /// by the parser: only drive keys, to the same key of the other axis,
    /// whose source is final); the tied key takes that key's source.
    ///
    /// `shapes` holds each axis' waveform where the keys give one; `axis.y`
    /// without one takes `axis.x`'s, and its shape keys with it.
    pub(super) fn build(
        given: &[bool; SLOTS],
        ties: &[Option<usize>; SLOTS],
        (mode, friction): (Mode, Law),
        shapes: [Option<Shape>; AXES],
    ) -> Plan {
        let own = |axis: usize| -> [bool; AXIS_FIELDS.len()] {
            std::array::from_fn(|j| given[axis_slot(axis, j)])
        };
        let x = own(0);
        let y = own(1);
        let kept = kept_from_lower(&y, &x, false, shapes[1].is_some());
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
            Mechanism::TABLE1.load[0],
            Mechanism::TABLE1.load[1],
            Lugre::DEFAULT.bristle_stiffness,
            // Derived from sigma0 and m_s ([`Lugre::damping`]) unless given.
            f64::NAN,
            Lugre::DEFAULT.viscous_friction,
            Lugre::DEFAULT.stribeck_velocity,
        ];
        let or_default = |slot: usize, default: f64| {
            if given[slot] {
                Src::Slot(slot)
            } else {
                Src::Const(default)
            }
        };
        let x_shape = shapes[0].unwrap_or_default();
        let mut axes = [
            AxisPlan::build(&x_sources, Axis::TABLE1.voltage, x_shape),
            AxisPlan::build(&y_sources, 0.0, shapes[1].unwrap_or(x_shape)),
        ];
        if let Some(ratio) = y_sources[FREQUENCY_RATIO] {
            axes[1].frequency = axes[0].frequency.times(ratio);
        }
        for axis in 0..AXES {
            for j in TIEABLE {
                if let Some(target) = ties[axis_slot(axis, j)] {
                    debug_assert_eq!(target, axis_slot(1 - axis, j), "ties are checked");
                    let source = axes[1 - axis].drive(j);
                    *axes[axis].drive_mut(j) = source;
                }
            }
        }
        Plan {
            mechanism: std::array::from_fn(|i| or_default(i, mechanism_defaults[i])),
            friction,
            axes,
            mode,
            cycles: match mode {
                Mode::Window => or_default(CYCLES_SLOT, Instance::TABLE1.cycles as f64),
                Mode::Steady => or_default(MAX_CYCLES_SLOT, Measure::DEFAULT_MAX_CYCLES as f64),
            },
            settle: match mode {
                Mode::Window => or_default(SETTLE_SLOT, Instance::TABLE1.settle as f64),
                Mode::Steady => or_default(SETTLE_SLOT, Measure::DEFAULT_SETTLE as f64),
            },
            step_tolerance: or_default(STEP_TOLERANCE_SLOT, Measure::DEFAULT_STEP_TOLERANCE),
        }
    }

    /// The instance for a set of raw key values.
    pub(super) fn resolve(&self, raw: &[f64; SLOTS]) -> Instance {
        let [
            slider_mass,
            static_friction,
            coulomb_friction,
            velocity_band,
            load_x,
            load_y,
            bristle_stiffness,
            bristle_damping,
            viscous_friction,
            stribeck_velocity,
        ] = self.mechanism.map(|src| src.get(raw));
        let friction = self.friction.friction([
            bristle_stiffness,
            bristle_damping,
            viscous_friction,
            stribeck_velocity,
        ]);
        Instance {
            mechanism: Mechanism {
                slider_mass,
                static_friction,
                coulomb_friction,
                velocity_band,
                load: [load_x, load_y],
                friction,
            },
            axes: [self.axes[0].resolve(raw), self.axes[1].resolve(raw)],
            cycles: self.cycles.get(raw) as u32,
            settle: self.settle.get(raw) as u32,
            measure: match self.mode {
                Mode::Window => Measure::Window,
                Mode::Steady => Measure::Steady {
                    step_tolerance: self.step_tolerance.get(raw),
                },
            },
        }
    }
}

impl AxisPlan {
    /// The plan of one axis from the slots its keys come from.
    pub(super) fn build(
        sources: &[Option<usize>; AXIS_FIELDS.len()],
        voltage: f64,
        shape: Shape,
    ) -> AxisPlan {
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
            shape,
            rise: src(RISE, 0.0),
            hold: src(HOLD, 0.0),
            fall: src(FALL, 0.0),
            slew_rate: src(SLEW_RATE, NO_SLEW_LIMIT),
        }
    }

    /// The source of drive key `j` (one of [`TIEABLE`]).
    fn drive(&self, j: usize) -> Src {
        let mut copy = *self;
        *copy.drive_mut(j)
    }

    /// The source of drive key `j` (one of [`TIEABLE`]), to set it.
    fn drive_mut(&mut self, j: usize) -> &mut Src {
        match j {
            GAIN => &mut self.gain,
            VOLTAGE => &mut self.voltage,
            FREQUENCY => &mut self.frequency,
            DUTY => &mut self.duty,
            PHASE => &mut self.phase,
            RISE => &mut self.rise,
            HOLD => &mut self.hold,
            FALL => &mut self.fall,
            SLEW_RATE => &mut self.slew_rate,
            _ => unreachable!("axis key {j} is not a drive key"),
        }
    }

    /// The axis for a set of raw key values.
    pub(super) fn resolve(&self, raw: &[f64; SLOTS]) -> Axis {
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
            shape: self.shape,
            rise: self.rise.get(raw),
            hold: self.hold.get(raw),
            fall: self.fall.get(raw),
            slew_rate: self.slew_rate.get(raw),
        }
    }
}

/// The raw slots an error may be located by, most relevant first.
pub(super) type Culprits = [Option<usize>; 2];

/// The slot of a source, when it comes from the file.
pub(super) fn src_slot(src: Src) -> Option<usize> {
    match src {
        Src::Slot(slot) | Src::Ratio { ratio: slot, .. } => Some(slot),
        Src::Const(_) => None,
    }
}

/// The trapezoid's fractions sum to more than 0 and at most 1; every
/// waveform is one `floor::drive::Waveform::check` accepts.
fn check_waveform(name: &str, axis: &Axis, plan: &AxisPlan) -> Result<(), (String, Culprits)> {
    if axis.shape == Shape::Trapezoid {
        let sum = axis.rise + axis.hold + axis.fall;
        if !(sum > 0.0 && sum <= 1.0) {
            return Err((
                format!(
                    "axis.{name}: rise + hold + fall = {} + {} + {} = {}: expected fractions of \
                     a cycle that sum to more than 0 and at most 1 (the rest of the cycle dwells \
                     at 0)",
                    fmt_num(axis.rise),
                    fmt_num(axis.hold),
                    fmt_num(axis.fall),
                    fmt_num(sum)
                ),
                [src_slot(plan.rise), src_slot(plan.fall)],
            ));
        }
    }
    crate::laws::floor::drive::axis_waveform(axis)
        .check()
        .map_err(|e| (format!("axis.{name}.{e}"), [None, None]))
}

/// Checks what per-key checks cannot: derived stage quantities, the load
/// against the kinetic friction, and settle < cycles (a window) or settle <
/// max_cycles (steady). Returns the message and the slots to locate it by.
pub(super) fn check_instance(instance: &Instance, plan: &Plan) -> Result<(), (String, Culprits)> {
    for (a, (axis, axis_plan)) in instance.axes.iter().zip(&plan.axes).enumerate() {
        let name = AXIS_NAMES[a];
        check_waveform(name, axis, axis_plan)?;
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
            && let Some(expected) = derived_expected(field, value)
        {
            return Err((
                format!(
                    "axis.{name}.{} = {} (derived from {from}): {expected}",
                    field.name(),
                    fmt_num(value)
                ),
                [src_slot(resonance), None],
            ));
        }
        if let Src::Ratio { ratio, base, .. } = axis_plan.frequency
            && let Some(expected) = derived_expected(Field::Frequency, axis.frequency)
        {
            return Err((
                format!(
                    "axis.{name}.frequency = {} (derived from {}): {expected}",
                    fmt_num(axis.frequency),
                    axis_plan.frequency.describe(Field::Frequency)
                ),
                [Some(ratio), base],
            ));
        }
        if let DampingPlan::Quality(quality) = axis_plan.damping
            && let Some(expected) = derived_expected(Field::Damping, axis.damping)
        {
            return Err((
                format!(
                    "axis.{name}.damping = {} (derived from {}, the stiffness and the stage \
                     mass): {expected}",
                    fmt_num(axis.damping),
                    quality.describe(Field::QualityFactor)
                ),
                [src_slot(quality), None],
            ));
        }
    }
    if let Some(refusal) = load_refusal(instance, plan) {
        return Err(refusal);
    }
    if instance.settle >= instance.cycles {
        let message = match plan.mode {
            Mode::Window => format!(
                "simulation.settle = {} with simulation.cycles = {}: expected settle < cycles \
                 (the settle periods are discarded before measuring)",
                instance.settle, instance.cycles
            ),
            Mode::Steady => format!(
                "simulation.settle = {} with simulation.max_cycles = {}: expected settle < \
                 max_cycles (at least the settle periods are discarded before measuring, and \
                 max_cycles bounds the whole run)",
                instance.settle, instance.cycles
            ),
        };
        return Err((message, [src_slot(plan.settle), src_slot(plan.cycles)]));
    }
    Ok(())
}

/// Why an instance's load is refused (docs/model.md section 7): a non-zero load
/// whose magnitude |L| is at least the kinetic friction f_c, along which a
/// slipping slider is not stopped by friction and may run away. The
/// message names each non-zero load key and its value, |L| where both are
/// set, and f_c with its source; the culprits are the load keys, the
/// larger first.
fn load_refusal(instance: &Instance, plan: &Plan) -> Option<(String, Culprits)> {
    let m = &instance.mechanism;
    if !m.load_refused() {
        return None;
    }
    let keys: Vec<String> = (0..AXES)
        .filter(|&a| m.load[a] != 0.0)
        .map(|a| format!("{} = {}", slot_path(LOAD_SLOTS[a]), fmt_num(m.load[a])))
        .collect();
    let magnitude = if keys.len() > 1 {
        format!(" (|L| = {} N)", fmt_short(m.load_magnitude()))
    } else {
        String::new()
    };
    let friction = match plan.mechanism[COULOMB_SLOT] {
        Src::Slot(slot) => format!("{} = {} N", slot_path(slot), fmt_num(m.coulomb_friction)),
        _ => format!(
            "the kinetic friction f_c = {} N (the default coulomb_friction)",
            fmt_num(m.coulomb_friction)
        ),
    };
    let larger = usize::from(m.load[1].abs() > m.load[0].abs());
    let culprits = [
        src_slot(plan.mechanism[LOAD_SLOTS[larger]]),
        src_slot(plan.mechanism[LOAD_SLOTS[1 - larger]]),
    ];
    Some((
        format!(
            "{}{magnitude}: expected a load of magnitude |L| < {friction}: a slider slipping \
             along a load of the kinetic friction or more is not stopped by it and may run away \
             (docs/model.md section 7)",
            keys.join(" and ")
        ),
        culprits,
    ))
}

/// What a derived stage quantity (stage mass, stiffness or damping) should
/// have been when `value` is not acceptable for `field`: finite and of the
/// key's sign, then within its plausible bounds; `None` when it is fine.
fn derived_expected(field: Field, value: f64) -> Option<String> {
    let rule = field.rule();
    if !value.is_finite() || !rule.accepts(value) {
        return Some(rule.expected().replacen("a number", "a finite number", 1));
    }
    match field.bounds() {
        Some(bounds) if !bounds.contains(value) => Some(bounds.expected(field.units())),
        _ => None,
    }
}
