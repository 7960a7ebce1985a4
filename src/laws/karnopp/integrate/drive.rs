//! The sawtooth drives: the force and its slope now, the time of each
//! axis' next corner, and the passing of corners and period ends.

use super::coefficients::Coefficients;
use super::constants::MODE_STICK;
use super::precision::only_f64;
use super::precision::{CORNER_CLOCK, DEFLECTION, FIXED_PHASE};
use super::step::{start_slip, stick_force};
use super::vec2::{Vec2, norm2};
use super::{Real, State, time_reached};

/// One linear piece of an axis' drive over a cycle, from a corner to the
/// next (docs/model.md section 2; `laws::floor::drive::Corners`). The
/// drive there is `amplitude * (level - to_corner * fall)`, with
/// `to_corner` the cycles left to its end: the sawtooth's rise is
/// `1 - to_corner / d` and its fall `to_corner / (1 - d)`, the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Segment {
    /// The phase of its end [cycles], and its length [cycles] (above 0:
    /// a jump is the step between one segment's end level and the next
    /// one's start).
    pub end: Real,
    pub length: Real,
    /// The level at its end, and its change per cycle, (L1 - L0) / length.
    pub level: Real,
    pub per_cycle: Real,
    /// The drive force's slope on it [N/s], (delta V f)(L1 - L0) / length.
    pub slope: Real,
    /// Its duration, length / f, as hi + lo [s] (the corner clock's).
    pub time: Real,
    pub time_lo: Real,
}

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
    let [x, y] = current_segments(c, st);
    let w = Vec2::new(x.level, y.level) - to_corner * Vec2::new(x.per_cycle, y.per_cycle);
    (c.amplitude * w, Vec2::new(x.slope, y.slope))
}

/// Whether an axis' segments are a sawtooth's, corner for corner: a
/// rise to level 1 from u = 0 and a fall to level 0 ending at u = 1 (or,
/// at duty 1, one rise to 1 over the cycle). The shader then drives it
/// from its coefficients (`gpu::karnopp::layout`: duty, 1 / d, 1 / (1 -
/// d), the slopes and durations of segments 0 and 1), which is this
/// module's arithmetic on these segments, bit for bit.
pub fn is_sawtooth(segments: &[Segment]) -> bool {
    match segments {
        [rise] => rise.end == 1.0 && rise.level == 1.0,
        [rise, fall] => rise.level == 1.0 && fall.level == 0.0 && fall.end == 1.0,
        _ => false,
    }
}

/// Each axis' current segment.
fn current_segments<'a>(c: &'a Coefficients, st: &State) -> [&'a Segment; 2] {
    [0, 1].map(|i| &c.segments[i][st.segment[i] as usize])
}

/// The segment of `segments` that holds cycle phase `p` in [0, 1), and
/// the phase of its end (on `p`'s scale): the first one to end past `p`,
/// or the one that wraps past the cycle's end where `p` lies before the
/// first one's start.
pub fn segment_at(segments: &[Segment], p: Real) -> (u32, Real) {
    let last = segments.len() - 1;
    if p < segments[0].end - segments[0].length {
        return (last as u32, segments[last].end - 1.0);
    }
    let k = segments.iter().position(|s| p < s.end).unwrap_or(last);
    (k as u32, segments[k].end)
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
            let count = c.segments[i].len() as u32;
            st.segment[i] = if st.segment[i] + 1 < count {
                st.segment[i] + 1
            } else {
                0
            };
            let next = &c.segments[i][st.segment[i] as usize];
            st.next_corner[i] += next.length;
            if CORNER_CLOCK {
                let moved = add_parts(
                    (st.corner_at[i], st.corner_at_lo[i]),
                    (next.time, next.time_lo),
                );
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

/// `exact` (an f64 drive's segments) in this precision: each value
/// rounded once, the lengths the differences of the rounded ends (the
/// sawtooth's fall is then `1 - d` in this precision, as the shader has
/// it), and the durations in two parts split by `round`.
#[allow(clippy::unnecessary_cast)]
pub fn rounded(
    exact: &[crate::laws::karnopp::double::integrate::drive::Segment],
    round: impl Fn(f64) -> f64,
) -> Box<[Segment]> {
    let last_end = exact.last().expect("a drive has a segment").end as Real;
    let mut start = last_end - 1.0;
    exact
        .iter()
        .map(|e| {
            let end = e.end as Real;
            let hi = round(e.time);
            let seg = Segment {
                end,
                length: end - start,
                level: e.level as Real,
                per_cycle: e.per_cycle as Real,
                slope: e.slope as Real,
                time: hi as Real,
                time_lo: round(e.time - hi) as Real,
            };
            start = end;
            seg
        })
        .collect()
}

only_f64! {
/// One cycle of `axis`' drive as segments (`floor::drive::axis_corners`),
/// in the axis' units: jumps are no segment of their own. On an undriven
/// axis the slopes and durations are zero (its corners are never passed).
pub fn segments_of(axis: &crate::model::Axis) -> Box<[Segment]> {
    let corners = crate::laws::floor::drive::axis_corners(axis);
    let driven = axis.is_driven();
    let amplitude_rate = axis.gain * axis.voltage * axis.frequency;
    let pieces: Vec<_> = corners.segments().filter(|(a, b)| b[0] > a[0]).collect();
    let mut start = pieces.last().expect("a waveform rises or falls").1[0] - 1.0;
    pieces
        .into_iter()
        .map(|(a, b)| {
            let (end, level) = (b[0], b[1]);
            let length = end - start;
            let change = level - a[1];
            start = end;
            Segment {
                end,
                length,
                level,
                per_cycle: change / length,
                slope: if driven { amplitude_rate * change / length } else { 0.0 },
                time: if driven { length / axis.frequency } else { 0.0 },
                time_lo: 0.0,
            }
        })
        .collect()
}

/// The local time of each axis' first corner, as hi + lo [s] with the
/// parts split by `round` (zero low parts in f64): the corner clock's
/// start (f32's `CORNER_CLOCK`). It divides by the frequency, as
/// [`corner_time`] does.
pub fn first_corner(c: &Coefficients, round: impl Fn(Real) -> Real) -> (Vec2, Vec2) {
    let at = |i: usize| {
        if !c.driven[i] {
            return (0.0, 0.0);
        }
        let p = frac(c.phase[i]);
        let (_, corner) = segment_at(&c.segments[i], p);
        let t = ((corner - p) / c.frequency[i]).max(0.0);
        let hi = round(t);
        (hi, round(t - hi))
    };
    let (x, y) = (at(0), at(1));
    (Vec2::new(x.0, y.0), Vec2::new(x.1, y.1))
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
        let to_f32 = |x: Real| x as f32 as Real;
        let f32_segments = rounded(&c.segments[0], to_f32);
        let exact = &c.segments[0];
        assert!(exact.iter().all(|s| s.time_lo == 0.0));
        let f32_first = first_corner(&c, to_f32);
        let period = (c.period as f32, (c.period - c.period as f32 as Real) as f32);
        let mut at = (f32_first.0.x as f32, f32_first.1.x as f32);
        let mut plain = at.0;
        let mut truth = first_corner(&c, |x| x).0.x;
        let mut k = segment_at(exact, frac(inst.axes[0].phase)).0 as usize;
        let mut worst: Real = 0.0;
        let mut worst_plain: Real = 0.0;
        for _ in 0..1000 {
            while truth < c.period {
                k = (k + 1) % exact.len();
                let seg = (f32_segments[k].time as f32, f32_segments[k].time_lo as f32);
                at = add_parts(at, seg);
                plain += seg.0;
                truth += exact[k].time;
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
