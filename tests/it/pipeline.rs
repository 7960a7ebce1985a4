//! The sweep's pipeline (issue 32): chunks that overlap (the backend on
//! chunk k while the driver writes chunk k-1 and expands chunk k+1) give
//! the same records bit for bit as chunks one after another, on every
//! backend and precision, steady and window, baselines shared across
//! chunks, and with the GPU's CPU tail; and a run stopped mid-pipeline
//! leaves no output file.

use std::process::{Command, Stdio};

use pidm::backend::{Backend, CpuBackend, GpuBackend, Precision};
use pidm::gpu::{BatchOptions, GpuContext};
use pidm::scene::Scene;
use pidm::sweep::{BaselineMemo, Plan, Record, Summary, run_chunks};

use crate::common::s;

/// A 5 x 5 voltage map with baselines and a non-round y frequency, steady
/// or in a window of 3 cycles.
fn scene(steady: bool) -> Scene {
    let measure = if steady {
        "[simulation]\nmax_cycles = 60\n"
    } else {
        "[simulation]\nmeasure = \"window\"\ncycles = 3\n"
    };
    let text = format!(
        "name = \"pipeline\"\n{measure}\
         [axis.x]\nvoltage = {{ from = -120.0, to = 120.0, steps = 5 }}\n\
         [axis.y]\nvoltage = {{ from = -100.0, to = 140.0, steps = 5 }}\nfrequency = 13.7\n\
         [output]\nbaselines = true\n"
    );
    Scene::from_toml(&text, None).unwrap()
}

/// Every record of a sweep in index order, and its summary.
fn sweep(
    scene: &Scene,
    backend: &dyn Backend,
    chunk: usize,
    overlap: bool,
) -> (Vec<Record>, Summary) {
    let instance = |i: u64| scene.instance(i);
    let plan = Plan {
        work: Plan::everything(scene.instance_count()),
        instance: &instance,
        settings: scene.settings,
        baselines: scene.baselines,
        verify: false,
    };
    let mut records = Vec::new();
    let summary = run_chunks(
        &plan,
        backend,
        chunk,
        &|_| {},
        &mut |start, chunk| {
            assert_eq!(start, records.len() as u64, "chunks arrive in order");
            records.extend_from_slice(chunk);
            Ok(())
        },
        &mut BaselineMemo::default(),
        overlap,
    )
    .unwrap();
    (records, summary)
}

/// One row: overlapping chunks against chunks one after another, the
/// records compared bit for bit (their Debug text tells -0 from 0).
fn check(label: &str, backend: &dyn Backend, steady: bool, chunk: usize) -> Summary {
    let scene = scene(steady);
    let (apart, _) = sweep(&scene, backend, chunk, false);
    let (overlapped, summary) = sweep(&scene, backend, chunk, true);
    assert_eq!(apart.len() as u64, scene.instance_count(), "{label}");
    for (k, (a, b)) in apart.iter().zip(&overlapped).enumerate() {
        assert_eq!(format!("{a:?}"), format!("{b:?}"), "{label}: instance {k}");
    }
    assert!(
        apart.iter().all(|r| r.status == 0 || r.status == 6),
        "{label}: {apart:?}"
    );
    // Baselines ran: the 1-DOF steps are there.
    assert!(apart.iter().any(|r| r.baseline_step[0] != 0.0), "{label}");
    summary
}

#[test]
fn overlapping_chunks_give_the_records_of_chunks_one_after_another_on_the_cpu() {
    for precision in [Precision::F64, Precision::F32] {
        let cpu = CpuBackend::with_precision(Some(2), precision).unwrap();
        for steady in [true, false] {
            for chunk in [1, 4, 7, 25] {
                check(
                    &format!("cpu {precision} steady {steady} chunk {chunk}"),
                    &cpu,
                    steady,
                    chunk,
                );
            }
        }
    }
}

