//! `pidm check` of a design scene (`[sensitivity]`, `[optimize]`): the
//! study described and checked before any run, with what it will cost.

use std::path::Path;

use anyhow::Result;

use super::check::check_report;
use super::format::{human_duration, plural};
use crate::design::model::Model;

/// `pidm check`: validates and describes a scene without running it, as
/// text or (`json`) as one JSON object on stdout; a design scene here, any
/// other by `check::check_scene`.
pub fn check(path: &Path, json: bool) -> Result<()> {
    let text = crate::scene::read_text(path)?;
    if crate::design::sensitivity::spec::is_sensitivity_scene(&text) {
        check_sensitivity(path, json)
    } else if crate::design::optimize::spec::is_optimize_scene(&text) {
        check_optimize(path, json)
    } else {
        super::check::check_scene(path, &text, json)
    }
}

/// `pidm check` of a sensitivity scene: its inputs, outputs and the
/// N (k + 2) runs it costs.
fn check_sensitivity(path: &Path, json: bool) -> Result<()> {
    let (spec, outputs) = super::sensitivity::load(path)?;
    let keys: Vec<String> = spec.inputs.iter().map(|i| i.key.clone()).collect();
    let model = Model::new(&spec.base_text, "sensitivity", keys, &spec.middle())?;
    let middle = model.scene(&spec.middle())?;
    let report = check_report(&middle);
    let k = spec.inputs.len();
    let runs = spec.samples * (k + 2);
    let estimate_s = report.sweep_s * runs as f64;
    let outputs: Vec<String> = outputs.iter().map(|q| q.text()).collect();
    if json {
        let inputs: Vec<_> = spec
            .inputs
            .iter()
            .map(|i| {
                serde_json::json!({"key": i.key, "units": i.range.units, "distribution": i.describe(), "truncated_share": i.cut()})
            })
            .collect();
        let value = serde_json::json!({
            "sensitivity": true,
            "inputs": inputs,
            "outputs": outputs,
            "samples": spec.samples,
            "runs": runs,
            "estimate_s": estimate_s,
        });
        println!("{value:#}");
        return Ok(());
    }
    println!(
        "sensitivity scene: {} over {k} {}",
        outputs.join(", "),
        plural(k as u64, "input", "inputs")
    );
    for i in &spec.inputs {
        let cut = i.cut();
        let truncated = if cut > 0.0 {
            format!(", truncated to the key's range ({cut:.2e} cut off)")
        } else {
            String::new()
        };
        println!(
            "  {} ~ {} [{}]{truncated}",
            i.key,
            i.describe(),
            i.range.units
        );
    }
    println!(
        "Saltelli's sample: N = {} base rows x (k + 2 = {}) = {runs} runs, estimated at {} on {} CPU {}",
        spec.samples,
        k + 2,
        human_duration(estimate_s),
        report.cores,
        plural(report.cores as u64, "core", "cores")
    );
    println!("the scene at the inputs' medians:\n{}", middle.describe());
    Ok(())
}

/// `pidm check` of an optimize scene: its objectives, free keys,
/// constraints and budget.
fn check_optimize(path: &Path, json: bool) -> Result<()> {
    let (spec, model) = super::optimize::load(path)?;
    let middle = model.scene(&spec.middle())?;
    let report = check_report(&middle);
    let estimate_s = report.sweep_s * spec.budget as f64;
    let objectives: Vec<String> = spec
        .objectives
        .iter()
        .map(|o| format!("{} {}", o.sense.name(), o.quantity.text()))
        .collect();
    let constraints: Vec<String> = spec.constraints.iter().map(|c| c.written.clone()).collect();
    if json {
        let free: Vec<_> = spec.free.iter().map(|f| f.describe()).collect();
        let value = serde_json::json!({
            "optimize": true,
            "objectives": objectives,
            "front": spec.front(),
            "free": free,
            "subject_to": constraints,
            "budget": spec.budget,
            "estimate_s": estimate_s,
        });
        println!("{value:#}");
        return Ok(());
    }
    let what = if spec.front() { "a front: " } else { "" };
    println!("optimize scene: {what}{}", objectives.join(" and "));
    for f in &spec.free {
        let scale = if f.log { "log scale" } else { "linear" };
        println!(
            "  {} in [{}, {}] {} ({scale})",
            f.key, f.bounds[0], f.bounds[1], f.units
        );
    }
    for c in &constraints {
        println!("  subject to {c}");
    }
    println!(
        "a budget of {} runs, estimated at {} on {} CPU {}",
        spec.budget,
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
