//! `pidm accuracy`: the work-precision study of each scene, its files and
//! its report.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::scenes::{DEFAULT_SCENE, load_scenes, scene_integrations};
use crate::backend::{GpuBackend, Precision};
use crate::laws::Law;
use crate::model::{Instance, Measure};
use crate::scene::Scene;

/// The steady measurement's `max_cycles` in the measurement study: twice
/// the default, so that the error of a run stopped by its tolerance shows
/// rather than the cap (issue 31 judged its estimator at 20,000).
const ACCURACY_MAX_CYCLES: u32 = 20_000;

/// `pidm accuracy`: the work-precision study of each scene, written to
/// `out_dir` as `accuracy_<name>.h5` and `.png`, and summarised in
/// `accuracy.md`.
pub fn accuracy(paths: &[PathBuf], out_dir: &Path, karnopp_steps: &[f64], gpu: bool) -> Result<()> {
    use crate::accuracy::{self, Report};
    let defaults = [PathBuf::from(DEFAULT_SCENE)];
    let paths = if paths.is_empty() {
        &defaults[..]
    } else {
        paths
    };
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    let mut report = Report::new(&regenerating_command(paths, out_dir, karnopp_steps, gpu));
    let mut limit_done = false;
    for scene in load_scenes(paths)? {
        let instances = window_instances(&scene_integrations(&scene));
        let methods = integrator_methods(&scene, karnopp_steps, gpu)?;
        study_integrator(&scene, &instances, &methods, out_dir, &mut report)?;
        if scene.law() != Law::default() {
            // The limit replaces the law's own parameters: one study of it,
            // on the first scene of a law with a limit, is all there is to
            // see.
            if !limit_done && scene.law().limit().is_some() {
                karnopp_limit(
                    &scene.name,
                    &instances,
                    scene.settings,
                    out_dir,
                    &mut report,
                )?;
                limit_done = true;
            }
            // The measurement's study needs windows of up to 40,000
            // periods, minutes per instance under LuGre: the default law's
            // scenes study the estimator, which is the same for every law.
            continue;
        }
        // The measurement, where two drive frequencies make it matter.
        if accuracy::has_two_frequencies(&instances) {
            study_measurement(&scene, &instances, out_dir, &mut report)?;
        }
    }
    let out = report.write(out_dir)?;
    println!("wrote {}", out.display());
    Ok(())
}

/// The command that regenerates the report, every option spelled out.
fn regenerating_command(
    paths: &[PathBuf],
    out_dir: &Path,
    karnopp_steps: &[f64],
    gpu: bool,
) -> String {
    let mut command: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    let steps: Vec<String> = karnopp_steps.iter().map(|h| format!("{h:e}")).collect();
    command.push(format!("--karnopp-steps {}", steps.join(",")));
    if gpu {
        command.push("--gpu".into());
    }
    command.push(format!("--out-dir {}", out_dir.display()));
    command.join(" ")
}

/// The instances as the integrator is studied: over the paper's fixed
/// window (10 periods, 2 discarded), whatever the scene measures. The
/// fixed-step Karnopp baseline has no steady stop, and a window isolates
/// the integration error from the measurement's.
fn window_instances(measured: &[Instance]) -> Vec<Instance> {
    measured
        .iter()
        .map(|inst| match inst.measure {
            Measure::Window => *inst,
            Measure::Steady { .. } => Instance {
                cycles: Instance::TABLE1.cycles,
                settle: Instance::TABLE1.settle,
                measure: Measure::Window,
                ..*inst
            },
        })
        .collect()
}

/// The integration methods studied on a scene: the CPU's, the GPU's with
/// `--gpu` (LuGre's in f64 only, Karnopp's in every precision the adapter
/// offers; a line says why where none is studied), and Karnopp's
/// fixed-step baseline on Karnopp scenes.
fn integrator_methods<'a>(
    scene: &Scene,
    karnopp_steps: &[f64],
    gpu: bool,
) -> Result<Vec<crate::accuracy::Method<'a>>> {
    use crate::accuracy;
    let law = scene.law();
    let mut methods = vec![accuracy::cpu_method(scene.settings, law)];
    if gpu && law.no_f32().is_some() {
        // A law without f32 has an f64 shader only.
        match crate::gpu::GpuContext::new(true) {
            Ok(ctx) if ctx.supports_f64() => methods.push(accuracy::backend_method(
                Box::new(GpuBackend::new(ctx, Precision::F64)?),
                scene.settings,
                law,
            )),
            Ok(ctx) => println!("  gpu: not studied ({} offers no f64)", ctx.describe()),
            Err(err) => println!("  gpu: not studied ({err})"),
        }
    } else if gpu {
        // Every precision the adapter offers, software adapters included.
        match crate::gpu::GpuContext::new(true) {
            Ok(ctx) => {
                let f64_ok = ctx.supports_f64();
                methods.push(accuracy::backend_method(
                    Box::new(GpuBackend::new(ctx, Precision::F32)?),
                    scene.settings,
                    law,
                ));
                if f64_ok {
                    let ctx = crate::gpu::GpuContext::new(true)?;
                    methods.push(accuracy::backend_method(
                        Box::new(GpuBackend::new(ctx, Precision::F64)?),
                        scene.settings,
                        law,
                    ));
                }
            }
            Err(err) => println!("  gpu: not studied ({err})"),
        }
    }
    if let Some(run_fixed_step) = law.fixed_step_baseline() {
        methods.push(accuracy::fixed_step_method(
            run_fixed_step,
            karnopp_steps.to_vec(),
        ));
    }
    Ok(methods)
}

