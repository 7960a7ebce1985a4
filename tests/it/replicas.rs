//! Replicas (issue 39, `pidm::replicas`): one steady instance as several
//! trajectories whose faster drive starts at other phases, merged into one
//! estimate. `replicas = 1` is the run before replicas bit for bit; eight
//! replicas of a quasi-periodic instance agree with a long run in a
//! quarter of its periods; a periodic instance keeps its exact step; a
//! replica planted on another attractor is not merged, and the instance
//! is labelled multistable; an interrupted run resumes to the same map;
//! the GPU's groups give the CPU's values.

use std::process::{Command, Stdio};

use pidm::gpu::{BatchOptions, Precision};
use pidm::laws::status::STATUS_OK;
use pidm::laws::{Replica, Replicas, Settings};
use pidm::measurement::Measured;
use pidm::model::Instance;
use pidm::model::motion::Motion;
use pidm::replicas::{self, Group, cpu::run_group, cpu::run_replicas};

use crate::common::{manifest, pidm, s};
use crate::golden::{file_digests, golden_lines};
use crate::gpu::{context, f32_allowance, gpu_batch};
use crate::steady::{measure, quasi_periodic_reference, steady, step_um};

/// The quasi-periodic instance: 10 Hz against 10 sqrt 2 Hz at
/// 100 V, steady to 0.01 um within 20,000 periods.
fn quasi() -> Instance {
    steady(10.0, 10.0 * 2f64.sqrt(), 2, 1e-8, 20_000)
}

/// `count` replicas of `inst` on the CPU.
fn split_run(inst: &Instance, count: u32) -> (Measured, u32) {
    let settings = Settings {
        replicas: Replicas::Count(count),
        ..Settings::default()
    };
    let split = replicas::split_of(inst, &settings, count).expect("splittable");
    let run = run_group(inst, &settings, split, &|| false).expect("never stopped");
    (run.measured, run.replicas)
}

/// Asserts each axis of `got` [um] within 3 of its standard errors +
/// 0.002 um of `reference` [um].
fn covers(name: &str, inst: &Instance, got: &Measured, reference: [f64; 2]) {
    for (axis, b) in reference.into_iter().enumerate() {
        let a = step_um(inst, got, axis);
        let se = got.se[axis] * 1e6;
        eprintln!(
            "{name} axis {axis}: {a:+.5} +- {se:.5} um after {} periods; reference {b:+.5} um",
            got.periods
        );
        assert!(
            (a - b).abs() <= 3.0 * se + 0.002,
            "{name} axis {axis}: {a} +- {se} um against {b} um"
        );
    }
}

#[test]
fn eight_replicas_cover_a_long_run_in_a_quarter_of_its_periods() {
    let inst = quasi();
    let alone = measure(&inst);
    assert_eq!(alone.motion, Motion::QuasiPeriodic, "{alone:?}");
    let (merged, count) = split_run(&inst, 8);
    assert_eq!(count, 8);
    assert_eq!(merged.status, STATUS_OK, "{merged:?}");
    assert_eq!(merged.motion, Motion::QuasiPeriodic, "{merged:?}");
    // Each replica settles on its own: the quarter is of the periods
    // measured.
    let measured = |periods: u32| periods - inst.settle;
    assert!(
        measured(merged.periods) * 4 <= measured(alone.periods),
        "{} periods per replica, {} alone",
        merged.periods,
        alone.periods
    );
    assert!(merged.se.iter().all(|&se| se <= 1e-8 * (1.0 + 1e-12)));
    covers("8 replicas", &inst, &merged, quasi_periodic_reference());
}

