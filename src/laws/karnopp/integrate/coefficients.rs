//! Everything the integrator derives from an instance and the settings,
//! computed once per instance in Real (`Coefficients::new`, which exists
//! in Real only) and rounded once to the precision in its units
//! ([`Coefficients::of`]). The Real integrator reads them in SI units; the
//! GPU packs the same numbers (`pidm::gpu::karnopp::layout`), so the shader divides
//! by no parameter and takes no square root of one.

use super::measure::Gauge;
use super::phase::{Gaps, LEVELS, Replica};
use super::precision::{TIME_EPSILON, UNITS, only_f64};
use super::vec2::Vec2;
use super::{Real, Settings};
use crate::model::Instance;

/// One mode's oscillator per axis: m x'' + c x' + k x = g, with the stage
/// alone (slip) or stage and slider together (stick).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Oscillator {
    /// Moving mass m [kg].
    pub mass: Vec2,
    /// sigma = c / 2m [1/s].
    pub sigma: Vec2,
    /// w^2 = k / m [1/s^2].
    pub w2: Vec2,
    /// sqrt(w^2) + 2 sigma [1/s]: bounds how fast the motion can change,
    /// for the propagator's scaling and the step lengths.
    pub rate: Vec2,
    /// 1 / m [1/kg].
    pub inv_mass: Vec2,
    /// 1 / w^2 [s^2].
    pub inv_w2: Vec2,
}

