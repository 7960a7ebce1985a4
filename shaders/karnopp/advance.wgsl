// Mirror of `laws::karnopp::integrate`: the state, and one iteration of the
// integrator.

// The integrator state, as `pidm::cpu::integrate::State`, plus `time_lo`,
// the low part of the time (always zero unless COMPENSATED_TIME), and
// `corner_at` + `corner_at_lo`, the local time of each axis' next corner in
// two parts, which only CORNER_CLOCK (f32) keeps (drive.wgsl).
struct State {
    x_p: V2,
    v_p: V2,
    x_s: V2,
    v_s: V2,
    v_rel: V2,
    held: V2,
    settle_x_s: V2,
    cycle_phase: V2,
    next_corner: V2,
    corner_at: V2,
    corner_at_lo: V2,
    time: Real,
    time_lo: Real,
    h_slip: Real,
    h_accepted: Real,
    err_accepted: Real,
    _pad: Real,
    segment: vec2<u32>,
    mode: u32,
    period: u32,
    status: u32,
    steps: u32,
    stalled: u32,
    rejections: u32,
    measured: u32,
    // GPU only (entry.wgsl): dispatches in a row in which the driver's
    // loop limiter cut this instance's first iteration short.
    limited: u32,
    _pad_v: vec2<u32>,
}

fn initial_state() -> State {
    let c = &coefficients[held];
    let p = frac(c.phase);
    let rising = p < c.duty;
    var init: State;
    init.x_p = V2(0.0);
    init.v_p = V2(0.0);
    init.x_s = V2(0.0);
    init.v_s = V2(0.0);
    init.v_rel = V2(0.0);
    init.held = V2(0.0);
    init.settle_x_s = V2(0.0);
    init.cycle_phase = p;
    init.next_corner = select(V2(1.0), c.duty, rising);
    init.segment = select(vec2<u32>(1u), vec2<u32>(0u), rising);
    if WAVEFORM {
        let x = segment_at(c.segment_first.x, c.segment_count.x, p.x);
        let y = segment_at(c.segment_first.y, c.segment_count.y, p.y);
        init.next_corner = V2(x.corner, y.corner);
        init.segment = vec2<u32>(x.index, y.index);
    }
    init.corner_at = c.first_corner;
    init.corner_at_lo = c.first_corner_lo;
    init.time = Real(0.0);
    init.time_lo = Real(0.0);
    init.h_slip = Real(0.0);
    init.h_accepted = Real(0.0);
    init.err_accepted = Real(0.0);
    init.mode = MODE_STICK;
    init.period = 0u;
    init.status = STATUS_OK;
    init.steps = 0u;
    init.stalled = 0u;
    init.rejections = 0u;
    init.measured = 0u;
    init._pad = Real(0.0);
    if DEFLECTION {
        // At rest at zero: deflected by minus the drive's static motion.
        let drive = drive_force(init);
        init.x_p = -drive.force * c.inv_stiffness;
        init.v_p = -drive.slope * c.inv_stiffness;
    }
    return init;
}

fn is_finished(st: State) -> bool {
    let c = &coefficients[held];
    return st.status != STATUS_OK || st.period >= c.cycles || st.measured != 0u;
}

// `st.time >= t + t_lo` on two-part times (t_lo is zero unless
// CORNER_CLOCK).
fn time_reached(st: State, t: Real, t_lo: Real) -> bool {
    return st.time > t || (st.time == t && st.time_lo >= t_lo);
}

// The next stop (the period end or a drive corner) in two parts.
struct Stop {
    at: Real,
    lo: Real,
}

fn stop_time(st: State) -> Stop {
    let c = &coefficients[held];
    let corners = corner_time(st);
    let at = min(min(c.period, corners.x), corners.y);
    var lo = Real(0.0);
    if CORNER_CLOCK {
        // The low part of the stop that ends first (of equal high parts,
        // the earlier one).
        let corners_lo = corner_time_lo(st);
        lo = INFINITY;
        if c.period == at {
            lo = c.period_lo;
        }
        if corners.x == at {
            lo = min(lo, corners_lo.x);
        }
        if corners.y == at {
            lo = min(lo, corners_lo.y);
        }
    }
    return Stop(at, lo);
}

// Returns what the iteration did (ITERATION_*), for the lane's counts.
fn iterate(st: ptr<function, State>) -> u32 {
    let c = &coefficients[held];
    if (*st).period == c.settle && (*st).time == Real(0.0) && (*st).time_lo == Real(0.0) {
        (*st).settle_x_s = (*st).x_s;
    }
    var stop = stop_time(*st);
    if time_reached(*st, stop.at, stop.lo) {
        pass_boundaries(st);
        if is_finished(*st) {
            return ITERATION_BOUNDARY;
        }
        stop = stop_time(*st);
        if time_reached(*st, stop.at, stop.lo) {
            return ITERATION_BOUNDARY;
        }
    }
    var h_max = (stop.at - (*st).time) - (*st).time_lo;
    if CORNER_CLOCK {
        h_max = (stop.at - (*st).time) + (stop.lo - (*st).time_lo);
    }
    let time_before = (*st).time;
    let time_lo_before = (*st).time_lo;
    let stuck = (*st).mode == MODE_STICK;
    let outcome = step(st, h_max, stop.at, stop.lo);
    (*st).steps += 1u;
    if outcome != STEP_REJECTED || (*st).status != STATUS_OK {
        if (*st).time > time_before || ((*st).time == time_before && (*st).time_lo > time_lo_before) {
            (*st).stalled = 0u;
        } else {
            (*st).stalled += 1u;
            if (*st).stalled > MAX_STALLED_EVENTS {
                (*st).status = STATUS_EVENT_STORM;
            }
        }
    }
    if !state_is_finite(*st) {
        (*st).status = STATUS_NON_FINITE;
    } else if (*st).steps > c.budget {
        (*st).status = STATUS_STEP_BUDGET;
    }
    return iteration_kind(outcome, stuck);
}

fn iteration_kind(outcome: u32, stuck: bool) -> u32 {
    if outcome == STEP_REJECTED {
        return ITERATION_REJECTED;
    }
    if outcome == STEP_LOCATED {
        return ITERATION_EVENT;
    }
    return select(ITERATION_SLIP, ITERATION_STICK, stuck);
}

// `f64::is_finite`, with INFINITY standing for infinity.
fn is_finite(x: Real) -> bool {
    return abs(x) < INFINITY;
}

fn is_finite2(v: V2) -> bool {
    return all(abs(v) < V2(INFINITY));
}

fn state_is_finite(st: State) -> bool {
    return is_finite(st.time) && is_finite(st.h_slip) && is_finite2(st.x_p) && is_finite2(st.v_p)
        && is_finite2(st.x_s) && is_finite2(st.v_s) && is_finite2(st.v_rel);
}
