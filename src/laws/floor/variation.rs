//! The slider's backward travel (docs/model.md section 4, "Backward
//! travel"; issue 59), measured beside the step by any law, on the CPU in
//! f64.
//!
//! The backward travel of an axis is the slider's travel against its
//! step's direction per own drive cycle: the total variation of the
//! slider's position over the measured span, minus the absolute net
//! displacement, halved. The run keeps the cumulative total variation
//! per axis ([`Variation::total`]) as an extra position: a law adds each
//! step's variation ([`piece_variation`], with the slider's velocity
//! zeros inside the step located on the law's own dense output) and, at
//! every period end the step's measurement processes, [`follow`] records
//! that position into accumulators of the same shape as the step's
//! (`measure::Measure`): the same batches, the same phase-ladder windows,
//! the same cycle. What stops the run and which estimate a map shows stay
//! the step's: `follow` takes the step's verdict and never decides, and
//! the reduction (`crate::measurement::reduce_variation`) uses the step's
//! choice of estimate and MSER cut, so the step's maps are bit for bit
//! those of a run that does not measure the backward travel.

use super::double::gauge::Gauge;
use super::double::measure::{
    Measure, SNAPSHOTS, VERDICT_PERIODIC, VERDICT_RUNNING, VERDICT_WAITING, close_batch,
    initial_measure,
};
use super::double::phase::phase_period_end;
use super::double::vec2::Vec2;

/// A run's total variation and the accumulators that follow the step's
/// measurement with it (unused by a window, which reads `total` at its
/// end against its value when the measured periods began).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variation {
    /// The slider's total variation since the run began, per axis [m].
    pub total: Vec2,
    /// `total` when the measured periods began [m]: a window's start,
    /// which each law sets where it sets its record's `settle_x_s`.
    pub settle_total: Vec2,
    /// The step's accumulators, kept of `total` instead of the slider's
    /// position: `measure.travel` is the variation over the step's cycle
    /// or judged window, `measure.sums` over its batches.
    pub measure: Measure,
    /// `total` at the last common-period ends, a ring of the step's
    /// recurrence test's length: where the step finds its cycle, the
    /// variation over it is `total` now minus the one a cycle ago.
    snaps: [Vec2; SNAPSHOTS],
    taken: u32,
}

impl Variation {
    /// Nothing travelled yet, the accumulators of a run that has not
    /// started.
    pub fn new(c: &impl Gauge) -> Variation {
        Variation {
            total: Vec2::ZERO,
            settle_total: Vec2::ZERO,
            measure: initial_measure(c),
            snaps: [Vec2::ZERO; SNAPSHOTS],
            taken: 0,
        }
    }

    /// A variation kept elsewhere (a GPU lane's entry:
    /// `crate::gpu::layout::variation_to_cpu`): its total and the total
    /// when the measured periods began [m], its accumulators, and the ring
    /// of totals at common-period ends with the count taken.
    pub fn from_parts(
        total: Vec2,
        settle_total: Vec2,
        measure: Measure,
        snaps: [Vec2; SNAPSHOTS],
        taken: u32,
    ) -> Variation {
        Variation {
            total,
            settle_total,
            measure,
            snaps,
            taken,
        }
    }

    /// Lets the accumulators go on where the step's replica was released
    /// from its group's wait (`record::release`): `follow` then reads the
    /// step's next verdict as running again, as the step's own measure does.
    pub fn release(&mut self) {
        if self.measure.verdict == VERDICT_WAITING {
            self.measure.verdict = VERDICT_RUNNING;
        }
    }

    /// A cycle split's piece (`crate::replicas::cycle_split`), once it has
    /// run: the variation over its measured periods, read where the step's
    /// piece reads its ends (`replicas::group`'s `piece_ends`): over the
    /// cycle the step found, or between the first two common-period ends.
    pub fn piece_travel(&self) -> Option<Vec2> {
        match (self.measure.verdict, self.taken) {
            (VERDICT_PERIODIC, _) => Some(self.measure.travel),
            (_, 2..) => Some(self.snaps[1] - self.snaps[0]),
            _ => None,
        }
    }
}

