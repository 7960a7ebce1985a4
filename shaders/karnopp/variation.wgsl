// Mirror of `laws::karnopp::variation`, with the floor's
// `laws::floor::variation` (`piece_variation`, `follow`) that it calls:
// the slider's total variation over every step the lane takes, and the
// accumulators that follow the step's measurement with it (the backward
// travel, docs/model.md section 4; issue 59). Only BACKWARD variants carry
// this file (`pidm::gpu::shader::Parts::backward`, always with the steady
// part); the others get empty twins of `follow_step` and
// `follow_period_end`. What it adds never changes the state: a BACKWARD
// variant's steps are those of the variant without it, bit for bit.
//
// The variation of measurement slot `slot` (an instance's, or a lane's
// scratch entry) is the entry `variation_slot(slot)` of the second half of
// `measures`: a Measure of the total variation instead of the slider's
// position, whose snapshots (which `follow` does not use) hold what the
// CPU's `Variation` keeps beside it: `snaps[0].x_p` the total [m],
// `snaps[0].v_p` the total when the measured periods began, the ring of
// totals at common-period ends in `snaps[k].x_s` and their count in
// `snapshots` (`pidm::gpu::karnopp::layout::double::variation_to_cpu`
// reads them back).

fn variation_slot(slot: u32) -> u32 {
    return slot + measure_entries();
}

// The slider on one axis at one instant [m, m/s, m/s^2] (`Point`).
struct Point {
    x: Real,
    v: Real,
    a: Real,
}

fn axis_point(s: Slider, axis: u32) -> Point {
    if axis == 0u {
        return Point(s.x_s.x, s.v_s.x, s.a_s.x);
    }
    return Point(s.x_s.y, s.v_s.y, s.a_s.y);
}


// Where the step being followed ends (`StepMotion`'s `at_end`), which
// `motion_sample` gives at and past its length `flow.end_tau`.
fn motion_end() -> Slider {
    return flow.end;
}

// Keeps where the step that `move_to` takes starts (`period`, `time`)
// and ends (`s`, after `tau`), for `follow_step` after the move.
fn follow_end(period: u32, time: Real, s: Sample, tau: Real) {
    flow.start_period = period;
    flow.start_time = time;
    flow.end_tau = tau;
    flow.end = Slider(s.x_p, s.v_p, s.x_s, s.v_s, s.a_s);
}

// Adds the variation of the step `follow_end` kept (the lane's flow) to
// the instance's total (the CPU's `Follower::step`).
fn follow_step() {
    let c = &coefficients[held];
    let v = variation_slot(held);
    if flow.start_period == c.settle && flow.start_time == Real(0.0) {
        measures[v].snaps[0].v_p = measures[v].snaps[0].x_p;
    }
    measures[v].snaps[0].x_p = measures[v].snaps[0].x_p + step_variation(flow.end_tau);
}

// The instance's total and its value when the measured periods began, as
// an iteration starts: what a loop-limited lane puts back where the
// driver's limiter cut the iteration short (`advance`).
fn followed_now() -> Followed {
    let v = variation_slot(held);
    return Followed(measures[v].snaps[0].x_p, measures[v].snaps[0].v_p);
}

fn follow_undo(f: Followed) {
    let v = variation_slot(held);
    measures[v].snaps[0].x_p = f.total;
    measures[v].snaps[0].v_p = f.settle;
}

// `StepMotion::sample` as the variation reads it, `tau` into the step,
// `prop` its propagator (read in stick only): in stick (whose flow has no
// Taylor form: `make_flow`) the stage's closed form, which the slider
// shares; in slip and in the band only the slider's polynomial, the
// stage's members left 0 (nothing here reads them there). Both are
// `eval_flow`'s own functions, with a fraction of its code for a driver
// that inlines every call.
fn motion_sample(prop: Propagator, tau: Real) -> Slider {
    if tau >= flow.end_tau {
        return motion_end();
    }
    let at = max(tau, Real(0.0));
    if flow.stuck != 0u {
        return stuck_slider(eval_stage(prop, at), at);
    }
    let free = slip_slider(at);
    return Slider(V2(0.0), V2(0.0), free.x_s, flow.v_s + free.dv_s, free.a_s);
}

