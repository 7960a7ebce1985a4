// The steady measurement of a LuGre run at its period ends, on the device:
// mirror of `laws::lugre::run::Periods::period_end`. The floor's per-period
// bookkeeping (`shaders/shared/setup.wgsl`, `measure.wgsl` and
// `phase.wgsl`, included as they are after this file: batches, the phase
// ladder and the stop rule, on the instance's own accumulators in
// `measures`), then docs/model.md section 8's recurrence test, which
// compares z too. The floor's own recurrence test never runs here: the
// host packs LuGre's coefficients with a common period of 0, as the CPU's
// run does, and passes the real one in `Model.common_period`.

// A run's constants: the floor's measurement constants
// (`pidm::laws::floor::Setup`, by the names shaders/shared/measure.wgsl
// reads) and the periods it may integrate (`pidm::gpu::lugre::layout::
// Coefficients` on the host).
struct Coefficients {
    se_limit2: V2,
    period: Real,
    period_lo: Real,
    repeat_x: Real,
    repeat_v: Real,
    cycles: u32,
    settle: u32,
    steady: u32,
    common_period: u32,
    batch_length: u32,
    min_batch: u32,
    phase_levels: u32,
    phase_lattice: u32,
    replica: u32,
    replicas: u32,
    _pad: vec2<u32>,
    gaps: array<Gaps, LEVELS>,
}

// The members of a law's state that the floor's measurement reads and
// writes at a period end (`pidm::laws::floor::measure::Slider`).
struct State {
    x_p: V2,
    v_p: V2,
    x_s: V2,
    v_s: V2,
    mode: u32,
    period: u32,
    measured: u32,
    _pad: u32,
}

// `measure.wgsl`'s `at_period_end` reads it; only Karnopp's entry calls
// that (a LuGre lane finds its period ends by its own time, entry.wgsl).
fn time_reached(st: State, t: Real, t_lo: Real) -> bool {
    return false;
}

// The recurrence test's snapshots of one instance (`run::Recurrence`):
// the state at the last SNAPSHOTS common periods' ends, and how many were
// taken.
struct Recurrence {
    snaps: array<Vector, SNAPSHOTS>,
    taken: u32,
    _pad: u32,
}

// The floor's measurement reads the instance `held` holds in
// `coefficients` and `measures` (its `coefficients[held]`): here the
// lane's own.
var<private> held: u32;

@group(0) @binding(0) var<storage, read> coefficients: array<Coefficients>;
// One per instance where any instance of the batch is steady, else one
// unused entry (a window never touches them).
@group(0) @binding(5) var<storage, read_write> measures: array<Measure>;
@group(0) @binding(10) var<storage, read_write> recurrences: array<Recurrence>;

// A run's start: the accumulators and snapshots of a fresh measurement.
fn start_measure() {
    let c = &coefficients[held];
    if c.steady == 1u {
        measures[held] = initial_measure();
    }
    if BACKWARD {
        measures[variation_slot(held)] = initial_measure();
    }
    recurrences[held].taken = 0u;
}

// A finished steady run leaves its head for the host (the engine's
// `heads`, `shaders/engine/queue.wgsl`).
fn finish_measure() {
    let c = &coefficients[held];
    if c.steady == 1u {
        let m = &measures[held];
        heads[held] = Head((*m).travel, (*m).se2, (*m).next_end, (*m).lag, (*m).verdict, (*m).span);
    }
}

// The end of the lane's current scene period, with the integrator's state
// `y` there: the lane keeps `y` (`last`), counts the period and says
// whether the measurement ended it (`measured`), as the CPU's run does.
fn lugre_period_end(lane: ptr<function, Lane>, y: Vector) {
    let c = &coefficients[held];
    var st: State;
    st.x_p = V2(y[XP], y[XP + 1u]);
    st.v_p = V2(y[VP], y[VP + 1u]);
    st.x_s = V2(y[XS], y[XS + 1u]);
    st.v_s = V2(y[VS], y[VS + 1u]);
    st.period = (*lane).period;
    st.measured = (*lane).measured;
    // The period's variation counts (variation.wgsl), before the
    // measurement the backward travel follows.
    follow_commit();
    if c.steady == 1u {
        period_end(&st, held);
        let ended = st.period + 1u;
        let lag_unit = models[held].common_period;
        if lag_unit > 0u && ended >= c.settle && (ended - c.settle) % lag_unit == 0u
            && measures[held].verdict == VERDICT_RUNNING && repeats(y, lag_unit) {
            st.measured = 1u;
        }
        follow(held, lag_unit);
    }
    (*lane).last = y;
    (*lane).period = st.period + 1u;
    (*lane).measured = st.measured;
    if (*lane).period == c.settle {
        (*lane).settle_x_s = array<Real, 2>(st.x_s.x, st.x_s.y);
        follow_settle();
    }
}

// Whether `y` repeats a kept snapshot (`Recurrence::repeats`); if it does,
// records the lag and the travel over it (a periodic verdict), else keeps
// `y`.
fn repeats(y: Vector, lag_unit: u32) -> bool {
    let taken = recurrences[held].taken;
    let kept = min(taken, SNAPSHOTS);
    for (var back = 1u; back <= kept; back++) {
        let s = (taken - back) % SNAPSHOTS;
        if repeats_snapshot(y, s) {
            measures[held].lag = back * lag_unit;
            measures[held].travel = V2(
                y[XS] - recurrences[held].snaps[s][XS],
                y[XS + 1u] - recurrences[held].snaps[s][XS + 1u],
            );
            measures[held].verdict = VERDICT_PERIODIC;
            return true;
        }
    }
    recurrences[held].snaps[taken % SNAPSHOTS] = y;
    recurrences[held].taken = taken + 1u;
    return false;
}
