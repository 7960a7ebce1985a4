//! `pidm accuracy`: a work-precision study. Every method runs the scene's
//! instances at a ladder of its accuracy setting; the error of the step maps
//! is measured against the f64 CPU path at a much tighter tolerance, and the
//! wall time on one thread is recorded. The fixed-step Karnopp integration
//! of the paper is included as a baseline, to show what locating mode
//! changes buys.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use plotters::prelude::*;

use crate::backend::{Backend, CpuBackend};
use crate::laws::status::STATUS_OK;
use crate::laws::{Law, Settings};
use crate::measurement::keeps_values;
use crate::model::{AXES, Instance};
use crate::sweep::Outcome;

mod limit;
mod measurement;
mod report;
pub use limit::{
    LIMIT_STIFFNESS, LIMIT_STRIBECK, LimitRow, karnopp_limit, limit_markdown, plot_limit,
};
pub use measurement::{
    MEASUREMENT_REFERENCE_MAX_CYCLES, MEASUREMENT_REFERENCE_TOLERANCE, REFERENCE_WINDOW,
    has_two_frequencies, lattice_length, measurement_reference, steady_method, window_method,
};
pub use report::{Report, reference_note, setting};

/// One method of the study and how to run it at a setting.
pub struct Method<'a> {
    /// Short name, e.g. "event-locating f64 (cpu)".
    pub name: String,
    /// What the setting means, e.g. "tolerance [rad]".
    pub setting_name: &'static str,
    /// The ladder, loosest first.
    pub settings: Vec<f64>,
    /// Runs every instance at one setting.
    #[allow(clippy::type_complexity)]
    pub run: Box<dyn Fn(&[Instance], f64) -> Result<Vec<Outcome>> + 'a>,
}

/// One measured point of the study.
#[derive(Clone, Debug)]
pub struct Point {
    pub method: String,
    pub setting: f64,
    /// Largest error of any step over all instances and axes [um].
    pub max_error_um: f64,
    /// Root mean square error over instances and axes [um].
    pub rms_error_um: f64,
    /// Wall time for all instances on one thread [s].
    pub wall_s: f64,
    /// Instances that did not finish normally ("not steady" ones among
    /// them: their values are compared too, as a map shows them).
    pub failed: usize,
    /// Scene periods integrated per compared instance, on average.
    pub periods: f64,
}

/// Steps [um] per instance and axis.
fn steps_um(instances: &[Instance], outcomes: &[Outcome]) -> Vec<[f64; AXES]> {
    instances
        .iter()
        .zip(outcomes)
        .map(|(inst, out)| {
            let mut s = [0.0; AXES];
            for (i, v) in s.iter_mut().enumerate() {
                *v = out.step(inst, i) * 1e6;
            }
            s
        })
        .collect()
}

/// The CPU integrator of `law` at a ladder of tolerances (each law's
/// tolerance means what [`Law::tolerance_setting`] says).
pub fn cpu_method<'a>(base: Settings, law: Law) -> Method<'a> {
    let backend = CpuBackend::new(Some(1)).expect("a one-thread pool");
    Method {
        name: format!("{} f64 (cpu)", law.integrator()),
        setting_name: law.tolerance_setting(),
        settings: vec![1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7],
        run: Box::new(move |instances, tolerance| {
            let settings = Settings { tolerance, ..base };
            backend.run(instances, &settings, &|_| {})
        }),
    }
}

/// A backend (the GPU path) at the same ladder of tolerances as the CPU,
/// named for the integrator of `law` that runs on it.
pub fn backend_method<'a>(backend: Box<dyn Backend + 'a>, base: Settings, law: Law) -> Method<'a> {
    Method {
        name: format!(
            "{} {} ({})",
            law.integrator(),
            backend.precision(),
            backend.describe()
        ),
        setting_name: law.tolerance_setting(),
        settings: vec![1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7],
        run: Box::new(move |instances, tolerance| {
            let settings = Settings { tolerance, ..base };
            backend.run(instances, &settings, &|_| {})
        }),
    }
}

/// A law's fixed-step baseline (`Law::fixed_step_baseline`: the paper's
/// Karnopp RK4) at a ladder of step sizes.
pub fn fixed_step_method<'a>(
    run_fixed_step: crate::laws::law::FixedStep,
    steps: Vec<f64>,
) -> Method<'a> {
    Method {
        name: "fixed-step Karnopp RK4 (paper's method)".into(),
        setting_name: "step [s]",
        settings: steps,
        run: Box::new(move |instances, step| {
            Ok(instances
                .iter()
                .map(|inst| {
                    let (displacement, steps) = run_fixed_step(inst, step);
                    Outcome {
                        displacement,
                        span: (inst.cycles - inst.settle) as f64,
                        periods: inst.cycles,
                        status: STATUS_OK,
                        steps: steps.min(u32::MAX as u64) as u32,
                        ..Outcome::default()
                    }
                })
                .collect())
        }),
    }
}

