//! One step of the integrator, the same code for every friction mode: the
//! mode only chooses the step length, the flow and which events to watch.
//! The sampling, the event search and location, and the move are shared,
//! so on a GPU the lanes of a warp in different modes run the same
//! instructions together.
//!
//! * STICK: the flow of stage and slider as one body; straight to the stop
//!   when an energy bound shows the stiction cannot break before it,
//!   otherwise a sampled sub-step watching the breakaway.
//! * SLIP: one trial step of the friction-direction quadratic (fixed-point
//!   collocation at the middle and end). A trial whose direction error
//!   exceeds the tolerance is rejected: the step shrinks and the next
//!   iteration tries again (counted as a step, time unchanged). An accepted
//!   step watches the relative velocity entering the band.
//! * BAND: the held friction direction makes the motion exact; the step
//!   watches the relative velocity leaving the band and reversing.

use super::arith::step_factor;
use super::coefficients::Coefficients;
use super::constants::{
    APPROACH_SHARE, COLLOCATION_ITERATIONS, EVENT_APPROACH, EVENT_BREAKAWAY, EVENT_ENTER_BAND,
    EVENT_LEAVE_BAND, EVENT_NONE, EVENT_REVERSAL, GRAZE_MARGIN, MAX_REJECTIONS, MAX_SQUARINGS,
    MODE_BAND, MODE_SLIP, MODE_STICK, SLIP_DIRECTION_ITERATIONS, STATUS_GRAZE,
    STATUS_STEP_UNDERFLOW, STEP_FACTOR_BISECTIONS, STEP_FACTOR_QUANTUM,
};
use super::drive::drive_force;
use super::drive::two_sum;
use super::events::{
    THETA, approach_event, approach_scale, find_crossing, locate, primary_event, primary_scale,
    relative_acceleration, relative_velocity, reversal_event, reversal_scale,
};
use super::flow::{
    DirectionModel, Flow, IDENTITY, Sample, SamplePropagators, eval_at, eval_flow, make_flow,
    sample_propagators,
};
use super::precision::{APPROACH_NOISE, COMPENSATED_TIME, DEFLECTION, GRAZE_GUARD, TINY};
use super::vec2::{Vec2, dot, norm2};
use super::{Real, State, StepMotion, StepObserver};

/// What one call of [`step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepOutcome {
    /// The state moved without meeting an event, or the instance failed.
    Moved,
    /// The state moved to an event (possibly by zero time, one that fires
    /// at once) and changed mode there.
    Located,
    /// A slip trial was rejected: only the step length changed.
    Rejected,
}

/// The flow of the current state in its mode.
fn mode_flow(
    c: &Coefficients,
    st: &State,
    force: Vec2,
    slope: Vec2,
    dir: &DirectionModel,
    h: Real,
    inv_h: Real,
) -> Flow {
    make_flow(
        c,
        st.mode == MODE_STICK,
        st.x_p,
        st.v_p,
        st.x_s,
        st.v_s,
        st.v_rel,
        force,
        slope,
        dir,
        h,
        inv_h,
    )
}

/// The unit vector of the relative velocity, or `None` where it is zero or
/// not finite.
fn direction(s: &Sample) -> Option<Vec2> {
    let v = relative_velocity(s);
    let n = norm2(v).sqrt();
    if n > 0.0 && n.is_finite() {
        Some(v * (1.0 / n))
    } else {
        None
    }
}

/// What the phases of one step share: the trial's length and its
/// reciprocal, the direction model and the flow, and what the step learnt
/// of them.
struct Trial {
    h: Real,
    inv_h: Real,
    dir: DirectionModel,
    flow: Flow,
    /// STICK: the energy bound shows that the stiction holds to the stop.
    safe: bool,
    /// SLIP: the direction error (infinite where the relative velocity
    /// reversed or vanished), and the event the step ends at: the band
    /// entry, or its approach along a fixed direction.
    err: Real,
    slip_event: u32,
}

/// The event a step meets first, if any.
struct StepEvent {
    /// `EVENT_NONE` where the step meets none.
    kind: u32,
    tau: Real,
    /// A slip that passes the band closer than the graze margin, or enters
    /// it only skimming (see `GRAZE_MARGIN`).
    grazed: bool,
}