/// 21.34 and 23.66 Hz repeat after 1067 periods, which the run alone
/// finds by its recurrence test after settle + 1067. Four replicas make a
/// cycle split: pieces of 266-267 periods, each from rest at the drives'
/// phases of its first period, joined end to start within the recurrence
/// test's tolerances. The motion is the run alone's (periodic, the same
/// lag, no standard error), its step the same to far below the maps'
/// 0.002 um, in a quarter of the periods.
#[test]
fn a_periodic_instance_keeps_its_exact_step() {
    let inst = steady(21.34, 23.66, 2, 1e-8, 10_000);
    let alone = measure(&inst);
    assert_eq!(alone.motion, Motion::Periodic, "{alone:?}");
    let (merged, count) = split_run(&inst, 4);
    assert_eq!(count, 4, "{merged:?}");
    assert_eq!(
        (merged.motion, merged.lag, merged.se, merged.status),
        (alone.motion, alone.lag, [0.0; 2], STATUS_OK)
    );
    let measured = |periods: u32| periods - inst.settle;
    assert_eq!(measured(merged.periods), 1067_u32.div_ceil(4));
    for axis in 0..2 {
        let (a, b) = (step_um(&inst, &merged, axis), step_um(&inst, &alone, axis));
        eprintln!("axis {axis}: joined {a:+.12} um, alone {b:+.12} um");
        assert!((a - b).abs() <= 1e-6, "axis {axis}: {a} um against {b} um");
    }
}

/// A cycle split whose pieces do not join (one planted on another
/// attractor, its y drive at -100 V) is given up: the instance's own run
/// is kept bit for bit, unlabelled, since a join that fails may as well be
/// a piece not yet settled.
#[test]
fn a_cycle_split_that_does_not_join_runs_alone() {
    let inst = steady(21.34, 23.66, 2, 1e-8, 10_000);
    let settings = Settings {
        replicas: Replicas::Count(4),
        ..Settings::default()
    };
    let split = replicas::split_of(&inst, &settings, 4).unwrap();
    assert_eq!((split.count, split.cycle), (4, 1067), "{split:?}");
    let group = Group::new(&inst, &settings, split);
    assert!(group.is_cycle());
    let mut planted = group.replicas();
    planted[1].0.axes[1].voltage = -100.0;
    let run = run_replicas(&inst, &settings, &group, &planted, &|| false).unwrap();
    assert_eq!(run.replicas, 1, "{run:?}");
    assert_eq!(run.measured, measure(&inst));
    assert_eq!(run.measured.motion, Motion::Periodic);
}

/// One replica planted on another attractor (its y drive at -100 V: its y
/// steps run the other way): its own estimate disagrees with the merged
/// one, the group is not merged, and the instance's own run is kept and
/// labelled multistable.
#[test]
fn a_replica_on_another_attractor_is_not_merged() {
    let inst = quasi();
    let settings = Settings {
        replicas: Replicas::Count(4),
        ..Settings::default()
    };
    let split = replicas::split_of(&inst, &settings, 4).unwrap();
    let group = Group::new(&inst, &settings, split);
    let mut planted = group.replicas();
    planted[2].0.axes[1].voltage = -100.0;
    let run = run_replicas(&inst, &settings, &group, &planted, &|| false).unwrap();
    assert_eq!(run.replicas, 1);
    assert_eq!(run.measured.motion, Motion::Multistable);
    assert!(
        run.disagreement > replicas::group::DISAGREEMENT_Z,
        "{run:?}"
    );
    let alone = measure(&inst);
    assert_eq!(run.measured.travel, alone.travel);
    assert_eq!(run.measured.se, alone.se);
    // Unplanted, the same group merges.
    let merged = run_replicas(&inst, &settings, &group, &group.replicas(), &|| false).unwrap();
    assert_eq!(merged.replicas, 4);
    assert_eq!(merged.measured.motion, Motion::QuasiPeriodic);
    assert!(
        merged.disagreement <= replicas::group::DISAGREEMENT_Z,
        "{merged:?}"
    );
}

