// Mirror of `laws::karnopp::integrate::drive`: the drives. A sawtooth's
// rise and fall (segments 0 and 1) come from the coefficients; other
// waveforms' segments from their buffer (`segments.wgsl`, WAVEFORM).

// Local time of each axis' next drive corner, or INFINITY where undriven.
fn corner_time(st: State) -> V2 {
    let c = &coefficients[held];
    // A division (see drive.rs).
    var t = max(div2(st.next_corner - st.cycle_phase, c.frequency), V2(0.0));
    if CORNER_CLOCK {
        t = st.corner_at;
    }
    return select(V2(INFINITY), t, c.driven == vec2<u32>(1u));
}

// The low part of `corner_time` (zero unless CORNER_CLOCK).
fn corner_time_lo(st: State) -> V2 {
    let c = &coefficients[held];
    if CORNER_CLOCK {
        return select(V2(0.0), st.corner_at_lo, c.driven == vec2<u32>(1u));
    }
    return V2(0.0);
}

// The drive force of each axis now, and its slope.
struct Drive {
    force: V2,
    slope: V2,
}

fn drive_force(st: State) -> Drive {
    let c = &coefficients[held];
    // With the two-part time (f32) the low part adds its own phase; in f64
    // it is zero and this is the CPU's sum.
    let u = st.cycle_phase + c.frequency * st.time + c.frequency * st.time_lo;
    var to_corner = max(st.next_corner - u, V2(0.0));
    if CORNER_CLOCK {
        // The distance to the corner from the two-part times: exact where
        // the step stops at the corner, and relative to itself elsewhere.
        let ahead = (st.corner_at - st.time) + (st.corner_at_lo - st.time_lo);
        to_corner = max(c.frequency * ahead, V2(0.0));
    }
    if WAVEFORM {
        return segment_drive(st, to_corner);
    }
    let rising = st.segment == vec2<u32>(0u);
    let w = select(to_corner * c.inv_fall, Real(1.0) - to_corner * c.inv_duty, rising);
    let slope = select(c.fall_slope, c.rise_slope, rising);
    return Drive(c.amplitude * w, slope);
}

// Passes every drive corner and the period end that lie at the current
// time, then lets a stuck slider break loose if a jump of the drive (duty
// 1) demands it.
fn pass_boundaries(st: ptr<function, State>) {
    let c = &coefficients[held];
    // The drive just before the corners, which DEFLECTION follows.
    var before = Drive(V2(0.0), V2(0.0));
    if DEFLECTION {
        before = drive_force(*st);
    }
    let corners = corner_time(*st);
    let corners_lo = corner_time_lo(*st);
    let reached = vec2<bool>(
        time_reached(*st, corners.x, corners_lo.x),
        time_reached(*st, corners.y, corners_lo.y),
    );
    if WAVEFORM {
        next_segments(st, reached);
    } else {
        pass_sawtooth_corners(st, reached);
    }
    if DEFLECTION {
        // The deflections follow the drive's static motion across the
        // corner: its slope changes, and its force jumps at duty 1.
        let after = drive_force(*st);
        let d = (before.force - after.force) * c.inv_stiffness;
        let u = (before.slope - after.slope) * c.inv_stiffness;
        (*st).x_p = select((*st).x_p, (*st).x_p + d, reached);
        (*st).v_p = select((*st).v_p, (*st).v_p + u, reached);
    }
    if time_reached(*st, c.period, c.period_lo) {
        if CORNER_CLOCK {
            let back = add_parts((*st).corner_at, (*st).corner_at_lo, V2(-c.period), V2(-c.period_lo));
            (*st).corner_at = back.hi;
            (*st).corner_at_lo = back.lo;
        }
        (*st).period += 1u;
        (*st).time = Real(0.0);
        (*st).time_lo = Real(0.0);
        let end_phase = (*st).cycle_phase + c.frequency * c.period;
        var start_phase = frac(c.phase + Real((*st).period) * c.cycles_per_period);
        if FIXED_PHASE {
            start_phase = fixed_start_phase((*st).period);
        }
        let shift = round(end_phase - start_phase);
        (*st).cycle_phase = start_phase;
        (*st).next_corner = (*st).next_corner - shift;
        if (*st).period == c.settle {
            (*st).settle_x_s = (*st).x_s;
        }
    }
    if (*st).mode == MODE_STICK {
        let need = stick_force(*st);
        if dot(need, need) > c.hold2 {
            start_slip(st, need);
        }
    }
}