/// The per-instance constants of the integrator, in one unit system
/// (whatever the instance is given in).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coefficients {
    /// Stiffness k and damping c per axis (the stage mass enters through
    /// the oscillators and the shares below).
    pub stiffness: Vec2,
    pub damping: Vec2,
    /// 1 / k, for the polynomial particular solutions.
    pub inv_stiffness: Vec2,
    /// Stage and slider as one body (STICK).
    pub stick: Oscillator,
    /// The stage alone (SLIP and BAND).
    pub slip: Oscillator,
    /// Drive force amplitude delta V [N]: zero on an undriven axis.
    pub amplitude: Vec2,
    /// Drive frequency f [1/s].
    pub frequency: Vec2,
    /// Each axis' drive, one cycle's linear segments (`drive::Segment`).
    pub segments: [Box<[super::drive::Segment]>; 2],
    /// Drive phase [cycles] and drive cycles per scene period.
    pub phase: Vec2,
    pub cycles_per_period: Vec2,
    /// The same in fixed point, for the f32 shader's period start phases
    /// (`drive::fixed_start_phase`): the phase's fraction in units of
    /// 2^-32 cycles, and the fraction of the cycles per period in units of
    /// 2^-64 cycles as a high and a low word. Period starts are then exact
    /// integer sums, where `phase + period * cycles_per_period` in f32
    /// loses about 1e-6 cycles by the fifth period.
    pub phase_fixed: [u32; 2],
    pub cycles_fixed: [u32; 2],
    pub cycles_fixed_lo: [u32; 2],
    /// m_p / (m_p + m_s) and m_s / (m_p + m_s): the momentum-conserving
    /// common velocity is the sum of the two velocities weighted by them.
    pub stage_share: Vec2,
    pub slider_share: Vec2,
    /// (m_p + m_s) / (m_p m_s): turns f_need into the relative acceleration
    /// A of `slip_direction`, and f_c into its B.
    pub slip_scale: Vec2,
    pub slip_b: Vec2,
    /// The load on the slider (docs/model.md section 7), in the forms the
    /// integrator uses it in: each enters only by a subtraction of a value
    /// that is +0 at L = 0, so an unloaded run is bit for bit what it was
    /// before the load existed (x - (+0) = x for every x, -0 included,
    /// where x + 0 turns -0 into +0). `load_need` = m_p L / (m_p + m_s)
    /// [N]: f_need = m_s P / (m_p + m_s) - load_need. `load_accel` = L /
    /// m_s [m/s^2]: f_need = m_s (a_p - load_accel) in stick.
    /// `neg_load` = -L [N], subtracted from the stuck body's force (stage
    /// and slider together feel the load), and `neg_load_accel` = -L / m_s
    /// [m/s^2], subtracted from the slipping slider's acceleration. Only
    /// constant forces: the closed-form flows keep their form, with a
    /// shifted particular solution.
    pub load_need: Vec2,
    pub load_accel: Vec2,
    pub neg_load: Vec2,
    pub neg_load_accel: Vec2,
    /// The larger component of `slip_b`.
    pub slip_b_max: Real,
    /// max(f_s, f_c)^2 [N^2]: the interface holds while |f_need|^2 <= hold2.
    pub hold2: Real,
    /// (max(f_s, f_c) - |L|)^2 [N^2]: a stick segment whose homogeneous
    /// acceleration a has m_s^2 |a|^2 below this for good cannot break,
    /// since |f_need| = |m_s a - L| <= m_s |a| + |L| (the energy bound of
    /// `step::trial`); hold2 itself at L = 0. A scene's load is below f_c
    /// <= max(f_s, f_c), so the difference is positive.
    pub safe_hold2: Real,
    /// m_s^2 and 2 m_s^2 [kg^2].
    pub ms2: Real,
    pub two_ms2: Real,
    /// Kinetic friction f_c [N] and f_c / m_s [m/s^2].
    pub coulomb: Real,
    pub fc_over_ms: Real,
    /// Detection band a [m/s] and a^2 [m^2/s^2].
    pub band: Real,
    pub band2: Real,
    /// Scene period T [s], and the rest of it below the precision (zero
    /// in f64).
    pub period: Real,
    pub period_lo: Real,
    /// The corner clock's (`drive::CornerClock`, f32's `CORNER_CLOCK`)
    /// local time of the first corner, as hi + lo [s] (the segments carry
    /// their durations); zero on undriven axes.
    pub first_corner: Vec2,
    pub first_corner_lo: Vec2,
    /// Step lengths that sample the fastest oscillation of stick and of
    /// slip densely enough for event detection [s].
    pub event_step_stuck: Real,
    pub event_step_slip: Real,
    /// The smallest slip step before the instance gives up [s].
    pub min_step: Real,
    /// Simulated and discarded scene periods.
    pub cycles: u32,
    pub settle: u32,
    /// The accuracy knob [rad] ([`Settings::tolerance`]).
    pub tolerance: Real,
    /// The change of the direction model below which its fixed-point
    /// iteration stops [rad].
    pub collocation_tolerance: Real,
    /// Steps allowed in the whole run, saturated at `u32::MAX`.
    pub budget: u32,
    /// Whether each axis is driven (a non-zero voltage).
    pub driven: [bool; 2],
    /// A steady measurement (`measure::period_end` runs at period ends).
    pub steady: bool,
    /// The drives' common period [scene periods], 0 when there is none up
    /// to `measure::MAX_COMMON_PERIOD` (`measure::common_period`).
    pub common_period: u32,
    /// The phase ladder's three-gap table per window length
    /// (`phase::gaps`; zero where the ladder is off).
    pub gaps: [Gaps; LEVELS],
    /// The ladder levels whose end may stop the run, a bit per level
    /// (`phase::ladder`); 0 where the ladder is off, which then keeps no
    /// windows at all.
    pub phase_levels: u32,
    /// The levels whose window is a near-complete lattice of the common
    /// period, judged without their quarters (`phase::Ladder::lattice`).
    pub phase_lattice: u32,
    /// Which replica of a split run this is, and of how many
    /// (`phase::Replica`; 0 of 1 for a run of its own): the ladder's tables
    /// and levels are then the virtual run's.
    pub replica: u32,
    pub replicas: u32,
    /// The first batch length [scene periods].
    pub batch_length: u32,
    /// The batch length a statistical stop needs [scene periods]: the
    /// common period or the slowest beat (`measure::beat_batch_length`).
    pub min_batch: u32,
    /// Squared standard error allowed on each axis' travel per scene
    /// period [m^2]: (step_tolerance f_i T)^2.
    pub se_limit2: Vec2,
    /// The recurrence test's tolerances on positions [m] and velocities
    /// [m/s].
    pub repeat_x: Real,
    pub repeat_v: Real,
    /// f_c = 0: slip does not depend on the friction direction.
    pub frictionless: bool,
}

// Karnopp's coefficients carry the floor's measurement constants among
// their own, flat, as `shaders/karnopp/coefficients.wgsl` does.
super::measure::gauge_by_fields!(Coefficients);

