// Mirror of src/cpu/integrate/measure.rs: the per-period bookkeeping of a
// steady measurement and the rule that stops its run. The host computes
// the common period, the first batch length and the tolerances
// (Coefficients) and reduces what is left here to the map's values
// (src/measurement.rs); the shader keeps each instance's Measure in the
// `measures` buffer and copies it in only at a period end.

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

// What judging a level reads: W_j, W_{j-2}, V_j and the four quarters.
struct LevelSums {
    whole: V2,
    half: V2,
    second: V2,
    quarters: array<V2, 4>,
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

fn initial_measure(c: Coefficients) -> Measure {
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
fn at_period_end(c: Coefficients, st: State, next_end: u32) -> bool {
    return c.steady == 1u && time_reached(st, c.period, c.period_lo) && next_end == st.period;
}

fn period_end(c: Coefficients, st: ptr<function, State>, m: ptr<function, Measure>) {
    (*m).next_end = (*st).period + 1u;
    let ended = (*st).period + 1u;
    if ended < c.settle {
        return;
    }
    if ended > c.settle {
        let d = (*st).x_s - (*m).last_x_s;
        (*m).d_min = min((*m).d_min, d);
        (*m).d_max = max((*m).d_max, d);
        (*m).measured += 1u;
        (*m).in_batch += 1u;
        if (*m).in_batch == (*m).batch_length {
            close_batch(m, (*st).x_s);
        }
    } else {
        (*m).batch_start = (*st).x_s;
    }
    (*m).last_x_s = (*st).x_s;
    if c.common_period > 0u && (ended - c.settle) % c.common_period == 0u {
        recurrence(c, *st, m);
    }
    if PHASE && c.phase_levels != 0u {
        // A whole variable to point at (a pointer to a member of one that
        // is pointed at is not portable SPIR-V for naga).
        var phase = (*m).phase;
        let judged = phase_period_end(c, &phase, ended - c.settle, (*st).x_s);
        (*m).phase = phase;
        if judged.span > 0u && (*m).verdict == VERDICT_RUNNING {
            if c.replicas > 1u {
                (*m).pending_level = judged.level;
                (*m).verdict = VERDICT_WAITING;
            } else {
                (*m).travel = judged.value * Real(judged.span);
                (*m).span = judged.span;
                (*m).se2 = judged.se2;
                if judged.se2.x <= c.se_limit2.x && judged.se2.y <= c.se_limit2.y {
                    (*m).verdict = VERDICT_PHASE;
                }
            }
        }
    }
    if (*m).verdict == VERDICT_RUNNING && (*m).in_batch == 0u && (*m).filled >= MIN_BATCHES
        && (*m).batch_length >= c.min_batch {
        let e = estimate(m);
        if e.stationary && e.se2.x <= c.se_limit2.x && e.se2.y <= c.se_limit2.y {
            (*m).verdict = VERDICT_CONVERGED;
        }
    }
    if (*m).verdict == VERDICT_WAITING {
        (*st).measured = 2u;
    } else if (*m).verdict != VERDICT_RUNNING {
        (*st).measured = 1u;
    }
}

fn close_batch(m: ptr<function, Measure>, x_s: V2) {
    (*m).sums[(*m).filled] = x_s - (*m).batch_start;
    (*m).filled += 1u;
    (*m).batch_start = x_s;
    (*m).in_batch = 0u;
    if (*m).filled == BATCHES {
        for (var j = 0u; j < BATCHES / 2u; j++) {
            (*m).sums[j] = (*m).sums[2u * j] + (*m).sums[2u * j + 1u];
        }
        (*m).filled = BATCHES / 2u;
        (*m).batch_length *= 2u;
    }
}

fn recurrence(c: Coefficients, st: State, m: ptr<function, Measure>) {
    let kept = min((*m).snapshots, SNAPSHOTS);
    for (var back = 1u; back <= kept; back++) {
        let s = (*m).snaps[((*m).snapshots - back) % SNAPSHOTS];
        if s.mode == st.mode && close(st.x_p, s.x_p, c.repeat_x) && close(st.v_p, s.v_p, c.repeat_v)
            && close(st.v_s, s.v_s, c.repeat_v) {
            (*m).lag = back * c.common_period;
            (*m).travel = st.x_s - s.x_s;
            (*m).verdict = VERDICT_PERIODIC;
            return;
        }
    }
    var s: Snapshot;
    s.x_p = st.x_p;
    s.v_p = st.v_p;
    s.v_s = st.v_s;
    s.x_s = st.x_s;
    s.mode = st.mode;
    (*m).snaps[(*m).snapshots % SNAPSHOTS] = s;
    (*m).snapshots += 1u;
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

fn statistics(m: ptr<function, Measure>, start: u32, end: u32) -> Statistics {
    let count = end - start;
    var total = V2(0.0);
    for (var j = start; j < end; j++) {
        total = total + (*m).sums[j];
    }
    let b = Real((*m).batch_length);
    let inv_count = recip(Real(count));
    let per_batch = total * inv_count;
    var squares = V2(0.0);
    var lagged = V2(0.0);
    var previous = V2(0.0);
    var walk = V2(0.0);
    var low = V2(0.0);
    var high = V2(0.0);
    for (var j = start; j < end; j++) {
        let e = (*m).sums[j] - per_batch;
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

fn estimate(m: ptr<function, Measure>) -> Estimate {
    let n = (*m).filled;
    let cuts = mser_cut(m);
    let cut = u32(max(cuts.x, cuts.y));
    let kept = n - cut;
    let span = kept * (*m).batch_length;
    if kept < 2u {
        var total = V2(0.0);
        for (var j = cut; j < n; j++) {
            total = total + (*m).sums[j];
        }
        let largest = max(abs((*m).d_min), abs((*m).d_max));
        return Estimate(total, span, largest * largest, false);
    }
    let whole = statistics(m, cut, n);
    let half = kept / 2u;
    var stationary = false;
    if half >= 2u && cut < n / 2u && !any(whole.correlated) {
        let first = statistics(m, cut, cut + half);
        let last = statistics(m, n - half, n);
        let d = first.mean - last.mean;
        let allowed = (first.se2 + last.se2) * (STATIONARY_Z * STATIONARY_Z);
        stationary = d.x * d.x <= allowed.x && d.y * d.y <= allowed.y;
    }
    return Estimate(whole.total, span, whole.se2, stationary);
}

fn mser_cut(m: ptr<function, Measure>) -> V2 {
    let n = (*m).filled;
    var best = V2(INFINITY);
    var cut = V2(0.0);
    for (var d = 0u; d <= n / 2u; d++) {
        let left = Real(n - d);
        let inv_left = recip(left);
        var total = V2(0.0);
        for (var j = d; j < n; j++) {
            total = total + (*m).sums[j];
        }
        let mean = total * inv_left;
        var squares = V2(0.0);
        for (var j = d; j < n; j++) {
            let e = (*m).sums[j] - mean;
            squares = squares + e * e;
        }
        let score = squares * (inv_left * inv_left);
        let better = score < best;
        best = select(best, score, better);
        cut = select(cut, V2(Real(d)), better);
    }
    return cut;
}
