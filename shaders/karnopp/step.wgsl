// Mirror of `laws::karnopp::integrate::step`: one step, the same code for every
// friction mode (the mode only picks the step length, the flow and the
// events watched), so the lanes of a warp in different modes run the same
// sampling, event and move instructions together.

// `StepOutcome`.
const STEP_MOVED: u32 = 0u;
const STEP_REJECTED: u32 = 1u;
const STEP_LOCATED: u32 = 2u;

// The flow of the state's mode, into the lane's `flow`.
fn mode_flow(st: State, drive: Drive, dir: DirectionModel, h: Real, inv_h: Real) {
    make_flow(st.mode == MODE_STICK, st.x_p, st.v_p, st.x_s, st.v_s, st.v_rel, drive.force, drive.slope, dir, h, inv_h);
}

// The five samples of a step (`[Sample; 5]` on the CPU): members, not an
// array; the lane's one `samples` (hold_registers.wgsl or
// hold_memory.wgsl).
struct Samples {
    s0: Sample,
    s1: Sample,
    s2: Sample,
    s3: Sample,
    s4: Sample,
}

// Which samples `sample_flow` evaluates: bit j for sample j.
const SAMPLES_ALL: u32 = 31u;
const SAMPLES_QUARTERS: u32 = 10u;

// The samples of `mask` of the flow over a step of length h, in one loop:
// one copy of the flow's evaluation, whatever the samples.
fn sample_flow(h: Real, mask: u32) {
    for (var j = 0u; j < 5u; j++) {
        if ((mask >> j) & 1u) == 0u {
            continue;
        }
        var prop = identity_propagator();
        if j == 1u {
            prop = props.quarter;
        } else if j == 2u {
            prop = props.half;
        } else if j == 3u {
            prop = props.three_quarters;
        } else if j == 4u {
            prop = props.full;
        }
        let s = eval_flow(prop, theta(j) * h);
        switch j {
            case 0u: {
                samples.s0 = s;
            }
            case 1u: {
                samples.s1 = s;
            }
            case 2u: {
                samples.s2 = s;
            }
            case 3u: {
                samples.s3 = s;
            }
            default: {
                samples.s4 = s;
            }
        }
    }
}

// The `Option<Vec2>` of `direction`.
struct Direction {
    ok: bool,
    u: V2,
}

fn direction(s: Sample) -> Direction {
    let v = relative_velocity(s);
    let n2 = dot(v, v);
    var out = Direction(false, V2(0.0));
    if n2 > Real(0.0) && is_finite(n2) {
        out.ok = true;
        out.u = v * recip_root(n2);
    }
    return out;
}

// What the phases of one step share (see step.rs).
struct Trial {
    h: Real,
    inv_h: Real,
    dir: DirectionModel,
    safe: bool,
    err: Real,
    slip_event: u32,
}

// The event a step meets first: `kind` is EVENT_NONE where it meets none.
struct StepEvent {
    kind: u32,
    tau: Real,
    grazed: bool,
}

