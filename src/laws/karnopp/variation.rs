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
#[cfg(doc)]
use crate::laws::floor::variation::GUESSED_SHARE;
use crate::laws::floor::variation::{Point, Variation, follow, monotone, piece_variation};
use crate::model::Instance;

/// The most pieces one axis' stick step is cut into: half periods of
/// its ringing, until the drift outruns the ringing or the ringing fades
/// below [`RINGING_FLOOR`] (a stick step spans at most about one drive
/// segment, a few hundred of the stage's oscillations for the scenes'
/// ranges). Past it, the rest of the step counts as one monotone piece.
pub const MAX_PIECES: u32 = 1 << 14;

/// The slider's total variation per axis over one step [m]. In slip and
/// in the band the slider's velocity is a polynomial of degree at most 3
/// (its acceleration is the direction model's quadratic): one piece, the
/// floor's Hermite looking for a dip, or, where both axes' ends show a
/// monotone piece ([`monotone`]), their travel at once (the GPU's lanes
/// then skip the pieces' loops). In stick it is the stage's, a
/// damped oscillation about the drive's drift: see [`stick_variation`].
pub fn step_variation(motion: &StepMotion) -> Vec2 {
    let h = motion.length();
    if h <= 0.0 {
        return Vec2::ZERO;
    }
    let start = motion.start();
    let end = motion.sample(IDENTITY, h);
    if !motion.stuck() && (0..2).all(|i| monotone(point(&start, i), point(&end, i), h)) {
        return (end.x_s - start.x_s).abs();
    }
    let mut total = Vec2::ZERO;
    for i in 0..2 {
        total[i] = if motion.stuck() {
            stick_variation(motion, i, &start, &end)
        } else {
            let at = |t: f64| point(&motion.sample(motion.propagator(t), t), i);
            piece_variation(point(&start, i), point(&end, i), h, None, &at)
        };
    }
    total
}

/// One axis' variation over a stick step, from `start` to `end`. Its
/// velocity is the drift plus a damped oscillation whose acceleration is
/// a damped sinusoid: its extrema lie half a damped period apart, so
/// pieces cut there ([`Ring::cuts`]) each hold a monotone velocity and
/// at most one zero, found from the closed form's guess
/// ([`Ring::zero_guess`]) in one evaluation of the motion. Each piece's
/// start is the one before composed with the half period's propagator.
/// The pieces end where the drift outruns the ringing or the ringing has
/// faded ([`Ring::settled`]); the rest is one monotone piece.
fn stick_variation(motion: &StepMotion, i: usize, start: &Sample, end: &Sample) -> f64 {
    let h = motion.length();
    let osc = motion.oscillator();
    let ring = Ring::new(motion.drift(0.0)[i], osc.sigma[i], osc.w2[i]);
    let first = point(start, i);
    let cuts = ring.cuts(first);
    let half = if cuts.half < h {
        motion.propagator(cuts.half)
    } else {
        IDENTITY
    };
    // What the half period's propagator scales the ringing by: -q I.
    let q = if cuts.half.is_finite() {
        -(1.0 + half.a0m1[i])
    } else {
        1.0
    };
    let (mut base, mut t0, mut a) = (IDENTITY, 0.0, first);
    let mut t1 = cuts.first.min(h);
    let mut next = if t1 < h {
        motion.propagator(t1)
    } else {
        IDENTITY
    };
    let mut total = 0.0;
    for _ in 0..MAX_PIECES {
        let s1 = if t1 < h {
            motion.sample(next, t1)
        } else {
            *end
        };
        let b = point(&s1, i);
        let guess = ring.zero_guess(a, b, t1 - t0);
        let at = |t: f64| {
            point(
                &motion.sample(motion.compose(base, motion.propagator(t)), t0 + t),
                i,
            )
        };
        total += piece_variation(a, b, t1 - t0, guess, &at);
        if t1 >= h {
            return total;
        }
        if ring.settled(motion.ringing_energy(&s1, t1)[i], b.v, q) {
            return total + (end.x_s[i] - b.x).abs();
        }
        (base, t0, a) = (next, t1, b);
        next = motion.compose(base, half);
        t1 = (t0 + cuts.half).min(h);
    }
    total + (end.x_s[i] - a.x).abs()
}

