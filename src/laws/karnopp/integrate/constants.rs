//! The integrator's named numbers: friction modes, status codes, event
//! kinds and tuning constants. This file is their one home: the shader gets
//! them through the prelude that `pidm::gpu::shader` generates from
//! [`wgsl_constants`], never by hand.

/// Stick: slider and stage move together.
pub const MODE_STICK: u32 = 0;
/// Slip outside the detection band: friction along the relative velocity.
pub const MODE_SLIP: u32 = 1;
/// Slip inside the detection band: friction along a held direction.
pub const MODE_BAND: u32 = 2;

// The status codes live on the laws' floor (`crate::laws::status`), the
// same for every law; the prelude's WGSL names them from there.
pub use crate::laws::status::{
    STATUS_EVENT_STORM, STATUS_GRAZE, STATUS_NON_FINITE, STATUS_NOT_STEADY, STATUS_OK,
    STATUS_STEP_BUDGET, STATUS_STEP_UNDERFLOW, STATUS_UNCONVERGED,
};

/// No event is watched.
pub const EVENT_NONE: u32 = 0;
/// Stick breaks: hold^2 - |m_s a_p|^2 (f_need of the coupled system).
pub const EVENT_BREAKAWAY: u32 = 1;
/// Slip enters the band: |v_rel|^2 - a^2.
pub const EVENT_ENTER_BAND: u32 = 2;
/// Band slip leaves the band: a^2 - |v_rel|^2.
pub const EVENT_LEAVE_BAND: u32 = 3;
/// The relative velocity reverses against the held direction:
/// sign * v_rel . held.
pub const EVENT_REVERSAL: u32 = 4;
/// Slip along a fixed direction u slows into the band: v_rel . u - a. The
/// band entry of a slip trial whose relative velocity reverses (see
/// `step::approach_trial`), linear in the velocity where |v_rel|^2 - a^2 is
/// quadratic, so f32 resolves it too.
pub const EVENT_APPROACH: u32 = 5;

// The kinds of iteration a lane counts: the floor's (`iterate` returns
// one of them).
pub use crate::laws::floor::kinds::{
    ITERATION_BOUNDARY, ITERATION_EVENT, ITERATION_KINDS, ITERATION_PERIOD_END, ITERATION_REJECTED,
    ITERATION_SLIP, ITERATION_STICK, KIND_NAMES, rejected_share,
};

/// The band grazes that an f32 run hands to the f64 reference, as a
/// fraction of the band: slip whose relative velocity passes the velocity
/// band a with a closest approach |v_rel|^2 within `GRAZE_MARGIN` a^2 of
/// a^2, on either side (a near miss, or an entry that only skims the band).
/// Whether such a slip ends in the band is decided by the relative
/// velocity at the level of the direction tolerance, not of f32's rounding
/// (a tolerance of 1e-4 rad keeps v_rel to a few per cent of a 1e-6 m/s
/// band over a millisecond of slip), so two correct integrations that take
/// slightly different steps decide it differently, and the step that
/// follows can move by micrometres. Over 54,000 random instances
/// (`results/gpu.md`, "Band grazes") every f32 step that missed the f64
/// reference's by more than 0.005 um + 1 % had a graze within 0.065 a^2;
/// 0.1 hands about 4 % of random instances to the CPU (0.3 would hand 9 %
/// for 3 fewer of the mirror's misses in 114,000). Applies to window
/// measurements only: a steady measurement is the long run's mean, which a
/// graze does not move.
pub const GRAZE_MARGIN: f64 = 0.1;