fn step(st: ptr<function, State>, h_max: Real, stop: Real, stop_lo: Real) -> u32 {
    let c = &coefficients[held];
    let drive = drive_force(*st);
    let slipping = (*st).mode == MODE_SLIP;
    var t = trial(*st, drive, h_max);
    sample_propagators(t.h);
    collocate(*st, drive, &t);
    if slipping && c.frictionless == 0u {
        if t.err == Real(0.0) {
            t.err = direction_error(t.dir, 4u);
        }
        if t.err >= INFINITY {
            approach_trial(*st, drive, &t);
        }
        if t.err > c.tolerance {
            reject(st, t.h, t.err);
            return STEP_REJECTED;
        }
    }
    var found = find_event(*st, t);
    // One call of `move_to` for a step to its end and to an event (the
    // first half of step.rs's `take_event` is here): a driver that inlines
    // every call compiles what `move_to` calls once (the backward travel's
    // variation.wgsl).
    var moved = samples.s4;
    var tau = t.h;
    if found.kind != EVENT_NONE {
        (*st).h_accepted = Real(0.0);
        moved = eval_at(found.tau);
        tau = found.tau;
        if found.kind == EVENT_APPROACH && approach_turned(moved) {
            reject(st, t.h, INFINITY);
            return STEP_REJECTED;
        }
        // Read of the sample before the move, which leaves it unused.
        found.grazed = found.kind == EVENT_ENTER_BAND && skims_band(moved);
    }
    move_to(st, moved, tau, h_max, stop, stop_lo);
    if found.kind == EVENT_NONE {
        if slipping {
            if t.h < h_max {
                (*st).h_slip = next_slip_step(st, t.h, t.err);
            } else {
                (*st).h_slip = max((*st).h_slip, t.h);
            }
        }
    } else {
        take_event(st, t, found.kind, h_max);
    }
    if GRAZE_GUARD && c.steady == 0u && found.grazed {
        (*st).status = STATUS_GRAZE;
    }
    (*st).rejections = 0u;
    return select(STEP_LOCATED, STEP_MOVED, found.kind == EVENT_NONE);
}

// The trial of a step: its length, the direction model's constant term and
// the flow; every sample starts as the flow's start.
fn trial(st: State, drive: Drive, h_max: Real) -> Trial {
    let c = &coefficients[held];
    let stuck = st.mode == MODE_STICK;
    let slipping = st.mode == MODE_SLIP;
    var dir = DirectionModel(V2(0.0), V2(0.0), V2(0.0));
    var h = h_max;
    if slipping {
        h = min(min(st.h_slip, c.event_step_slip), h_max);
        if h <= Real(0.0) {
            h = min(c.event_step_slip, h_max);
        }
        let v = st.v_rel;
        dir.b0 = v * recip_root(dot(v, v));
    } else if st.mode == MODE_BAND {
        h = min(h_max, c.event_step_slip);
        dir.b0 = st.held;
    }
    // A slip trial's limit from the start of a flow of unit length, and one
    // reciprocal of the step length for every flow of the step (see step.rs).
    let band = st.mode == MODE_BAND;
    var inv_h = Real(1.0);
    var flow_h = Real(1.0);
    if band {
        inv_h = recip(h);
        flow_h = h;
    }
    mode_flow(st, drive, dir, flow_h, inv_h);
    let first = eval_flow(identity_propagator(), Real(0.0));
    if slipping {
        if c.frictionless == 0u {
            h = approach_limit(st.v_rel, relative_acceleration(first), h);
        }
        inv_h = recip(h);
        mode_flow(st, drive, dir, h, inv_h);
    }
    var safe = false;
    if stuck {
        let bound = dot(first.a_p, first.a_p) + dot(first.j_p * first.j_p, flow.osc.inv_w2);
        safe = c.ms2 * bound <= c.safe_hold2;
        if !safe {
            h = min(h_max, c.event_step_stuck);
        }
    }
    samples.s0 = first;
    samples.s1 = first;
    samples.s2 = first;
    samples.s3 = first;
    samples.s4 = first;
    return Trial(h, inv_h, dir, safe, Real(0.0), EVENT_ENTER_BAND);
}

// The samples of the trial. SLIP: first the collocation of the direction
// model, by the CPU's iteration with the samples evaluated at the top of
// each pass, so that the code evaluates a flow in one place (every copy of
// a flow's evaluation is code the driver compiles and the lanes fetch).
// Other modes evaluate once and leave.
fn collocate(st: State, drive: Drive, t: ptr<function, Trial>) {
    let c = &coefficients[held];
    let collocating = st.mode == MODE_SLIP && c.frictionless == 0u;
    let h = (*t).h;
    var done = !collocating;
    let u0 = (*t).dir.b0;
    var k = 0u;
    loop {
        samples.s2 = eval_flow(props.half, Real(0.5) * h);
        samples.s4 = eval_flow(props.full, h);
        if done || k == COLLOCATION_ITERATIONS {
            break;
        }
        let um = direction(samples.s2);
        let ue = direction(samples.s4);
        if !um.ok || !ue.ok {
            (*t).err = INFINITY;
            break;
        }
        let b1 = Real(4.0) * um.u - Real(3.0) * u0 - ue.u;
        let b2 = Real(2.0) * (ue.u - Real(2.0) * um.u + u0);
        let db1 = abs(b1 - (*t).dir.b1);
        let db2 = abs(b2 - (*t).dir.b2);
        let change = max(max(db1.x, db1.y), max(db2.x, db2.y));
        (*t).dir.b1 = b1;
        (*t).dir.b2 = b2;
        if change == Real(0.0) {
            break;
        }
        mode_flow(st, drive, (*t).dir, h, (*t).inv_h);
        done = change <= c.collocation_tolerance;
        k++;
    }
    // The start again where collocation changed the flow, and the
    // quarters.
    sample_flow(h, select(SAMPLES_QUARTERS, SAMPLES_QUARTERS | 1u, collocating));
}

