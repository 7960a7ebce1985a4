//! The physical model of `docs/model.md`: the parameters of one 2-DOF instance,
//! the sawtooth drive and the derived quantities every backend needs.
//!
//! The model never does I/O and never allocates: it is plain data and pure
//! functions, shared by the CPU integrator, the GPU packer and the scene
//! expander.

pub mod drive;
pub mod motion;
pub mod random;

pub use drive::{NO_SLEW_LIMIT, Shape, Table};

/// Number of actuated axes of the mechanism (x and y).
pub const AXES: usize = 2;

/// Axis names, in storage order.
pub const AXIS_NAMES: [&str; AXES] = ["x", "y"];

/// One actuator + stage axis and its drive (docs/model.md sections 1-2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    /// Equivalent mass of actuator and stage, m_p [kg].
    pub stage_mass: f64,
    /// Stiffness of actuator and stage, k [N/m].
    pub stiffness: f64,
    /// Viscous damping of actuator and stage, c [N s/m].
    pub damping: f64,
    /// Force per volt of the piezo actuator, delta [N/V].
    pub gain: f64,
    /// Sawtooth amplitude V [V]; zero means the axis is undriven.
    pub voltage: f64,
    /// Drive frequency f [Hz].
    pub frequency: f64,
    /// Rise fraction d of each drive cycle, in (0, 1]; 1 is a ramp with an
    /// instantaneous drop.
    pub duty: f64,
    /// Drive phase offset [cycles].
    pub phase: f64,
    /// The waveform: the sawtooth (with `duty`), the trapezoid (with the
    /// three fractions below) or a table (docs/model.md section 2).
    pub shape: Shape,
    /// The trapezoid's rise, hold at the top and fall, each a fraction of
    /// a cycle (0 is a jump); the rest of the cycle dwells at 0. Unused
    /// (0) by the other shapes.
    pub rise: f64,
    pub hold: f64,
    pub fall: f64,
    /// The amplifier's slew limit [V/s]: the stage's voltage follows the
    /// waveform never faster than this. [`NO_SLEW_LIMIT`] (infinite) by
    /// default, the waveform itself.
    pub slew_rate: f64,
}

/// The shared friction interface and its slider (docs/model.md section 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanism {
    /// Slider mass m_s [kg].
    pub slider_mass: f64,
    /// Maximum static friction f_s [N].
    pub static_friction: f64,
    /// Coulomb (sliding) friction f_c [N].
    pub coulomb_friction: f64,
    /// Karnopp detection band a on the relative speed [m/s] (Karnopp
    /// friction only: LuGre has no modes, and its scenes refuse the key).
    pub velocity_band: f64,
    /// Constant external force on the slider, (L_x, L_y) [N] (docs/model.md
    /// section 7: a weight, a cable, a preloaded spring). Default 0, which
    /// reproduces every unloaded result bit for bit; a scene refuses
    /// |L| >= f_c (a slider slipping along such a load is not stopped by
    /// kinetic friction and may run away).
    pub load: [f64; AXES],
    /// The friction law at the interface (`mechanism.friction`).
    pub friction: Friction,
}

/// The friction law at the interface (`mechanism.friction`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Friction {
    /// Coulomb friction with stiction in Karnopp's form, two modes (docs/model.md
    /// section 3): the default, integrated in closed form.
    #[default]
    Karnopp,
    /// The 2-D LuGre model (docs/model.md section 8): bristles with a state of
    /// their own, no modes, a stiff right-hand side.
    Lugre(Lugre),
}