/// Records `v.total` at the end of scene period `ended - 1`, right after
/// the step's measurement `step` processed that end (its verdict,
/// cycle and judged windows already this end's): the mirror of
/// `measure::period_end` with the variation as the position, deciding
/// nothing. `common` is the law's common period of its recurrence test
/// (0: none).
pub fn follow(c: &impl Gauge, common: u32, ended: u32, step: &Measure, v: &mut Variation) {
    let x = v.total;
    let m = &mut v.measure;
    m.next_end = ended;
    if ended < c.settle() {
        return;
    }
    if ended > c.settle() {
        let d = x - m.last_x_s;
        m.d_min = m.d_min.zip(d, f64::min);
        m.d_max = m.d_max.zip(d, f64::max);
        m.measured += 1;
        m.in_batch += 1;
        if m.in_batch == m.batch_length {
            close_batch(m, x);
        }
    } else {
        m.batch_start = x;
    }
    m.last_x_s = x;
    let running = m.verdict == VERDICT_RUNNING;
    let cycle_found = running && step.verdict == VERDICT_PERIODIC;
    if c.phase_levels() != 0 {
        let judged = phase_period_end(c, &mut m.phase, ended - c.settle(), x);
        if judged.span > 0 && running && !cycle_found {
            if c.replicas() > 1 {
                m.pending_level = judged.level;
            } else {
                m.travel = judged.value * judged.span as f64;
                m.span = judged.span;
                m.se2 = judged.se2;
            }
        }
    }
    if common > 0 && (ended - c.settle()).is_multiple_of(common) && running {
        if cycle_found {
            let back = step.lag / common;
            m.lag = step.lag;
            m.travel = x - v.snaps[((v.taken - back) % SNAPSHOTS as u32) as usize];
        } else {
            v.snaps[(v.taken % SNAPSHOTS as u32) as usize] = x;
            v.taken += 1;
        }
    }
    m.verdict = step.verdict;
}

/// The constants of `shaders/shared/pieces.wgsl`, from these (the one
/// home of each): the zero search's Hermite guess, its end and its cap.
pub fn wgsl_constants() -> String {
    format!(
        "const HERMITE_GUESS: Real = {HERMITE_GUESS:e};\n\
         const GUESSED_SHARE: Real = {GUESSED_SHARE:e};\n\
         const ZERO_TIME: Real = {ZERO_TIME:e};\n\
         const ZERO_ITERATIONS: u32 = {ZERO_ITERATIONS}u;\n"
    )
}

/// The slider's position, velocity and acceleration on one axis at one
/// instant [m, m/s, m/s^2].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    pub x: f64,
    pub v: f64,
    pub a: f64,
}

/// Newton steps at most (each kept inside its bracket, else a bisection)
/// that locate a velocity zero, until one is shorter than [`ZERO_TIME`]:
/// 40 bisections alone reach 1e-12 of the bracket. Measured: a cap of 8
/// left zeros of random instances unconverged, 1.8e-4 um of backward
/// travel off.
pub const ZERO_ITERATIONS: u32 = 40;

/// A Newton step from the first guess ([`locate_zero`]) at most this
/// share of the bracket gives the zero's position from that one
/// evaluation: the quadratic through it is off by a jerk's (1e-3 h)^3 / 6
/// there, 8e-11 of the ringing's amplitude over an eighth of its period
/// and 5e-9 over half of it (Karnopp's stick pieces, whose closed-form
/// guess is within about 1e-6 of the bracket).
pub const HERMITE_GUESS: f64 = 1e-3;

