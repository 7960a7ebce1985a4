// On the laws' floor: every law's shader includes this file as it is
// (a law's lanes keep the State members it reads; shaders/lugre/measure.wgsl
// says how LuGre's do). Its CPU mirror is compiled in both of Karnopp's
// precisions, which is why it lives beside Karnopp's integrator.
// Mirror of `laws::karnopp::integrate::measure`: the per-period bookkeeping of a
// steady measurement and the rule that stops its run. The host computes
// the common period, the first batch length and the tolerances
// (Coefficients) and reduces what is left here to the map's values
// (src/measurement.rs); the shader keeps each instance's Measure in the
// `measures` buffer (steady.wgsl) and updates it there, in place, at a
// period end: `slot` is the entry the functions below work on (the
// instance's own on hardware; steady.wgsl says why a loop-limited variant
// works on a lane's scratch entry).

// The state at the end of one common period.
struct Snapshot {
    x_p: V2,
    v_p: V2,
    v_s: V2,
    x_s: V2,
    mode: u32,
    _pad_u: u32,
    _pad_v: vec2<u32>,
}

// The phase ladder's windows' sums, as
// `pidm::cpu::integrate::phase::Phase` (phase.wgsl adds to them).
struct Phase {
    whole: array<V2, LEVELS>,
    second: array<V2, LEVELS>,
    quarters: array<V2, 4>,
    pending: LevelSums,
}

// A judged window: the mean travel per scene period, its squared standard
// error per axis, the window's length (0 when none was judged) and level.
struct PhaseEstimate {
    value: V2,
    se2: V2,
    span: u32,
    level: u32,
}

// Which replica of a split run this is, and of how many (phase.rs).
struct Replica {
    index: u32,
    count: u32,
}

// What judging a level reads: W_j, W_{j-2}, V_j and the four quarters
// (members, not an array: nothing indexed at run time).
struct LevelSums {
    whole: V2,
    half: V2,
    second: V2,
    q0: V2,
    q1: V2,
    q2: V2,
    q3: V2,
}

// The per-instance accumulators, as `pidm::cpu::integrate::Measure`.
struct Measure {
    last_x_s: V2,
    batch_start: V2,
    d_min: V2,
    d_max: V2,
    travel: V2,
    sums: array<V2, BATCHES>,
    snaps: array<Snapshot, SNAPSHOTS>,
    next_end: u32,
    measured: u32,
    filled: u32,
    batch_length: u32,
    in_batch: u32,
    snapshots: u32,
    lag: u32,
    verdict: u32,
    span: u32,
    pending_level: u32,
    _pad_v: vec2<u32>,
    se2: V2,
    phase: Phase,
}

fn initial_measure() -> Measure {
    let c = &coefficients[held];
    var m: Measure;
    m.last_x_s = V2(0.0);
    m.batch_start = V2(0.0);
    m.d_min = V2(INFINITY);
    m.d_max = V2(-INFINITY);
    m.travel = V2(0.0);
    m.next_end = 0u;
    m.measured = 0u;
    m.filled = 0u;
    m.batch_length = c.batch_length;
    m.in_batch = 0u;
    m.snapshots = 0u;
    m.lag = 0u;
    m.verdict = VERDICT_RUNNING;
    m.span = 0u;
    m.se2 = V2(0.0);
    return m;
}

// Whether the state sits at a period end not processed yet (the caller
// checks `c.steady` first and reads `next_end` from the instance's
// Measure).
fn at_period_end(st: State, next_end: u32) -> bool {
    let c = &coefficients[held];
    return c.steady == 1u && time_reached(st, c.period, c.period_lo) && next_end == st.period;
}

fn period_end(st: ptr<function, State>, slot: u32) {
    let c = &coefficients[held];
    measures[slot].next_end = (*st).period + 1u;
    let ended = (*st).period + 1u;
    if ended < c.settle {
        return;
    }
    if ended > c.settle {
        let d = (*st).x_s - measures[slot].last_x_s;
        measures[slot].d_min = min(measures[slot].d_min, d);
        measures[slot].d_max = max(measures[slot].d_max, d);
        measures[slot].measured += 1u;
        measures[slot].in_batch += 1u;
        if measures[slot].in_batch == measures[slot].batch_length {
            close_batch(slot, (*st).x_s);
        }
    } else {
        measures[slot].batch_start = (*st).x_s;
    }
    measures[slot].last_x_s = (*st).x_s;
    if c.common_period > 0u && (ended - c.settle) % c.common_period == 0u {
        recurrence(*st, slot);
    }
    if PHASE && c.phase_levels != 0u {
        let judged = phase_period_end(slot, ended - c.settle, (*st).x_s);
        if judged.span > 0u && measures[slot].verdict == VERDICT_RUNNING {
            if c.replicas > 1u {
                measures[slot].pending_level = judged.level;
                measures[slot].verdict = VERDICT_WAITING;
            } else {
                measures[slot].travel = judged.value * Real(judged.span);
                measures[slot].span = judged.span;
                measures[slot].se2 = judged.se2;
                if judged.se2.x <= c.se_limit2.x && judged.se2.y <= c.se_limit2.y {
                    measures[slot].verdict = VERDICT_PHASE;
                }
            }
        }
    }
    if measures[slot].verdict == VERDICT_RUNNING && measures[slot].in_batch == 0u && measures[slot].filled >= MIN_BATCHES
        && measures[slot].batch_length >= c.min_batch {
        let e = estimate(slot);
        if e.stationary && e.se2.x <= c.se_limit2.x && e.se2.y <= c.se_limit2.y {
            measures[slot].verdict = VERDICT_CONVERGED;
        }
    }
    if measures[slot].verdict == VERDICT_WAITING {
        (*st).measured = 2u;
    } else if measures[slot].verdict != VERDICT_RUNNING {
        (*st).measured = 1u;
    }
}