/// `tests/golden/replicas_one.toml` with `replicas = 1` gives the digests
/// the binary before replicas wrote, on the CPU and on the GPU in f64 (since
/// issue 47 changed the integrator's steps, the digests of the binary that
/// changed them: tests/golden/write_goldens.sh).
#[test]
fn one_replica_is_the_run_before_replicas_bit_for_bit() {
    let golden = std::fs::read_to_string(manifest("tests/golden/replicas_one.txt")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(manifest("tests/golden/replicas_one.toml")).unwrap();
    let scene = dir.path().join("replicas_one.toml");
    std::fs::write(&scene, format!("{text}replicas = 1\n")).unwrap();
    let mut runs = vec![("cpu_f64_steady", "cpu")];
    if context().is_some() {
        runs.push(("gpu_f64_steady", "gpu"));
    }
    for (label, backend) in runs {
        let out = dir.path().join(format!("{label}.h5"));
        let args = ["run", s(&scene), "--backend", backend, "--precision", "f64"];
        let run = pidm(&[&args[..], &["--out", s(&out)]].concat(), dir.path());
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let file = hdf5::File::open(&out).unwrap();
        let mut got = file_digests(&file);
        let ones: Vec<u32> = file.dataset("maps/replicas").unwrap().read_raw().unwrap();
        assert_eq!(ones, [1, 1], "{label}");
        got.retain(|g| g.0 != "/maps/replicas");
        assert_eq!(got, golden_lines(&golden, label), "{label}");
    }
}

/// A CPU run of few instances (a chunk of one: both threads on its
/// replicas) stopped with Ctrl-C while a group runs leaves no file, and
/// its resume writes the uninterrupted run's map.
#[test]
fn an_interrupted_run_with_replicas_resumes_to_the_same_map() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("split.toml");
    std::fs::write(
        &scene,
        "name = \"split\"\n[simulation]\nmeasure = \"steady\"\nreplicas = 2\n\
         [axis.x]\nvoltage = 100.0\nfrequency = 10.0\n\
         [axis.y]\nvoltage = 100.0\nfrequency = { from = 13.1421356, to = 14.1421356, steps = 4 }\n",
    )
    .unwrap();
    let run = |out: &std::path::Path, resume: bool| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_pidm"));
        command
            .args(["run", s(&scene), "--out", s(out), "--backend", "cpu"])
            .args(["--threads", "2", "--chunk-size", "1"])
            .current_dir(d)
            .env("HDF5_USE_FILE_LOCKING", "FALSE")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        if resume {
            command.arg("--resume");
        }
        command.spawn().unwrap()
    };
    let whole = d.join("whole.h5");
    let done = run(&whole, false).wait_with_output().unwrap();
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let replicas: Vec<u32> = hdf5::File::open(&whole)
        .unwrap()
        .dataset("maps/replicas")
        .unwrap()
        .read_raw()
        .unwrap();
    assert!(replicas.contains(&2), "{replicas:?}");

    let out = d.join("split.h5");
    let checkpoint = d.join(".split.h5.checkpoint");
    let ended = crate::common::interrupt_after_first_chunk(run(&out, false), &checkpoint);
    let err = String::from_utf8_lossy(&ended.stderr);
    assert_eq!(ended.status.code(), Some(130), "the run ended first: {err}");
    assert!(!out.exists());
    let resumed = run(&out, true).wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{err}");
    assert!(err.contains("resuming from"), "{err}");
    pidm::output::compare_contents(&whole, &out).unwrap();
}

/// The GPU's groups against the CPU's, four replicas each (two phase
/// splits and a cycle split): f64 merges the same windows and joins the
/// same pieces (the same periods and kinds of motion, values within the
/// f64 shader's rounding of the CPU's); f32 merges its phase splits too
/// (issue 47), within the CPU's errors and f32's allowance, and a cycle
/// split's pieces join or the instance runs alone.
#[test]
fn the_gpu_merges_replicas_as_the_cpu_does() {
    let Some(ctx) = context() else {
        return;
    };
    let (instances, settings, cpu) = groups_on_the_cpu();
    for precision in crate::gpu::precisions(ctx) {
        let gpu = gpu_batch(
            ctx,
            &instances,
            &settings,
            precision,
            &BatchOptions::default(),
        );
        for (k, (inst, (c, g))) in instances.iter().zip(cpu.iter().zip(&gpu)).enumerate() {
            against_the_cpu(&format!("{precision} #{k}"), precision, inst, c, g);
        }
    }
}