/// One step of at most `h_max`, ending no later than the local time `stop`
/// (hi, lo: the low part is zero but in f32).
pub fn step<O: StepObserver>(
    c: &Coefficients,
    st: &mut State,
    h_max: Real,
    stop: (Real, Real),
    observer: &mut O,
) -> StepOutcome {
    let (force, slope) = drive_force(c, st);
    let slipping = st.mode == MODE_SLIP;
    let (mut t, start) = trial(c, st, force, slope, h_max);
    let props = sample_propagators(&t.flow, t.h);
    let mut samples = collocate(c, st, force, slope, &props, &mut t, start);
    if slipping && !c.frictionless {
        if t.err == 0.0 {
            t.err = direction_error(&t.dir, &samples, 4);
        }
        if t.err == Real::INFINITY {
            samples = approach_trial(c, st, force, slope, &props, &mut t);
        }
        if t.err > c.tolerance {
            reject(c, st, t.h, t.err);
            return StepOutcome::Rejected;
        }
    }
    let mut found = find_event(c, st, &t, &samples);
    if found.kind == EVENT_NONE {
        move_to(st, &samples[4], t.h, h_max, stop, &t.flow, observer);
        if slipping {
            // A step cut short by the stop says nothing about the next one.
            if t.h < h_max {
                st.h_slip = next_slip_step(c, st, t.h, t.err);
            } else {
                st.h_slip = st.h_slip.max(t.h);
            }
        }
    } else if !take_event(c, st, &t, &mut found, h_max, stop, observer) {
        return StepOutcome::Rejected;
    }
    if GRAZE_GUARD && !c.steady && found.grazed {
        st.status = STATUS_GRAZE;
    }
    st.rejections = 0;
    if found.kind == EVENT_NONE {
        StepOutcome::Moved
    } else {
        StepOutcome::Located
    }
}

/// The trial of a step: its length, the direction model's constant term
/// and the flow, with the flow's start.
fn trial(c: &Coefficients, st: &State, force: Vec2, slope: Vec2, h_max: Real) -> (Trial, Sample) {
    let stuck = st.mode == MODE_STICK;
    let slipping = st.mode == MODE_SLIP;
    // The step length and the direction model's constant term.
    let mut dir = DirectionModel::default();
    let mut h = h_max;
    if slipping {
        h = st.h_slip.min(c.event_step_slip).min(h_max);
        if h <= 0.0 {
            h = c.event_step_slip.min(h_max);
        }
        let v = st.v_rel;
        dir.b0 = v * (1.0 / norm2(v).sqrt());
    } else if st.mode == MODE_BAND {
        h = h_max.min(c.event_step_slip);
        dir.b0 = st.held;
    }
    // A flow's start does not depend on its length while the direction
    // model is constant (stick, and a slip trial before its collocation):
    // a slip trial reads its limit there, from a flow of unit length, then
    // takes the flow of the length it keeps. One reciprocal of the step
    // length serves every flow of the step.
    let band = st.mode == MODE_BAND;
    let mut inv_h = if band { 1.0 / h } else { 1.0 };
    let mut flow = mode_flow(c, st, force, slope, &dir, if band { h } else { 1.0 }, inv_h);
    let start = eval_flow(&flow, IDENTITY, 0.0);
    if slipping {
        if !c.frictionless {
            h = approach_limit(c, st.v_rel, relative_acceleration(&start), h);
        }
        inv_h = 1.0 / h;
        flow = mode_flow(c, st, force, slope, &dir, h, inv_h);
    }
    // The homogeneous acceleration obeys the same oscillator equation, so
    // m a'' + c a' + k a = 0 and k a^2 + m a'^2 never grows: |a| stays below
    // sqrt(a^2 + a'^2 / w2) for the rest of a stick segment, and |f_need| =
    // |m_s a - L| below m_s times that plus |L| (`safe_hold2`).
    let mut safe = false;
    if stuck {
        let bound = norm2(start.a_p) + dot(start.j_p * start.j_p, flow.osc.inv_w2);
        safe = c.ms2 * bound <= c.safe_hold2;
        if !safe {
            h = h_max.min(c.event_step_stuck);
        }
    }
    let trial = Trial {
        h,
        inv_h,
        dir,
        flow,
        safe,
        err: 0.0,
        slip_event: EVENT_ENTER_BAND,
    };
    (trial, start)
}