fn point(s: &Sample, i: usize) -> Point {
    Point {
        x: s.x_s[i],
        v: s.v_s[i],
        a: s.a_s[i],
    }
}

/// One axis' stick motion: velocity = `drift` + w, the ringing w of an
/// oscillator w'' + 2 `sigma` w' + `w2` w = 0 [m/s, 1/s, 1/s^2], whose
/// damped frequency is `omega` [1/s] (0 where it does not ring).
struct Ring {
    drift: f64,
    sigma: f64,
    w2: f64,
    omega: f64,
}

/// Where one axis' stick pieces are cut [s]: at `first`, the velocity's
/// first extremum at or after the start, and every `half` after it (half
/// the damped period). An oscillator that does not ring has at most one
/// extremum and an infinite `half`; where there is none ahead, `first`
/// is infinite too.
struct Cuts {
    first: f64,
    half: f64,
}

impl Ring {
    fn new(drift: f64, sigma: f64, w2: f64) -> Ring {
        let squared = w2 - sigma * sigma;
        let omega = if squared > 0.0 { squared.sqrt() } else { 0.0 };
        Ring {
            drift,
            sigma,
            w2,
            omega,
        }
    }

    /// The cuts for a step starting at `p`: where the ringing's
    /// acceleration, a damped sinusoid e^(-sigma t) (a cos(w t) + beta
    /// sin(w t)), is zero. Its phase comes from f32's atan2: a cut off the
    /// extremum by f32's rounding leaves a sliver in which the velocity
    /// turns back by a jerk's dt^2 / 2, and a zero pair inside it (a
    /// graze to that depth) carries a travel of about jerk dt^3.
    fn cuts(&self, p: Point) -> Cuts {
        let (w, a) = (p.v - self.drift, p.a);
        let jerk = -self.w2 * w - 2.0 * self.sigma * a;
        let none = Cuts {
            first: f64::INFINITY,
            half: f64::INFINITY,
        };
        if self.omega > 0.0 {
            let omega = self.omega;
            let beta = (jerk + self.sigma * a) / omega;
            let scale = a.abs().max(beta.abs());
            if scale == 0.0 {
                return none;
            }
            let mut theta = ((-a / scale) as f32).atan2((beta / scale) as f32);
            if theta < 0.0 {
                theta += std::f32::consts::PI;
            }
            if theta >= std::f32::consts::PI {
                theta -= std::f32::consts::PI;
            }
            return Cuts {
                first: theta as f64 / omega,
                half: std::f64::consts::PI / omega,
            };
        }
        // Not ringing: a = C1 e^(r1 t) + C2 e^(r2 t), r = -sigma +- mu, is
        // zero once at most, at ln(1 + x) / (2 mu) = u ln(1 + x) / x with
        // u = -a / (jerk - r2 a) (critical damping's zero) and x = 2 mu u.
        let mu = (self.sigma * self.sigma - self.w2).sqrt();
        let denominator = jerk + (self.sigma + mu) * a;
        if denominator == 0.0 {
            return none;
        }
        let u = -a / denominator;
        let x = (2.0 * mu * u) as f32;
        let ratio = if x.abs() < 1e-4 {
            1.0 - x * (0.5 - x / 3.0)
        } else {
            (1.0 + x).ln() / x
        };
        let first = u * ratio as f64;
        let ahead = 1.0 + x > 0.0 && first > 0.0;
        if !ahead {
            return none;
        }
        Cuts { first, ..none }
    }

