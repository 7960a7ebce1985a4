//! A LuGre run: period by period, each one Rodas4 segments between the
//! drive's corners, with the measurement of every backend on top (the
//! window's travel, or `measure::period_end`'s batches, phase ladder and
//! stop rule). Its result is the floor's `Run`, which
//! `measurement::reduce` turns into a map's values as it does Karnopp's.

// The model and Rodas4's coefficients, also for the GPU's mirror of both
// (`crate::gpu::lugre` and `shaders/lugre/`).
pub(crate) use super::model::{Clock, Linear, Model, N, State, T, VP, VS, XP, XS, Z};
pub(crate) use super::rodas::{A, C, GAMMA, R, REDUCED, SMALLEST_STEP, rodas4, segment};
use crate::laws::floor::drive::{Corners, axis_corners};
use crate::laws::floor::measure::{
    Measure, SNAPSHOTS, VERDICT_PERIODIC, VERDICT_RUNNING, initial_measure, period_end,
};
use crate::laws::floor::variation::{Variation, follow};
use crate::laws::floor::{Record, Run, Setup, Vec2};
use crate::laws::observe::{Observer, Positions};
use crate::laws::status::STATUS_OK;
use crate::laws::{Replica, Settings};
use crate::model::{AXES, Instance, Lugre};

/// What `simulation.tolerance` (a number, 1e-4 by default) means under
/// LuGre: each Rodas4 step's local error is at most `tolerance` times
/// this length [m] in the positions (1e-11 m at the default), `tolerance`
/// times this length times the stage's angular resonance in the
/// velocities, and the same force (times the stage's stiffness over
/// sigma0) in the bristles' deflection. 0.1 um is about the presliding
/// deflection f_s / sigma0 at the defaults. Measured on docs/model.md section 8's
/// cases (`pidm accuracy sweeps/lugre_paper.toml sweeps/lugre_stiff.toml`):
/// the largest error is about tolerance / 2 um per cycle at the defaults
/// and up to 1.7 tolerance at sigma0 = 1e9 (4.9e-5 and 1.7e-4 um at the
/// default tolerance).
pub const LENGTH_PER_TOLERANCE: f64 = 1e-7;

/// The weights of the error control: each state's largest local error.
pub(crate) fn error_scale(model: &Model, lugre: &Lugre, tolerance: f64) -> State {
    let inst = &model.inst;
    let length = tolerance * LENGTH_PER_TOLERANCE;
    let omega = inst
        .axes
        .iter()
        .map(|a| (a.stiffness / a.stage_mass).sqrt())
        .fold(0.0, f64::max);
    let stiffness = inst
        .axes
        .iter()
        .map(|a| a.stiffness)
        .fold(f64::INFINITY, f64::min);
    let mut scale = [length; N];
    for i in 0..AXES {
        scale[VP + i] = length * omega;
        scale[VS + i] = length * omega;
        scale[Z + i] = length * (stiffness / lugre.bristle_stiffness).min(1.0);
    }
    scale[T] = f64::INFINITY;
    scale
}

/// The first trial step [s]: a thousandth of the fastest stage's period;
/// the control adapts it within a few steps.
pub(crate) fn first_step(inst: &Instance) -> f64 {
    let omega = inst
        .axes
        .iter()
        .map(|a| (a.stiffness / a.stage_mass).sqrt())
        .fold(0.0, f64::max);
    1e-3 * std::f64::consts::TAU / omega
}

/// Integrates the LuGre instance `inst` to the end of its measurement, or
/// until `stop` returns true (asked once per scene period), in which case
/// there is no result. The run starts at rest, z = 0 (docs/model.md section 8).
///
/// # Panics
/// If `inst`'s friction is not LuGre's.
pub fn run_instance_until(
    inst: &Instance,
    settings: &Settings,
    stop: impl Fn() -> bool,
) -> Option<Run> {
    let mut book = Periods::new(inst, settings);
    let start = PeriodStart::first(&book);
    continue_until(&mut book, start, stop).then_some(book.run)
}

