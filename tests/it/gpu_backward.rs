//! The backward travel on the GPU (issue 59, `shaders/karnopp/variation.wgsl`):
//! Karnopp's f64 shader measures it as the CPU's f64 path does, windows
//! and steady runs of every verdict, waveforms, loads, 1-DOF and 2-DOF,
//! where the CPU finishes the device's slow tail and where llvmpipe's loop
//! limiter cuts dispatches short; measuring it moves no step beyond
//! rounding; and its
//! pipeline's self-test catches a wrong variation.

use pidm::gpu::{BatchOptions, GpuOutcome, Precision};
use pidm::laws::Settings;
use pidm::model::random::random_instances;
use pidm::model::{Instance, Measure, Shape};
use pidm::sweep::run_one;

use crate::gpu::{f64_context, gpu_batch, paper_cases, table1_cases};

/// The bar for lavapipe's f64 against the CPU [m per own drive
/// cycle]: 1e-6 um.
const BAR_M: f64 = 1e-12;

/// How far a step may move with the backward travel on the GPU, relative
/// to the step without it: the two are different compiled programs, and
/// llvmpipe rounds (contracts) their shared arithmetic differently
/// (measured: 576 ulps of a 40-period travel, 1e-13 of it). The CPU path
/// keeps the step's bits (`backward::measuring_the_backward_travel_changes_no_step`).
const STEP_ROUNDING: f64 = 1e-11;

fn backward() -> Settings {
    Settings {
        backward: true,
        ..Settings::default()
    }
}

/// Windows and steady runs: Table 1 against 14 Hz (periodic), against
/// 10 sqrt 2 Hz (the phase ladder), 1-DOF, under a load, a slew-limited
/// trapezoid, a trapezoid with a hold, stages that do not ring in stick,
/// and random windows with and without loads.
fn cases() -> Vec<Instance> {
    let steady = |mut inst: Instance| {
        inst.settle = 1;
        inst.cycles = 400;
        inst.measure = Measure::Steady {
            step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
        };
        inst
    };
    let mut out = Vec::new();
    let mut periodic = Instance::TABLE1;
    periodic.axes[1].voltage = 60.0;
    periodic.axes[1].frequency = 14.0;
    out.push(steady(periodic));
    let mut phase = periodic;
    phase.axes[1].frequency = 10.0 * 2f64.sqrt();
    out.push(steady(phase));
    out.push(steady(Instance::TABLE1));
    let mut loaded = periodic;
    loaded.mechanism.load = [0.3, -0.2];
    out.push(steady(loaded));
    let mut trapezoid = periodic;
    trapezoid.axes[0].shape = Shape::Trapezoid;
    [
        trapezoid.axes[0].rise,
        trapezoid.axes[0].hold,
        trapezoid.axes[0].fall,
    ] = [0.8, 0.1, 0.03];
    trapezoid.axes[0].slew_rate = 2e4;
    out.push(steady(trapezoid));
    let mut window = periodic;
    window.cycles = 6;
    window.settle = 2;
    out.push(window);
    // A hold and a dwell, where a stuck stage rings about no drift, and
    // stages that do not ring in stick (critically damped, overdamped):
    // the extrema cut's other branches (`ring_cuts`, `ring_settled`).
    let mut hold = window;
    hold.axes[0].shape = Shape::Trapezoid;
    [hold.axes[0].rise, hold.axes[0].hold, hold.axes[0].fall] = [0.5, 0.3, 0.02];
    out.push(hold);
    for zeta in [1.0, 3.0] {
        let mut dead = window;
        for axis in dead.axes.iter_mut() {
            let mass = axis.stage_mass + dead.mechanism.slider_mass;
            axis.damping = 2.0 * zeta * (axis.stiffness * mass).sqrt();
        }
        out.push(dead);
    }
    out.extend(random_instances(17, 6, 6, 2));
    out
}

/// Each outcome's backward travel against the CPU's f64 run's, within
/// `bar` [m] per axis, and its run the same as the one without it (status,
/// cycle, steps, periods; the travel to [`STEP_ROUNDING`], or 1e-12 um
/// where it is about zero); returns the
/// largest difference.
fn check(
    label: &str,
    instances: &[Instance],
    got: &[GpuOutcome],
    plain: &[GpuOutcome],
    bar: f64,
) -> f64 {
    let mut worst: f64 = 0.0;
    for (k, inst) in instances.iter().enumerate() {
        let want = run_one(inst, &backward());
        let (g, p) = (&got[k], &plain[k]);
        assert_eq!(
            (g.status, g.lag, g.steps, g.periods),
            (p.status, p.lag, p.steps, p.periods),
            "{label} {k}: the run changed with the backward travel"
        );
        for axis in 0..2 {
            let (a, b) = (g.displacement[axis], p.displacement[axis]);
            assert!(
                (a - b).abs() <= STEP_ROUNDING * b.abs() + 1e-18,
                "{label} {k} axis {axis}: travel {a:e} m with the backward travel, {b:e} m without"
            );
        }
        for axis in 0..2 {
            let d = (g.variation[axis] - want.variation[axis]).abs();
            assert!(
                d <= bar,
                "{label} {k} axis {axis}: backward travel {:e} m on the GPU, {:e} m on the CPU \
                 ({d:.2e} m apart)",
                g.variation[axis],
                want.variation[axis]
            );
            worst = worst.max(d);
        }
    }
    worst
}

