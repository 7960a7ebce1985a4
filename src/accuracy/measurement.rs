//! The measurement's part of the study (MODEL.md section 4): how far a
//! fixed window of periods and a steady measurement at a ladder of step
//! tolerances are from the long-run mean step, with their wall times. Only
//! scenes with two different drive frequencies are studied: at equal
//! frequencies the motion is periodic after a few periods and every method
//! measures it exactly.

use super::Method;
use crate::backend::{Backend, CpuBackend};
use crate::cpu::integrate::Settings;
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

/// The instances as the reference measures them: steady, to
/// [`MEASUREMENT_REFERENCE_TOLERANCE`], for at most
/// [`MEASUREMENT_REFERENCE_MAX_CYCLES`] periods.
pub fn measurement_reference(instances: &[Instance]) -> Vec<Instance> {
    instances
        .iter()
        .map(|inst| Instance {
            cycles: MEASUREMENT_REFERENCE_MAX_CYCLES,
            settle: Measure::DEFAULT_SETTLE,
            measure: Measure::Steady {
                step_tolerance: MEASUREMENT_REFERENCE_TOLERANCE,
            },
            ..*inst
        })
        .collect()
}

/// Fixed windows of `periods` scene periods (the first 2 discarded, as the
/// paper's 10 / 2), on one CPU thread.
pub fn window_method<'a>(base: Settings, periods: Vec<f64>) -> Method<'a> {
    let backend = CpuBackend::new(Some(1)).expect("a one-thread pool");
    Method {
        name: "fixed window (cpu)".into(),
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
        name: format!("steady, max_cycles {max_cycles} (cpu)"),
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