/// How the references of a study were obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct References {
    /// Instances whose reference needed a looser tolerance than asked (at
    /// the tightest tolerance a turn may be unresolvable: status 3).
    pub loosened: usize,
    /// Instances with no reference at any tolerance tried, left out of
    /// every comparison.
    pub excluded: usize,
}

/// How many times looser than asked, at most, a reference may be run for
/// an instance whose reference fails at the asked tolerance.
const REFERENCE_LOOSENINGS: [f64; 2] = [10.0, 100.0];

/// Runs the study. An instance whose reference run does not finish normally
/// is rerun 10 and then 100 times looser; one that fails at all three is
/// left out of every comparison. The returned counts say how many.
/// `reference_instances` are the instances as the reference measures them
/// (the instances themselves for a study of the integrator; long steady
/// runs for a study of the measurement).
pub fn study(
    instances: &[Instance],
    reference_instances: &[Instance],
    reference_settings: Settings,
    methods: &[Method],
    log: &mut dyn FnMut(&Point),
) -> Result<(Vec<Point>, References)> {
    let reference_backend = CpuBackend::new(None)?;
    let mut reference_outcomes =
        reference_backend.run(reference_instances, &reference_settings, &|_| {})?;
    let mut counts = References::default();
    for factor in REFERENCE_LOOSENINGS {
        let failed: Vec<usize> = (0..instances.len())
            .filter(|&k| reference_outcomes[k].status != STATUS_OK)
            .collect();
        if failed.is_empty() {
            break;
        }
        let retry: Vec<Instance> = failed.iter().map(|&k| reference_instances[k]).collect();
        let looser = Settings {
            tolerance: reference_settings.tolerance * factor,
            ..reference_settings
        };
        let outcomes = reference_backend.run(&retry, &looser, &|_| {})?;
        for (&k, outcome) in failed.iter().zip(outcomes) {
            if outcome.status == STATUS_OK {
                counts.loosened += 1;
            }
            reference_outcomes[k] = outcome;
        }
    }
    let excluded: Vec<bool> = reference_outcomes
        .iter()
        .map(|o| o.status != STATUS_OK)
        .collect();
    counts.excluded = excluded.iter().filter(|&&e| e).count();
    if counts.excluded == instances.len() {
        anyhow::bail!("no instance's reference run finished normally");
    }
    let reference = reference_outcomes;
    let reference = steps_um(instances, &reference);
    let mut points = Vec::new();
    for method in methods {
        for &setting in &method.settings {
            let started = Instant::now();
            let outcomes = (method.run)(instances, setting)?;
            let wall_s = started.elapsed().as_secs_f64();
            let got = steps_um(instances, &outcomes);
            let mut max: f64 = 0.0;
            let mut sum = 0.0;
            let mut n = 0;
            let mut failed = 0;
            let mut periods = 0.0;
            let mut compared = 0;
            for (k, (g, r)) in got.iter().zip(&reference).enumerate() {
                if excluded[k] {
                    continue;
                }
                periods += outcomes[k].periods as f64;
                compared += 1;
                // "Not steady" values are on the map: they are compared,
                // and counted as failed to converge.
                if outcomes[k].status != STATUS_OK {
                    failed += 1;
                }
                if !keeps_values(outcomes[k].status) {
                    continue;
                }
                for axis in 0..AXES {
                    let e = (g[axis] - r[axis]).abs();
                    max = max.max(e);
                    sum += e * e;
                    n += 1;
                }
            }
            let point = Point {
                method: method.name.clone(),
                setting,
                max_error_um: max,
                rms_error_um: (sum / n.max(1) as f64).sqrt(),
                wall_s,
                failed,
                periods: periods / compared.max(1) as f64,
            };
            log(&point);
            points.push(point);
        }
    }
    Ok((points, counts))
}

