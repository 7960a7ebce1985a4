//! The event-locating stick-slip integrator in f64: the CPU mirror of
//! `shaders/integrate.wgsl` and the reference every backend is held to.
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
//!   integrated in closed form. A fixed direction (1-DOF motion, the diagonal
//!   of equal axes) is therefore integrated exactly, and a turning direction
//!   is resolved by step-size control on the interpolation error, the one
//!   accuracy knob ([`Settings::tolerance`], radians).
//! * BAND: inside the detection band the friction direction is held; the
//!   motion is again exact.
//!
//! Mode changes are found by sampling their event functions at five points
//! of every step (with a Hermite check for dips between samples) and located
//! by safeguarded Newton iteration on the closed-form dense output, to near
//! machine precision. Drive corners and period ends are step boundaries.
//!
//! Every function here is written so that it maps one to one onto WGSL: no
//! allocation, no recursion, fixed-size arrays and bounded loops.

// Index loops and long argument lists mirror the WGSL shader, which has no
// iterators, closures or methods on arrays.
#![allow(clippy::needless_range_loop, clippy::too_many_arguments)]

use crate::model::{AXES, Instance};

/// Stick: slider and stage move together.
pub const MODE_STICK: u32 = 0;
/// Slip outside the detection band: friction along the relative velocity.
pub const MODE_SLIP: u32 = 1;
/// Slip inside the detection band: friction along a held direction.
pub const MODE_BAND: u32 = 2;

/// The instance finished normally.
pub const STATUS_OK: u32 = 0;
/// The step budget ([`Settings::max_steps_per_period`]) ran out.
pub const STATUS_STEP_BUDGET: u32 = 1;
/// A non-finite number appeared in the state.
pub const STATUS_NON_FINITE: u32 = 2;
/// The slip step size fell below the time resolution of a period.
pub const STATUS_STEP_UNDERFLOW: u32 = 3;
/// Mode changes kept following each other without time advancing.
pub const STATUS_EVENT_STORM: u32 = 4;

/// Number of Taylor terms of the propagator after scaling to norm <= 1/2:
/// the truncation error is below 0.5^15 / 15! = 2.3e-17.
const TAYLOR_TERMS: u32 = 14;
/// Fraction of the fastest oscillation period spanned by one step while an
/// event is possible: each of the four sample intervals then covers at most
/// 1/16 of a period, so an event function has at most one extremum there.
const EVENT_STEP_PERIODS: f64 = 0.25;
/// Fixed-point iterations of the friction-direction quadratic per slip step.
const COLLOCATION_ITERATIONS: u32 = 4;
/// The iteration stops once the model changes by less than this fraction of
/// the tolerance.
const COLLOCATION_CONVERGED: f64 = 1e-2;
/// Terms of the stage Taylor series on short slip steps (rate * h <= 1):
/// the truncation error is below 1 / 21! = 2e-20.
const TAYLOR_STAGE_TERMS: u32 = 21;
/// Newton iterations for the direction slip starts in (monotone, converges
/// in a handful).
const SLIP_DIRECTION_ITERATIONS: u32 = 40;
/// Rounding noise of an event function, in units of epsilon times the
/// magnitude of its terms.
const EVENT_NOISE: f64 = 16.0;
/// Bisection-guarded Newton iterations when locating an event.
const ROOT_ITERATIONS: u32 = 80;
/// Consecutive events allowed without the time advancing.
const MAX_STALLED_EVENTS: u32 = 64;
/// Step rejections allowed in one slip step.
const MAX_REJECTIONS: u32 = 60;

/// The one accuracy knob and the per-instance work limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Largest deviation, in radians, allowed between the friction direction
    /// and its quadratic model within one slip step. Only a turning friction
    /// direction (genuine 2-DOF slip) is affected; stick, 1-DOF slip and
    /// slip along a fixed direction are integrated exactly. Measured error in
    /// the step maps is about tolerance / 4 micrometres (`pidm accuracy`);
    /// the default 1e-4 keeps every MODEL.md reference case within 3e-5 um.
    pub tolerance: f64,
    /// Steps (accepted or rejected, events included) allowed per scene
    /// period before the instance stops with [`STATUS_STEP_BUDGET`].
    pub max_steps_per_period: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            tolerance: 1e-4,
            max_steps_per_period: 2_000_000,
        }
    }
}

/// The complete integrator state of one instance. It is everything needed to
/// continue a run, so a run may be cut into slices anywhere between steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    /// Stage positions [m] and velocities [m/s].
    pub x_p: [f64; AXES],
    pub v_p: [f64; AXES],
    /// Slider positions [m] and velocities [m/s].
    pub x_s: [f64; AXES],
    pub v_s: [f64; AXES],
    /// Friction direction held inside the band (unit vector on the slider).
    pub held: [f64; AXES],
    /// Slider positions when the measured periods began [m].
    pub settle_x_s: [f64; AXES],
    /// Time within the current scene period [s].
    pub time: f64,
    /// Next trial step in slip [s].
    pub h_slip: f64,
    /// Drive phase of each axis at the start of the period [cycles].
    pub cycle_phase: [f64; AXES],
    /// Drive phase of each axis' next corner, on the same scale.
    pub next_corner: [f64; AXES],
    /// 1 while an axis' drive is on its rise, 0 on its fall.
    pub rising: [u32; AXES],
    pub mode: u32,
    /// Index of the current scene period.
    pub period: u32,
    pub status: u32,
    /// Steps taken so far (accepted, rejected and events).
    pub steps: u32,
    /// Consecutive events without the time advancing.
    pub stalled: u32,
}

/// The exponential of a 2x2 oscillator matrix A = [[0, 1], [-w2, -2 sigma]]
/// over some time tau, stored as exp(A tau) = (1 + a0m1) I + a1 A. Keeping
/// a0 - 1 rather than a0 makes short steps exact at tau = 0 and free of
/// cancellation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Propagator {
    pub a0m1: f64,
    pub a1: f64,
}

/// The propagator over zero time.
pub const IDENTITY: Propagator = Propagator { a0m1: 0.0, a1: 0.0 };

/// An oscillator m x'' + c x' + k x = g, as sigma = c / 2m and w2 = k / m.
#[derive(Clone, Copy, Debug, Default)]
struct Oscillator {
    mass: f64,
    damping: f64,
    stiffness: f64,
    sigma: f64,
    w2: f64,
}

