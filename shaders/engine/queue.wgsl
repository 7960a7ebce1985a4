// The engine's queue (GPU only; its host is `pidm::gpu::slices`), which
// every law's entry point follows: the first dispatch of a batch runs
// every instance on a lane of its own; the host then queues the unfinished
// ones in `order`, dearest first, and a lane whose instance finishes takes
// the next one from the atomic `counters.next`, so no lane of a warp idles
// while instances are left; once the queue is empty the host packs the
// busy lanes into fewer workgroups. Every lane reports what it did in each
// dispatch in `tallies` (`pidm::gpu::warps`), and every finished steady
// run leaves its head in `heads`. The law declares its coefficients
// (binding 0), its per-instance states (binding 1) and the steady
// measurement's accumulators (5); its own buffers come after binding 8.

// The lane holds no instance.
const NO_INSTANCE: u32 = 0xffffffffu;
// The tally's count of instances taken from the queue (after the kinds of
// iteration, ITERATION_*).
const TAKEN: u32 = 6u;

// The work counters of a batch.
struct Counters {
    // The next position of `order` no lane has taken yet.
    next: atomic<u32>,
    // Instances finished (normally or not), or parked at the cap.
    finished: atomic<u32>,
    // Instances parked at the cap since the host last queued them again,
    // and their indices (`park`).
    parked: atomic<u32>,
    parked_list: array<u32>,
}

// The per-dispatch controls, read from a small storage buffer.
struct Control {
    // Units of work per lane in this dispatch: iterations of `iterate`
    // (Karnopp), step attempts (LuGre).
    max_iterations: u32,
    // 1 in a batch's first dispatch (Karnopp's lanes then start their
    // instances: `initial_state`; LuGre's host starts them).
    initialize: u32,
    // Karnopp's: always 1.0 (see `move_to`); the passes of its loop-limiter
    // probe and the passes it must see, and always 0 (see
    // `loop_limiter_intact`).
    one: f32,
    probe: u32,
    probe_min: u32,
    zero: u32,
    // Entries of `order` a lane may take (0 in the first dispatch).
    queued: u32,
    // Lanes below this one that hold no instance at the start take one
    // from `order` (replicas queued again between dispatches).
    lanes: u32,
    // The round's cap on an instance's steps (0xffffffff: none):
    // a lane parks an instance at its first iteration boundary at or past
    // it, so that where the CPU takes over a run depends on the run alone,
    // not on the lanes' timing (`pidm::gpu::slices`, the rounds).
    cap: u32,
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

// Whether an instance that has taken `steps` steps has reached the
// round's cap (`control.cap`).
fn at_cap(steps: u32) -> bool {
    return steps >= control.cap;
}

// Parks instance `index`, whose state the caller has stored: it counts as
// finished for this round, and the host queues it again under a higher cap
// or hands it to the CPU.
fn park(index: u32) {
    let k = atomicAdd(&counters.parked, 1u);
    counters.parked_list[k] = index;
    atomicAdd(&counters.finished, 1u);
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

// What the host reads of every finished steady measurement: all that the
// reduction of a periodic or phase-resolved verdict reads
// (`pidm::gpu::layout::*::Head`). The host copies the whole accumulators
// of the others only (`pidm::gpu::readback`).
struct Head {
    travel: V2,
    se2: V2,
    next_end: u32,
    lag: u32,
    verdict: u32,
    span: u32,
}
// One per instance where any instance is steady, written when a steady
// instance finishes (bound only where a batch measures steady runs).
@group(0) @binding(6) var<storage, read_write> heads: array<Head>;
