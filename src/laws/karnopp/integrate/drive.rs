//! The sawtooth drives: the force and its slope now, the time of each
//! axis' next corner, and the passing of corners and period ends.

use super::coefficients::Coefficients;
use super::constants::MODE_STICK;
use super::precision::only_f64;
use super::precision::{CORNER_CLOCK, DEFLECTION, FIXED_PHASE};
use super::step::{start_slip, stick_force};
use super::vec2::{Vec2, norm2};
use super::{Real, State, time_reached};

/// Local time of each axis' next drive corner, or infinity where undriven.
/// It divides by the frequency rather than multiplying by its inverse:
/// corners of different axes that coincide exactly (3.5 cycles at 35 Hz
/// and 1 cycle at 10 Hz) then coincide in floating point too, and their
/// force jumps are passed together, as the model has them.
pub fn corner_time(c: &Coefficients, st: &State) -> Vec2 {
    // A division, not a product with 1 / f: the corner at the end of a
    // cycle must fall on the period's end exactly, and a product moved a
    // duty-1 drive's jump 4e-14 s into the next period (issue 47: a
    // stress instance then failed at tolerance 1e-8).
    let mut t = ((st.next_corner - st.cycle_phase) / c.frequency).map(|t| t.max(0.0));
    if CORNER_CLOCK {
        t = st.corner_at;
    }
    Vec2::select(Vec2::splat(Real::INFINITY), t, c.driven)
}

/// The low part of [`corner_time`] (zero unless `CORNER_CLOCK`).
pub fn corner_time_lo(c: &Coefficients, st: &State) -> Vec2 {
    if CORNER_CLOCK {
        Vec2::select(Vec2::ZERO, st.corner_at_lo, c.driven)
    } else {
        Vec2::ZERO
    }
}

/// The drive force of each axis now, and its slope [N, N/s].
pub fn drive_force(c: &Coefficients, st: &State) -> (Vec2, Vec2) {
    let to_corner = if CORNER_CLOCK {
        // The distance to the corner from the two-part times: exact where
        // the step stops at the corner, and relative to itself elsewhere.
        let ahead = (st.corner_at - st.time) + (st.corner_at_lo - st.time_lo);
        (c.frequency * ahead).map(|d| d.max(0.0))
    } else {
        let u = st.cycle_phase + c.frequency * st.time;
        (st.next_corner - u).map(|d| d.max(0.0))
    };
    let rising = [st.rising[0] == 1, st.rising[1] == 1];
    let w = Vec2::select(to_corner * c.inv_fall, 1.0 - to_corner * c.inv_duty, rising);
    let slope = Vec2::select(c.fall_slope, c.rise_slope, rising);
    (c.amplitude * w, slope)
}

/// Passes every drive corner and the period end that lie at the current
/// time, then lets a stuck slider break loose if a jump of the drive (duty
/// 1) demands it.
pub fn pass_boundaries(c: &Coefficients, st: &mut State) {
    // The drive just before the corners, which DEFLECTION follows.
    let before = if DEFLECTION {
        drive_force(c, st)
    } else {
        (Vec2::ZERO, Vec2::ZERO)
    };
    let corners = corner_time(c, st);
    let corners_lo = corner_time_lo(c, st);
    for i in 0..2 {
        if time_reached(st, corners[i], corners_lo[i]) {
            let duty = c.duty[i];
            let rising = st.rising[i] == 1;
            if duty >= 1.0 {
                st.next_corner[i] += 1.0;
            } else if rising {
                st.rising[i] = 0;
                st.next_corner[i] += 1.0 - duty;
            } else {
                st.rising[i] = 1;
                st.next_corner[i] += duty;
            }
            if CORNER_CLOCK {
                // The next corner is a fall after a rise, a rise after a
                // fall, and a cycle after a jump (duty 1, whose rise time
                // is the cycle).
                let falls = rising && duty < 1.0;
                let next = if falls {
                    (c.fall_time[i], c.fall_time_lo[i])
                } else {
                    (c.rise_time[i], c.rise_time_lo[i])
                };
                let moved = add_parts((st.corner_at[i], st.corner_at_lo[i]), next);
                st.corner_at[i] = moved.0;
                st.corner_at_lo[i] = moved.1;
            }
            if DEFLECTION {
                // The deflections follow the drive's static motion across
                // the corner: its slope changes, and its force jumps at
                // duty 1.
                let after = drive_force(c, st);
                st.x_p[i] += (before.0[i] - after.0[i]) * c.inv_stiffness[i];
                st.v_p[i] += (before.1[i] - after.1[i]) * c.inv_stiffness[i];
            }
        }
    }
    if time_reached(st, c.period, c.period_lo) {
        if CORNER_CLOCK {
            for i in 0..2 {
                let back = add_parts(
                    (st.corner_at[i], st.corner_at_lo[i]),
                    (-c.period, -c.period_lo),
                );
                st.corner_at[i] = back.0;
                st.corner_at_lo[i] = back.1;
            }
        }
        st.period += 1;
        st.time = 0.0;
        st.time_lo = 0.0;
        let end_phase = st.cycle_phase + c.frequency * c.period;
        let start_phase = if FIXED_PHASE {
            fixed_start_phase(c, st.period)
        } else {
            (c.phase + st.period as Real * c.cycles_per_period).map(frac)
        };
        let shift = (end_phase - start_phase).map(round_half_even);
        st.cycle_phase = start_phase;
        st.next_corner = st.next_corner - shift;
        if st.period == c.settle {
            st.settle_x_s = st.x_s;
        }
    }
    if st.mode == MODE_STICK {
        let need = stick_force(c, st);
        if norm2(need) > c.hold2 {
            start_slip(c, st, need);
        }
    }
}

