//! The subcommands behind the `pidm` binary. `main.rs` only parses the
//! command line and prints errors; everything a command does is here, so
//! tests can call it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::backend::{
    Backend, BackendChoice, CpuBackend, GpuBackend, Hardware, Precision, select_backend,
};
use crate::cpu::integrate::STATUS_OK;
use crate::cpu::integrate::constants::STATUS_NOT_STEADY;
use crate::model::{AXES, AXIS_NAMES, Instance, Measure};
use crate::motion::Motion;
use crate::output::ShardInfo;
use crate::run::{RunResult, RunScope, default_output, run_scene};
use crate::scene::{Layout, MAP_MEMORY_BUDGET_BYTES, Scene};
use crate::sweep;

pub use crate::estimate::NOMINAL_SIMULATED_PER_CORE;

/// Options of `pidm run`.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    pub scene: PathBuf,
    pub out: Option<PathBuf>,
    pub threads: Option<usize>,
    pub backend: BackendChoice,
    pub precision: Option<Precision>,
    /// Print the per-instance table for scenes up to this many instances.
    pub table_limit: u64,
    /// Shard, resume and chunking.
    pub scope: RunScope,
}

/// `pidm run`: prints a short summary and returns the number of instances
/// that did not finish normally.
pub fn run(opts: &RunOptions) -> Result<u64> {
    // Ctrl-C and SIGTERM from here on stop the run through the checkpoint
    // (exit 130 or 143), not by ending the process mid-write.
    crate::run::install_interrupt_handler();
    let scene = Scene::load(&opts.scene)?;
    let selected = select_backend(
        opts.backend,
        opts.precision,
        opts.threads,
        integrations_for_choice(&scene, opts.scope),
    )?;
    let backend = selected.as_ref();
    let out = match (&opts.out, opts.scope.shard) {
        (Some(out), _) => out.clone(),
        (None, Some(shard)) => shard.default_output(&scene.name),
        (None, None) => default_output(&scene),
    };
    if crate::output::claim::is_same_file(&out, &opts.scene) {
        bail!(
            "{} is the scene file itself; give another --out",
            out.display()
        );
    }
    eprintln!(
        "pidm: scene {:?}: {} {}{} on {}, {}, tolerance {:e} rad",
        scene.name,
        scene.instance_count(),
        plural(scene.instance_count(), "instance", "instances"),
        if scene.baselines {
            " (+ 1-DOF baselines)"
        } else {
            ""
        },
        backend.describe(),
        backend.precision(),
        scene.settings.tolerance
    );
    if let Some(shard) = opts.scope.shard {
        eprintln!(
            "pidm: shard {shard}: {} of the {} instances",
            ShardInfo::new(shard, scene.instance_count()).len(),
            scene.instance_count()
        );
    }
    let result = run_scene(&scene, backend, &out, opts.table_limit, opts.scope)?;
    print_summary(&scene, &result);
    // Closing a GPU device costs NVIDIA's driver 0.03-0.05 s, as long as
    // the whole integration of a 200 x 200 map. The output is complete and
    // closed here and the process ends right after this command, so the
    // device is left to the operating system, which frees it either way.
    if backend.hardware() == Hardware::Gpu {
        std::mem::forget(selected);
    }
    // "Not steady" instances finished normally and keep their estimates.
    let counts = &result.summary.status_counts;
    Ok(result.summary.instances - counts[STATUS_OK as usize] - counts[STATUS_NOT_STEADY as usize])
}

/// Largest run whose distinct integrations `pidm run` counts before
/// choosing a backend; larger runs count as their instances.
const COUNTED_RUN: u64 = 1 << 16;

/// The integrations a run computes, for `--backend auto`'s choice: small
/// runs are counted exactly (repeated instances and shared baselines once),
/// larger ones and shards by their instances, an upper bound.
fn integrations_for_choice(scene: &Scene, scope: RunScope) -> u64 {
    let count = match scope.shard {
        Some(shard) => ShardInfo::new(shard, scene.instance_count()).len(),
        None => scene.instance_count(),
    };
    if scope.shard.is_some() || count > COUNTED_RUN {
        return count;
    }
    let instances: Vec<Instance> = (0..count).map(|i| scene.instance(i)).collect();
    crate::sweep::distinct_integrations(&instances, scene.baselines).len() as u64
}

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

