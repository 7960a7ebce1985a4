// Mirror of `laws::karnopp::variation`: the slider's total variation over
// every step the lane takes (the backward travel, docs/model.md section 4;
// issue 59), with the floor's `piece_variation` and `follow` from
// `shared/variation.wgsl`, whose `piece_point` and `variation_slot` this
// file defines. Only BACKWARD variants carry the two files
// (`pidm::gpu::shader::Parts::backward`, always with the steady part); the
// others get empty twins of `follow_step` and `follow`. What they add
// never changes the state: a BACKWARD variant's steps are those of the
// variant without it, bit for bit.
//
// The variation of measurement slot `slot` (an instance's, or a lane's
// scratch entry) is the entry `variation_slot(slot)` of the second half of
// `measures`: a Measure of the total variation instead of the slider's
// position (`shared/variation.wgsl` says what its snapshots hold).

fn variation_slot(slot: u32) -> u32 {
    return slot + measure_entries();
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
