//! Two drive frequencies on the GPU (issue 31): the shader's phase ladder
//! (`shaders/shared/phase.wgsl`) and long common periods measure as the
//! CPU does. In f64 the same verdicts, periods and kinds of motion, and on
//! periodic instances the same steps within `F64_ALLOWANCE`; every other
//! value within the CPU's reported standard error (f32: plus its
//! allowance), whether the GPU read its heads or the whole accumulators
//! back. Measured on lavapipe: f64 agrees to the printed 1e-6 um, f32
//! within 5e-4 um.

use pidm::gpu::{BatchOptions, Precision};
use pidm::laws::Settings;
use pidm::laws::karnopp::integrate::run_instance;
use pidm::laws::status::STATUS_NOT_STEADY;
use pidm::laws::status::STATUS_OK;
use pidm::measurement::{Measured, reduce};
use pidm::model::motion::Motion;
use pidm::model::{Instance, Measure};

use crate::gpu::{F64_ALLOWANCE, context, f32_allowance, gpu_batch, precisions};

/// Table 1 at 100 V, x at `fx` and y at `fy` Hz, measured steady at the
/// default tolerance for at most `max_cycles` periods.
fn two_frequencies(fx: f64, fy: f64, max_cycles: u32) -> Instance {
    let mut inst = Instance::TABLE1;
    inst.axes[0].frequency = fx;
    inst.axes[1].frequency = fy;
    inst.cycles = max_cycles;
    inst.measure = Measure::Steady {
        step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
    };
    inst
}

#[test]
fn two_frequency_measurements_match_the_cpu() {
    let Some(ctx) = context() else {
        return;
    };
    // Quasi-periodic (the ladder stops at 962 periods), periodic after a
    // common period of 719 (14.38 / 16.7 Hz, near 1/6: no window resolves
    // enough phases before), and near 10/9 cut at 1,000 periods (not
    // steady, the latest window kept).
    let instances = [
        two_frequencies(10.0, 10.0 * 2f64.sqrt(), 10_000),
        two_frequencies(14.38, 16.7, 10_000),
        two_frequencies(21.34, 23.66, 1000),
    ];
    let settings = Settings::default();
    let cpu: Vec<Measured> = instances
        .iter()
        .map(|inst| reduce(inst, &run_instance(inst, &settings).ended()))
        .collect();
    let kinds: Vec<Motion> = cpu.iter().map(|m| m.motion).collect();
    assert_eq!(
        kinds,
        [
            Motion::QuasiPeriodic,
            Motion::Periodic,
            Motion::Undetermined
        ]
    );
    assert_eq!(cpu[1].lag, 719);
    assert_eq!(cpu[2].status, STATUS_NOT_STEADY);
    let whole = BatchOptions {
        whole_accumulators: true,
        ..BatchOptions::default()
    };
    for precision in precisions(ctx) {
        for (label, options) in [("heads", BatchOptions::default()), ("whole", whole)] {
            let gpu = gpu_batch(ctx, &instances, &settings, precision, &options);
            for (k, (inst, (c, g))) in instances.iter().zip(cpu.iter().zip(&gpu)).enumerate() {
                let name = format!("{label} {precision} #{k}");
                if precision == Precision::F64 {
                    assert_eq!(
                        (g.status, g.lag, g.periods, g.motion),
                        (c.status, c.lag, c.periods, c.motion),
                        "{name}: {g:?} {c:?}"
                    );
                } else {
                    assert!(
                        g.status == STATUS_OK || g.status == STATUS_NOT_STEADY,
                        "{name}: {g:?}"
                    );
                }
                for i in 0..2 {
                    let step = |travel: f64, span: f64| inst.measure_over(i, travel, span).1 * 1e6;
                    let (a, b) = (step(g.displacement[i], g.span), step(c.travel[i], c.span));
                    let bound = match precision {
                        Precision::F64 if c.lag > 0 => F64_ALLOWANCE,
                        Precision::F64 => c.se[i] * 1e6,
                        Precision::F32 => c.se[i] * 1e6 + f32_allowance(b),
                    };
                    eprintln!("{name} axis {i}: GPU {a:+.6} um, CPU {b:+.6} um, bound {bound:.2e}");
                    assert!(
                        (a - b).abs() <= bound,
                        "{name} axis {i}: GPU {a} um ({g:?}), CPU {b} um ({c:?}), bound {bound}"
                    );
                }
            }
        }
    }
}