fn close_batch(slot: u32, x_s: V2) {
    measures[slot].sums[measures[slot].filled] = x_s - measures[slot].batch_start;
    measures[slot].filled += 1u;
    measures[slot].batch_start = x_s;
    measures[slot].in_batch = 0u;
    if measures[slot].filled == BATCHES {
        for (var j = 0u; j < BATCHES / 2u; j++) {
            measures[slot].sums[j] = measures[slot].sums[2u * j] + measures[slot].sums[2u * j + 1u];
        }
        measures[slot].filled = BATCHES / 2u;
        measures[slot].batch_length *= 2u;
    }
}

fn recurrence(st: State, slot: u32) {
    let c = &coefficients[held];
    let kept = min(measures[slot].snapshots, SNAPSHOTS);
    for (var back = 1u; back <= kept; back++) {
        let s = measures[slot].snaps[(measures[slot].snapshots - back) % SNAPSHOTS];
        if s.mode == st.mode && close(st.x_p, s.x_p, c.repeat_x) && close(st.v_p, s.v_p, c.repeat_v)
            && close(st.v_s, s.v_s, c.repeat_v) {
            measures[slot].lag = back * c.common_period;
            measures[slot].travel = st.x_s - s.x_s;
            measures[slot].verdict = VERDICT_PERIODIC;
            return;
        }
    }
    var s: Snapshot;
    s.x_p = st.x_p;
    s.v_p = st.v_p;
    s.v_s = st.v_s;
    s.x_s = st.x_s;
    s.mode = st.mode;
    measures[slot].snaps[measures[slot].snapshots % SNAPSHOTS] = s;
    measures[slot].snapshots += 1u;
}

fn close(a: V2, b: V2, tolerance: Real) -> bool {
    return all(abs(a - b) <= V2(tolerance));
}

// The batch estimate of the mean travel per scene period.
struct Estimate {
    travel: V2,
    span: u32,
    se2: V2,
    stationary: bool,
}

// Batch means and the range term over complete batches `start .. end`.
struct Statistics {
    total: V2,
    mean: V2,
    se2: V2,
    correlated: vec2<bool>,
}

fn statistics(slot: u32, start: u32, end: u32) -> Statistics {
    let count = end - start;
    var total = V2(0.0);
    for (var j = start; j < end; j++) {
        total = total + measures[slot].sums[j];
    }
    let b = Real(measures[slot].batch_length);
    let inv_count = recip(Real(count));
    let per_batch = total * inv_count;
    var squares = V2(0.0);
    var lagged = V2(0.0);
    var previous = V2(0.0);
    var walk = V2(0.0);
    var low = V2(0.0);
    var high = V2(0.0);
    for (var j = start; j < end; j++) {
        let e = measures[slot].sums[j] - per_batch;
        squares = squares + e * e;
        lagged = lagged + e * previous;
        previous = e;
        walk = walk + e;
        low = min(low, walk);
        high = max(high, walk);
    }
    let inv_span = recip(Real(count) * b);
    let range = (high - low) * inv_span;
    let inv_b = recip(b);
    let batch = squares * (inv_count * recip(Real(count - 1u))) * (inv_b * inv_b);
    let bound = squares * squares * (CORRELATION_Z * CORRELATION_Z * inv_count);
    let correlated = lagged > V2(0.0) & lagged * lagged > bound;
    return Statistics(total, total * inv_span, batch + range * range, correlated);
}

fn estimate(slot: u32) -> Estimate {
    let n = measures[slot].filled;
    let cuts = mser_cut(slot);
    let cut = u32(max(cuts.x, cuts.y));
    let kept = n - cut;
    let span = kept * measures[slot].batch_length;
    if kept < 2u {
        var total = V2(0.0);
        for (var j = cut; j < n; j++) {
            total = total + measures[slot].sums[j];
        }
        let largest = max(abs(measures[slot].d_min), abs(measures[slot].d_max));
        return Estimate(total, span, largest * largest, false);
    }
    let whole = statistics(slot, cut, n);
    let half = kept / 2u;
    var stationary = false;
    if half >= 2u && cut < n / 2u && !any(whole.correlated) {
        let first = statistics(slot, cut, cut + half);
        let last = statistics(slot, n - half, n);
        let d = first.mean - last.mean;
        let allowed = (first.se2 + last.se2) * (STATIONARY_Z * STATIONARY_Z);
        stationary = d.x * d.x <= allowed.x && d.y * d.y <= allowed.y;
    }
    return Estimate(whole.total, span, whole.se2, stationary);
}

fn mser_cut(slot: u32) -> V2 {
    let n = measures[slot].filled;
    var best = V2(INFINITY);
    var cut = V2(0.0);
    for (var d = 0u; d <= n / 2u; d++) {
        let left = Real(n - d);
        let inv_left = recip(left);
        var total = V2(0.0);
        for (var j = d; j < n; j++) {
            total = total + measures[slot].sums[j];
        }
        let mean = total * inv_left;
        var squares = V2(0.0);
        for (var j = d; j < n; j++) {
            let e = measures[slot].sums[j] - mean;
            squares = squares + e * e;
        }
        let score = squares * (inv_left * inv_left);
        let better = score < best;
        best = select(best, score, better);
        cut = select(cut, V2(Real(d)), better);
    }
    return cut;
}
