// Mirror of the floor's `follow` (`laws::floor::variation`; issue 59,
// docs/model.md section 4, "Backward travel"), which records the total at
// every period end the step's measurement processes into accumulators of
// the step's shape. Every law's BACKWARD variants carry this file beside
// their own variation file, which defines `variation_slot(slot)` (where
// the variation's entry of a measurement slot lives). The entry's
// snapshots (which `follow` does not use) hold what the CPU's
// `Variation` keeps beside its accumulators: `snaps[0].x_p` the total
// [m], `snaps[0].v_p` the total when the measured periods began, the ring
// of totals at common-period ends in `snaps[k].x_s` and their count in
// `snapshots` (`pidm::gpu::layout::variation_to_cpu` reads them back).
// Karnopp's variants also carry `pieces.wgsl`, the pieces' travel.

// Records the total at the period end the step's measurement (slot
// `step`) has just processed, deciding nothing; `lag_unit` is the law's
// common period of its recurrence test (the CPU's `common`; 0: none).
fn follow(step: u32, lag_unit: u32) {
    let c = &coefficients[held];
    let v = variation_slot(step);
    let ended = measures[step].next_end;
    let x = measures[v].snaps[0].x_p;
    measures[v].next_end = ended;
    if ended < c.settle {
        return;
    }
    if ended > c.settle {
        let d = x - measures[v].last_x_s;
        measures[v].d_min = min(measures[v].d_min, d);
        measures[v].d_max = max(measures[v].d_max, d);
        measures[v].measured += 1u;
        measures[v].in_batch += 1u;
        if measures[v].in_batch == measures[v].batch_length {
            close_batch(v, x);
        }
    } else {
        measures[v].batch_start = x;
    }
    measures[v].last_x_s = x;
    let running = measures[v].verdict == VERDICT_RUNNING;
    let cycle_found = running && measures[step].verdict == VERDICT_PERIODIC;
    if PHASE && c.phase_levels != 0u {
        let judged = phase_period_end(v, ended - c.settle, x);
        if judged.span > 0u && running && !cycle_found {
            if c.replicas > 1u {
                measures[v].pending_level = judged.level;
            } else {
                measures[v].travel = judged.value * Real(judged.span);
                measures[v].span = judged.span;
                measures[v].se2 = judged.se2;
            }
        }
    }
    if lag_unit > 0u && (ended - c.settle) % lag_unit == 0u && running {
        if cycle_found {
            let back = measures[step].lag / lag_unit;
            measures[v].lag = measures[step].lag;
            measures[v].travel = x - measures[v].snaps[(measures[v].snapshots - back) % SNAPSHOTS].x_s;
        } else {
            measures[v].snaps[measures[v].snapshots % SNAPSHOTS].x_s = x;
            measures[v].snapshots += 1u;
        }
    }
    measures[v].verdict = measures[step].verdict;
}