impl Coefficients {
    /// The coefficients of an instance in this precision's units: computed
    /// in f64 from the instance in those units and rounded once, exactly
    /// as the GPU packs them (`pidm::gpu::karnopp::layout`), the corner clock's
    /// values split into a rounded part and the rounded rest. In f64 they
    /// are those of `Coefficients::new` in SI units.
    pub fn of(inst: &Instance, settings: &Settings) -> Coefficients {
        Coefficients::of_replica(inst, settings, Replica::NONE)
    }

    /// Each axis' drive segments of `inst` as [`Coefficients::of`] (and
    /// `of_replica`, whose replicas share their drive's shape) holds them,
    /// without deriving the rest: a waveform batch's segment buffer
    /// (`gpu::karnopp::layout::segment_buffer`) from the instances alone.
    #[allow(clippy::unnecessary_cast)]
    pub fn segments_of(inst: &Instance) -> [Box<[super::drive::Segment]>; 2] {
        let scaled = UNITS.scale(inst);
        std::array::from_fn(|i| {
            let exact =
                crate::laws::karnopp::double::integrate::drive::segments_of(&scaled.axes[i]);
            super::drive::rounded(&exact, |x| x as Real as f64)
        })
    }

    /// [`Coefficients::of`] for replica `r` of a split run: `inst` is the
    /// replica's instance (its faster drive's phase advanced,
    /// `pidm::replicas::replica_instance`).
    pub fn of_replica(inst: &Instance, settings: &Settings, r: Replica) -> Coefficients {
        let exact = crate::laws::karnopp::double::integrate::Coefficients::new_replica(
            &UNITS.scale(inst),
            settings,
            TIME_EPSILON,
            r,
        );
        Coefficients::rounded(&exact)
    }

    /// `exact` (f64) rounded once to this precision, with the corner clock
    /// in two parts (zero low parts in f64).
    #[allow(clippy::unnecessary_cast)]
    pub fn rounded(exact: &crate::laws::karnopp::double::integrate::Coefficients) -> Coefficients {
        use crate::laws::karnopp::double::integrate as exact_integrate;
        let v = |x: exact_integrate::Vec2| Vec2::new(x.x as Real, x.y as Real);
        let r = |x: f64| x as Real;
        let osc = |o: &exact_integrate::coefficients::Oscillator| Oscillator {
            mass: v(o.mass),
            sigma: v(o.sigma),
            w2: v(o.w2),
            rate: v(o.rate),
            inv_mass: v(o.inv_mass),
            inv_w2: v(o.inv_w2),
        };
        let period = {
            let hi = exact.period as Real;
            (hi, (exact.period - hi as f64) as Real)
        };
        let first = exact_integrate::drive::first_corner(exact, |x| x as Real as f64);
        let e = exact;
        Coefficients {
            stiffness: v(e.stiffness),
            damping: v(e.damping),
            inv_stiffness: v(e.inv_stiffness),
            stick: osc(&e.stick),
            slip: osc(&e.slip),
            amplitude: v(e.amplitude),
            frequency: v(e.frequency),
            segments: std::array::from_fn(|i| {
                super::drive::rounded(&e.segments[i], |x| x as Real as f64)
            }),
            phase: v(e.phase),
            cycles_per_period: v(e.cycles_per_period),
            phase_fixed: e.phase_fixed,
            cycles_fixed: e.cycles_fixed,
            cycles_fixed_lo: e.cycles_fixed_lo,
            stage_share: v(e.stage_share),
            slider_share: v(e.slider_share),
            slip_scale: v(e.slip_scale),
            slip_b: v(e.slip_b),
            load_need: v(e.load_need),
            load_accel: v(e.load_accel),
            neg_load: v(e.neg_load),
            neg_load_accel: v(e.neg_load_accel),
            slip_b_max: r(e.slip_b_max),
            hold2: r(e.hold2),
            safe_hold2: r(e.safe_hold2),
            ms2: r(e.ms2),
            two_ms2: r(e.two_ms2),
            coulomb: r(e.coulomb),
            fc_over_ms: r(e.fc_over_ms),
            band: r(e.band),
            band2: r(e.band2),
            period: period.0,
            period_lo: period.1,
            first_corner: v(first.0),
            first_corner_lo: v(first.1),
            event_step_stuck: r(e.event_step_stuck),
            event_step_slip: r(e.event_step_slip),
            min_step: r(e.min_step),
            cycles: e.cycles,
            settle: e.settle,
            tolerance: r(e.tolerance),
            collocation_tolerance: r(e.collocation_tolerance),
            budget: e.budget,
            driven: e.driven,
            steady: e.steady,
            common_period: e.common_period,
            gaps: e.gaps.map(|g| Gaps {
                a: g.a,
                b: g.b,
                alpha: r(g.alpha),
                beta: r(g.beta),
            }),
            phase_levels: e.phase_levels,
            phase_lattice: e.phase_lattice,
            replica: e.replica,
            replicas: e.replicas,
            batch_length: e.batch_length,
            min_batch: e.min_batch,
            se_limit2: v(e.se_limit2),
            repeat_x: r(e.repeat_x),
            repeat_v: r(e.repeat_v),
            frictionless: e.frictionless,
        }
    }
}