/// [`run_instance_until`], keeping the slider's total variation beside
/// the measurement (`crate::laws::floor::variation`): the same run, bit
/// for bit, and its variation.
pub fn run_with_variation_until(
    inst: &Instance,
    settings: &Settings,
    stop: impl Fn() -> bool,
) -> Option<(Run, Variation)> {
    let mut book = Periods::new(inst, settings);
    book.variation = Some(Box::new(Variation::new(&book.c)));
    let start = PeriodStart::first(&book);
    if !continue_until(&mut book, start, stop) {
        return None;
    }
    let v = *book.variation.take().expect("kept from the start");
    Some((book.run, v))
}

/// The slider's total variation per axis over one accepted step from `a`
/// to `b` [m]: over the cubic Hermite of the ends' positions and
/// velocities ([`hermite`], the trajectories' dense output), whose
/// velocity is a quadratic ([`cubic_variation`]).
fn step_variation(a: &State, b: &State) -> Vec2 {
    let h = b[T] - a[T];
    let mut total = Vec2::ZERO;
    for i in 0..AXES {
        let (xa, va, xb, vb) = (a[XS + i], a[VS + i], b[XS + i], b[VS + i]);
        total[i] = if h > 0.0 {
            cubic_variation(xa, va, xb, vb, h)
        } else {
            (xb - xa).abs()
        };
    }
    total
}

/// The total variation [m] of the cubic `x(s) = xa + s (h va + s (c2 +
/// s c3))`, `s = t / h` in [0, 1], through positions `xa`, `xb` [m] with
/// velocities `va`, `vb` [m/s] over `h` [s]. Its slope `3 c3 s^2 + 2 c2
/// s + h va` has at most two zeros, found in closed form
/// ([`quadratic_roots`]): the velocity's zeros are located, not sampled,
/// with no iteration (`shaders/lugre/variation.wgsl` mirrors it written
/// out, no loop for llvmpipe's limiter to count). Between them x is
/// monotone.
pub fn cubic_variation(xa: f64, va: f64, xb: f64, vb: f64, h: f64) -> f64 {
    let c2 = 3.0 * (xb - xa) - h * (2.0 * va + vb);
    let c3 = 2.0 * (xa - xb) + h * (va + vb);
    let [lo, hi] = quadratic_roots(3.0 * c3, 2.0 * c2, h * va);
    let x = |s: f64| xa + s * (h * va + s * (c2 + s * c3));
    let inside = |s: f64| s > 0.0 && s < 1.0;
    let p1 = if inside(lo) { x(lo) } else { xa };
    let p2 = if inside(hi) { x(hi) } else { p1 };
    (p1 - xa).abs() + (p2 - p1).abs() + (xb - p2).abs()
}

/// The real roots of qa s^2 + qb s + qc, the smaller first, by the
/// cancellation-free form (q = -(qb + sign(qb) sqrt(disc)) / 2, roots q /
/// qa and qc / q); -1 for a root that does not exist (no real roots, or
/// qa = 0: the one root of the line, or none).
pub fn quadratic_roots(qa: f64, qb: f64, qc: f64) -> [f64; 2] {
    let disc = qb * qb - 4.0 * qa * qc;
    let real = disc >= 0.0;
    if !real {
        return [-1.0, -1.0];
    }
    let sign = if qb < 0.0 { -1.0 } else { 1.0 };
    let q = -0.5 * (qb + sign * disc.sqrt());
    let r1 = if qa != 0.0 { q / qa } else { -1.0 };
    let r2 = if q != 0.0 { qc / q } else { -1.0 };
    [r1.min(r2), r1.max(r2)]
}