/// The stall search's lines of the run summary (MODEL.md section 7): the
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
            let meaning = crate::status::Status::describe(code as u32);
            println!("    stall status {code} ({meaning}): {n}");
        }
    }
}

/// Metres as signed micrometres to 4 decimals; a value that rounds to
/// zero is "0.0000", never "-0.0000".
pub fn um(x: f64) -> String {
    let v = x * 1e6;
    if (v * 1e4).round() == 0.0 {
        "0.0000".to_owned()
    } else {
        format!("{v:+.4}")
    }
}

fn print_summary(scene: &Scene, result: &RunResult) {
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
    if let Some(report) = &result.refine {
        print_refine(report);
    }
    if let Some(report) = &result.stall {
        print_stall(scene, report);
    }
    if s.on_cpu > 0 {
        println!(
            "  {} of the integrations ran on the CPU in f64 (the slow tail of a GPU batch, \
             continued from the GPU's state in f64 and started over in f32; instances that \
             failed or met a band graze in f32, or that f32's check of its heaviest runs sent \
             there; or iterations the driver's loop limiter cut)",
            s.on_cpu
        );
    }
    if s.grazes > 0 {
        println!(
            "  {} of them were f32 runs whose slip passed the velocity band a within {} a^2 \
             (in |v_rel|^2), where the direction tolerance decides whether the slip ends \
             (docs/gpu.md, \"Precision\")",
            s.grazes,
            crate::cpu::integrate::constants::GRAZE_MARGIN
        );
    }
    if s.checked > 0 {
        println!(
            "  {} f32 runs, the heaviest {} % of those f32 finished itself, were checked for \
             steps that f32 does not determine (chaotic ones): {} carry the f64 reference's \
             value (their twin, nudged and at {}x the tolerance, disagreed, or the check integrated them in \
             f64 directly), {} keep f32's (their twin agreed within half of 0.005 um + 1 %)",
            s.checked,
            (crate::backend::check::share() * 1000.0).round() / 10.0,
            s.checked_on_cpu,
            crate::backend::check::TWIN_LOOSENING,
            s.checked - s.checked_on_cpu
        );
    }
    for (code, &n) in s.status_counts.iter().enumerate() {
        if n > 0 {
            let meaning = crate::status::Status::describe(code as u32);
            println!("  status {code} ({meaning}): {n}");
        }
    }
    let steady = matches!(scene.instance(0).measure, Measure::Steady { .. });
    if steady && s.instances > 0 {
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
    }
    if s.extreme_step[0].is_finite() {
        println!(
            "  step range: {} .. {} um per own drive cycle",
            um(s.extreme_step[0]),
            um(s.extreme_step[1])
        );
    }
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
    if !result.records.is_empty() {
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
}

/// The run summary's counts of each kind of motion, the kinds a steady
/// measurement decides first and undetermined last: "12 periodic, 40
/// quasi_periodic, 3 irregular, 1 undetermined". `counts` is indexed by
/// code, as `Summary::motion` is.
fn motion_counts(counts: &[u64; Motion::ALL.len()]) -> String {
    let order = Motion::ALL
        .into_iter()
        .filter(|&m| m != Motion::Undetermined)
        .chain([Motion::Undetermined]);
    order
        .map(|m| format!("{} {}", counts[m.code() as usize], m.name()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Names instance `index` of a scene by what sets it apart: its grid
/// coordinates (`axis.x.voltage = 150, axis.y.voltage = 60`), its point's
/// label, or its flat index.
pub fn instance_name(scene: &Scene, index: u64) -> String {
    match &scene.layout {
        Layout::Grid { axes } if !axes.is_empty() => {
            let mut rest = index;
            let mut parts: Vec<String> = axes
                .iter()
                .rev()
                .map(|axis| {
                    let n = axis.values.len() as u64;
                    let value = axis.values[(rest % n) as usize];
                    rest /= n;
                    let units = if axis.units == "1" {
                        String::new()
                    } else {
                        format!(" {}", axis.units)
                    };
                    format!("{} = {}{units}", axis.key, short_number(value))
                })
                .collect();
            parts.reverse();
            parts.join(", ")
        }
        Layout::Points { labels } if !labels[index as usize].is_empty() => {
            format!("{:?}", labels[index as usize])
        }
        _ => format!("instance {index}"),
    }
}

/// A number to six significant digits, without trailing zeros.
fn short_number(value: f64) -> String {
    let text = format!("{value:.6}");
    let precise = format!("{}", value);
    if precise.len() <= text.len() {
        precise
    } else {
        format!("{value:.6e}")
    }
}

/// `pidm info`: every GPU adapter wgpu finds, with type, backend, limits
/// and f64 support, which precisions it runs and trusts (each compiled and
/// self-tested against the CPU), and which one `--backend auto` and `gpu`
/// would take.
pub fn info() -> Result<()> {
    let adapters = crate::gpu::check_adapters();
    println!(
        "WGPU_BACKEND={}",
        std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "(unset: all)".into())
    );
    if adapters.is_empty() {
        println!("no GPU adapters found");
    }
    for (a, checks) in &adapters {
        println!(
            "- {} ({}, {}, {}): f64 {}, pipeline cache {}, max storage binding {} MiB, \
             max buffer {} MiB, max workgroups per dimension {}",
            a.name,
            a.device_type,
            a.backend,
            a.driver,
            if a.f64 { "yes" } else { "no" },
            if a.pipeline_cache { "yes" } else { "no" },
            a.max_storage_buffer_binding_size >> 20,
            a.max_buffer_size >> 20,
            a.max_compute_workgroups_per_dimension
        );
        let checks: Vec<String> = checks.iter().map(|c| c.describe()).collect();
        println!("  runs and trusts: {}", checks.join(", "));
    }
    for (label, software) in [
        ("--backend auto (a run large enough for a GPU)", false),
        ("--backend gpu", true),
    ] {
        match crate::gpu::GpuContext::new(software) {
            Ok(ctx) if !software && !ctx.supports_f64() => println!(
                "{label}: {} in f32 (it has no f64 in shaders)",
                ctx.describe()
            ),
            Ok(ctx) => println!("{label}: {}", ctx.describe()),
            Err(err) => println!(
                "{label}: {}",
                if software {
                    format!("fails: {err}")
                } else {
                    format!("the CPU path ({err})")
                }
            ),
        }
    }
    println!(
        "cpu: {} threads",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    Ok(())
}

/// What `pidm check` finds out about a scene: its size and a cost estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckReport {
    pub instances: u64,
    /// The distinct integrations a run computes (instances and baselines
    /// that repeat counted once; estimated beyond 65,536 instances).
    pub integrations: u64,
    /// Simulated time over every instance and distinct baseline [s], each
    /// run to its `cycles` (`max_cycles` when steady: an upper bound).
    pub simulated_s: f64,
    /// The estimated cost [core-seconds], from the probe.
    pub core_seconds: f64,
    /// The cores of this machine: the CPU path's threads the estimate
    /// assumes.
    pub cores: usize,
    /// The estimated wall time of the run on the CPU path on `cores`
    /// threads [s]: its integrations (`sweep_s`), its trajectories
    /// (`trajectories_s`) and [`crate::estimate::RUN_OVERHEAD_S`].
    pub estimate_s: f64,
    /// Of `estimate_s`, the integrations of the maps [s].
    pub sweep_s: f64,
    /// Of `estimate_s`, recording the trajectories [s].
    pub trajectories_s: f64,
    /// The estimate is an upper bound: a probed steady integration ran to
    /// the probe's limit and was charged up to its `max_cycles`.
    pub upper_bound: bool,
    /// What the probe measured.
    pub probe: crate::estimate::Probe,
}

/// Sizes up a scene and estimates its cost with a short probe (see
/// [`crate::estimate`]).
pub fn check_report(scene: &Scene) -> CheckReport {
    let count = scene.instance_count();
    // Exact total simulated time for up to a million instances, else a
    // sample of evenly spaced ones.
    let sample = count.clamp(1, 1_000_000);
    let mut simulated = 0.0;
    // A run integrates each distinct baseline once (they repeat along every
    // other grid axis): those of the sampled instances, not scaled up.
    let mut baselines = std::collections::HashSet::new();
    let mut baseline_time = 0.0;
    for k in 0..sample {
        let i = if count <= sample {
            k
        } else {
            k * count / sample
        };
        let inst = scene.instance(i);
        simulated += inst.duration();
        if scene.baselines {
            for axis in 0..AXES {
                let base = inst.baseline(axis);
                if base != inst && baselines.insert(base.key()) {
                    baseline_time += base.duration();
                }
            }
        }
    }
    simulated = simulated * count as f64 / sample as f64 + baseline_time;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (integrations, probe) = crate::estimate::probe(scene, cores);
    let core_seconds = probe.mean_core_s * integrations as f64;
    // The run spreads its integrations over the cores the probe had (fewer
    // than the machine's where other work shares it), and cannot spread
    // fewer integrations than cores over them all.
    let spread = (integrations as f64).clamp(1.0, probe.parallelism);
    // A probe of every integration, each to its end, was the run itself.
    let whole = probe.integrations as u64 == integrations && probe.scaled + probe.cut == 0;
    let sweep_s = if whole {
        probe.wall_s
    } else {
        core_seconds / spread
    };
    let trajectories_s = crate::estimate::trajectories_s(scene, &probe);
    let estimate_s = sweep_s + trajectories_s + crate::estimate::RUN_OVERHEAD_S;
    CheckReport {
        instances: count,
        integrations,
        simulated_s: simulated,
        core_seconds,
        cores,
        estimate_s,
        sweep_s,
        trajectories_s,
        upper_bound: probe.scaled + probe.cut > 0,
        probe,
    }
}

/// `pidm check`: validates and describes a scene without running it, as
/// text or (`json`) as one JSON object on stdout (see [`check_json`]).
pub fn check(path: &Path, json: bool) -> Result<()> {
    let scene = Scene::load(path)?;
    scene.check_memory(MAP_MEMORY_BUDGET_BYTES)?;
    let report = check_report(&scene);
    if json {
        println!("{}", check_json(&scene, &report));
        return Ok(());
    }
    println!("{}", scene.describe());
    let CheckReport {
        instances,
        integrations,
        simulated_s,
        core_seconds,
        cores,
        estimate_s,
        sweep_s,
        trajectories_s,
        upper_bound,
        ref probe,
    } = report;
    let steady = matches!(scene.instance(0).measure, Measure::Steady { .. });
    println!(
        "instances: {instances} ({integrations} distinct {}, baselines included)",
        plural(integrations, "integration", "integrations")
    );
    if steady {
        println!(
            "simulated time: at most {simulated_s:.4e} s (each run to max_cycles; a steady \
             measurement stops as soon as its steps are known, often long before)"
        );
    } else {
        println!("simulated time: {simulated_s:.4e} s (baselines included)");
    }
    let at_most = if upper_bound { "at most " } else { "" };
    println!(
        "estimated cost: {at_most}{core_seconds:.3e} core-seconds: {at_most}{} on the CPU path \
         (f64) on this machine's {cores} {} (--backend cpu; a GPU run is not estimated)",
        human_duration(estimate_s),
        plural(cores as u64, "core", "cores")
    );
    let trajectories = if trajectories_s > 0.0 {
        format!(
            ", {} recording trajectories",
            human_duration(trajectories_s)
        )
    } else {
        String::new()
    };
    println!(
        "  {} integrating{trajectories}, {} starting and writing",
        human_duration(sweep_s),
        human_duration(crate::estimate::RUN_OVERHEAD_S)
    );
    println!("  {}", probe_note(probe));
    Ok(())
}

/// How the estimate was made, in one sentence.
fn probe_note(probe: &crate::estimate::Probe) -> String {
    let mut note = format!(
        "from a probe of {} {} ({:.2} s, {:.1} cores busy): {:.3} ms and {:.1} periods each \
         on average",
        probe.integrations,
        plural(probe.integrations as u64, "integration", "integrations"),
        probe.wall_s,
        probe.parallelism,
        probe.mean_core_s * 1e3,
        probe.mean_periods
    );
    if probe.scaled > 0 {
        note.push_str(&format!(
            "; {} ran past {} periods and {} charged up to {} max_cycles",
            probe.scaled,
            crate::estimate::PROBE_PERIODS,
            if probe.scaled == 1 { "is" } else { "are" },
            if probe.scaled == 1 { "its" } else { "their" }
        ));
    }
    if probe.cut > 0 {
        note.push_str(&format!(
            "; {} took over {} s and {} charged at {} simulated s per core-second",
            probe.cut,
            crate::estimate::PROBE_CUTOFF_S,
            if probe.cut == 1 { "is" } else { "are" },
            NOMINAL_SIMULATED_PER_CORE
        ));
    }
    note
}

/// `n` and the singular or plural noun.
pub fn plural(n: u64, one: &'static str, many: &'static str) -> &'static str {
    if n == 1 { one } else { many }
}

/// `pidm check --json`: the scene's name, layout (`"grid"` with its axes:
/// key, units, size, first and last value; or `"points"` with their
/// labels), instance count, shape, baselines, trajectory count, the bytes
/// of its output maps, and the cost estimate: simulated time
/// (`simulated_s`, to every `max_cycles` when steady), the distinct
/// `integrations`, `core_seconds` and `estimate_s` on the CPU path
/// (`estimate_backend`) on this machine's `cores` (of it
/// `estimate_sweep_s` integrating the maps and `estimate_trajectories_s`
/// recording trajectories, the rest starting and writing), measured by a probe
/// (`probe`: integrations, scaled, cut, mean_periods, mean_core_s,
/// wall_s); `estimate_is_upper_bound` where a probed steady integration
/// was charged up to its `max_cycles`. `nominal_simulated_per_core_s` is
/// the rate charged to a probed integration that was cut off.
pub fn check_json(scene: &Scene, report: &CheckReport) -> serde_json::Value {
    use serde_json::json;
    let (layout, axes, labels) = match &scene.layout {
        Layout::Grid { axes } => {
            let axes: Vec<serde_json::Value> = axes
                .iter()
                .map(|a| {
                    json!({
                        "key": a.key,
                        "units": a.units,
                        "size": a.values.len(),
                        "first": a.values.first(),
                        "last": a.values.last(),
                    })
                })
                .collect();
            ("grid", axes, Vec::new())
        }
        Layout::Points { labels } => ("points", Vec::new(), labels.clone()),
    };
    let probe = &report.probe;
    json!({
        "name": scene.name,
        "layout": layout,
        "instances": report.instances,
        "integrations": report.integrations,
        "shape": scene.shape(),
        "axes": axes,
        "labels": labels,
        "baselines": scene.baselines,
        "trajectories": scene.trajectories.len(),
        "tolerance_rad": scene.settings.tolerance,
        "output_bytes": scene.bytes_per_instance().saturating_mul(report.instances),
        "simulated_s": report.simulated_s,
        "core_seconds": report.core_seconds,
        "cores": report.cores,
        "estimate_s": report.estimate_s,
        "estimate_backend": format!("cpu (f64, {} threads)", report.cores),
        "estimate_sweep_s": report.sweep_s,
        "estimate_trajectories_s": report.trajectories_s,
        "estimate_is_upper_bound": report.upper_bound,
        "probe": {
            "integrations": probe.integrations,
            "scaled": probe.scaled,
            "cut": probe.cut,
            "mean_periods": probe.mean_periods,
            "mean_core_s": probe.mean_core_s,
            "wall_s": probe.wall_s,
            "parallelism": probe.parallelism,
        },
        "nominal_simulated_per_core_s": NOMINAL_SIMULATED_PER_CORE,
    })
}

/// Formats seconds for people.
pub fn human_duration(seconds: f64) -> String {
    if seconds < 1.0 {
        format!("{:.0} ms", seconds * 1e3)
    } else if seconds < 120.0 {
        format!("{seconds:.1} s")
    } else if seconds < 7200.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

/// The default scene of `pidm accuracy` and `pidm bench`.
pub const DEFAULT_SCENE: &str = "sweeps/paper.toml";

/// Loads a scene file; a shipped scene named by its path in the checkout
/// (`sweeps/paper.toml`, the commands' defaults) that is not there, as
/// from another directory, is the copy built into the binary.
pub fn load_scene(path: &Path) -> Result<Scene> {
    if !path.exists()
        && let Some(scene) = path.to_str().and_then(Scene::shipped)
    {
        return Ok(scene?);
    }
    Ok(Scene::load(path)?)
}

/// [`load_scene`] for each path.
fn load_scenes(paths: &[PathBuf]) -> Result<Vec<Scene>> {
    paths.iter().map(|p| load_scene(p)).collect()
}

/// Every distinct integration a whole scene asks for.
fn scene_integrations(scene: &Scene) -> Vec<Instance> {
    let instances: Vec<Instance> = (0..scene.instance_count())
        .map(|i| scene.instance(i))
        .collect();
    sweep::distinct_integrations(&instances, scene.baselines)
}

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
        let reference = crate::cpu::integrate::Settings {
            tolerance: 1e-9,
            ..scene.settings
        };
        let mut methods = vec![accuracy::cpu_method(scene.settings)];
        if gpu {
            // Every precision the adapter offers, software adapters included.
            match crate::gpu::GpuContext::new(true) {
                Ok(ctx) => {
                    let f64_ok = ctx.supports_f64();
                    methods.push(accuracy::backend_method(
                        Box::new(GpuBackend::new(ctx, Precision::F32)?),
                        scene.settings,
                    ));
                    if f64_ok {
                        let ctx = crate::gpu::GpuContext::new(true)?;
                        methods.push(accuracy::backend_method(
                            Box::new(GpuBackend::new(ctx, Precision::F64)?),
                            scene.settings,
                        ));
                    }
                }
                Err(err) => println!("  gpu: not studied ({err})"),
            }
        }
        methods.push(accuracy::karnopp_method(karnopp_steps.to_vec()));
        println!(
            "accuracy: scene {:?}, {} integrations, reference tolerance 1e-9 rad",
            scene.name,
            instances.len()
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
    reference: crate::cpu::integrate::Settings,
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

/// `pidm random-scene`: a points scene of seeded random instances (see
/// `random.rs` for the ranges), as TOML on stdout, measured over a fixed
/// window (`measure = "window"`, `cycles` periods of which `settle` are
/// discarded) so that backends can be compared on it exactly. Refuses
/// `count` 0: a scene without points is one default instance, not none.
pub fn random_scene(seed: u64, count: usize, cycles: u32, settle: u32) -> Result<String> {
    use std::fmt::Write as _;
    if count == 0 {
        bail!(
            "random-scene --count 0: expected at least 1 instance (a scene without points would \
             run one default instance)"
        );
    }
    let mut toml = String::new();
    let _ = writeln!(
        toml,
        "# {count} seeded random 2-DOF instances (seed {seed}): written by\n\
         # `pidm random-scene --seed {seed} --count {count} --cycles {cycles} --settle {settle}`.\n\
         name = \"random\"\n\n[simulation]\nmeasure = \"window\"\ncycles = {cycles}\nsettle = {settle}\n"
    );
    for (k, inst) in crate::random::random_instances(seed, count, cycles, settle)
        .iter()
        .enumerate()
    {
        let _ = writeln!(toml, "[[points]]\nlabel = \"random {k}\"");
        // Loads only where set (never, today): the text of unloaded
        // instances is what it was before the load existed.
        let mechanism: Vec<(&str, f64)> = inst
            .mechanism
            .parameters()
            .into_iter()
            .filter(|&(key, value)| !(key.starts_with("load_") && value == 0.0))
            .collect();
        let _ = writeln!(toml, "mechanism = {}", inline_table(&mechanism));
        for (name, a) in AXIS_NAMES.iter().zip(&inst.axes) {
            let _ = writeln!(toml, "axis.{name} = {}", inline_table(&a.parameters()));
        }
        toml.push('\n');
    }
    // What is written must be a scene that runs: its own validation
    // refuses flags it cannot hold (`--cycles 0`, `--settle` >= `--cycles`).
    Scene::from_toml(&toml, None).context("random-scene: the flags do not make a valid scene")?;
    Ok(toml)
}

/// A TOML inline table of named values, each written so that it reads back
/// bit for bit.
fn inline_table(entries: &[(&str, f64)]) -> String {
    let fields: Vec<String> = entries
        .iter()
        .map(|(k, v)| format!("{k} = {v:?}"))
        .collect();
    format!("{{ {} }}", fields.join(", "))
}

/// `pidm bench`: simulated seconds per wall second per core on one thread
/// at the scene's accuracy, and the all-core figure; `path` `None` is the
/// built-in paper scene.
pub fn bench(path: Option<&Path>, min_seconds: f64) -> Result<()> {
    let default = PathBuf::from(DEFAULT_SCENE);
    let scene = load_scene(path.unwrap_or(&default))?;
    let count = scene.instance_count();
    if count > 100_000 {
        bail!("bench runs every instance repeatedly; {count} instances is too many");
    }
    let instances = scene_integrations(&scene);
    let simulated: f64 = instances.iter().map(Instance::duration).sum();
    println!(
        "bench: scene {:?}, {} integrations ({} simulated s per pass), tolerance {:e} rad",
        scene.name,
        instances.len(),
        simulated,
        scene.settings.tolerance
    );
    let mut backends: Vec<Box<dyn Backend>> = vec![
        Box::new(CpuBackend::new(Some(1))?),
        Box::new(CpuBackend::new(None)?),
    ];
    match crate::gpu::GpuContext::new(true) {
        Ok(ctx) => {
            let f64_ok = ctx.supports_f64();
            backends.push(Box::new(GpuBackend::new(ctx, Precision::F32)?));
            if f64_ok {
                let ctx = crate::gpu::GpuContext::new(true)?;
                backends.push(Box::new(GpuBackend::new(ctx, Precision::F64)?));
            }
        }
        Err(err) => println!("  gpu: not measured ({err})"),
    }
    // Instances per second of the all-core CPU path, to compare the GPU with.
    let mut cpu_rate = None;
    for backend in &backends {
        let mut passes = 0;
        // One warm-up pass (pipeline compilation on the GPU), then passes
        // until the time budget is used.
        backend.run(&instances, &scene.settings, &|_| {})?;
        let started = Instant::now();
        while started.elapsed().as_secs_f64() < min_seconds || passes == 0 {
            let out = backend.run(&instances, &scene.settings, &|_| {})?;
            if out.iter().any(|o| o.status != STATUS_OK) {
                bail!("an instance did not finish normally during the benchmark");
            }
            passes += 1;
        }
        let wall = started.elapsed().as_secs_f64();
        let rate = passes as f64 * simulated / wall;
        let per_core = match backend.hardware() {
            Hardware::Cpu { threads } => format!(" ({:.1} per core)", rate / threads as f64),
            Hardware::Gpu => String::new(),
        };
        let per_second = passes as f64 * instances.len() as f64 / wall;
        let versus = match (backend.hardware(), cpu_rate) {
            (Hardware::Cpu { .. }, _) => {
                cpu_rate = Some(per_second);
                String::new()
            }
            (Hardware::Gpu, Some(cpu)) => {
                format!(", {:.2} times the CPU path on every core", per_second / cpu)
            }
            (Hardware::Gpu, None) => String::new(),
        };
        println!(
            "  {} {}: {:.1} simulated s per wall s{per_core}, {:.1} instances per s{versus}, \
             {passes} passes in {wall:.2} s",
            backend.describe(),
            backend.precision(),
            rate,
            per_second
        );
    }
    Ok(())
}

/// `pidm report`: writes the paper report to `out`.
pub fn report(paths: &[PathBuf], out: &Path) -> Result<()> {
    let defaults: Vec<PathBuf> = crate::scene::SHIPPED
        .iter()
        .map(|(path, _)| PathBuf::from(path))
        .collect();
    let paths = if paths.is_empty() {
        &defaults[..]
    } else {
        paths
    };
    let scenes = load_scenes(paths)?;
    let md = crate::report::report(&scenes)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    // Written whole to a temporary name, then renamed: complete or absent.
    let temp = out.with_extension("md.partial");
    std::fs::write(&temp, &md).with_context(|| format!("cannot write {}", temp.display()))?;
    std::fs::rename(&temp, out).with_context(|| format!("cannot write {}", out.display()))?;
    println!("wrote {}", out.display());
    Ok(())
}

/// `pidm merge`: joins shard files into one map file.
pub fn merge(out: &Path, shards: &[PathBuf]) -> Result<()> {
    let merged = crate::shard::merge(out, shards)?;
    println!(
        "wrote {} ({} instances from {} shards)",
        merged.path.display(),
        merged.instances,
        merged.shards
    );
    Ok(())
}

/// `pidm refine-study`: a uniform run of a refined scene's finest grid and
/// the refined run, both timed on the same backend; the rule's variants
/// replayed on the uniform run's values; prints Markdown tables.
pub fn refine_study(
    scene_path: &Path,
    out_dir: &Path,
    choice: BackendChoice,
    uniform: Option<&Path>,
) -> Result<()> {
    use crate::refine::study;
    let scene = load_scene(scene_path)?;
    let Some(refine) = scene.refine else {
        bail!("{}: the scene has no [refine]", scene_path.display());
    };
    crate::run::install_interrupt_handler();
    let selected = select_backend(choice, None, None, scene.instance_count())?;
    let backend = selected.as_ref();
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    let quiet = RunScope {
        progress: Some(crate::progress::ProgressMode::Off),
        ..RunScope::default()
    };
    let (uniform_path, uniform_wall) = match uniform {
        Some(path) => {
            let f = hdf5::File::open(path)?;
            let wall = f
                .attr(crate::output::schema::WALL_TIME_S)?
                .read_scalar::<f64>()?;
            (path.to_path_buf(), wall)
        }
        None => {
            let mut whole = scene.clone();
            whole.refine = None;
            let out = out_dir.join(format!("{}.uniform.h5", scene.name));
            let r = run_scene(&whole, backend, &out, 0, quiet)?;
            (r.path, r.wall_time_s)
        }
    };
    let refined_out = out_dir.join(format!("{}.refined.h5", scene.name));
    let refined = run_scene(&scene, backend, &refined_out, 0, quiet)?;
    let pct = |x: f64| format!("{:.2} %", 100.0 * x);
    let row = |name: &str, m: &study::Metrics| {
        println!(
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {:.4} |",
            m.integrated,
            pct(m.integrated as f64 / m.points as f64),
            pct(m.sign_mismatch),
            pct(m.zero_sign_mismatch),
            m.regime_mismatch.map_or("-".to_string(), pct),
            m.regime_tol_mismatch.map_or("-".to_string(), pct),
            pct(m.within),
            m.worst * 1e6
        );
    };
    let header = "| rule | integrated | share | sign labels differ (dead zone tol) | sign differs \
                  (0.001 um) | coupling regime differs (0.001 um) | coupling regime differs \
                  (tol) | step values within tol + 1 % | largest error [um] |\n\
                  |---|---|---|---|---|---|---|---|---|";
    println!(
        "scene {:?}: coarse {} x {}, levels {}, tolerance {:e} m, finest grid {} points; \
         backend {}\n",
        scene.name,
        refine.coarse[0],
        refine.coarse[1],
        refine.levels,
        refine.tolerance,
        scene.instance_count(),
        backend.describe()
    );
    let (_, uniform_records, baselines) = study::read_records(&uniform_path)?;
    let (_, raster, _) = study::read_records(&refined.path)?;
    let index: Vec<u64> = hdf5::File::open(&refined.path)?
        .dataset(crate::output::schema::REFINE_INDEX)?
        .read_raw()?;
    let same = index.iter().all(|&k| {
        let (a, b) = (&raster[k as usize], &uniform_records[k as usize]);
        let bits = |r: &sweep::Record| {
            [r.step, r.step_se, r.velocity, r.baseline_step].map(|v| v.map(f64::to_bits))
        };
        bits(a) == bits(b) && a.status == b.status && a.baseline_status == b.baseline_status
    });
    let mut m = study::compare(&raster, &uniform_records, refine.tolerance, baselines);
    m.integrated = index.len() as u64;
    println!(
        "The refined run ({}) against the uniform one ({}):\n",
        refined.path.display(),
        uniform_path.display()
    );
    println!("{header}");
    row("refined run (standard rule)", &m);
    let share = m.integrated as f64 / m.points as f64;
    println!(
        "\nintegrated points bit-identical to the uniform run's: {}\nwall time: uniform \
         {uniform_wall:.3} s, refined {:.3} s = {:.3} of uniform; integrated share \
         {share:.3} (bound: share x 1.2 = {:.3})\n",
        if same { "yes" } else { "NO" },
        refined.wall_time_s,
        refined.wall_time_s / uniform_wall,
        share * 1.2
    );
    println!("Rule variants, replayed on the uniform run's values:\n\n{header}");
    let mut levels = Vec::new();
    for (name, m, r) in study::study(
        &uniform_path,
        refine.coarse,
        refine.levels,
        refine.tolerance,
    )? {
        row(name, &m);
        levels.push((name, r.stats));
    }
    println!(
        "\n| rule | level | points | cells judged | refined | by labels | by probes | by \
         neighbours | audited | audit finds | largest miss [um] | batches |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (name, stats) in levels
        .iter()
        .filter(|(name, _)| name.starts_with("standard ("))
    {
        for (level, st) in stats.iter().enumerate() {
            println!(
                "| {name} | {level} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {} |",
                st.integrated,
                st.candidates,
                st.flagged,
                st.by_label,
                st.by_probe,
                st.by_neighbours,
                st.audited,
                st.audit_finds,
                st.largest_miss * 1e6,
                st.batches
            );
        }
    }
    if backend.hardware() == Hardware::Gpu {
        std::mem::forget(selected);
    }
    Ok(())
}
