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

/// The fractional part, u - floor(u).
pub fn frac(u: f64) -> f64 {
    u - u.floor()
}

/// WGSL's `round`: to the nearest integer, halves to even.
fn round_half_even(x: f64) -> f64 {
    x.round_ties_even()
}