/// The samples of the trial from its flow's `start`. SLIP: first the
/// direction model through the true direction at the start, middle and end
/// of the step, by fixed-point iteration (an infinite error where the
/// relative velocity vanishes). Without kinetic friction the motion does
/// not depend on the direction: no turn to resolve, and no step limit.
fn collocate(
    c: &Coefficients,
    st: &State,
    force: Vec2,
    slope: Vec2,
    props: &SamplePropagators,
    t: &mut Trial,
    start: Sample,
) -> [Sample; 5] {
    let h = t.h;
    let mut start = start;
    let mut mid = eval_flow(&t.flow, props.half, 0.5 * h);
    let mut end = eval_flow(&t.flow, props.full, h);
    if st.mode == MODE_SLIP && !c.frictionless {
        let u0 = t.dir.b0;
        for _ in 0..COLLOCATION_ITERATIONS {
            let (Some(um), Some(ue)) = (direction(&mid), direction(&end)) else {
                t.err = Real::INFINITY;
                break;
            };
            let b1 = 4.0 * um - 3.0 * u0 - ue;
            let b2 = 2.0 * (ue - 2.0 * um + u0);
            let change = (b1 - t.dir.b1)
                .abs()
                .max_element()
                .max((b2 - t.dir.b2).abs().max_element());
            t.dir.b1 = b1;
            t.dir.b2 = b2;
            if change == 0.0 {
                break;
            }
            t.flow = mode_flow(c, st, force, slope, &t.dir, h, t.inv_h);
            mid = eval_flow(&t.flow, props.half, 0.5 * h);
            end = eval_flow(&t.flow, props.full, h);
            if change <= c.collocation_tolerance {
                break;
            }
        }
        start = eval_flow(&t.flow, IDENTITY, 0.0);
    }
    let quarter = eval_flow(&t.flow, props.quarter, 0.25 * h);
    let three_quarters = eval_flow(&t.flow, props.three_quarters, 0.75 * h);
    [start, quarter, mid, three_quarters, end]
}

/// A slip trial whose relative velocity reversed (or vanished) within it,
/// so that no quadratic follows its direction; but the band is entered
/// before any reversal. Takes the constant direction u of the start (exact
/// for motion along a fixed direction), finds where v_rel . u slows to the
/// band, and checks the direction only before that; returns the samples of
/// that flow. Without this, a slip that slows down toward the band is found
/// by halving and quadrupling the step about twenty times, until a step
/// happens to end inside the band.
fn approach_trial(
    c: &Coefficients,
    st: &State,
    force: Vec2,
    slope: Vec2,
    props: &SamplePropagators,
    t: &mut Trial,
) -> [Sample; 5] {
    let h = t.h;
    t.dir = DirectionModel {
        b0: t.dir.b0,
        ..DirectionModel::default()
    };
    t.flow = mode_flow(c, st, force, slope, &t.dir, h, t.inv_h);
    let samples = sample_flow(&t.flow, props, h);
    let ev = samples.map(|s| approach_event(c, &t.flow, &s));
    let scale = approach_scale(c, &t.flow, &samples[0]);
    let entry = find_crossing(c, st, EVENT_APPROACH, 1.0, &ev, scale, &t.flow, h);
    if entry.found {
        let before = THETA.iter().filter(|&&th| th * h <= entry.lo).count() - 1;
        t.err = direction_error(&t.dir, &samples, before);
        t.slip_event = EVENT_APPROACH;
    }
    samples
}