/// The motion of one axis over one step in closed form.
#[derive(Clone, Copy, Debug, Default)]
struct AxisFlow {
    osc: Oscillator,
    /// Particular solution x(tau) = part[0] + part[1] tau + part[2] tau^2.
    part: [f64; 3],
    /// Homogeneous displacement and velocity at tau = 0.
    y0: f64,
    w0: f64,
    x_p0: f64,
    x_s0: f64,
    v_s0: f64,
    /// Slider acceleration polynomial in theta = tau / h (slip only).
    slider_acc: [f64; 3],
    /// Stage force polynomial g0 + g1 tau + g2 tau^2 [N, N/s, N/s^2].
    force: [f64; 3],
    x_p: f64,
    v_p: f64,
    /// True when the stage is evaluated by its Taylor series in tau rather
    /// than particular solution plus propagator: on short steps the
    /// particular solution of a steep force polynomial cancels badly.
    taylor: bool,
}

/// The motion of both axes over one step.
#[derive(Clone, Copy, Debug, Default)]
struct Flow {
    axes: [AxisFlow; AXES],
    /// True in stick: the slider rides on the stage.
    stuck: bool,
    /// Step length the slider polynomial is scaled to [s].
    h: f64,
}

/// The state at one instant of a step, with the derivatives event functions
/// need.
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    x_p: [f64; AXES],
    v_p: [f64; AXES],
    a_p: [f64; AXES],
    j_p: [f64; AXES],
    x_s: [f64; AXES],
    v_s: [f64; AXES],
    a_s: [f64; AXES],
}

/// Fractions of a step at which every step is sampled.
const THETA: [f64; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];

/// A fresh state: everything at rest at zero displacement, in stick, at the
/// start of period 0 (MODEL.md section 4).
pub fn initial_state(inst: &Instance) -> State {
    let mut st = State {
        x_p: [0.0; AXES],
        v_p: [0.0; AXES],
        x_s: [0.0; AXES],
        v_s: [0.0; AXES],
        held: [0.0; AXES],
        settle_x_s: [0.0; AXES],
        time: 0.0,
        h_slip: 0.0,
        cycle_phase: [0.0; AXES],
        next_corner: [0.0; AXES],
        rising: [1; AXES],
        mode: MODE_STICK,
        period: 0,
        status: STATUS_OK,
        steps: 0,
        stalled: 0,
    };
    for i in 0..AXES {
        let axis = &inst.axes[i];
        let p = frac(axis.phase);
        st.cycle_phase[i] = p;
        if p < axis.duty {
            st.rising[i] = 1;
            st.next_corner[i] = axis.duty;
        } else {
            st.rising[i] = 0;
            st.next_corner[i] = 1.0;
        }
    }
    st
}

/// True once the instance has finished, normally or not.
pub fn is_finished(inst: &Instance, st: &State) -> bool {
    st.status != STATUS_OK || st.period >= inst.cycles
}

/// Integrates one instance to the end and returns its final state.
pub fn run_instance(inst: &Instance, settings: &Settings) -> State {
    let mut st = initial_state(inst);
    while !is_finished(inst, &st) {
        advance(inst, settings, &mut st, u32::MAX);
    }
    st
}

/// Slider displacement over the measured periods [m], or zero where the
/// instance did not finish normally (its status says why).
pub fn displacement(inst: &Instance, st: &State) -> [f64; AXES] {
    let mut d = [0.0; AXES];
    if st.status == STATUS_OK && st.period >= inst.cycles {
        for i in 0..AXES {
            d[i] = st.x_s[i] - st.settle_x_s[i];
        }
    }
    d
}

/// Advances the state by at most `max_iterations` steps, corners and events.
pub fn advance(inst: &Instance, settings: &Settings, st: &mut State, max_iterations: u32) {
    advance_observed(inst, settings, st, max_iterations, &mut NoObserver);
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
    tau: f64,
    /// Local time within the period where the step ends [s].
    end: f64,
    /// The state the step ends in.
    at_end: &'a Sample,
}

impl StepMotion<'_> {
    /// Step length [s].
    pub fn length(&self) -> f64 {
        self.tau
    }

    /// Local time within the scene period where the step ends [s] (the
    /// step starts at the observed state's `time`).
    pub fn end(&self) -> f64 {
        self.end
    }

    /// Stage and slider positions [m] per axis at `tau` seconds into the
    /// step, 0 <= tau <= [`StepMotion::length`]; at the end exactly the
    /// state the integrator moves to.
    pub fn positions_at(&self, tau: f64) -> ([f64; AXES], [f64; AXES]) {
        if tau >= self.tau {
            return (self.at_end.x_p, self.at_end.x_s);
        }
        let s = eval_at(self.flow, tau.max(0.0));
        (s.x_p, s.x_s)
    }
}

/// [`advance`] with an observer that sees the motion over every step.
pub fn advance_observed<O: StepObserver>(
    inst: &Instance,
    settings: &Settings,
    st: &mut State,
    max_iterations: u32,
    observer: &mut O,
) {
    let period = inst.period();
    let budget = (settings.max_steps_per_period as u64) * (inst.cycles as u64);
    let mut iteration = 0;
    while iteration < max_iterations {
        iteration += 1;
        if is_finished(inst, st) {
            return;
        }
        if st.period == inst.settle && st.time == 0.0 {
            st.settle_x_s = st.x_s;
        }
        let mut stop = period;
        for i in 0..AXES {
            stop = stop.min(corner_time(inst, st, i));
        }
        if st.time >= stop {
            pass_boundaries(inst, st, period);
            continue;
        }
        let h_max = stop - st.time;
        let time_before = st.time;
        match st.mode {
            MODE_STICK => step_stick(inst, st, h_max, stop, observer),
            MODE_SLIP => step_slip(inst, settings, st, h_max, stop, period, observer),
            _ => step_band(inst, st, h_max, stop, observer),
        }
        st.steps += 1;
        if st.time > time_before {
            st.stalled = 0;
        } else {
            st.stalled += 1;
            if st.stalled > MAX_STALLED_EVENTS {
                st.status = STATUS_EVENT_STORM;
            }
        }
        if !state_is_finite(st) {
            st.status = STATUS_NON_FINITE;
        } else if st.steps as u64 > budget {
            st.status = STATUS_STEP_BUDGET;
        }
    }
}

fn frac(u: f64) -> f64 {
    u - u.floor()
}

/// Local time of axis `i`'s next drive corner, or infinity when undriven.
fn corner_time(inst: &Instance, st: &State, i: usize) -> f64 {
    let axis = &inst.axes[i];
    if !axis.is_driven() {
        return f64::INFINITY;
    }
    ((st.next_corner[i] - st.cycle_phase[i]) / axis.frequency).max(0.0)
}