/// The same share for a law's own guess (Karnopp's closed form in stick,
/// within about 1e-6 of its half-period bracket): the quadratic is then
/// off by (1e-5 pi)^3 / 6, 5e-15 of the ringing's amplitude, where a
/// share of 1e-3 would let a rougher guess leave 5e-9 of it.
pub const GUESSED_SHARE: f64 = 1e-5;

/// A Newton step shorter than this share of the bracket ends the search:
/// the position is stationary at the zero, so the position found is off
/// by about a v' (1e-6 h)^2 / 2, 3e-13 of the ringing's amplitude over
/// an eighth of its period.
pub const ZERO_TIME: f64 = 1e-6;

/// The total variation of one axis' slider position over a piece of a
/// step from `a` to `b` (times 0 and `h` [s]), `at(t)` the law's dense
/// output at time t inside it: |x_b - x_a| where the velocity keeps its
/// sign, otherwise the sum over the sub-pieces between its zeros. A sign
/// change between the ends is one zero; where the ends share a sign, the
/// cubic Hermite of the velocity (its values and derivatives at the ends)
/// shows whether it dips through zero between them, and if the true
/// velocity at the Hermite's extremum does, two zeros are located around
/// it. The piece must be short against the motion's ringing, so that its
/// velocity has at most one extremum and two zeros in it (LuGre's steps
/// are; Karnopp cuts its stick steps at the velocity's extrema, so that
/// the velocity is monotone in each piece); a dip the Hermite does not
/// show is one whose travel is of the order of the Hermite's error.
/// `guess` is the law's first guess of the time [s after a] of the one
/// zero between ends of opposite signs (else the Hermite's zero).
pub fn piece_variation(
    a: Point,
    b: Point,
    h: f64,
    guess: Option<f64>,
    at: &impl Fn(f64) -> Point,
) -> f64 {
    if monotone(a, b, h) {
        return (b.x - a.x).abs();
    }
    if a.v * b.v < 0.0 {
        let (first, share) = match guess {
            Some(t) if t > 0.0 && t < h => (t, GUESSED_SHARE),
            _ => (hermite_root(a, b, h), HERMITE_GUESS),
        };
        let z = locate_zero(a, 0.0, b, h, (first, share), at);
        return (z.x - a.x).abs() + (b.x - z.x).abs();
    }
    match hermite_extremum(a, b, h) {
        Some(t) => {
            let m = at(t);
            if m.v * a.v < 0.0 || (a.v == 0.0 && m.v * b.v < 0.0) {
                let z1 = locate_zero(a, 0.0, m, t, (hermite_root(a, m, t), HERMITE_GUESS), at);
                let z2 = locate_zero(
                    m,
                    t,
                    b,
                    h,
                    (t + hermite_root(m, b, h - t), HERMITE_GUESS),
                    at,
                );
                (z1.x - a.x).abs() + (z2.x - z1.x).abs() + (b.x - z2.x).abs()
            } else {
                (b.x - a.x).abs()
            }
        }
        None => (b.x - a.x).abs(),
    }
}

/// Whether the cubic Hermite of the velocity over a piece of `h` [s]
/// cannot dip through zero between ends that share a sign: in
/// `v(s) = v0 H00 + v1 H01 + m0 H10 + m1 H11`, `H00 + H01 = 1` with both
/// at least 0, and `|H10|` and `|H11|` are at most 4 / 27, so no dip
/// reaches zero where the smaller end's speed exceeds 4 / 27 of the
/// slopes' sum.
fn no_dip(a: Point, b: Point, h: f64) -> bool {
    let (m0, m1) = (a.a * h, b.a * h);
    a.v.abs().min(b.v.abs()) * 27.0 > 4.0 * (m0.abs() + m1.abs())
}

