// Mirror of `laws::karnopp::integrate::events`: event functions, the search for
// the first crossing among a step's samples, and its location.

// The first bracket of a crossing in step time.
struct Crossing {
    found: bool,
    lo: Real,
    hi: Real,
    // The smallest positive value at a dip that did not cross.
    closest: Real,
}

// Fractions of a step at which every step is sampled (`THETA[j]`).
fn theta(j: u32) -> Real {
    return Real(0.25) * Real(j);
}

fn relative_velocity(s: Sample) -> V2 {
    return s.v_rel;
}

fn relative_acceleration(s: Sample) -> V2 {
    return s.a_p - s.a_s;
}

// Value and time derivative of the primary event of a kind.
fn primary_event(kind: u32, s: Sample) -> V2 {
    let c = &coefficients[held];
    if kind == EVENT_BREAKAWAY {
        // f_need = m_s a_p - L = m_s (a_p - L / m_s) (docs/model.md section 7).
        let a = s.a_p - load_accel();
        let e = c.hold2 - c.ms2 * dot(a, a);
        return V2(e, -c.two_ms2 * dot(a, s.j_p));
    }
    let v = relative_velocity(s);
    let a = relative_acceleration(s);
    let e = dot(v, v) - c.band2;
    let de = Real(2.0) * dot(v, a);
    if kind == EVENT_ENTER_BAND {
        return V2(e, de);
    }
    return V2(-e, -de);
}

fn approach_event(s: Sample) -> V2 {
    let c = &coefficients[held];
    return V2(dot(relative_velocity(s), flow.b0) - c.band, dot(relative_acceleration(s), flow.b0));
}

fn approach_scale(s: Sample) -> Real {
    let c = &coefficients[held];
    return c.band + dot(abs(s.v_p) + abs(s.v_s), abs(flow.b0));
}

fn reversal_event(st: State, s: Sample) -> V2 {
    return V2(dot(relative_velocity(s), st.held), dot(relative_acceleration(s), st.held));
}

fn primary_scale(kind: u32, s: Sample) -> Real {
    let c = &coefficients[held];
    if kind == EVENT_BREAKAWAY {
        let forces = c.stiffness * abs(s.x_p) + c.damping * abs(s.v_p);
        let terms = abs(s.a_p) + Real(2.0) * forces * c.stick.inv_mass + abs(load_accel());
        return c.hold2 + dot(c.two_ms2 * abs(s.a_p - load_accel()), terms);
    }
    let v = relative_velocity(s);
    return c.band2 + dot(Real(2.0) * abs(v), abs(s.v_p) + abs(s.v_s));
}

fn reversal_scale(st: State, s: Sample) -> Real {
    return dot(abs(s.v_p) + abs(s.v_s), abs(st.held));
}

// The event values at the five samples of a step: five members, not an
// array, so that nothing is indexed at run time (a private array indexed at
// run time lives in memory, off-chip on NVIDIA).
struct EventSamples {
    v0: V2,
    v1: V2,
    v2: V2,
    v3: V2,
    v4: V2,
}

// `ev[j]` by selection.
fn event_sample(ev: EventSamples, j: u32) -> V2 {
    var out = ev.v0;
    out = select(out, ev.v1, j == 1u);
    out = select(out, ev.v2, j == 2u);
    out = select(out, ev.v3, j == 3u);
    return select(out, ev.v4, j == 4u);
}

// The value of event `kind` at `s`.
fn kind_event(st: State, kind: u32, s: Sample) -> V2 {
    if kind == EVENT_REVERSAL {
        return reversal_event(st, s);
    }
    return any_primary_event(kind, s);
}