/// Writes the study's data to HDF5: one group per method with `setting`,
/// `max_error_um`, `rms_error_um`, `wall_s`, `failed` and `periods` (per
/// compared instance, on average).
pub fn write_hdf5(path: &Path, scene_name: &str, points: &[Point]) -> Result<()> {
    let temp = path.with_extension("h5.partial");
    {
        let file = hdf5::File::create(&temp)
            .with_context(|| format!("cannot create {}", temp.display()))?;
        let name: hdf5::types::VarLenUnicode = scene_name.parse().context("scene name")?;
        file.new_attr::<hdf5::types::VarLenUnicode>()
            .create("scene")?
            .write_scalar(&name)?;
        let mut methods: Vec<&str> = points.iter().map(|p| p.method.as_str()).collect();
        methods.dedup();
        for (m, method) in methods.iter().enumerate() {
            let group = file.create_group(&format!("method{m}"))?;
            let label: hdf5::types::VarLenUnicode = method.parse().context("method name")?;
            group
                .new_attr::<hdf5::types::VarLenUnicode>()
                .create("name")?
                .write_scalar(&label)?;
            let pts: Vec<&Point> = points.iter().filter(|p| p.method == *method).collect();
            let column = |f: &dyn Fn(&Point) -> f64| pts.iter().map(|p| f(p)).collect::<Vec<_>>();
            for (key, data) in [
                ("setting", column(&|p| p.setting)),
                ("max_error_um", column(&|p| p.max_error_um)),
                ("rms_error_um", column(&|p| p.rms_error_um)),
                ("wall_s", column(&|p| p.wall_s)),
                ("failed", column(&|p| p.failed as f64)),
                ("periods", column(&|p| p.periods)),
            ] {
                group.new_dataset_builder().with_data(&data).create(key)?;
            }
        }
        file.close()?;
    }
    std::fs::rename(&temp, path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// Error floor drawn for exact results on the log axis [um].
const PLOT_FLOOR_UM: f64 = 1e-9;

/// The axes of a log-log figure: the ranges and their titles.
pub(crate) struct LogLog<'t> {
    pub(crate) title: &'t str,
    pub(crate) x: std::ops::Range<f64>,
    pub(crate) y: std::ops::Range<f64>,
    pub(crate) x_desc: &'t str,
    pub(crate) y_desc: &'t str,
    /// Whether the series' labels are listed (upper right).
    pub(crate) legend: bool,
}

/// A log-log chart on a drawing area.
pub(crate) type LogChart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<
        plotters::coord::combinators::LogCoord<f64>,
        plotters::coord::combinators::LogCoord<f64>,
    >,
>;

/// Writes a 900 x 600 log-log figure to `path` (a temporary file renamed
/// into place when complete): `draw` adds the series to the chart `axes`
/// describes, with its mesh drawn.
pub(crate) fn log_log_png(
    path: &Path,
    axes: &LogLog<'_>,
    draw: impl FnOnce(&mut LogChart<'_, '_>) -> Result<()>,
) -> Result<()> {
    let _ =
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    let temp = path.with_extension("png.partial.png");
    {
        let root = BitMapBackend::new(&temp, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(axes.title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(85)
            .build_cartesian_2d(axes.x.clone().log_scale(), axes.y.clone().log_scale())?;
        chart
            .configure_mesh()
            .x_desc(axes.x_desc)
            .y_desc(axes.y_desc)
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .label_style(("sans-serif", 15))
            .draw()?;
        draw(&mut chart)?;
        if axes.legend {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.9))
                .border_style(BLACK)
                .label_font(("sans-serif", 15))
                .position(SeriesLabelPosition::UpperRight)
                .draw()?;
        }
        root.present()?;
    }
    std::fs::rename(&temp, path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// Draws max error against wall time, log-log, one line per method.
pub fn plot(path: &Path, title: &str, points: &[Point]) -> Result<()> {
    let t_min = points
        .iter()
        .map(|p| p.wall_s)
        .fold(f64::INFINITY, f64::min);
    let t_max = points.iter().map(|p| p.wall_s).fold(0.0, f64::max);
    let e_max = points
        .iter()
        .map(|p| p.max_error_um)
        .fold(PLOT_FLOOR_UM, f64::max);
    let axes = LogLog {
        title,
        x: t_min * 0.5..t_max * 2.0,
        y: PLOT_FLOOR_UM * 0.5..e_max * 3.0,
        x_desc: "wall time on one core [s]",
        y_desc: "largest error of a step [um]",
        legend: true,
    };
    log_log_png(path, &axes, |chart| {
        let mut methods: Vec<&str> = points.iter().map(|p| p.method.as_str()).collect();
        methods.dedup();
        for (m, method) in methods.iter().enumerate() {
            let color = Palette99::pick(m).to_rgba();
            let series: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| p.method == *method)
                .map(|p| (p.wall_s, p.max_error_um.max(PLOT_FLOOR_UM)))
                .collect();
            chart
                .draw_series(LineSeries::new(series.clone(), color.stroke_width(2)))?
                .label(*method)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart.draw_series(
                series
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), 4, color.filled())),
            )?;
        }
        for target in [1e-2, 1e-3] {
            chart.draw_series(LineSeries::new(
                vec![(t_min * 0.5, target), (t_max * 2.0, target)],
                BLACK.mix(0.3),
            ))?;
        }
        Ok(())
    })
}

/// The cheapest setting of a method that reaches `target` um, if any:
/// among those where every instance finished normally, else among those
/// whose compared values (a "not steady" estimate is compared too) all
/// reach it.
pub fn cheapest(points: &[Point], method: &str, target: f64) -> Option<Point> {
    let reaching = |all_finished: bool| {
        points
            .iter()
            .filter(|p| p.method == method && p.max_error_um <= target)
            .filter(|p| !all_finished || p.failed == 0)
            .min_by(|a, b| a.wall_s.total_cmp(&b.wall_s))
            .cloned()
    };
    reaching(true).or_else(|| reaching(false))
}