/// Three instances split four ways on the GPU's groups' tests (two phase
/// splits and a cycle split), the settings, and each one's group run on
/// the CPU with the replicas it made.
fn groups_on_the_cpu() -> ([Instance; 3], Settings, Vec<(Measured, u32)>) {
    let instances = [
        steady(10.0, 10.0 * 2f64.sqrt(), 2, 1e-8, 20_000),
        steady(10.0, 10.0 * 3f64.sqrt(), 2, 3e-8, 20_000),
        steady(21.34, 23.66, 2, 1e-8, 10_000),
    ];
    let settings = Settings {
        replicas: Replicas::Count(4),
        ..Settings::default()
    };
    let cpu: Vec<(Measured, u32)> = instances
        .iter()
        .map(|inst| {
            let split = replicas::split_of(inst, &settings, 4).expect("splits");
            let run = run_group(inst, &settings, split, &|| false).unwrap();
            (run.measured, run.replicas)
        })
        .collect();
    assert_eq!(
        cpu.iter().map(|c| c.1).collect::<Vec<_>>(),
        [4, 4, 4],
        "{cpu:?}"
    );
    (instances, settings, cpu)
}

/// A GPU outcome `g` of `inst` against its CPU group `(c, count)`: in f64
/// the same replicas, periods, kind of motion and status, each step
/// within 1e-6 um (the f64 shader's rounding); in f32 within the CPU's
/// errors and f32's allowance, from as many replicas where a phase split
/// merges (a cycle split's f32 pieces may not join: then one run alone).
fn against_the_cpu(
    name: &str,
    precision: Precision,
    inst: &Instance,
    (c, count): &(Measured, u32),
    g: &pidm::gpu::GpuOutcome,
) {
    eprintln!("{name}: cpu {c:?} x {count}, gpu {g:?}");
    for axis in 0..2 {
        let a = inst.measure_over(axis, g.displacement[axis], g.span).1 * 1e6;
        let b = step_um(inst, c, axis);
        let allowed = match precision {
            Precision::F64 => 1e-6,
            Precision::F32 => 3.0 * c.se[axis] * 1e6 + f32_allowance(b),
        };
        assert!(
            (a - b).abs() <= allowed,
            "{name} axis {axis}: {a} um, cpu {b} um"
        );
    }
    match precision {
        Precision::F64 => assert_eq!(
            (g.replicas, g.periods, g.motion, g.status),
            (*count, c.periods, c.motion, c.status),
            "{name}"
        ),
        Precision::F32 if c.lag > 0 => {
            assert!(g.replicas == 1 || g.replicas == *count, "{name}")
        }
        Precision::F32 => assert_eq!(g.replicas, *count, "{name}"),
    }
}

/// Groups on fewer lanes than jobs (12 jobs on 5 lanes: replicas queued
/// again at every merge, lanes taking them as others free) merge and join
/// as on the CPU, whether the device runs every group to its end or hands
/// the groups left to the CPU once its queue is empty
/// (`BatchOptions::cpu_tail`): the same replicas, periods and kinds of
/// motion, values within the f64 shader's rounding of the CPU's. Before
/// the shader handed a finished instance over after its loop too, the loop
/// limiter could leave a replica on its lane while its group queued it
/// again, and two lanes ran it (the 6 x 6 map: 1,588 slices with a job on
/// two lanes).
#[test]
fn queued_replicas_and_the_cpu_tail_merge_as_the_cpu_does() {
    let Some(ctx) = context() else {
        return;
    };
    let (instances, settings, cpu) = groups_on_the_cpu();
    for tail in [0, 1000] {
        let options = BatchOptions {
            lanes: Some(5),
            cpu_tail: Some(tail),
            ..BatchOptions::default()
        };
        let gpu = gpu_batch(ctx, &instances, &settings, Precision::F64, &options);
        // The handover waits for an empty queue: with 12 jobs on 5 lanes,
        // once the first groups have ended.
        let handed = gpu.iter().filter(|g| g.finished_on_cpu).count();
        assert_eq!(handed > 0, tail > 0, "tail {tail}: {handed} handed over");
        for (k, (inst, (c, g))) in instances.iter().zip(cpu.iter().zip(&gpu)).enumerate() {
            against_the_cpu(&format!("tail {tail} #{k}"), Precision::F64, inst, c, g);
        }
    }
}

