//! Karnopp's part of the backward travel (`crate::laws::floor::variation`):
//! the slider's total variation over every step, from the integrator's
//! own closed-form motion, and a run that keeps it beside the step's
//! measurement. f64 on the CPU only. An observer never changes the run,
//! so the step's values are those of a run without it, bit for bit.

use super::integrate::flow::{IDENTITY, Sample};
use super::integrate::{
    self, Coefficients, ITERATIONS_BETWEEN_STOP_CHECKS, Measure, Run, State, StepMotion,
    StepObserver, Vec2,
};
use crate::laws::Settings;
use crate::laws::floor::variation::{Point, Variation, follow, piece_variation};
use crate::model::Instance;

/// The longest piece a step is cut into, in radians of its fastest
/// oscillator (an eighth of its period): over such a piece the stage's
/// velocity (which a stuck slider shares) turns at most once, and the
/// cubic Hermite of the velocity that `piece_variation` reads shows a dip
/// through zero to 1e-3 of the ringing's amplitude. Measured: quarter
/// periods moved random instances' backward travel by up to 0.005 um
/// and failed the SciPy cross-check (1.2e-3 um).
pub const PIECE_RADIANS: f64 = std::f64::consts::FRAC_PI_4;

/// The most pieces one step is cut into: a stick step that rides out
/// its ringing spans at most about one drive segment, a few hundred of
/// the stage's oscillations at most for the scenes' ranges.
pub const MAX_PIECES: u32 = 1 << 14;

/// The slider's total variation per axis over one step [m]. In slip and
/// in the band the slider's velocity is a polynomial of degree at most 3
/// (its acceleration is the direction model's quadratic): one piece. In
/// stick it is the stage's, a damped oscillation about the drive's drift:
/// pieces of [`PIECE_RADIANS`], each reached by composing one piece's
/// propagator, until the ringing can no longer reverse the slider (its
/// energy bound below the drift's speed over the rest of the step, where
/// the drift keeps its sign), and then one piece to the end.
pub fn step_variation(motion: &StepMotion) -> Vec2 {
    let h = motion.length();
    if h <= 0.0 {
        return Vec2::ZERO;
    }
    let start = motion.start();
    let end = motion.sample(IDENTITY, h);
    if !motion.stuck() {
        let at = |t: f64| motion.sample(motion.propagator(t), t);
        return piece(&start, &end, h, &at);
    }
    let pieces = ((h * motion.rate() / PIECE_RADIANS).ceil()).clamp(1.0, MAX_PIECES as f64) as u32;
    let length = h / pieces as f64;
    let one = if pieces > 1 {
        motion.propagator(length)
    } else {
        IDENTITY
    };
    let (mut prop, mut t0, mut s0) = (IDENTITY, 0.0, start);
    let mut total = Vec2::ZERO;
    for k in 0..pieces {
        if cannot_reverse(motion, &s0, t0) {
            return total + (end.x_s - s0.x_s).abs();
        }
        let last = k + 1 == pieces;
        let next = if last {
            prop
        } else {
            motion.compose(prop, one)
        };
        let t1 = if last { h } else { t0 + length };
        let s1 = if last { end } else { motion.sample(next, t1) };
        let at = |t: f64| motion.sample(motion.compose(prop, motion.propagator(t)), t0 + t);
        total = total + piece(&s0, &s1, t1 - t0, &at);
        (prop, t0, s0) = (next, t1, s1);
    }
    total
}

/// Each axis' variation over one piece from `a` to `b` (`h` long), `at(t)`
/// the motion `t` into it.
fn piece(a: &Sample, b: &Sample, h: f64, at: &impl Fn(f64) -> Sample) -> Vec2 {
    let point = |s: &Sample, i: usize| Point {
        x: s.x_s[i],
        v: s.v_s[i],
        a: s.a_s[i],
    };
    let mut total = Vec2::ZERO;
    for i in 0..2 {
        total[i] = piece_variation(point(a, i), point(b, i), h, &|t| point(&at(t), i));
    }
    total
}

/// Whether no axis' slider velocity can change sign between `tau` (the
/// sample `s`) and the step's end: on each axis the drift keeps its sign
/// with a speed above the ringing's bound, or there is neither drift nor
/// ringing.
fn cannot_reverse(motion: &StepMotion, s: &Sample, tau: f64) -> bool {
    let energy = motion.ringing_energy(s, tau);
    let (d0, d1) = (motion.drift(tau), motion.drift(motion.length()));
    (0..2).all(|i| {
        let slowest = d0[i].abs().min(d1[i].abs());
        let still = energy[i] == 0.0 && d0[i] == 0.0 && d1[i] == 0.0;
        still || (d0[i] * d1[i] > 0.0 && energy[i] < slowest * slowest * RINGING_MARGIN)
    })
}

/// The ringing's squared bound must stay below this share of the drift's
/// squared speed: a margin for the bound's rounding.
const RINGING_MARGIN: f64 = 0.98;

/// The constants `shaders/karnopp/variation.wgsl` mirrors this module and
/// the floor's `piece_variation` with, as WGSL declarations (their one
/// home is here and in `crate::laws::floor::variation`).
pub fn wgsl_constants() -> String {
    format!(
        "const PIECE_RADIANS: Real = {PIECE_RADIANS:e};\n\
         const MAX_PIECES: u32 = {MAX_PIECES}u;\n\
         const RINGING_MARGIN: Real = {RINGING_MARGIN:e};\n{}",
        crate::laws::floor::variation::wgsl_constants()
    )
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
            // The measured periods begin (`integrate::iterate` sets the
            // state's `settle_x_s` here).
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
    let run = Run {
        state: integrate::initial_state(&c),
        measure: integrate::initial_measure(&c),
    };
    let mut v = Variation::new(&c);
    continue_until(&c, run, &mut v, stop).map(|run| (run, v))
}

/// `integrate::continue_until` keeping the variation `v` beside the
/// step's measurement: from where `run` stands to its end or a replica's
/// wait for its group's merge (`crate::replicas`), or until `stop` returns
/// true (then `None`).
pub fn continue_until(
    c: &Coefficients,
    mut run: Run,
    v: &mut Variation,
    stop: impl Fn() -> bool,
) -> Option<Run> {
    let mut follower = Follower {
        v,
        settle: c.settle,
    };
    while !integrate::is_finished(c, &run.state) {
        if stop() {
            return None;
        }
        integrate::advance_observed(
            c,
            &mut run.state,
            &mut run.measure,
            ITERATIONS_BETWEEN_STOP_CHECKS,
            &mut follower,
        );
    }
    Some(run)
}
