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

fn pick(v: V2, axis: u32) -> Real {
    return select(v.y, v.x, axis == 0u);
}

// `step_variation` of the lane's flow over `h`: a slip or band step whose
// axes are both `monotone` at once, with no loop for the lane to wait in
// (most steps); otherwise an axis at a time
// (`axis_variation`), so that `piece_variation` (and the `piece_point`
// it evaluates) is called from one place: a driver that inlines every
// call (llvmpipe) compiles the flow's evaluation a few times, not once
// per path to it. The pieces' ends and propagators live in the flow
// (`piece_from`, `piece_to`, `base`, `next_base`, `piece`), not in
// registers.
fn step_variation(h: Real) -> V2 {
    if h <= Real(0.0) {
        return V2(0.0);
    }
    if flow.stuck == 0u && slip_monotone(0u, h) && slip_monotone(1u, h) {
        return abs(flow.end.x_s - flow.x_s);
    }
    var out = V2(0.0);
    for (var axis = 0u; axis < 2u; axis++) {
        let v = axis_variation(h, axis);
        if axis == 0u {
            out.x = v;
        } else {
            out.y = v;
        }
    }
    return out;
}

// `monotone` of one axis over a slip or band step of `h`, from its start
// (`motion_start`'s slider, read where used) to its end.
fn slip_monotone(axis: u32, h: Real) -> bool {
    let a = Point(pick(flow.x_s, axis), pick(flow.v_s, axis), pick(flow.slider0, axis));
    return monotone(a, axis_point(flow.end, axis), h);
}

// One axis' variation over the step: in slip and in the band one piece
// (the CPU's `step_variation`), in stick the pieces between the ringing's
// extrema (`stick_variation`), `flow.piece` the half period's propagator.
fn axis_variation(h: Real, axis: u32) -> Real {
    let stuck = flow.stuck != 0u;
    flow.base = identity_propagator();
    flow.next_base = identity_propagator();
    flow.piece = identity_propagator();
    flow.piece_from = motion_start();
    flow.piece_t0 = Real(0.0);
    var ring = Ring(Real(0.0), Real(0.0), Real(0.0), Real(0.0));
    var half = INFINITY;
    var q = Real(1.0);
    var t1 = h;
    if stuck {
        ring = ring_of(pick(flow.part1, axis), pick(flow.osc.sigma, axis), pick(flow.osc.w2, axis));
        let cuts = ring_cuts(ring, axis_point(flow.piece_from, axis));
        half = cuts.half;
        if half < h {
            flow.piece = propagator(half);
        }
        if half < INFINITY {
            q = -(Real(1.0) + pick(flow.piece.a0m1, axis));
        }
        t1 = min(cuts.first, h);
        if t1 < h {
            flow.next_base = propagator(t1);
        }
    }
    var total = Real(0.0);
    for (var k = 0u; k < MAX_PIECES; k++) {
        let last = t1 >= h;
        if last {
            flow.piece_to = flow.end;
        } else {
            flow.piece_to = motion_sample(flow.next_base, t1);
        }
        let a = axis_point(flow.piece_from, axis);
        let b = axis_point(flow.piece_to, axis);
        let length = t1 - flow.piece_t0;
        var guess = Real(-1.0);
        if stuck {
            guess = zero_guess(ring, a, b, length);
        }
        total = total + piece_variation(a, b, length, flow.piece_t0, axis, guess);
        if last {
            return total;
        }
        if ring_settled(ring, pick(ringing_energy(flow.piece_to, t1), axis), b.v, q) {
            return total + abs(pick(flow.end.x_s, axis) - b.x);
        }
        flow.base = flow.next_base;
        flow.piece_t0 = t1;
        flow.piece_from = flow.piece_to;
        flow.next_base = compose(flow.base, flow.piece);
        t1 = min(t1 + half, h);
    }
    return total + abs(pick(flow.end.x_s, axis) - pick(flow.piece_from.x_s, axis));
}

// `Ring`: one axis' stick motion, velocity = drift + the ringing of an
// oscillator with `sigma` and `w2`, its damped frequency `omega` (0 where
// it does not ring).
struct Ring {
    drift: Real,
    sigma: Real,
    w2: Real,
    omega: Real,
}

// `Ring::new`.
fn ring_of(drift: Real, sigma: Real, w2: Real) -> Ring {
    let squared = w2 - sigma * sigma;
    var omega = Real(0.0);
    if squared > Real(0.0) {
        omega = root(squared);
    }
    return Ring(drift, sigma, w2, omega);
}

struct Cuts {
    first: Real,
    half: Real,
}

// `Ring::cuts` (INFINITY for the CPU's infinity): the phase of the
// ringing's acceleration from f32's atan2.
fn ring_cuts(r: Ring, p: Point) -> Cuts {
    let w = p.v - r.drift;
    let a = p.a;
    let jerk = -r.w2 * w - Real(2.0) * r.sigma * a;
    let none = Cuts(INFINITY, INFINITY);
    if r.omega > Real(0.0) {
        let omega = r.omega;
        let beta = div(jerk + r.sigma * a, omega);
        let scale = max(abs(a), abs(beta));
        if scale == Real(0.0) {
            return none;
        }
        var theta = atan2(f32(div(-a, scale)), f32(div(beta, scale)));
        if theta < 0.0 {
            theta += PI_F32;
        }
        if theta >= PI_F32 {
            theta -= PI_F32;
        }
        return Cuts(div(Real(theta), omega), div(PI_REAL, omega));
    }
    let mu = root(r.sigma * r.sigma - r.w2);
    let denominator = jerk + (r.sigma + mu) * a;
    if denominator == Real(0.0) {
        return none;
    }
    let u = div(-a, denominator);
    let x = f32(Real(2.0) * mu * u);
    var ratio = 1.0 - x * (0.5 - x / 3.0);
    if abs(x) >= 1e-4 {
        ratio = log(1.0 + x) / x;
    }
    let first = u * Real(ratio);
    if !(1.0 + x > 0.0) || !(first > Real(0.0)) {
        return none;
    }
    return Cuts(first, INFINITY);
}

// `Ring::zero_guess`, negative for none.
fn zero_guess(r: Ring, a: Point, b: Point, length: Real) -> Real {
    if !(a.v * b.v < Real(0.0)) || !(r.omega > Real(0.0)) {
        return Real(-1.0);
    }
    let omega = f32(r.omega);
    let sigma = f32(r.sigma);
    let drift = f32(r.drift);
    let w = f32(a.v - r.drift);
    let acc = f32(a.a);
    let jerk = -f32(r.w2) * w - 2.0 * sigma * acc;
    let sw = (acc + sigma * w) / omega;
    let sa = (jerk + sigma * acc) / omega;
    let l = f32(length);
    let s = l * (acos(f32(div(-(a.v + b.v), a.v - b.v))) * ONE_OVER_PI_F32);
    let c = cos(omega * s);
    let sn = sin(omega * s);
    let decay = exp(-sigma * s);
    let v = drift + decay * (w * c + sw * sn);
    let dv = decay * (acc * c + sa * sn);
    let newton = s - v / dv;
    if newton > 0.0 && newton < l {
        return Real(newton);
    }
    return Real(s);
}

// `Ring::settled`.
fn ring_settled(r: Ring, energy: Real, v: Real, q: Real) -> bool {
    let outrun = r.drift * v > Real(0.0) && energy < r.drift * r.drift * RINGING_MARGIN;
    let floor = RINGING_FLOOR * (Real(1.0) - q);
    return outrun || Real(16.0) * energy <= r.w2 * floor * floor;
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
