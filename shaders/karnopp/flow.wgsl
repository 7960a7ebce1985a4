// Mirror of `laws::karnopp::integrate::flow`: the closed-form motion over one
// step and its evaluation at any time inside the step.

// exp(A tau) = (1 + a0m1) I + a1 A per axis.
struct Propagator {
    a0m1: V2,
    a1: V2,
}

// The propagators at a quarter, half, three quarters and all of a step.
struct SamplePropagators {
    quarter: Propagator,
    half: Propagator,
    three_quarters: Propagator,
    full: Propagator,
}

// The state at one instant of a step, with the derivatives event functions
// need.
struct Sample {
    x_p: V2,
    v_p: V2,
    a_p: V2,
    j_p: V2,
    x_s: V2,
    v_s: V2,
    a_s: V2,
    v_rel: V2,
}

// What the variation reads of a `Sample`: the stage's position and
// velocity (the ringing's bound) and the slider's motion.
struct Slider {
    x_p: V2,
    v_p: V2,
    x_s: V2,
    v_s: V2,
    a_s: V2,
}

// The motion of both axes over one step: the lane's one `flow`
// (hold_registers.wgsl or hold_memory.wgsl), which `make_flow` writes. Its
// flags are u32s (1 true), so that it may live in device memory.
struct Flow {
    stuck: u32,
    osc: Oscillator,
    damping: V2,
    stiffness: V2,
    h: Real,
    inv_h: Real,
    part1: V2,
    part2: V2,
    y0: V2,
    w0: V2,
    x_p: V2,
    v_p: V2,
    x_s: V2,
    v_s: V2,
    v_rel: V2,
    b0: V2,
    slider0: V2,
    slider1: V2,
    slider2: V2,
    g0: V2,
    g1: V2,
    g2: V2,
    // DEFLECTION (f32): g0 - drive force, g1 - drive slope, and the drive's
    // static velocity slope / k; x_p and v_p are then the stage's
    // deflection from the drive's static position F / k and its velocity
    // relative to slope / k (see `make_flow`).
    g0_rel: V2,
    g1_rel: V2,
    ramp: V2,
    taylor: vec2<u32>,
    // The backward travel's view of the step (variation.wgsl, BACKWARD
    // variants only): its length [s] and where it ends (`end`), the half
    // period's propagator (`piece`), the propagators to a piece's start
    // and end, and the motion at both. Kept here, where an f64
    // hardware lane's flow lives in device memory, so that its registers
    // do not hold them.
    end_tau: Real,
    end: Slider,
    piece: Propagator,
    base: Propagator,
    next_base: Propagator,
    piece_from: Slider,
    piece_to: Slider,
    // Where a piece starts [s].
    piece_t0: Real,
    // Where the step moved from: its period and local time [s].
    start_time: Real,
    start_period: u32,
    // The propagator of a point inside a piece (`piece_point`).
    point_prop: Propagator,
}

// The friction direction model u(theta) = b0 + b1 theta + b2 theta^2.
struct DirectionModel {
    b0: V2,
    b1: V2,
    b2: V2,
}

fn identity_propagator() -> Propagator {
    return Propagator(V2(0.0), V2(0.0));
}

fn propagator(tau: Real) -> Propagator {
    var scale = flow.osc.rate * tau;
    var t = V2(tau);
    var squarings = vec2<u32>(0u);
    for (var k = 0u; k < MAX_SQUARINGS; k++) {
        let more = scale > V2(0.5);
        if !any(more) {
            break;
        }
        scale = select(scale, scale * Real(0.5), more);
        t = select(t, t * Real(0.5), more);
        squarings += select(vec2<u32>(0u), vec2<u32>(1u), more);
    }
    var prop = taylor_propagator(t);
    let most = max(squarings.x, squarings.y);
    for (var k = 0u; k < most; k++) {
        let squared = compose(prop, prop);
        let more = vec2<u32>(k) < squarings;
        prop = Propagator(select(prop.a0m1, squared.a0m1, more), select(prop.a1, squared.a1, more));
    }
    return prop;
}

