// The event-locating stick-slip integrator of `src/cpu/integrate.rs`, ported
// function by function: the same names, the same order of operations, the
// same constants. Read the Rust file for the reasoning behind every step;
// the comments here only note where WGSL forces a different shape.
//
// The shader is generic over its floating-point type. The host prepends a
// prelude (see `src/gpu/shader.rs`) that defines:
//
// * `Real`: `f32` or `f64`.
// * `EPSILON`: the machine epsilon of `Real`.
// * `TIME_EPSILON`: the relative resolution of the time within a period.
//   It equals `EPSILON` in f64; in f32 the time is kept as an unevaluated
//   sum of two numbers (`time + time_lo`), which resolves far below one
//   f32 ulp of the period.
// * `INFINITY`: the largest finite `Real`, which stands for infinity (WGSL
//   has no infinity literal); `is_finite` treats it as infinite.
// * `TINY`: the smallest magnitude `hermite_minimum` divides by.
// * `COMPENSATED_TIME`: true to keep `time_lo` (f32), false to leave it
//   zero (f64, where the arithmetic is then exactly that of the CPU).
// * `NOISE`: rounding noise allowed for in the friction-direction error, in
//   units of EPSILON times the speeds involved; zero in f64.
// * `WORKGROUP_SIZE`: from `pidm::gpu::WORKGROUP_SIZE`.
// * `ACTIVE_AXES`: 2, or 1 for the 1-DOF specialisation that the host picks
//   when axis y is undriven in every instance of a batch. Every per-axis
//   loop runs over the active axes only; an inactive axis keeps its
//   zero-initialised state, which is exactly what an undriven axis does in
//   the 2-DOF integrator (MODEL.md: y stays exactly 0).
//
// The code is unit-agnostic: the f64 host packs SI units, the f32 host
// micrometres and milliseconds (`src/gpu/layout.rs`).
//
// WGSL has no enums, options, tuples or early returns of several values:
// those become small structs with flags. Every loop is bounded. Beyond the
// port, `advance` checks after every iteration whether the driver's loop
// limiter cut it short (`loop_limiter_intact`) and then undoes it.

const AXES: u32 = 2u;

// Friction modes.
const MODE_STICK: u32 = 0u;
const MODE_SLIP: u32 = 1u;
const MODE_BAND: u32 = 2u;

// Final statuses.
const STATUS_OK: u32 = 0u;
const STATUS_STEP_BUDGET: u32 = 1u;
const STATUS_NON_FINITE: u32 = 2u;
const STATUS_STEP_UNDERFLOW: u32 = 3u;
const STATUS_EVENT_STORM: u32 = 4u;
// GPU only: one iteration of `advance` needs more loop iterations than the
// driver allows one invocation (see `loop_limiter_intact`).
const STATUS_LOOP_LIMIT: u32 = 100u;

// Event functions (the `EventKind` of the Rust file).
const EVENT_BREAKAWAY: u32 = 0u;
const EVENT_ENTER_BAND: u32 = 1u;
const EVENT_LEAVE_BAND: u32 = 2u;
const EVENT_REVERSAL: u32 = 3u;

const TAYLOR_TERMS: u32 = 14u;
const EVENT_STEP_PERIODS: Real = Real(0.25);
const COLLOCATION_ITERATIONS: u32 = 4u;
const COLLOCATION_CONVERGED: Real = Real(1e-2);
const TAYLOR_STAGE_TERMS: u32 = 21u;
const SLIP_DIRECTION_ITERATIONS: u32 = 40u;
const EVENT_NOISE: Real = Real(16.0);
const ROOT_ITERATIONS: u32 = 80u;
const MAX_STALLED_EVENTS: u32 = 64u;
const MAX_REJECTIONS: u32 = 60u;
const PI: Real = Real(3.141592653589793);

// One actuator + stage axis and its drive, as `pidm::model::Axis`.
struct Axis {
    stage_mass: Real,
    stiffness: Real,
    damping: Real,
    gain: Real,
    voltage: Real,
    frequency: Real,
    duty: Real,
    phase: Real,
}

// The friction interface, as `pidm::model::Mechanism`.
struct Mechanism {
    slider_mass: Real,
    holding_friction: Real,
    coulomb_friction: Real,
    velocity_band: Real,
}

// One instance, as `pidm::model::Instance`, with the derived quantities the
// Rust code computes on the fly packed by the host in f64: the scene period
// (`Instance::period`) and each axis' drive cycles per scene period.
struct Instance {
    mechanism: Mechanism,
    axes: array<Axis, AXES>,
    period: Real,
    cycles_per_period: array<Real, AXES>,
    cycles: u32,
    settle: u32,
}

// The integrator settings, as `pidm::cpu::integrate::Settings`.
struct Settings {
    tolerance: Real,
    max_steps_per_period: u32,
    _pad: u32,
}

// Everything the shader reads about one instance.
struct Params {
    inst: Instance,
    settings: Settings,
}

// The integrator state, as `pidm::cpu::integrate::State`, plus `time_lo`,
// the low part of the time (always zero unless COMPENSATED_TIME).
struct State {
    x_p: array<Real, AXES>,
    v_p: array<Real, AXES>,
    x_s: array<Real, AXES>,
    v_s: array<Real, AXES>,
    held: array<Real, AXES>,
    settle_x_s: array<Real, AXES>,
    cycle_phase: array<Real, AXES>,
    next_corner: array<Real, AXES>,
    time: Real,
    time_lo: Real,
    h_slip: Real,
    rising: array<u32, AXES>,
    mode: u32,
    period: u32,
    status: u32,
    steps: u32,
    stalled: u32,
    _pad: u32,
}

// The per-dispatch controls, read from a small storage buffer.
struct Control {
    // Iterations of `advance` in this dispatch.
    max_iterations: u32,
    // 1 when the states must first be set to `initial_state`.
    initialize: u32,
    // Always 1.0; see `move_to`.
    one: f32,
    // Passes of the loop-limiter probe, and the passes it must see; see
    // `loop_limiter_intact`.
    probe: u32,
    probe_min: u32,
    // Always 0; see `loop_limiter_intact`.
    zero: u32,
}

