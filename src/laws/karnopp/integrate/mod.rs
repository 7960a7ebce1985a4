//! The event-locating stick-slip integrator: the CPU mirror of the shader in
//! `shaders/karnopp/` (one Rust file per WGSL file, the same function
//! names, the same order of operations). Like the shader it is written for
//! a scalar `Real` and compiled once per precision (`pidm::laws::karnopp::double`,
//! the f64 reference every backend is held to, and `pidm::laws::karnopp::single`,
//! the f32 shader's mirror); the f32 formulation's branches
//! (`COMPENSATED_TIME`, `FIXED_PHASE`, `CORNER_CLOCK`, `DEFLECTION`,
//! `APPROACH_NOISE`) are constants of the precision, as in the shader.
//! Units are those of the precision (SI for f64; the docs below give SI).
//!
//! Each axis' stage is a linear oscillator driven by a force that is affine
//! in time between drive corners. The integrator uses that structure:
//!
//! * STICK: stage and slider move as one body per axis. The motion is
//!   integrated in closed form (particular solution plus the homogeneous
//!   propagator `exp(A tau) = a0 I + a1 A`), so a stick phase costs one step
//!   once its ringing can no longer break the stiction (an energy bound on
//!   the acceleration proves that).
//! * SLIP: the friction force is `f_c u(t)` with `u` the direction of the
//!   relative velocity. Over a step `u` is replaced by the quadratic that
//!   interpolates the true direction at the step's start, middle and end
//!   (found by fixed-point iteration); the stage and slider are then again
//!   integrated in closed form. A fixed direction (1-DOF motion, the
//!   diagonal of equal axes) is therefore integrated exactly, and a turning
//!   direction is resolved by step-size control on the interpolation error,
//!   the one accuracy knob ([`Settings::tolerance`], radians).
//! * BAND: inside the detection band the friction direction is held; the
//!   motion is again exact.
//!
//! Mode changes are found by sampling their event functions at five points
//! of every step (with a Hermite check for dips between samples) and located
//! by safeguarded Newton iteration on the closed-form dense output, to near
//! machine precision. Drive corners and period ends are step boundaries.
//!
//! The code is shaped for the GPU: per-axis values are [`Vec2`]s (never an
//! array indexed by a run-time axis), every per-instance constant is
//! computed once ([`Coefficients`]), every step of every mode runs the same
//! sampling, event and move code ([`step::step`]), one iteration does one
//! bounded piece of work (a rejected slip trial is an iteration of its
//! own), and there is no allocation or recursion.

// Long argument lists mirror the WGSL shader, which has no methods.
#![allow(clippy::too_many_arguments)]

pub mod arith;
pub mod coefficients;
pub mod constants;
pub mod drive;
pub mod events;
pub mod flow;
pub mod step;

// The floor's measurement, phase ladder and Vec2, in this precision.
pub use super::precision::floor::{measure, phase, setup, vec2};

pub use coefficients::Coefficients;
pub use constants::{
    MODE_BAND, MODE_SLIP, MODE_STICK, STATUS_EVENT_STORM, STATUS_NON_FINITE, STATUS_OK,
    STATUS_STEP_BUDGET, STATUS_STEP_UNDERFLOW,
};
pub use measure::{Measure, initial_measure};
pub use vec2::Vec2;

use constants::{
    ITERATION_BOUNDARY, ITERATION_EVENT, ITERATION_PERIOD_END, ITERATION_REJECTED, ITERATION_SLIP,
    ITERATION_STICK, MAX_STALLED_EVENTS,
};
use drive::{corner_time, corner_time_lo, drive_force, frac, pass_boundaries};
use flow::{Flow, Propagator, Sample, eval_at, eval_flow};
use std::sync::atomic::{AtomicU64, Ordering};
use step::StepOutcome;

pub use super::precision::Real;
// The precision module of this instance, for the files below.
use super::precision;
pub use crate::laws::settings::{Replica, Replicas, Settings};

use super::precision::{COMPENSATED_TIME, CORNER_CLOCK, DEFLECTION};
use crate::model::{AXES, Instance};