/// The LuGre parameters of docs/model.md section 8. The defaults are
/// illustrative, not identified for any device.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lugre {
    /// sigma0, the bristles' stiffness [N/m]: 1e7 by default, a presliding
    /// deflection f_s / sigma0 of 0.12 um at breakaway on Table 1.
    pub bristle_stiffness: f64,
    /// sigma1, the bristles' damping [N s/m]; `None` (the default):
    /// sqrt(sigma0 m_s), a damping ratio of 0.5 of the slider on its
    /// bristles, from the instance's own sigma0 and m_s.
    pub bristle_damping: Option<f64>,
    /// sigma2, viscous friction [N s/m]: 0 by default.
    pub viscous_friction: f64,
    /// v_S, the Stribeck velocity [m/s]: 1e-3 by default.
    pub stribeck_velocity: f64,
}

impl Lugre {
    /// docs/model.md section 8's defaults.
    pub const DEFAULT: Lugre = Lugre {
        bristle_stiffness: 1e7,
        bristle_damping: None,
        viscous_friction: 0.0,
        stribeck_velocity: 1e-3,
    };

    /// sigma1 [N s/m] for a slider of `slider_mass` [kg]: the given value,
    /// or sqrt(sigma0 m_s).
    pub fn damping(&self, slider_mass: f64) -> f64 {
        self.bristle_damping
            .unwrap_or((self.bristle_stiffness * slider_mass).sqrt())
    }

    /// The parameters, named by their scene keys, in storage order;
    /// `bristle_damping` is NaN where it is derived.
    pub fn parameters(&self) -> [(&'static str, f64); 4] {
        [
            ("bristle_stiffness", self.bristle_stiffness),
            ("bristle_damping", self.bristle_damping.unwrap_or(f64::NAN)),
            ("viscous_friction", self.viscous_friction),
            ("stribeck_velocity", self.stribeck_velocity),
        ]
    }
}

impl Default for Lugre {
    fn default() -> Lugre {
        Lugre::DEFAULT
    }
}

impl Mechanism {
    /// The LuGre parameters, if the interface is LuGre's.
    pub fn lugre(&self) -> Option<&Lugre> {
        match &self.friction {
            Friction::Lugre(lugre) => Some(lugre),
            Friction::Karnopp => None,
        }
    }

    /// The largest friction force the interface holds without slipping
    /// [N]: max(f_s, f_c). It is f_s whenever f_c <= f_s (every physical
    /// interface). With f_c > f_s, docs/model.md's rules chatter: a breakaway
    /// with f_s < |f_need| <= f_c starts a slip that the larger kinetic
    /// friction cannot let grow (the slip direction exists only for
    /// |f_need| > f_c, see `slip_direction`), so the relative velocity
    /// falls back into the band at once, over and over, at a cost that
    /// grows like 1/a. The limit a -> 0 of that chatter is a slider held
    /// at the stage's velocity until |f_need| exceeds f_c, which is what
    /// this threshold integrates directly (measured: the chatter's steps
    /// approach it as a shrinks; docs/extreme.md).
    pub fn holding_friction(&self) -> f64 {
        self.static_friction.max(self.coulomb_friction)
    }
}

/// The bits of every parameter of an [`Instance`] ([`Instance::key`]).
pub type InstanceKey = [u64; 43];

/// How an instance's step is measured (docs/model.md section 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measure {
    /// The paper's fixed window: [`Instance::cycles`] scene periods, the
    /// first [`Instance::settle`] discarded. It equals the steady step only
    /// when the motion is periodic from `settle` on with a period that
    /// divides `cycles - settle`.
    Window,
    /// The steady step: after at least [`Instance::settle`] periods, the
    /// run stops when its motion repeats or when each axis' standard error
    /// is at most `step_tolerance`, and at [`Instance::cycles`]
    /// (`max_cycles`) periods at the latest.
    Steady {
        /// Standard error allowed on each axis' mean step [m per own drive
        /// cycle].
        step_tolerance: f64,
    },
}

