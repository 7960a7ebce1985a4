// Mirror of src/cpu/integrate/arith.rs: arithmetic WGSL's standard library
// lacks, written out so the CPU computes exactly what the shader computes.

// The cube root of `c` in [1e-3, 1e2] by range reduction to [1/8, 1] and
// Newton's iteration from a linear guess.
fn cube_root(c: Real) -> Real {
    var x = c;
    var scale = Real(1.0);
    for (var k = 0u; k < 4u; k++) {
        if x > Real(1.0) {
            x *= Real(0.125);
            scale *= Real(2.0);
        }
    }
    for (var k = 0u; k < 4u; k++) {
        if x < Real(0.125) {
            x *= Real(8.0);
            scale *= Real(0.5);
        }
    }
    var y = CUBE_ROOT_GUESS_0 + CUBE_ROOT_GUESS_1 * x;
    for (var k = 0u; k < CUBE_ROOT_ITERATIONS; k++) {
        y = (Real(2.0) * y + div(x, y * y)) * ONE_THIRD;
    }
    return y * scale;
}

// A step-size factor 0.9 cbrt(ratio), rounded down to a multiple of
// 1 / STEP_FACTOR_QUANTUM and limited to [lo, hi].
fn step_factor(ratio: Real, lo: Real, hi: Real) -> Real {
    let r = clamp(ratio, STEP_RATIO_MIN, STEP_RATIO_MAX);
    let factor = floor(Real(0.9) * cube_root(r) * STEP_FACTOR_QUANTUM) * STEP_FACTOR_GRID;
    return clamp(factor, lo, hi);
}