// The sawtooth's corners at `reached`: a rise ends or begins (duty 1: one
// corner per cycle).
fn pass_sawtooth_corners(st: ptr<function, State>, reached: vec2<bool>) {
    let c = &coefficients[held];
    let jump = c.duty >= V2(1.0);
    let rising = (*st).segment == vec2<u32>(0u);
    // Duty 1: one corner per cycle; otherwise the rise ends or begins.
    let advance_by = select(select(c.duty, Real(1.0) - c.duty, rising), V2(1.0), jump);
    (*st).next_corner = select((*st).next_corner, (*st).next_corner + advance_by, reached);
    let flips = reached & !jump;
    if CORNER_CLOCK {
        // The next corner is a fall after a rise, a rise after a fall, and
        // a cycle after a jump (duty 1, whose rise_time is the cycle).
        let falls = flips & rising;
        let next = select(c.rise_time, c.fall_time, falls);
        let next_lo = select(c.rise_time_lo, c.fall_time_lo, falls);
        let moved = add_parts((*st).corner_at, (*st).corner_at_lo, next, next_lo);
        (*st).corner_at = select((*st).corner_at, moved.hi, reached);
        (*st).corner_at_lo = select((*st).corner_at_lo, moved.lo, reached);
    }
    (*st).segment = select((*st).segment, select(vec2<u32>(0u), vec2<u32>(1u), rising), flips);
}

// The high word of the 64-bit product a * b, from 16-bit halves.
fn mul_hi(a: u32, b: u32) -> u32 {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let mid = (p00 >> 16u) + (p01 & 0xffffu) + (p10 & 0xffffu);
    return a1 * b1 + (p01 >> 16u) + (p10 >> 16u) + (mid >> 16u);
}

// frac(phase + period * cycles_per_period) as an exact integer sum in
// units of 2^-32 cycles, converted once (f32 resolves the sum itself only
// to about 1e-6 cycles by the fifth period).
fn fixed_start_phase(period: u32) -> V2 {
    let c = &coefficients[held];
    let s = c.phase_fixed + period * c.cycles_fixed
        + vec2<u32>(mul_hi(period, c.cycles_fixed_lo.x), mul_hi(period, c.cycles_fixed_lo.y));
    let p = ldexp(V2(s), vec2<i32>(-32));
    return select(p, V2(0.0), p >= V2(1.0));
}

// Two-part values (CORNER_CLOCK and the two-part time): Knuth's two-sum
// keeps the rounding error of an addition. Shader compilers may simplify
// floating-point algebra (Mesa turns a - (sum - (sum - a)) into 0);
// multiplying by a 1 they cannot see through (it comes from the control
// buffer) keeps the sums exact. Mirrored by `two_sum` and `add_parts` in
// `laws::karnopp::integrate::drive`.
struct Parts {
    hi: Real,
    lo: Real,
}

struct Parts2 {
    hi: V2,
    lo: V2,
}

fn two_sum(a: Real, b: Real) -> Parts {
    let one = Real(control.one);
    let sum = (a + b) * one;
    let bb = (sum - a) * one;
    return Parts(sum, (a - (sum - bb)) + (b - bb));
}

fn two_sum2(a: V2, b: V2) -> Parts2 {
    let one = Real(control.one);
    let sum = (a + b) * one;
    let bb = (sum - a) * one;
    return Parts2(sum, (a - (sum - bb)) + (b - bb));
}

// (a_hi + a_lo) + (b_hi + b_lo) in two parts.
fn add_parts(a_hi: V2, a_lo: V2, b_hi: V2, b_lo: V2) -> Parts2 {
    let s = two_sum2(a_hi, b_hi);
    return two_sum2(s.hi, s.lo + (a_lo + b_lo));
}

fn frac(u: V2) -> V2 {
    return u - floor(u);
}
