// On the laws' floor: every law's shader includes this file as it is
// (a law's lanes keep the State members it reads; shaders/lugre/measure.wgsl
// says how LuGre's do). Its CPU mirror is compiled in both of Karnopp's
// precisions, which is why it lives beside Karnopp's integrator.
// Mirror of `laws::karnopp::integrate::phase`: the phase-resolved estimate of the
// steady step for two drive frequencies. A ladder of windows from the start
// of the measurement, each the trapezoid rule over the faster drive's phase
// as a combination of the slider positions at six periods; the host
// computes each window length's three-gap table (Coefficients.gaps) and
// the levels that may stop the run (Coefficients.phase_levels), and the
// ladder's constants come from Rust through the prelude.

// Its structs live beside their users: `Gaps` in coefficients.wgsl, `Phase`
// and `PhaseEstimate` in measure.wgsl, so a variant without the ladder
// (`pidm::gpu::shader::Parts`) leaves this file out.

fn ladder_length(j: u32) -> u32 {
    var base = LADDER_EVEN;
    if j % 2u == 1u {
        base = LADDER_ODD;
    }
    return base << (j / 2u);
}

fn window_weight(g: Gaps, length: u32, k: u32) -> Real {
    var right = g.alpha + g.beta;
    if k + g.a < length {
        right = g.alpha;
    } else if k >= g.b {
        right = g.beta;
    }
    var left = g.alpha + g.beta;
    if k >= g.a {
        left = g.alpha;
    } else if k + g.b < length {
        left = g.beta;
    }
    return Real(0.5) * (left + right);
}

// Whether cut c lies in (at - count, at].
fn is_cut(c: u32, at: u32, count: u32) -> bool {
    return at < c + count && c <= at;
}

fn window_coefficient(g: Gaps, length: u32, at: u32, count: u32) -> Real {
    if !(is_cut(0u, at, count) || is_cut(length, at, count) || is_cut(g.a, at, count)
        || is_cut(g.b, at, count) || (g.a <= length && is_cut(length - g.a, at, count))
        || (g.b <= length && is_cut(length - g.b, at, count))) {
        return Real(0.0);
    }
    var before = Real(0.0);
    if at >= count {
        before = window_weight(g, length, at - count);
    }
    var here = Real(0.0);
    if at < length {
        here = window_weight(g, length, at);
    }
    return before - here;
}

fn add_to_window(sum: V2, g: Gaps, start: u32, length: u32, k: u32, r: Replica, x: V2) -> V2 {
    let v = r.count * k + r.index;
    if v < start || v >= start + length + r.count {
        return sum;
    }
    let coefficient = window_coefficient(g, length, v - start, r.count);
    if coefficient != Real(0.0) {
        return sum + x * coefficient;
    }
    return sum;
}

fn first_at(k: u32, r: Replica, at: u32) -> bool {
    let v = r.count * k + r.index;
    return v >= at && v < at + r.count;
}

// The ladder's windows live in the instance's accumulators (`slot`, see
// measure.wgsl) and are updated there in place; each window length's
// three-gap table is read from the coefficients where it is used.
fn phase_period_end(slot: u32, k: u32, x: V2) -> PhaseEstimate {
    let c = &coefficients[held];
    let r = Replica(c.replica, c.replicas);
    var judged = PhaseEstimate(V2(0.0), V2(0.0), 0u, 0u);
    for (var j = 0u; j < LEVELS; j++) {
        let length = ladder_length(j);
        let whole = add_to_window(measures[slot].phase.whole[j], c.gaps[j], 0u, length, k, r, x);
        measures[slot].phase.whole[j] = whole;
        if j >= 2u {
            let half = ladder_length(j - 2u);
            let second = add_to_window(measures[slot].phase.second[j], c.gaps[j - 2u], half, half, k, r, x);
            measures[slot].phase.second[j] = second;
        }
        if j >= FIRST_JUDGED {
            let quarter = ladder_length(j - 4u);
            let ring = 2u * (j % 2u);
            if first_at(k, r, 2u * quarter) {
                measures[slot].phase.quarters[ring] = V2(0.0);
                measures[slot].phase.quarters[ring + 1u] = V2(0.0);
            }
            let g = c.gaps[j - 4u];
            let early = add_to_window(measures[slot].phase.quarters[ring], g, 2u * quarter, quarter, k, r, x);
            measures[slot].phase.quarters[ring] = early;
            let late = add_to_window(measures[slot].phase.quarters[ring + 1u], g, 3u * quarter, quarter, k, r, x);
            measures[slot].phase.quarters[ring + 1u] = late;
            if first_at(k, r, length) && ((c.phase_levels >> j) & 1u) == 1u {
                if r.count > 1u {
                    measures[slot].phase.pending = level_sums(slot, j);
                    judged = PhaseEstimate(V2(0.0), V2(0.0), length, j);
                } else {
                    judged = evaluate(slot, j, ((c.phase_lattice >> j) & 1u) == 1u);
                }
            }
        }
    }
    return judged;
}

fn level_sums(slot: u32, j: u32) -> LevelSums {
    let ring = 2u * (j % 2u);
    return LevelSums(
        measures[slot].phase.whole[j],
        measures[slot].phase.whole[j - 2u],
        measures[slot].phase.second[j],
        measures[slot].phase.whole[j - 4u],
        measures[slot].phase.second[j - 2u],
        measures[slot].phase.quarters[ring],
        measures[slot].phase.quarters[ring + 1u],
    );
}

fn evaluate(slot: u32, j: u32, lattice: bool) -> PhaseEstimate {
    return evaluate_sums(level_sums(slot, j), j, lattice);
}

fn evaluate_sums(s: LevelSums, j: u32, lattice: bool) -> PhaseEstimate {
    let w = s.whole;
    let half = s.half;
    let richardson = (w - half) * (w - half);
    let halves = (s.second - half) * (s.second - half) * Real(0.25);
    let mean = (s.q0 + s.q1 + s.q2 + s.q3) * Real(0.25);
    var squares = V2(0.0);
    squares = squares + (s.q0 - mean) * (s.q0 - mean);
    squares = squares + (s.q1 - mean) * (s.q1 - mean);
    squares = squares + (s.q2 - mean) * (s.q2 - mean);
    squares = squares + (s.q3 - mean) * (s.q3 - mean);
    var quarters = squares * Real(1.0 / 12.0);
    if ladder_length(j - 4u) >= QUARTER_TRUSTED {
        quarters = squares * Real(1.0 / 27.0);
    }
    if lattice {
        quarters = V2(0.0);
    }
    let se2 = max(max(richardson, halves), quarters);
    return PhaseEstimate(w, se2, ladder_length(j), j);
}
