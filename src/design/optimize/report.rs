//! What `pidm optimize` writes: OPT.json (schema in docs/design.md),
//! OPT.toml (the scene at the optimum), OPT.png, and the lines it prints.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde_json::{Value as Json, json};

use super::Found;
use super::search::{Search, objective_value};
use crate::design::model::Evaluation;
use crate::laws::status::STATUS_OK;
use crate::plot::{FitPanel, FitSeries};

/// Where the search came from, for the reports.
pub struct Origin<'a> {
    pub scene: &'a Path,
    pub backend: String,
    pub seed: u64,
    /// The search's wall time [s]: the one field two runs of one seed do
    /// not share.
    pub wall_time_s: f64,
}

/// How the search went, as OPT.json names it.
pub const METHOD: &str = "differential evolution (current-to-best/1/bin, feasibility first by \
     Deb's rules) on about 60 % of each problem's runs, then a compass search on rotating \
     orthogonal directions from its best; the optimum is the best of every run";

/// How a front is made, as OPT.json names it.
pub const FRONT_METHOD: &str = "non-dominated sorting in the population: GDE3 (generalized \
     differential evolution, Kukkonen and Lampinen 2005; rand/1/bin trials, constraint-domination \
     by Deb's rules, NSGA-II's crowding distance); the front is the non-dominated set of every \
     steady, feasible run";

/// The search's verdict.
pub fn status(search: &Search, found: &Found) -> &'static str {
    match found.optimum {
        None => "failed: no run finished",
        Some(i) if search.fitness(0, &search.archive.runs[i]).violation > 0.0 => {
            "infeasible: no run kept every constraint; the optimum is the least violation"
        }
        Some(_) if found.probes.iter().any(|p| !p.changes.is_empty()) => "ok, on a cliff",
        Some(_) => "ok",
    }
}

/// One run as OPT.json gives it: its keys, objectives and status.
fn point(search: &Search, index: usize) -> Json {
    let run = &search.archive.runs[index];
    let keys: serde_json::Map<String, Json> = search
        .spec
        .free
        .iter()
        .zip(&search.archive.values[index])
        .map(|(f, v)| (f.key.clone(), json!(v)))
        .collect();
    let objectives: Vec<Json> = search
        .spec
        .objectives
        .iter()
        .map(|o| {
            let v = objective_value(o, run);
            json!({"quantity": o.quantity.text(), "value": finite(v.value), "se": finite(v.se)})
        })
        .collect();
    let (status, motion) = match run {
        Ok(r) => (json!(r.record.status), json!(r.record.motion.name())),
        Err(why) => (json!(why), Json::Null),
    };
    json!({"values": keys, "objectives": objectives, "status": status, "motion": motion})
}

fn finite(v: f64) -> Json {
    if v.is_finite() { json!(v) } else { Json::Null }
}

/// Each constraint at a run: its slack, the slack's SE and the margin in
/// SEs (absolute where the measurement has no SE).
fn constraints(search: &Search, run: &Evaluation) -> Vec<Json> {
    let Ok(r) = run else {
        return Vec::new();
    };
    search
        .spec
        .constraints
        .iter()
        .map(|c| {
            let s = c.slack(&r.record, r.frequency);
            let margin = if s.se > 0.0 {
                json!({"margin_se": s.value / s.se})
            } else {
                json!({"margin": s.value, "margin_note": "the measurement has no SE (a window or a periodic motion): the margin is absolute"})
            };
            let mut entry = json!({"constraint": c.written, "kept": s.value >= 0.0, "slack": s.value, "slack_se": s.se});
            entry.as_object_mut().unwrap().extend(margin.as_object().unwrap().clone());
            entry
        })
        .collect()
}

/// OPT.json's content.
pub fn json(search: &Search, found: &Found, origin: &Origin) -> Json {
    let spec = search.spec;
    let free: Vec<Json> = spec.free.iter().map(|f| f.describe()).collect();
    let objectives: Vec<Json> = spec
        .objectives
        .iter()
        .map(|o| json!({"sense": o.sense.name(), "quantity": o.quantity.text(), "units": o.quantity.units()}))
        .collect();
    let optimum = found.optimum.map(|i| {
        let mut p = point(search, i);
        p["constraints"] = json!(constraints(search, &search.archive.runs[i]));
        let probes: Vec<Json> = found
            .probes
            .iter()
            .map(|pr| {
                let mut q = point(search, pr.index);
                q["moved"] = json!({"key": spec.free[pr.key].key, "direction": pr.direction});
                q["changes"] = json!(pr.changes);
                q["constraints"] = json!(constraints(search, &search.archive.runs[pr.index]));
                q
            })
            .collect();
        p["neighbourhood"] = json!({
            "offset": "1 % of each key's range (of its logarithm on a log scale), clipped to the bounds",
            "cliff": found.probes.iter().any(|p| !p.changes.is_empty()),
            "probes": probes,
        });
        p
    });
    let front: Vec<Json> = found.front.iter().map(|&i| point(search, i)).collect();
    json!({
        "scene": origin.scene.display().to_string(),
        "backend": origin.backend,
        "seed": origin.seed,
        "method": METHOD,
        "front_method": spec.front().then_some(FRONT_METHOD),
        "free": free,
        "objectives": objectives,
        "subject_to": spec.constraints.iter().map(|c| c.written.clone()).collect::<Vec<_>>(),
        "budget": spec.budget,
        "runs": search.model.runs,
        "status": status(search, found),
        "optimum": optimum,
        "front": spec.front().then_some(front),
        "progress": search.archive.progress.iter().map(|(n, b)| json!([n, finite(*b)])).collect::<Vec<_>>(),
        "wall_time_s": origin.wall_time_s,
    })
}