/// The complete integrator state of one instance. It is everything needed to
/// continue a run, so a run may be cut into slices anywhere between
/// iterations.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    /// Stage positions [m] and velocities [m/s].
    pub x_p: Vec2,
    pub v_p: Vec2,
    /// Slider positions [m] and velocities [m/s].
    pub x_s: Vec2,
    pub v_s: Vec2,
    /// Relative velocity v_p - v_s [m/s], integrated on its own from its
    /// changes: near the band it is far smaller than the two velocities,
    /// and their difference would know it only to their rounding.
    pub v_rel: Vec2,
    /// Friction direction held inside the band (unit vector on the slider).
    pub held: Vec2,
    /// Slider positions when the measured periods began [m].
    pub settle_x_s: Vec2,
    /// Drive phase of each axis at the start of the period [cycles].
    pub cycle_phase: Vec2,
    /// Drive phase of each axis' next corner, on the same scale.
    pub next_corner: Vec2,
    /// Drive corners' local times in two parts, hi + lo [s] (f32 only,
    /// `CORNER_CLOCK`: `drive::CornerClock`; zero in f64).
    pub corner_at: Vec2,
    pub corner_at_lo: Vec2,
    /// Time within the current scene period [s].
    pub time: Real,
    /// The low part of the two-part time (f32 only, `COMPENSATED_TIME`;
    /// zero in f64).
    pub time_lo: Real,
    /// Next trial step in slip [s].
    pub h_slip: Real,
    /// The last accepted slip step that was neither cut by a stop nor
    /// ended at an event [s], and its direction error [rad], for the
    /// step-size controller's prediction (`step::next_slip_step`); 0 where
    /// the slip has none yet.
    pub h_accepted: Real,
    pub err_accepted: Real,
    /// The index of each axis' current drive segment (`drive::Segment`).
    pub segment: [u32; AXES],
    pub mode: u32,
    /// Index of the current scene period.
    pub period: u32,
    pub status: u32,
    /// Steps taken so far (accepted, rejected and events).
    pub steps: u32,
    /// Consecutive events without the time advancing.
    pub stalled: u32,
    /// Slip trials rejected in a row.
    pub rejections: u32,
    /// 1 once a steady measurement is complete (`measure::period_end`); 2
    /// while a replica waits for its group's merge (`measure::VERDICT_WAITING`).
    pub measured: u32,
}

/// A fresh state: everything at rest at zero displacement, in stick, at the
/// start of period 0 (docs/model.md section 4).
pub fn initial_state(c: &Coefficients) -> State {
    let p = c.phase.map(frac);
    let [(sx, cx), (sy, cy)] = [0, 1].map(|i| drive::segment_at(&c.segments[i], p[i]));
    let mut st = State {
        x_p: Vec2::ZERO,
        v_p: Vec2::ZERO,
        x_s: Vec2::ZERO,
        v_s: Vec2::ZERO,
        v_rel: Vec2::ZERO,
        held: Vec2::ZERO,
        settle_x_s: Vec2::ZERO,
        cycle_phase: p,
        next_corner: Vec2::new(cx, cy),
        corner_at: if CORNER_CLOCK {
            c.first_corner
        } else {
            Vec2::ZERO
        },
        corner_at_lo: if CORNER_CLOCK {
            c.first_corner_lo
        } else {
            Vec2::ZERO
        },
        time: 0.0,
        time_lo: 0.0,
        h_slip: 0.0,
        h_accepted: 0.0,
        err_accepted: 0.0,
        segment: [sx, sy],
        mode: MODE_STICK,
        period: 0,
        status: STATUS_OK,
        steps: 0,
        stalled: 0,
        rejections: 0,
        measured: 0,
    };
    if DEFLECTION {
        // At rest at zero: deflected by minus the drive's static motion.
        let (force, slope) = drive_force(c, &st);
        st.x_p = -force * c.inv_stiffness;
        st.v_p = -slope * c.inv_stiffness;
    }
    st
}

/// True once the instance has finished, normally or not.
pub fn is_finished(c: &Coefficients, st: &State) -> bool {
    st.status != STATUS_OK || st.period >= c.cycles || st.measured != 0
}

/// `st.time >= t + t_lo` on two-part times (`t_lo` and the state's
/// `time_lo` are zero but in f32).
pub fn time_reached(st: &State, t: Real, t_lo: Real) -> bool {
    st.time > t || (st.time == t && st.time_lo >= t_lo)
}

// Karnopp's state as the floor's measurement reads it.
mod slider {
    use super::measure::{Slider, slider_by_fields};
    use super::{Real, State, Vec2, time_reached};
    slider_by_fields!(State, time_reached);
}