// exp(A tau) = (1 + a0m1) I + a1 A; see `Propagator` in integrate.rs.
struct Propagator {
    a0m1: Real,
    a1: Real,
}

struct Oscillator {
    mass: Real,
    damping: Real,
    stiffness: Real,
    sigma: Real,
    w2: Real,
}

struct AxisFlow {
    osc: Oscillator,
    part: array<Real, 3>,
    y0: Real,
    w0: Real,
    x_p0: Real,
    x_s0: Real,
    v_s0: Real,
    slider_acc: array<Real, 3>,
    force: array<Real, 3>,
    x_p: Real,
    v_p: Real,
    taylor: bool,
}

struct Flow {
    axes: array<AxisFlow, AXES>,
    stuck: bool,
    h: Real,
}

struct Sample {
    x_p: array<Real, AXES>,
    v_p: array<Real, AXES>,
    a_p: array<Real, AXES>,
    j_p: array<Real, AXES>,
    x_s: array<Real, AXES>,
    v_s: array<Real, AXES>,
    a_s: array<Real, AXES>,
}

// The `Option<(f64, f64)>` bracket of `find_crossing`.
struct Crossing {
    found: bool,
    lo: Real,
    hi: Real,
}

// The `Option<[f64; AXES]>` of `direction`.
struct Direction {
    ok: bool,
    u: array<Real, AXES>,
}

// The `(Flow, [Sample; 5], f64)` of `slip_trial`.
struct Trial {
    flow: Flow,
    samples: array<Sample, 5>,
    err: Real,
}

@group(0) @binding(0) var<storage, read> params: array<Params>;
@group(0) @binding(1) var<storage, read_write> states: array<State>;
// The controls live in a storage buffer, not a uniform: drivers may
// specialise a shader on the values of uniforms that steer its loops, which
// would unroll the loop-limiter probe and fold the opaque 1.0 away.
@group(0) @binding(2) var<storage, read> control: Control;
@group(0) @binding(3) var<storage, read_write> unfinished: atomic<u32>;

// Runs one slice of `advance` for one instance, then counts it if it has
// not finished.
@compute @workgroup_size(WORKGROUP_SIZE)
fn advance_slice(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let index = gid.x + gid.y * groups.x * WORKGROUP_SIZE;
    if index >= arrayLength(&states) || index >= arrayLength(&params) {
        return;
    }
    let p = params[index];
    var st: State;
    if control.initialize == 1u {
        st = initial_state(p.inst);
    } else {
        st = states[index];
    }
    advance(p.inst, p.settings, &st, control.max_iterations);
    states[index] = st;
    if !is_finished(p.inst, st) {
        atomicAdd(&unfinished, 1u);
    }
}

// Fractions of a step at which every step is sampled (`THETA[j]`).
fn theta(j: u32) -> Real {
    return Real(0.25) * Real(j);
}

// `f64::is_finite`, with INFINITY standing for infinity.
fn is_finite(x: Real) -> bool {
    return abs(x) < INFINITY;
}

// `f64::cbrt` from an f32 power (Vulkan has no 64-bit `pow`) polished by two
// Newton steps in Real. Only step-size factors use it.
fn cbrt(x: Real) -> Real {
    let c = clamp(x, Real(1e-30), Real(1e30));
    var y = Real(pow(f32(c), 1.0 / 3.0));
    for (var k = 0u; k < 2u; k++) {
        y = y - (y * y * y - c) / (Real(3.0) * y * y);
    }
    return y;
}

// `(max_steps_per_period as u64) * (cycles as u64)`, saturated at u32::MAX
// (a step count in u32 can never exceed that, just as it can never exceed
// the u64 product).
fn step_budget(max_steps_per_period: u32, cycles: u32) -> u32 {
    if cycles != 0u && max_steps_per_period > 0xffffffffu / cycles {
        return 0xffffffffu;
    }
    return max_steps_per_period * cycles;
}

// `st.time >= t` on the two-part time.
fn time_reached(st: State, t: Real) -> bool {
    return st.time > t || (st.time == t && st.time_lo >= Real(0.0));
}

fn initial_state(inst: Instance) -> State {
    var st: State;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        st.x_p[i] = Real(0.0);
        st.v_p[i] = Real(0.0);
        st.x_s[i] = Real(0.0);
        st.v_s[i] = Real(0.0);
        st.held[i] = Real(0.0);
        st.settle_x_s[i] = Real(0.0);
        st.cycle_phase[i] = Real(0.0);
        st.next_corner[i] = Real(0.0);
        st.rising[i] = 1u;
    }
    st.time = Real(0.0);
    st.time_lo = Real(0.0);
    st.h_slip = Real(0.0);
    st.mode = MODE_STICK;
    st.period = 0u;
    st.status = STATUS_OK;
    st.steps = 0u;
    st.stalled = 0u;
    st._pad = 0u;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let axis = inst.axes[i];
        let p = frac(axis.phase);
        st.cycle_phase[i] = p;
        if p < axis.duty {
            st.rising[i] = 1u;
            st.next_corner[i] = axis.duty;
        } else {
            st.rising[i] = 0u;
            st.next_corner[i] = Real(1.0);
        }
    }
    return st;
}

fn is_finished(inst: Instance, st: State) -> bool {
    return st.status != STATUS_OK || st.period >= inst.cycles;
}

