//! The lanes of a GPU batch (issue 38): after a first dispatch that starts
//! every instance, a few lanes work through the rest from a queue, dearest
//! first, and the busy ones are packed into fewer workgroups once the queue
//! is empty. Which lane runs an instance, and when, changes nothing of its
//! outcome: the refilled batch gives the outcomes of a lane per instance
//! bit for bit, in both precisions, steady and window, with f32's check,
//! with the CPU tail, and a run stopped mid-chunk resumes to the file of an
//! uninterrupted one. The lanes' tallies count what the CPU mirror does.

use std::process::{Command, Stdio};

use pidm::gpu::{BatchOptions, GpuContext, GpuOutcome, Order, Precision, run_batch_with};
use pidm::laws::Settings;
use pidm::laws::karnopp::integrate::constants::ITERATION_KINDS;
use pidm::laws::karnopp::integrate::{
    Coefficients, NoObserver, initial_state, is_finished, iterate,
};
use pidm::model::Instance;

use crate::common::s;
use crate::gpu::{context, precisions};

/// Windows (Table 1's cases), quick steady measurements (periodic at
/// ratios 1.5, 1.4 and 2, and a quasi-periodic one cut at 12 periods) and a
/// few random windows: instances of very different costs.
fn mixed() -> Vec<Instance> {
    let mut out: Vec<Instance> = crate::common::reference_cases()
        .into_iter()
        .map(|(_, inst, _)| inst)
        .take(7)
        .collect();
    let steady = crate::common::steady_instances();
    out.extend([steady[2], steady[3], steady[4], steady[7]]);
    out.extend(pidm::model::random::random_instances(5, 6, 3, 1));
    out
}

fn run(
    ctx: &GpuContext,
    instances: &[Instance],
    precision: Precision,
    options: BatchOptions,
) -> Vec<GpuOutcome> {
    run_batch_with(
        ctx,
        instances,
        &Settings::default(),
        precision,
        &options,
        &mut |_, _| {},
    )
    .expect("batch runs")
}

/// A lane per instance, as the dispatch was before the queue, against one
/// lane, three and five, in cost and index order, in short and default
/// slices: the same outcomes bit for bit (f32's check included).
#[test]
fn refilled_lanes_give_the_outcomes_of_a_lane_per_instance() {
    let Some(ctx) = context() else {
        return;
    };
    let instances = mixed();
    let n = instances.len();
    for precision in precisions(ctx) {
        let one_each = run(
            ctx,
            &instances,
            precision,
            BatchOptions {
                lanes: Some(n),
                order: Order::Index,
                ..BatchOptions::default()
            },
        );
        for (lanes, order, slice) in [
            (1, Order::Cost, pidm::gpu::SLICE_ITERATIONS),
            (3, Order::Cost, 7),
            (3, Order::Index, pidm::gpu::SLICE_ITERATIONS),
            (5, Order::Cost, 64),
        ] {
            let refilled = run(
                ctx,
                &instances,
                precision,
                BatchOptions {
                    lanes: Some(lanes),
                    order,
                    slice_iterations: slice,
                    ..BatchOptions::default()
                },
            );
            assert_eq!(
                refilled, one_each,
                "{precision:?}: {lanes} lanes, {order} order, slices of {slice}"
            );
        }
    }
}

/// Seven short instances and one forty periods long, the tail one
/// instance: on a lane each or on two lanes, in either order, the third
/// (the first the probe left unfinished) is the rounds' pilot and the long one the tail the CPU finishes, and
/// the outcomes agree bit for bit.
#[test]
fn the_cpu_tail_is_the_same_whichever_lanes_run_the_batch() {
    let Some(ctx) = context() else {
        return;
    };
    let mut instances: Vec<Instance> = crate::common::reference_cases()
        .into_iter()
        .map(|(_, inst, _)| inst)
        .collect();
    instances.truncate(7);
    let mut long = instances[6];
    long.cycles = 40;
    instances.push(long);
    for precision in precisions(ctx) {
        let options = |lanes: usize, order: Order| BatchOptions {
            lanes: Some(lanes),
            order,
            slice_iterations: 64,
            cpu_tail: Some(1),
            ..BatchOptions::default()
        };
        let one_each = run(ctx, &instances, precision, options(8, Order::Index));
        let on_cpu: Vec<bool> = one_each.iter().map(|o| o.finished_on_cpu).collect();
        assert_eq!(
            on_cpu,
            [false, false, true, false, false, false, false, true]
        );
        for order in [Order::Cost, Order::Index] {
            let two = run(ctx, &instances, precision, options(2, order));
            assert_eq!(two, one_each, "{precision:?}: two lanes, {order} order");
        }
    }
}