/// Drive force of axis `i` at the current time and its slope [N, N/s].
fn drive_force(inst: &Instance, st: &State, i: usize) -> (f64, f64) {
    let axis = &inst.axes[i];
    if !axis.is_driven() {
        return (0.0, 0.0);
    }
    let amplitude = axis.gain * axis.voltage;
    let u = st.cycle_phase[i] + axis.frequency * st.time;
    let to_corner = (st.next_corner[i] - u).max(0.0);
    if st.rising[i] == 1 {
        let w = 1.0 - to_corner / axis.duty;
        (amplitude * w, amplitude * axis.frequency / axis.duty)
    } else {
        let w = to_corner / (1.0 - axis.duty);
        (
            amplitude * w,
            -amplitude * axis.frequency / (1.0 - axis.duty),
        )
    }
}

/// Passes every drive corner and the period end that lie at the current
/// time, then lets a stuck slider break loose if a jump of the drive (duty 1)
/// demands it.
fn pass_boundaries(inst: &Instance, st: &mut State, period: f64) {
    for i in 0..AXES {
        if corner_time(inst, st, i) <= st.time {
            let duty = inst.axes[i].duty;
            if duty >= 1.0 {
                st.next_corner[i] += 1.0;
            } else if st.rising[i] == 1 {
                st.rising[i] = 0;
                st.next_corner[i] += 1.0 - duty;
            } else {
                st.rising[i] = 1;
                st.next_corner[i] += duty;
            }
        }
    }
    if st.time >= period {
        st.period += 1;
        st.time = 0.0;
        for i in 0..AXES {
            let axis = &inst.axes[i];
            let end_phase = st.cycle_phase[i] + axis.frequency * period;
            let start_phase = frac(axis.phase + (st.period as f64) * (axis.frequency * period));
            let shift = (end_phase - start_phase).round();
            st.cycle_phase[i] = start_phase;
            st.next_corner[i] -= shift;
        }
        if st.period == inst.settle {
            st.settle_x_s = st.x_s;
        }
    }
    if st.mode == MODE_STICK {
        let need = stick_force(inst, st);
        let hold = inst.mechanism.holding_friction();
        if norm2(need) > hold * hold {
            start_slip(inst, st, need);
        }
    }
}

/// The exponential of the oscillator matrix over `tau`, by Taylor series
/// after scaling the norm to at most 1/2, then repeated squaring.
pub fn propagator(sigma: f64, w2: f64, tau: f64) -> Propagator {
    let mut scale = tau * (w2.sqrt() + 2.0 * sigma);
    let mut t = tau;
    let mut squarings = 0;
    while scale > 0.5 && squarings < 200 {
        scale *= 0.5;
        t *= 0.5;
        squarings += 1;
    }
    // Term n of the series is t^n / n! A^n = p I + q A; A^2 = -w2 I - 2 sigma A.
    let mut p = 1.0;
    let mut q = 0.0;
    let mut a0m1 = 0.0;
    let mut a1 = 0.0;
    for n in 1..=TAYLOR_TERMS {
        let f = t / n as f64;
        let next_p = -w2 * q * f;
        let next_q = (p - 2.0 * sigma * q) * f;
        p = next_p;
        q = next_q;
        a0m1 += p;
        a1 += q;
    }
    let mut prop = Propagator { a0m1, a1 };
    for _ in 0..squarings {
        prop = compose(sigma, w2, prop, prop);
    }
    prop
}

/// The product of two propagators of the same oscillator.
fn compose(sigma: f64, w2: f64, a: Propagator, b: Propagator) -> Propagator {
    // (1 + a) (1 + b) - 1 = a + b + a b for the identity parts.
    let ab = a.a1 * b.a1;
    Propagator {
        a0m1: a.a0m1 + b.a0m1 + a.a0m1 * b.a0m1 - w2 * ab,
        a1: a.a1 + b.a1 + a.a0m1 * b.a1 + a.a1 * b.a0m1 - 2.0 * sigma * ab,
    }
}

fn oscillator(mass: f64, damping: f64, stiffness: f64) -> Oscillator {
    Oscillator {
        mass,
        damping,
        stiffness,
        sigma: damping / (2.0 * mass),
        w2: stiffness / mass,
    }
}

/// The oscillator of axis `i` in a mode: the stage alone in slip, stage and
/// slider together in stick.
fn axis_oscillator(inst: &Instance, i: usize, stuck: bool) -> Oscillator {
    let axis = &inst.axes[i];
    let mass = if stuck {
        axis.stage_mass + inst.mechanism.slider_mass
    } else {
        axis.stage_mass
    };
    oscillator(mass, axis.damping, axis.stiffness)
}

/// Step length that samples the fastest oscillation of a mode densely
/// enough for event detection [s].
fn event_step(inst: &Instance, stuck: bool) -> f64 {
    let mut rate: f64 = 0.0;
    for i in 0..AXES {
        let osc = axis_oscillator(inst, i, stuck);
        rate = rate.max(osc.w2.sqrt() + 2.0 * osc.sigma);
    }
    EVENT_STEP_PERIODS * 2.0 * std::f64::consts::PI / rate
}

/// Sets up the closed-form motion of one axis from the current state under a
/// stage force g0 + g1 tau + g2 tau^2 and, in slip, a slider acceleration
/// polynomial in theta = tau / h.
fn axis_flow(osc: Oscillator, g: [f64; 3], x_p: f64, v_p: f64, x_s: f64, v_s: f64) -> AxisFlow {
    // Polynomial particular solution of m x'' + c x' + k x = g.
    let x2 = g[2] / osc.stiffness;
    let x1 = (g[1] - 2.0 * osc.damping * x2) / osc.stiffness;
    let x0 = (g[0] - osc.damping * x1 - 2.0 * osc.mass * x2) / osc.stiffness;
    AxisFlow {
        osc,
        part: [x0, x1, x2],
        y0: x_p - x0,
        w0: v_p - x1,
        x_p0: x_p,
        x_s0: x_s,
        v_s0: v_s,
        slider_acc: [0.0; 3],
        force: g,
        x_p,
        v_p,
        taylor: false,
    }
}