fn find_crossing(
    st: State,
    kind: u32,
    sign: Real,
    ev: EventSamples,
    scale: Real,
    h: Real,
) -> Crossing {
    var prev = sign * ev.v0;
    let noise = EVENT_NOISE * EPSILON * scale;
    if prev.x < -noise {
        return Crossing(true, Real(0.0), Real(0.0), INFINITY);
    }
    var closest = INFINITY;
    for (var j = 0u; j < 4u; j++) {
        let next = sign * event_sample(ev, j + 1u);
        let lo = theta(j) * h;
        let hi = theta(j + 1u) * h;
        let armed = prev.x > Real(0.0) || j == 0u;
        if armed && next.x <= Real(0.0) && (prev.x > Real(0.0) || next.x < Real(0.0)) {
            return Crossing(true, lo, hi, closest);
        }
        if prev.x > Real(0.0) && next.x > Real(0.0) && prev.y < Real(0.0) && next.y > Real(0.0) {
            let tau = hermite_minimum(prev, next, hi - lo);
            let e = event_at(st, kind, sign, lo + tau).x;
            if e <= Real(0.0) {
                return Crossing(true, lo, lo + tau, closest);
            }
            closest = min(closest, e);
        }
        prev = next;
    }
    return Crossing(false, Real(0.0), Real(0.0), closest);
}

fn event_at(st: State, kind: u32, sign: Real, tau: Real) -> V2 {
    return sign * kind_event(st, kind, eval_at(tau));
}

// The `good` closure of `hermite_minimum`.
fn hermite_good(s: Real, len: Real, qa: Real, qb: Real) -> bool {
    return s > Real(0.0) && s < len && (qb + Real(2.0) * qa * s) > Real(0.0);
}

fn hermite_minimum(a: V2, b: V2, len: Real) -> Real {
    let d = div(b.x - a.x, len);
    let c2 = div(Real(3.0) * d - Real(2.0) * a.y - b.y, len);
    let c3 = div(a.y + b.y - Real(2.0) * d, len * len);
    let qa = Real(3.0) * c3;
    let qb = Real(2.0) * c2;
    let qc = a.y;
    var s: Real;
    if abs(qa) < TINY || abs(qa * len) < Real(1e-12) * abs(qb) {
        s = div(-qc, qb);
    } else {
        let disc = root(max(qb * qb - Real(4.0) * qa * qc, Real(0.0)));
        let signum = select(Real(-1.0), Real(1.0), qb >= Real(0.0));
        let r = Real(-0.5) * (qb + signum * disc);
        let r1 = div(r, qa);
        var r2 = r1;
        if r != Real(0.0) {
            r2 = div(qc, r);
        }
        if hermite_good(r1, len, qa, qb) {
            s = r1;
        } else if hermite_good(r2, len, qa, qb) {
            s = r2;
        } else {
            s = Real(0.5) * len;
        }
    }
    return clamp(s, Real(0.0), len);
}

fn locate(
    st: State,
    kind: u32,
    sign: Real,
    lo_in: Real,
    hi_in: Real,
) -> Real {
    let c = &coefficients[held];
    var lo = lo_in;
    var hi = hi_in;
    // In f64 the second term never wins (hi <= period and TIME_EPSILON =
    // EPSILON); in f32 it stops the bisection at the resolution of tau.
    let resolution = max(Real(4.0) * TIME_EPSILON * c.period, Real(4.0) * EPSILON * hi);
    var tau = Real(0.5) * (lo + hi);
    var checks = 0u;
    for (var k = 0u; k < ROOT_ITERATIONS; k++) {
        // The crossing found is the first only where the function is still
        // positive halfway to it (a bracket may hold three: results/events.md).
        let check = hi - lo <= resolution;
        if check {
            if checks == FIRST_ROOT_CHECKS {
                break;
            }
            checks += 1u;
            tau = Real(0.5) * (lo_in + hi);
        }
        let ev = event_at(st, kind, sign, tau);
        if check {
            if ev.x > Real(0.0) {
                break;
            }
            lo = lo_in;
        }
        if ev.x > Real(0.0) {
            lo = tau;
        } else {
            hi = tau;
        }
        let newton = tau - div(ev.x, ev.y);
        if newton > lo && newton < hi && ev.y != Real(0.0) {
            tau = newton;
        } else {
            tau = Real(0.5) * (lo + hi);
        }
        let margin = Real(1e-3) * (hi - lo);
        if tau - lo < margin || hi - tau < margin {
            tau = clamp(tau, lo + margin, hi - margin);
        }
    }
    return hi;
}