impl Measure {
    /// Default `step_tolerance` [m per own drive cycle]: 0.01 um, twice the
    /// 0.005 um a map is compared at and a hundred times the integrator's
    /// own error (1e-4 um).
    pub const DEFAULT_STEP_TOLERANCE: f64 = 1e-8;
    /// Default `max_cycles` [scene periods]. A quasi-periodic instance's
    /// standard error falls like (oscillation range) / N, measured 0.01-0.12
    /// um after 1,000 periods, so 0.01 um takes up to about 12,000 periods;
    /// periodic instances stop after a few common periods whatever this is.
    /// 10,000 bounds the cost of a map's worst instances to seconds each,
    /// and those that do not converge by then say so (status "not steady").
    pub const DEFAULT_MAX_CYCLES: u32 = 10_000;
    /// Default leading periods discarded at least (the window's default too).
    pub const DEFAULT_SETTLE: u32 = 2;

    /// The scene's name of the method: "window" or "steady".
    pub fn name(&self) -> &'static str {
        match self {
            Measure::Window => "window",
            Measure::Steady { .. } => "steady",
        }
    }

    /// The step tolerance [m per own drive cycle], 0 for a window.
    pub fn step_tolerance(&self) -> f64 {
        match self {
            Measure::Window => 0.0,
            Measure::Steady { step_tolerance } => *step_tolerance,
        }
    }
}

/// Everything that defines one simulated instance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    pub mechanism: Mechanism,
    pub axes: [Axis; AXES],
    /// Scene periods simulated (a window) or the most that may be
    /// simulated (`max_cycles` of a steady measurement) (docs/model.md section 4).
    pub cycles: u32,
    /// Leading periods discarded before measuring (at least, when steady).
    pub settle: u32,
    /// How the step is measured.
    pub measure: Measure,
}

impl Axis {
    /// Table 1 of the paper as printed: a 3.18 kHz stage with Q = 15.6,
    /// driven at 100 V, 10 Hz, duty 0.98.
    pub const TABLE1: Axis = Axis {
        stage_mass: 2.5e-3,
        stiffness: 1.0e6,
        damping: 3.2,
        gain: -0.6,
        voltage: 100.0,
        frequency: 10.0,
        duty: 0.98,
        phase: 0.0,
        shape: Shape::Sawtooth,
        rise: 0.0,
        hold: 0.0,
        fall: 0.0,
        slew_rate: NO_SLEW_LIMIT,
    };

    /// The paper's text (1 kHz, Q = 50) with k = 1e6 N/m, through eqs. 6-7.
    pub const TEXT: Axis = Axis {
        stage_mass: 2.533_029_591_058_444e-2,
        damping: 3.183_098_861_837_907,
        ..Axis::TABLE1
    };