/// A LuGre run that stops where a replica waits for its group's merge
/// (`measure::VERDICT_WAITING`) and goes on from there once released: the
/// replicas of a split steady measurement (`crate::replicas`).
pub struct Resumable {
    book: Periods,
    start: PeriodStart,
}

impl Resumable {
    /// Replica `r` of a split run at rest (`inst` the replica's instance,
    /// `Setup::new`).
    pub fn new(inst: &Instance, settings: &Settings, r: Replica) -> Resumable {
        let mut book = Periods::new_replica(inst, settings, r);
        if settings.backward {
            book.variation = Some(Box::new(Variation::new(&book.c)));
        }
        let start = PeriodStart::first(&book);
        Resumable { book, start }
    }

    /// Integrates to the run's end or its next wait (true), or until
    /// `stop` returns true (false).
    pub fn advance(&mut self, stop: impl Fn() -> bool) -> bool {
        observe_from(&mut self.book, &mut self.start, stop, &mut |_, _, _| {})
    }

    /// The run so far.
    pub fn run(&self) -> &Run {
        &self.book.run
    }

    /// The slider's total variation so far, where the run keeps it
    /// (`Settings::backward`).
    pub fn variation(&self) -> Option<&Variation> {
        self.book.variation.as_deref()
    }

    /// Lets the run go on if it waits for its group's merge, and the
    /// variation's accumulators with it.
    pub fn release(&mut self) {
        self.book.run.release();
        if let Some(v) = self.book.variation.as_deref_mut() {
            v.release();
        }
    }
}

/// Integrates the LuGre instance `inst` to its end, showing `observer`
/// every accepted step, and returns its final state (that of
/// [`run_instance_until`], bit for bit). Between step ends the positions
/// are the cubic Hermite interpolant of the ends' positions and
/// velocities (third order in the step; Rodas4's own dense output is not
/// kept); at step ends they are the integrator's.
pub fn run_observed(inst: &Instance, settings: &Settings, observer: &mut dyn Observer) -> Record {
    let mut book = Periods::new(inst, settings);
    let start = PeriodStart::first(&book);
    let mut seen = |period: u32, a: &State, b: &State| {
        observer.step(period, a[T], b[T], &|t| hermite(a, b, t));
    };
    let _ = observe_until(&mut book, start, || false, &mut seen);
    book.run.record
}

/// The positions at local time `t` between step ends `a` and `b`: cubic
/// Hermite in the positions and velocities of both ends.
fn hermite(a: &State, b: &State, t: f64) -> Positions {
    let h = b[T] - a[T];
    if h <= 0.0 || t >= b[T] {
        return ([b[XP], b[XP + 1]], [b[XS], b[XS + 1]]);
    }
    let s = ((t - a[T]) / h).clamp(0.0, 1.0);
    let (s2, s3) = (s * s, s * s * s);
    let w = [
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        3.0 * s2 - 2.0 * s3,
        s3 - s2,
    ];
    let at = |x: usize, v: usize| w[0] * a[x] + w[1] * h * a[v] + w[2] * b[x] + w[3] * h * b[v];
    (
        [at(XP, VP), at(XP + 1, VP + 1)],
        [at(XS, VS), at(XS + 1, VS + 1)],
    )
}

/// Where a scene period of a LuGre run starts: the integrator's state
/// (its time 0 within the period), its next trial step and the steps the
/// run may still take. Each GPU lane keeps its own, so that the CPU can
/// take a run over at its current period's start (the batch's CPU tail,
/// `crate::gpu::lugre`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PeriodStart {
    pub(crate) y: State,
    pub(crate) h: f64,
    pub(crate) budget: u32,
}

impl PeriodStart {
    /// The start of a run: at rest, z = 0, with [`first_step`].
    pub(crate) fn first(book: &Periods) -> PeriodStart {
        PeriodStart {
            y: [0.0; N],
            h: first_step(&book.inst),
            budget: book.budget,
        }
    }
}

