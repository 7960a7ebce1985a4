//! A fit's answer written out: `FIT.json` (the schema of docs/fit.md),
//! `FIT.toml` (the scene with the fitted values, ready for `pidm run`) and
//! the table printed on the terminal. Every file is written whole under a
//! temporary name and renamed into place.

use std::path::Path;

use anyhow::{Context, Result};
use serde_json::{Value, json};

use super::judge::Answer;
use super::problem::Problem;
use super::solve::Ending;
use crate::model::AXIS_NAMES;

/// Where a fit came from: the scene file, the backend and the seed.
pub struct Origin<'a> {
    pub scene: &'a Path,
    pub backend: String,
    pub seed: u64,
}

impl Ending {
    /// The name `FIT.json` gives it.
    pub fn name(self) -> &'static str {
        match self {
            Ending::Converged => "converged",
            Ending::NotConverged => "not converged",
            Ending::Interrupted => "interrupted",
        }
    }
}

/// `FIT.json`'s object.
pub fn json(problem: &Problem, answer: &Answer, origin: &Origin) -> Value {
    let mut parameters = serde_json::Map::new();
    for (i, free) in problem.free.iter().enumerate() {
        parameters.insert(
            free.key.clone(),
            json!({
                "value": answer.values[i],
                "se": answer.se[i],
                "se_scaled": answer.se_scaled.as_ref().map(|s| s[i]),
                "interval68": answer.intervals.as_ref().map(|v| [v[i].lo68, v[i].hi68]),
                "interval95": answer.intervals.as_ref().map(|v| [v[i].lo95, v[i].hi95]),
                "bounds": free.bounds,
                "units": free.units,
                "scale": if free.log { "log" } else { "linear" },
            }),
        );
    }
    json!({
        "pidm_version": env!("CARGO_PKG_VERSION"),
        "scene": origin.scene.display().to_string(),
        "data": problem.data.path.display().to_string(),
        "data_description": super::describe::json(&problem.data),
        "se_source": super::describe::se_source(&problem.data),
        "backend": origin.backend,
        "seed": origin.seed,
        "status": answer.ending.name(),
        "order": answer.keys,
        "parameters": parameters,
        "correlation": answer.correlation,
        "covariance": answer.covariance,
        "errors": problem.errors.name(),
        "chi2": answer.chi2,
        "dof": answer.dof,
        "reduced_chi2": (answer.dof > 0).then(|| answer.chi2 / answer.dof as f64),
        "p_value": answer.p_value,
        "evaluations": problem.evaluations,
        "infeasible": problem.infeasible,
        "failed": problem.failed,
        "failures": problem.reasons,
        "identifiable": answer.identifiable,
        "warnings": answer.warnings,
        "notes": answer.notes,
        "weights": weights(answer),
        "step_tolerance": problem.step_tolerance.map(|fit| json!({
            "scene": problem.scene_step_tolerance, "fit": fit
        })),
        "condition": answer.condition,
        "generations": answer.generations,
        "iterations": answer.iterations,
        "rows": rows(problem, answer),
    })
}

fn weights(answer: &Answer) -> Value {
    let mut out = serde_json::Map::new();
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        out.insert(
            (*name).into(),
            if answer.weights.known[a] {
                json!({ "from": "data" })
            } else {
                json!({ "from": "residuals", "scale": answer.weights.scale[a] })
            },
        );
    }
    Value::Object(out)
}

/// Each data row with the model at the fitted values.
fn rows(problem: &Problem, answer: &Answer) -> Value {
    let rows = problem
        .data
        .rows
        .iter()
        .zip(&answer.models)
        .map(|(row, model)| {
            let mut out = serde_json::Map::new();
            out.insert("line".into(), json!(row.line));
            if row.lines.len() > 1 {
                out.insert("lines".into(), json!(row.lines));
            }
            for (key, value) in problem.row_keys(row) {
                out.insert(key, json!(value));
            }
            for (a, name) in AXIS_NAMES.iter().enumerate() {
                if let Some(step) = row.step[a] {
                    let se = answer.weights.data_se(row.se[a], a);
                    out.insert(format!("step_{name}"), json!(step));
                    out.insert(format!("step_{name}_se"), json!(se));
                    // The normalized residual: (model - data) / the data's SE.
                    out.insert(
                        format!("residual_{name}"),
                        json!((model.step[a] - step) / se),
                    );
                }
                out.insert(format!("model_step_{name}"), json!(model.step[a]));
                out.insert(format!("model_step_{name}_se"), json!(model.se[a]));
            }
            Value::Object(out)
        });
    Value::Array(rows.collect())
}

