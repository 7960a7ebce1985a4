//! The shader's variants (issue 38): a pipeline carries the steady
//! measurement, the phase ladder and the load terms only where a batch's
//! instances use them. What a variant leaves out changes no outcome of the
//! instances it runs (bit for bit against the whole shader); a batch never
//! runs on a variant without a part it needs; and a scene's run prepares
//! the variant of what it uses up front.

use pidm::gpu::{
    BatchOptions, GpuContext, GpuOutcome, Parts, Precision, Variant, create_pipeline,
    execute_gpu_inner,
};
use pidm::laws::Settings;
use pidm::model::Instance;
use pidm::scene::Scene;

use crate::gpu::{context, precisions};

/// Windows, and steady measurements with and without the phase ladder,
/// each unloaded and under a load.
fn instances() -> Vec<Instance> {
    let mut windows: Vec<Instance> = crate::common::reference_cases()
        .into_iter()
        .map(|(_, inst, _)| inst)
        .take(5)
        .collect();
    windows.extend(pidm::model::random::random_instances(21, 4, 2, 1));
    let steady = crate::common::steady_instances();
    // 10 Hz against 10 sqrt(3) Hz: quasi-periodic, the ladder on.
    let mut ladder = steady[6];
    ladder.cycles = 300;
    let mut out = windows;
    out.extend([steady[2], steady[3], steady[7], ladder]);
    // A window, a steady run and the ladder's under a slew-limited
    // trapezoid on x (the waveform part).
    let shaped: Vec<Instance> = [out[0], steady[2], ladder]
        .into_iter()
        .map(|mut inst| {
            let x = &mut inst.axes[0];
            x.shape = pidm::model::Shape::Trapezoid;
            [x.rise, x.hold, x.fall] = [0.9, 0.03, 0.02];
            x.slew_rate = 3e4;
            inst
        })
        .collect();
    out.extend(shaped);
    let loaded = crate::common::loaded(&out, 5);
    out.extend(loaded);
    out
}

/// The outcomes of `instances` on a pipeline of `parts` compiled here.
fn on_variant(
    ctx: &GpuContext,
    parts: Parts,
    precision: Precision,
    instances: &[Instance],
) -> Result<Vec<GpuOutcome>, pidm::gpu::GpuError> {
    let options = BatchOptions {
        check: pidm::gpu::F32Check::Off,
        ..BatchOptions::default()
    };
    on_pipeline(ctx, ctx.variant(precision, parts), instances, &options)
}

/// The outcomes of `instances` on a pipeline of `variant` compiled here.
fn on_pipeline(
    ctx: &GpuContext,
    variant: Variant,
    instances: &[Instance],
    options: &BatchOptions,
) -> Result<Vec<GpuOutcome>, pidm::gpu::GpuError> {
    let pipeline = create_pipeline(ctx.device(), variant, None).unwrap();
    execute_gpu_inner(
        ctx.device(),
        ctx.queue(),
        (&pipeline, variant),
        ctx.limits(),
        instances,
        &Settings::default(),
        variant.precision,
        options,
        &mut |_, _| {},
    )
}

/// Every variant gives the instances it covers the whole shader's outcomes,
/// bit for bit (f64; in f32 the smallest variant).
#[test]
fn every_variant_gives_the_whole_shaders_outcomes_bit_for_bit() {
    let Some(ctx) = context() else {
        return;
    };
    let settings = Settings::default();
    let all = instances();
    let needs: Vec<Parts> = all.iter().map(|i| Parts::of(&[*i], &settings)).collect();
    // The instances cover every part.
    assert_eq!(
        needs.iter().fold(Parts::default(), |a, b| a.union(*b)),
        Parts::ALL
    );
    for precision in precisions(ctx) {
        let whole = on_variant(ctx, Parts::ALL, precision, &all).unwrap();
        let variants = match precision {
            Precision::F64 => Parts::every(),
            Precision::F32 => vec![Parts::default()],
        };
        for parts in variants {
            let covered: Vec<usize> = (0..all.len()).filter(|&k| parts.covers(needs[k])).collect();
            let instances: Vec<Instance> = covered.iter().map(|&k| all[k]).collect();
            let got = on_variant(ctx, parts, precision, &instances).unwrap();
            let want: Vec<GpuOutcome> = covered.iter().map(|&k| whole[k]).collect();
            assert_eq!(got, want, "{precision:?} {}", parts.name());
        }
    }
}