    /// Every parameter, named by its scene key, in storage order.
    pub fn parameters(&self) -> [(&'static str, f64); 8] {
        [
            ("stage_mass", self.stage_mass),
            ("stiffness", self.stiffness),
            ("damping", self.damping),
            ("gain", self.gain),
            ("voltage", self.voltage),
            ("frequency", self.frequency),
            ("duty", self.duty),
            ("phase", self.phase),
        ]
    }

    /// The drive's shape beyond the sawtooth's keys, as bits: the shape,
    /// its fractions, the slew limit and the table's identity (zeros for
    /// a plain sawtooth).
    pub fn shape_key(&self) -> [u64; 6] {
        let (tag, table) = match self.shape {
            Shape::Sawtooth => (0, 0),
            Shape::Trapezoid => (1, 0),
            Shape::Table(t) => (2, t.id()),
        };
        [
            tag,
            self.rise.to_bits(),
            self.hold.to_bits(),
            self.fall.to_bits(),
            self.slew_rate.to_bits(),
            table,
        ]
    }

    /// True when the axis has a non-zero drive.
    pub fn is_driven(&self) -> bool {
        self.voltage != 0.0
    }

    /// Stage mass from a resonance [Hz] and stiffness (paper eq. 6).
    pub fn mass_from_resonance(resonance_hz: f64, stiffness: f64) -> f64 {
        let omega = 2.0 * std::f64::consts::PI * resonance_hz;
        stiffness / (omega * omega)
    }

    /// Stiffness from a resonance [Hz] and stage mass (paper eq. 6).
    pub fn stiffness_from_resonance(resonance_hz: f64, stage_mass: f64) -> f64 {
        let omega = 2.0 * std::f64::consts::PI * resonance_hz;
        stage_mass * omega * omega
    }

    /// Damping from a quality factor (paper eq. 7: c = sqrt(k m) / Q).
    pub fn damping_from_quality(quality_factor: f64, stiffness: f64, stage_mass: f64) -> f64 {
        (stiffness * stage_mass).sqrt() / quality_factor
    }

    /// Resonance of the free stage [Hz].
    pub fn resonance_hz(&self) -> f64 {
        (self.stiffness / self.stage_mass).sqrt() / (2.0 * std::f64::consts::PI)
    }

    /// Quality factor of the free stage.
    pub fn quality_factor(&self) -> f64 {
        (self.stiffness * self.stage_mass).sqrt() / self.damping
    }
}

impl Mechanism {
    /// Every parameter, named by its scene key, in storage order.
    pub fn parameters(&self) -> [(&'static str, f64); 6] {
        [
            ("slider_mass", self.slider_mass),
            ("static_friction", self.static_friction),
            ("coulomb_friction", self.coulomb_friction),
            ("velocity_band", self.velocity_band),
            ("load_x", self.load[0]),
            ("load_y", self.load[1]),
        ]
    }

    /// The load's magnitude |L| [N] (the friction law is isotropic, so the
    /// refusal of docs/model.md section 7 is on the vector's length).
    pub fn load_magnitude(&self) -> f64 {
        self.load[0].hypot(self.load[1])
    }

    /// Whether the load is refused (docs/model.md section 7): a non-zero load of
    /// at least the kinetic friction f_c, along which a slipping slider is
    /// not stopped by friction and may run away. A zero load is never
    /// refused, also with f_c = 0.
    pub fn load_refused(&self) -> bool {
        let l = self.load_magnitude();
        l > 0.0 && l >= self.coulomb_friction
    }

    /// Table 1 of the paper.
    pub const TABLE1: Mechanism = Mechanism {
        slider_mass: 5.0e-3,
        static_friction: 1.2,
        coulomb_friction: 1.0,
        velocity_band: 1.0e-6,
        load: [0.0; AXES],
        friction: Friction::Karnopp,
    };
}

impl Instance {
    /// The paper's Fig. 6 point with Table 1 as printed: both axes at 100 V,
    /// 10 Hz, duty 0.98; 10 periods of which 2 settle.
    pub const TABLE1: Instance = Instance {
        mechanism: Mechanism::TABLE1,
        axes: [Axis::TABLE1, Axis::TABLE1],
        cycles: 10,
        settle: 2,
        measure: Measure::Window,
    };

    /// Scene period T = 1 / (lowest frequency among driven axes), or 1 / f_x
    /// when nothing is driven (docs/model.md section 4) [s].
    pub fn period(&self) -> f64 {
        let lowest = self
            .axes
            .iter()
            .filter(|axis| axis.is_driven())
            .map(|axis| axis.frequency)
            .fold(f64::INFINITY, f64::min);
        if lowest.is_finite() {
            1.0 / lowest
        } else {
            1.0 / self.axes[0].frequency
        }
    }

    /// Simulated time at most [s] (a steady measurement usually stops
    /// earlier).
    pub fn duration(&self) -> f64 {
        self.cycles as f64 * self.period()
    }

    /// The same mechanism with every axis but `keep` undriven: the 1-DOF
    /// baseline of docs/model.md section 4 (paper curves d_s1, d_s2). It carries
    /// only its own axis' load, (L_i, 0) on axis i (docs/model.md section 7),
    /// so it is the 1-DOF actuator under the same load along its axis.
    pub fn baseline(&self, keep: usize) -> Instance {
        let mut out = *self;
        for (i, axis) in out.axes.iter_mut().enumerate() {
            if i != keep {
                axis.voltage = 0.0;
                out.mechanism.load[i] = 0.0;
            }
        }
        out
    }