// One term of the propagator's Taylor series: (p, q) <- (-w2 q f, (p - 2
// sigma q) f), accumulated.
struct Series {
    p: V2,
    q: V2,
    a0m1: V2,
    a1: V2,
}

fn series_term(s: ptr<function, Series>, f: V2) {
    let next_p = -flow.osc.w2 * (*s).q * f;
    let next_q = ((*s).p - Real(2.0) * flow.osc.sigma * (*s).q) * f;
    (*s).p = next_p;
    (*s).q = next_q;
    (*s).a0m1 = (*s).a0m1 + next_p;
    (*s).a1 = (*s).a1 + next_q;
}

// The TAYLOR_TERMS terms, unrolled with constant factors 1 / n, the
// prelude's INVERSE_n literals (a call of `inverse_integer` would be
// inlined, switch and all, before its argument is folded; the host checks
// that the count matches).
fn taylor_propagator(t: V2) -> Propagator {
    var s = Series(V2(1.0), V2(0.0), V2(0.0), V2(0.0));
    series_term(&s, t * INVERSE_1);
    series_term(&s, t * INVERSE_2);
    series_term(&s, t * INVERSE_3);
    series_term(&s, t * INVERSE_4);
    series_term(&s, t * INVERSE_5);
    series_term(&s, t * INVERSE_6);
    series_term(&s, t * INVERSE_7);
    series_term(&s, t * INVERSE_8);
    series_term(&s, t * INVERSE_9);
    series_term(&s, t * INVERSE_10);
    series_term(&s, t * INVERSE_11);
    series_term(&s, t * INVERSE_12);
    series_term(&s, t * INVERSE_13);
    series_term(&s, t * INVERSE_14);
    return Propagator(s.a0m1, s.a1);
}

fn compose(a: Propagator, b: Propagator) -> Propagator {
    let ab = a.a1 * b.a1;
    return Propagator(
        a.a0m1 + b.a0m1 + a.a0m1 * b.a0m1 - flow.osc.w2 * ab,
        a.a1 + b.a1 + a.a0m1 * b.a1 + a.a1 * b.a0m1 - Real(2.0) * flow.osc.sigma * ab,
    );
}

// `sample_propagators` of the lane's flow, into the lane's `props`
// (hold_registers.wgsl or hold_memory.wgsl).
fn sample_propagators(h: Real) {
    let quarter = propagator(Real(0.25) * h);
    let half = compose(quarter, quarter);
    props.quarter = quarter;
    props.half = half;
    props.three_quarters = compose(half, quarter);
    props.full = compose(half, half);
}

