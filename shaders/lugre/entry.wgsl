// The compute entry point of the LuGre integrator (GPU only; the CPU's
// counterpart is the period loop of `pidm::laws::lugre::run::continue_until`).
// Each invocation is a lane of the engine's queue
// (`shaders/engine/queue.wgsl`, host `pidm::gpu::slices`): each dispatch
// it makes at most `control.max_iterations` Rodas4 step attempts on the
// instances it holds, one after another, measuring their period ends on
// the way (measure.wgsl) and starting their next periods, until their
// runs end. An instance's run stays in `states` between dispatches.

// A lane's flag (the prelude's, from `pidm::gpu::lugre`): LANE_FRESH (the
// host set it up at its run's start: the device starts the measurement and
// the first period), LANE_RUNNING or LANE_STOPPED (failed, its status says
// why, or finished).

// One instance's run between dispatches (`pidm::gpu::lugre::Lane`).
struct Lane {
    y: Vector,
    // The state at the last period end (zero before the first): where the
    // current period started (the CPU tail continues from there), and the
    // motion the run's result reports.
    last: Vector,
    // The next trial step [s], and the one at the current period's start.
    h: Real,
    start_h: Real,
    // The current segment's end [s] and drive.
    end: Real,
    drive: Drive,
    // The drive's clock of the current scene period.
    clock: Clock,
    // The slider's position at the settling periods' end [m].
    settle_x_s: array<Real, 2>,
    // Steps the run may still take, now and at the current period's start.
    budget: u32,
    start_budget: u32,
    // Steps of the segments completed (saturating), now and before the
    // current period.
    steps: u32,
    start_steps: u32,
    // Attempts in the current segment.
    segment_steps: u32,
    // 1 when the last attempt of the current segment was rejected.
    rejected: u32,
    // 1 inside a segment (`end` and `drive` hold).
    in_segment: u32,
    // STATUS_OK, or why the run failed.
    status: u32,
    // Scene periods completed, and the measurement's verdict on them
    // (Karnopp's `State.measured`: 0 while running).
    period: u32,
    measured: u32,
    // LANE_FRESH, LANE_RUNNING or LANE_STOPPED.
    flag: u32,
    _pad: u32,
}

// Every instance's run, set up by the host (LANE_FRESH).
@group(0) @binding(1) var<storage, read_write> states: array<Lane>;
// Every instance's parameters (`pidm::gpu::lugre::Params`).
@group(0) @binding(9) var<storage, read> models: array<Model>;

// Whether the lane's run has ended: failed, measured or out of periods
// (`Periods::is_finished`).
fn run_finished(lane: Lane) -> bool {
    let c = &coefficients[held];
    return lane.status != STATUS_OK || lane.period >= c.cycles || lane.measured != 0u;
}

// Starts the lane's current period (`continue_until`'s period start): the
// time within the period back to 0, the drive's clock of the period
// (`Clock::of`), and the period start the CPU tail would continue from.
fn begin_period(lane: ptr<function, Lane>) {
    (*lane).y[T] = Real(0.0);
    let p = Real((*lane).period);
    (*lane).clock.start = array<Real, 2>(
        model.cycles[0] * p + model.phase[0],
        model.cycles[1] * p + model.phase[1],
    );
    (*lane).in_segment = 0u;
    (*lane).start_h = (*lane).h;
    (*lane).start_budget = (*lane).budget;
    (*lane).start_steps = (*lane).steps;
}

// A fresh lane: its measurement starts, then its first period, unless the
// run has no periods.
fn start_run(lane: ptr<function, Lane>) {
    start_measure();
    (*lane).flag = LANE_RUNNING;
    if run_finished(*lane) {
        (*lane).flag = LANE_STOPPED;
    } else {
        begin_period(lane);
    }
}