/// Evaluates one axis at tau with the propagator for tau; returns stage
/// (x, v, a, jerk).
fn eval_stage(f: &AxisFlow, prop: Propagator, tau: f64) -> (f64, f64, f64, f64) {
    if f.taylor {
        return eval_stage_taylor(f, tau);
    }
    let o = &f.osc;
    // Changes of the homogeneous part since tau = 0, then the state as the
    // start value plus changes, so tau = 0 reproduces the start exactly.
    let dy = prop.a0m1 * f.y0 + prop.a1 * f.w0;
    let dw = prop.a0m1 * f.w0 + prop.a1 * (-o.w2 * f.y0 - 2.0 * o.sigma * f.w0);
    let y = f.y0 + dy;
    let w = f.w0 + dw;
    let a_h = -o.w2 * y - 2.0 * o.sigma * w;
    let j_h = -o.w2 * w - 2.0 * o.sigma * a_h;
    let x = f.x_p + (f.part[1] + f.part[2] * tau) * tau + dy;
    let v = f.v_p + 2.0 * f.part[2] * tau + dw;
    let a = 2.0 * f.part[2] + a_h;
    (x, v, a, j_h)
}

/// Evaluates one axis at tau by the Taylor series of the exact solution,
/// with derivatives from m x'' = g - c x' - k x. Valid and accurate to
/// rounding for rate * tau <= 1 ([`TAYLOR_STAGE_TERMS`] terms).
fn eval_stage_taylor(f: &AxisFlow, tau: f64) -> (f64, f64, f64, f64) {
    let o = &f.osc;
    let inv_m = 1.0 / o.mass;
    // Sliding window of derivatives d[n..n+3] and the force derivatives.
    let mut d0 = f.x_p;
    let mut d1 = f.v_p;
    let mut d2 = (f.force[0] - o.damping * d1 - o.stiffness * d0) * inv_m;
    let mut d3 = (f.force[1] - o.damping * d2 - o.stiffness * d1) * inv_m;
    let mut t = 1.0;
    // The n-th term is bounded by (rate tau)^n / n! times the state's scale.
    let rate_tau = (o.w2.sqrt() + 2.0 * o.sigma) * tau;
    let mut bound = 1.0;
    let (mut x, mut v, mut a, mut j) = (0.0, 0.0, 0.0, 0.0);
    for n in 0..TAYLOR_STAGE_TERMS {
        if n >= 3 && bound < 1e-18 {
            break;
        }
        bound *= rate_tau / (n + 1) as f64;
        x += d0 * t;
        v += d1 * t;
        a += d2 * t;
        j += d3 * t;
        // g^(n+2)(0): 2 g2 for n = 0, zero after.
        let g = if n == 0 { 2.0 * f.force[2] } else { 0.0 };
        let d4 = (g - o.damping * d3 - o.stiffness * d2) * inv_m;
        d0 = d1;
        d1 = d2;
        d2 = d3;
        d3 = d4;
        t *= tau / (n + 1) as f64;
    }
    (x, v, a, j)
}

/// Evaluates the flow at tau, given each axis' propagator for tau.
fn eval_flow(flow: &Flow, props: [Propagator; AXES], tau: f64) -> Sample {
    let mut s = Sample::default();
    for i in 0..AXES {
        let f = &flow.axes[i];
        let (x, v, a, j) = eval_stage(f, props[i], tau);
        s.x_p[i] = x;
        s.v_p[i] = v;
        s.a_p[i] = a;
        s.j_p[i] = j;
        if flow.stuck {
            s.x_s[i] = f.x_s0 + (x - f.x_p0);
            s.v_s[i] = v;
            s.a_s[i] = a;
        } else {
            let th = tau / flow.h;
            let c = f.slider_acc;
            let h = flow.h;
            s.a_s[i] = c[0] + (c[1] + c[2] * th) * th;
            s.v_s[i] = f.v_s0 + h * th * (c[0] + th * (c[1] / 2.0 + th * c[2] / 3.0));
            s.x_s[i] = f.x_s0
                + f.v_s0 * tau
                + h * h * th * th * (c[0] / 2.0 + th * (c[1] / 6.0 + th * c[2] / 12.0));
        }
    }
    s
}

/// Evaluates the flow at an arbitrary tau (dense output).
fn eval_at(flow: &Flow, tau: f64) -> Sample {
    let mut props = [Propagator::default(); AXES];
    for i in 0..AXES {
        let o = &flow.axes[i].osc;
        props[i] = propagator(o.sigma, o.w2, tau);
    }
    eval_flow(flow, props, tau)
}

/// Propagators of every axis at the five sample points of a step of length h.
fn sample_propagators(flow: &Flow, h: f64) -> [[Propagator; AXES]; 5] {
    let mut out = [[IDENTITY; AXES]; 5];
    for i in 0..AXES {
        let o = &flow.axes[i].osc;
        let quarter = propagator(o.sigma, o.w2, 0.25 * h);
        let half = compose(o.sigma, o.w2, quarter, quarter);
        out[1][i] = quarter;
        out[2][i] = half;
        out[3][i] = compose(o.sigma, o.w2, half, quarter);
        out[4][i] = compose(o.sigma, o.w2, half, half);
    }
    out
}

/// Builds the stick flow from the current state.
fn stick_flow(inst: &Instance, st: &State, force: [[f64; 2]; AXES]) -> Flow {
    let mut flow = Flow {
        stuck: true,
        h: 1.0,
        ..Flow::default()
    };
    for i in 0..AXES {
        let osc = axis_oscillator(inst, i, true);
        flow.axes[i] = axis_flow(
            osc,
            [force[i][0], force[i][1], 0.0],
            st.x_p[i],
            st.v_p[i],
            st.x_s[i],
            st.v_s[i],
        );
    }
    flow
}

/// Builds the slip flow of a step of length h with the friction direction
/// on the slider modelled as u(theta) = b[0] + b[1] theta + b[2] theta^2.
fn slip_flow(
    inst: &Instance,
    st: &State,
    force: [[f64; 2]; AXES],
    b: [[f64; 3]; AXES],
    h: f64,
) -> Flow {
    let mut flow = Flow {
        stuck: false,
        h,
        ..Flow::default()
    };
    let fc = inst.mechanism.coulomb_friction;
    let ms = inst.mechanism.slider_mass;
    for i in 0..AXES {
        let osc = axis_oscillator(inst, i, false);
        let g = [
            force[i][0] - fc * b[i][0],
            force[i][1] - fc * b[i][1] / h,
            -fc * b[i][2] / (h * h),
        ];
        let mut f = axis_flow(osc, g, st.x_p[i], st.v_p[i], st.x_s[i], st.v_s[i]);
        f.taylor =
            (b[i][1] != 0.0 || b[i][2] != 0.0) && (osc.w2.sqrt() + 2.0 * osc.sigma) * h <= 1.0;
        f.slider_acc = [fc / ms * b[i][0], fc / ms * b[i][1], fc / ms * b[i][2]];
        flow.axes[i] = f;
    }
    flow
}

