//! What values each numeric key accepts: its [`Rule`] (sign, interval,
//! integrality: what the model's equations need) and its [`Bounds`] (what
//! is physically plausible for a millimetre-scale piezoelectric stick-slip
//! drive, generously).
//!
//! Both are intervals, so a monotone range is valid exactly when both its
//! ends are, and the derived stage quantities (monotone in each key) are
//! valid over a whole grid exactly when they are at its corners.
//!
//! The bounds keep every run finite. Within them a force is at most 1e9 N
//! (friction) and a mass at least 1e-9 kg, so an acceleration is at most
//! about 1e18 m/s^2; a run lasts at most 4.3e9 periods of 1e3 s, about
//! 4.3e12 s; so no displacement, velocity or energy of a run comes near
//! f64's 1.8e308, where the unbounded values they replace (a frequency of
//! 1e300 Hz, a voltage of 1e308 V) overflowed and ended with status 2. Each
//! bound is also at least 10 times wider than every shipped scene
//! (`sweeps/*.toml`; `sweeps/extreme.toml` spans the widest ranges).
//! The GPU's f32 path has a far smaller range (3.4e38); the bounds do not
//! promise that every corner of them stays finite there.

use super::format::fmt_num;
use super::keys::Field;

/// What values a key accepts, by sign, interval and integrality. Every rule
/// is an interval (plus integrality).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Rule {
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
    pub(super) fn accepts(self, value: f64) -> bool {
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
    pub(super) fn expected(self) -> &'static str {
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
    pub(super) fn integer(self) -> bool {
        matches!(self, Rule::Count | Rule::Settle)
    }
}

/// The plausible values of a key, a closed interval in the key's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Bounds {
    /// The smallest plausible value.
    pub(super) min: f64,
    /// The largest plausible value.
    pub(super) max: f64,
}

impl Bounds {
    /// Whether `value` lies within the bounds.
    pub(super) fn contains(self, value: f64) -> bool {
        value >= self.min && value <= self.max
    }

    /// What the bounds expect, with the key's units, for error messages.
    pub(super) fn expected(self, units: &str) -> String {
        let unit = if units == "1" {
            String::new()
        } else {
            format!(" {units}")
        };
        format!(
            "expected a number from {} to {}{unit} (the plausible range of the model)",
            fmt_num(self.min),
            fmt_num(self.max)
        )
    }
}

/// Slider and stage masses, 1 ug to 1 t [kg]. The shipped scenes use 1e-6
/// kg (`sweeps/extreme.toml`) to 1 kg; the lower end keeps an acceleration
/// (force / mass) finite.
const MASS: Bounds = Bounds {
    min: 1e-9,
    max: 1e3,
};

/// Static friction, 1 pN to 1 GN [N]. `sweeps/extreme.toml` goes from 1e-9
/// N (almost none) to 1e6 N (never slips).
const STATIC_FRICTION: Bounds = Bounds {
    min: 1e-12,
    max: 1e9,
};

/// Coulomb (sliding) friction, none to 1 GN [N], like the static friction.
const COULOMB_FRICTION: Bounds = Bounds { min: 0.0, max: 1e9 };

/// A load on the slider, -1 GN to 1 GN per axis [N], like the friction it
/// must stay below: the refusal that matters is the load's magnitude
/// against the kinetic friction (docs/model.md section 7,
/// `plan::check_instance`), which these bounds only keep finite.
const LOAD: Bounds = Bounds {
    min: -1e9,
    max: 1e9,
};

/// The velocity band of the stick detection, 1 fm/s to 1 km/s [m/s].
/// `sweeps/extreme.toml` uses 1e-9 to 1e-3 m/s; a band wider than any
/// speed of the run only means the slider always sticks.
const VELOCITY_BAND: Bounds = Bounds {
    min: 1e-15,
    max: 1e3,
};

/// LuGre's bristle stiffness sigma0, 1 N/m to 1e12 N/m [N/m]. Issue 40's
/// range is 1e5 to 1e10 N/m (soft presliding to the Karnopp limit); the
/// integrator is implicit, so stiffness costs steps only where it costs
/// accuracy.
const BRISTLE_STIFFNESS: Bounds = Bounds {
    min: 1.0,
    max: 1e12,
};