/// lavapipe's f64 gives the CPU's backward travel within 1e-6 um per cycle
/// on every case, its steps those of a run without it, and travels back
/// where the CPU does (the bar is not met by zeros).
#[test]
fn the_shader_measures_the_backward_travel_as_the_cpu_does() {
    let Some(ctx) = f64_context() else {
        return;
    };
    let instances = cases();
    let options = BatchOptions::default();
    let got = gpu_batch(ctx, &instances, &backward(), Precision::F64, &options);
    let plain = gpu_batch(
        ctx,
        &instances,
        &Settings::default(),
        Precision::F64,
        &options,
    );
    let worst = check("batch", &instances, &got, &plain, BAR_M);
    eprintln!("largest backward-travel difference: {worst:.2e} m");
    let back = got.iter().filter(|o| o.variation[0] > 1e-6).count();
    assert!(back >= instances.len() / 2, "{back} travel back: {got:?}");
    assert!(got.iter().all(|o| !o.finished_on_cpu && !o.cpu_fallback));
}

/// The CPU continues an instance the device left unfinished with the
/// lane's variation (a tail of one, forty periods long), and a slice so
/// long that llvmpipe's limiter cuts every dispatch short undoes each cut
/// iteration's variation with its state: the same backward travel.
#[test]
fn the_tail_and_cut_dispatches_keep_the_backward_travel() {
    let Some(ctx) = f64_context() else {
        return;
    };
    // As `gpu::the_slow_tail_of_a_batch_finishes_on_the_cpu`: one short
    // one is the rounds' pilot (the CPU's from its start), the long one
    // the tail the CPU continues.
    let mut instances = table1_cases();
    let mut long = paper_cases()[6];
    long.cycles = 40;
    instances.push(long);
    let settings = backward();
    let tail = BatchOptions {
        slice_iterations: 64,
        cpu_tail: Some(1),
        ..BatchOptions::default()
    };
    let got = gpu_batch(ctx, &instances, &settings, Precision::F64, &tail);
    let on_cpu: Vec<bool> = got.iter().map(|g| g.finished_on_cpu).collect();
    assert!(on_cpu[7], "{on_cpu:?}");
    assert_eq!(on_cpu.iter().filter(|&&c| c).count(), 2, "{on_cpu:?}");
    let plain = gpu_batch(ctx, &instances, &Settings::default(), Precision::F64, &tail);
    check("tail", &instances, &got, &plain, BAR_M);
    let cut = BatchOptions {
        slice_iterations: 1 << 20,
        ..BatchOptions::default()
    };
    let long_slices = gpu_batch(ctx, &instances, &settings, Precision::F64, &cut);
    check("cut", &instances, &long_slices, &plain, BAR_M);
}

/// A pipeline that measures the backward travel passes its self-test, and
/// fails it against a CPU variation moved past its allowance, naming it.
#[test]
fn a_backward_pipelines_self_test_checks_the_variation() {
    let Some(ctx) = f64_context() else {
        return;
    };
    ctx.self_test_backward_skewed(0.0)
        .expect("the self-test passes");
    let skew = 2.0 * pidm::gpu::BACKWARD_ALLOWANCE_M;
    let err = ctx
        .self_test_backward_skewed(skew)
        .expect_err("a skewed variation fails")
        .to_string();
    assert!(err.contains("backward travel"), "{err}");
}

/// `pidm run --backend gpu` of a backward scene whose first instance
/// splits into two replicas (100 V at 10 Hz against 60 V at 10 sqrt 2 Hz)
/// and whose second does not (both at 10 Hz): the split one runs its
/// group on the CPU, the CPU path's outcome bit for bit (Karnopp's device
/// groups merge no backward travel), the other on the device, within the
/// bar of the CPU's.
#[test]
fn a_split_instance_runs_its_group_on_the_cpu_beside_the_device() {
    use crate::common::run_maps;
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(
        dir.path().join("split.toml"),
        "name = \"split\"\n[axis.x]\nvoltage = 100\n\
         [axis.y]\nvoltage = 60\nfrequency = [14.142135623730951, 10.0]\n\
         [simulation]\nreplicas = 2\n[output]\nbackward = true\n",
    )
    .expect("written");
    let names = [
        "replicas",
        "step_x",
        "backward_x",
        "backward_y",
        "backward_ratio_y",
    ];
    let cpu = run_maps(dir.path(), "split.toml", "cpu", &names);
    let gpu = run_maps(dir.path(), "split.toml", "gpu", &names);
    assert_eq!(
        (cpu[0].clone(), gpu[0].clone()),
        (vec![2.0, 1.0], vec![2.0, 1.0])
    );
    for (k, name) in names.iter().enumerate().skip(1) {
        assert_eq!(
            gpu[k][0].to_bits(),
            cpu[k][0].to_bits(),
            "{name}: {gpu:?} {cpu:?}"
        );
        let bar = if name.contains("ratio") { 1e-6 } else { BAR_M };
        assert!(
            (gpu[k][1] - cpu[k][1]).abs() <= bar,
            "{name}: {gpu:?} {cpu:?}"
        );
    }
}