fn advance(inst: Instance, settings: Settings, st: ptr<function, State>, max_iterations: u32) {
    let period = inst.period;
    let budget = step_budget(settings.max_steps_per_period, inst.cycles);
    var iteration = 0u;
    while iteration < max_iterations {
        iteration += 1u;
        if is_finished(inst, *st) {
            return;
        }
        let before = *st;
        if (*st).period == inst.settle && (*st).time == Real(0.0) && (*st).time_lo == Real(0.0) {
            (*st).settle_x_s = (*st).x_s;
        }
        var stop = period;
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            stop = min(stop, corner_time(inst, *st, i));
        }
        // The Rust `continue` after passing the boundaries becomes an else
        // branch, so that every iteration reaches the loop-limiter check.
        if time_reached(*st, stop) {
            pass_boundaries(inst, st, period);
        } else {
            let h_max = (stop - (*st).time) - (*st).time_lo;
            let time_before = (*st).time;
            let time_lo_before = (*st).time_lo;
            switch (*st).mode {
                case MODE_STICK: {
                    step_stick(inst, st, h_max, stop);
                }
                case MODE_SLIP: {
                    step_slip(inst, settings, st, h_max, stop, period);
                }
                default: {
                    step_band(inst, st, h_max, stop);
                }
            }
            (*st).steps += 1u;
            if (*st).time > time_before || ((*st).time == time_before && (*st).time_lo > time_lo_before) {
                (*st).stalled = 0u;
            } else {
                (*st).stalled += 1u;
                if (*st).stalled > MAX_STALLED_EVENTS {
                    (*st).status = STATUS_EVENT_STORM;
                }
            }
            if !state_is_finite(*st) {
                (*st).status = STATUS_NON_FINITE;
            } else if (*st).steps > budget {
                (*st).status = STATUS_STEP_BUDGET;
            }
        }
        // An iteration cut short by the driver's loop limiter is undone and
        // redone by the next dispatch; one that cannot fit in a dispatch at
        // all is handed back to the host (which runs it on the CPU).
        if !loop_limiter_intact((*st).steps) {
            *st = before;
            if iteration == 1u {
                (*st).status = STATUS_LOOP_LIMIT;
            }
            return;
        }
    }
}

// False once the driver's loop limiter has cut loops short in this
// invocation. llvmpipe/lavapipe share one counter of 65,535 loop iterations
// between all loops of an invocation (and its SIMD neighbours) and then
// silently leave every loop after its first pass (or two, where the
// compiler has peeled one). This loop makes `control.probe` passes unless
// the limiter runs out first. The pass count comes from the control buffer
// and depends on the state, so the compiler can neither unroll the loop nor
// hoist it out of the iteration it checks. The passes are compared with a
// second control value, not with `passes` itself: the compiler knows that
// the loop only ends once k >= passes. Other drivers have no such limiter.
fn loop_limiter_intact(dependency: u32) -> bool {
    let passes = control.probe + dependency * control.zero;
    var k = 0u;
    loop {
        k += 1u;
        if k >= passes {
            break;
        }
    }
    return k >= control.probe_min;
}

fn frac(u: Real) -> Real {
    return u - floor(u);
}

fn is_driven(axis: Axis) -> bool {
    return axis.voltage != Real(0.0);
}

fn corner_time(inst: Instance, st: State, i: u32) -> Real {
    let axis = inst.axes[i];
    if !is_driven(axis) {
        return INFINITY;
    }
    return max((st.next_corner[i] - st.cycle_phase[i]) / axis.frequency, Real(0.0));
}

// Returns (force, slope).
fn drive_force(inst: Instance, st: State, i: u32) -> array<Real, 2> {
    let axis = inst.axes[i];
    if !is_driven(axis) {
        return array<Real, 2>(Real(0.0), Real(0.0));
    }
    let amplitude = axis.gain * axis.voltage;
    let u = st.cycle_phase[i] + axis.frequency * st.time + axis.frequency * st.time_lo;
    let to_corner = max(st.next_corner[i] - u, Real(0.0));
    if st.rising[i] == 1u {
        let w = Real(1.0) - to_corner / axis.duty;
        return array<Real, 2>(amplitude * w, amplitude * axis.frequency / axis.duty);
    } else {
        let w = to_corner / (Real(1.0) - axis.duty);
        return array<Real, 2>(amplitude * w, -amplitude * axis.frequency / (Real(1.0) - axis.duty));
    }
}

fn pass_boundaries(inst: Instance, st: ptr<function, State>, period: Real) {
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        if time_reached(*st, corner_time(inst, *st, i)) {
            let duty = inst.axes[i].duty;
            if duty >= Real(1.0) {
                (*st).next_corner[i] += Real(1.0);
            } else if (*st).rising[i] == 1u {
                (*st).rising[i] = 0u;
                (*st).next_corner[i] += Real(1.0) - duty;
            } else {
                (*st).rising[i] = 1u;
                (*st).next_corner[i] += duty;
            }
        }
    }
    if time_reached(*st, period) {
        (*st).period += 1u;
        (*st).time = Real(0.0);
        (*st).time_lo = Real(0.0);
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            let axis = inst.axes[i];
            let end_phase = (*st).cycle_phase[i] + axis.frequency * period;
            let start_phase = frac(axis.phase + Real((*st).period) * inst.cycles_per_period[i]);
            let shift = round(end_phase - start_phase);
            (*st).cycle_phase[i] = start_phase;
            (*st).next_corner[i] -= shift;
        }
        if (*st).period == inst.settle {
            (*st).settle_x_s = (*st).x_s;
        }
    }
    if (*st).mode == MODE_STICK {
        let need = stick_force(inst, *st);
        let fs = inst.mechanism.holding_friction;
        if norm2(need) > fs * fs {
            start_slip(inst, st, need);
        }
    }
}

fn propagator(sigma: Real, w2: Real, tau: Real) -> Propagator {
    var scale = tau * (sqrt(w2) + Real(2.0) * sigma);
    var t = tau;
    var squarings = 0u;
    while scale > Real(0.5) && squarings < 200u {
        scale *= Real(0.5);
        t *= Real(0.5);
        squarings += 1u;
    }
    var p = Real(1.0);
    var q = Real(0.0);
    var a0m1 = Real(0.0);
    var a1 = Real(0.0);
    for (var n = 1u; n <= TAYLOR_TERMS; n++) {
        let f = t / Real(n);
        let next_p = -w2 * q * f;
        let next_q = (p - Real(2.0) * sigma * q) * f;
        p = next_p;
        q = next_q;
        a0m1 += p;
        a1 += q;
    }
    var prop = Propagator(a0m1, a1);
    for (var k = 0u; k < squarings; k++) {
        prop = compose(sigma, w2, prop, prop);
    }
    return prop;
}

fn compose(sigma: Real, w2: Real, a: Propagator, b: Propagator) -> Propagator {
    let ab = a.a1 * b.a1;
    return Propagator(
        a.a0m1 + b.a0m1 + a.a0m1 * b.a0m1 - w2 * ab,
        a.a1 + b.a1 + a.a0m1 * b.a1 + a.a1 * b.a0m1 - Real(2.0) * sigma * ab,
    );
}