fn current_force(inst: &Instance, st: &State) -> [[f64; 2]; AXES] {
    let mut force = [[0.0; 2]; AXES];
    for (i, f) in force.iter_mut().enumerate() {
        let (value, slope) = drive_force(inst, st, i);
        *f = [value, slope];
    }
    force
}

fn norm2(v: [f64; AXES]) -> f64 {
    let mut s = 0.0;
    for x in v {
        s += x * x;
    }
    s
}

fn dot(a: [f64; AXES], b: [f64; AXES]) -> f64 {
    let mut s = 0.0;
    for i in 0..AXES {
        s += a[i] * b[i];
    }
    s
}

fn relative_velocity(s: &Sample) -> [f64; AXES] {
    let mut v = [0.0; AXES];
    for i in 0..AXES {
        v[i] = s.v_p[i] - s.v_s[i];
    }
    v
}

fn relative_acceleration(s: &Sample) -> [f64; AXES] {
    let mut a = [0.0; AXES];
    for i in 0..AXES {
        a[i] = s.a_p[i] - s.a_s[i];
    }
    a
}

/// The static friction force on the slider that stick would need now, with
/// both bodies at their common (momentum-conserving) velocity.
fn stick_force(inst: &Instance, st: &State) -> [f64; AXES] {
    let ms = inst.mechanism.slider_mass;
    let mut need = [0.0; AXES];
    for (i, n) in need.iter_mut().enumerate() {
        let axis = &inst.axes[i];
        let (force, _) = drive_force(inst, st, i);
        let mp = axis.stage_mass;
        let v = (mp * st.v_p[i] + ms * st.v_s[i]) / (mp + ms);
        let p = force - axis.damping * v - axis.stiffness * st.x_p[i];
        *n = ms * p / (mp + ms);
    }
    need
}

/// The direction in which slip grows out of zero relative velocity. In
/// slip the relative acceleration is A - B u per axis, with A_i = P_i / m_p,i
/// and B_i = f_c (1 / m_p,i + 1 / m_s), so the friction direction u is
/// consistent only where A - B u = lambda u with lambda > 0:
/// u_i = A_i / (lambda + B_i) with sum_i A_i^2 / (lambda + B_i)^2 = 1. That
/// root exists exactly when |f_need| > f_c. With equal stage masses B is the
/// same on both axes and u is the direction of f_need (MODEL.md section 3);
/// with unequal ones, slip along f_need itself would turn the relative
/// velocity away from the friction and chatter at the band edge.
fn slip_direction(inst: &Instance, need: [f64; AXES]) -> [f64; AXES] {
    let ms = inst.mechanism.slider_mass;
    let fc = inst.mechanism.coulomb_friction;
    let mut a = [0.0; AXES];
    let mut b = [0.0; AXES];
    let mut b_max: f64 = 0.0;
    for i in 0..AXES {
        let mp = inst.axes[i].stage_mass;
        let scale = (mp + ms) / (mp * ms);
        a[i] = need[i] * scale;
        b[i] = fc * scale;
        b_max = b_max.max(b[i]);
    }
    // g(lambda) = sum A^2 / (lambda + B)^2 - 1 is convex and decreasing, and
    // g >= 0 at max(0, |A| - max B): Newton from there rises monotonically
    // to the root.
    let mut lambda = (norm2(a).sqrt() - b_max).max(0.0);
    for _ in 0..SLIP_DIRECTION_ITERATIONS {
        let mut g = -1.0;
        let mut dg = 0.0;
        for i in 0..AXES {
            let d = lambda + b[i];
            let q = a[i] * a[i] / (d * d);
            g += q;
            dg -= 2.0 * q / d;
        }
        // Stops at the root, and on NaN (no comparison holds).
        if g.is_nan() || g <= 0.0 || dg == 0.0 {
            break;
        }
        let next = lambda - g / dg;
        if next.is_nan() || next <= lambda {
            break;
        }
        lambda = next;
    }
    let mut u = [0.0; AXES];
    for i in 0..AXES {
        u[i] = a[i] / (lambda + b[i]);
    }
    // Normalise away the last rounding; fall back to f_need's direction if
    // the iteration met a degenerate case.
    let n = norm2(u).sqrt();
    if n > 0.0 && n.is_finite() {
        for i in 0..AXES {
            u[i] /= n;
        }
    } else {
        let m = norm2(need).sqrt();
        for i in 0..AXES {
            u[i] = need[i] / m;
        }
    }
    u
}

/// STICK -> SLIP: enters the band at zero relative velocity with the
/// friction held along the direction slip grows in.
fn start_slip(inst: &Instance, st: &mut State, need: [f64; AXES]) {
    st.held = slip_direction(inst, need);
    st.mode = MODE_BAND;
}

/// At a relative velocity inside the band the two bodies' velocities merge
/// per axis, conserving momentum (a change of at most the band a). Then they
/// stick if the static friction can hold them, or else slip starts afresh
/// along the needed force, exactly as a breakaway from stick does (in 1-D:
/// the slider reverses). Starting the new slip from zero relative velocity
/// keeps the relative velocity aligned with the friction when it leaves the
/// band; holding the old, misaligned relative velocity would make it
/// re-enter the band at once, over and over.
fn try_stick(inst: &Instance, st: &mut State) {
    let need = stick_force(inst, st);
    let fs = inst.mechanism.holding_friction();
    let ms = inst.mechanism.slider_mass;
    for i in 0..AXES {
        let mp = inst.axes[i].stage_mass;
        let v = (mp * st.v_p[i] + ms * st.v_s[i]) / (mp + ms);
        st.v_p[i] = v;
        st.v_s[i] = v;
    }
    if norm2(need) <= fs * fs {
        st.mode = MODE_STICK;
    } else {
        start_slip(inst, st, need);
    }
}

fn set_sample(st: &mut State, s: &Sample) {
    st.x_p = s.x_p;
    st.v_p = s.v_p;
    st.x_s = s.x_s;
    st.v_s = s.v_s;
}