/// A tail of several instances, taken in rounds, is the same whichever
/// lanes run the batch and however its dispatches are cut: which instances
/// the CPU takes, and where, depends on their steps alone (issue 58: the
/// same command writes the same bits). Forty random windows, a tail of
/// two (a pilot of two sets the first cap, low enough for rounds), on one
/// lane each, on three and on seven lanes, in slices of 64 and 7
/// iterations.
#[test]
fn a_tail_taken_in_rounds_does_not_depend_on_the_lanes() {
    let Some(ctx) = context() else {
        return;
    };
    let instances = pidm::model::random::random_instances(23, 40, 2, 1);
    for precision in precisions(ctx) {
        let options = |lanes: usize, slice: u32| BatchOptions {
            lanes: Some(lanes),
            slice_iterations: slice,
            cpu_tail: Some(2),
            ..BatchOptions::default()
        };
        let one_each = run(ctx, &instances, precision, options(40, 64));
        let on_cpu = one_each.iter().filter(|o| o.finished_on_cpu).count();
        // The pilot (two) and a tail of one or two.
        assert!(
            (3..=4).contains(&on_cpu),
            "{precision:?}: {on_cpu} on the CPU"
        );
        for (lanes, slice) in [(3, 64), (7, 7)] {
            let other = run(ctx, &instances, precision, options(lanes, slice));
            assert_eq!(
                other, one_each,
                "{precision:?}: {lanes} lanes, slices of {slice}"
            );
        }
    }
}

/// Instance k's lane in the first dispatch counts, by kind, the iterations
/// the f64 CPU mirror makes of instance k in as many iterations (windows:
/// boundary, stick, slip, rejected trial, event location). Where lavapipe's
/// loop limiter ends a lane's dispatch early, the lane counts the
/// iterations it completed, and the mirror is held to as many.
#[test]
fn the_lanes_tallies_count_the_mirrors_iterations() {
    let Some(ctx) = context() else {
        return;
    };
    if !ctx.supports_f64() {
        return;
    }
    let mut instances: Vec<Instance> = crate::common::reference_cases()
        .into_iter()
        .map(|(_, inst, _)| inst)
        .take(7)
        .collect();
    instances.extend(pidm::model::random::random_instances(9, 8, 2, 1));
    let settings = Settings::default();
    let iterations = 300;
    let limiter = ctx
        .variant(Precision::F64, pidm::gpu::Parts::default())
        .loop_limiter;
    let tallies =
        pidm::gpu::karnopp::probes::f64_tallies_after(ctx, &instances, &settings, iterations)
            .unwrap();
    let mut kinds_seen = [0u64; ITERATION_KINDS];
    for (k, (inst, tally)) in instances.iter().zip(&tallies).enumerate() {
        let done = tally.passes();
        assert!(
            done == iterations as u64 || tally.held().is_none() || (limiter && done > 0),
            "instance {k}: {done} iterations"
        );
        let c = Coefficients::of(inst, &settings);
        let mut st = initial_state(&c);
        let mut counts = [0u64; ITERATION_KINDS];
        for _ in 0..done {
            assert!(!is_finished(&c, &st), "instance {k}");
            counts[iterate(&c, &mut st, &mut NoObserver) as usize] += 1;
        }
        assert_eq!(tally.by_kind(), counts, "instance {k}");
        // A lane the limiter stopped may still hold an instance that its
        // last iteration finished: the next dispatch lets it go.
        let cut = limiter && done < iterations as u64;
        assert!(
            tally.held().is_none() == is_finished(&c, &st) || cut,
            "instance {k}"
        );
        for (seen, count) in kinds_seen.iter_mut().zip(counts) {
            *seen += count;
        }
    }
    // Every kind but the steady measurement's period ends came up.
    assert!(kinds_seen[..5].iter().all(|&n| n > 0), "{kinds_seen:?}");
}

/// A run on few lanes (`PIDM_GPU_LANES=3`, chunks of 8) stopped with
/// Ctrl-C mid-chunk resumes to the file of an uninterrupted run on the
/// adapter's lanes, bit for bit.
#[test]
fn a_run_on_few_lanes_stopped_mid_chunk_resumes_to_the_uninterrupted_file() {
    if context().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("lanes.toml");
    std::fs::write(
        &scene,
        "name = \"lanes\"\n[simulation]\nmeasure = \"window\"\ncycles = 24\n\
         [axis.x]\nvoltage = { from = 40.0, to = 150.0, steps = 24 }\n\
         [axis.y]\nvoltage = 60.0\nfrequency = 13.7\n",
    )
    .unwrap();
    let run = |out: &std::path::Path, lanes: Option<&str>, resume: bool| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_pidm"));
        command
            .args(["run", s(&scene), "--out", s(out), "--backend", "gpu"])
            .args(["--chunk-size", "8"])
            .current_dir(d)
            .env("WGPU_BACKEND", "vulkan")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        if resume {
            command.arg("--resume");
        }
        if let Some(lanes) = lanes {
            command.env("PIDM_GPU_LANES", lanes);
        }
        command.spawn().unwrap()
    };
    let whole = d.join("whole.h5");
    let done = run(&whole, None, false).wait_with_output().unwrap();
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );

    let out = d.join("lanes.h5");
    let checkpoint = d.join(".lanes.h5.checkpoint");
    let ended =
        crate::common::interrupt_after_first_chunk(run(&out, Some("3"), false), &checkpoint);
    let err = String::from_utf8_lossy(&ended.stderr);
    assert_eq!(ended.status.code(), Some(130), "the run ended first: {err}");
    assert!(!out.exists());
    let resumed = run(&out, Some("3"), true).wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{err}");
    assert!(err.contains("resuming from"), "{err}");
    pidm::output::compare_contents(&whole, &out).unwrap();
}