    /// A first guess of the velocity zero between the ends `a` and `b` of
    /// a monotone piece `length` long [s after a], in f32: the zero of the
    /// half cosine through the ends' velocities (exact for an undamped
    /// ringing between two extrema), then one Newton step on the closed
    /// form, kept inside the piece. Measured on the dense-search test's
    /// instances: 1.19 evaluations of the motion per zero with the
    /// floor's [`GUESSED_SHARE`] (1.06 with two steps, 3.3 from the half
    /// cosine alone), each step costing on lavapipe about 0.4 of an
    /// evaluation. Only where the ends' velocities differ in sign and the
    /// oscillator rings (else the floor's Hermite guesses).
    fn zero_guess(&self, a: Point, b: Point, length: f64) -> Option<f64> {
        let brackets = a.v * b.v < 0.0 && self.omega > 0.0;
        if !brackets {
            return None;
        }
        let f = |x: f64| x as f32;
        let (omega, sigma, drift) = (f(self.omega), f(self.sigma), f(self.drift));
        let (w, acc) = (f(a.v - self.drift), f(a.a));
        let jerk = -f(self.w2) * w - 2.0 * sigma * acc;
        let (sw, sa) = ((acc + sigma * w) / omega, (jerk + sigma * acc) / omega);
        let l = f(length);
        let s = l * (f(-(a.v + b.v) / (a.v - b.v)).acos() * std::f32::consts::FRAC_1_PI);
        let (sin, cos) = (omega * s).sin_cos();
        let decay = (-sigma * s).exp();
        let v = drift + decay * (w * cos + sw * sin);
        let dv = decay * (acc * cos + sa * sin);
        let newton = s - v / dv;
        Some(if newton > 0.0 && newton < l {
            newton
        } else {
            s
        } as f64)
    }

    /// Whether the rest of the step, from a cut where the ringing's
    /// energy bound (`motion.ringing_energy`, never growing) is `energy`
    /// and the velocity `v`, is one monotone piece to within
    /// [`RINGING_FLOOR`]: the drift keeps its sign there with a speed
    /// above the ringing's bound, or the ringing's reversals can add no
    /// more than the floor. The ringing's displacement is at most
    /// sqrt(energy / w2) and shrinks by `q` each half period, so the
    /// reversals add at most 4 sqrt(energy / w2) / (1 - q).
    fn settled(&self, energy: f64, v: f64, q: f64) -> bool {
        let outrun = self.drift * v > 0.0 && energy < self.drift * self.drift * RINGING_MARGIN;
        let floor = RINGING_FLOOR * (1.0 - q);
        outrun || 16.0 * energy <= self.w2 * floor * floor
    }
}

/// The ringing's squared bound must stay below this share of the drift's
/// squared speed: a margin for the bound's rounding.
const RINGING_MARGIN: f64 = 0.98;

/// The most travel [m] a stick step's remaining ringing may add and be
/// left out (a thousandth of the GPU's bar of 1e-12 m per cycle for a
/// thousand such steps a cycle): a ringing about no drift (a hold) reverses
/// the slider every half period until its energy is gone, and its
/// reversals count until their sum is below this.
pub const RINGING_FLOOR: f64 = 1e-18;