// `make_flow`, into the lane's `flow`.
fn make_flow(
    stuck: bool,
    x_p: V2,
    v_p: V2,
    x_s: V2,
    v_s: V2,
    v_rel: V2,
    force: V2,
    slope: V2,
    dir: DirectionModel,
    h: Real,
    inv_h: Real,
) {
    // Each member is written as soon as it is known and read back where it
    // is used, so that a lane whose flow lives in device memory holds few
    // of them at once (the CPU's arithmetic, in its order per member).
    let c = &coefficients[held];
    flow.stuck = select(0u, 1u, stuck);
    flow.h = h;
    flow.inv_h = inv_h;
    flow.x_p = x_p;
    flow.v_p = v_p;
    flow.x_s = x_s;
    flow.v_s = v_s;
    flow.v_rel = v_rel;
    flow.damping = c.damping;
    flow.stiffness = c.stiffness;
    flow.ramp = slope * c.inv_stiffness;
    flow.b0 = dir.b0;
    flow.slider0 = c.fc_over_ms * dir.b0 - neg_load_accel();
    flow.slider1 = c.fc_over_ms * dir.b1;
    flow.slider2 = c.fc_over_ms * dir.b2;
    if stuck {
        // The load acts on stage and slider as one body (docs/model.md section
        // 7): only the particular solution moves.
        flow.osc = c.stick;
        flow.g0 = force - neg_load();
        flow.g1 = slope;
        flow.g2 = V2(0.0);
        flow.g0_rel = V2(0.0) - neg_load();
        flow.g1_rel = V2(0.0);
    } else {
        flow.osc = c.slip;
        flow.g0_rel = -c.coulomb * dir.b0;
        flow.g1_rel = -c.coulomb * dir.b1 * inv_h;
        flow.g0 = force + flow.g0_rel;
        flow.g1 = slope + flow.g1_rel;
        flow.g2 = -c.coulomb * dir.b2 * (inv_h * inv_h);
    }
    // The particular solution x0 + x1 tau + x2 tau^2.
    flow.part2 = flow.g2 * c.inv_stiffness;
    flow.part1 = (flow.g1 - Real(2.0) * c.damping * flow.part2) * c.inv_stiffness;
    let x0 = (flow.g0 - c.damping * flow.part1 - Real(2.0) * flow.osc.mass * flow.part2) * c.inv_stiffness;
    flow.y0 = flow.x_p - x0;
    flow.w0 = flow.v_p - flow.part1;
    if DEFLECTION {
        // x_p and v_p are deflections (x_p - F / k, v_p - slope / k): the
        // homogeneous part's start is their sum with the small offsets of
        // the particular solution from the drive's static motion, with no
        // difference of two large positions (f32 would know it only to
        // 6e-8 of the stage's position).
        flow.y0 = flow.x_p + (c.damping * flow.part1 + Real(2.0) * flow.osc.mass * flow.part2 - flow.g0_rel) * c.inv_stiffness;
        flow.w0 = flow.v_p + (Real(2.0) * c.damping * flow.part2 - flow.g1_rel) * c.inv_stiffness;
        flow.part1 = (flow.g1_rel - Real(2.0) * c.damping * flow.part2) * c.inv_stiffness;
    }
    let turning = dir.b1 != V2(0.0) | dir.b2 != V2(0.0);
    let short = flow.osc.rate * h <= V2(1.0);
    flow.taylor = select(vec2<u32>(0u), vec2<u32>(1u), vec2<bool>(!stuck) & turning & short);
}

// Stage (x, change of v since the start, a, jerk) per axis.
struct Stage {
    x: V2,
    dv: V2,
    a: V2,
    j: V2,
}

fn eval_stage(prop: Propagator, tau: Real) -> Stage {
    let dy = prop.a0m1 * flow.y0 + prop.a1 * flow.w0;
    let dw = prop.a0m1 * flow.w0 + prop.a1 * (-flow.osc.w2 * flow.y0 - Real(2.0) * flow.osc.sigma * flow.w0);
    let y = flow.y0 + dy;
    let w = flow.w0 + dw;
    let a_h = -flow.osc.w2 * y - Real(2.0) * flow.osc.sigma * w;
    let j_h = -flow.osc.w2 * w - Real(2.0) * flow.osc.sigma * a_h;
    let x = flow.x_p + (flow.part1 + flow.part2 * tau) * tau + dy;
    let dv = Real(2.0) * flow.part2 * tau + dw;
    let a = Real(2.0) * flow.part2 + a_h;
    return Stage(x, dv, a, j_h);
}