/// The first event the accepted trial meets: the events it watches, their
/// values at the samples, and in band slip the sign the reversal product
/// first takes.
fn find_event(c: &Coefficients, st: &State, t: &Trial, samples: &[Sample; 5]) -> StepEvent {
    let (flow, h) = (&t.flow, t.h);
    let start = samples[0];
    let primary = if st.mode == MODE_STICK {
        if t.safe { EVENT_NONE } else { EVENT_BREAKAWAY }
    } else if st.mode == MODE_SLIP {
        t.slip_event
    } else {
        EVENT_LEAVE_BAND
    };
    let mut ev_primary = [[0.0; 2]; 5];
    let mut ev_reversal = [[0.0; 2]; 5];
    let mut sign = 0.0;
    for (j, s) in samples.iter().enumerate() {
        ev_primary[j] = if primary == EVENT_APPROACH {
            approach_event(c, flow, s)
        } else {
            primary_event(c, primary, s)
        };
        ev_reversal[j] = reversal_event(st, s);
        if sign == 0.0 && ev_reversal[j][0] != 0.0 {
            sign = if ev_reversal[j][0] > 0.0 { 1.0 } else { -1.0 };
        }
    }
    let watch_reversal = st.mode == MODE_BAND && sign != 0.0;
    let mut found = StepEvent {
        kind: EVENT_NONE,
        tau: 0.0,
        grazed: false,
    };
    for k in 0..2 {
        let (kind, kind_sign, ev, scale) = if k == 0 {
            let scale = if primary == EVENT_APPROACH {
                approach_scale(c, flow, &start)
            } else {
                primary_scale(c, primary, &start)
            };
            (primary, 1.0, &ev_primary, scale)
        } else {
            (
                if watch_reversal {
                    EVENT_REVERSAL
                } else {
                    EVENT_NONE
                },
                sign,
                &ev_reversal,
                reversal_scale(st, &start),
            )
        };
        if kind == EVENT_NONE {
            continue;
        }
        let crossing = find_crossing(c, st, kind, kind_sign, ev, scale, flow, h);
        if kind == EVENT_ENTER_BAND && !crossing.found {
            found.grazed = crossing.closest < GRAZE_MARGIN as Real * c.band2;
        }
        if crossing.found {
            let tau = locate(c, st, kind, kind_sign, flow, crossing.lo, crossing.hi);
            if found.kind == EVENT_NONE || tau < found.tau {
                found.kind = kind;
                found.tau = tau;
            }
        }
    }
    found
}

/// Moves the state to the event `found` and changes its mode there; false
/// where the event is an approach whose direction turned too far on the
/// way (the trial is rejected instead).
fn take_event<O: StepObserver>(
    c: &Coefficients,
    st: &mut State,
    t: &Trial,
    found: &mut StepEvent,
    h_max: Real,
    stop: (Real, Real),
    observer: &mut O,
) -> bool {
    let event = found.kind;
    st.h_accepted = 0.0;
    let s = eval_at(&t.flow, found.tau);
    if event == EVENT_APPROACH && approach_turned(c, &s, &t.flow) {
        reject(c, st, t.h, Real::INFINITY);
        return false;
    }
    move_to(st, &s, found.tau, h_max, stop, &t.flow, observer);
    found.grazed = event == EVENT_ENTER_BAND && skims_band(c, &s);
    // The force slip starts along, where it starts (one call of
    // `start_slip` for both: the shader's code holds one copy).
    let mut slip_need = None;
    if event == EVENT_BREAKAWAY {
        slip_need = Some(stick_force(c, st));
    } else if event == EVENT_LEAVE_BAND {
        st.mode = MODE_SLIP;
        st.h_slip = initial_slip_step(c, st, h_max);
    } else {
        if event == EVENT_ENTER_BAND || event == EVENT_APPROACH {
            st.h_slip = t.h;
        }
        slip_need = try_stick(c, st);
    }
    if let Some(need) = slip_need {
        start_slip(c, st, need);
    }
    true
}

/// Whether the relative velocity turned on its way from the start of flow
/// `flow` to the approach event at sample `s`: v_rel . u = a is the band
/// entry only while v_rel still points along u, and a relative velocity
/// that turned on its way to zero (a pass of the band in 2-D) needs shorter
/// steps instead.
fn approach_turned(c: &Coefficients, s: &Sample, flow: &Flow) -> bool {
    let turned = match direction(s) {
        Some(u) => norm2(u - flow.b0).sqrt(),
        None => Real::INFINITY,
    };
    let mut allowed = c.tolerance;
    if APPROACH_NOISE {
        // f32 knows v_rel here only to the rounding of the stage's and the
        // slider's velocity changes it is the difference of (their
        // deflection form makes that all): a turn below it is not one f32
        // can see, and shorter steps, which shrink the changes, only cost
        // steps (results/gpu.md).
        let dv = (s.v_p - flow.v_p).abs() + (s.v_s - flow.v_s).abs();
        let v = s.v_rel;
        allowed += (4.0 * Real::EPSILON * (dv.x + dv.y)) / norm2(v).max(TINY).sqrt();
    }
    turned > allowed
}