/// Whether [`piece_variation`] of a piece of `h` [s] from `a` to `b` is
/// `|b.x - a.x|` from the ends alone: no sign change between them and no
/// dip ([`no_dip`]). A law may skip a step's pieces where every axis'
/// is (Karnopp's slip steps, whose lanes then leave the pieces' loops
/// out); the value is `piece_variation`'s, bit for bit.
pub fn monotone(a: Point, b: Point, h: f64) -> bool {
    let crosses = a.v * b.v < 0.0;
    !crosses && h > 0.0 && no_dip(a, b, h)
}

/// Where the cubic Hermite of the velocity over [0, h] (values a.v, b.v,
/// derivatives a.a, b.a) has an extremum strictly inside whose value has
/// the sign opposite to the ends' (or is zero), if it has one. Its one
/// caller, [`piece_variation`], has found a dip possible ([`monotone`]).
fn hermite_extremum(a: Point, b: Point, h: f64) -> Option<f64> {
    if h <= 0.0 {
        return None;
    }
    let [c0, c1, c2, c3] = hermite_cubic(a, b, h);
    let value = |s: f64| c0 + s * (c1 + s * (c2 + s * c3));
    // v'(s) = c1 + 2 c2 s + 3 c3 s^2 = 0.
    let (qa, qb, qc) = (3.0 * c3, 2.0 * c2, c1);
    let mut roots = [f64::NAN; 2];
    if qa.abs() <= 1e-14 * (qb.abs() + qc.abs()) {
        if qb != 0.0 {
            roots[0] = -qc / qb;
        }
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            roots = [q / qa, if q != 0.0 { qc / q } else { f64::NAN }];
        }
    }
    let sign = if a.v != 0.0 { a.v } else { b.v };
    roots
        .into_iter()
        .filter(|s| *s > 0.0 && *s < 1.0)
        .find(|&s| value(s) * sign <= 0.0)
        .map(|s| s * h)
}

/// The cubic Hermite of the velocity over a piece from `a` to `b` (`h`
/// long): v(s) = c0 + c1 s + c2 s^2 + c3 s^3 for s = t / h in [0, 1],
/// with the ends' values and derivatives.
fn hermite_cubic(a: Point, b: Point, h: f64) -> [f64; 4] {
    let (m0, m1) = (a.a * h, b.a * h);
    [
        a.v,
        m0,
        3.0 * (b.v - a.v) - 2.0 * m0 - m1,
        2.0 * (a.v - b.v) + m0 + m1,
    ]
}

/// A first guess of the velocity zero between `a` and `b` (`h` apart,
/// velocities of opposite signs) [s after a]: the zero of the cubic
/// Hermite of the velocity, by Newton's steps on the cubic from the
/// secant's zero, kept inside the bracket.
fn hermite_root(a: Point, b: Point, h: f64) -> f64 {
    let [c0, c1, c2, c3] = hermite_cubic(a, b, h);
    let mut s = a.v / (a.v - b.v);
    for _ in 0..4 {
        let v = c0 + s * (c1 + s * (c2 + s * c3));
        let d = c1 + s * (2.0 * c2 + 3.0 * s * c3);
        let next = if d != 0.0 { s - v / d } else { s };
        if !(next > 0.0 && next < 1.0) {
            break;
        }
        s = next;
    }
    s * h
}