fn eval_stage_taylor(tau: Real) -> Stage {
    var d0 = flow.x_p;
    var d1 = flow.v_p;
    var d2 = (flow.g0 - flow.damping * d1 - flow.stiffness * d0) * flow.osc.inv_mass;
    var d3 = (flow.g1 - flow.damping * d2 - flow.stiffness * d1) * flow.osc.inv_mass;
    if DEFLECTION {
        // The same derivatives from the deflections (F - k x_p = -k d).
        d2 = (flow.g0_rel - flow.damping * (d1 + flow.ramp) - flow.stiffness * d0) * flow.osc.inv_mass;
        d3 = (flow.g1_rel - flow.damping * d2 - flow.stiffness * d1) * flow.osc.inv_mass;
    }
    var t = Real(1.0);
    let rate_tau = flow.osc.rate * tau;
    var bound = V2(1.0);
    var out = Stage(V2(0.0), V2(0.0), V2(0.0), V2(0.0));
    for (var n = 0u; n < TAYLOR_STAGE_TERMS; n++) {
        let live = vec2<bool>(n < 3u) | bound >= V2(TAYLOR_STAGE_CONVERGED);
        if !any(live) {
            break;
        }
        let inv_n1 = inverse_integer(n + 1u);
        bound = select(bound, bound * rate_tau * inv_n1, live);
        out.x = select(out.x, out.x + d0 * t, live);
        if n > 0u {
            out.dv = select(out.dv, out.dv + d1 * t, live);
        }
        out.a = select(out.a, out.a + d2 * t, live);
        out.j = select(out.j, out.j + d3 * t, live);
        var g = V2(0.0);
        if n == 0u {
            g = Real(2.0) * flow.g2;
        }
        let d4 = (g - flow.damping * d3 - flow.stiffness * d2) * flow.osc.inv_mass;
        d0 = d1;
        d1 = d2;
        d2 = d3;
        d3 = d4;
        t *= tau * inv_n1;
    }
    return out;
}

fn eval_flow(prop: Propagator, tau: Real) -> Sample {
    // Each form only where an axis needs it (see flow.rs).
    var stage = Stage(V2(0.0), V2(0.0), V2(0.0), V2(0.0));
    let taylor = flow.taylor != vec2<u32>(0u);
    if !all(taylor) {
        stage = eval_stage(prop, tau);
    }
    if any(taylor) {
        let ts = eval_stage_taylor(tau);
        stage.x = select(stage.x, ts.x, taylor);
        stage.dv = select(stage.dv, ts.dv, taylor);
        stage.a = select(stage.a, ts.a, taylor);
        stage.j = select(stage.j, ts.j, taylor);
    }
    let v = flow.v_p + stage.dv;
    var s: Sample;
    s.x_p = stage.x;
    s.v_p = v;
    s.a_p = stage.a;
    s.j_p = stage.j;
    if flow.stuck != 0u {
        let rides = stuck_slider(stage, tau);
        s.x_s = rides.x_s;
        s.v_s = rides.v_s;
        s.a_s = rides.a_s;
        s.v_rel = V2(0.0);
    } else {
        let free = slip_slider(tau);
        s.x_s = free.x_s;
        s.v_s = flow.v_s + free.dv_s;
        s.a_s = free.a_s;
        s.v_rel = flow.v_rel + (stage.dv - free.dv_s);
    }
    return s;
}

// The stage and the slider stuck to it at `tau`, from the stage's motion
// there (`eval_flow`'s and the backward travel's `motion_sample`'s).
fn stuck_slider(stage: Stage, tau: Real) -> Slider {
    let v = flow.v_p + stage.dv;
    var s = Slider(stage.x, v, flow.x_s + (stage.x - flow.x_p), v, stage.a);
    if DEFLECTION {
        s.x_s = flow.x_s + ((stage.x - flow.x_p) + flow.ramp * tau);
        s.v_s = v + flow.ramp;
    }
    return s;
}

// The slider's polynomial in slip and in the band at `tau`: its position,
// its change of velocity since the step began and its acceleration.
struct SlipSlider {
    x_s: V2,
    dv_s: V2,
    a_s: V2,
}

fn slip_slider(tau: Real) -> SlipSlider {
    let th = tau * flow.inv_h;
    let h = flow.h;
    let c0 = flow.slider0;
    let c1 = flow.slider1;
    let c2 = flow.slider2;
    let x_s = flow.x_s
        + flow.v_s * tau
        + (h * h * th * th) * (c0 * Real(0.5) + (c1 * ONE_SIXTH + c2 * (ONE_TWELFTH * th)) * th);
    let dv_s = (h * th) * (c0 + (c1 * Real(0.5) + c2 * (ONE_THIRD * th)) * th);
    return SlipSlider(x_s, dv_s, c0 + (c1 + c2 * th) * th);
}

fn eval_at(tau: Real) -> Sample {
    return eval_flow(propagator(tau), tau);
}