/// Where a Karnopp run ended or paused: the integrator's state and the
/// measurement's accumulators (unused by a window). Everything above the
/// laws reads its floor record ([`Run::ended`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    pub state: State,
    pub measure: Measure,
}

/// Integrates one instance to the end.
pub fn run_instance(inst: &Instance, settings: &Settings) -> Run {
    run_instance_until(inst, settings, || false).expect("never asked to stop")
}

/// Iterations between two looks at the stop request of
/// [`run_instance_until`]: about a millisecond of integration, and far too
/// many for the look to cost anything measurable.
pub const ITERATIONS_BETWEEN_STOP_CHECKS: u32 = 1 << 14;

/// Integrates one instance to the end, or until `stop` returns true (it is
/// asked every `ITERATIONS_BETWEEN_STOP_CHECKS` iterations), in which
/// case there is no result. Integrating in slices gives the same state bit
/// for bit as integrating in one go: `advance` resumes where it stopped.
pub fn run_instance_until(
    inst: &Instance,
    settings: &Settings,
    stop: impl Fn() -> bool,
) -> Option<Run> {
    let c = Coefficients::of(inst, settings);
    let run = Run {
        state: initial_state(&c),
        measure: initial_measure(&c),
    };
    continue_instance_until(inst, settings, run, stop)
}

/// Integrates one instance to the end from a state it reached, which the
/// f64 shader may have left (see `pidm::gpu::karnopp::layout::double::State`): the
/// shader mirrors this integrator step for step, so the run continues
/// where the GPU stopped. `stop` as in [`run_instance_until`].
pub fn continue_instance_until(
    inst: &Instance,
    settings: &Settings,
    run: Run,
    stop: impl Fn() -> bool,
) -> Option<Run> {
    continue_until(&Coefficients::of(inst, settings), run, stop)
}

/// [`continue_instance_until`] with the instance's coefficients (a
/// replica's, `Coefficients::of_replica`): to its end, or where a replica
/// waits for its group's merge (`measure::VERDICT_WAITING`).
pub fn continue_until(c: &Coefficients, mut run: Run, stop: impl Fn() -> bool) -> Option<Run> {
    while !is_finished(c, &run.state) {
        if stop() {
            return None;
        }
        advance(
            c,
            &mut run.state,
            &mut run.measure,
            ITERATIONS_BETWEEN_STOP_CHECKS,
        );
    }
    Some(run)
}

/// Advances the state by at most `max_iterations` iterations.
pub fn advance(c: &Coefficients, st: &mut State, m: &mut Measure, max_iterations: u32) {
    advance_observed(c, st, m, max_iterations, &mut NoObserver);
}

/// Sees the closed-form motion over every step the integrator takes (CPU
/// only; the shader has no counterpart). An observer reads and never
/// changes the state, so an observed run is the same bit for bit as an
/// unobserved one.
pub trait StepObserver {
    /// Called once per step that moves the state, before it moves: `st` is
    /// the state at the start of the step (period `st.period`, local time
    /// `st.time`), `motion` the motion over the step.
    fn step(&mut self, st: &State, motion: &StepMotion);

    /// Called at every period end the steady measurement processes, right
    /// after it (`measure::period_end`): `m.next_end` is the period that
    /// ended plus one.
    #[inline(always)]
    fn period_end(&mut self, _c: &Coefficients, _st: &State, _m: &Measure) {}
}

/// The observer of plain runs: does nothing, and compiles to nothing.
pub struct NoObserver;

impl StepObserver for NoObserver {
    #[inline(always)]
    fn step(&mut self, _st: &State, _motion: &StepMotion) {}
}

/// The motion over one step, as the integrator's own dense output: the
/// closed-form flow that event location evaluates at interior points.
pub struct StepMotion<'a> {
    flow: &'a Flow,
    /// Step length [s].
    tau: Real,
    /// Local time within the period where the step ends [s].
    end: Real,
    /// The state the step ends in.
    at_end: &'a Sample,
}

