// The compute entry point of the LuGre integrator (GPU only; the CPU's
// counterpart is the period loop of `pidm::cpu::lugre::run`). One
// invocation per instance: each dispatch advances every running instance
// by at most `control.attempts` Rodas4 step attempts, and no further than
// the end of its current scene period, where it waits for the host
// (`pidm::gpu::lugre`), which measures the period as the CPU's run does
// (`run::Periods::period_end`) and starts the next one.

// A lane's flag (the prelude's, from `pidm::gpu::lugre`): LANE_RUNNING
// (the host set it going at a period's start), LANE_PERIOD_END (it waits at
// the end of its scene period for the host) or LANE_STOPPED (failed, its
// status says why, or finished).

// One instance's integrator state between dispatches
// (`pidm::gpu::lugre::Lane`).
struct Lane {
    y: State,
    // The next trial step [s].
    h: Real,
    // The current segment's end [s] and drive.
    end: Real,
    drive: Drive,
    // The drive's clock of the current scene period.
    clock: Clock,
    // Steps the run may still take.
    budget: u32,
    // Steps of the segments completed, saturating.
    steps: u32,
    // Attempts in the current segment.
    segment_steps: u32,
    // 1 when the last attempt of the current segment was rejected.
    rejected: u32,
    // 1 inside a segment (`end` and `drive` hold).
    in_segment: u32,
    // STATUS_OK, or why the run failed.
    status: u32,
    // LANE_RUNNING, LANE_PERIOD_END or LANE_STOPPED.
    flag: u32,
    _pad: u32,
}

struct Control {
    // Step attempts per lane in this dispatch.
    attempts: u32,
}

@group(0) @binding(0) var<storage, read> models: array<Model>;
@group(0) @binding(1) var<storage, read_write> lanes: array<Lane>;
// A storage buffer, not a uniform: drivers may specialise a shader on the
// values of uniforms that steer its loops.
@group(0) @binding(2) var<storage, read> control: Control;

// Advances one lane by at most `attempts` step attempts: the CPU's loop
// over the segments of a period (`run_instance_until`) fused with the
// `while` of its `segment`, at most one attempt per pass (llvmpipe counts
// the loop passes of a SIMD group's lanes together, so that a nested loop
// of attempts inside a loop of segments would count the lanes' attempts
// one after the other).
fn advance(lane: Lane, attempts: u32) -> Lane {
    var out = lane;
    var y = lane.y;
    var h = lane.h;
    var end = lane.end;
    var drive = lane.drive;
    var budget = lane.budget;
    var segment_steps = lane.segment_steps;
    var rejected = lane.rejected != 0u;
    var in_segment = lane.in_segment != 0u;
    var steps = lane.steps;
    for (var round = 0u; round < attempts; round++) {
        close_segment(y, end, &in_segment, &steps, segment_steps);
        if !in_segment {
            if !(y[T] < model.period) {
                out.flag = LANE_PERIOD_END;
                break;
            }
            // The next segment: to the first corner or the period's end.
            var stop = model.period;
            for (var i = 0u; i < 2u; i++) {
                stop = min(stop, next_corner(lane.clock, i, y[T]));
            }
            end = stop;
            let mid = Real(0.5) * (y[T] + end);
            drive = Drive(drive_on(lane.clock, 0u, mid), drive_on(lane.clock, 1u, mid));
            segment_steps = 0u;
            rejected = false;
            in_segment = true;
        }
        let r = segment(drive, &y, end, &h, &budget, &segment_steps, &rejected);
        if r != SEGMENT_GOING && r != SEGMENT_DONE {
            out.status = r;
            out.flag = LANE_STOPPED;
            break;
        }
    }
    // Out of attempts at a period's end: say so now, not a dispatch later.
    if out.flag == LANE_RUNNING {
        close_segment(y, end, &in_segment, &steps, segment_steps);
        if !in_segment && !(y[T] < model.period) {
            out.flag = LANE_PERIOD_END;
        }
    }
    out.y = y;
    out.h = h;
    out.end = end;
    out.drive = drive;
    out.budget = budget;
    out.steps = steps;
    out.segment_steps = segment_steps;
    out.rejected = u32(rejected);
    out.in_segment = u32(in_segment);
    return out;
}

// Ends the current segment once `y` is at its end (the CPU's `while`
// condition): its attempts count in `steps`, saturating (the CPU's
// `Periods::add_steps`).
fn close_segment(
    y: State,
    end: Real,
    in_segment: ptr<function, bool>,
    steps: ptr<function, u32>,
    segment_steps: u32,
) {
    if *in_segment && !(y[T] < end) {
        let sum = *steps + segment_steps;
        *steps = select(sum, 0xffffffffu, sum < *steps);
        *in_segment = false;
    }
}

@compute @workgroup_size(LUGRE_WORKGROUP_SIZE)
fn lugre_advance(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let index = gid.x + gid.y * groups.x * LUGRE_WORKGROUP_SIZE;
    if index >= arrayLength(&lanes) || index >= arrayLength(&models) {
        return;
    }
    if lanes[index].flag != LANE_RUNNING {
        return;
    }
    model = models[index];
    opaque_one = model.one;
    lanes[index] = advance(lanes[index], control.attempts);
}

// The shader-only functions of each (x, y) in `function_values` (five
// numbers each: x, y, then exp_nonpositive(x), hypot(x, y) and
// fourth_root(|y|); `models[0]` gives `keep` its 1), for the tests (`pidm::gpu::lugre::LugreGpu::
// functions_on_gpu`).
@group(0) @binding(3) var<storage, read_write> function_values: array<Real>;

@compute @workgroup_size(LUGRE_WORKGROUP_SIZE)
fn lugre_functions(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = 5u * gid.x;
    if i + 4u < arrayLength(&function_values) {
        opaque_one = models[0].one;
        let x = function_values[i];
        let y = function_values[i + 1u];
        function_values[i + 2u] = exp_nonpositive(x);
        function_values[i + 3u] = hypot(x, y);
        function_values[i + 4u] = fourth_root(abs(y));
    }
}

// The mirror's probes (`pidm::gpu::lugre::LugreGpu::mirror_on_gpu`): the
// right-hand side, the Jacobian and one Rodas4 step of the instance in
// `models[0]` at each probe's state, drive and step, for the tests to
// compare with the CPU's functions.
struct Probe {
    y: State,
    drive: Drive,
    h: Real,
}

struct Probed {
    rhs: State,
    jacobian: Matrix,
    next: State,
    error: State,
}

@group(0) @binding(4) var<storage, read> probes: array<Probe>;
@group(0) @binding(5) var<storage, read_write> probed: array<Probed>;

@compute @workgroup_size(LUGRE_WORKGROUP_SIZE)
fn lugre_mirror(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= arrayLength(&probes) || gid.x >= arrayLength(&probed) {
        return;
    }
    model = models[0];
    opaque_one = model.one;
    let p = probes[gid.x];
    let step = rodas4(p.drive, p.y, p.h);
    probed[gid.x] = Probed(rhs(p.y, p.drive), jacobian(p.y, p.drive), step.next, step.error);
}
