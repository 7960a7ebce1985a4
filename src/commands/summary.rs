//! The summary `pidm run` prints: integrations and times, the refinement's
//! and the stall search's lines, the instances that ran on the CPU or were
//! checked, the status and motion counts, the best steps, and the table of
//! a small scene's instances.

use super::format::{instance_name, plural, um};
use crate::laws::status::STATUS_NOT_STEADY;
use crate::laws::status::STATUS_OK;
use crate::model::motion::Motion;
use crate::model::{AXIS_NAMES, Measure};
use crate::run::RunResult;
use crate::scene::{Layout, Scene};
use crate::sweep::Summary;

/// The refinement's lines of the run summary: integrated and inferred
/// points, and per level what was integrated, refined and missed.
fn print_refine(report: &crate::refine::Report) {
    let inferred = report.points - report.integrated;
    println!(
        "  refined map: {} of the {} points integrated ({:.1} %), {inferred} inferred (bilinear, \
         /maps/inferred = 1); the instance counts below are the integrated points",
        report.integrated,
        report.points,
        100.0 * report.integrated as f64 / report.points.max(1) as f64
    );
    for (level, st) in report.levels.iter().enumerate() {
        if level == 0 {
            println!("    level 0 (coarse grid): {} points", st.integrated);
        } else {
            println!(
                "    level {level}: {} points, {} of {} cells refined, largest probe miss {:.4} \
                 um, audit {} cells, {} found",
                st.integrated,
                st.flagged,
                st.candidates,
                st.largest_miss * 1e6,
                st.audited,
                st.audit_finds
            );
        }
    }
}

/// The stall search's lines of the run summary (docs/model.md section 7): the
/// waves and probes it took, the stall loads found and the best, and the
/// instances with no stall load or a failed probe.
fn print_stall(scene: &Scene, report: &crate::stall::Report) {
    let name = AXIS_NAMES[report.axis];
    let found = report.status_counts[0] + report.status_counts[STATUS_NOT_STEADY as usize];
    println!(
        "  stall load along {name}: {} waves after the unloaded run, {} probe {} ({:.3} s \
         integrating)",
        report.waves,
        report.probes,
        plural(report.probes, "integration", "integrations"),
        report.integration_s
    );
    if let (Some((load, index)), Some((lo, hi))) = (report.best, report.range) {
        println!(
            "    best: {load:+.5} N at {} (the largest load moved); stall loads {lo:+.5} .. \
             {hi:+.5} N",
            instance_name(scene, index)
        );
    }
    println!(
        "    found: {found}; no stall load below f_c: {}",
        report.no_stall()
    );
    for (code, &n) in report.status_counts.iter().enumerate() {
        if n > 0 && code != 0 {
            let meaning = crate::measurement::status::Status::describe(code as u32);
            println!("    stall status {code} ({meaning}): {n}");
        }
    }
}

/// The summary `pidm run` prints after a run (see the module's doc).
pub(super) fn print_summary(scene: &Scene, result: &RunResult) {
    let s = &result.summary;
    print_written(result);
    if let Some(report) = &result.refine {
        print_refine(report);
    }
    if let Some(report) = &result.stall {
        print_stall(scene, report);
    }
    print_precision(s);
    for (code, &n) in s.status_counts.iter().enumerate() {
        if n > 0 {
            let meaning = crate::measurement::status::Status::describe(code as u32);
            println!("  status {code} ({meaning}): {n}");
        }
    }
    let steady = matches!(scene.instance(0).measure, Measure::Steady { .. });
    if steady && s.instances > 0 {
        print_steady(s);
    }
    if s.extreme_step[0].is_finite() {
        println!(
            "  step range: {} .. {} um per own drive cycle",
            um(s.extreme_step[0]),
            um(s.extreme_step[1])
        );
    }
    print_best(scene, s);
    if !result.records.is_empty() {
        print_table(scene, result, steady);
    }
}

/// The summary's first line: the file written, its instances and
/// integrations, and the run's times.
fn print_written(result: &RunResult) {
    let s = &result.summary;
    // After --resume the integrations and times are this run's own; the
    // instances and statuses count the whole file.
    let resumed = match result.from_checkpoint {
        0 => String::new(),
        n => format!(
            " ({n} of them from the checkpoint; {:.3} s wall over every part of the run)",
            result.total_wall_time_s
        ),
    };
    println!(
        "wrote {} ({} {}{resumed}, {} distinct {} in this run, {:.3} s wall of which {:.3} s \
         integrating, {:.0} simulated s per wall s)",
        result.path.display(),
        s.instances,
        plural(s.instances, "instance", "instances"),
        s.integrations,
        plural(s.integrations, "integration", "integrations"),
        result.wall_time_s,
        s.integration_s,
        s.simulated_s / result.wall_time_s.max(1e-9)
    );
}