/// OPT.toml: the scene at the optimum, runnable with `pidm run`.
pub fn toml(search: &Search, found: &Found, origin: &Origin) -> Option<String> {
    let i = found.optimum?;
    let mut out = format!(
        "# pidm optimize of {} (seed {}): the scene at the optimum ({}).\n",
        origin.scene.display(),
        origin.seed,
        status(search, found)
    );
    for (f, v) in search.spec.free.iter().zip(&search.archive.values[i]) {
        writeln!(out, "# {} = {v:e} {}", f.key, f.units).unwrap();
    }
    out.push_str(&search.model.scene_text(&search.archive.values[i]));
    Some(out)
}

/// The lines `pidm optimize` prints.
pub fn table(search: &Search, found: &Found) -> String {
    let mut out = format!("status: {}\n", status(search, found));
    if let Some(i) = found.optimum {
        for (f, v) in search.spec.free.iter().zip(&search.archive.values[i]) {
            writeln!(out, "  {} = {v:.6e} {}", f.key, f.units).unwrap();
        }
        for o in &search.spec.objectives {
            let v = objective_value(o, &search.archive.runs[i]);
            writeln!(
                out,
                "  {} {} = {:.6e} ± {:.2e} {}",
                o.sense.name(),
                o.quantity.text(),
                v.value,
                v.se,
                o.quantity.units()
            )
            .unwrap();
        }
        for c in constraints(search, &search.archive.runs[i]) {
            writeln!(
                out,
                "  {}: slack {:.4e}",
                c["constraint"].as_str().unwrap_or(""),
                c["slack"].as_f64().unwrap_or(f64::NAN)
            )
            .unwrap();
        }
        for p in found.probes.iter().filter(|p| !p.changes.is_empty()) {
            writeln!(
                out,
                "  cliff: {} {}1 %: {}",
                search.spec.free[p.key].key,
                if p.direction > 0.0 { "+" } else { "-" },
                p.changes.join(", ")
            )
            .unwrap();
        }
    }
    if search.spec.front() {
        writeln!(out, "front: {} points", found.front.len()).unwrap();
    }
    writeln!(
        out,
        "runs: {} of a budget of {}",
        search.model.runs, search.spec.budget
    )
    .unwrap();
    out
}

/// How OPT.png shows a quantity: lengths in um, velocities in um/s (the
/// map's units, docs/output.md, in m and m/s, label ticks poorly).
fn shown(q: &crate::design::quantity::Quantity) -> (f64, &'static str) {
    match q.units() {
        "m" => (1e6, "um"),
        "m/s" => (1e6, "um/s"),
        other => (1.0, other),
    }
}

/// One panel of points with their SEs joined by a line.
fn panel(
    title: String,
    x_label: String,
    y_label: String,
    points: Vec<(f64, f64, f64)>,
) -> FitPanel {
    FitPanel {
        title,
        x_label,
        y_label,
        series: vec![FitSeries {
            label: "steady runs".into(),
            curve: points.iter().map(|p| (p.0, p.1)).collect(),
            points,
        }],
    }
}

/// OPT.png: the search's progress, then the front or the objective along
/// each free key through the optimum.
pub fn draw(search: &Search, found: &Found, origin: &Origin, path: &Path) -> Result<()> {
    let spec = search.spec;
    let first = &spec.objectives[0];
    let (k1, u1) = shown(&first.quantity);
    let label1 = format!("{} {} [{u1}]", first.sense.name(), first.quantity.text());
    let progress = FitPanel {
        title: "search progress: the best run so far (feasible first)".into(),
        x_label: "runs".into(),
        y_label: label1.clone(),
        series: vec![FitSeries {
            label: "best so far".into(),
            points: Vec::new(),
            curve: search
                .archive
                .progress
                .iter()
                .filter(|p| p.1.is_finite())
                .map(|&(n, b)| (n as f64, k1 * b))
                .collect(),
        }],
    };
    let mut below = Vec::new();
    if spec.front() {
        let second = &spec.objectives[1];
        let (k2, u2) = shown(&second.quantity);
        let points = found
            .front
            .iter()
            .map(|&i| {
                let run = &search.archive.runs[i];
                let (a, b) = (objective_value(first, run), objective_value(second, run));
                (k2 * b.value, k1 * a.value, k1 * a.se)
            })
            .collect();
        let label2 = format!("{} {} [{u2}]", second.sense.name(), second.quantity.text());
        below.push(panel(
            "front (non-dominated runs)".into(),
            label2,
            label1,
            points,
        ));
    } else {
        for (j, scan) in found.scans.iter().enumerate() {
            let f = &spec.free[j];
            let points = scan
                .iter()
                .filter(
                    |&&i| matches!(&search.archive.runs[i], Ok(r) if r.record.status == STATUS_OK),
                )
                .map(|&i| {
                    let v = objective_value(first, &search.archive.runs[i]);
                    (search.archive.values[i][j], k1 * v.value, k1 * v.se)
                })
                .collect();
            let title = format!("through the optimum along {}", f.key);
            below.push(panel(
                title,
                format!("{} [{}]", f.key, f.units),
                label1.clone(),
                points,
            ));
        }
    }
    let title = vec![
        format!("pidm optimize: {}", origin.scene.display()),
        format!(
            "{}; {} runs, seed {}",
            status(search, found),
            search.model.runs,
            origin.seed
        ),
    ];
    crate::plot::fit_figure(path, &title, &[progress], &below)
}