    /// The instance's exact identity: every parameter's bits. Two instances
    /// with the same key integrate to the same result on any backend.
    pub fn key(&self) -> InstanceKey {
        let mut key = [0; 43];
        key[..6].copy_from_slice(&self.mechanism.parameters().map(|(_, v)| v.to_bits()));
        key[6..8].copy_from_slice(&[self.cycles as u64, self.settle as u64]);
        for (i, a) in self.axes.iter().enumerate() {
            key[8 + 8 * i..16 + 8 * i].copy_from_slice(&a.parameters().map(|(_, v)| v.to_bits()));
        }
        key[24] = matches!(self.measure, Measure::Steady { .. }) as u64;
        key[25] = self.measure.step_tolerance().to_bits();
        if let Some(lugre) = self.mechanism.lugre() {
            key[26] = 1;
            key[27..31].copy_from_slice(&lugre.parameters().map(|(_, v)| v.to_bits()));
        }
        for (i, a) in self.axes.iter().enumerate() {
            key[31 + 6 * i..37 + 6 * i].copy_from_slice(&a.shape_key());
        }
        key
    }

    /// Converts a slider displacement measured over the kept periods into
    /// (velocity [m/s], step per own drive cycle [m]) for axis `i`.
    pub fn measure(&self, i: usize, displacement: f64) -> (f64, f64) {
        self.measure_over(i, displacement, (self.cycles - self.settle) as f64)
    }

    /// Converts a slider travel over `span` scene periods into (velocity
    /// [m/s], step per own drive cycle [m]) for axis `i`; zeros when
    /// nothing was measured (`span` 0).
    pub fn measure_over(&self, i: usize, travel: f64, span: f64) -> (f64, f64) {
        if span <= 0.0 {
            return (0.0, 0.0);
        }
        let kept = span * self.period();
        let velocity = travel / kept;
        (velocity, velocity / self.axes[i].frequency)
    }
}

/// Normalised sawtooth w(u; d) of docs/model.md section 2: a rise from 0 to 1 over
/// the first fraction `duty` of each cycle, then a fall back to 0.
pub fn sawtooth(u: f64, duty: f64) -> f64 {
    let p = u - u.floor();
    if p < duty {
        p / duty
    } else {
        (1.0 - p) / (1.0 - duty)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_parameters_follow_from_eqs_6_and_7() {
        let m = Axis::mass_from_resonance(1000.0, 1.0e6);
        assert!((m - Axis::TEXT.stage_mass).abs() < 1e-15);
        let c = Axis::damping_from_quality(50.0, 1.0e6, m);
        assert!((c - Axis::TEXT.damping).abs() < 1e-12);
        assert!((Axis::TABLE1.resonance_hz() - 3183.1).abs() < 0.1);
        assert!((Axis::TABLE1.quality_factor() - 15.625).abs() < 1e-9);
    }

    #[test]
    fn period_follows_the_slowest_driven_axis() {
        let mut inst = Instance::TABLE1;
        inst.axes[1].frequency = 20.0;
        assert_eq!(inst.period(), 0.1);
        inst.axes[0].voltage = 0.0;
        assert_eq!(inst.period(), 0.05);
        inst.axes[1].voltage = 0.0;
        assert_eq!(inst.period(), 0.1);
    }

    #[test]
    fn sawtooth_rises_slowly_and_falls_fast() {
        assert_eq!(sawtooth(0.0, 0.98), 0.0);
        assert!((sawtooth(0.49, 0.98) - 0.5).abs() < 1e-15);
        assert!((sawtooth(0.99, 0.98) - 0.5).abs() < 1e-12);
        assert!((sawtooth(2.25, 0.5) - 0.5).abs() < 1e-15);
        assert!((sawtooth(0.999, 1.0) - 0.999).abs() < 1e-15);
    }
}