// The relative velocity reversed within the trial: the constant direction
// of the start up to where it slows into the band (see step.rs).
fn approach_trial(st: State, drive: Drive, t: ptr<function, Trial>) {
    let h = (*t).h;
    (*t).dir = DirectionModel((*t).dir.b0, V2(0.0), V2(0.0));
    mode_flow(st, drive, (*t).dir, h, (*t).inv_h);
    sample_flow(h, SAMPLES_ALL);
    let ev = EventSamples(
        approach_event(samples.s0),
        approach_event(samples.s1),
        approach_event(samples.s2),
        approach_event(samples.s3),
        approach_event(samples.s4),
    );
    let scale = approach_scale(samples.s0);
    let entry = find_crossing(st, EVENT_APPROACH, Real(1.0), ev, scale, h);
    if entry.found {
        var before = 0u;
        for (var j = 1u; j < 5u; j++) {
            if theta(j) * h <= entry.lo {
                before = j;
            }
        }
        (*t).err = direction_error((*t).dir, before);
        (*t).slip_event = EVENT_APPROACH;
    }
}

// The first event the accepted trial meets (see step.rs).
fn find_event(st: State, t: Trial) -> StepEvent {
    let c = &coefficients[held];
    let h = t.h;
    var primary = EVENT_LEAVE_BAND;
    if st.mode == MODE_STICK {
        primary = select(EVENT_BREAKAWAY, EVENT_NONE, t.safe);
    } else if st.mode == MODE_SLIP {
        primary = t.slip_event;
    }
    let ev_primary = EventSamples(
        any_primary_event(primary, samples.s0),
        any_primary_event(primary, samples.s1),
        any_primary_event(primary, samples.s2),
        any_primary_event(primary, samples.s3),
        any_primary_event(primary, samples.s4),
    );
    let ev_reversal = EventSamples(
        reversal_event(st, samples.s0),
        reversal_event(st, samples.s1),
        reversal_event(st, samples.s2),
        reversal_event(st, samples.s3),
        reversal_event(st, samples.s4),
    );
    var sign = Real(0.0);
    for (var j = 0u; j < 5u; j++) {
        let d = event_sample(ev_reversal, j).x;
        if sign == Real(0.0) && d != Real(0.0) {
            sign = select(Real(-1.0), Real(1.0), d > Real(0.0));
        }
    }
    let watch_reversal = st.mode == MODE_BAND && sign != Real(0.0);
    var found = StepEvent(EVENT_NONE, Real(0.0), false);
    for (var k = 0u; k < 2u; k++) {
        var kind = primary;
        var kind_sign = Real(1.0);
        var scale: Real;
        if k == 0u {
            if primary == EVENT_APPROACH {
                scale = approach_scale(samples.s0);
            } else {
                scale = primary_scale(primary, samples.s0);
            }
        } else {
            kind = select(EVENT_NONE, EVENT_REVERSAL, watch_reversal);
            kind_sign = sign;
            scale = reversal_scale(st, samples.s0);
        }
        if kind == EVENT_NONE {
            continue;
        }
        // One call for both kinds (one copy of its code).
        var ev = ev_primary;
        if k == 1u {
            ev = ev_reversal;
        }
        let crossing = find_crossing(st, kind, kind_sign, ev, scale, h);
        if kind == EVENT_ENTER_BAND && !crossing.found {
            found.grazed = crossing.closest < GRAZE_MARGIN * c.band2;
        }
        if crossing.found {
            let tau = locate(st, kind, kind_sign, crossing.lo, crossing.hi);
            if found.kind == EVENT_NONE || tau < found.tau {
                found.kind = kind;
                found.tau = tau;
            }
        }
    }
    return found;
}

