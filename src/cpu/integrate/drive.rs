//! The sawtooth drives: the force and its slope now, the time of each
//! axis' next corner, and the passing of corners and period ends.

use super::State;
use super::coefficients::Coefficients;
use super::constants::MODE_STICK;
use super::step::{start_slip, stick_force};
use super::vec2::{Vec2, norm2};

/// Local time of each axis' next drive corner, or infinity where undriven.
/// It divides by the frequency rather than multiplying by its inverse:
/// corners of different axes that coincide exactly (3.5 cycles at 35 Hz
/// and 1 cycle at 10 Hz) then coincide in floating point too, and their
/// force jumps are passed together, as the model has them.
pub fn corner_time(c: &Coefficients, st: &State) -> Vec2 {
    let t = ((st.next_corner - st.cycle_phase) / c.frequency).map(|t| t.max(0.0));
    Vec2::select(Vec2::splat(f64::INFINITY), t, c.driven)
}

/// The drive force of each axis now, and its slope [N, N/s].
pub fn drive_force(c: &Coefficients, st: &State) -> (Vec2, Vec2) {
    let u = st.cycle_phase + c.frequency * st.time;
    let to_corner = (st.next_corner - u).map(|d| d.max(0.0));
    let rising = [st.rising[0] == 1, st.rising[1] == 1];
    let w = Vec2::select(to_corner * c.inv_fall, 1.0 - to_corner * c.inv_duty, rising);
    let slope = Vec2::select(c.fall_slope, c.rise_slope, rising);
    (c.amplitude * w, slope)
}

/// Passes every drive corner and the period end that lie at the current
/// time, then lets a stuck slider break loose if a jump of the drive (duty
/// 1) demands it.
pub fn pass_boundaries(c: &Coefficients, st: &mut State) {
    let corners = corner_time(c, st);
    for i in 0..2 {
        if corners[i] <= st.time {
            let duty = c.duty[i];
            if duty >= 1.0 {
                st.next_corner[i] += 1.0;
            } else if st.rising[i] == 1 {
                st.rising[i] = 0;
                st.next_corner[i] += 1.0 - duty;
            } else {
                st.rising[i] = 1;
                st.next_corner[i] += duty;
            }
        }
    }
    if st.time >= c.period {
        st.period += 1;
        st.time = 0.0;
        let end_phase = st.cycle_phase + c.frequency * c.period;
        let start_phase = (c.phase + st.period as f64 * c.cycles_per_period).map(frac);
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
        let p = s as f64 * (1.0 / 4_294_967_296.0);
        if p >= 1.0 { 0.0 } else { p }
    };
    Vec2::new(at(0), at(1))
}

/// The fractional part, u - floor(u).
pub fn frac(u: f64) -> f64 {
    u - u.floor()
}

/// WGSL's `round`: to the nearest integer, halves to even.
fn round_half_even(x: f64) -> f64 {
    x.round_ties_even()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::integrate::Settings;
    use crate::model::Instance;

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
        let c = Coefficients::new(&inst, &Settings::default(), f64::EPSILON);
        let mut worst: f64 = 0.0;
        for n in [0u32, 1, 2, 3, 5, 17, 100, 999] {
            let fixed = fixed_start_phase(&c, n);
            let exact = (c.phase + n as f64 * c.cycles_per_period).map(frac);
            for i in 0..2 {
                let d = (fixed[i] - exact[i]).abs();
                worst = worst.max(d.min(1.0 - d));
            }
        }
        assert!(worst < 1e-9, "worst {worst:e} cycles");
    }
}