// `StepMotion::start`.
fn motion_start() -> Slider {
    let a_p = (flow.g0 - flow.damping * flow.v_p - flow.stiffness * flow.x_p) * flow.osc.inv_mass;
    var s = Slider(flow.x_p, flow.v_p, flow.x_s, flow.v_s, flow.slider0);
    if flow.stuck != 0u {
        s.a_s = a_p;
    }
    return s;
}

// `StepMotion::drift`.
fn motion_drift(tau: Real) -> V2 {
    return flow.part1 + Real(2.0) * flow.part2 * tau;
}

// `StepMotion::ringing_energy`.
fn ringing_energy(s: Slider, tau: Real) -> V2 {
    let dy = s.x_p - flow.x_p - (flow.part1 + flow.part2 * tau) * tau;
    let y = flow.y0 + dy;
    let w = s.v_p - motion_drift(tau);
    return w * w + flow.osc.w2 * y * y;
}

// `cannot_reverse`.
fn cannot_reverse(s: Slider, tau: Real) -> bool {
    let energy = ringing_energy(s, tau);
    let d0 = motion_drift(tau);
    let d1 = motion_drift(flow.end_tau);
    let slowest = min(abs(d0), abs(d1));
    let still = energy == V2(0.0) & d0 == V2(0.0) & d1 == V2(0.0);
    return all(still | (d0 * d1 > V2(0.0) & energy < slowest * slowest * RINGING_MARGIN));
}

// `step_variation` of the lane's flow over `h`. A step in slip or in the
// band is one piece (the CPU's first branch); each `piece_pair` and
// `piece_point` is called from one place, so that a driver that inlines
// every call (llvmpipe) compiles the flow's evaluation a few times, not
// once per path to it. The pieces' ends and propagators live in the flow
// (`piece_from`, `piece_to`, `base`, `next_base`), not in registers.
fn step_variation(h: Real) -> V2 {
    if h <= Real(0.0) {
        return V2(0.0);
    }
    let stuck = flow.stuck != 0u;
    var pieces = 1u;
    if stuck {
        let rate = max(flow.osc.rate.x, flow.osc.rate.y);
        pieces = u32(clamp(ceil(div(h * rate, PIECE_RADIANS)), Real(1.0), Real(MAX_PIECES)));
    }
    flow.piece_length = div(h, Real(pieces));
    flow.piece = identity_propagator();
    if pieces > 1u {
        flow.piece = propagator(flow.piece_length);
    }
    flow.base = identity_propagator();
    flow.piece_from = motion_start();
    flow.piece_t0 = Real(0.0);
    flow.total = V2(0.0);
    for (var k = 0u; k < pieces; k++) {
        if stuck && cannot_reverse(flow.piece_from, flow.piece_t0) {
            return flow.total + abs(flow.end.x_s - flow.piece_from.x_s);
        }
        let last = k + 1u == pieces;
        flow.next_base = flow.base;
        var t1 = flow.end_tau;
        if last {
            flow.piece_to = flow.end;
        } else {
            flow.next_base = compose(flow.base, flow.piece);
            t1 = flow.piece_t0 + flow.piece_length;
            flow.piece_to = motion_sample(flow.next_base, t1);
        }
        flow.total = flow.total + piece_pair(t1 - flow.piece_t0, flow.piece_t0);
        flow.base = flow.next_base;
        flow.piece_from = flow.piece_to;
        flow.piece_t0 = t1;
    }
    return flow.total;
}

// Both axes' `piece` from `flow.piece_from` to `flow.piece_to`, `h` long, starting
// `t0` into the step (`flow.base` the propagator over `t0`).
fn piece_pair(h: Real, t0: Real) -> V2 {
    var out = V2(0.0);
    for (var axis = 0u; axis < 2u; axis++) {
        let v = piece_variation(axis_point(flow.piece_from, axis), axis_point(flow.piece_to, axis), h, t0, axis);
        if axis == 0u {
            out.x = v;
        } else {
            out.y = v;
        }
    }
    return out;
}

// The piece's `at(t)`: axis `axis` of the motion `t` into the piece.
fn piece_point(t0: Real, t: Real, axis: u32) -> Point {
    flow.point_prop = identity_propagator();
    if flow.stuck != 0u {
        flow.point_prop = propagator(t);
        flow.point_prop = compose(flow.base, flow.point_prop);
    }
    return axis_point(motion_sample(flow.point_prop, t0 + t), axis);
}