/// The constants `shaders/karnopp/variation.wgsl` mirrors this module and
/// the floor's `piece_variation` with, as WGSL declarations (their one
/// home is here and in `crate::laws::floor::variation`).
pub fn wgsl_constants() -> String {
    format!(
        "const MAX_PIECES: u32 = {MAX_PIECES}u;\n\
         const RINGING_MARGIN: Real = {RINGING_MARGIN:e};\n\
         const RINGING_FLOOR: Real = {RINGING_FLOOR:e};\n\
         const PI_REAL: Real = {:e};\n\
         const PI_F32: f32 = {:e};\n\
         const ONE_OVER_PI_F32: f32 = {:e};\n{}",
        std::f64::consts::PI,
        std::f32::consts::PI,
        std::f32::consts::FRAC_1_PI,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::random::random_instances;

    /// An independent variation of one axis over a stick step: the step
    /// cut into pieces of 1/16 radian of its fastest oscillator, each
    /// sign change of the velocity between them located by bisection
    /// (each sample its own propagator, none composed).
    fn dense(motion: &StepMotion, i: usize) -> f64 {
        let h = motion.length();
        let n = ((h * motion.rate() * 128.0).ceil() as u32).max(64);
        let at = |t: f64| point(&motion.sample(motion.propagator(t), t), i);
        let mut a = at(0.0);
        let (mut ta, mut total) = (0.0, 0.0);
        for k in 1..=n {
            let tb = if k == n { h } else { h * k as f64 / n as f64 };
            let b = at(tb);
            if a.v * b.v < 0.0 {
                let (mut lo, mut hi) = (ta, tb);
                for _ in 0..80 {
                    let mid = 0.5 * (lo + hi);
                    if at(mid).v * a.v > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let z = at(0.5 * (lo + hi));
                total += (z.x - a.x).abs() + (b.x - z.x).abs();
            } else {
                total += (b.x - a.x).abs();
            }
            (a, ta) = (b, tb);
        }
        total
    }

    /// The largest difference between `step_variation` and `dense` over
    /// every stick step of a run.
    struct AgainstDense {
        worst: f64,
        worst_share: f64,
        stick: usize,
    }

    impl StepObserver for AgainstDense {
        fn step(&mut self, _st: &State, motion: &StepMotion) {
            if !motion.stuck() || motion.length() <= 0.0 {
                return;
            }
            self.stick += 1;
            let got = step_variation(motion);
            for i in 0..2 {
                let want = dense(motion, i);
                let d = (got[i] - want).abs();
                self.worst = self.worst.max(d);
                if want > 0.0 {
                    self.worst_share = self.worst_share.max(d / want);
                }
            }
        }
    }

    fn check(inst: &Instance) -> AgainstDense {
        let c = Coefficients::of(inst, &Settings::default());
        let mut st = integrate::initial_state(&c);
        let mut m = integrate::initial_measure(&c);
        let mut obs = AgainstDense {
            worst: 0.0,
            worst_share: 0.0,
            stick: 0,
        };
        while !integrate::is_finished(&c, &st) {
            integrate::advance_observed(&c, &mut st, &mut m, 1 << 16, &mut obs);
        }
        obs
    }

    /// Every stick step's variation, cut at the ringing's extrema, against
    /// the dense search: random instances (unequal stages among them,
    /// instance 1,844 of `pidm random-scene --seed 11 --count 2000` the one
    /// whose map moved most from the eighth-period pieces, 3.6e-11 m per
    /// cycle), a trapezoid whose hold and dwell ring about no drift, and
    /// stages that do not ring (critically damped and overdamped in stick).
    #[test]
    fn stick_steps_cut_at_the_extrema_agree_with_a_dense_search() {
        let mut cases: Vec<(String, Instance)> = random_instances(11, 12, 3, 1)
            .into_iter()
            .enumerate()
            .map(|(k, inst)| (format!("random {k}"), inst))
            .collect();
        cases.push(("random 1844".into(), random_instances(11, 1845, 3, 1)[1844]));
        let mut hold = Instance::TABLE1;
        hold.axes[0].shape = crate::model::Shape::Trapezoid;
        [hold.axes[0].rise, hold.axes[0].hold, hold.axes[0].fall] = [0.5, 0.3, 0.02];
        cases.push(("trapezoid with a hold".into(), hold));
        for zeta in [1.0, 3.0] {
            let mut dead = Instance::TABLE1;
            for axis in dead.axes.iter_mut() {
                let mass = axis.stage_mass + dead.mechanism.slider_mass;
                axis.damping = 2.0 * zeta * (axis.stiffness * mass).sqrt();
            }
            cases.push((format!("damping ratio {zeta} in stick"), dead));
        }
        for (label, inst) in &cases {
            let o = check(inst);
            assert!(o.stick > 0, "{label}: no stick step");
            assert!(
                o.worst <= 1e-16 || o.worst_share <= 1e-12,
                "{label}: {:e} m, {:e} of the step's variation",
                o.worst,
                o.worst_share
            );
        }
    }
}