/// The high word of the 64-bit product of two u32 (WGSL has no wide
/// multiply; the shader builds it from 16-bit halves).
pub fn mul_hi(a: u32, b: u32) -> u32 {
    ((a as u64 * b as u64) >> 32) as u32
}

/// The drive phase of each axis at the start of scene period `period`,
/// `frac(phase + period * cycles_per_period)`, from the fixed-point
/// coefficients: an exact integer sum (to 2^-32 cycles for the phase and
/// period * 2^-64 cycles for the cycles per period), converted once. The
/// f32 shader starts its periods with it (`FIXED_PHASE`); the f64 paths
/// keep the floating-point sum of [`pass_boundaries`], which this agrees
/// with to about 1e-9 cycles (tested).
pub fn fixed_start_phase(c: &Coefficients, period: u32) -> Vec2 {
    let at = |i: usize| {
        let s = c.phase_fixed[i]
            .wrapping_add(period.wrapping_mul(c.cycles_fixed[i]))
            .wrapping_add(mul_hi(period, c.cycles_fixed_lo[i]));
        let p = s as Real * (1.0 / 4_294_967_296.0);
        if p >= 1.0 { 0.0 } else { p }
    };
    Vec2::new(at(0), at(1))
}

only_f64! {
/// The f32 shader's corner clock (`CORNER_CLOCK`): each axis' next drive
/// corner as a local time in two parts, hi + lo, each in the shader's
/// precision, advanced by the two-part durations of the drive's segments
/// and moved back by the two-part period at each period end, so a corner
/// is known to about 1e-14 of the period where one f32 time within the
/// period knows it to 6e-8 of the period (about 1e-7 drive cycles): the
/// random scenes' f32 misses of issue 19 went with per-corner noise of that
/// size (results/gpu.md). The drive reads its distance to the corner from
/// the same two parts, so the force reaches its corner value exactly where
/// the step stops. The f64 paths keep the phase of [`drive_force`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerClock {
    /// Duration of a rise (a whole cycle for duty 1) and of a fall, as
    /// (hi, lo) [time units].
    pub rise: (Vec2, Vec2),
    pub fall: (Vec2, Vec2),
    /// The local time of the first corner (as [`corner_time`] of the
    /// initial state).
    pub first: (Vec2, Vec2),
    /// The scene period.
    pub period: (Real, Real),
}

impl CornerClock {
    /// The clock of coefficients `c`, each value split into a part that
    /// `round` (to the shader's precision) leaves unchanged and the rounded
    /// rest; zero on undriven axes. With `round` the identity (f64) the low
    /// parts are zero.
    pub fn new(c: &Coefficients, round: impl Fn(Real) -> Real) -> CornerClock {
        let split = |x: Real| {
            let hi = round(x);
            (hi, round(x - hi))
        };
        let per_axis = |f: &dyn Fn(usize) -> Real| {
            let x = split(if c.driven[0] { f(0) } else { 0.0 });
            let y = split(if c.driven[1] { f(1) } else { 0.0 });
            (Vec2::new(x.0, y.0), Vec2::new(x.1, y.1))
        };
        let first = |i: usize| {
            let p = frac(c.phase[i]);
            let corner = if p < c.duty[i] { c.duty[i] } else { 1.0 };
            ((corner - p) / c.frequency[i]).max(0.0)
        };
        CornerClock {
            rise: per_axis(&|i| c.duty[i].min(1.0) / c.frequency[i]),
            fall: per_axis(&|i| (1.0 - c.duty[i]).max(0.0) / c.frequency[i]),
            first: per_axis(&first),
            period: split(c.period),
        }
    }
}
}