/// Integrates `book`'s run from `start`, the start of its current period,
/// to the end of its measurement (true), or until `stop` returns true
/// (asked once per scene period; false). A failed segment ends the run
/// with its status.
pub(crate) fn continue_until(
    book: &mut Periods,
    start: PeriodStart,
    stop: impl Fn() -> bool,
) -> bool {
    observe_until(book, start, stop, &mut |_, _, _| {})
}

/// [`continue_until`], showing `observe` every accepted step with the
/// scene period it is in.
fn observe_until(
    book: &mut Periods,
    mut start: PeriodStart,
    stop: impl Fn() -> bool,
    observe: &mut impl FnMut(u32, &State, &State),
) -> bool {
    observe_from(book, &mut start, stop, observe)
}

/// [`observe_until`] from `start`, left at the start of the period where
/// the run ended or waits.
fn observe_from(
    book: &mut Periods,
    start: &mut PeriodStart,
    stop: impl Fn() -> bool,
    observe: &mut impl FnMut(u32, &State, &State),
) -> bool {
    let inst = book.inst;
    let period = inst.period();
    let PeriodStart {
        mut y,
        mut h,
        mut budget,
    } = *start;
    let mut total = book.variation.as_ref().map(|v| v.total);
    while !book.is_finished() {
        if stop() {
            return false;
        }
        let clock = book.clock();
        let period_index = book.run.record.period;
        y[T] = 0.0;
        while y[T] < period {
            let end = (0..AXES)
                .map(|i| clock.next_corner(&inst, &book.drives[i], i, y[T]))
                .fold(period, f64::min);
            let mid = 0.5 * (y[T] + end);
            let drive = [0, 1].map(|i| clock.drive_on(&inst, &book.drives[i], i, mid));
            match segment(
                &book.model,
                &drive,
                &book.scale,
                &mut y,
                end,
                (&mut h, &mut budget),
                &mut |a: &State, b: &State| {
                    if let Some(t) = total.as_mut() {
                        *t = *t + step_variation(a, b);
                    }
                    observe(period_index, a, b)
                },
            ) {
                Ok(steps) => book.add_steps(steps),
                Err(status) => {
                    book.run.record.status = status;
                    return true;
                }
            }
        }
        if let (Some(v), Some(t)) = (book.variation.as_deref_mut(), total) {
            v.total = t;
        }
        book.period_end(&y);
        *start = PeriodStart { y, h, budget };
    }
    debug_assert_eq!(book.run.record.status, STATUS_OK);
    true
}

/// A LuGre run's bookkeeping outside the integrator, period by period: the
/// model, the error control's weights, the step budget, the run's
/// floor `Run` and the measurement on top of it (`measure::period_end`
/// and the recurrence test with z). The CPU's run ([`run_instance_until`])
/// uses it; the GPU's lanes measure with its WGSL mirror
/// (`shaders/lugre/measure.wgsl`), and their host turns what they kept into
/// one ([`Periods::resume`]): the result, or where the CPU tail continues.
pub(crate) struct Periods {
    pub(crate) inst: Instance,
    pub(crate) model: Model,
    /// The error control's weights ([`error_scale`]).
    pub(crate) scale: State,
    /// Steps (accepted and rejected) the whole run may take.
    pub(crate) budget: u32,
    /// The run so far: its `record.steps` and `record.status` are the
    /// integrator's to set ([`Periods::add_steps`]).
    pub(crate) run: Run,
    /// Each axis' drive over a cycle (`floor::drive::axis_corners`).
    pub(crate) drives: [Corners; AXES],
    c: Setup,
    /// The common period of the recurrence test (0: none).
    common: u32,
    recurrence: Recurrence,
    /// The slider's total variation beside the measurement, when the run
    /// keeps it (`crate::laws::floor::variation`; [`run_with_variation_until`]).
    pub(crate) variation: Option<Box<Variation>>,
}

