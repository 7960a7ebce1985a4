//! `pidm check`: a scene validated and described without running it, with
//! its cost estimated by a probe ([`crate::run::estimate`]), as text or as JSON.

use std::path::Path;

use anyhow::{Context, Result};

use super::format::{human_duration, plural};
use crate::backend::cost::Plan;
use crate::model::{AXES, Measure};
use crate::run::estimate::NOMINAL_SIMULATED_PER_CORE;
use crate::scene::{Layout, MAP_MEMORY_BUDGET_BYTES, Scene};

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
    /// (`trajectories_s`) and [`crate::run::estimate::RUN_OVERHEAD_S`].
    pub estimate_s: f64,
    /// Of `estimate_s`, the integrations of the maps [s].
    pub sweep_s: f64,
    /// Of `estimate_s`, recording the trajectories [s].
    pub trajectories_s: f64,
    /// The estimate is an upper bound: a probed steady integration ran to
    /// the probe's limit and was charged up to its `max_cycles`.
    pub upper_bound: bool,
    /// What the probe measured.
    pub probe: crate::run::estimate::Probe,
    /// What `--backend auto` would do on `cores` threads, from the same
    /// probe ([`crate::backend::cost::plan`]): the CPU path unweighed (too
    /// few integrations), the CPU path, or a hardware GPU where one opens.
    pub auto: Plan,
}

/// Sizes up a scene and estimates its cost with a short probe (see
/// [`crate::run::estimate`]).
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
    let (integrations, probe) = crate::run::estimate::probe(scene, cores);
    let core_seconds = probe.mean_core_s * integrations as f64;
    let sweep_s = crate::run::estimate::cpu_sweep_s(integrations, &probe);
    let trajectories_s = crate::run::estimate::trajectories_s(scene, &probe);
    // auto's plan from this probe (it probes fewer integrations itself).
    let auto = crate::backend::cost::plan(
        integrations,
        cores,
        cores,
        None,
        || {
            let book = crate::backend::cost_book::load();
            crate::backend::select::known_costs(&book, None, &scene.settings)
        },
        |_| probe.clone(),
    );
    let estimate_s = sweep_s + trajectories_s + crate::run::estimate::RUN_OVERHEAD_S;
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
        auto,
    }
}

/// `pidm check` of a map or fit scene (`check_design::check` takes the
/// design scenes and hands this the others): validates and describes it
/// without running it, as text or (`json`) as one JSON object on stdout
/// (see [`check_json`]).
pub fn check_scene(path: &Path, text: &str, json: bool) -> Result<()> {
    if crate::fit::spec::is_fit_scene(text) {
        return check_fit(path, json);
    }
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
        ref auto,
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
        human_duration(crate::run::estimate::RUN_OVERHEAD_S)
    );
    println!("  {}", probe_note(probe));
    match scene.auto_on_cpu() {
        Some(why) => println!("--backend auto: the CPU path ({why})"),
        None => println!("--backend auto: {}", auto_note(auto)),
    }
    Ok(())
}

/// What `--backend auto` would do, in one sentence.
fn auto_note(plan: &Plan) -> String {
    match plan {
        Plan::TooFew {
            integrations,
            threads,
        } => format!(
            "the CPU path ({integrations} {} too few for a GPU to beat {threads} CPU {}; it \
             needs {} or more)",
            plural(*integrations, "integration is", "integrations are"),
            plural(*threads as u64, "thread", "threads"),
            crate::backend::cost::min_integrations(*threads)
        ),
        Plan::Cpu(estimate) => format!("the CPU path: {}", estimate.weighed("a GPU")),
        Plan::LookForGpu(Some(estimate)) => format!(
            "a hardware GPU where one opens (weighing its own measured costs), else the CPU \
             path: {}",
            estimate.weighed("a GPU")
        ),
        Plan::LookForGpu(None) => "a hardware GPU where one opens, else the CPU path".into(),
    }
}

/// `pidm check --json`'s `auto`: what `--backend auto` would do and the
/// estimates it weighed [s].
fn auto_json(plan: &Plan) -> serde_json::Value {
    use serde_json::json;
    match plan {
        Plan::TooFew { .. } => json!({ "backend": "cpu", "weighed": false }),
        Plan::Cpu(e) | Plan::LookForGpu(Some(e)) => json!({
            "backend": if matches!(plan, Plan::Cpu(_)) { "cpu" } else { "gpu" },
            "weighed": true,
            "cpu_s": e.cpu.seconds,
            "gpu_fixed_s": e.gpu.fixed_s(),
            "gpu_work_s": e.gpu_work_s(),
            "gpu_cores": e.gpu.cores,
            "gpu_costs": e.gpu.source(),
        }),
        Plan::LookForGpu(None) => json!({ "backend": "gpu", "weighed": false }),
    }
}