/// Whether a band entry at sample `s` only skims the band: where the
/// relative velocity v moves along its acceleration a, its closest approach
/// to zero is |v|^2 - (v . a)^2 / |a|^2, which lies below a^2 (|v| = a at
/// the entry) by (v . a)^2 / |a|^2; an entry shallower than the graze
/// margin is a graze (see `GRAZE_MARGIN`).
fn skims_band(c: &Coefficients, s: &Sample) -> bool {
    let va = dot(relative_velocity(s), relative_acceleration(s));
    va * va < GRAZE_MARGIN as Real * c.band2 * norm2(relative_acceleration(s))
}

/// The five samples of a flow over a step of length h.
fn sample_flow(flow: &Flow, props: &SamplePropagators, h: Real) -> [Sample; 5] {
    [
        eval_flow(flow, IDENTITY, 0.0),
        eval_flow(flow, props.quarter, 0.25 * h),
        eval_flow(flow, props.half, 0.5 * h),
        eval_flow(flow, props.three_quarters, 0.75 * h),
        eval_flow(flow, props.full, h),
    ]
}

/// The largest distance between the direction model and the true direction
/// of the resulting motion at samples 1 to `last`, or infinity where the
/// relative velocity turns by a right angle between samples or vanishes.
/// Squared distances are compared and one root taken (the root of the
/// largest is the largest root, rounding included).
fn direction_error(dir: &DirectionModel, samples: &[Sample; 5], last: usize) -> Real {
    let mut err2: Real = 0.0;
    let mut prev_v = relative_velocity(&samples[0]);
    for (s, th) in samples.iter().zip(THETA).skip(1).take(last) {
        let v = relative_velocity(s);
        if dot(v, prev_v) <= 0.0 {
            return Real::INFINITY;
        }
        prev_v = v;
        let Some(u) = direction(s) else {
            return Real::INFINITY;
        };
        let model = dir.b0 + (dir.b1 + dir.b2 * th) * th;
        let d = u - model;
        err2 = err2.max(norm2(d));
    }
    err2.sqrt()
}

/// A rejected slip trial: the next one is shorter, unless the step has
/// become too short or too many were rejected in a row.
fn reject(c: &Coefficients, st: &mut State, h: Real, err: Real) {
    st.rejections += 1;
    let factor = if err.is_finite() {
        step_factor(c.tolerance, err, c.tolerance, 0.0, 0.1, 0.9)
    } else {
        0.25
    };
    let shorter = h * factor;
    if shorter < c.min_step || st.rejections > MAX_REJECTIONS {
        st.status = STATUS_STEP_UNDERFLOW;
    } else {
        st.h_slip = shorter;
    }
}

/// The slip trial after an accepted step of length h with direction error
/// err, which the stop did not cut short (issue 47: a third of all slip
/// trials were rejected with the plain controller alone):
///
/// * the plain controller, 0.9 cbrt(tol / err), in [0.2, 4];
/// * Gustafsson's predictive controller (1994; Hairer and Wanner, *Solving
///   ODEs II*, IV.8), where the step before was accepted too: a direction
///   that turns ever faster makes the error grow from step to step at the
///   same length, and h (h / h_prev) 0.9 cbrt(tol err_prev / err^2)
///   follows that trend where the plain rule lags one rejection behind;
/// * no growth right after a rejection.
///
/// The smallest applies; it is remembered with err for the next one.
fn next_slip_step(c: &Coefficients, st: &mut State, h: Real, err: Real) -> Real {
    // The predictive bound, where the step before was accepted too (else
    // a second bound that always holds).
    let (mut allowed2, mut err2) = (c.tolerance, 0.0);
    if st.h_accepted > 0.0 && st.err_accepted > 0.0 && err > 0.0 {
        let r = h / st.h_accepted;
        allowed2 = c.tolerance * st.err_accepted * (r * r * r);
        err2 = err * err;
    }
    let mut factor = step_factor(c.tolerance, err, allowed2, err2, 0.2, 4.0);
    if st.rejections > 0 {
        factor = factor.min(1.0);
    }
    st.h_accepted = h;
    st.err_accepted = err;
    h * factor
}