impl Periods {
    /// A run of `inst` at rest at the start of period 0.
    ///
    /// # Panics
    /// If `inst`'s friction is not LuGre's.
    pub(crate) fn new(inst: &Instance, settings: &Settings) -> Periods {
        Periods::new_replica(inst, settings, Replica::NONE)
    }

    /// [`Periods::new`] for replica `r` of a split run (`inst` the
    /// replica's instance).
    pub(crate) fn new_replica(inst: &Instance, settings: &Settings, r: Replica) -> Periods {
        let lugre = *inst.mechanism.lugre().expect("a LuGre instance");
        let model = Model::new(inst, &lugre);
        let mut c = Setup::new(inst, settings, r);
        // The recurrence test compares z too: done here, not by `period_end`.
        let common = std::mem::replace(&mut c.common_period, 0);
        let recurrence = Recurrence::new(&c, inst, &lugre);
        let scale = error_scale(&model, &lugre, settings.tolerance);
        let mut run = Run {
            record: Record::at_rest(),
            measure: initial_measure(&c),
        };
        if c.settle == 0 {
            run.record.settle_x_s = run.record.x_s;
        }
        let budget =
            (settings.max_steps_per_period as u64 * inst.cycles as u64).min(u32::MAX as u64) as u32;
        Periods {
            inst: *inst,
            model,
            scale,
            budget,
            run,
            drives: inst.axes.map(|a| axis_corners(&a)),
            c,
            common,
            recurrence,
            variation: None,
        }
    }

    /// Whether the run has ended: measured, failed or out of periods.
    pub(crate) fn is_finished(&self) -> bool {
        let st = &self.run.record;
        st.status != STATUS_OK || st.period >= self.inst.cycles || st.measured != 0
    }

    /// The drive's clock of the current scene period.
    pub(crate) fn clock(&self) -> Clock {
        Clock::of(&self.inst, self.run.record.period)
    }

    /// Counts the steps of one segment.
    pub(crate) fn add_steps(&mut self, steps: u32) {
        let st = &mut self.run.record;
        st.steps = st.steps.saturating_add(steps);
    }

    /// The end of the current scene period with the integrator's state `y`:
    /// the state's positions and velocities, the steady measurement
    /// (`measure::period_end` and the recurrence test), the next period.
    pub(crate) fn period_end(&mut self, y: &State) {
        let (c, common) = (&self.c, self.common);
        let (st, m) = (&mut self.run.record, &mut self.run.measure);
        set_motion(st, y);
        st.time = self.inst.period();
        if c.steady {
            period_end(c, st, m);
            let ended = st.period + 1;
            if common > 0
                && ended >= c.settle
                && (ended - c.settle).is_multiple_of(common)
                && m.verdict == VERDICT_RUNNING
                && self.recurrence.repeats(y, common, m)
            {
                st.measured = 1;
            }
            if let Some(v) = self.variation.as_deref_mut() {
                follow(c, common, st.period + 1, m, v);
            }
        }
        st.period += 1;
        st.time = 0.0;
        if st.period == c.settle {
            st.settle_x_s = st.x_s;
            if let Some(v) = self.variation.as_deref_mut() {
                v.settle_total = v.total;
            }
        }
    }
}

/// The positions and velocities of the state `y` in `st`.
fn set_motion(st: &mut Record, y: &State) {
    st.x_p = Vec2::new(y[XP], y[XP + 1]);
    st.v_p = Vec2::new(y[VP], y[VP + 1]);
    st.x_s = Vec2::new(y[XS], y[XS + 1]);
    st.v_s = Vec2::new(y[VS], y[VS + 1]);
}

/// A run as the GPU kept it (`crate::gpu::lugre`, which measures its
/// period ends on the device): the integrator's state at the last period
/// end (zero before the first), the run's counts and status, and the
/// measurement's accumulators and the recurrence test's snapshots.
pub(crate) struct Kept {
    pub(crate) y: State,
    pub(crate) period: u32,
    pub(crate) measured: u32,
    /// Steps of the segments completed before the current period.
    pub(crate) steps: u32,
    pub(crate) status: u32,
    pub(crate) settle_x_s: [f64; AXES],
    pub(crate) measure: Measure,
    pub(crate) snaps: [State; SNAPSHOTS],
    pub(crate) taken: u32,
}

