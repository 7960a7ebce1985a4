//! The backward travel in LuGre's shader (issue 59,
//! `shaders/lugre/variation.wgsl` with the floor's
//! `shaders/shared/variation.wgsl`): the software variant gives the CPU's
//! f64 backward travel (`laws::lugre::run_with_variation_until`) bit for
//! bit on lavapipe and the CPU's steps with it; the hardware's variant
//! (fused arithmetic, run on lavapipe here) within the step's own bound;
//! the CPU tail continues a lane's variation from its period start; and
//! the backward pipeline's self-test catches a wrong variation.

use pidm::gpu::GpuOutcome;
use pidm::gpu::lugre::{BACKWARD_ALLOWANCE_M, Form, LugreGpu};
use pidm::laws::Settings;
use pidm::laws::lugre::run::run_with_variation_until;
use pidm::measurement::{reduce, reduce_variation};
use pidm::model::{Axis, Friction, Instance, Lugre, Measure, Shape, Table};

use crate::common::case;
use crate::gpu::f64_context;

/// The hardware variant's bars on lavapipe [m per own drive cycle]: its
/// division and roots move the step control, which is chaotic at the
/// tolerance's scale, so the step within `gpu_lugre`'s 2e-5 um and the
/// backward travel within the LuGre self-test's allowance (a one-ulp
/// change of the tolerance moves the CPU's own by up to 3.9e-10 m).
const HARDWARE_BARS_M: [f64; 2] = [2e-11, pidm::gpu::lugre::BACKWARD_ALLOWANCE_M];

fn backward() -> Settings {
    Settings {
        backward: true,
        ..Settings::default()
    }
}

/// LuGre windows of 4 periods (settling 1) at its defaults: 1-DOF, 2-DOF
/// at two frequencies, a slew-limited trapezoid against a table with a
/// jump, and a steady 2-DOF run whose cycle the recurrence finds.
fn cases() -> Vec<Instance> {
    let lugre = |v: [f64; 2], f: [f64; 2]| {
        let mut inst = case(v[0], v[1], f[0], f[1], Axis::TABLE1);
        inst.mechanism.friction = Friction::Lugre(Lugre::DEFAULT);
        (inst.cycles, inst.settle) = (4, 1);
        inst
    };
    let mut shaped = lugre([100.0, 80.0], [10.0, 20.0]);
    let x = &mut shaped.axes[0];
    (x.shape, x.rise, x.hold, x.fall, x.slew_rate) = (Shape::Trapezoid, 0.8, 0.1, 0.03, 2e4);
    shaped.axes[1].shape = Shape::Table(Table::intern(&[[0.1, -0.5], [0.6, 1.0], [0.6, 0.2]]));
    let mut steady = lugre([100.0, 60.0], [10.0, 20.0]);
    steady.measure = Measure::Steady {
        step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
    };
    steady.cycles = 40;
    vec![
        lugre([100.0, 0.0], [10.0, 10.0]),
        lugre([100.0, 100.0], [10.0, 20.0]),
        shaped,
        steady,
    ]
}

/// Each outcome against the CPU's run with its variation: the same
/// status, periods and lag; steps and backward travels within `bars` [m
/// per own drive cycle] (0: bit for bit). Returns the largest step and
/// backward differences.
fn check(label: &str, instances: &[Instance], got: &[GpuOutcome], bars: [f64; 2]) -> [f64; 2] {
    let mut worst = [0.0_f64; 2];
    for (k, (inst, g)) in instances.iter().zip(got).enumerate() {
        let (run, v) = run_with_variation_until(inst, &backward(), || false).expect("ran");
        let want = reduce(inst, &run);
        let (variation, _) = reduce_variation(inst, &run, &v);
        assert_eq!(
            (g.status, g.periods, g.lag),
            (want.status, want.periods, want.lag),
            "{label} {k}"
        );
        for (axis, want_back) in variation.into_iter().enumerate() {
            let step = inst.measure_over(axis, want.travel[axis], want.span).1;
            let got_step = inst.measure_over(axis, g.displacement[axis], g.span).1;
            let d = (got_step - step).abs();
            assert!(
                d <= bars[0],
                "{label} {k} axis {axis}: step {got_step:e} m, CPU {step:e} m"
            );
            worst[0] = worst[0].max(d);
            let d = (g.variation[axis] - want_back).abs();
            assert!(
                d <= bars[1],
                "{label} {k} axis {axis}: backward travel {:e} m on the GPU, {:e} m on the CPU",
                g.variation[axis],
                want_back
            );
            worst[1] = worst[1].max(d);
        }
    }
    worst
}

/// The software and the hardware variants measure the CPU's backward
/// travel, the software's bit for bit (on a software adapter), and travel
/// back where the CPU does.
#[test]
fn lugres_shader_measures_the_backward_travel_as_the_cpu_does() {
    let Some(ctx) = f64_context() else {
        return;
    };
    let instances = cases();
    // The software variant divides natively in f64, which NVIDIA's
    // compiler refuses: a hardware adapter runs the hardware's alone.
    let variants = match ctx.is_hardware() {
        true => vec![(true, HARDWARE_BARS_M)],
        false => vec![(false, [0.0; 2]), (true, HARDWARE_BARS_M)],
    };
    for (hardware, bars) in variants {
        let gpu = LugreGpu::variant(ctx, hardware, Form::Backward).expect("self-tested");
        assert!(gpu.measures_backward() && gpu.drives_waveforms());
        let got = gpu
            .outcomes_until(&instances, &backward(), || false, &|_| {})
            .expect("the batch");
        let [step, back] = check(&format!("hardware {hardware}"), &instances, &got, bars);
        eprintln!(
            "hardware variant {hardware}: largest differences: step {step:.2e} m, backward {back:.2e} m"
        );
        let back = got.iter().filter(|o| o.variation[0] > 1e-7).count();
        assert!(back >= 3, "{back} travel back: {got:?}");
    }
}

/// A run the CPU takes over from its lane's period start keeps the lane's
/// variation: the same backward travel, bit for bit on a software
/// adapter; and the backward pipeline's self-test fails against a CPU
/// variation moved past its allowance, naming it.
#[test]
fn lugres_tail_keeps_the_backward_travel_and_its_self_test_checks_it() {
    let Some(ctx) = f64_context() else {
        return;
    };
    let mut gpu = LugreGpu::variant(ctx, ctx.is_hardware(), Form::Backward).expect("self-tested");
    let mut instances = cases();
    instances[1].cycles = 12;
    gpu.cpu_tail = Some(1);
    let got = gpu
        .outcomes_until(&instances, &backward(), || false, &|_| {})
        .expect("the batch");
    assert!(got.iter().any(|o| o.finished_on_cpu), "{got:?}");
    let bars = match ctx.is_hardware() {
        true => HARDWARE_BARS_M,
        false => [0.0; 2],
    };
    check("tail", &instances, &got, bars);
    let err = gpu
        .self_test_backward_skewed(2.0 * BACKWARD_ALLOWANCE_M)
        .expect_err("a skewed variation fails")
        .to_string();
    assert!(err.contains("backward travel"), "{err}");
    gpu.self_test_backward_skewed(0.0).expect("passes");
}