fn oscillator(mass: Real, damping: Real, stiffness: Real) -> Oscillator {
    return Oscillator(mass, damping, stiffness, damping / (Real(2.0) * mass), stiffness / mass);
}

fn axis_oscillator(inst: Instance, i: u32, stuck: bool) -> Oscillator {
    let axis = inst.axes[i];
    var mass = axis.stage_mass;
    if stuck {
        mass = axis.stage_mass + inst.mechanism.slider_mass;
    }
    return oscillator(mass, axis.damping, axis.stiffness);
}

fn event_step(inst: Instance, stuck: bool) -> Real {
    var rate = Real(0.0);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let osc = axis_oscillator(inst, i, stuck);
        rate = max(rate, sqrt(osc.w2) + Real(2.0) * osc.sigma);
    }
    return EVENT_STEP_PERIODS * Real(2.0) * PI / rate;
}

fn axis_flow(osc: Oscillator, g: array<Real, 3>, x_p: Real, v_p: Real, x_s: Real, v_s: Real) -> AxisFlow {
    let x2 = g[2] / osc.stiffness;
    let x1 = (g[1] - Real(2.0) * osc.damping * x2) / osc.stiffness;
    let x0 = (g[0] - osc.damping * x1 - Real(2.0) * osc.mass * x2) / osc.stiffness;
    var f: AxisFlow;
    f.osc = osc;
    f.part = array<Real, 3>(x0, x1, x2);
    f.y0 = x_p - x0;
    f.w0 = v_p - x1;
    f.x_p0 = x_p;
    f.x_s0 = x_s;
    f.v_s0 = v_s;
    f.slider_acc = array<Real, 3>(Real(0.0), Real(0.0), Real(0.0));
    f.force = g;
    f.x_p = x_p;
    f.v_p = v_p;
    f.taylor = false;
    return f;
}

// Returns stage (x, v, a, jerk).
fn eval_stage(f: AxisFlow, prop: Propagator, tau: Real) -> array<Real, 4> {
    if f.taylor {
        return eval_stage_taylor(f, tau);
    }
    let o = f.osc;
    let dy = prop.a0m1 * f.y0 + prop.a1 * f.w0;
    let dw = prop.a0m1 * f.w0 + prop.a1 * (-o.w2 * f.y0 - Real(2.0) * o.sigma * f.w0);
    let y = f.y0 + dy;
    let w = f.w0 + dw;
    let a_h = -o.w2 * y - Real(2.0) * o.sigma * w;
    let j_h = -o.w2 * w - Real(2.0) * o.sigma * a_h;
    let x = f.x_p + (f.part[1] + f.part[2] * tau) * tau + dy;
    let v = f.v_p + Real(2.0) * f.part[2] * tau + dw;
    let a = Real(2.0) * f.part[2] + a_h;
    return array<Real, 4>(x, v, a, j_h);
}

fn eval_stage_taylor(f: AxisFlow, tau: Real) -> array<Real, 4> {
    let o = f.osc;
    let inv_m = Real(1.0) / o.mass;
    var d0 = f.x_p;
    var d1 = f.v_p;
    var d2 = (f.force[0] - o.damping * d1 - o.stiffness * d0) * inv_m;
    var d3 = (f.force[1] - o.damping * d2 - o.stiffness * d1) * inv_m;
    var t = Real(1.0);
    let rate_tau = (sqrt(o.w2) + Real(2.0) * o.sigma) * tau;
    var bound = Real(1.0);
    var x = Real(0.0);
    var v = Real(0.0);
    var a = Real(0.0);
    var j = Real(0.0);
    for (var n = 0u; n < TAYLOR_STAGE_TERMS; n++) {
        if n >= 3u && bound < Real(1e-18) {
            break;
        }
        bound *= rate_tau / Real(n + 1u);
        x += d0 * t;
        v += d1 * t;
        a += d2 * t;
        j += d3 * t;
        var g = Real(0.0);
        if n == 0u {
            g = Real(2.0) * f.force[2];
        }
        let d4 = (g - o.damping * d3 - o.stiffness * d2) * inv_m;
        d0 = d1;
        d1 = d2;
        d2 = d3;
        d3 = d4;
        t *= tau / Real(n + 1u);
    }
    return array<Real, 4>(x, v, a, j);
}

fn eval_flow(flow: Flow, props: array<Propagator, AXES>, tau: Real) -> Sample {
    var s: Sample;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let f = flow.axes[i];
        let e = eval_stage(f, props[i], tau);
        let x = e[0];
        let v = e[1];
        let a = e[2];
        s.x_p[i] = x;
        s.v_p[i] = v;
        s.a_p[i] = a;
        s.j_p[i] = e[3];
        if flow.stuck {
            s.x_s[i] = f.x_s0 + (x - f.x_p0);
            s.v_s[i] = v;
            s.a_s[i] = a;
        } else {
            let th = tau / flow.h;
            let c = f.slider_acc;
            let h = flow.h;
            s.a_s[i] = c[0] + (c[1] + c[2] * th) * th;
            s.v_s[i] = f.v_s0 + h * th * (c[0] + th * (c[1] / Real(2.0) + th * c[2] / Real(3.0)));
            s.x_s[i] = f.x_s0
                + f.v_s0 * tau
                + h * h * th * th * (c[0] / Real(2.0) + th * (c[1] / Real(6.0) + th * c[2] / Real(12.0)));
        }
    }
    return s;
}

fn eval_at(flow: Flow, tau: Real) -> Sample {
    var props: array<Propagator, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let o = flow.axes[i].osc;
        props[i] = propagator(o.sigma, o.w2, tau);
    }
    return eval_flow(flow, props, tau);
}

fn identity_propagators() -> array<Propagator, AXES> {
    return array<Propagator, AXES>(Propagator(Real(0.0), Real(0.0)), Propagator(Real(0.0), Real(0.0)));
}