/// Number of Taylor terms of the propagator after scaling to norm <= 1/2:
/// the truncation error is below 0.5^15 / 15! = 2.3e-17.
pub const TAYLOR_TERMS: u32 = 14;
/// Fraction of the fastest oscillation period spanned by one step while an
/// event is possible: each of the four sample intervals then covers at most
/// 1/16 of a period, so an event function has at most one extremum there.
pub const EVENT_STEP_PERIODS: f64 = 0.25;
/// Fixed-point iterations of the friction-direction quadratic per slip
/// step.
pub const COLLOCATION_ITERATIONS: u32 = 4;
/// The iteration stops once the model changes by less than this fraction of
/// the tolerance.
pub const COLLOCATION_CONVERGED: f64 = 1e-2;
/// Terms of the stage Taylor series on short slip steps (rate * h <= 1):
/// the truncation error is below 1 / 21! = 2e-20.
pub const TAYLOR_STAGE_TERMS: u32 = 21;
/// The stage Taylor series stops once the bound on its next term falls
/// below this (relative to the state's scale).
pub const TAYLOR_STAGE_CONVERGED: f64 = 1e-18;
/// Newton iterations for the direction slip starts in (monotone, converges
/// in a handful).
pub const SLIP_DIRECTION_ITERATIONS: u32 = 40;
/// Rounding noise of an event function, in units of epsilon times the
/// magnitude of its terms.
pub const EVENT_NOISE: f64 = 16.0;
/// Bisection-guarded Newton iterations when locating an event.
pub const ROOT_ITERATIONS: u32 = 80;
/// How many times `events::locate` looks for an earlier crossing before
/// the one it found, each time halfway to it (one event evaluation each
/// where the one found is the first; results/events.md).
pub const FIRST_ROOT_CHECKS: u32 = 4;
/// Consecutive events allowed without the time advancing.
pub const MAX_STALLED_EVENTS: u32 = 64;
/// Step rejections allowed in a row before a slip step gives up.
pub const MAX_REJECTIONS: u32 = 60;
/// Largest number of halvings of a propagator's time before its Taylor
/// series (2^-200 of any step is far below every time resolution).
pub const MAX_SQUARINGS: u32 = 200;
/// The smallest slip step, in units of epsilon times the scene period.
pub const MIN_STEP_EPSILONS: f64 = 64.0;
/// The share of the way to the coming band entry a slip trial may span
/// where the relative velocity slows while it turns (`step::approach_limit`):
/// the quadratic direction model fails as the speed nears zero, where the
/// direction turns ever faster, so a trial that reached further would be
/// rejected. Measured on `pidm random-scene --seed 11 --count 2000` (issue
/// 47): 0.3, 0.5, 0.7 and 1 took 2.87, 2.74, 2.75 and 2.87 million slip
/// trials.
pub const APPROACH_SHARE: f64 = 0.5;
/// The step-size controller's safety factor on its cube-root law.
pub const STEP_SAFETY: f64 = 0.9;
/// Step-size factors are rounded down to multiples of 1 / this. The
/// controller's input, the direction error, carries rounding noise that
/// differs between backends (fused multiply-adds); a factor that followed
/// it continuously would turn last-bit differences into different step
/// sequences, and so different results at the level of the tolerance.
/// Rounded factors differ only where the error sits on a rounding boundary.
pub const STEP_FACTOR_QUANTUM: f64 = 64.0;
/// (safety x quantum)^3: the controller's bound in grid units
/// (`arith::step_factor`).
pub const STEP_FACTOR_CUBE: f64 = (STEP_SAFETY * STEP_FACTOR_QUANTUM)
    * (STEP_SAFETY * STEP_FACTOR_QUANTUM)
    * (STEP_SAFETY * STEP_FACTOR_QUANTUM);
/// Bisections of `arith::step_factor`: its grid spans at most 2^9 points
/// (factors up to 8 at 64 a unit).
pub const STEP_FACTOR_BISECTIONS: u32 = 9;
/// Rational constants of the slider polynomial.
pub const ONE_THIRD: f64 = 1.0 / 3.0;
pub const ONE_SIXTH: f64 = 1.0 / 6.0;
pub const ONE_TWELFTH: f64 = 1.0 / 12.0;

/// The constants above that the shader reads, as WGSL `const`
/// declarations for its prelude (the host folds the others into
/// `Coefficients`). Real-valued ones are typed `Real`, so one text serves
/// f32 and f64.
pub fn wgsl_constants() -> String {
    let u = |name: &str, v: u32| format!("const {name}: u32 = {v}u;\n");
    let r = |name: &str, v: f64| format!("const {name}: Real = Real({v:e});\n");
    [
        u("MODE_STICK", MODE_STICK),
        u("MODE_SLIP", MODE_SLIP),
        u("MODE_BAND", MODE_BAND),
        r("GRAZE_MARGIN", GRAZE_MARGIN),
        u("EVENT_NONE", EVENT_NONE),
        u("EVENT_BREAKAWAY", EVENT_BREAKAWAY),
        u("EVENT_ENTER_BAND", EVENT_ENTER_BAND),
        u("EVENT_LEAVE_BAND", EVENT_LEAVE_BAND),
        u("EVENT_REVERSAL", EVENT_REVERSAL),
        u("EVENT_APPROACH", EVENT_APPROACH),
        u("TAYLOR_TERMS", TAYLOR_TERMS),
        u("COLLOCATION_ITERATIONS", COLLOCATION_ITERATIONS),
        u("TAYLOR_STAGE_TERMS", TAYLOR_STAGE_TERMS),
        r("TAYLOR_STAGE_CONVERGED", TAYLOR_STAGE_CONVERGED),
        u("SLIP_DIRECTION_ITERATIONS", SLIP_DIRECTION_ITERATIONS),
        r("EVENT_NOISE", EVENT_NOISE),
        u("ROOT_ITERATIONS", ROOT_ITERATIONS),
        u("FIRST_ROOT_CHECKS", FIRST_ROOT_CHECKS),
        u("MAX_STALLED_EVENTS", MAX_STALLED_EVENTS),
        u("MAX_REJECTIONS", MAX_REJECTIONS),
        u("MAX_SQUARINGS", MAX_SQUARINGS),
        r("APPROACH_SHARE", APPROACH_SHARE),
        r("STEP_FACTOR_QUANTUM", STEP_FACTOR_QUANTUM),
        u("STEP_FACTOR_QUANTUM_U32", STEP_FACTOR_QUANTUM as u32),
        r("STEP_FACTOR_GRID", 1.0 / STEP_FACTOR_QUANTUM),
        r("STEP_FACTOR_CUBE", STEP_FACTOR_CUBE),
        u("STEP_FACTOR_BISECTIONS", STEP_FACTOR_BISECTIONS),
        r("ONE_THIRD", ONE_THIRD),
        r("ONE_SIXTH", ONE_SIXTH),
        r("ONE_TWELFTH", ONE_TWELFTH),
    ]
    .concat()
}