// The second half of step.rs's `take_event`: the mode the event (kind
// `event`), where the state has moved to, leads to (`step` has the first).
fn take_event(st: ptr<function, State>, t: Trial, event: u32, h_max: Real) {
    // One call of `start_slip` for both ways slip starts (see step.rs).
    var slip = SlipStart(false, V2(0.0));
    if event == EVENT_BREAKAWAY {
        slip = SlipStart(true, stick_force(*st));
    } else if event == EVENT_LEAVE_BAND {
        (*st).mode = MODE_SLIP;
        (*st).h_slip = initial_slip_step(*st, h_max);
    } else {
        if event == EVENT_ENTER_BAND || event == EVENT_APPROACH {
            (*st).h_slip = t.h;
        }
        slip = try_stick(st);
    }
    if slip.starts {
        start_slip(st, slip.need);
    }
}

// Whether v_rel turned on its way to the approach event at `s`: the
// approach is the band entry only while v_rel still points along the
// step's direction (see step.rs).
fn approach_turned(s: Sample) -> bool {
    let c = &coefficients[held];
    let u = direction(s);
    var turned = INFINITY;
    if u.ok {
        let d = u.u - flow.b0;
        turned = root(dot(d, d));
    }
    var allowed = c.tolerance;
    if APPROACH_NOISE {
        // f32 knows v_rel here only to the rounding of the stage's and the
        // slider's velocity changes it is the difference of (their
        // deflection form makes that all): a turn below it is not one f32
        // can see, and shorter steps, which shrink the changes, only cost
        // steps (results/gpu.md).
        let dv = abs(s.v_p - flow.v_p) + abs(s.v_s - flow.v_s);
        let v = s.v_rel;
        allowed += div(Real(4.0) * EPSILON * (dv.x + dv.y), root(max(dot(v, v), TINY)));
    }
    return turned > allowed;
}

// Whether a band entry only skims the band (see step.rs).
fn skims_band(s: Sample) -> bool {
    let c = &coefficients[held];
    let a = relative_acceleration(s);
    let va = dot(relative_velocity(s), a);
    return va * va < GRAZE_MARGIN * c.band2 * dot(a, a);
}

// The primary event of a step (the `if primary == EVENT_APPROACH` of
// step.rs).
fn any_primary_event(kind: u32, s: Sample) -> V2 {
    if kind == EVENT_APPROACH {
        return approach_event(s);
    }
    return primary_event(kind, s);
}

// The squared error of one sample after the start (see `direction_error`);
// the relative velocity of the previous sample comes in `prev_v`.
fn sample_direction_error(dir: DirectionModel, s: Sample, th: Real, prev_v: V2) -> Real {
    let v = relative_velocity(s);
    if dot(v, prev_v) <= Real(0.0) {
        return INFINITY;
    }
    let u = direction(s);
    if !u.ok {
        return INFINITY;
    }
    let model = dir.b0 + (dir.b1 + dir.b2 * th) * th;
    let d = u.u - model;
    return dot(d, d);
}

// The error at samples 1 to `last`: one root of the largest square (see
// step.rs).
fn direction_error(dir: DirectionModel, last: u32) -> Real {
    var err = Real(0.0);
    if last >= 1u {
        err = max(err, sample_direction_error(dir, samples.s1, Real(0.25), relative_velocity(samples.s0)));
    }
    if last >= 2u {
        err = max(err, sample_direction_error(dir, samples.s2, Real(0.5), relative_velocity(samples.s1)));
    }
    if last >= 3u {
        err = max(err, sample_direction_error(dir, samples.s3, Real(0.75), relative_velocity(samples.s2)));
    }
    if last >= 4u {
        err = max(err, sample_direction_error(dir, samples.s4, Real(1.0), relative_velocity(samples.s3)));
    }
    if err >= INFINITY {
        return INFINITY;
    }
    return root(err);
}