fn sample_propagators(flow: Flow, h: Real) -> array<array<Propagator, AXES>, 5> {
    var out: array<array<Propagator, AXES>, 5>;
    for (var j = 0u; j < 5u; j++) {
        out[j] = identity_propagators();
    }
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let o = flow.axes[i].osc;
        let quarter = propagator(o.sigma, o.w2, Real(0.25) * h);
        let half = compose(o.sigma, o.w2, quarter, quarter);
        out[1][i] = quarter;
        out[2][i] = half;
        out[3][i] = compose(o.sigma, o.w2, half, quarter);
        out[4][i] = compose(o.sigma, o.w2, half, half);
    }
    return out;
}

fn stick_flow(inst: Instance, st: State, force: array<array<Real, 2>, AXES>) -> Flow {
    var flow: Flow;
    flow.stuck = true;
    flow.h = Real(1.0);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let osc = axis_oscillator(inst, i, true);
        flow.axes[i] = axis_flow(
            osc,
            array<Real, 3>(force[i][0], force[i][1], Real(0.0)),
            st.x_p[i],
            st.v_p[i],
            st.x_s[i],
            st.v_s[i],
        );
    }
    return flow;
}

fn slip_flow(
    inst: Instance,
    st: State,
    force: array<array<Real, 2>, AXES>,
    b: array<array<Real, 3>, AXES>,
    h: Real,
) -> Flow {
    var flow: Flow;
    flow.stuck = false;
    flow.h = h;
    let fc = inst.mechanism.coulomb_friction;
    let ms = inst.mechanism.slider_mass;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let osc = axis_oscillator(inst, i, false);
        let g = array<Real, 3>(
            force[i][0] - fc * b[i][0],
            force[i][1] - fc * b[i][1] / h,
            -fc * b[i][2] / (h * h),
        );
        var f = axis_flow(osc, g, st.x_p[i], st.v_p[i], st.x_s[i], st.v_s[i]);
        f.taylor = (b[i][1] != Real(0.0) || b[i][2] != Real(0.0))
            && (sqrt(osc.w2) + Real(2.0) * osc.sigma) * h <= Real(1.0);
        f.slider_acc = array<Real, 3>(fc / ms * b[i][0], fc / ms * b[i][1], fc / ms * b[i][2]);
        flow.axes[i] = f;
    }
    return flow;
}

fn current_force(inst: Instance, st: State) -> array<array<Real, 2>, AXES> {
    var force: array<array<Real, 2>, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        force[i] = drive_force(inst, st, i);
    }
    return force;
}

fn norm2(v: array<Real, AXES>) -> Real {
    var s = Real(0.0);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        s += v[i] * v[i];
    }
    return s;
}

// `dot` of the Rust file (WGSL's own `dot` takes vectors, not arrays).
fn dot_axes(a: array<Real, AXES>, b: array<Real, AXES>) -> Real {
    var s = Real(0.0);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        s += a[i] * b[i];
    }
    return s;
}

fn relative_velocity(s: Sample) -> array<Real, AXES> {
    var v: array<Real, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        v[i] = s.v_p[i] - s.v_s[i];
    }
    return v;
}

fn relative_acceleration(s: Sample) -> array<Real, AXES> {
    var a: array<Real, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        a[i] = s.a_p[i] - s.a_s[i];
    }
    return a;
}

fn stick_force(inst: Instance, st: State) -> array<Real, AXES> {
    let ms = inst.mechanism.slider_mass;
    var need: array<Real, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let axis = inst.axes[i];
        let force = drive_force(inst, st, i)[0];
        let mp = axis.stage_mass;
        let v = (mp * st.v_p[i] + ms * st.v_s[i]) / (mp + ms);
        let p = force - axis.damping * v - axis.stiffness * st.x_p[i];
        need[i] = ms * p / (mp + ms);
    }
    return need;
}

fn slip_direction(inst: Instance, need: array<Real, AXES>) -> array<Real, AXES> {
    let ms = inst.mechanism.slider_mass;
    let fc = inst.mechanism.coulomb_friction;
    var a: array<Real, AXES>;
    var b: array<Real, AXES>;
    var b_max = Real(0.0);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let mp = inst.axes[i].stage_mass;
        let scale = (mp + ms) / (mp * ms);
        a[i] = need[i] * scale;
        b[i] = fc * scale;
        b_max = max(b_max, b[i]);
    }
    var lambda = max(sqrt(norm2(a)) - b_max, Real(0.0));
    for (var it = 0u; it < SLIP_DIRECTION_ITERATIONS; it++) {
        var g = Real(-1.0);
        var dg = Real(0.0);
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            let d = lambda + b[i];
            let q = a[i] * a[i] / (d * d);
            g += q;
            dg -= Real(2.0) * q / d;
        }
        // Stops at the root, and on NaN (no comparison holds).
        if !(g > Real(0.0)) || dg == Real(0.0) {
            break;
        }
        let next = lambda - g / dg;
        if !(next > lambda) {
            break;
        }
        lambda = next;
    }
    var u: array<Real, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        u[i] = a[i] / (lambda + b[i]);
    }
    let n = sqrt(norm2(u));
    if n > Real(0.0) && is_finite(n) {
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            u[i] /= n;
        }
    } else {
        let m = sqrt(norm2(need));
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            u[i] = need[i] / m;
        }
    }
    return u;
}

fn start_slip(inst: Instance, st: ptr<function, State>, need: array<Real, AXES>) {
    (*st).held = slip_direction(inst, need);
    (*st).mode = MODE_BAND;
}

fn try_stick(inst: Instance, st: ptr<function, State>) {
    let need = stick_force(inst, *st);
    let fs = inst.mechanism.holding_friction;
    let ms = inst.mechanism.slider_mass;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        let mp = inst.axes[i].stage_mass;
        let v = (mp * (*st).v_p[i] + ms * (*st).v_s[i]) / (mp + ms);
        (*st).v_p[i] = v;
        (*st).v_s[i] = v;
    }
    if norm2(need) <= fs * fs {
        (*st).mode = MODE_STICK;
    } else {
        start_slip(inst, st, need);
    }
}

fn set_sample(st: ptr<function, State>, s: Sample) {
    (*st).x_p = s.x_p;
    (*st).v_p = s.v_p;
    (*st).x_s = s.x_s;
    (*st).v_s = s.v_s;
}