impl Periods {
    /// The bookkeeping `kept` describes, as [`Periods::period_end`] leaves
    /// it: the result of a run the device finished, or where the CPU
    /// continues one ([`continue_until`]).
    pub(crate) fn resume(&mut self, kept: &Kept) {
        let st = &mut self.run.record;
        set_motion(st, &kept.y);
        st.time = 0.0;
        st.period = kept.period;
        st.measured = kept.measured;
        st.steps = kept.steps;
        st.status = kept.status;
        st.settle_x_s = Vec2::new(kept.settle_x_s[0], kept.settle_x_s[1]);
        self.run.measure = kept.measure;
        self.recurrence.snaps = kept.snaps;
        self.recurrence.taken = kept.taken;
    }

    /// The steady measurement's constants (the floor's, with no common
    /// period: the recurrence test is this run's, [`Periods::period_end`]).
    pub(crate) fn setup(&self) -> &Setup {
        &self.c
    }

    /// The periods the run may integrate (the instance's `cycles`).
    pub(crate) fn cycles(&self) -> u32 {
        self.inst.cycles
    }

    /// The recurrence test's tolerances per component (infinite: not
    /// compared) and its common period (0: no test), for the GPU.
    pub(crate) fn recurrence_test(&self) -> (State, u32) {
        (self.recurrence.repeat, self.common)
    }
}

/// docs/model.md section 4's recurrence test under LuGre: the state at a common
/// period's end against the last [`SNAPSHOTS`] ones, z included (section
/// 8), with the tolerances of Karnopp's test (`Setup::repeat_x`,
/// `repeat_v`) and z's force-equivalent one.
struct Recurrence {
    repeat: State,
    snaps: [State; SNAPSHOTS],
    taken: u32,
}

impl Recurrence {
    fn new(c: &Setup, inst: &Instance, lugre: &Lugre) -> Recurrence {
        let stiffness = inst
            .axes
            .iter()
            .map(|a| a.stiffness)
            .fold(f64::INFINITY, f64::min);
        let mut repeat = [c.repeat_x; N];
        for i in 0..AXES {
            repeat[VP + i] = c.repeat_v;
            repeat[VS + i] = c.repeat_v;
            repeat[Z + i] = c.repeat_x * (stiffness / lugre.bristle_stiffness).min(1.0);
        }
        // The slider's position is the travel, and the time the period's
        // end: neither is compared.
        for i in 0..AXES {
            repeat[XS + i] = f64::INFINITY;
        }
        repeat[T] = f64::INFINITY;
        Recurrence {
            repeat,
            snaps: [[0.0; N]; SNAPSHOTS],
            taken: 0,
        }
    }

    /// Whether `y` repeats a kept snapshot; if it does, records the lag
    /// and the travel over it in `m` (a periodic verdict), else keeps `y`.
    fn repeats(&mut self, y: &State, common: u32, m: &mut Measure) -> bool {
        let kept = self.taken.min(SNAPSHOTS as u32);
        for back in 1..=kept {
            let s = &self.snaps[((self.taken - back) % SNAPSHOTS as u32) as usize];
            if (0..N).all(|n| (y[n] - s[n]).abs() <= self.repeat[n]) {
                m.lag = back * common;
                m.travel = Vec2::new(y[XS] - s[XS], y[XS + 1] - s[XS + 1]);
                m.verdict = VERDICT_PERIODIC;
                return true;
            }
        }
        self.snaps[(self.taken % SNAPSHOTS as u32) as usize] = *y;
        self.taken += 1;
        false
    }
}