/// The split follows the setting: a count of one never splits, `auto`
/// splits only where workers are free, a window never.
#[test]
fn only_steady_instances_with_free_workers_split() {
    let inst = quasi();
    let auto = Settings {
        replicas: Replicas::Auto,
        ..Settings::default()
    };
    let one = Settings::default();
    assert_eq!(one.replicas, Replicas::Count(1));
    let count =
        |settings: &Settings, workers, jobs| replicas::count(settings.replicas, workers, jobs);
    assert_eq!(replicas::split_of(&inst, &one, count(&one, 16, 1)), None);
    assert_eq!(count(&auto, 16, 1), replicas::MAX_AUTO);
    assert_eq!(count(&auto, 16, 16), 1);
    assert_eq!(count(&auto, 16, 5), 3);
    let split: Option<Replica> = replicas::split_of(&inst, &auto, 3);
    assert!(
        split.is_some_and(|r| (2..=3).contains(&r.count)),
        "{split:?}"
    );
    let window = crate::steady::window(&inst, 100);
    assert_eq!(replicas::split_of(&window, &auto, 8), None);
}

/// Issue 58: a steady LuGre map of both drive frequencies (x at 7.13 and
/// 13.1 Hz, y at 9.71 and 17.3 Hz, 100 V each) makes replicas, phase
/// splits only (`Law::splits_by_cycle`), and holds its values within 3 of
/// their standard errors + 0.002 um of the map with `replicas = 1`: on
/// the CPU, and under the GPU backend in f64, whose LuGre lanes run no
/// group merges, so its split instances run their groups on the CPU's
/// threads (marked on the CPU) and the rest on the device.
#[test]
fn lugre_maps_make_replicas_that_hold_their_values() {
    use pidm::backend::{Backend, CpuBackend, GpuBackend};
    use pidm::measurement::Outcome;
    let scene = |replicas: u32| {
        pidm::scene::Scene::from_toml(
            &format!(
                "name = \"lugre_replicas\"\n[mechanism]\nfriction = \"lugre\"\n\
                 [axis.x]\nvoltage = 100.0\nfrequency = [7.13, 13.1]\n\
                 [axis.y]\nvoltage = 100.0\nfrequency = [9.71, 17.3]\n\
                 [simulation]\nreplicas = {replicas}\n"
            ),
            None,
        )
        .unwrap()
    };
    let (one, four) = (scene(1), scene(4));
    let instances: Vec<Instance> = (0..4).map(|k| one.instance(k)).collect();
    let cpu = CpuBackend::new(None).unwrap();
    let alone = cpu.run(&instances, &one.settings, &|_| {}).unwrap();
    let holds = |name: &str, got: &[Outcome]| {
        for (k, inst) in instances.iter().enumerate() {
            let (a, b) = (&got[k], &alone[k]);
            assert_eq!((a.status, b.status), (STATUS_OK, STATUS_OK), "{name} #{k}");
            for axis in 0..2 {
                let (x, y) = (a.step(inst, axis) * 1e6, b.step(inst, axis) * 1e6);
                let se = a.se[axis].max(b.se[axis]) * 1e6;
                assert!(
                    (x - y).abs() <= 3.0 * se + 0.002,
                    "{name} #{k} axis {axis}: {x} against {y} +- {se} um"
                );
            }
        }
        let split = got.iter().filter(|o| o.replicas > 1).count();
        assert!(split >= 1, "{name}: no instance made replicas");
        split
    };
    let split = cpu.run(&instances, &four.settings, &|_| {}).unwrap();
    holds("cpu", &split);
    let Some(ctx) = context() else {
        return;
    };
    if !ctx.supports_f64() {
        return;
    }
    let gpu = GpuBackend::new(pidm::gpu::GpuContext::new(true).unwrap(), Precision::F64).unwrap();
    let on_gpu = gpu.run(&instances, &four.settings, &|_| {}).unwrap();
    holds("gpu", &on_gpu);
    for (k, (g, c)) in on_gpu.iter().zip(&split).enumerate() {
        if g.replicas > 1 {
            assert!(g.on_cpu, "#{k}: a LuGre group runs on the CPU's threads");
            assert_eq!(g.displacement, c.displacement, "#{k}: the CPU's group");
        }
    }
}