/// LuGre's bristle damping sigma1 and viscous friction sigma2, none to
/// 1e9 N s/m [N s/m]. At the defaults sigma1 is 223.6 N s/m.
const BRISTLE_DAMPING: Bounds = Bounds { min: 0.0, max: 1e9 };

/// LuGre's Stribeck velocity v_S, 1 fm/s to 1 km/s [m/s], like the
/// Karnopp band it replaces (1e-3 m/s by default; 1e-5 m/s for the Karnopp
/// limit).
const STRIBECK_VELOCITY: Bounds = Bounds {
    min: 1e-15,
    max: 1e3,
};

/// Stage stiffness, 1 mN/m to 1 TN/m [N/m]. `sweeps/extreme.toml` goes to
/// 1e9 N/m (a 100 kHz stage); Table 1 has 1e6 N/m.
const STIFFNESS: Bounds = Bounds {
    min: 1e-3,
    max: 1e12,
};

/// Stage damping, none to 1e9 N s/m [N s/m]. Q = 0.5 at 1e9 N/m and 2.5 g
/// (`sweeps/extreme.toml`) needs about 3e3 N s/m.
const DAMPING: Bounds = Bounds { min: 0.0, max: 1e9 };

/// Stage resonance, 1 mHz to 10 GHz [Hz]: up to the 5e9 Hz of the stiffest
/// and lightest stage the mass and stiffness bounds allow, down to the
/// drive's lowest frequency. The paper's text uses 1 kHz.
const RESONANCE: Bounds = Bounds {
    min: 1e-3,
    max: 1e10,
};

/// Stage quality factor, 1e-3 (far overdamped) to 1e9 [1].
/// `sweeps/extreme.toml` spans 0.5 to 1e4.
const QUALITY: Bounds = Bounds {
    min: 1e-3,
    max: 1e9,
};

/// Piezo force constant, -1 kN/V to 1 kN/V [N/V]. Table 1 has -0.6 N/V.
const GAIN: Bounds = Bounds {
    min: -1e3,
    max: 1e3,
};

/// Drive amplitude, -10 kV to 10 kV [V]: ten times the +-1000 V of
/// `sweeps/extreme.toml`, beyond which piezo stacks break down.
const VOLTAGE: Bounds = Bounds {
    min: -1e4,
    max: 1e4,
};

/// Drive frequency, 1 mHz to 1 MHz [Hz]. `sweeps/extreme.toml` drives at
/// up to 13 kHz, past the 3.2 kHz stage resonance of Table 1; 1 MHz is ten
/// times the resonance of its stiffest stage. At the lower end one period
/// lasts 1000 s.
const FREQUENCY: Bounds = Bounds {
    min: 1e-3,
    max: 1e6,
};

/// Ratio of the y drive's frequency to the x drive's, 1e-3 to 1e3 [1]: two
/// drives of one actuator three decades apart already make the scene
/// period (1 / the lowest frequency) a thousand periods of the faster one;
/// the derived f_y is also held to the frequency bounds above.
const FREQUENCY_RATIO: Bounds = Bounds {
    min: 1e-3,
    max: 1e3,
};

/// Duty of the sawtooth, 1e-6 to 1 [1]: a rise shorter than a millionth of
/// the period would make the drive's slope, voltage / (duty x period),
/// enormous for no physical reason. `sweeps/stress.toml` goes down to 0.6.
const DUTY: Bounds = Bounds {
    min: 1e-6,
    max: 1.0,
};

/// The trapezoid's rise, hold and fall, 0 to 1 [1]: fractions of a cycle
/// (0 is a jump); their sum is checked per instance (at most 1, not 0).
const FRACTION: Bounds = Bounds { min: 0.0, max: 1.0 };

/// The amplifier's slew limit, 1e-3 V/s to 1e12 V/s [V/s]: a stack of 1 uF
/// on a 1 A amplifier slews at 1e6 V/s (I_max / C); the ends only keep the
/// limit's slope, slew_rate / (|V| f) levels per cycle, finite and
/// positive. A limit at or above every flank is the waveform itself.
const SLEW_RATE: Bounds = Bounds {
    min: 1e-3,
    max: 1e12,
};