/// The velocity zero between `a` (at time ta) and `b` (at tb), whose
/// velocities differ in sign or one of which is zero: Newton's steps
/// from the time `first` (the Hermite's zero, or the law's guess), each
/// kept inside the bracket (bisection where it would leave it); a first
/// step within `share` of the bracket ends the search at once
/// ([`HERMITE_GUESS`], [`GUESSED_SHARE`]).
fn locate_zero(
    a: Point,
    ta: f64,
    b: Point,
    tb: f64,
    (first, share): (f64, f64),
    at: &impl Fn(f64) -> Point,
) -> Point {
    if a.v == 0.0 {
        return a;
    }
    if b.v == 0.0 {
        return b;
    }
    let (mut lo, mut hi) = (ta, tb);
    let lo_sign = a.v.signum();
    let mut t = if first > ta && first < tb {
        first
    } else {
        hermite_root(a, b, tb - ta) + ta
    };
    let mut p = at(t);
    // The guess is within about 1e-3 of the bracket: where the
    // Newton step from it is that short, the position at the zero is the
    // quadratic's extremum, x - v^2 / (2 a), to a jerk's v^3 / a^3 / 6.
    if p.a != 0.0 {
        let dt = -p.v / p.a;
        if dt.abs() <= share * (tb - ta) && t + dt > ta && t + dt < tb {
            return Point {
                x: p.x + 0.5 * p.v * dt,
                v: 0.0,
                a: p.a,
            };
        }
    }
    for _ in 0..ZERO_ITERATIONS {
        if p.v == 0.0 {
            break;
        }
        if p.v.signum() == lo_sign {
            lo = t;
        } else {
            hi = t;
        }
        let newton = if p.a != 0.0 { t - p.v / p.a } else { f64::NAN };
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        // Converged: a change of the time below this moves the position
        // by a v' dt^2 / 2, far below any rounding of it.
        let settled = (next - t).abs() <= ZERO_TIME * (tb - ta);
        t = next;
        p = at(t);
        if settled {
            break;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pieces' variation against closed forms: x = sin(w t) over
    /// pieces of an eighth of its period (no zero, one zero, a dip with
    /// two), a cubic whose velocity dips through zero between ends of one
    /// sign, and a velocity that only touches zero.
    #[test]
    fn piece_variation_locates_the_velocity_zeros() {
        let w = 2.0 * std::f64::consts::PI;
        let sine = |t: f64| Point {
            x: (w * t).sin(),
            v: w * (w * t).cos(),
            a: -w * w * (w * t).sin(),
        };
        let total = |f: &dyn Fn(f64) -> Point, t0: f64, t1: f64, pieces: u32| -> f64 {
            let h = (t1 - t0) / pieces as f64;
            (0..pieces)
                .map(|k| {
                    let s = t0 + k as f64 * h;
                    piece_variation(f(s), f(s + h), h, None, &|t| f(s + t))
                })
                .sum()
        };
        // One period of sin is 4 in total variation, however it is cut
        // into pieces of at most an eighth of it.
        for pieces in [8, 13, 40] {
            let tv = total(&sine, 0.1, 1.1, pieces);
            assert!((tv - 4.0).abs() < 1e-12, "{pieces} pieces: {tv}");
        }
        // x = t^3 - 1.5 t^2 + 0.56 t: v = 3 t^2 - 3 t + 0.56 > 0 at 0 and
        // 1, zeros at (3 -+ sqrt(2.28)) / 6 (v(0.5) = -0.19).
        let cubic = |t: f64| Point {
            x: t * t * t - 1.5 * t * t + 0.56 * t,
            v: 3.0 * t * t - 3.0 * t + 0.56,
            a: 6.0 * t - 3.0,
        };
        let x = |t: f64| cubic(t).x;
        let (z1, z2) = ((3.0 - 2.28f64.sqrt()) / 6.0, (3.0 + 2.28f64.sqrt()) / 6.0);
        let exact = (x(z1) - x(0.0)).abs() + (x(z2) - x(z1)).abs() + (x(1.0) - x(z2)).abs();
        let tv = total(&cubic, 0.0, 1.0, 1);
        assert!((tv - exact).abs() < 1e-14, "{tv} against {exact}");
        assert!(tv > (x(1.0) - x(0.0)).abs() + 0.01);
        // v = 3 (t - 0.5)^2 touches zero: the variation is |x1 - x0|.
        let touch = |t: f64| Point {
            x: (t - 0.5).powi(3),
            v: 3.0 * (t - 0.5).powi(2),
            a: 6.0 * (t - 0.5),
        };
        let tv = total(&touch, 0.0, 1.0, 1);
        assert!((tv - 0.25).abs() < 1e-14, "{tv}");
    }
}