/// The integrator's study of a scene: each method's error against a
/// reference at tolerance 1e-9, printed, written, drawn and added to the
/// report.
fn study_integrator(
    scene: &Scene,
    instances: &[Instance],
    methods: &[crate::accuracy::Method],
    out_dir: &Path,
    report: &mut crate::accuracy::Report,
) -> Result<()> {
    let reference = crate::laws::Settings {
        tolerance: 1e-9,
        ..scene.settings
    };
    println!(
        "accuracy: scene {:?}, {} integrations, reference tolerance 1e-9 {}",
        scene.name,
        instances.len(),
        scene.law().tolerance_unit(reference.tolerance)
    );
    let (points, references) = study_and_print(instances, instances, reference, methods)?;
    write_study(
        out_dir,
        &format!("accuracy_{}", scene.name),
        &scene.name,
        &format!("scene {}: error against run time", scene.name),
        &points,
    )?;
    report.add_scene(&scene.name, instances.len(), references, methods, &points);
    Ok(())
}

/// The measurement's study of a scene with two drive frequencies: fixed
/// windows and steady runs against long windows or tight steady runs,
/// printed, written, drawn and added to the report.
fn study_measurement(
    scene: &Scene,
    instances: &[Instance],
    out_dir: &Path,
    report: &mut crate::accuracy::Report,
) -> Result<()> {
    use crate::accuracy;
    let methods = [
        accuracy::window_method(
            scene.settings,
            vec![10.0, 100.0, 300.0, 1000.0, 3000.0, 10_000.0],
        ),
        accuracy::steady_method(
            scene.settings,
            vec![1e-7, 3e-8, 1e-8, 3e-9],
            ACCURACY_MAX_CYCLES,
        ),
    ];
    println!(
        "accuracy: scene {:?}, the measurement: against lattice windows of at most {} \
         periods, or steady runs to {:e} m (at most {} periods) where the motion \
         repeats",
        scene.name,
        accuracy::REFERENCE_WINDOW,
        accuracy::MEASUREMENT_REFERENCE_TOLERANCE,
        accuracy::MEASUREMENT_REFERENCE_MAX_CYCLES
    );
    let long = accuracy::measurement_reference(instances);
    let (points, references) = study_and_print(instances, &long, scene.settings, &methods)?;
    write_study(
        out_dir,
        &format!("accuracy_{}_measure", scene.name),
        &scene.name,
        &format!("scene {}: measurement error against run time", scene.name),
        &points,
    )?;
    report.add_measurement(&scene.name, instances.len(), references, &methods, &points);
    Ok(())
}

/// Writes a study's points to `<stem>.h5` and draws them to `<stem>.png`
/// in `out_dir`, and says so.
fn write_study(
    out_dir: &Path,
    stem: &str,
    scene_name: &str,
    title: &str,
    points: &[crate::accuracy::Point],
) -> Result<()> {
    let h5 = out_dir.join(format!("{stem}.h5"));
    let png = out_dir.join(format!("{stem}.png"));
    crate::accuracy::write_hdf5(&h5, scene_name, points)?;
    crate::accuracy::plot(&png, title, points)?;
    println!("  wrote {} and {}", h5.display(), png.display());
    Ok(())
}

/// Runs one study and prints its points as they come.
fn study_and_print(
    instances: &[Instance],
    reference_instances: &[Instance],
    reference: crate::laws::Settings,
    methods: &[crate::accuracy::Method],
) -> Result<(Vec<crate::accuracy::Point>, crate::accuracy::References)> {
    use crate::accuracy::{self, Point, reference_note};
    println!(
        "  {:42} {:>10} {:>14} {:>14} {:>10}",
        "method", "setting", "max err [um]", "rms err [um]", "wall [s]"
    );
    let (points, references) = accuracy::study(
        instances,
        reference_instances,
        reference,
        methods,
        &mut |p: &Point| {
            println!(
                "  {:42} {:>10} {:>14.3e} {:>14.3e} {:>10.4}{}",
                p.method,
                accuracy::setting(p.setting),
                p.max_error_um,
                p.rms_error_um,
                p.wall_s,
                if p.failed > 0 {
                    format!("  ({} failed)", p.failed)
                } else {
                    String::new()
                }
            );
        },
    )?;
    let note = reference_note(references, instances.len());
    if !note.is_empty() {
        println!("  {note}");
    }
    Ok((points, references))
}

/// The Karnopp limit of a LuGre scene's instances (`accuracy::limit`):
/// printed, drawn and added to the report.
fn karnopp_limit(
    name: &str,
    instances: &[Instance],
    settings: crate::laws::Settings,
    out_dir: &Path,
    report: &mut crate::accuracy::Report,
) -> Result<()> {
    use crate::accuracy::{self, LIMIT_STRIBECK};
    println!(
        "accuracy: scene {name:?}, the Karnopp limit (stribeck_velocity {LIMIT_STRIBECK:e} m/s, \
         bristle_damping derived)"
    );
    let (karnopp, rows) = accuracy::karnopp_limit(instances, settings)?;
    for row in &rows {
        println!(
            "  sigma0 {:.0e} N/m: largest |LuGre - Karnopp| {:.3e} um, {:.4} s{}",
            row.bristle_stiffness,
            row.max_difference_um,
            row.wall_s,
            if row.failed > 0 {
                format!(" ({} failed)", row.failed)
            } else {
                String::new()
            }
        );
    }
    let png = out_dir.join(format!("accuracy_{name}_limit.png"));
    accuracy::plot_limit(&png, &format!("scene {name}: LuGre against Karnopp"), &rows)?;
    report.add_markdown(&accuracy::limit_markdown(name, &karnopp, &rows));
    println!("  wrote {}", png.display());
    Ok(())
}
