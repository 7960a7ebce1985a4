//! Karnopp's part of the backward travel (`crate::laws::floor::variation`):
//! the slider's total variation over every step, from the integrator's
//! own closed-form motion, and a run that keeps it beside the step's
//! measurement. f64 on the CPU only. An observer never changes the run,
//! so the step's values are those of a run without it, bit for bit.

use super::integrate::{
    self, Coefficients, ITERATIONS_BETWEEN_STOP_CHECKS, Measure, Run, State, StepMotion,
    StepObserver, Vec2,
};
use crate::laws::Settings;
use crate::laws::floor::variation::{Point, Variation, follow, piece_variation};
use crate::model::Instance;

/// The longest piece a step is cut into, in radians of its fastest
/// oscillator (an eighth of its period): over such a piece the stage's
/// velocity (which a stuck slider shares) turns at most once, so no
/// velocity has more than the two zeros `piece_variation` finds.
pub const PIECE_RADIANS: f64 = std::f64::consts::FRAC_PI_4;

/// The most pieces one step is cut into: a stick step that rides out
/// its ringing spans at most about one drive segment, a few hundred of
/// the stage's oscillations at most for the scenes' ranges.
pub const MAX_PIECES: u32 = 1 << 14;

/// The slider's total variation per axis over one step [m].
pub fn step_variation(motion: &StepMotion) -> Vec2 {
    let h = motion.length();
    if h <= 0.0 {
        return Vec2::ZERO;
    }
    let pieces = ((h * motion.rate() / PIECE_RADIANS).ceil()).clamp(1.0, MAX_PIECES as f64) as u32;
    let piece = h / pieces as f64;
    let point = |t: f64, i: usize| {
        let (x, v, a) = motion.slider_at(t);
        Point {
            x: x[i],
            v: v[i],
            a: a[i],
        }
    };
    let mut total = Vec2::ZERO;
    let mut start = motion.slider_at(0.0);
    for k in 0..pieces {
        let t0 = k as f64 * piece;
        let t1 = if k + 1 == pieces { h } else { t0 + piece };
        let end = motion.slider_at(t1);
        for i in 0..2 {
            let a = Point {
                x: start.0[i],
                v: start.1[i],
                a: start.2[i],
            };
            let b = Point {
                x: end.0[i],
                v: end.1[i],
                a: end.2[i],
            };
            total[i] += piece_variation(a, b, t1 - t0, &|t| point(t0 + t, i));
        }
        start = end;
    }
    total
}

/// Adds every step's variation to a run's [`Variation`] and follows the
/// step's measurement at every period end.
struct Follower<'a> {
    v: &'a mut Variation,
    settle: u32,
}

impl StepObserver for Follower<'_> {
    fn step(&mut self, st: &State, motion: &StepMotion) {
        if st.period == self.settle && st.time == 0.0 {
            // A window's start (the steady measurement keeps its own).
            self.v.settle_total = self.v.total;
        }
        self.v.total = self.v.total + step_variation(motion);
    }

    fn period_end(&mut self, c: &Coefficients, _st: &State, m: &Measure) {
        follow(c, c.common_period, m.next_end, m, self.v);
    }
}

/// Integrates one instance to the end in f64, keeping the slider's total
/// variation beside the step's measurement, or until `stop` returns true
/// (asked as `integrate::run_instance_until` asks it; then `None`). The
/// run is that of `integrate::run_instance_until`, bit for bit.
pub fn run_until(
    inst: &Instance,
    settings: &Settings,
    stop: impl Fn() -> bool,
) -> Option<(Run, Variation)> {
    let c = Coefficients::of(inst, settings);
    let mut run = Run {
        state: integrate::initial_state(&c),
        measure: integrate::initial_measure(&c),
    };
    let mut v = Variation::new(&c);
    let mut follower = Follower {
        v: &mut v,
        settle: c.settle,
    };
    while !integrate::is_finished(&c, &run.state) {
        if stop() {
            return None;
        }
        integrate::advance_observed(
            &c,
            &mut run.state,
            &mut run.measure,
            ITERATIONS_BETWEEN_STOP_CHECKS,
            &mut follower,
        );
    }
    if c.settle == 0 {
        v.settle_total = Vec2::ZERO;
    }
    Some((run, v))
}