impl StepMotion<'_> {
    /// Step length [s].
    pub fn length(&self) -> Real {
        self.tau
    }

    /// Local time within the scene period where the step ends [s] (the
    /// step starts at the observed state's `time`).
    pub fn end(&self) -> Real {
        self.end
    }

    /// Stage and slider positions [m] per axis at `tau` seconds into the
    /// step, 0 <= tau <= [`StepMotion::length`]; at the end exactly the
    /// state the integrator moves to.
    pub fn positions_at(&self, tau: Real) -> ([Real; AXES], [Real; AXES]) {
        if tau >= self.tau {
            return (self.at_end.x_p.to_array(), self.at_end.x_s.to_array());
        }
        let s = eval_at(self.flow, tau.max(0.0));
        (s.x_p.to_array(), s.x_s.to_array())
    }

    /// The motion at `tau` seconds into the step, 0 <= tau <= the length,
    /// given the propagator over `tau` (`flow::propagator`, or composed of
    /// shorter ones by [`StepMotion::compose`]); at the end the state the
    /// integrator moves to.
    pub fn sample(&self, prop: Propagator, tau: Real) -> Sample {
        if tau >= self.tau {
            *self.at_end
        } else {
            eval_flow(self.flow, prop, tau.max(0.0))
        }
    }

    /// The motion at the step's start: the state's positions and
    /// velocities, with the accelerations of its mode (the stage's from
    /// its equation of motion, the slider's from the friction model), no
    /// jerk; the propagator's evaluation at 0 to rounding, without it.
    pub fn start(&self) -> Sample {
        let f = self.flow;
        let a_p = (f.g0 - f.damping * f.v_p - f.stiffness * f.x_p) * f.osc.inv_mass;
        Sample {
            x_p: f.x_p,
            v_p: f.v_p,
            a_p,
            j_p: Vec2::ZERO,
            x_s: f.x_s,
            v_s: f.v_s,
            a_s: if f.stuck { a_p } else { f.slider0 },
            v_rel: f.v_rel,
        }
    }

    /// The propagator over `tau` of the step's oscillators.
    pub fn propagator(&self, tau: Real) -> Propagator {
        flow::propagator(&self.flow.osc, tau)
    }

    /// The propagator over the sum of two times, from theirs.
    pub fn compose(&self, a: Propagator, b: Propagator) -> Propagator {
        flow::compose(&self.flow.osc, a, b)
    }

    /// The fastest rate of the step's oscillators [1/s] (sqrt(k / m) +
    /// 2 sigma, the larger axis'): how fast its motion can turn.
    pub fn rate(&self) -> Real {
        self.flow.osc.rate.max_element()
    }

    /// The step's oscillators: in stick each axis' stage and slider as one
    /// body, the ringing of the stage's velocity about its drift.
    pub fn oscillator(&self) -> &coefficients::Oscillator {
        &self.flow.osc
    }

    /// Whether the slider rides on the stage over the step (stick): its
    /// velocity is then the stage's, a damped oscillation about a drift;
    /// otherwise (slip, band) a polynomial of degree at most 3 in time.
    pub fn stuck(&self) -> bool {
        self.flow.stuck
    }

    /// The stage's drift velocity at `tau`, the particular solution's
    /// [m/s] (f64: `DEFLECTION` off).
    pub fn drift(&self, tau: Real) -> Vec2 {
        self.flow.part1 + 2.0 * self.flow.part2 * tau
    }

    /// The squared amplitude bound of the stage's oscillation about its
    /// drift at `tau`, from the sample `s` there [m^2/s^2]: w^2 + w2 y^2 of
    /// the homogeneous part (y, w), which never grows (its rate of change
    /// is -4 sigma w^2), so |v - drift| stays below its root from `tau`
    /// on (f64: `DEFLECTION` off).
    pub fn ringing_energy(&self, s: &Sample, tau: Real) -> Vec2 {
        let f = self.flow;
        let dy = s.x_p - f.x_p - (f.part1 + f.part2 * tau) * tau;
        let y = f.y0 + dy;
        let w = s.v_p - self.drift(tau);
        w * w + f.osc.w2 * y * y
    }
}

/// [`advance`] with an observer that sees the motion over every step.
/// A steady measurement processes each period end before the iteration
/// that passes it (`measure::period_end`); a window never looks.
pub fn advance_observed<O: StepObserver>(
    c: &Coefficients,
    st: &mut State,
    m: &mut Measure,
    max_iterations: u32,
    observer: &mut O,
) {
    let mut kinds = [0u32; constants::ITERATION_KINDS];
    for _ in 0..max_iterations {
        if is_finished(c, st) {
            break;
        }
        if measure::at_period_end(c, st, m) {
            measure::period_end(c, st, m);
            observer.period_end(c, st, m);
            kinds[ITERATION_PERIOD_END as usize] += 1;
            if is_finished(c, st) {
                break;
            }
        }
        kinds[iterate(c, st, observer) as usize] += 1;
    }
    for (total, k) in ITERATIONS.iter().zip(kinds) {
        if k > 0 {
            total.fetch_add(k as u64, Ordering::Relaxed);
        }
    }
}