only_f64! {
use super::constants::{COLLOCATION_CONVERGED, EVENT_STEP_PERIODS, MIN_STEP_EPSILONS};

impl Oscillator {
    fn new(mass: Vec2, damping: Vec2, stiffness: Vec2) -> Oscillator {
        let sigma = damping.zip(mass, |c, m| c / (2.0 * m));
        let w2 = stiffness / mass;
        Oscillator {
            mass,
            sigma,
            w2,
            rate: w2.zip(sigma, |w2, s| w2.sqrt() + 2.0 * s),
            inv_mass: mass.map(|m| 1.0 / m),
            inv_w2: w2.map(|w2| 1.0 / w2),
        }
    }
}

impl Coefficients {
    /// The coefficients of an instance given in any consistent unit system.
    /// `time_epsilon` is the relative resolution of the time within a
    /// period (f64's epsilon on the CPU; the f32 shader's two-part time
    /// resolves far finer than its own epsilon).
    #[allow(clippy::unnecessary_cast)]
    pub fn new(inst: &Instance, settings: &Settings, time_epsilon: f64) -> Coefficients {
        Coefficients::new_replica(inst, settings, time_epsilon, Replica::NONE)
    }

    /// [`Coefficients::new`] for replica `r` of a split run
    /// ([`Coefficients::of_replica`]).
    pub fn new_replica(
        inst: &Instance,
        settings: &Settings,
        time_epsilon: f64,
        r: Replica,
    ) -> Coefficients {
        let mut c = Coefficients::default();
        c.set_mechanism(inst);
        c.set_drive(inst);
        c.set_steps(inst, settings, time_epsilon);
        c.set_measurement(inst, settings, r);
        (c.first_corner, c.first_corner_lo) = super::drive::first_corner(&c, |x| x);
        c
    }

    /// The stage, the slider and the friction between them: the
    /// oscillators, the mass shares, the load and the holding force.
    fn set_mechanism(&mut self, inst: &Instance) {
        let [ax, ay] = &inst.axes;
        let per_axis = |f: &dyn Fn(&crate::model::Axis) -> f64| Vec2::new(f(ax), f(ay));
        let m = &inst.mechanism;
        let ms = m.slider_mass;
        let fc = m.coulomb_friction;
        let stage_mass = per_axis(&|a| a.stage_mass);
        let stiffness = per_axis(&|a| a.stiffness);
        let damping = per_axis(&|a| a.damping);
        let slip_scale = stage_mass.map(|mp| (mp + ms) / (mp * ms));
        let slip_b = slip_scale * fc;
        // The load per axis, each form +0 at L = 0 whatever the sign of
        // the zero given (`0.0 - x` and `x + 0.0` are +0 for x = -0).
        let load = Vec2::new(m.load[0], m.load[1]);
        let plus_zero = |x: Vec2| x.map(|x| x + 0.0);
        let hold = m.holding_friction();
        let loose = hold - m.load_magnitude();
        *self = Coefficients {
            stiffness,
            damping,
            inv_stiffness: stiffness.map(|k| 1.0 / k),
            stick: Oscillator::new(stage_mass + ms, damping, stiffness),
            slip: Oscillator::new(stage_mass, damping, stiffness),
            stage_share: stage_mass.map(|mp| mp / (mp + ms)),
            slider_share: stage_mass.map(|mp| ms / (mp + ms)),
            slip_scale,
            slip_b,
            load_need: plus_zero(stage_mass.map(|mp| mp / (mp + ms)) * load),
            load_accel: plus_zero(load.map(|l| l / ms)),
            neg_load: load.map(|l| 0.0 - l),
            neg_load_accel: load.map(|l| 0.0 - l / ms),
            slip_b_max: slip_b.max_element().max(0.0),
            hold2: hold * hold,
            safe_hold2: loose.max(0.0) * loose.max(0.0),
            ms2: ms * ms,
            two_ms2: 2.0 * (ms * ms),
            coulomb: fc,
            fc_over_ms: fc / ms,
            band: m.velocity_band,
            band2: m.velocity_band * m.velocity_band,
            frictionless: fc == 0.0,
            ..std::mem::take(self)
        };
    }

    /// The drives and the scene period (the corner clock is set
    /// from these by [`Coefficients::new_replica`]).
    fn set_drive(&mut self, inst: &Instance) {
        let [ax, ay] = &inst.axes;
        let per_axis = |f: &dyn Fn(&crate::model::Axis) -> f64| Vec2::new(f(ax), f(ay));
        let period = inst.period();
        let cycles_per_period = per_axis(&|a| a.frequency * period);
        *self = Coefficients {
            amplitude: per_axis(&|a| {
                if a.is_driven() {
                    a.gain * a.voltage
                } else {
                    0.0
                }
            }),
            frequency: per_axis(&|a| a.frequency),
            segments: [ax, ay].map(super::drive::segments_of),
            phase: per_axis(&|a| a.phase),
            cycles_per_period,
            phase_fixed: [ax.phase, ay.phase].map(fixed_fraction_32),
            cycles_fixed: cycles_per_period
                .to_array()
                .map(|n| (fixed_fraction_64(n) >> 32) as u32),
            cycles_fixed_lo: cycles_per_period
                .to_array()
                .map(|n| fixed_fraction_64(n) as u32),
            driven: [ax.is_driven(), ay.is_driven()],
            period,
            // The corner clock, exact in f64.
            period_lo: 0.0,
            ..std::mem::take(self)
        };
    }

    /// The step lengths, the run's length and its budget of steps, and the
    /// tolerance (after [`Coefficients::set_mechanism`] and
    /// [`Coefficients::set_drive`]).
    fn set_steps(&mut self, inst: &Instance, settings: &Settings, time_epsilon: f64) {
        let event_step = |osc: &Oscillator| {
            EVENT_STEP_PERIODS * 2.0 * std::f64::consts::PI / osc.rate.max_element()
        };
        let budget =
            (settings.max_steps_per_period as u64 * inst.cycles as u64).min(u32::MAX as u64) as u32;
        *self = Coefficients {
            event_step_stuck: event_step(&self.stick),
            event_step_slip: event_step(&self.slip),
            min_step: MIN_STEP_EPSILONS * time_epsilon * self.period,
            cycles: inst.cycles,
            settle: inst.settle,
            tolerance: settings.tolerance,
            collocation_tolerance: COLLOCATION_CONVERGED * settings.tolerance,
            budget,
            ..std::mem::take(self)
        };
    }

    /// The measurement of replica `r`: the common period, the phase
    /// ladder, the batches and the stop rules' tolerances (after
    /// [`Coefficients::set_mechanism`] and [`Coefficients::set_drive`]).
    fn set_measurement(&mut self, inst: &Instance, settings: &Settings, r: Replica) {
        // The floor's, computed from the instance alone (its period and
        // settling are already set, to the same values).
        let g = super::setup::Setup::new(inst, settings, r);
        *self = Coefficients {
            steady: g.steady,
            common_period: g.common_period,
            gaps: g.gaps,
            phase_levels: g.phase_levels,
            phase_lattice: g.phase_lattice,
            replica: g.replica,
            replicas: g.replicas,
            batch_length: g.batch_length,
            min_batch: g.min_batch,
            se_limit2: g.se_limit2,
            repeat_x: g.repeat_x,
            repeat_v: g.repeat_v,
            ..std::mem::take(self)
        };
    }
}

/// The fraction of `u` in units of 2^-32 cycles, rounded (wrapping to 0 at
/// a whole cycle).
pub fn fixed_fraction_32(u: f64) -> u32 {
    ((u - u.floor()) * 4_294_967_296.0).round() as u64 as u32
}

/// The fraction of `u` in units of 2^-64 cycles, truncated.
pub fn fixed_fraction_64(u: f64) -> u64 {
    // Exact scaling by 2^64; the cast saturates below 2^64 for fractions
    // that round up to a whole cycle, an error of 2^-64 cycles.
    ((u - u.floor()) * 18_446_744_073_709_551_616.0) as u64
}
}
