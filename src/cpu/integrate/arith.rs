//! Arithmetic the shader cannot take from its standard library, written out
//! so the CPU computes exactly what the shader computes.

use super::Real;
use super::constants::{STEP_FACTOR_BISECTIONS, STEP_FACTOR_CUBE, STEP_FACTOR_QUANTUM};
use super::precision::only_f64;

/// The step-size factor `0.9 cbrt(allowed / err)` rounded down to a
/// multiple of 1 / [`STEP_FACTOR_QUANTUM`] and limited to [lo, hi] (hi at
/// most 8): the classic controller for an error that grows like the cube of
/// the step. It neither divides nor takes a cube root (both are sequences
/// of operations on the f64 shader): it bisects the grid's integers n for
/// the largest with n^3 err <= (0.9 quantum)^3 allowed, products the shader
/// rounds as the CPU does. An error of zero gives hi; an infinite or NaN
/// one gives lo.
pub fn step_factor(allowed: Real, err: Real, lo: Real, hi: Real) -> Real {
    let quantum = STEP_FACTOR_QUANTUM as Real;
    let bound = STEP_FACTOR_CUBE as Real * allowed;
    // Above: the first grid integer beyond hi (n there gives hi after the
    // limit); below: the last one short of lo (lo where nothing passes).
    let mut above = (hi * quantum).floor() + 1.0;
    if above * above * above * err <= bound {
        return hi;
    }
    let mut below = (lo * quantum).ceil() - 1.0;
    for _ in 0..STEP_FACTOR_BISECTIONS {
        if above - below <= 1.0 {
            break;
        }
        let n = (0.5 * (above + below)).floor();
        if n * n * n * err <= bound {
            below = n;
        } else {
            above = n;
        }
    }
    (below * (1.0 / STEP_FACTOR_QUANTUM) as Real).max(lo)
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;

    /// The factor is the continuous controller rounded down to the grid,
    /// within the limits, for ratios across and beyond both limits.
    #[test]
    fn step_factor_is_the_controller_rounded_down() {
        for err in [0.0, 1e-12, 1e-7, 1e-4, 3e-4, 1e-2, 0.5, 1.0, 7.0, 1e3, Real::INFINITY] {
            for (lo, hi) in [(0.1, 0.9), (0.2, 4.0)] {
                let tol = 1e-4;
                let exact: Real = (0.9 * Real::cbrt(tol / err)).clamp(lo, hi);
                let got = step_factor(tol, err, lo, hi);
                assert!(
                    got <= exact && exact - got < 1.0 / STEP_FACTOR_QUANTUM,
                    "err {err}: {got} against {exact}"
                );
                let on_grid = got == (got * STEP_FACTOR_QUANTUM).round() / STEP_FACTOR_QUANTUM;
                assert!(on_grid || got == lo || got == hi, "{got} is off the grid");
            }
        }
        assert_eq!(step_factor(1e-4, Real::NAN, 0.2, 4.0), 0.2);
    }

    /// Where 0.9 cbrt(r) lands exactly on a grid point, that point passes.
    #[test]
    fn step_factor_keeps_exact_grid_points() {
        for n in [13.0, 32.0, 57.0, 100.0, 255.0] {
            let f: Real = n / STEP_FACTOR_QUANTUM;
            // f^3 err = 0.729 allowed with err = 1: allowed = (f / 0.9)^3.
            let allowed = (n * n * n) / STEP_FACTOR_CUBE;
            let got = step_factor(allowed * (1.0 + 1e-12), 1.0, 0.2, 4.0);
            assert_eq!(got, f, "n = {n}");
        }
    }
}
}