/// The summary's lines on precision, where they apply: the integrations
/// run on the CPU in f64, the f32 runs that grazed the velocity band, and
/// those f32's check looked at.
fn print_precision(s: &Summary) {
    if s.on_cpu > 0 {
        println!(
            "  {} of the integrations ran on the CPU in f64 (the slow tail of a GPU batch, \
             continued from the GPU's state in f64 (under LuGre from the start of its period) \
             and started over in f32; instances that \
             failed or met a band graze in f32, or that f32's check of its heaviest runs sent \
             there; iterations the driver's loop limiter cut; or instances split into replicas \
             under LuGre, or with the backward travel, whose groups run on the CPU's threads)",
            s.on_cpu
        );
    }
    if s.grazes > 0 {
        println!(
            "  {} of them were f32 runs whose slip passed the velocity band a within {} a^2 \
             (in |v_rel|^2), where the direction tolerance decides whether the slip ends \
             (docs/gpu.md, \"Precision\")",
            s.grazes,
            crate::laws::Law::ALL
                .iter()
                .find_map(|law| law.graze_margin())
                .expect("a law with f32 grazes")
        );
    }
    if s.checked > 0 {
        println!(
            "  {} f32 runs, the heaviest {} % of those f32 finished itself, were checked for \
             steps that f32 does not determine (chaotic ones): {} carry the f64 reference's \
             value (their twin, nudged and at {}x the tolerance, disagreed, or the check integrated them in \
             f64 directly), {} keep f32's (their twin agreed within half of 0.005 um + 1 %)",
            s.checked,
            (crate::laws::floor::check::share() * 1000.0).round() / 10.0,
            s.checked_on_cpu,
            crate::laws::floor::check::TWIN_LOOSENING,
            s.checked - s.checked_on_cpu
        );
    }
}

/// The steady measurement's lines: how the instances stopped, their
/// motions, and the replicas merged.
fn print_steady(s: &Summary) {
    let not_steady = s.status_counts[STATUS_NOT_STEADY as usize];
    let converged = s.status_counts[STATUS_OK as usize].saturating_sub(s.periodic);
    println!(
        "  steady measurement: {} periodic (exact), {converged} converged within the step \
         tolerance, {not_steady} not steady (ran to max_cycles; estimates kept with their \
         standard errors); largest standard error {:.4} um; periods per instance: mean \
         {:.0}, most {}",
        s.periodic,
        s.largest_se * 1e6,
        s.periods as f64 / s.instances as f64,
        s.max_periods
    );
    println!("  motion: {}", motion_counts(&s.motion));
    let multistable = s.motion[Motion::Multistable.code() as usize];
    if s.merged > 0 || multistable > 0 {
        println!(
            "  replicas: {} instances merged from {} replicas; {multistable} whose replicas \
             disagreed (multistable: their own runs kept)",
            s.merged, s.replicas
        );
    }
}

/// The best forward and backward steps on each axis the scene ever drives.
fn print_best(scene: &Scene, s: &Summary) {
    for (axis, name) in AXIS_NAMES.iter().enumerate() {
        let [backward, forward] = s.best[axis];
        let say = |(step, index): (f64, u64), sign: f64| {
            if index == u64::MAX || step * sign <= 0.0 {
                "none".to_owned()
            } else {
                format!("{} um at {}", um(step), instance_name(scene, index))
            }
        };
        if forward.1 != u64::MAX && scene.axis_ever_driven(axis) {
            println!(
                "  best on {name}: forward {}; backward {}",
                say(forward, 1.0),
                say(backward, -1.0)
            );
        }
    }
}

/// The table of a small scene's instances: steps, baselines, status,
/// motion (steady scenes) and stall loads, one row per instance.
fn print_table(scene: &Scene, result: &RunResult, steady: bool) {
    let labels: Vec<String> = match &scene.layout {
        Layout::Points { labels } => labels.clone(),
        Layout::Grid { .. } => (0..result.records.len()).map(|i| format!("#{i}")).collect(),
    };
    let width = labels.iter().map(String::len).max().unwrap_or(0).max(5);
    print!("  {:width$}  step_x [um]  step_y [um]", "point");
    if scene.baselines {
        print!("  1-DOF x [um]  1-DOF y [um]");
    }
    print!("  status");
    if steady {
        print!("  motion");
    }
    let stalls = &result.stall_records;
    if let Some(report) = &result.stall {
        print!("  stall load {} [N]  stall status", AXIS_NAMES[report.axis]);
    }
    println!();
    for (k, (label, r)) in labels.iter().zip(&result.records).enumerate() {
        print!(
            "  {label:width$}  {:>11}  {:>11}",
            um(r.step[0]),
            um(r.step[1])
        );
        if scene.baselines {
            print!(
                "  {:>12}  {:>12}",
                um(r.baseline_step[0]),
                um(r.baseline_step[1])
            );
        }
        print!("  {:>6}", r.status.max(r.baseline_status));
        if steady {
            print!("  {}", r.motion.name());
        }
        if let Some(stall) = stalls.get(k) {
            print!("  {:>+18.5}  {:>12}", stall.load, stall.status);
        }
        println!();
    }
}

/// The run summary's counts of each kind of motion, the kinds a steady
/// measurement decides first and undetermined last: "12 periodic, 40
/// quasi_periodic, 3 irregular, 1 undetermined"; multistable only where
/// replicas found some (`crate::replicas`). `counts` is indexed by code,
/// as `Summary::motion` is.
fn motion_counts(counts: &[u64; Motion::ALL.len()]) -> String {
    let order = Motion::ALL
        .into_iter()
        .filter(|&m| m != Motion::Undetermined)
        .filter(|&m| m != Motion::Multistable || counts[m.code() as usize] > 0)
        .chain([Motion::Undetermined]);
    order
        .map(|m| format!("{} {}", counts[m.code() as usize], m.name()))
        .collect::<Vec<_>>()
        .join(", ")
}
