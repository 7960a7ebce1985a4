//! The measurement's part of the study (docs/model.md section 4): how far a
//! fixed window of periods (the running mean) and a steady measurement at
//! a ladder of step tolerances (the phase-resolved estimate, issue 31, or
//! batch means where it does not decide) are from the long-run mean step,
//! with their wall times and periods. Only scenes with two different drive
//! frequencies are studied: at equal frequencies the motion is periodic
//! after a few periods and every method measures it exactly.
//!
//! The reference does not use the estimator it judges: for two drive
//! frequencies without a short common period it is the running mean over
//! a lattice window ([`lattice_length`]): a whole number of common periods
//! (exact once the motion repeats), or the largest continued-fraction
//! denominator q_n of the faster drive's advance per period, whose phases
//! lie within 1 / q_{n+1} of an even lattice, so that its error is at most
//! the variation of the increments over the phase divided by q_n
//! (Denjoy-Koksma; measured 0.0002-0.003 um at q_n of 1,000-3,000 on the
//! instances of `laws::floor::phase`).

use super::Method;
use crate::backend::{Backend, CpuBackend};
use crate::laws::Settings;
use crate::model::{Instance, Measure};

/// The reference's step tolerance [m per own drive cycle]: 0.001 um, five
/// times below the 0.005 um maps are compared at.
pub const MEASUREMENT_REFERENCE_TOLERANCE: f64 = 1e-9;
/// The most periods a reference may run; an instance whose motion neither
/// repeats nor converges to [`MEASUREMENT_REFERENCE_TOLERANCE`] by then has
/// no reference and is left out (the report counts them).
pub const MEASUREMENT_REFERENCE_MAX_CYCLES: u32 = 100_000;

/// Whether some instance drives both axes at different frequencies.
pub fn has_two_frequencies(instances: &[Instance]) -> bool {
    instances.iter().any(|inst| {
        let [x, y] = &inst.axes;
        x.is_driven() && y.is_driven() && x.frequency != y.frequency
    })
}

/// The longest lattice window of a reference [scene periods].
pub const REFERENCE_WINDOW: u32 = 40_000;

/// The instances as the reference measures them: a fixed window over a
/// lattice ([`lattice_length`]) where two drive frequencies have no common
/// period up to `measure::SHORT_COMMON_PERIOD`; otherwise steady, to
/// [`MEASUREMENT_REFERENCE_TOLERANCE`], for at most
/// [`MEASUREMENT_REFERENCE_MAX_CYCLES`] periods (such motions repeat, and
/// the recurrence test finds them exactly).
pub fn measurement_reference(instances: &[Instance]) -> Vec<Instance> {
    instances
        .iter()
        .map(|inst| match lattice_length(inst, REFERENCE_WINDOW) {
            Some(length) => Instance {
                cycles: Measure::DEFAULT_SETTLE + length,
                settle: Measure::DEFAULT_SETTLE,
                measure: Measure::Window,
                ..*inst
            },
            None => Instance {
                cycles: MEASUREMENT_REFERENCE_MAX_CYCLES,
                settle: Measure::DEFAULT_SETTLE,
                measure: Measure::Steady {
                    step_tolerance: MEASUREMENT_REFERENCE_TOLERANCE,
                },
                ..*inst
            },
        })
        .collect()
}

/// The lattice window of at most `longest` periods of an instance with two
/// drive frequencies and no common period up to
/// `measure::SHORT_COMMON_PERIOD` (None otherwise): the largest multiple
/// of the common period where there is one, else the largest
/// continued-fraction denominator of rho, the faster drive's advance per
/// scene period.
pub fn lattice_length(inst: &Instance, longest: u32) -> Option<u32> {
    use crate::laws::floor::measure::{SHORT_COMMON_PERIOD, common_period};
    let [x, y] = &inst.axes;
    if !(x.is_driven() && y.is_driven()) || x.frequency == y.frequency {
        return None;
    }
    let period = inst.period();
    let frequency = crate::laws::floor::Vec2::new(x.frequency, y.frequency);
    let cycles = frequency * period;
    let q = common_period(frequency, cycles, [true, true]);
    if q > 0 && q <= SHORT_COMMON_PERIOD {
        return None;
    }
    if let Some(whole) = longest.checked_div(q) {
        return Some(whole.max(1) * q);
    }
    let rho = cycles.max_element().fract();
    // The continued fraction of rho: denominators q_n = a_n q_{n-1} +
    // q_{n-2}, kept while at most `longest`.
    let (mut previous, mut current) = (0u64, 1u64);
    let mut rest = rho;
    while rest > 1e-12 {
        let inverse = 1.0 / rest;
        let a = inverse.floor();
        rest = inverse - a;
        let next = a as u64 * current + previous;
        if next > longest as u64 {
            break;
        }
        (previous, current) = (current, next);
    }
    Some(current as u32)
}

/// Fixed windows of `periods` scene periods (the first 2 discarded, as the
/// paper's 10 / 2): the running mean, on one CPU thread.
pub fn window_method<'a>(base: Settings, periods: Vec<f64>) -> Method<'a> {
    let backend = CpuBackend::new(Some(1)).expect("a one-thread pool");
    Method {
        name: "running mean: fixed window (cpu)".into(),
        setting_name: "periods",
        settings: periods,
        run: Box::new(move |instances, periods| {
            let windows: Vec<Instance> = instances
                .iter()
                .map(|inst| Instance {
                    cycles: periods as u32,
                    settle: Measure::DEFAULT_SETTLE,
                    measure: Measure::Window,
                    ..*inst
                })
                .collect();
            backend.run(&windows, &base, &|_| {})
        }),
    }
}

/// Steady measurements at a ladder of step tolerances [m per own drive
/// cycle], at most `max_cycles` periods each, on one CPU thread.
pub fn steady_method<'a>(base: Settings, tolerances: Vec<f64>, max_cycles: u32) -> Method<'a> {
    let backend = CpuBackend::new(Some(1)).expect("a one-thread pool");
    Method {
        name: format!("steady (phase-resolved / batch means), max_cycles {max_cycles} (cpu)"),
        setting_name: "step tolerance [m]",
        settings: tolerances,
        run: Box::new(move |instances, tolerance| {
            let steady: Vec<Instance> = instances
                .iter()
                .map(|inst| Instance {
                    cycles: max_cycles,
                    settle: Measure::DEFAULT_SETTLE,
                    measure: Measure::Steady {
                        step_tolerance: tolerance,
                    },
                    ..*inst
                })
                .collect();
            backend.run(&steady, &base, &|_| {})
        }),
    }
}