/// How the estimate was made, in one sentence.
fn probe_note(probe: &crate::run::estimate::Probe) -> String {
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
            crate::run::estimate::PROBE_PERIODS,
            if probe.scaled == 1 { "is" } else { "are" },
            if probe.scaled == 1 { "its" } else { "their" }
        ));
    }
    if probe.cut > 0 {
        note.push_str(&format!(
            "; {} took over {} s and {} charged at {} simulated s per core-second",
            probe.cut,
            crate::run::estimate::PROBE_CUTOFF_S,
            if probe.cut == 1 { "is" } else { "are" },
            NOMINAL_SIMULATED_PER_CORE
        ));
    }
    note
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
/// the rate charged to a probed integration that was cut off. `auto` says
/// what `--backend auto` would do on this machine's cores (`backend`:
/// `"cpu"`, or `"gpu"` where a hardware one opens) and, where it `weighed`
/// the run's cost, its estimates: `cpu_s`, `gpu_fixed_s`, `gpu_work_s`,
/// `gpu_cores` (the GPU's throughput in CPU cores) and `gpu_costs` (where
/// the GPU's figures come from).
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
        "auto": match scene.auto_on_cpu() {
            Some(why) => serde_json::json!({ "backend": "cpu", "weighed": false, "why": why }),
            None => auto_json(&report.auto),
        },
    })
}

/// `pidm check` of a fit scene: the fit described, its scene and data
/// checked, its cost estimated from the scene at the middle of the bounds.
fn check_fit(path: &Path, json: bool) -> Result<()> {
    use crate::fit::problem::Problem;
    let (spec, data) = crate::fit::load(path, None)?;
    let problem = Problem::new(&spec, data).with_context(|| format!("scene {}", path.display()))?;
    let middle = problem.scene(&problem.middle(), problem.points())?;
    let report = check_report(&middle);
    let candidates = crate::fit::solve::expected_candidates(spec.free.len());
    let estimate_s = report.sweep_s * candidates as f64;
    if json {
        let free: Vec<_> = spec.free.iter().map(|f| f.describe()).collect();
        let value = serde_json::json!({
            "fit": true,
            "free": free,
            "data": problem.data.path.display().to_string(),
            "rows": problem.data.rows.len(),
            "measurements": problem.data.measurements(),
            "data_description": crate::fit::describe::json(&problem.data),
            "se_source": crate::fit::describe::se_source(&problem.data),
            "notes": problem.inherited_notes(),
            "candidates": candidates,
            "estimate_s": estimate_s,
        });
        println!("{value:#}");
        return Ok(());
    }
    let data = &problem.data;
    println!(
        "fit scene: {} free {} against {} measured {} ({} of step x, {} of step y) in {} rows of {}",
        spec.free.len(),
        plural(spec.free.len() as u64, "key", "keys"),
        data.measurements(),
        plural(data.measurements() as u64, "value", "values"),
        data.measured_on(0),
        data.measured_on(1),
        data.rows.len(),
        data.path.display()
    );
    for f in &spec.free {
        let scale = if f.log { "log scale" } else { "linear" };
        println!(
            "  {} in [{}, {}] {} ({scale})",
            f.key, f.bounds[0], f.bounds[1], f.units
        );
    }
    if !data.keys.is_empty() {
        println!("the rows set: {}", data.keys.join(", "));
    }
    for line in crate::fit::describe::lines(data) {
        println!("data: {line}");
    }
    for note in problem.inherited_notes() {
        println!("note: {note}");
    }
    println!(
        "each candidate: {} {}; about {candidates} candidates, estimated at {} on {} CPU {}",
        middle.instance_count(),
        plural(middle.instance_count(), "instance", "instances"),
        human_duration(estimate_s),
        report.cores,
        plural(report.cores as u64, "core", "cores")
    );
    println!(
        "the scene at the middle of the bounds:\n{}",
        middle.describe()
    );
    Ok(())
}