// `piece_variation` of one axis: the path from `a` through the velocity
// zeros to `b`, each zero located in its bracket by one call of
// `locate_zero`.
fn piece_variation(a: Point, b: Point, h: Real, t0: Real, axis: u32) -> Real {
    // The brackets' ends: a to b, or a to the dip m and m to b.
    var mid = b;
    var t_mid = h;
    var zeros = 0u;
    if a.v * b.v < Real(0.0) {
        zeros = 1u;
    } else {
        let t = hermite_extremum(a, b, h);
        if t < Real(0.0) {
            return abs(b.x - a.x);
        }
        let m = piece_point(t0, t, axis);
        if !(m.v * a.v < Real(0.0) || (a.v == Real(0.0) && m.v * b.v < Real(0.0))) {
            return abs(b.x - a.x);
        }
        mid = m;
        t_mid = t;
        zeros = 2u;
    }
    var total = Real(0.0);
    var last = a;
    for (var k = 0u; k < zeros; k++) {
        var lo = a;
        var t_lo = Real(0.0);
        var hi = mid;
        var t_hi = t_mid;
        if k == 1u {
            lo = mid;
            t_lo = t_mid;
            hi = b;
            t_hi = h;
        }
        let z = locate_zero(lo, t_lo, hi, t_hi, t0, axis);
        total = total + abs(z.x - last.x);
        last = z;
    }
    return total + abs(b.x - last.x);
}

// `hermite_cubic`: v(s) = c0 + c1 s + c2 s^2 + c3 s^3.
struct Cubic {
    c0: Real,
    c1: Real,
    c2: Real,
    c3: Real,
}

fn hermite_cubic(a: Point, b: Point, h: Real) -> Cubic {
    let m0 = a.a * h;
    let m1 = b.a * h;
    return Cubic(a.v, m0, Real(3.0) * (b.v - a.v) - Real(2.0) * m0 - m1, Real(2.0) * (a.v - b.v) + m0 + m1);
}

fn cubic_value(q: Cubic, s: Real) -> Real {
    return q.c0 + s * (q.c1 + s * (q.c2 + s * q.c3));
}

// `hermite_extremum` [s into the piece], or -1 where it has none.
fn hermite_extremum(a: Point, b: Point, h: Real) -> Real {
    if h <= Real(0.0) {
        return Real(-1.0);
    }
    let m0 = a.a * h;
    let m1 = b.a * h;
    if min(abs(a.v), abs(b.v)) * Real(27.0) > Real(4.0) * (abs(m0) + abs(m1)) {
        return Real(-1.0);
    }
    let q = hermite_cubic(a, b, h);
    let qa = Real(3.0) * q.c3;
    let qb = Real(2.0) * q.c2;
    let qc = q.c1;
    // The roots of v'(s), each with whether it exists (the CPU's NaN).
    var r0 = Real(0.0);
    var r1 = Real(0.0);
    var has = vec2<bool>(false);
    if abs(qa) <= Real(1e-14) * (abs(qb) + abs(qc)) {
        if qb != Real(0.0) {
            r0 = div(-qc, qb);
            has.x = true;
        }
    } else {
        let disc = qb * qb - Real(4.0) * qa * qc;
        if disc >= Real(0.0) {
            let qs = -Real(0.5) * (qb + select(Real(1.0), Real(-1.0), qb < Real(0.0)) * root(disc));
            r0 = div(qs, qa);
            has.x = true;
            if qs != Real(0.0) {
                r1 = div(qc, qs);
                has.y = true;
            }
        }
    }
    let sign = select(b.v, a.v, a.v != Real(0.0));
    if has.x && r0 > Real(0.0) && r0 < Real(1.0) && cubic_value(q, r0) * sign <= Real(0.0) {
        return r0 * h;
    }
    if has.y && r1 > Real(0.0) && r1 < Real(1.0) && cubic_value(q, r1) * sign <= Real(0.0) {
        return r1 * h;
    }
    return Real(-1.0);
}