/// The longest slip trial from a relative velocity v that changes at rate
/// a, given the step h the controller asks for: where v slows while it
/// turns, at most [`APPROACH_SHARE`] of the time v . v / (-v . a) it would
/// take to stop at its present rate. The direction of v turns ever faster
/// as its speed nears zero, which no quadratic follows; a trial that
/// reaches that far is rejected, and the controller, which knows only past
/// errors, overshoots it again at the next step. A direction that does not
/// turn (|v x a| within the tolerance of v . a: motion along a line) is
/// exact at any length and keeps h, so its band entry is located in one
/// step. The limit is h halved, then rounded down to a multiple of 1 /
/// [`STEP_FACTOR_QUANTUM`] of that, as the controller's factors are: a
/// step that followed v . v / (-v . a) continuously would turn last-bit
/// differences between backends into different steps. No division.
fn approach_limit(c: &Coefficients, v: Vec2, a: Vec2, h: Real) -> Real {
    let closing = -dot(v, a);
    let turning = (v.x * a.y - v.y * a.x).abs();
    let reach = APPROACH_SHARE as Real * norm2(v);
    if !(closing > 0.0 && turning > c.tolerance * closing && h * closing > reach) {
        return h;
    }
    // Halvings to within a factor of two: reach < limit closing <= 2 reach.
    let mut limit = h;
    for _ in 0..MAX_SQUARINGS {
        if limit * closing <= 2.0 * reach {
            break;
        }
        limit *= 0.5;
    }
    limit * grid_fraction(limit * closing, reach)
}

/// The largest n / [`STEP_FACTOR_QUANTUM`] in [1/2, 1) with n x <= quantum
/// bound, for x in (bound, 2 bound], by bisection.
fn grid_fraction(x: Real, bound: Real) -> Real {
    let scaled = STEP_FACTOR_QUANTUM as Real * bound;
    let quantum = STEP_FACTOR_QUANTUM as u32;
    let (mut below, mut above) = (quantum / 2, quantum);
    for _ in 0..STEP_FACTOR_BISECTIONS {
        if above - below <= 1 {
            break;
        }
        let n = (above + below) / 2;
        if n as Real * x <= scaled {
            below = n;
        } else {
            above = n;
        }
    }
    below as Real * (1.0 / STEP_FACTOR_QUANTUM) as Real
}

/// Moves the state to tau within the current step of flow `flow` (tau >=
/// h_max lands exactly on the stop), showing the observer the motion first.
fn move_to<O: StepObserver>(
    st: &mut State,
    s: &Sample,
    tau: Real,
    h_max: Real,
    stop: (Real, Real),
    flow: &Flow,
    observer: &mut O,
) {
    let end = if tau >= h_max { stop.0 } else { st.time + tau };
    observer.step(
        st,
        &StepMotion {
            flow,
            tau,
            end,
            at_end: s,
        },
    );
    st.x_p = s.x_p;
    st.v_p = s.v_p;
    st.x_s = s.x_s;
    st.v_s = s.v_s;
    st.v_rel = s.v_rel;
    if tau >= h_max {
        st.time = stop.0;
        st.time_lo = stop.1;
    } else if COMPENSATED_TIME {
        let (hi, lo) = two_sum(st.time, tau + st.time_lo);
        st.time = hi;
        st.time_lo = lo;
    } else {
        st.time += tau;
    }
}

/// A first slip step after leaving the band: short enough to follow the
/// turn of the relative velocity, which happens on the time scale
/// |v_rel| / |dv_rel/dt across|. The step is the event step halved until
/// it is at most a tenth of that time: the relative velocity is a small
/// difference of large velocities, so the turn time carries rounding noise
/// that differs between backends, and a power-of-two step does not follow
/// it (only a turn time on a power of two could tip it).
fn initial_slip_step(c: &Coefficients, st: &State, h_max: Real) -> Real {
    let (force, slope) = drive_force(c, st);
    let v = st.v_rel;
    let dir = DirectionModel {
        b0: v * (1.0 / norm2(v).sqrt()),
        ..DirectionModel::default()
    };
    let flow = mode_flow(c, st, force, slope, &dir, 1.0, 1.0);
    let s = eval_flow(&flow, IDENTITY, 0.0);
    let v = relative_velocity(&s);
    let a = relative_acceleration(&s);
    let speed = norm2(v).sqrt();
    // |a across v| = |v x a| / |v|, free of the cancellation of
    // sqrt(|a|^2 - (a . v / |v|)^2).
    let across = (v.x * a.y - v.y * a.x).abs() / speed;
    let turn = if across > 0.0 {
        0.1 * speed / across
    } else {
        Real::INFINITY
    };
    let mut h = c.event_step_slip;
    for _ in 0..MAX_SQUARINGS {
        if h <= turn {
            break;
        }
        h *= 0.5;
    }
    h.min(h_max.max(0.0))
}

