// Mirror of `laws::karnopp::integrate::arith`: arithmetic WGSL's standard library
// lacks, written out so the CPU computes exactly what the shader computes.

// The step-size factor 0.9 cbrt(allowed / err) rounded down to a multiple
// of 1 / STEP_FACTOR_QUANTUM and limited to [lo, hi], the smaller of it and
// the second bound's (err2 = 0: none), by bisection of the grid's integers
// (no division, no cube root; n^3 exact in u32).
fn step_factor(allowed: Real, err: Real, allowed2: Real, err2: Real, lo: Real, hi: Real) -> Real {
    let bound = STEP_FACTOR_CUBE * allowed;
    let bound2 = STEP_FACTOR_CUBE * allowed2;
    var above = u32(hi * STEP_FACTOR_QUANTUM) + 1u;
    let top = Real(above * above * above);
    if top * err <= bound && top * err2 <= bound2 {
        return hi;
    }
    var below = u32(ceil(lo * STEP_FACTOR_QUANTUM)) - 1u;
    for (var k = 0u; k < STEP_FACTOR_BISECTIONS; k++) {
        if above - below <= 1u {
            break;
        }
        let n = (above + below) / 2u;
        let n3 = Real(n * n * n);
        if n3 * err <= bound && n3 * err2 <= bound2 {
            below = n;
        } else {
            above = n;
        }
    }
    return max(Real(below) * STEP_FACTOR_GRID, lo);
}