#[test]
fn overlapping_chunks_give_the_records_of_chunks_one_after_another_on_the_gpu() {
    let Some(ctx) = crate::gpu::context() else {
        return;
    };
    for precision in [Precision::F64, Precision::F32] {
        if precision == Precision::F64 && !ctx.supports_f64() {
            continue;
        }
        for steady in [true, false] {
            // Small batches, few lanes and a CPU tail of two per batch: the
            // CPU finishes the slowest instances of every batch (from the
            // GPU's state in f64).
            let options = BatchOptions {
                max_batch: Some(5),
                lanes: Some(3),
                cpu_tail: Some(2),
                ..BatchOptions::default()
            };
            // The backend a run uses, on a context of its own: it packs
            // each chunk's coefficients ahead, on the driver thread.
            let device =
                GpuBackend::with_options(GpuContext::new(true).unwrap(), precision, options)
                    .unwrap();
            let label = format!("gpu {precision} steady {steady}");
            let summary = check(&label, &device, steady, 9);
            assert!(summary.on_cpu > 0, "{label}: no CPU tail");
        }
    }
}

/// Ctrl-C while the GPU integrates one chunk and the driver writes the one
/// before: exit status 130, no output file and no temporary file, the
/// finished chunks in the checkpoint.
#[test]
fn a_run_stopped_mid_pipeline_on_the_gpu_leaves_no_partial_file() {
    if crate::gpu::context().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("long.toml");
    std::fs::write(
        &scene,
        "name = \"long\"\n[simulation]\nmeasure = \"window\"\ncycles = 40\n\
         [axis.x]\nvoltage = { from = 40.0, to = 150.0, steps = 40 }\n\
         [axis.y]\nvoltage = 60.0\nfrequency = 13.7\n",
    )
    .unwrap();
    let out = d.join("long.h5");
    let checkpoint = d.join(".long.h5.checkpoint");
    let child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args([
            "run",
            s(&scene),
            "--out",
            s(&out),
            "--backend",
            "gpu",
            "--chunk-size",
            "2",
        ])
        .current_dir(d)
        .env("WGPU_BACKEND", "vulkan")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let ended = crate::common::interrupt_after_first_chunk(child, &checkpoint);
    let err = String::from_utf8_lossy(&ended.stderr);
    assert_eq!(ended.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(err.contains("--resume"), "{err}");
    assert!(!out.exists());
    assert!(checkpoint.exists());
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// `--profile` prints one table, whose driver phases and left-over line
/// add up to the process's wall time (to the table's rounding), with the
/// integrator's and writer's lines beside it.
#[test]
fn the_profile_table_accounts_for_the_wall_time() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("small.toml");
    std::fs::write(
        &scene,
        "name = \"small\"\n[axis.x]\nvoltage = { from = -150.0, to = 150.0, steps = 9 }\n\
         [axis.y]\nvoltage = { from = -150.0, to = 150.0, steps = 9 }\n\
         [output]\nbaselines = true\n",
    )
    .unwrap();
    let out = crate::common::pidm(
        &[
            "run",
            s(&scene),
            "--out",
            s(&d.join("small.h5")),
            "--backend",
            "cpu",
            "--chunk-size",
            "10",
            "--profile",
        ],
        d,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("phase table (driver").count(), 1, "{err}");
    // "pidm: phase <label> <seconds> s <share> %".
    let seconds = |line: &str| -> f64 {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let s = fields.iter().rposition(|f| *f == "s").expect(line);
        fields[s - 1].parse().expect(line)
    };
    let driver: Vec<&str> = err
        .lines()
        .skip_while(|l| !l.contains("phase table (driver"))
        .skip(1)
        .take_while(|l| !l.contains("wall time of the process"))
        .collect();
    let wall = err
        .lines()
        .find(|l| l.contains("wall time of the process"))
        .map(seconds)
        .expect("a wall-time line");
    assert_eq!(driver.len(), 9, "{err}");
    let sum: f64 = driver.iter().map(|l| seconds(l)).sum();
    assert!((sum - wall).abs() <= 0.006, "{sum} against {wall}: {err}");
    for beside in ["integrator thread, whole", "writer thread", "hidden behind"] {
        assert!(err.contains(beside), "{beside}: {err}");
    }
}