/// Iterations of this precision's CPU integrator by kind
/// (`constants::ITERATION_*`, period ends included), over the process:
/// what `--profile` reports of the CPU's work, as the shader's lanes count
/// theirs in their tallies.
pub static ITERATIONS: [AtomicU64; constants::ITERATION_KINDS] =
    [const { AtomicU64::new(0) }; constants::ITERATION_KINDS];

/// The end of the current step interval: the period end or the next drive
/// corner, whichever comes first.
fn stop_time(c: &Coefficients, st: &State) -> (Real, Real) {
    let corners = corner_time(c, st);
    let at = c.period.min(corners.x).min(corners.y);
    let mut lo = 0.0;
    if CORNER_CLOCK {
        // The low part of the stop that ends first (of equal high parts,
        // the earlier one).
        let corners_lo = corner_time_lo(c, st);
        lo = Real::INFINITY;
        if c.period == at {
            lo = c.period_lo;
        }
        if corners.x == at {
            lo = lo.min(corners_lo.x);
        }
        if corners.y == at {
            lo = lo.min(corners_lo.y);
        }
    }
    (at, lo)
}

/// One iteration: passes the boundaries at the current time if any, then
/// (unless the run ended there) takes one step or one rejected slip trial.
/// Returns what it did, one of `constants::ITERATION_*` (counted in
/// [`ITERATIONS`], as the shader's lanes count theirs).
pub fn iterate<O: StepObserver>(c: &Coefficients, st: &mut State, observer: &mut O) -> u32 {
    if st.period == c.settle && st.time == 0.0 && st.time_lo == 0.0 {
        st.settle_x_s = st.x_s;
    }
    let mut stop = stop_time(c, st);
    if time_reached(st, stop.0, stop.1) {
        pass_boundaries(c, st);
        if is_finished(c, st) {
            return ITERATION_BOUNDARY;
        }
        stop = stop_time(c, st);
        if time_reached(st, stop.0, stop.1) {
            return ITERATION_BOUNDARY;
        }
    }
    let h_max = if CORNER_CLOCK {
        (stop.0 - st.time) + (stop.1 - st.time_lo)
    } else if COMPENSATED_TIME {
        (stop.0 - st.time) - st.time_lo
    } else {
        stop.0 - st.time
    };
    let time_before = st.time;
    let time_lo_before = st.time_lo;
    let stuck = st.mode == MODE_STICK;
    let outcome = step::step(c, st, h_max, stop, observer);
    st.steps += 1;
    if outcome != StepOutcome::Rejected || st.status != STATUS_OK {
        if st.time > time_before || (st.time == time_before && st.time_lo > time_lo_before) {
            st.stalled = 0;
        } else {
            st.stalled += 1;
            if st.stalled > MAX_STALLED_EVENTS {
                st.status = STATUS_EVENT_STORM;
            }
        }
    }
    if !state_is_finite(st) {
        st.status = STATUS_NON_FINITE;
    } else if st.steps > c.budget {
        st.status = constants::STATUS_STEP_BUDGET;
    }
    iteration_kind(outcome, stuck)
}

/// The kind of an iteration that took a step ([`constants::ITERATION_STICK`]
/// and the rest), for the lanes' counts.
fn iteration_kind(outcome: StepOutcome, stuck: bool) -> u32 {
    match outcome {
        StepOutcome::Rejected => ITERATION_REJECTED,
        StepOutcome::Located => ITERATION_EVENT,
        StepOutcome::Moved if stuck => ITERATION_STICK,
        StepOutcome::Moved => ITERATION_SLIP,
    }
}

fn state_is_finite(st: &State) -> bool {
    let finite = |v: Vec2| v.x.is_finite() && v.y.is_finite();
    st.time.is_finite()
        && st.h_slip.is_finite()
        && finite(st.x_p)
        && finite(st.v_p)
        && finite(st.x_s)
        && finite(st.v_s)
        && finite(st.v_rel)
}