fn state_is_finite(st: &State) -> bool {
    let mut ok = st.time.is_finite() && st.h_slip.is_finite();
    for i in 0..AXES {
        ok = ok
            && st.x_p[i].is_finite()
            && st.v_p[i].is_finite()
            && st.x_s[i].is_finite()
            && st.v_s[i].is_finite();
    }
    ok
}

/// Which event function a step watches. Each is positive before its event
/// and crosses to zero or below at it.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum EventKind {
    /// Stick breaks: f_s^2 - |f_need|^2.
    Breakaway,
    /// Slip enters the band: |v_rel|^2 - a^2.
    EnterBand,
    /// Band slip leaves the band: a^2 - |v_rel|^2.
    LeaveBand,
    /// The relative velocity reverses against the held direction:
    /// sign * v_rel . held.
    Reversal,
}

/// Value and time derivative of an event function at a sample.
fn event_value(inst: &Instance, st: &State, kind: EventKind, sign: f64, s: &Sample) -> (f64, f64) {
    let m = &inst.mechanism;
    match kind {
        EventKind::Breakaway => {
            let ms2 = m.slider_mass * m.slider_mass;
            let hold = m.holding_friction();
            let e = hold * hold - ms2 * norm2(s.a_p);
            (e, -2.0 * ms2 * dot(s.a_p, s.j_p))
        }
        EventKind::EnterBand => {
            let v = relative_velocity(s);
            let a = relative_acceleration(s);
            (
                norm2(v) - m.velocity_band * m.velocity_band,
                2.0 * dot(v, a),
            )
        }
        EventKind::LeaveBand => {
            let v = relative_velocity(s);
            let a = relative_acceleration(s);
            (
                m.velocity_band * m.velocity_band - norm2(v),
                -2.0 * dot(v, a),
            )
        }
        EventKind::Reversal => {
            let v = relative_velocity(s);
            let a = relative_acceleration(s);
            (sign * dot(v, st.held), sign * dot(a, st.held))
        }
    }
}

/// The magnitude of the terms an event function is the difference of, for
/// its rounding noise.
fn event_scale(inst: &Instance, st: &State, kind: EventKind, s: &Sample) -> f64 {
    let m = &inst.mechanism;
    match kind {
        EventKind::Breakaway => {
            // The stage acceleration is the small difference of the drive,
            // spring and damper forces, so its rounding is relative to
            // those forces, not to itself.
            let hold = m.holding_friction();
            let mut scale = hold * hold;
            for i in 0..AXES {
                let axis = &inst.axes[i];
                let forces = axis.stiffness * s.x_p[i].abs() + axis.damping * s.v_p[i].abs();
                let terms = s.a_p[i].abs() + 2.0 * forces / (axis.stage_mass + m.slider_mass);
                scale += m.slider_mass * m.slider_mass * 2.0 * s.a_p[i].abs() * terms;
            }
            scale
        }
        EventKind::EnterBand | EventKind::LeaveBand => {
            // The relative velocity is a difference of two velocities that
            // are often far larger (a slider sliding with its stage), so
            // its rounding is relative to those, not to itself.
            let v = relative_velocity(s);
            let mut scale = m.velocity_band * m.velocity_band;
            for i in 0..AXES {
                scale += 2.0 * v[i].abs() * (s.v_p[i].abs() + s.v_s[i].abs());
            }
            scale
        }
        EventKind::Reversal => {
            let mut scale = 0.0;
            for i in 0..AXES {
                scale += (s.v_p[i].abs() + s.v_s[i].abs()) * st.held[i].abs();
            }
            scale
        }
    }
}

/// Finds the first crossing of an event function among the samples of a
/// step. Returns the bracket (lo, hi) in step time, with the function
/// positive at lo and not positive at hi, or None.
fn find_crossing(
    inst: &Instance,
    st: &State,
    kind: EventKind,
    sign: f64,
    flow: &Flow,
    samples: &[Sample; 5],
    h: f64,
) -> Option<(f64, f64)> {
    let mut prev = event_value(inst, st, kind, sign, &samples[0]);
    // A function already past its event when the step starts fires at once;
    // one at it, within the rounding noise of its evaluation, is armed for
    // the first interval. The noise margin keeps a decision taken at the
    // root of the previous event (the function is then zero up to
    // rounding) from depending on the last bit, which differs between
    // backends that fuse multiply-adds differently.
    let noise = EVENT_NOISE * f64::EPSILON * event_scale(inst, st, kind, &samples[0]);
    if prev.0 < -noise {
        return Some((0.0, 0.0));
    }
    for j in 0..4 {
        let next = event_value(inst, st, kind, sign, &samples[j + 1]);
        let lo = THETA[j] * h;
        let hi = THETA[j + 1] * h;
        let armed = prev.0 > 0.0 || j == 0;
        if armed && next.0 <= 0.0 && (prev.0 > 0.0 || next.0 < 0.0) {
            return Some((lo, hi));
        }
        if prev.0 > 0.0 && next.0 > 0.0 && prev.1 < 0.0 && next.1 > 0.0 {
            // A dip between samples: locate the minimum of the Hermite cubic
            // through both ends and test the true function there.
            let tau = hermite_minimum(prev, next, hi - lo);
            let (e, _) = event_value(inst, st, kind, sign, &eval_at(flow, lo + tau));
            if e <= 0.0 {
                return Some((lo, lo + tau));
            }
        }
        prev = next;
    }
    None
}

/// Position of the minimum of the cubic Hermite interpolant of (value,
/// slope) pairs at 0 and len, given a negative slope at 0 and a positive one
/// at len.
fn hermite_minimum(a: (f64, f64), b: (f64, f64), len: f64) -> f64 {
    // p(s) = a + a' s + c2 s^2 + c3 s^3 on [0, len].
    let d = (b.0 - a.0) / len;
    let c2 = (3.0 * d - 2.0 * a.1 - b.1) / len;
    let c3 = (a.1 + b.1 - 2.0 * d) / (len * len);
    // p'(s) = a' + 2 c2 s + 3 c3 s^2 = 0; the root where p' goes from - to +.
    let qa = 3.0 * c3;
    let qb = 2.0 * c2;
    let qc = a.1;
    let s = if qa.abs() < 1e-300 || (qa * len).abs() < 1e-12 * qb.abs() {
        -qc / qb
    } else {
        let disc = (qb * qb - 4.0 * qa * qc).max(0.0).sqrt();
        // Stable quadratic roots; pick the one in (0, len) with p'' > 0.
        let r = -0.5 * (qb + qb.signum() * disc);
        let r1 = r / qa;
        let r2 = if r != 0.0 { qc / r } else { r1 };
        let good = |s: f64| s > 0.0 && s < len && (qb + 2.0 * qa * s) > 0.0;
        if good(r1) {
            r1
        } else if good(r2) {
            r2
        } else {
            0.5 * len
        }
    };
    s.clamp(0.0, len)
}

