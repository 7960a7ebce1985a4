//! Arithmetic the shader cannot take from its standard library, written out
//! so the CPU computes exactly what the shader computes.

use super::Real;
use super::constants::{
    CUBE_ROOT_GUESS, CUBE_ROOT_ITERATIONS, ONE_THIRD, STEP_FACTOR_QUANTUM, STEP_RATIO_MAX,
    STEP_RATIO_MIN,
};
use super::precision::only_f64;

/// The cube root of `c` in [1e-3, 1e2] by range reduction to [1/8, 1]
/// (exact scalings by 8) and Newton's iteration from a linear guess. WGSL
/// has no cube root, and f64 WGSL no `pow`; the CPU uses the same iteration
/// so that both step-size controllers take the same steps.
pub fn cube_root(c: Real) -> Real {
    let mut x = c;
    let mut scale = 1.0;
    for _ in 0..4 {
        if x > 1.0 {
            x *= 0.125;
            scale *= 2.0;
        }
    }
    for _ in 0..4 {
        if x < 0.125 {
            x *= 8.0;
            scale *= 0.5;
        }
    }
    let mut y = CUBE_ROOT_GUESS[0] as Real + CUBE_ROOT_GUESS[1] as Real * x;
    for _ in 0..CUBE_ROOT_ITERATIONS {
        y = (2.0 * y + x / (y * y)) * ONE_THIRD as Real;
    }
    y * scale
}

/// A step-size factor 0.9 cbrt(ratio), rounded down to a multiple of
/// 1 / [`STEP_FACTOR_QUANTUM`] and limited to [lo, hi]: the classic
/// controller for an error that grows like the cube of the step.
pub fn step_factor(ratio: Real, lo: Real, hi: Real) -> Real {
    let r = ratio.clamp(STEP_RATIO_MIN as Real, STEP_RATIO_MAX as Real);
    let quantum = STEP_FACTOR_QUANTUM as Real;
    let factor = (0.9 * cube_root(r) * quantum).floor() * (1.0 / STEP_FACTOR_QUANTUM) as Real;
    factor.clamp(lo, hi)
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_root_is_accurate_over_its_range() {
        let mut worst: Real = 0.0;
        let mut c = STEP_RATIO_MIN;
        while c <= STEP_RATIO_MAX {
            let err = (cube_root(c) - c.cbrt()).abs() / c.cbrt();
            worst = worst.max(err);
            c *= 1.0137;
        }
        assert!(worst <= 4.0 * Real::EPSILON, "relative error {worst:e}");
    }

    #[test]
    fn step_factor_is_the_controller_rounded_down() {
        for ratio in [1e-9, 1e-4, 1e-3, 0.01, 0.5, 1.0, 2.0, 50.0, 1e3, 1e12] {
            for (lo, hi) in [(0.1, 0.9), (0.2, 4.0)] {
                let exact: Real = (0.9 * Real::cbrt(ratio)).clamp(lo, hi);
                let got = step_factor(ratio, lo, hi);
                assert!(
                    got <= exact && exact - got < 1.0 / STEP_FACTOR_QUANTUM,
                    "ratio {ratio}: {got} against {exact}"
                );
                let on_grid = got == (got * STEP_FACTOR_QUANTUM).round() / STEP_FACTOR_QUANTUM;
                assert!(on_grid || got == lo || got == hi, "{got} is off the grid");
            }
        }
    }
}
}