/// The static friction force on the slider that stick would need now, with
/// both bodies at their common (momentum-conserving) velocity: f_need =
/// (m_s P - m_p L) / (m_p + m_s) (docs/model.md section 7), section 3's at L = 0
/// bit for bit.
pub fn stick_force(c: &Coefficients, st: &State) -> Vec2 {
    let (force, slope) = drive_force(c, st);
    if DEFLECTION {
        // F - k x_p = -k d: the force balance without the drive force.
        let v = c.stage_share * (st.v_p + slope * c.inv_stiffness) + c.slider_share * st.v_s;
        return c.slider_share * (-c.damping * v - c.stiffness * st.x_p) - c.load_need;
    }
    let v = c.stage_share * st.v_p + c.slider_share * st.v_s;
    let p = force - c.damping * v - c.stiffness * st.x_p;
    c.slider_share * p - c.load_need
}

/// The direction in which slip grows out of zero relative velocity. In
/// slip the relative acceleration is A - B u per axis, with A_i = P_i /
/// m_p,i - L_i / m_s = f_need,i (1 / m_p,i + 1 / m_s) (the load of docs/model.md
/// section 7 is in f_need) and B_i = f_c (1 / m_p,i + 1 / m_s), so the friction direction u
/// is consistent only where A - B u = lambda u with lambda > 0:
/// u_i = A_i / (lambda + B_i) with sum_i A_i^2 / (lambda + B_i)^2 = 1. That
/// root exists exactly when |f_need| > f_c. With equal stage masses B is
/// the same on both axes and u is the direction of f_need (docs/model.md
/// section 3); with unequal ones, slip along f_need itself would turn the
/// relative velocity away from the friction and chatter at the band edge.
fn slip_direction(c: &Coefficients, need: Vec2) -> Vec2 {
    let a = need * c.slip_scale;
    let b = c.slip_b;
    // g(lambda) = sum A^2 / (lambda + B)^2 - 1 is convex and decreasing,
    // and g >= 0 at max(0, |A| - max B): Newton from there rises
    // monotonically to the root.
    let mut lambda = (norm2(a).sqrt() - c.slip_b_max).max(0.0);
    for _ in 0..SLIP_DIRECTION_ITERATIONS {
        let d = b + lambda;
        let r = a / d;
        let q = r * r;
        let g = q.x + q.y - 1.0;
        let dg = -2.0 * dot(q, Vec2::splat(1.0) / d);
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
    let u = a / (b + lambda);
    // Normalise away the last rounding; fall back to f_need's direction if
    // the iteration met a degenerate case.
    let n = norm2(u).sqrt();
    if n > 0.0 && n.is_finite() {
        u * (1.0 / n)
    } else {
        need * (1.0 / norm2(need).sqrt())
    }
}

/// STICK -> SLIP: enters the band at zero relative velocity with the
/// friction held along the direction slip grows in.
pub fn start_slip(c: &Coefficients, st: &mut State, need: Vec2) {
    st.held = slip_direction(c, need);
    st.mode = MODE_BAND;
}

/// At a relative velocity inside the band the two bodies' velocities merge
/// per axis, conserving momentum (a change of at most the band a). Then
/// they stick if the static friction can hold them, or else slip starts
/// afresh along the needed force, exactly as a breakaway from stick does
/// (in 1-D: the slider reverses). Starting the new slip from zero relative
/// velocity keeps the relative velocity aligned with the friction when it
/// leaves the band; holding the old, misaligned relative velocity would
/// make it re-enter the band at once, over and over. Returns the force slip
/// starts along where the static friction cannot hold (the caller starts
/// it).
fn try_stick(c: &Coefficients, st: &mut State) -> Option<Vec2> {
    let need = stick_force(c, st);
    if DEFLECTION {
        // The merged velocity relative to the drive's static velocity
        // (with v_s = v_p - v_rel, no difference of two speeds), and
        // absolute for the slider.
        let u = st.v_p - c.slider_share * st.v_rel;
        st.v_p = u;
        st.v_s = u + drive_force(c, st).1 * c.inv_stiffness;
    } else {
        let v = c.stage_share * st.v_p + c.slider_share * st.v_s;
        st.v_p = v;
        st.v_s = v;
    }
    st.v_rel = Vec2::ZERO;
    if norm2(need) <= c.hold2 {
        st.mode = MODE_STICK;
        None
    } else {
        Some(need)
    }
}