// `hermite_root` [s after a].
fn hermite_root(a: Point, b: Point, h: Real) -> Real {
    let q = hermite_cubic(a, b, h);
    var s = div(a.v, a.v - b.v);
    for (var k = 0u; k < 4u; k++) {
        let v = cubic_value(q, s);
        let d = q.c1 + s * (Real(2.0) * q.c2 + Real(3.0) * s * q.c3);
        var next = s;
        if d != Real(0.0) {
            next = s - div(v, d);
        }
        if !(next > Real(0.0) && next < Real(1.0)) {
            break;
        }
        s = next;
    }
    return s * h;
}

// `locate`: the velocity zero between `a` (at `ta` into the piece) and
// `b` (at `tb`), the motion evaluated in one place: evaluation 0 is the
// Hermite's guess, each later one a Newton or bisection step's.
fn locate_zero(a: Point, ta: Real, b: Point, tb: Real, t0: Real, axis: u32) -> Point {
    if a.v == Real(0.0) {
        return a;
    }
    if b.v == Real(0.0) {
        return b;
    }
    var lo = ta;
    var hi = tb;
    let rising = a.v > Real(0.0);
    var t = hermite_root(a, b, tb - ta) + ta;
    var p = a;
    var settled = false;
    // A bound the compiler cannot know (`control.zero` is 0), so that it
    // keeps the loop rolled: unrolled, its 41 evaluations of the motion
    // tripled llvmpipe's compile of the whole shader.
    let most = ZERO_ITERATIONS + control.zero;
    for (var k = 0u; k <= most; k++) {
        p = piece_point(t0, t, axis);
        if k == 0u && p.a != Real(0.0) {
            let dt = div(-p.v, p.a);
            if abs(dt) <= HERMITE_GUESS * (tb - ta) && t + dt > ta && t + dt < tb {
                return Point(p.x + Real(0.5) * p.v * dt, Real(0.0), p.a);
            }
        }
        if settled || k == most || p.v == Real(0.0) {
            break;
        }
        if (p.v > Real(0.0)) == rising {
            lo = t;
        } else {
            hi = t;
        }
        var next = Real(0.5) * (lo + hi);
        if p.a != Real(0.0) {
            let newton = t - div(p.v, p.a);
            if newton > lo && newton < hi {
                next = newton;
            }
        }
        settled = abs(next - t) <= ZERO_TIME * (tb - ta);
        t = next;
    }
    return p;
}

// `follow`: records the total at the period end the step's measurement
// (slot `step`) has just processed, deciding nothing.
fn follow_period_end(step: u32) {
    let c = &coefficients[held];
    let v = variation_slot(step);
    let ended = measures[step].next_end;
    let x = measures[v].snaps[0].x_p;
    measures[v].next_end = ended;
    if ended < c.settle {
        return;
    }
    if ended > c.settle {
        let d = x - measures[v].last_x_s;
        measures[v].d_min = min(measures[v].d_min, d);
        measures[v].d_max = max(measures[v].d_max, d);
        measures[v].measured += 1u;
        measures[v].in_batch += 1u;
        if measures[v].in_batch == measures[v].batch_length {
            close_batch(v, x);
        }
    } else {
        measures[v].batch_start = x;
    }
    measures[v].last_x_s = x;
    let running = measures[v].verdict == VERDICT_RUNNING;
    let cycle_found = running && measures[step].verdict == VERDICT_PERIODIC;
    if PHASE && c.phase_levels != 0u {
        let judged = phase_period_end(v, ended - c.settle, x);
        if judged.span > 0u && running && !cycle_found {
            if c.replicas > 1u {
                measures[v].pending_level = judged.level;
            } else {
                measures[v].travel = judged.value * Real(judged.span);
                measures[v].span = judged.span;
                measures[v].se2 = judged.se2;
            }
        }
    }
    if c.common_period > 0u && (ended - c.settle) % c.common_period == 0u && running {
        if cycle_found {
            let back = measures[step].lag / c.common_period;
            measures[v].lag = measures[step].lag;
            measures[v].travel = x - measures[v].snaps[(measures[v].snapshots - back) % SNAPSHOTS].x_s;
        } else {
            measures[v].snaps[measures[v].snapshots % SNAPSHOTS].x_s = x;
            measures[v].snapshots += 1u;
        }
    }
    measures[v].verdict = measures[step].verdict;
}
