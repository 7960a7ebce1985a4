// The compute entry point (GPU only; the CPU's counterpart is the loop of
// `pidm::laws::karnopp::integrate::advance`). Each invocation is a lane
// that works through instances for at most `control.max_iterations`
// iterations per dispatch, keeping the state of the instance in hand in
// registers and in the `states` buffer between dispatches, by the
// engine's queue (`shaders/engine/queue.wgsl`). The first dispatch of a
// batch starts every instance on a lane of its own
// (`control.initialize`), a short probe of each one's cost.

// Dispatches in a row in which the loop limiter must cut an instance's
// first iteration (or period end) short before the instance is handed to
// the CPU (STATUS_LOOP_LIMIT): lavapipe's limiter counts the loops of a
// SIMD group's lanes together, so a lane that has done nothing yet may
// find the count spent by its neighbours; an iteration that fits in no
// dispatch is cut every time.
const LIMITED_DISPATCHES: u32 = 3u;

// Counts one more dispatch that cut the instance short at its start, and
// hands it to the CPU after LIMITED_DISPATCHES of them.
fn limited_at_start(st: ptr<function, State>) {
    (*st).limited += 1u;
    if (*st).limited >= LIMITED_DISPATCHES {
        (*st).status = STATUS_LOOP_LIMIT;
    }
}

@group(0) @binding(0) var<storage, read> coefficients: array<Coefficients>;
@group(0) @binding(1) var<storage, read_write> states: array<State>;

// The instance the lane holds, whose coefficients every function reads
// where it uses them (`let c = &coefficients[held];`): a lane copies none
// of them.
var<private> held: u32;

// The lane's own entry of the buffers where an f64 hardware lane holds a
// step's flow and samples (hold_memory.wgsl).
var<private> lane_slot: u32;

@compute @workgroup_size(WORKGROUP_SIZE)
fn advance_slice(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let lane = gid.x + gid.y * groups.x * WORKGROUP_SIZE;
    if lane >= arrayLength(&lanes) {
        return;
    }
    lane_slot = lane;
    var tally: Tally;
    let count = min(arrayLength(&states), arrayLength(&coefficients));
    var index = lanes[lane];
    if index >= count {
        index = take_idle(lane);
        if index == NO_INSTANCE {
            tally.more.w = NO_INSTANCE;
            tallies[lane] = tally;
            return;
        }
        count_kind(&tally, TAKEN);
    }
    held = index;
    var st: State;
    take_state(index, control.initialize == 1u, &st);
    var left = control.max_iterations;
    loop {
        let finished = is_finished(st);
        if finished || at_cap(st.steps) {
            keep_state(index, &st);
            if finished {
                finish_measure(index);
                atomicAdd(&counters.finished, 1u);
            } else {
                park(index);
            }
            let slot = atomicAdd(&counters.next, 1u);
            if slot >= control.queued {
                index = NO_INSTANCE;
                break;
            }
            index = order[slot];
            held = index;
            load_state(index, &st);
            count_kind(&tally, TAKEN);
        }
        if left == 0u {
            break;
        }
        if at_measured_end(st, index) {
            // A period end of a steady measurement, before the iteration
            // that passes it (as the CPU's `advance_observed`), processed
            // here and not inside `advance`'s loop of iterations (on
            // llvmpipe code there slows every iteration of every instance,
            // windows included).
            if !measure_period_end(&st, index, lane, left == control.max_iterations) {
                break;
            }
            count_kind(&tally, ITERATION_PERIOD_END);
            continue;
        }
        let run = advance(&st, index, left, left == control.max_iterations, &tally);
        left -= run.iterations;
        if run.cut {
            break;
        }
    }
    // The driver's loop limiter may leave the lane's loop at any of its
    // back edges, also right after a period end that finished the instance
    // or set a replica waiting, before the loop's top hands it over. Hand
    // it over here, outside any loop: a lane never keeps an instance whose
    // state says it is done, which the host may already have queued again
    // (a replica released by its group's merge: two lanes would then run
    // it, each writing its state and accumulators).
    if index != NO_INSTANCE && is_finished(st) {
        keep_state(index, &st);
        finish_measure(index);
        atomicAdd(&counters.finished, 1u);
        index = NO_INSTANCE;
    } else if index != NO_INSTANCE && at_cap(st.steps) {
        keep_state(index, &st);
        park(index);
        index = NO_INSTANCE;
    }
    if index != NO_INSTANCE {
        keep_state(index, &st);
        tally.progress = f32(st.period) + f32(st.time) / f32(coefficients[index].period);
    }
    lanes[lane] = index;
    tally.more.w = index;
    tally.emulated = emulated;
    tallies[lane] = tally;
}

// The backward travel's total variation and its value when the measured
// periods began [m] (variation.wgsl), kept across an iteration the
// driver's loop limiter may cut short.
struct Followed {
    total: V2,
    settle: V2,
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
// iteration in this dispatch yet. Each iteration is counted in `tally`.
fn advance(
    st: ptr<function, State>,
    index: u32,
    max_iterations: u32,
    fresh: bool,
    tally: ptr<function, Tally>,
) -> Advance {
    var iteration = 0u;
    for (; iteration < max_iterations; iteration++) {
        if is_finished(*st) || at_cap((*st).steps) {
            break;
        }
        if at_measured_end(*st, index) {
            // The lane's loop processes it (above).
            break;
        }
        // An iteration cut short by the driver's loop limiter is undone
        // and redone by the next dispatch; one that cannot fit in a whole
        // dispatch is handed back to the host. One call of `iterate` for
        // both kinds of adapter: drivers inline every call before they
        // drop the branch LOOP_LIMITER rules out, so two calls would
        // compile the integrator twice.
        let before = *st;
        var followed = Followed(V2(0.0), V2(0.0));
        if LOOP_LIMITER && BACKWARD {
            followed = followed_now();
        }
        let kind = iterate(st);
        if LOOP_LIMITER {
            if !loop_limiter_intact((*st).steps) {
                *st = before;
                if BACKWARD {
                    follow_undo(followed);
                }
                if iteration == 0u && fresh {
                    limited_at_start(st);
                }
                return Advance(iteration, true);
            }
            (*st).limited = 0u;
        }
        count_kind(tally, kind);
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
