// The steady measurement's half of the entry point (GPU only, beside
// entry.wgsl): the accumulators and heads of each instance and what the
// lane's loop does with them. Only variants with steady instances carry
// it; the others get `pidm::gpu::shader`'s empty twins of these functions
// (`Parts`), and their pipelines bind neither buffer.

// The steady measurement's accumulators per instance (measure.wgsl), read
// and written in place only at the period ends of steady instances; a
// batch of windows binds a single unused entry. A loop-limited variant's
// buffer ends with one scratch entry per lane (`measure_period_end`).
@group(0) @binding(5) var<storage, read_write> measures: array<Measure>;

// What the host reads of every finished steady measurement: the engine's
// `heads` (`shaders/engine/queue.wgsl`).

// The entries of the steady measurement's half of `measures`: all of them,
// or the first half where the second holds the backward travel's
// (variation.wgsl).
fn measure_entries() -> u32 {
    if BACKWARD {
        return arrayLength(&measures) / 2u;
    }
    return arrayLength(&measures);
}

// A steady instance's accumulators start with its run, and so do the
// backward travel's of any instance.
fn start_measure(index: u32) {
    let c = &coefficients[held];
    if c.steady == 1u {
        measures[index] = initial_measure();
    }
    if BACKWARD {
        measures[variation_slot(index)] = initial_measure();
    }
}

// A finished steady instance leaves its head for the host.
fn finish_measure(index: u32) {
    let c = &coefficients[held];
    if c.steady == 1u {
        heads[index] = Head(
            measures[index].travel,
            measures[index].se2,
            measures[index].next_end,
            measures[index].lag,
            measures[index].verdict,
            measures[index].span,
        );
    }
}

// Whether a steady instance sits at a period end its measurement has not
// processed yet.
fn at_measured_end(st: State, index: u32) -> bool {
    let c = &coefficients[held];
    return c.steady == 1u && at_period_end(st, measures[index].next_end);
}

// Processes that period end, updating the accumulators in place (never
// copied whole: a lane holds none of them). False when the driver's loop
// limiter cut the update short: the state is as before, counted as cut at
// its start where the lane had done nothing yet in this dispatch (`fresh`:
// `limited_at_start`), and the lane's dispatch ends. A cut update must
// leave the accumulators as they were, so a loop-limited variant updates
// the lane's scratch entry (the buffer's last `arrayLength(&lanes)`
// entries) and copies it back once the update is complete.
fn measure_period_end(st: ptr<function, State>, index: u32, lane: u32, fresh: bool) -> bool {
    var slot = index;
    if LOOP_LIMITER {
        slot = measure_entries() - arrayLength(&lanes) + lane;
        measures[slot] = measures[index];
        if BACKWARD {
            measures[variation_slot(slot)] = measures[variation_slot(index)];
        }
    }
    let before = *st;
    period_end(st, slot);
    if BACKWARD {
        follow(slot, coefficients[held].common_period);
    }
    if LOOP_LIMITER {
        if !loop_limiter_intact((*st).steps) {
            *st = before;
            if fresh {
                limited_at_start(st);
            }
            return false;
        }
        measures[index] = measures[slot];
        if BACKWARD {
            measures[variation_slot(index)] = measures[variation_slot(slot)];
        }
    }
    (*st).limited = 0u;
    return true;
}