// Advances one lane by at most `*attempts` step attempts (counting them
// down), no further than the end of its current scene period: the CPU's
// loop over the segments of a period (`continue_until`) fused with the
// `while` of its `segment`, at most one attempt per pass (llvmpipe counts
// the loop passes of a SIMD group's lanes together, so that a nested loop
// of attempts inside a loop of segments would count the lanes' attempts
// one after the other).
fn advance(lane: Lane, attempts: ptr<function, u32>, tally: ptr<function, Tally>) -> Lane {
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
    var left = *attempts;
    for (; left > 0u; left--) {
        close_segment(y, end, &in_segment, &steps, segment_steps);
        if !in_segment {
            if !(y[T] < model.period) {
                break;
            }
            // The next segment: to the first corner or the period's end
            // (the CPU's fold over the axes, by literal indices).
            let stop = min(model.period, next_corner(lane.clock, 0u, y[T]));
            end = min(stop, next_corner(lane.clock, 1u, y[T]));
            let mid = Real(0.5) * (y[T] + end);
            drive = Drive(drive_on(lane.clock, 0u, mid), drive_on(lane.clock, 1u, mid));
            segment_steps = 0u;
            rejected = false;
            in_segment = true;
        }
        let r = segment(drive, &y, end, &h, &budget, &segment_steps, &rejected);
        count_kind(tally, select(ITERATION_SLIP, ITERATION_REJECTED, rejected));
        if r != SEGMENT_GOING && r != SEGMENT_DONE {
            out.status = r;
            out.flag = LANE_STOPPED;
            left--;
            break;
        }
    }
    // A segment complete at the last attempt ends now, so that a lane at
    // its period's end shows it (`lane_at_period_end`).
    close_segment(y, end, &in_segment, &steps, segment_steps);
    *attempts = left;
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

// Whether the lane sits at the end of its current scene period.
fn lane_at_period_end(lane: Lane) -> bool {
    return lane.in_segment == 0u && !(lane.y[T] < model.period);
}

// Ends the current segment once `y` is at its end (the CPU's `while`
// condition): its attempts count in `steps`, saturating (the CPU's
// `Periods::add_steps`).
fn close_segment(
    y: Vector,
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

// Loads instance `index` onto the lane: its parameters, and its run,
// started if the host has just set it up.
fn take_run(index: u32) -> Lane {
    held = index;
    load_model(index);
    opaque_one = model.one;
    var lane = states[index];
    if lane.flag == LANE_FRESH {
        start_run(&lane);
    }
    return lane;
}

// Scene periods the lane's run has completed, with the current one's
// share (the tally's `progress`, which ranks the queue), in f32: the fused
// shader divides no f64.
fn progress_of(lane: Lane) -> f32 {
    return f32(lane.period) + f32(lane.y[T]) / f32(model.period);
}

@compute @workgroup_size(LUGRE_WORKGROUP_SIZE)
fn lugre_advance(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let slot_of_lane = gid.x + gid.y * groups.x * LUGRE_WORKGROUP_SIZE;
    if slot_of_lane >= arrayLength(&lanes) {
        return;
    }
    var tally: Tally;
    let count = min(
        min(arrayLength(&states), arrayLength(&models)),
        min(arrayLength(&coefficients), arrayLength(&recurrences)),
    );
    var index = lanes[slot_of_lane];
    if index >= count {
        index = take_idle(slot_of_lane);
        if index >= count {
            tally.more.w = NO_INSTANCE;
            tallies[slot_of_lane] = tally;
            return;
        }
        count_kind(&tally, TAKEN);
    }
    // The run in hand, loaded at the loop's top (one call of `take_run`,
    // so that drivers inline it once).
    var lane: Lane;
    var taken = true;
    // Period by period: measure the one that ended, start the next, and
    // advance to its end, measuring at most PERIOD_ENDS_PER_DISPATCH
    // period ends (1 on a loop-limited adapter, whose loop budget they
    // share with the attempts; a lane at a second one waits there for the
    // next dispatch). A run that ends leaves its head and the lane takes
    // the queue's next instance.
    var attempts = control.max_iterations;
    var ends = 0u;
    loop {
        if taken {
            lane = take_run(index);
            taken = false;
        }
        // A run that reached the round's cap on its steps parks here, at
        // the loop's top, so within the period its steps reached the cap
        // in, whose start the CPU continues it from
        // (`pidm::gpu::rounds`).
        let parked = lane.flag != LANE_STOPPED && at_cap(lane.steps);
        if lane.flag == LANE_STOPPED || parked {
            states[index] = lane;
            if parked {
                park(index);
            } else {
                finish_measure();
                atomicAdd(&counters.finished, 1u);
            }
            let slot = atomicAdd(&counters.next, 1u);
            if slot >= control.queued || order[slot] >= count {
                index = NO_INSTANCE;
                break;
            }
            index = order[slot];
            taken = true;
            count_kind(&tally, TAKEN);
            continue;
        }
        if lane_at_period_end(lane) {
            if ends == PERIOD_ENDS_PER_DISPATCH {
                break;
            }
            ends++;
            count_kind(&tally, ITERATION_PERIOD_END);
            lugre_period_end(&lane, lane.y);
            if run_finished(lane) {
                lane.flag = LANE_STOPPED;
                continue;
            }
            begin_period(&lane);
        }
        if attempts == 0u {
            break;
        }
        lane = advance(lane, &attempts, &tally);
    }
    if index != NO_INSTANCE {
        states[index] = lane;
        tally.progress = progress_of(lane);
    }
    lanes[slot_of_lane] = index;
    tally.more.w = index;
    tallies[slot_of_lane] = tally;
}

// The shader-only functions of each (x, y) in `function_values` (five
// numbers each: x, y, then exp_nonpositive(x), hypot(x, y) and
// fourth_root(|y|); `models[0]` gives `keep` its 1), for the tests (`pidm::gpu::lugre::LugreGpu::
// functions_on_gpu`).
@group(0) @binding(11) var<storage, read_write> function_values: array<Real>;

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
    y: Vector,
    drive: Drive,
    h: Real,
}

struct Probed {
    rhs: Vector,
    jacobian: Matrix,
    next: Vector,
    error: Vector,
}

@group(0) @binding(12) var<storage, read> probes: array<Probe>;
@group(0) @binding(13) var<storage, read_write> probed: array<Probed>;

@compute @workgroup_size(LUGRE_WORKGROUP_SIZE)
fn lugre_mirror(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= arrayLength(&probes) || gid.x >= arrayLength(&probed) {
        return;
    }
    held = gid.x;
    load_model(held);
    opaque_one = model.one;
    let p = probes[gid.x];
    let step = rodas4(p.drive, p.y, p.h);
    probed[gid.x] = Probed(rhs(p.y, p.drive), jacobian(p.y, p.drive), step.next, step.error);
}
