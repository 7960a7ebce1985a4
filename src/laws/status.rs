//! The status codes an integration ends with, the same for every law: the
//! integrators set 0 to 4 (and f32's 7), the sweep 5 after `--verify`, the
//! measurement's reduction 6. `crate::measurement::status` says what each
//! means in a result file; every law's shader prelude names them from here.

/// The instance finished normally.
pub const STATUS_OK: u32 = 0;
/// The step budget ([`crate::laws::Settings::max_steps_per_period`]) ran out.
pub const STATUS_STEP_BUDGET: u32 = 1;
/// A non-finite number appeared in the state.
pub const STATUS_NON_FINITE: u32 = 2;
/// The slip step size fell below the time resolution of a period.
pub const STATUS_STEP_UNDERFLOW: u32 = 3;
/// Mode changes kept following each other without time advancing.
pub const STATUS_EVENT_STORM: u32 = 4;
/// An f32 run met a band graze it cannot decide like the f64 reference
/// (`laws::karnopp::integrate::constants::GRAZE_MARGIN`) and stopped there. Set only where the precision's
/// `GRAZE_GUARD` is on (f32); the host integrates such an instance again
/// in f64 on the CPU (`pidm::laws::karnopp::f32_needs_f64`), so the code never
/// reaches a result file.
pub const STATUS_GRAZE: u32 = 7;
/// A steady measurement reached `max_cycles` without its motion repeating
/// or its standard error falling within the step tolerance: the map keeps
/// the best estimate and its standard error (set by the host's reduction,
/// `pidm::measurement`; code 5 is the sweep's `--verify`).
pub const STATUS_NOT_STEADY: u32 = 6;
/// Status of an instance that `--verify` found unconverged: rerun with a
/// 100 times tighter tolerance, one of its steps (or baseline steps) moved
/// by more than `pidm::sweep::VERIFY_ALLOWANCE_M`. Like every non-zero status, its map
/// entries are 0. Set by the sweep, not by an integrator.
pub const STATUS_UNCONVERGED: u32 = 5;

/// The codes an integrator sets, as WGSL constants: every law's shader
/// prelude reads them from here (`crate::gpu::prelude`).
pub fn wgsl_constants() -> String {
    [
        ("STATUS_OK", STATUS_OK),
        ("STATUS_STEP_BUDGET", STATUS_STEP_BUDGET),
        ("STATUS_NON_FINITE", STATUS_NON_FINITE),
        ("STATUS_STEP_UNDERFLOW", STATUS_STEP_UNDERFLOW),
        ("STATUS_EVENT_STORM", STATUS_EVENT_STORM),
        ("STATUS_GRAZE", STATUS_GRAZE),
    ]
    .map(|(name, v)| format!("const {name}: u32 = {v}u;\n"))
    .concat()
}
