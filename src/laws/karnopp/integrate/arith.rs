//! Arithmetic the shader cannot take from its standard library, written out
//! so the CPU computes exactly what the shader computes.

use super::Real;
use super::constants::{STEP_FACTOR_BISECTIONS, STEP_FACTOR_CUBE, STEP_FACTOR_QUANTUM};
use super::precision::only_f64;

/// The step-size factor `0.9 cbrt(allowed / err)` rounded down to a
/// multiple of 1 / [`STEP_FACTOR_QUANTUM`] and limited to [lo, hi] (hi at
/// most 8): the classic controller for an error that grows like the cube of
/// the step; with a second bound (`allowed2`, `err2`) the smaller of the
/// two factors, found together (`err2` = 0: no second bound). It neither
/// divides nor takes a cube root (both are sequences of operations on the
/// f64 shader): it bisects the grid's integers n for the largest with n^3
/// err <= (0.9 quantum)^3 allowed (and the same for the second bound),
/// products the shader rounds as the CPU does. An error of zero gives hi;
/// an infinite or NaN one gives lo.
pub fn step_factor(
    allowed: Real,
    err: Real,
    allowed2: Real,
    err2: Real,
    lo: Real,
    hi: Real,
) -> Real {
    let quantum = STEP_FACTOR_QUANTUM as Real;
    let cube = STEP_FACTOR_CUBE as Real;
    let (bound, bound2) = (cube * allowed, cube * allowed2);
    // n^3 is exact in u32 (n <= 513) and rounded once to Real, as the
    // float product n * n * n would be. Each test is monotone in n, so
    // their conjunction is, and its largest n is the smaller factor's.
    let passes = |n: u32| {
        let n3 = (n * n * n) as Real;
        n3 * err <= bound && n3 * err2 <= bound2
    };
    // Above: the first grid integer beyond hi (n there gives hi after the
    // limit); below: the last one short of lo (lo where nothing passes).
    let mut above = (hi * quantum) as u32 + 1;
    if passes(above) {
        return hi;
    }
    let mut below = (lo * quantum).ceil() as u32 - 1;
    for _ in 0..STEP_FACTOR_BISECTIONS {
        if above - below <= 1 {
            break;
        }
        let n = (above + below) / 2;
        if passes(n) {
            below = n;
        } else {
            above = n;
        }
    }
    (below as Real * (1.0 / STEP_FACTOR_QUANTUM) as Real).max(lo)
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;

    /// The factor is the continuous controller rounded down to the grid,
    /// within the limits, for ratios across and beyond both limits; with a
    /// second bound, the smaller of the two factors.
    #[test]
    fn step_factor_is_the_controller_rounded_down() {
        for err in [0.0, 1e-12, 1e-7, 1e-4, 3e-4, 1e-2, 0.5, 1.0, 7.0, 1e3, Real::INFINITY] {
            for (lo, hi) in [(0.1, 0.9), (0.2, 4.0)] {
                let tol = 1e-4;
                let exact: Real = (0.9 * Real::cbrt(tol / err)).clamp(lo, hi);
                let got = step_factor(tol, err, tol, 0.0, lo, hi);
                let both = step_factor(tol, err, 4.0 * tol, 2.0 * err, lo, hi);
                assert_eq!(both, got.min(step_factor(4.0 * tol, 2.0 * err, tol, 0.0, lo, hi)));
                assert!(
                    got <= exact && exact - got < 1.0 / STEP_FACTOR_QUANTUM,
                    "err {err}: {got} against {exact}"
                );
                let on_grid = got == (got * STEP_FACTOR_QUANTUM).round() / STEP_FACTOR_QUANTUM;
                assert!(on_grid || got == lo || got == hi, "{got} is off the grid");
            }
        }
        assert_eq!(step_factor(1e-4, Real::NAN, 1e-4, 0.0, 0.2, 4.0), 0.2);
    }

    /// Where 0.9 cbrt(r) lands exactly on a grid point, that point passes.
    #[test]
    fn step_factor_keeps_exact_grid_points() {
        for n in [13.0, 32.0, 57.0, 100.0, 255.0] {
            let f: Real = n / STEP_FACTOR_QUANTUM;
            // f^3 err = 0.729 allowed with err = 1: allowed = (f / 0.9)^3.
            let allowed = (n * n * n) / STEP_FACTOR_CUBE;
            let got = step_factor(allowed * (1.0 + 1e-12), 1.0, 1.0, 0.0, 0.2, 4.0);
            assert_eq!(got, f, "n = {n}");
        }
    }
}
}