/// Knuth's two-sum: `a + b` and its rounding error, exactly (the shader's
/// `two_sum`, which guards the same operations against compiler algebra).
pub fn two_sum<T>(a: T, b: T) -> (T, T)
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Sub<Output = T>,
{
    let sum = a + b;
    let bb = sum - a;
    (sum, (a - (sum - bb)) + (b - bb))
}

/// (a_hi + a_lo) + (b_hi + b_lo) as a two-part value (the shader's
/// `add_parts`).
pub fn add_parts<T>(a: (T, T), b: (T, T)) -> (T, T)
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Sub<Output = T>,
{
    let (s, e) = two_sum(a.0, b.0);
    two_sum(s, e + (a.1 + b.1))
}

/// The fractional part, u - floor(u).
pub fn frac(u: Real) -> Real {
    u - u.floor()
}

/// WGSL's `round`: to the nearest integer, halves to even.
fn round_half_even(x: Real) -> Real {
    x.round_ties_even()
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;
    use crate::laws::karnopp::integrate::Settings;
    use crate::model::Instance;

    /// A corner clock in f32 parts, run through a thousand periods of rises
    /// and falls the way the shader runs it, stays within 1e-12 of the
    /// period of the f64 corner times, where one f32 time drifts by 1e-7.
    #[test]
    fn two_part_corner_times_stay_exact_in_f32() {
        let mut inst = Instance::TABLE1;
        inst.axes[0].duty = 0.8346873373227778;
        inst.axes[0].frequency = 18.810317121061885;
        inst.axes[0].phase = 0.9206799357119667;
        let c = Coefficients::new(&inst, &Settings::default(), Real::EPSILON);
        let f32_parts = CornerClock::new(&c, |x| x as f32 as Real);
        let exact = CornerClock::new(&c, |x| x);
        assert_eq!(exact.rise.1, Vec2::ZERO);
        let part = |p: (Vec2, Vec2)| (p.0.x as f32, p.1.x as f32);
        let (rise, fall) = (part(f32_parts.rise), part(f32_parts.fall));
        let period = (f32_parts.period.0 as f32, f32_parts.period.1 as f32);
        let mut at = part(f32_parts.first);
        let mut plain = at.0;
        let mut truth = exact.first.0.x;
        let mut rising = frac(inst.axes[0].phase) < inst.axes[0].duty;
        let mut worst: Real = 0.0;
        let mut worst_plain: Real = 0.0;
        for _ in 0..1000 {
            while truth < c.period {
                let seg = if rising { fall } else { rise };
                let seg_exact = if rising {
                    exact.fall.0.x
                } else {
                    exact.rise.0.x
                };
                at = add_parts(at, seg);
                plain += seg.0;
                truth += seg_exact;
                rising = !rising;
                let got = at.0 as Real + at.1 as Real;
                worst = worst.max((got - truth).abs());
                worst_plain = worst_plain.max((plain as Real - truth).abs());
            }
            at = add_parts(at, (-period.0, -period.1));
            plain -= period.0;
            truth -= c.period;
        }
        assert!(worst < 1e-12 * c.period, "two-part {worst:e} s");
        assert!(worst_plain > 1e-8 * c.period, "one f32 {worst_plain:e} s");
    }

    #[test]
    fn mul_hi_is_the_high_word() {
        for (a, b) in [
            (0u32, 0u32),
            (1, u32::MAX),
            (u32::MAX, u32::MAX),
            (0x1234_5678, 0x9abc_def0),
        ] {
            assert_eq!(mul_hi(a, b) as u64, (a as u64 * b as u64) >> 32);
        }
    }

    /// The fixed-point period starts agree with the f64 sum to about 1e-9
    /// cycles over a thousand periods, where f32's sum is off by 1e-6
    /// cycles at the fifth.
    #[test]
    fn fixed_start_phases_match_the_f64_sum() {
        let mut inst = Instance::TABLE1;
        inst.axes[0].phase = 0.8774;
        inst.axes[1].phase = 0.7407242613911252;
        inst.axes[0].frequency = 6.703568273604459;
        inst.axes[1].frequency = 39.40968822913329;
        let c = Coefficients::new(&inst, &Settings::default(), Real::EPSILON);
        let mut worst: Real = 0.0;
        for n in [0u32, 1, 2, 3, 5, 17, 100, 999] {
            let fixed = fixed_start_phase(&c, n);
            let exact = (c.phase + n as Real * c.cycles_per_period).map(frac);
            for i in 0..2 {
                let d = (fixed[i] - exact[i]).abs();
                worst = worst.max(d.min(1.0 - d));
            }
        }
        assert!(worst < 1e-9, "worst {worst:e} cycles");
    }
}
}