/// Phase offset, -1e6 to 1e6 periods [cycles]: only its fraction matters,
/// and beyond a million periods f64 keeps fewer than 10 of its digits.
const PHASE: Bounds = Bounds {
    min: -1e6,
    max: 1e6,
};

/// Integrator tolerance, 1e-12 to 1 rad [rad]: a deviation of the friction
/// direction above a radian leaves the quadratic model of the direction
/// nothing to approximate; the error of the step maps is about tolerance / 4
/// um, so 1e-12 rad already asks for 2.5e-13 um. The default is 1e-4 rad;
/// `tests/it/extreme.rs` converges at 1e-8 rad.
const TOLERANCE: Bounds = Bounds {
    min: 1e-12,
    max: 1.0,
};

/// Standard error allowed on a steady step, none to 1 mm per own drive
/// cycle [m]. The upper end is far beyond any stick-slip drive's step (Table
/// 1's converged steps are at most a few micrometres, docs/model.md section 6);
/// a tolerance above every step would accept any estimate as soon as
/// `settle` periods are past, a short window in disguise. There is no lower
/// end beyond > 0: a tolerance no estimate can meet only means the run
/// stops when its motion repeats or at `max_cycles`, which bounds it. The
/// default, `Measure::DEFAULT_STEP_TOLERANCE`, is 1e-8 m.
const STEP_TOLERANCE: Bounds = Bounds {
    min: 0.0,
    max: 1e-3,
};

impl Field {
    /// What values the key accepts.
    pub(super) fn rule(self) -> Rule {
        match self {
            Field::SliderMass
            | Field::StaticFriction
            | Field::VelocityBand
            | Field::StageMass
            | Field::Stiffness
            | Field::ResonanceHz
            | Field::QualityFactor
            | Field::Frequency
            | Field::FrequencyRatio
            | Field::Tolerance
            | Field::StepTolerance
            | Field::BristleStiffness
            | Field::StribeckVelocity
            | Field::SlewRate => Rule::Positive,
            Field::CoulombFriction
            | Field::Damping
            | Field::BristleDamping
            | Field::ViscousFriction
            | Field::Rise
            | Field::Hold
            | Field::Fall => Rule::NonNegative,
            Field::Gain | Field::Voltage | Field::Phase | Field::LoadX | Field::LoadY => {
                Rule::Finite
            }
            Field::Duty => Rule::Duty,
            // `max_cycles` is bounded like `cycles`: both are the most
            // periods an instance runs.
            Field::Cycles | Field::MaxCycles | Field::MaxStepsPerPeriod => Rule::Count,
            Field::Settle => Rule::Settle,
        }
    }

    /// The plausible values of the key, checked after its rule; none for the
    /// integer keys, which their rule already bounds.
    pub(super) fn bounds(self) -> Option<Bounds> {
        Some(match self {
            Field::SliderMass | Field::StageMass => MASS,
            Field::StaticFriction => STATIC_FRICTION,
            Field::CoulombFriction => COULOMB_FRICTION,
            Field::VelocityBand => VELOCITY_BAND,
            Field::LoadX | Field::LoadY => LOAD,
            Field::BristleStiffness => BRISTLE_STIFFNESS,
            Field::BristleDamping | Field::ViscousFriction => BRISTLE_DAMPING,
            Field::StribeckVelocity => STRIBECK_VELOCITY,
            Field::Stiffness => STIFFNESS,
            Field::Damping => DAMPING,
            Field::ResonanceHz => RESONANCE,
            Field::QualityFactor => QUALITY,
            Field::Gain => GAIN,
            Field::Voltage => VOLTAGE,
            Field::Frequency => FREQUENCY,
            Field::FrequencyRatio => FREQUENCY_RATIO,
            Field::Duty => DUTY,
            Field::Rise | Field::Hold | Field::Fall => FRACTION,
            Field::SlewRate => SLEW_RATE,
            Field::Phase => PHASE,
            Field::Tolerance => TOLERANCE,
            Field::StepTolerance => STEP_TOLERANCE,
            Field::Cycles | Field::Settle | Field::MaxCycles | Field::MaxStepsPerPeriod => {
                return None;
            }
        })
    }
}