/// Locates an event in (lo, hi) by bisection-guarded Newton iteration and
/// returns the step time just past the crossing.
fn locate(
    inst: &Instance,
    st: &State,
    kind: EventKind,
    sign: f64,
    flow: &Flow,
    mut lo: f64,
    mut hi: f64,
    period: f64,
) -> f64 {
    let resolution = 4.0 * f64::EPSILON * period;
    let mut tau = 0.5 * (lo + hi);
    for _ in 0..ROOT_ITERATIONS {
        if hi - lo <= resolution {
            break;
        }
        let (e, de) = event_value(inst, st, kind, sign, &eval_at(flow, tau));
        if e > 0.0 {
            lo = tau;
        } else {
            hi = tau;
        }
        let newton = tau - e / de;
        tau = if newton > lo && newton < hi && de != 0.0 {
            newton
        } else {
            0.5 * (lo + hi)
        };
        // Keep Newton from creeping toward one end of the bracket.
        let margin = 1e-3 * (hi - lo);
        if tau - lo < margin || hi - tau < margin {
            tau = tau.clamp(lo + margin, hi - margin);
        }
    }
    hi
}

/// Samples a flow at the five points of a step.
fn sample_step(flow: &Flow, h: f64) -> [Sample; 5] {
    let props = sample_propagators(flow, h);
    let mut out = [Sample::default(); 5];
    for j in 0..5 {
        out[j] = eval_flow(flow, props[j], THETA[j] * h);
    }
    out
}

/// Moves the state to tau within the current step of flow `flow` (tau ==
/// h_max lands exactly on the stop), showing the observer the motion first.
fn move_to<O: StepObserver>(
    st: &mut State,
    s: &Sample,
    tau: f64,
    h_max: f64,
    stop: f64,
    flow: &Flow,
    observer: &mut O,
) {
    let end = if tau >= h_max { stop } else { st.time + tau };
    let motion = StepMotion {
        flow,
        tau,
        end,
        at_end: s,
    };
    observer.step(st, &motion);
    set_sample(st, s);
    if tau >= h_max {
        st.time = stop;
    } else {
        st.time += tau;
    }
}

/// One STICK step: straight to the stop when the energy bound shows the
/// stiction cannot break before it, otherwise a sampled sub-step.
fn step_stick<O: StepObserver>(
    inst: &Instance,
    st: &mut State,
    h_max: f64,
    stop: f64,
    observer: &mut O,
) {
    let force = current_force(inst, st);
    let flow = stick_flow(inst, st, force);
    let m = &inst.mechanism;
    // The homogeneous acceleration obeys the same oscillator equation, so
    // m a'' + c a' + k a = 0 and k a^2 + m a'^2 never grows: |a| stays below
    // sqrt(a^2 + a'^2 / w2) for the rest of the segment.
    let s0 = eval_flow(&flow, [IDENTITY; AXES], 0.0);
    let mut bound = 0.0;
    for i in 0..AXES {
        bound += s0.a_p[i] * s0.a_p[i] + s0.j_p[i] * s0.j_p[i] / flow.axes[i].osc.w2;
    }
    let hold = m.holding_friction();
    let safe = m.slider_mass * m.slider_mass * bound <= hold * hold;
    let h = if safe {
        h_max
    } else {
        h_max.min(event_step(inst, true))
    };
    let samples = sample_step(&flow, h);
    if !safe
        && let Some((lo, hi)) =
            find_crossing(inst, st, EventKind::Breakaway, 1.0, &flow, &samples, h)
    {
        {
            let tau = locate(
                inst,
                st,
                EventKind::Breakaway,
                1.0,
                &flow,
                lo,
                hi,
                inst.period(),
            );
            let s = eval_at(&flow, tau);
            move_to(st, &s, tau, h_max, stop, &flow, observer);
            let need = stick_force(inst, st);
            start_slip(inst, st, need);
            return;
        }
    }
    move_to(st, &samples[4], h, h_max, stop, &flow, observer);
}

/// One BAND step: the held friction direction makes the motion exact; the
/// step ends where the relative velocity leaves the band or reverses.
fn step_band<O: StepObserver>(
    inst: &Instance,
    st: &mut State,
    h_max: f64,
    stop: f64,
    observer: &mut O,
) {
    let force = current_force(inst, st);
    let h = h_max.min(event_step(inst, false));
    let mut b = [[0.0; 3]; AXES];
    for i in 0..AXES {
        b[i][0] = st.held[i];
    }
    let flow = slip_flow(inst, st, force, b, h);
    let samples = sample_step(&flow, h);
    // The reversal is watched relative to the sign the product first takes.
    let mut sign = 0.0;
    for s in &samples {
        let d = dot(relative_velocity(s), st.held);
        if d != 0.0 {
            sign = d.signum();
            break;
        }
    }
    let period = inst.period();
    let mut first: Option<(f64, EventKind)> = None;
    for kind in [EventKind::LeaveBand, EventKind::Reversal] {
        // A product that is zero at every sample cannot reverse.
        if kind == EventKind::Reversal && sign == 0.0 {
            continue;
        }
        let sg = if kind == EventKind::Reversal {
            sign
        } else {
            1.0
        };
        if let Some((lo, hi)) = find_crossing(inst, st, kind, sg, &flow, &samples, h) {
            let tau = locate(inst, st, kind, sg, &flow, lo, hi, period);
            if first.is_none_or(|(t, _)| tau < t) {
                first = Some((tau, kind));
            }
        }
    }
    match first {
        Some((tau, kind)) => {
            let s = eval_at(&flow, tau);
            move_to(st, &s, tau, h_max, stop, &flow, observer);
            if kind == EventKind::LeaveBand {
                st.mode = MODE_SLIP;
                st.h_slip = initial_slip_step(inst, st, h_max);
            } else {
                try_stick(inst, st);
            }
        }
        None => move_to(st, &samples[4], h, h_max, stop, &flow, observer),
    }
}