fn reject(st: ptr<function, State>, h: Real, err: Real) {
    let c = &coefficients[held];
    (*st).rejections += 1u;
    var factor = Real(0.25);
    if is_finite(err) {
        factor = step_factor(c.tolerance, err, c.tolerance, Real(0.0), Real(0.1), Real(0.9));
    }
    let shorter = h * factor;
    if shorter < c.min_step || (*st).rejections > MAX_REJECTIONS {
        (*st).status = STATUS_STEP_UNDERFLOW;
    } else {
        (*st).h_slip = shorter;
    }
}

// The plain, the predictive and the no-growth-after-rejection controllers'
// smallest step (see step.rs).
fn next_slip_step(st: ptr<function, State>, h: Real, err: Real) -> Real {
    let c = &coefficients[held];
    var allowed2 = c.tolerance;
    var err2 = Real(0.0);
    if (*st).h_accepted > Real(0.0) && (*st).err_accepted > Real(0.0) && err > Real(0.0) {
        let r = div(h, (*st).h_accepted);
        allowed2 = c.tolerance * (*st).err_accepted * (r * r * r);
        err2 = err * err;
    }
    var factor = step_factor(c.tolerance, err, allowed2, err2, Real(0.2), Real(4.0));
    if (*st).rejections > 0u {
        factor = min(factor, Real(1.0));
    }
    (*st).h_accepted = h;
    (*st).err_accepted = err;
    return h * factor;
}

// The longest slip trial toward the coming band entry, halved and rounded
// to the grid (see step.rs).
fn approach_limit(v: V2, a: V2, h: Real) -> Real {
    let c = &coefficients[held];
    let closing = -dot(v, a);
    let turning = abs(v.x * a.y - v.y * a.x);
    let reach = APPROACH_SHARE * dot(v, v);
    if !(closing > Real(0.0) && turning > c.tolerance * closing && h * closing > reach) {
        return h;
    }
    var limit = h;
    for (var k = 0u; k < MAX_SQUARINGS; k++) {
        if limit * closing <= Real(2.0) * reach {
            break;
        }
        limit *= Real(0.5);
    }
    return limit * grid_fraction(limit * closing, reach);
}

// The largest n / STEP_FACTOR_QUANTUM in [1/2, 1) with n x <= quantum bound.
fn grid_fraction(x: Real, bound: Real) -> Real {
    let scaled = STEP_FACTOR_QUANTUM * bound;
    let quantum = STEP_FACTOR_QUANTUM_U32;
    var below = quantum / 2u;
    var above = quantum;
    for (var k = 0u; k < STEP_FACTOR_BISECTIONS; k++) {
        if above - below <= 1u {
            break;
        }
        let n = (above + below) / 2u;
        if Real(n) * x <= scaled {
            below = n;
        } else {
            above = n;
        }
    }
    return Real(below) * STEP_FACTOR_GRID;
}

fn move_to(st: ptr<function, State>, s: Sample, tau: Real, h_max: Real, stop: Real, stop_lo: Real) {
    // The CPU's observer sees the motion first (variation.wgsl): where the
    // step starts and ends, kept before the move, and the step's variation
    // after it, when the sample is no longer live.
    if BACKWARD {
        follow_end((*st).period, (*st).time, s, tau);
    }
    (*st).x_p = s.x_p;
    (*st).v_p = s.v_p;
    (*st).x_s = s.x_s;
    (*st).v_s = s.v_s;
    (*st).v_rel = s.v_rel;
    if tau >= h_max {
        (*st).time = stop;
        (*st).time_lo = stop_lo;
    } else if COMPENSATED_TIME {
        let t = two_sum((*st).time, tau + (*st).time_lo);
        (*st).time = t.hi;
        (*st).time_lo = t.lo;
    } else {
        (*st).time += tau;
    }
    if BACKWARD {
        follow_step();
    }
}