fn state_is_finite(st: State) -> bool {
    var ok = is_finite(st.time) && is_finite(st.h_slip);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        ok = ok
            && is_finite(st.x_p[i])
            && is_finite(st.v_p[i])
            && is_finite(st.x_s[i])
            && is_finite(st.v_s[i]);
    }
    return ok;
}

// Returns (value, time derivative).
fn event_value(inst: Instance, st: State, kind: u32, sign: Real, s: Sample) -> array<Real, 2> {
    let m = inst.mechanism;
    switch kind {
        case EVENT_BREAKAWAY: {
            let ms2 = m.slider_mass * m.slider_mass;
            let e = m.holding_friction * m.holding_friction - ms2 * norm2(s.a_p);
            return array<Real, 2>(e, Real(-2.0) * ms2 * dot_axes(s.a_p, s.j_p));
        }
        case EVENT_ENTER_BAND: {
            let v = relative_velocity(s);
            let a = relative_acceleration(s);
            return array<Real, 2>(
                norm2(v) - m.velocity_band * m.velocity_band,
                Real(2.0) * dot_axes(v, a),
            );
        }
        case EVENT_LEAVE_BAND: {
            let v = relative_velocity(s);
            let a = relative_acceleration(s);
            return array<Real, 2>(
                m.velocity_band * m.velocity_band - norm2(v),
                Real(-2.0) * dot_axes(v, a),
            );
        }
        default: {
            let v = relative_velocity(s);
            let a = relative_acceleration(s);
            return array<Real, 2>(sign * dot_axes(v, st.held), sign * dot_axes(a, st.held));
        }
    }
}

fn event_scale(inst: Instance, st: State, kind: u32, s: Sample) -> Real {
    let m = inst.mechanism;
    switch kind {
        case EVENT_BREAKAWAY: {
            // The stage acceleration is the small difference of the drive,
            // spring and damper forces, so its rounding is relative to
            // those forces, not to itself.
            var scale = m.holding_friction * m.holding_friction;
            for (var i = 0u; i < ACTIVE_AXES; i++) {
                let axis = inst.axes[i];
                let forces = axis.stiffness * abs(s.x_p[i]) + axis.damping * abs(s.v_p[i]);
                let terms = abs(s.a_p[i]) + Real(2.0) * forces / (axis.stage_mass + m.slider_mass);
                scale += m.slider_mass * m.slider_mass * Real(2.0) * abs(s.a_p[i]) * terms;
            }
            return scale;
        }
        case EVENT_ENTER_BAND, EVENT_LEAVE_BAND: {
            // The relative velocity is a difference of two velocities that
            // are often far larger (a slider sliding with its stage), so
            // its rounding is relative to those, not to itself.
            let v = relative_velocity(s);
            var scale = m.velocity_band * m.velocity_band;
            for (var i = 0u; i < ACTIVE_AXES; i++) {
                scale += Real(2.0) * abs(v[i]) * (abs(s.v_p[i]) + abs(s.v_s[i]));
            }
            return scale;
        }
        default: {
            var scale = Real(0.0);
            for (var i = 0u; i < ACTIVE_AXES; i++) {
                scale += (abs(s.v_p[i]) + abs(s.v_s[i])) * abs(st.held[i]);
            }
            return scale;
        }
    }
}

fn find_crossing(
    inst: Instance,
    st: State,
    kind: u32,
    sign: Real,
    flow: Flow,
    samples: array<Sample, 5>,
    h: Real,
) -> Crossing {
    var prev = event_value(inst, st, kind, sign, samples[0]);
    // Past the event by more than the rounding noise: fire at once; within
    // the noise: armed for the first interval (see integrate.rs).
    let noise = EVENT_NOISE * EPSILON * event_scale(inst, st, kind, samples[0]);
    if prev[0] < -noise {
        return Crossing(true, Real(0.0), Real(0.0));
    }
    for (var j = 0u; j < 4u; j++) {
        let next = event_value(inst, st, kind, sign, samples[j + 1u]);
        let lo = theta(j) * h;
        let hi = theta(j + 1u) * h;
        let armed = prev[0] > Real(0.0) || j == 0u;
        if armed && next[0] <= Real(0.0) && (prev[0] > Real(0.0) || next[0] < Real(0.0)) {
            return Crossing(true, lo, hi);
        }
        if prev[0] > Real(0.0) && next[0] > Real(0.0) && prev[1] < Real(0.0) && next[1] > Real(0.0) {
            let tau = hermite_minimum(prev, next, hi - lo);
            let e = event_value(inst, st, kind, sign, eval_at(flow, lo + tau))[0];
            if e <= Real(0.0) {
                return Crossing(true, lo, lo + tau);
            }
        }
        prev = next;
    }
    return Crossing(false, Real(0.0), Real(0.0));
}

// The `good` closure of `hermite_minimum`.
fn hermite_good(s: Real, len: Real, qa: Real, qb: Real) -> bool {
    return s > Real(0.0) && s < len && (qb + Real(2.0) * qa * s) > Real(0.0);
}

