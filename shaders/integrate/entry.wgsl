// The compute entry point (GPU only; the CPU's counterpart is the loop of
// `pidm::cpu::integrate::advance`). Each invocation is a lane that works
// through instances for at most `control.max_iterations` iterations per
// dispatch, keeping the state of the instance in hand in registers and in
// the `states` buffer between dispatches. A lane whose instance finishes
// takes the next unstarted one from an atomic counter, so no lane of a warp
// idles while a slow neighbour finishes.

// The lane holds no instance.
const NO_INSTANCE: u32 = 0xffffffffu;

// The work counters of a batch.
struct Counters {
    // The next instance no lane has taken yet.
    next: atomic<u32>,
    // Instances finished (normally or not).
    finished: atomic<u32>,
}

// The per-dispatch controls, read from a small storage buffer.
struct Control {
    // Iterations of `iterate` in this dispatch.
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

@group(0) @binding(0) var<storage, read> coefficients: array<Coefficients>;
@group(0) @binding(1) var<storage, read_write> states: array<State>;
// The controls live in a storage buffer, not a uniform: drivers may
// specialise a shader on the values of uniforms that steer its loops, which
// would unroll the loop-limiter probe and fold the opaque 1.0 away.
@group(0) @binding(2) var<storage, read> control: Control;
@group(0) @binding(3) var<storage, read_write> counters: Counters;
// The instance each lane holds (the host starts lane k on instance k).
@group(0) @binding(4) var<storage, read_write> lanes: array<u32>;
// The steady measurement's accumulators per instance (measure.wgsl), read
// and written only at the period ends of steady instances; a batch of
// windows binds a single unused entry.
@group(0) @binding(5) var<storage, read_write> measures: array<Measure>;

// What the host reads of every finished steady measurement: all that the
// reduction of a periodic or phase-resolved verdict reads
// (`pidm::gpu::layout::*::Head`). The host copies the whole accumulators
// of the others only.
struct Head {
    travel: V2,
    se2: V2,
    next_end: u32,
    lag: u32,
    verdict: u32,
    span: u32,
}
// One per instance where any instance is steady, written when a steady
// instance finishes; a batch of windows binds a single unused entry.
@group(0) @binding(6) var<storage, read_write> heads: array<Head>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn advance_slice(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let lane = gid.x + gid.y * groups.x * WORKGROUP_SIZE;
    if lane >= arrayLength(&lanes) {
        return;
    }
    let count = min(arrayLength(&states), arrayLength(&coefficients));
    var index = lanes[lane];
    if index >= count {
        return;
    }
    var c = coefficients[index];
    var st: State;
    if control.initialize == 1u {
        st = initial_state(c);
        if c.steady == 1u {
            measures[index] = initial_measure(c);
        }
    } else {
        st = states[index];
    }
    var left = control.max_iterations;
    loop {
        if is_finished(c, st) {
            states[index] = st;
            if c.steady == 1u {
                heads[index] = Head(
                    measures[index].travel,
                    measures[index].se2,
                    measures[index].next_end,
                    measures[index].lag,
                    measures[index].verdict,
                    measures[index].span,
                );
            }
            atomicAdd(&counters.finished, 1u);
            index = atomicAdd(&counters.next, 1u);
            if index >= count {
                index = NO_INSTANCE;
                break;
            }
            c = coefficients[index];
            st = initial_state(c);
            if c.steady == 1u {
                measures[index] = initial_measure(c);
            }
        }
        if left == 0u {
            break;
        }
        if c.steady == 1u && at_period_end(c, st, measures[index].next_end) {
            // A period end of a steady measurement, before the iteration
            // that passes it (as the CPU's `advance_observed`); its
            // accumulators are copied in and written back only here, and
            // only once the loop limiter has let the update complete. It
            // stands outside `advance` so that the loop of iterations
            // carries none of its code (on llvmpipe that code's presence in
            // the loop slows every iteration).
            var m = measures[index];
            let before = st;
            period_end(c, &st, &m);
            if LOOP_LIMITER && !loop_limiter_intact(st.steps) {
                st = before;
                if left == control.max_iterations {
                    st.status = STATUS_LOOP_LIMIT;
                }
                break;
            }
            measures[index] = m;
            continue;
        }
        let run = advance(c, &st, index, left, left == control.max_iterations);
        left -= run.iterations;
        if run.cut {
            break;
        }
    }
    if index != NO_INSTANCE {
        states[index] = st;
    }
    lanes[lane] = index;
}

// What a call of `advance` did.
struct Advance {
    // Iterations completed.
    iterations: u32,
    // The driver's loop limiter ended the dispatch for this lane.
    cut: bool,
}

// At most `max_iterations` iterations of one instance (`index`), up to its
// end or to a steady measurement's next period end, which the lane's loop
// in `advance_slice` processes. `fresh` says the lane has completed no
// iteration in this dispatch yet.
fn advance(c: Coefficients, st: ptr<function, State>, index: u32, max_iterations: u32, fresh: bool) -> Advance {
    var iteration = 0u;
    for (; iteration < max_iterations; iteration++) {
        if is_finished(c, *st) {
            break;
        }
        if c.steady == 1u && at_period_end(c, *st, measures[index].next_end) {
            // The lane's loop processes it (above).
            break;
        }
        if LOOP_LIMITER {
            // An iteration cut short by the driver's loop limiter is undone
            // and redone by the next dispatch; one that cannot fit in a
            // whole dispatch is handed back to the host.
            let before = *st;
            iterate(c, st);
            if !loop_limiter_intact((*st).steps) {
                *st = before;
                if iteration == 0u && fresh {
                    (*st).status = STATUS_LOOP_LIMIT;
                }
                return Advance(iteration, true);
            }
        } else {
            iterate(c, st);
        }
    }
    return Advance(iteration, false);
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
// the loop only ends once k >= passes. Other drivers have no such limiter,
// and their pipelines leave it out (LOOP_LIMITER is false).
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