fn initial_slip_step(st: State, h_max: Real) -> Real {
    let c = &coefficients[held];
    let drive = drive_force(st);
    let v0 = st.v_rel;
    let dir = DirectionModel(v0 * recip_root(dot(v0, v0)), V2(0.0), V2(0.0));
    mode_flow(st, drive, dir, Real(1.0), Real(1.0));
    let s = eval_flow(identity_propagator(), Real(0.0));
    let v = relative_velocity(s);
    let a = relative_acceleration(s);
    let speed = root(dot(v, v));
    let across = div(abs(v.x * a.y - v.y * a.x), speed);
    var turn = INFINITY;
    if across > Real(0.0) {
        turn = div(Real(0.1) * speed, across);
    }
    var h = c.event_step_slip;
    for (var k = 0u; k < MAX_SQUARINGS; k++) {
        if h <= turn {
            break;
        }
        h *= Real(0.5);
    }
    return min(h, max(h_max, Real(0.0)));
}

fn stick_force(st: State) -> V2 {
    let c = &coefficients[held];
    let drive = drive_force(st);
    if DEFLECTION {
        // F - k x_p = -k d: the force balance without the drive force.
        let v = c.stage_share * (st.v_p + drive.slope * c.inv_stiffness) + c.slider_share * st.v_s;
        return c.slider_share * (-c.damping * v - c.stiffness * st.x_p) - load_need();
    }
    let v = c.stage_share * st.v_p + c.slider_share * st.v_s;
    let p = drive.force - c.damping * v - c.stiffness * st.x_p;
    return c.slider_share * p - load_need();
}

fn slip_direction(need: V2) -> V2 {
    let c = &coefficients[held];
    let a = need * c.slip_scale;
    let b = c.slip_b;
    var lambda = max(root(dot(a, a)) - c.slip_b_max, Real(0.0));
    for (var k = 0u; k < SLIP_DIRECTION_ITERATIONS; k++) {
        let d = b + lambda;
        let r = div2(a, d);
        let q = r * r;
        let g = q.x + q.y - Real(1.0);
        let dg = Real(-2.0) * dot(q, div2(V2(1.0), d));
        // Stops at the root, and on NaN (no comparison holds).
        if !(g > Real(0.0)) || dg == Real(0.0) {
            break;
        }
        let next = lambda - div(g, dg);
        if !(next > lambda) {
            break;
        }
        lambda = next;
    }
    let u = div2(a, b + lambda);
    let n = root(dot(u, u));
    if n > Real(0.0) && is_finite(n) {
        return u * recip(n);
    }
    return need * recip(root(dot(need, need)));
}

fn start_slip(st: ptr<function, State>, need: V2) {
    (*st).held = slip_direction(need);
    (*st).mode = MODE_BAND;
}

// The `Option<Vec2>` of `try_stick`: whether slip starts, and along what.
struct SlipStart {
    starts: bool,
    need: V2,
}

fn try_stick(st: ptr<function, State>) -> SlipStart {
    let c = &coefficients[held];
    let need = stick_force(*st);
    if DEFLECTION {
        // The merged velocity relative to the drive's static velocity
        // (with v_s = v_p - v_rel, no difference of two speeds), and
        // absolute for the slider.
        let u = (*st).v_p - c.slider_share * (*st).v_rel;
        (*st).v_p = u;
        (*st).v_s = u + drive_force(*st).slope * c.inv_stiffness;
    } else {
        let v = c.stage_share * (*st).v_p + c.slider_share * (*st).v_s;
        (*st).v_p = v;
        (*st).v_s = v;
    }
    (*st).v_rel = V2(0.0);
    if dot(need, need) <= c.hold2 {
        (*st).mode = MODE_STICK;
        return SlipStart(false, V2(0.0));
    }
    return SlipStart(true, need);
}
