//! Karnopp's friction law (docs/model.md section 3) on the CPU: `integrate/`
//! follows `shaders/karnopp/` file by file and function by function, and is
//! compiled twice, as the shader is, with the scalar `Real` of each
//! precision: [`double`] (f64, SI units: the reference every backend is
//! held to) and [`single`] (f32 in micrometres and milliseconds: the f32
//! shader's mirror). [`integrate`] is the f64 one. [`paper_rk4`] is the
//! paper's fixed-step RK4 of the same law, a baseline, not the reference.
//! [`variation`] keeps the slider's total variation (the backward
//! travel's position) beside a run.

pub mod double;
pub mod paper_rk4;
pub mod single;
pub mod variation;

pub use double::integrate;

// The floor's record of an f64 state and run: what everything above the
// laws reads (`crate::laws::floor::record`).
impl integrate::State {
    /// The floor's record of this state (`crate::laws::floor::Record`).
    pub fn record(&self) -> crate::laws::floor::Record {
        crate::laws::floor::Record {
            x_p: self.x_p,
            v_p: self.v_p,
            x_s: self.x_s,
            v_s: self.v_s,
            settle_x_s: self.settle_x_s,
            time: self.time,
            mode: self.mode,
            period: self.period,
            status: self.status,
            steps: self.steps,
            measured: self.measured,
        }
    }
}

impl From<&integrate::State> for crate::laws::floor::Record {
    fn from(st: &integrate::State) -> crate::laws::floor::Record {
        st.record()
    }
}

impl integrate::Run {
    /// The floor's run: the record of the state, the same measurement.
    pub fn ended(&self) -> crate::laws::floor::Run {
        crate::laws::floor::Run {
            record: self.state.record(),
            measure: self.measure,
        }
    }
}

/// Whether `status` says the integration failed (step budget, non-finite
/// state, step underflow, event storm), as opposed to finishing or to a
/// steady measurement's verdict. In f32 such a failure is f32's own far
/// more often than the instance's (a velocity band below what f32 resolves
/// next to the stage speeds ends in step underflow: 279 of `stress.toml`'s
/// 432 instances with a 1e-9 m/s band).
pub fn is_integrator_failure(status: u32) -> bool {
    use crate::laws::karnopp::integrate::{
        STATUS_EVENT_STORM, STATUS_NON_FINITE, STATUS_STEP_BUDGET, STATUS_STEP_UNDERFLOW,
    };
    matches!(
        status,
        STATUS_STEP_BUDGET | STATUS_NON_FINITE | STATUS_STEP_UNDERFLOW | STATUS_EVENT_STORM
    )
}

/// Whether an f32 integration that ended with `status` is integrated again
/// on the CPU in f64, by every f32 path (the shader's batches and the CPU
/// mirror's backend alike): a failure ([`is_integrator_failure`]), or a
/// band graze, where f32 stopped because the step depends on a decision
/// that the direction tolerance, not f32, leaves open
/// (`laws::karnopp::integrate::constants::GRAZE_MARGIN`). The instance then carries
/// the f64 reference's value, or its status where that fails too, and is
/// counted as run on the CPU.
pub fn f32_needs_f64(status: u32) -> bool {
    is_integrator_failure(status)
        || status == crate::laws::karnopp::integrate::constants::STATUS_GRAZE
}

/// The profile table's lines of the CPU integrator's iterations by kind
/// (both precisions' mirrors together), with the share of slip trials
/// rejected; empty where the CPU integrated nothing (LuGre's integrator
/// is not counted).
pub fn iteration_lines() -> String {
    use integrate::constants::{ITERATION_KINDS, KIND_NAMES, rejected_share};
    use std::sync::atomic::Ordering;
    let mut kinds = [0u64; ITERATION_KINDS];
    for (k, total) in kinds.iter_mut().enumerate() {
        *total = integrate::ITERATIONS[k].load(Ordering::Relaxed)
            + single::integrate::ITERATIONS[k].load(Ordering::Relaxed);
    }
    let all: u64 = kinds.iter().sum();
    if all == 0 {
        return String::new();
    }
    let by_kind: Vec<String> = KIND_NAMES
        .iter()
        .zip(kinds)
        .filter(|(_, n)| *n > 0)
        .map(|(name, n)| format!("{name} {:.1} %", 100.0 * n as f64 / all as f64))
        .collect();
    format!(
        "pidm: phase CPU integrator: {all} iterations; by kind: {}\n\
         pidm: phase   rejected trials: {:.1} % of slip trials (slip steps and rejected trials)\n",
        by_kind.join(", "),
        100.0 * rejected_share(&kinds)
    )
}

/// Integrates `inst` on the CPU in `precision` to the end, or until `stop`
/// says so (then `None`): in f64 the reference, in f32 the f32 shader's
/// mirror with its results in SI. An f32 run that fails or meets a band
/// graze is integrated again in f64, as the f32 shader's are
/// ([`f32_needs_f64`]), and its f32 status comes back beside the run.
pub fn run_in_until(
    inst: &crate::model::Instance,
    settings: &crate::laws::Settings,
    precision: crate::laws::Precision,
    stop: impl Fn() -> bool + Copy,
) -> Option<(integrate::Run, Option<u32>)> {
    use crate::laws::Precision;
    match precision {
        Precision::F64 => integrate::run_instance_until(inst, settings, stop).map(|r| (r, None)),
        Precision::F32 => match single::integrate::run_instance_until(inst, settings, stop)? {
            r if f32_needs_f64(r.state.status) => {
                integrate::run_instance_until(inst, settings, stop)
                    .map(|f| (f, Some(r.state.status)))
            }
            r => Some((single::si::run(&r), None)),
        },
    }
}

/// Integrates `inst` with the f64 integrator to its end, showing
/// `observer` the closed-form motion of every step (the integrator's own
/// dense output), and returns its final state: that of the map's run of
/// the same instance, bit for bit.
pub fn run_observed(
    inst: &crate::model::Instance,
    settings: &crate::laws::Settings,
    observer: &mut dyn crate::laws::observe::Observer,
) -> integrate::State {
    use integrate::{Coefficients, State, StepMotion, StepObserver};
    /// Karnopp's steps as the law-neutral observer sees them.
    struct Steps<'a>(&'a mut dyn crate::laws::observe::Observer);
    impl StepObserver for Steps<'_> {
        fn step(&mut self, st: &State, motion: &StepMotion) {
            let start = st.time;
            self.0.step(st.period, start, motion.end(), &|t| {
                motion.positions_at(t - start)
            });
        }
    }
    let c = Coefficients::new(inst, settings, f64::EPSILON);
    let mut st = integrate::initial_state(&c);
    let mut measure = integrate::initial_measure(&c);
    let mut steps = Steps(observer);
    while !integrate::is_finished(&c, &st) {
        integrate::advance_observed(&c, &mut st, &mut measure, u32::MAX, &mut steps);
    }
    st
}