fn hermite_minimum(a: array<Real, 2>, b: array<Real, 2>, len: Real) -> Real {
    let d = (b[0] - a[0]) / len;
    let c2 = (Real(3.0) * d - Real(2.0) * a[1] - b[1]) / len;
    let c3 = (a[1] + b[1] - Real(2.0) * d) / (len * len);
    let qa = Real(3.0) * c3;
    let qb = Real(2.0) * c2;
    let qc = a[1];
    var s: Real;
    if abs(qa) < TINY || abs(qa * len) < Real(1e-12) * abs(qb) {
        s = -qc / qb;
    } else {
        let disc = sqrt(max(qb * qb - Real(4.0) * qa * qc, Real(0.0)));
        // `f64::signum`, up to the sign of a negative zero.
        let signum = select(Real(-1.0), Real(1.0), qb >= Real(0.0));
        let r = Real(-0.5) * (qb + signum * disc);
        let r1 = r / qa;
        var r2 = r1;
        if r != Real(0.0) {
            r2 = qc / r;
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
    inst: Instance,
    st: State,
    kind: u32,
    sign: Real,
    flow: Flow,
    lo_in: Real,
    hi_in: Real,
    period: Real,
) -> Real {
    var lo = lo_in;
    var hi = hi_in;
    // In f64 the second term never wins (hi <= period and TIME_EPSILON =
    // EPSILON); in f32 it stops the bisection at the resolution of tau.
    let resolution = max(Real(4.0) * TIME_EPSILON * period, Real(4.0) * EPSILON * hi);
    var tau = Real(0.5) * (lo + hi);
    for (var k = 0u; k < ROOT_ITERATIONS; k++) {
        if hi - lo <= resolution {
            break;
        }
        let ev = event_value(inst, st, kind, sign, eval_at(flow, tau));
        let e = ev[0];
        let de = ev[1];
        if e > Real(0.0) {
            lo = tau;
        } else {
            hi = tau;
        }
        let newton = tau - e / de;
        if newton > lo && newton < hi && de != Real(0.0) {
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

fn sample_step(flow: Flow, h: Real) -> array<Sample, 5> {
    let props = sample_propagators(flow, h);
    var out: array<Sample, 5>;
    for (var j = 0u; j < 5u; j++) {
        out[j] = eval_flow(flow, props[j], theta(j) * h);
    }
    return out;
}

fn move_to(st: ptr<function, State>, s: Sample, tau: Real, h_max: Real, stop: Real) {
    set_sample(st, s);
    if tau >= h_max {
        (*st).time = stop;
        (*st).time_lo = Real(0.0);
    } else if COMPENSATED_TIME {
        // Knuth's two-sum keeps the rounding error of the addition. Shader
        // compilers may simplify floating-point algebra (Mesa turns
        // a - (sum - (sum - a)) into 0); multiplying by a 1 they cannot see
        // through (it comes from the control buffer) keeps the sum exact.
        let one = Real(control.one);
        let a = (*st).time;
        let b = tau + (*st).time_lo;
        let sum = (a + b) * one;
        let bb = (sum - a) * one;
        (*st).time_lo = (a - (sum - bb)) + (b - bb);
        (*st).time = sum;
    } else {
        (*st).time += tau;
    }
}

fn step_stick(inst: Instance, st: ptr<function, State>, h_max: Real, stop: Real) {
    let force = current_force(inst, *st);
    let flow = stick_flow(inst, *st, force);
    let m = inst.mechanism;
    let s0 = eval_flow(flow, identity_propagators(), Real(0.0));
    var bound = Real(0.0);
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        bound += s0.a_p[i] * s0.a_p[i] + s0.j_p[i] * s0.j_p[i] / flow.axes[i].osc.w2;
    }
    let safe = m.slider_mass * m.slider_mass * bound <= m.holding_friction * m.holding_friction;
    var h = h_max;
    if !safe {
        h = min(h_max, event_step(inst, true));
    }
    let samples = sample_step(flow, h);
    if !safe {
        let c = find_crossing(inst, *st, EVENT_BREAKAWAY, Real(1.0), flow, samples, h);
        if c.found {
            let tau = locate(inst, *st, EVENT_BREAKAWAY, Real(1.0), flow, c.lo, c.hi, inst.period);
            let s = eval_at(flow, tau);
            move_to(st, s, tau, h_max, stop);
            let need = stick_force(inst, *st);
            start_slip(inst, st, need);
            return;
        }
    }
    move_to(st, samples[4], h, h_max, stop);
}

fn step_band(inst: Instance, st: ptr<function, State>, h_max: Real, stop: Real) {
    let force = current_force(inst, *st);
    let h = min(h_max, event_step(inst, false));
    var b: array<array<Real, 3>, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        b[i] = array<Real, 3>((*st).held[i], Real(0.0), Real(0.0));
    }
    let flow = slip_flow(inst, *st, force, b, h);
    let samples = sample_step(flow, h);
    var sign = Real(0.0);
    for (var j = 0u; j < 5u; j++) {
        let d = dot_axes(relative_velocity(samples[j]), (*st).held);
        if d != Real(0.0) {
            sign = select(Real(-1.0), Real(1.0), d > Real(0.0));
            break;
        }
    }
    let period = inst.period;
    var found = false;
    var first_tau = Real(0.0);
    var first_kind = EVENT_LEAVE_BAND;
    for (var k = 0u; k < 2u; k++) {
        let kind = select(EVENT_LEAVE_BAND, EVENT_REVERSAL, k == 1u);
        if kind == EVENT_REVERSAL && sign == Real(0.0) {
            continue;
        }
        var sg = Real(1.0);
        if kind == EVENT_REVERSAL {
            sg = sign;
        }
        let c = find_crossing(inst, *st, kind, sg, flow, samples, h);
        if c.found {
            let tau = locate(inst, *st, kind, sg, flow, c.lo, c.hi, period);
            if !found || tau < first_tau {
                found = true;
                first_tau = tau;
                first_kind = kind;
            }
        }
    }
    if found {
        let s = eval_at(flow, first_tau);
        move_to(st, s, first_tau, h_max, stop);
        if first_kind == EVENT_LEAVE_BAND {
            (*st).mode = MODE_SLIP;
            (*st).h_slip = initial_slip_step(inst, *st, h_max);
        } else {
            try_stick(inst, st);
        }
    } else {
        move_to(st, samples[4], h, h_max, stop);
    }
}

fn initial_slip_step(inst: Instance, st: State, h_max: Real) -> Real {
    let force = current_force(inst, st);
    let b = direction_poly(st);
    let flow = slip_flow(inst, st, force, b, Real(1.0));
    let s = eval_flow(flow, identity_propagators(), Real(0.0));
    let v = relative_velocity(s);
    let a = relative_acceleration(s);
    let speed = sqrt(norm2(v));
    let along = dot_axes(a, v) / speed;
    let across = sqrt(max(norm2(a) - along * along, Real(0.0)));
    var turn = INFINITY;
    if across > Real(0.0) {
        turn = Real(0.1) * speed / across;
    }
    return min(min(turn, event_step(inst, false)), max(h_max, Real(0.0)));
}

fn direction_poly(st: State) -> array<array<Real, 3>, AXES> {
    var v: array<Real, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        v[i] = st.v_p[i] - st.v_s[i];
    }
    let n = sqrt(norm2(v));
    var b: array<array<Real, 3>, AXES>;
    for (var i = 0u; i < ACTIVE_AXES; i++) {
        b[i] = array<Real, 3>(v[i] / n, Real(0.0), Real(0.0));
    }
    return b;
}

fn direction(s: Sample) -> Direction {
    let v = relative_velocity(s);
    let n = sqrt(norm2(v));
    var out: Direction;
    out.ok = n > Real(0.0) && is_finite(n);
    if out.ok {
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            out.u[i] = v[i] / n;
        }
    }
    return out;
}

fn slip_trial(
    inst: Instance,
    st: State,
    force: array<array<Real, 2>, AXES>,
    h: Real,
    tol: Real,
) -> Trial {
    var b = direction_poly(st);
    let u0 = array<Real, AXES>(b[0][0], b[1][0]);
    var flow = slip_flow(inst, st, force, b, h);
    let props = sample_propagators(flow, h);
    var mid = eval_flow(flow, props[2], Real(0.5) * h);
    var end = eval_flow(flow, props[4], h);
    // Without kinetic friction the slip motion does not depend on the
    // friction direction: there is no turn to resolve, and no step limit.
    let frictionless = inst.mechanism.coulomb_friction == Real(0.0);
    var iterations = COLLOCATION_ITERATIONS;
    if frictionless {
        iterations = 0u;
    }
    for (var k = 0u; k < iterations; k++) {
        let um = direction(mid);
        let ue = direction(end);
        if !um.ok || !ue.ok {
            return Trial(flow, array<Sample, 5>(end, end, end, end, end), INFINITY);
        }
        var change = Real(0.0);
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            let b1 = Real(4.0) * um.u[i] - Real(3.0) * u0[i] - ue.u[i];
            let b2 = Real(2.0) * (ue.u[i] - Real(2.0) * um.u[i] + u0[i]);
            change = max(max(change, abs(b1 - b[i][1])), abs(b2 - b[i][2]));
            b[i][1] = b1;
            b[i][2] = b2;
        }
        if change == Real(0.0) {
            break;
        }
        flow = slip_flow(inst, st, force, b, h);
        mid = eval_flow(flow, props[2], Real(0.5) * h);
        end = eval_flow(flow, props[4], h);
        if change <= COLLOCATION_CONVERGED * tol {
            break;
        }
    }
    let samples = array<Sample, 5>(
        eval_flow(flow, props[0], Real(0.0)),
        eval_flow(flow, props[1], Real(0.25) * h),
        mid,
        eval_flow(flow, props[3], Real(0.75) * h),
        end,
    );
    if frictionless {
        return Trial(flow, samples, Real(0.0));
    }
    var err = Real(0.0);
    var prev_v = relative_velocity(samples[0]);
    for (var j = 1u; j < 5u; j++) {
        let v = relative_velocity(samples[j]);
        if dot_axes(v, prev_v) <= Real(0.0) {
            return Trial(flow, samples, INFINITY);
        }
        prev_v = v;
        let u = direction(samples[j]);
        if !u.ok {
            return Trial(flow, samples, INFINITY);
        }
        let th = theta(j);
        var d2 = Real(0.0);
        for (var i = 0u; i < ACTIVE_AXES; i++) {
            let model = b[i][0] + (b[i][1] + b[i][2] * th) * th;
            d2 += (u.u[i] - model) * (u.u[i] - model);
        }
        // Rounding noise in the relative velocity, a difference of two
        // larger velocities, is not a direction error (NOISE is zero in f64,
        // where this subtracts nothing).
        var noise = Real(0.0);
        if NOISE > Real(0.0) {
            var scale = Real(0.0);
            for (var i = 0u; i < ACTIVE_AXES; i++) {
                scale += abs(samples[j].v_p[i]) + abs(samples[j].v_s[i]);
            }
            noise = NOISE * EPSILON * scale / sqrt(norm2(v));
        }
        err = max(err, sqrt(d2) - noise);
    }
    return Trial(flow, samples, err);
}