/// `FIT.toml`: the scene with the fitted values, without `[fit]`.
pub fn fitted_toml(problem: &Problem, answer: &Answer, origin: &Origin) -> String {
    let mut text = format!(
        "# Fitted by pidm fit {} from {} and {} ({}, chi2 {:.4e} on {} degrees of freedom).\n",
        env!("CARGO_PKG_VERSION"),
        origin.scene.display(),
        problem.data.path.display(),
        answer.ending.name(),
        answer.chi2,
        answer.dof
    );
    for (i, key) in answer.keys.iter().enumerate() {
        text += &format!("# {key} = {} +- {}\n", answer.values[i], answer.se[i]);
    }
    text += "\n";
    text + &problem.fitted_scene(&answer.values)
}

/// The terminal's table of values and standard errors, then the warnings
/// and notes.
pub fn table(problem: &Problem, answer: &Answer) -> String {
    let width = answer
        .keys
        .iter()
        .map(|k| k.len())
        .max()
        .unwrap_or(3)
        .max(3);
    let mut out = format!(
        "{:<width$}  {:>14}  {:>12}  {:>8}  {:>27}  units\n",
        "key", "value", "se", "se %", "68 % interval"
    );
    let side = |v: Option<f64>| v.map_or("open".to_owned(), |v| format!("{v:.5e}"));
    for (i, free) in problem.free.iter().enumerate() {
        let (v, se) = (answer.values[i], answer.se[i]);
        let interval = match &answer.intervals {
            Some(all) => format!("{} .. {}", side(all[i].lo68), side(all[i].hi68)),
            None => "-".into(),
        };
        out += &format!(
            "{:<width$}  {v:>14.6e}  {se:>12.4e}  {:>8.2}  {interval:>27}  {}\n",
            free.key,
            100.0 * se / v.abs(),
            free.units
        );
    }
    if let Some(scaled) = answer
        .se_scaled
        .as_ref()
        .filter(|_| problem.errors == super::spec::Errors::Given)
    {
        let shown: Vec<String> = answer
            .keys
            .iter()
            .zip(scaled)
            .map(|(k, se)| format!("{k} {se:.4e}"))
            .collect();
        out += &format!("scaled se: {}\n", shown.join(", "));
    }
    let p = match answer.p_value {
        Some(p) => format!(" (p = {p:.3e})"),
        None => String::new(),
    };
    out += &format!(
        "chi2 {:.4e} on {} degrees of freedom{p}; {} candidates evaluated ({} infeasible, {} failed); {}\n",
        answer.chi2,
        answer.dof,
        problem.evaluations,
        problem.infeasible,
        problem.failed,
        answer.ending.name()
    );
    for line in super::describe::lines(&problem.data) {
        out += &format!("data: {line}\n");
    }
    for warning in &answer.warnings {
        out += &format!("warning: {warning}\n");
    }
    for note in &answer.notes {
        out += &format!("note: {note}\n");
    }
    if !answer.identifiable {
        out += "not identifiable: the data do not determine every free key (see the warnings)\n";
    }
    out
}

/// Writes `bytes` to `path` whole: under a temporary name, then renamed.
pub fn write_whole(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut partial = path.as_os_str().to_owned();
    partial.push(".partial");
    let partial = std::path::PathBuf::from(partial);
    std::fs::write(&partial, bytes)
        .with_context(|| format!("cannot write {}", partial.display()))?;
    std::fs::rename(&partial, path).with_context(|| format!("cannot write {}", path.display()))
}