/// A batch takes a prepared pipeline that covers its parts, or prepares one
/// with them; a pipeline without a part a batch needs refuses the batch.
#[test]
fn a_batch_never_runs_on_a_variant_without_a_part_it_needs() {
    if context().is_none() {
        return;
    }
    let ctx = GpuContext::new(true).unwrap();
    let precision = *precisions(&ctx).last().unwrap();
    let settings = Settings::default();
    let all = instances();
    let window = &all[..3];
    let loaded = crate::common::loaded(window, 7);
    let steady = &all[9..11];
    ctx.prepare_parts(precision, Parts::default()).unwrap();
    let run = |instances: &[Instance]| {
        pidm::gpu::run_batch(&ctx, instances, &settings, precision, &mut |_, _| {}).unwrap()
    };
    run(window);
    let names = |ctx: &GpuContext| -> Vec<String> {
        ctx.prepared_variants()
            .iter()
            .filter(|v| v.precision == precision)
            .map(|v| v.parts.name())
            .collect()
    };
    assert_eq!(names(&ctx), ["window"]);
    run(&loaded);
    assert_eq!(names(&ctx), ["window", "window+load"]);
    run(steady);
    assert_eq!(names(&ctx), ["window", "window+load", "steady"]);
    // The window pipeline, handed a steady batch, refuses it.
    let err = on_variant(&ctx, Parts::default(), precision, steady).unwrap_err();
    assert!(
        err.to_string()
            .contains("cannot run instances that need steady"),
        "{err}"
    );
}

/// What a shipped scene's run prepares: a load map the load terms, a
/// two-frequency map the steady measurement and its ladder, a window map
/// nothing, a stall map the load it will search; trajectories are the
/// CPU's, so the paper scene's variant is its map's.
#[test]
fn each_scene_prepares_the_parts_it_uses() {
    let check = |path: &str, expected: Parts| {
        let scene = Scene::load(std::path::Path::new(&crate::common::manifest(path))).unwrap();
        let work = pidm::run::estimate::workload(&scene);
        assert_eq!(work.parts(), expected, "{path}");
    };
    let steady = Parts {
        steady: true,
        ..Parts::default()
    };
    check(
        "sweeps/load.toml",
        Parts {
            load: true,
            ..steady
        },
    );
    check(
        "sweeps/two_frequency.toml",
        Parts {
            phase: true,
            ..steady
        },
    );
    check("sweeps/coupling.toml", steady);
    check(
        "sweeps/stall.toml",
        Parts {
            load: true,
            ..steady
        },
    );
    check("sweeps/random.toml", Parts::default());
    // A window map whose trajectories add nothing to its variant.
    check("sweeps/paper.toml", Parts::default());
    let paper = Scene::load(std::path::Path::new(&crate::common::manifest(
        "sweeps/paper.toml",
    )))
    .unwrap();
    assert!(!paper.trajectories.is_empty());
}

/// The hardware variants (no loop-limiter checks, what a device runs) on
/// this adapter too, in slices short enough that lavapipe's loop limit
/// never cuts a lane (issue 57): in f64 each gives the outcomes of this
/// adapter's own variant of the same parts bit for bit, so the kernels a
/// device compiles run in CI.
#[test]
fn hardware_variants_give_this_adapters_outcomes() {
    let Some(ctx) = context() else {
        return;
    };
    if !precisions(ctx).contains(&Precision::F64) {
        return;
    }
    let settings = Settings::default();
    // Short runs: windows of 2 cycles, steady measurements cut at 6 (they
    // end "not steady", as deterministic as a steady end). With slices of
    // 200,000 iterations the limiter cuts the hardware variants' lanes and
    // their outcomes differ: the comparison can fail.
    let mut all = instances();
    for inst in &mut all {
        inst.cycles = inst.cycles.min(6);
    }
    let windows: Vec<Instance> = all
        .iter()
        .take(3)
        .map(|i| Instance { cycles: 2, ..*i })
        .collect();
    all.splice(0..3, windows);
    let needs: Vec<Parts> = all.iter().map(|i| Parts::of(&[*i], &settings)).collect();
    let options = BatchOptions {
        slice_iterations: 16,
        probe_iterations: 16,
        check: pidm::gpu::F32Check::Off,
        ..BatchOptions::default()
    };
    for parts in Parts::every() {
        let covered: Vec<Instance> = (0..all.len())
            .filter(|&k| needs[k] == parts)
            .map(|k| all[k])
            .collect();
        assert!(
            !covered.is_empty(),
            "no instance needs exactly {}",
            parts.name()
        );
        let run = |v: Variant| on_pipeline(ctx, v, &covered, &options).unwrap();
        let own = ctx.variant(Precision::F64, parts);
        let hardware = Variant {
            loop_limiter: false,
            ..own
        };
        assert_eq!(run(hardware), run(own), "{}", parts.name());
    }
}