fn step_slip(
    inst: Instance,
    settings: Settings,
    st: ptr<function, State>,
    h_max: Real,
    stop: Real,
    period: Real,
) {
    let force = current_force(inst, *st);
    let tol = settings.tolerance;
    let h_event = event_step(inst, false);
    var h = min(min((*st).h_slip, h_event), h_max);
    if h <= Real(0.0) {
        h = min(h_event, h_max);
    }
    let min_step = Real(64.0) * TIME_EPSILON * period;
    var rejections = 0u;
    var trial: Trial;
    // At most MAX_REJECTIONS + 1 trials: the last rejection returns.
    for (var attempt = 0u; attempt <= MAX_REJECTIONS + 1u; attempt++) {
        trial = slip_trial(inst, *st, force, h, tol);
        if trial.err <= tol {
            break;
        }
        rejections += 1u;
        (*st).steps += 1u;
        var factor = Real(0.25);
        if is_finite(trial.err) {
            factor = clamp(Real(0.9) * cbrt(tol / trial.err), Real(0.1), Real(0.9));
        }
        h *= factor;
        if h < min_step || rejections > MAX_REJECTIONS {
            (*st).status = STATUS_STEP_UNDERFLOW;
            return;
        }
    }
    let err = trial.err;
    var growth = Real(4.0);
    if err > Real(0.0) {
        growth = clamp(Real(0.9) * cbrt(tol / err), Real(0.2), Real(4.0));
    }
    let c = find_crossing(inst, *st, EVENT_ENTER_BAND, Real(1.0), trial.flow, trial.samples, h);
    if c.found {
        let tau = locate(inst, *st, EVENT_ENTER_BAND, Real(1.0), trial.flow, c.lo, c.hi, period);
        let s = eval_at(trial.flow, tau);
        move_to(st, s, tau, h_max, stop);
        (*st).h_slip = h;
        try_stick(inst, st);
        return;
    }
    move_to(st, trial.samples[4], h, h_max, stop);
    if h < h_max {
        (*st).h_slip = h * growth;
    } else {
        (*st).h_slip = max((*st).h_slip, h);
    }
}
