//! `pidm accuracy`: the work-precision study of each scene, its files and
//! its report.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::scenes::{DEFAULT_SCENE, load_scenes, scene_integrations};
use crate::backend::{GpuBackend, Precision};
use crate::model::{Instance, Measure};

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
    // The command that regenerates this report, every option spelled out.
    let mut command: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    let steps: Vec<String> = karnopp_steps.iter().map(|h| format!("{h:e}")).collect();
    command.push(format!("--karnopp-steps {}", steps.join(",")));
    if gpu {
        command.push("--gpu".into());
    }
    command.push(format!("--out-dir {}", out_dir.display()));
    let mut report = Report::new(&command.join(" "));
    let mut limit_done = false;
    for scene in load_scenes(paths)? {
        let measured = scene_integrations(&scene);
        // The integrator is studied over the paper's fixed window (10
        // periods, 2 discarded), whatever the scene measures: the
        // fixed-step Karnopp baseline has no steady stop, and a window
        // isolates the integration error from the measurement's.
        let instances: Vec<Instance> = measured
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
            .collect();
        let reference = crate::laws::karnopp::integrate::Settings {
            tolerance: 1e-9,
            ..scene.settings
        };
        let lugre = scene.is_lugre();
        let mut methods = vec![accuracy::cpu_method(scene.settings, lugre)];
        if gpu && lugre {
            // The LuGre shader is f64's only.
            match crate::gpu::GpuContext::new(true) {
                Ok(ctx) if ctx.supports_f64() => methods.push(accuracy::backend_method(
                    Box::new(GpuBackend::new(ctx, Precision::F64)?),
                    scene.settings,
                    true,
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
                        false,
                    ));
                    if f64_ok {
                        let ctx = crate::gpu::GpuContext::new(true)?;
                        methods.push(accuracy::backend_method(
                            Box::new(GpuBackend::new(ctx, Precision::F64)?),
                            scene.settings,
                            false,
                        ));
                    }
                }
                Err(err) => println!("  gpu: not studied ({err})"),
            }
        }
        if !lugre {
            methods.push(accuracy::karnopp_method(karnopp_steps.to_vec()));
        }
        println!(
            "accuracy: scene {:?}, {} integrations, reference tolerance 1e-9 {}",
            scene.name,
            instances.len(),
            if lugre {
                "(LuGre: 1e-16 m local error per step)"
            } else {
                "rad"
            }
        );
        let (points, references) = study_and_print(&instances, &instances, reference, &methods)?;
        let h5 = out_dir.join(format!("accuracy_{}.h5", scene.name));
        let png = out_dir.join(format!("accuracy_{}.png", scene.name));
        accuracy::write_hdf5(&h5, &scene.name, &points)?;
        accuracy::plot(
            &png,
            &format!("scene {}: error against run time", scene.name),
            &points,
        )?;
        println!("  wrote {} and {}", h5.display(), png.display());
        report.add_scene(&scene.name, instances.len(), references, &methods, &points);
        if lugre {
            // The limit replaces the bristles' parameters: one study of it,
            // on the first LuGre scene, is all there is to see.
            if !limit_done {
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
            // periods, minutes per instance under LuGre: Karnopp's scenes
            // study the estimator, which is the same for both laws.
            continue;
        }
        // The measurement, where two drive frequencies make it matter.
        if accuracy::has_two_frequencies(&instances) {
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
            let long = accuracy::measurement_reference(&instances);
            let (points, references) =
                study_and_print(&instances, &long, scene.settings, &methods)?;
            let h5 = out_dir.join(format!("accuracy_{}_measure.h5", scene.name));
            let png = out_dir.join(format!("accuracy_{}_measure.png", scene.name));
            accuracy::write_hdf5(&h5, &scene.name, &points)?;
            accuracy::plot(
                &png,
                &format!("scene {}: measurement error against run time", scene.name),
                &points,
            )?;
            println!("  wrote {} and {}", h5.display(), png.display());
            report.add_measurement(&scene.name, instances.len(), references, &methods, &points);
        }
    }
    let out = report.write(out_dir)?;
    println!("wrote {}", out.display());
    Ok(())
}

/// Runs one study and prints its points as they come.
fn study_and_print(
    instances: &[Instance],
    reference_instances: &[Instance],
    reference: crate::laws::karnopp::integrate::Settings,
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
    settings: crate::laws::karnopp::integrate::Settings,
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