#[cfg(test)]
mod tests {
    use super::cubic_variation;
    use crate::laws::floor::variation::{Point, piece_variation};

    /// The floor's iterative search on the same cubic (what the closed
    /// form replaced), a dense sum over 20,000 samples, and the most the
    /// samples can miss (|x''| / 8 n^2 at each of two peaks).
    fn references(xa: f64, va: f64, xb: f64, vb: f64, h: f64) -> (f64, f64, f64) {
        let c2 = 3.0 * (xb - xa) - h * (2.0 * va + vb);
        let c3 = 2.0 * (xa - xb) + h * (va + vb);
        let x = |s: f64| xa + s * (h * va + s * (c2 + s * c3));
        let point = |t: f64| {
            let s = t / h;
            Point {
                x: x(s),
                v: va + s * (2.0 * c2 + 3.0 * s * c3) / h,
                a: (2.0 * c2 + 6.0 * s * c3) / (h * h),
            }
        };
        let a = Point {
            x: xa,
            v: va,
            ..point(0.0)
        };
        let b = Point {
            x: xb,
            v: vb,
            ..point(h)
        };
        let iterative = piece_variation(a, b, h, None, &point);
        let n = 20_000;
        let dense = (1..=n).map(|k| (x(k as f64 / n as f64) - x((k - 1) as f64 / n as f64)).abs());
        let miss = 2.0 * (2.0 * c2.abs() + 6.0 * c3.abs()) / (8.0 * (n * n) as f64);
        (iterative, dense.sum(), miss)
    }

    fn check(name: &str, (xa, va, xb, vb, h): (f64, f64, f64, f64, f64)) {
        let got = cubic_variation(xa, va, xb, vb, h);
        let (iterative, dense, miss) = references(xa, va, xb, vb, h);
        let scale = xa.abs().max(xb.abs()).max(va.abs() * h).max(vb.abs() * h);
        assert!(
            (got - iterative).abs() <= 1e-14 * scale,
            "{name}: {got:e} against {iterative:e}"
        );
        let below = got - dense;
        assert!(
            below >= -1e-15 * scale && below <= miss + 1e-15 * scale,
            "{name}: {got:e} against dense {dense:e}"
        );
        assert!(
            got >= (xb - xa).abs() * (1.0 - 1e-15),
            "{name}: {got:e} below the net travel"
        );
    }

    #[test]
    fn cubic_variation_agrees_with_the_iterative_search_and_a_dense_sum() {
        let h = 1e-4;
        let cases = [
            ("monotone", (0.0, 1e-3, 2e-7, 3e-3, h)),
            ("one zero", (0.0, 1e-3, -1e-8, -2e-3, h)),
            ("two zeros", (0.0, 2e-3, 1e-8, 2e-3, h)),
            ("two zeros, backward first", (1e-6, -1e-3, 1e-6, -1e-3, h)),
            ("at rest at the start", (0.0, 0.0, 1e-7, -1e-3, h)),
            ("at rest at the end", (0.0, 1e-3, 1e-7, 0.0, h)),
            ("at rest", (5e-7, 0.0, 5e-7, 0.0, h)),
            ("a line", (0.0, 1e-3, 1e-7, 1e-3, h)),
            (
                "nearly tangent",
                (0.0, 1e-3, 6.6666e-8, 1e-3 * (1.0 - 1e-9), h),
            ),
        ];
        for (name, case) in cases {
            check(name, case);
        }
        // Seeded cubics of every shape (a Weyl sequence, no dependency).
        let mut u = 0.5f64;
        let mut next = || {
            u = (u + 0.618_033_988_749_894_9) % 1.0;
            2.0 * u - 1.0
        };
        for k in 0..200 {
            let case = (
                next() * 1e-6,
                next() * 1e-2,
                next() * 1e-6,
                next() * 1e-2,
                h,
            );
            check(&format!("seeded {k}"), case);
        }
    }
}
