// Mirror of src/cpu/integrate/arith.rs: arithmetic WGSL's standard library
// lacks, written out so the CPU computes exactly what the shader computes.

// The step-size factor 0.9 cbrt(allowed / err) rounded down to a multiple
// of 1 / STEP_FACTOR_QUANTUM and limited to [lo, hi], by bisection of the
// grid's integers (no division, no cube root).
fn step_factor(allowed: Real, err: Real, lo: Real, hi: Real) -> Real {
    let bound = STEP_FACTOR_CUBE * allowed;
    var above = floor(hi * STEP_FACTOR_QUANTUM) + Real(1.0);
    if above * above * above * err <= bound {
        return hi;
    }
    var below = ceil(lo * STEP_FACTOR_QUANTUM) - Real(1.0);
    for (var k = 0u; k < STEP_FACTOR_BISECTIONS; k++) {
        if above - below <= Real(1.0) {
            break;
        }
        let n = floor(Real(0.5) * (above + below));
        if n * n * n * err <= bound {
            below = n;
        } else {
            above = n;
        }
    }
    return max(below * STEP_FACTOR_GRID, lo);
}
