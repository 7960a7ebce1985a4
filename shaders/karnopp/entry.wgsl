// The compute entry point (GPU only; the CPU's counterpart is the loop of
// `pidm::cpu::integrate::advance`). Each invocation is a lane that works
// through instances for at most `control.max_iterations` iterations per
// dispatch, keeping the state of the instance in hand in registers and in
// the `states` buffer between dispatches. The first dispatch of a batch
// starts every instance on a lane of its own (`control.initialize`), a
// short probe of each one's cost; the host then queues the unfinished ones
// in `order`, most expensive first, and a lane whose instance finishes
// takes the next queued one from an atomic counter and continues it from
// its state, so no lane of a warp idles while instances are left
// (`pidm::gpu::runner`; the host packs the lanes still busy into fewer
// workgroups once the queue is empty). Every lane reports what it did in
// each dispatch in `tallies` (`pidm::gpu::warps`).

// The lane holds no instance.
const NO_INSTANCE: u32 = 0xffffffffu;
// The tally's count of instances taken from the queue (after the kinds of
// iteration, ITERATION_*).
const TAKEN: u32 = 6u;
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

// The work counters of a batch.
struct Counters {
    // The next position of `order` no lane has taken yet.
    next: atomic<u32>,
    // Instances finished (normally or not).
    finished: atomic<u32>,
}

// The per-dispatch controls, read from a small storage buffer.
struct Control {
    // Iterations of `iterate` in this dispatch.
    max_iterations: u32,
    // 1 when each lane's instance must first be set to `initial_state`.
    initialize: u32,
    // Always 1.0; see `move_to`.
    one: f32,
    // Passes of the loop-limiter probe, and the passes it must see; see
    // `loop_limiter_intact`.
    probe: u32,
    probe_min: u32,
    // Always 0; see `loop_limiter_intact`.
    zero: u32,
    // Entries of `order` a lane may take (0 in the first dispatch).
    queued: u32,
    // Lanes below this one that hold no instance at the start take one
    // from `order` (replicas queued again between dispatches).
    lanes: u32,
}

// What a lane did in one dispatch (`pidm::gpu::layout::Tally`).
struct Tally {
    // Iterations by kind: boundary, stick, slip, rejected trial.
    kinds: vec4<u32>,
    // Event locations, period ends, instances taken from the queue, and the
    // instance held at the end (NO_INSTANCE when none).
    more: vec4<u32>,
    // Scene periods the held instance has run, at the end.
    progress: f32,
    // Emulated f64 divisions and roots in the dispatch (the prelude's
    // `emulated`).
    emulated: u32,
    _pad_v: vec2<u32>,
}

@group(0) @binding(0) var<storage, read> coefficients: array<Coefficients>;
@group(0) @binding(1) var<storage, read_write> states: array<State>;
// The controls live in a storage buffer, not a uniform: drivers may
// specialise a shader on the values of uniforms that steer its loops, which
// would unroll the loop-limiter probe and fold the opaque 1.0 away.
@group(0) @binding(2) var<storage, read> control: Control;
@group(0) @binding(3) var<storage, read_write> counters: Counters;
// The instance each lane holds.
@group(0) @binding(4) var<storage, read_write> lanes: array<u32>;
// The queue: the instances lanes take after the first dispatch, in order.
@group(0) @binding(7) var<storage, read> order: array<u32>;
// One per lane: what it did in the last dispatch.
@group(0) @binding(8) var<storage, read_write> tallies: array<Tally>;

// Counts one iteration of `kind` (ITERATION_*, or TAKEN), without
// indexing (a local array indexed at run time would live in memory).
fn count_kind(tally: ptr<function, Tally>, kind: u32) {
    let k = vec4<u32>(kind);
    (*tally).kinds += select(vec4<u32>(0u), vec4<u32>(1u), k == vec4<u32>(0u, 1u, 2u, 3u));
    (*tally).more += select(vec4<u32>(0u), vec4<u32>(1u), k == vec4<u32>(4u, 5u, 6u, 7u));
}

// The queue's next instance for a lane that holds none, or NO_INSTANCE.
// A lane idles only once the queue ran dry, so this takes only what the
// host queued again since (`pidm::gpu::groups`); the load first keeps the
// counter from running far past the queue's end on every dispatch.
fn take_idle(lane: u32) -> u32 {
    if lane >= control.lanes || atomicLoad(&counters.next) >= control.queued {
        return NO_INSTANCE;
    }
    let slot = atomicAdd(&counters.next, 1u);
    if slot >= control.queued {
        return NO_INSTANCE;
    }
    return order[slot];
}

// Starts (`initialize`) or loads instance `index`.
fn take(index: u32, initialize: bool) -> State {
    if !initialize {
        return states[index];
    }
    start_measure(index);
    return initial_state();
}

// The instance the lane holds, whose coefficients every function reads
// where it uses them (`let c = &coefficients[held];`): a lane copies none
// of them.
var<private> held: u32;

@compute @workgroup_size(WORKGROUP_SIZE)
fn advance_slice(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let lane = gid.x + gid.y * groups.x * WORKGROUP_SIZE;
    if lane >= arrayLength(&lanes) {
        return;
    }
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
    var st = take(index, control.initialize == 1u);
    var left = control.max_iterations;
    loop {
        if is_finished(st) {
            states[index] = st;
            finish_measure(index);
            atomicAdd(&counters.finished, 1u);
            let slot = atomicAdd(&counters.next, 1u);
            if slot >= control.queued {
                index = NO_INSTANCE;
                break;
            }
            index = order[slot];
            held = index;
            st = states[index];
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
        states[index] = st;
        finish_measure(index);
        atomicAdd(&counters.finished, 1u);
        index = NO_INSTANCE;
    }
    if index != NO_INSTANCE {
        states[index] = st;
        tally.progress = f32(st.period) + f32(st.time) / f32(coefficients[index].period);
    }
    lanes[lane] = index;
    tally.more.w = index;
    tally.emulated = emulated;
    tallies[lane] = tally;
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
        if is_finished(*st) {
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
        let kind = iterate(st);
        if LOOP_LIMITER {
            if !loop_limiter_intact((*st).steps) {
                *st = before;
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