/// A first slip step after leaving the band: short enough to follow the
/// turn of the relative velocity, which happens on the time scale
/// |v_rel| / |dv_rel/dt across|.
fn initial_slip_step(inst: &Instance, st: &State, h_max: f64) -> f64 {
    let force = current_force(inst, st);
    let b = direction_poly(st);
    let flow = slip_flow(inst, st, force, b, 1.0);
    let s = eval_flow(&flow, [IDENTITY; AXES], 0.0);
    let v = relative_velocity(&s);
    let a = relative_acceleration(&s);
    let speed = norm2(v).sqrt();
    let along = dot(a, v) / speed;
    let across = (norm2(a) - along * along).max(0.0).sqrt();
    let turn = if across > 0.0 {
        0.1 * speed / across
    } else {
        f64::INFINITY
    };
    turn.min(event_step(inst, false)).min(h_max.max(0.0))
}

/// The constant direction polynomial of the current relative velocity.
fn direction_poly(st: &State) -> [[f64; 3]; AXES] {
    let mut v = [0.0; AXES];
    for i in 0..AXES {
        v[i] = st.v_p[i] - st.v_s[i];
    }
    let n = norm2(v).sqrt();
    let mut b = [[0.0; 3]; AXES];
    for i in 0..AXES {
        b[i][0] = v[i] / n;
    }
    b
}

fn direction(s: &Sample) -> Option<[f64; AXES]> {
    let v = relative_velocity(s);
    let n = norm2(v).sqrt();
    if n > 0.0 && n.is_finite() {
        let mut u = [0.0; AXES];
        for i in 0..AXES {
            u[i] = v[i] / n;
        }
        Some(u)
    } else {
        None
    }
}

/// A trial slip step of length h: the converged direction polynomial, its
/// flow, its samples, and the largest direction error at the samples.
fn slip_trial(
    inst: &Instance,
    st: &State,
    force: [[f64; 2]; AXES],
    h: f64,
    tol: f64,
) -> (Flow, [Sample; 5], f64) {
    let mut b = direction_poly(st);
    let u0 = [b[0][0], b[1][0]];
    let mut flow = slip_flow(inst, st, force, b, h);
    // The propagators depend on the step only, not on the direction model.
    let props = sample_propagators(&flow, h);
    let mut mid = eval_flow(&flow, props[2], 0.5 * h);
    let mut end = eval_flow(&flow, props[4], h);
    // Without kinetic friction the slip motion does not depend on the
    // friction direction: there is no turn to resolve, and no step limit.
    let frictionless = inst.mechanism.coulomb_friction == 0.0;
    let iterations = if frictionless {
        0
    } else {
        COLLOCATION_ITERATIONS
    };
    for _ in 0..iterations {
        let (Some(um), Some(ue)) = (direction(&mid), direction(&end)) else {
            return (flow, [end; 5], f64::INFINITY);
        };
        let mut change: f64 = 0.0;
        for i in 0..AXES {
            let b1 = 4.0 * um[i] - 3.0 * u0[i] - ue[i];
            let b2 = 2.0 * (ue[i] - 2.0 * um[i] + u0[i]);
            change = change.max((b1 - b[i][1]).abs()).max((b2 - b[i][2]).abs());
            b[i][1] = b1;
            b[i][2] = b2;
        }
        if change == 0.0 {
            break;
        }
        flow = slip_flow(inst, st, force, b, h);
        mid = eval_flow(&flow, props[2], 0.5 * h);
        end = eval_flow(&flow, props[4], h);
        if change <= COLLOCATION_CONVERGED * tol {
            break;
        }
    }
    let samples = [
        eval_flow(&flow, props[0], 0.0),
        eval_flow(&flow, props[1], 0.25 * h),
        mid,
        eval_flow(&flow, props[3], 0.75 * h),
        end,
    ];
    if frictionless {
        return (flow, samples, 0.0);
    }
    // The error is the distance between the model direction and the true
    // direction of the resulting motion, at every sample.
    let mut err: f64 = 0.0;
    let mut prev_v = relative_velocity(&samples[0]);
    for j in 1..5 {
        let v = relative_velocity(&samples[j]);
        if dot(v, prev_v) <= 0.0 {
            return (flow, samples, f64::INFINITY);
        }
        prev_v = v;
        let Some(u) = direction(&samples[j]) else {
            return (flow, samples, f64::INFINITY);
        };
        let th = THETA[j];
        let mut d2 = 0.0;
        for i in 0..AXES {
            let model = b[i][0] + (b[i][1] + b[i][2] * th) * th;
            d2 += (u[i] - model) * (u[i] - model);
        }
        err = err.max(d2.sqrt());
    }
    (flow, samples, err)
}

/// One SLIP step with error control; ends at the stop, at the end of an
/// accepted step, or where the relative velocity enters the band.
fn step_slip<O: StepObserver>(
    inst: &Instance,
    settings: &Settings,
    st: &mut State,
    h_max: f64,
    stop: f64,
    period: f64,
    observer: &mut O,
) {
    let force = current_force(inst, st);
    let tol = settings.tolerance;
    let h_event = event_step(inst, false);
    let mut h = st.h_slip.min(h_event).min(h_max);
    if h <= 0.0 {
        h = h_event.min(h_max);
    }
    let min_step = 64.0 * f64::EPSILON * period;
    let mut rejections = 0;
    let (flow, samples, err) = loop {
        let (flow, samples, err) = slip_trial(inst, st, force, h, tol);
        if err <= tol {
            break (flow, samples, err);
        }
        rejections += 1;
        st.steps += 1;
        let factor = if err.is_finite() {
            (0.9 * (tol / err).cbrt()).clamp(0.1, 0.9)
        } else {
            0.25
        };
        h *= factor;
        if h < min_step || rejections > MAX_REJECTIONS {
            st.status = STATUS_STEP_UNDERFLOW;
            return;
        }
    };
    let growth = if err > 0.0 {
        (0.9 * (tol / err).cbrt()).clamp(0.2, 4.0)
    } else {
        4.0
    };
    if let Some((lo, hi)) = find_crossing(inst, st, EventKind::EnterBand, 1.0, &flow, &samples, h) {
        let tau = locate(inst, st, EventKind::EnterBand, 1.0, &flow, lo, hi, period);
        let s = eval_at(&flow, tau);
        move_to(st, &s, tau, h_max, stop, &flow, observer);
        st.h_slip = h;
        try_stick(inst, st);
        return;
    }
    move_to(st, &samples[4], h, h_max, stop, &flow, observer);
    // A step cut short by the stop says nothing about the next one.
    st.h_slip = if h < h_max {
        h * growth
    } else {
        st.h_slip.max(h)
    };
}
