//! What `pidm sensitivity` writes: SENS.json (schema in docs/design.md),
//! SENS.png, the samples' CSV (`--samples-out`) and the table it prints.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde_json::{Value, json};

use super::spec::SensitivityScene;
use super::{Analysis, Study};
use crate::search::distributions::NOISE_WARNING;
use crate::search::sobol::RESAMPLES;

/// Where the study came from, for the reports.
pub struct Origin<'a> {
    pub scene: &'a Path,
    pub backend: String,
    pub seed: u64,
    /// The study's wall time [s]: the one field that differs between two
    /// runs of one seed.
    pub wall_time_s: f64,
}

/// How the sample was drawn, as SENS.json says it.
pub const SAMPLER: &str = "Saltelli's scheme without second-order indices: base matrices A and B \
     of N rows, plain Monte Carlo from the seeded SplitMix64 generator, and AB_i (A with column i \
     from B); N (k + 2) runs in SALib's row order A, AB_1 ... AB_k, B";

/// SENS.json's content.
pub fn json(spec: &SensitivityScene, study: &Study, origin: &Origin) -> Value {
    let inputs: Vec<Value> = spec
        .inputs
        .iter()
        .map(|i| {
            json!({
                "key": i.key,
                "units": i.range.units,
                "distribution": i.describe(),
                "range": [i.range.low, i.range.high],
                "truncated_share": i.cut(),
            })
        })
        .collect();
    let outputs: Vec<Value> = study.analyses.iter().map(output).collect();
    json!({
        "scene": origin.scene.display().to_string(),
        "backend": origin.backend,
        "seed": origin.seed,
        "sampler": SAMPLER,
        "estimators": {
            "first_order": "Saltelli et al. (2010)",
            "total": "Jansen (1999)",
            "confidence": format!("bootstrap 95 % half-width over {RESAMPLES} resamples of the base rows"),
        },
        "samples": spec.samples,
        "runs": study.samples.runs.len(),
        "runs_failed": study.failed,
        "failure_reasons": study.reasons,
        "rows_dropped": study.dropped,
        "rows_used": study.rows - study.dropped,
        "conditioned": if study.dropped > 0 {
            "the indices and the spread are conditioned on the base rows whose runs all finished"
        } else {
            "no base row was dropped"
        },
        "inputs": inputs,
        "outputs": outputs,
        "warnings": warnings(spec, study),
        "wall_time_s": origin.wall_time_s,
    })
}

/// One output's entry.
fn output(a: &Analysis) -> Value {
    let mut entry = json!({
        "quantity": a.quantity.text(),
        "units": a.quantity.units(),
    });
    match &a.indices {
        Ok(ix) => {
            entry["first"] = json!(ix.first);
            entry["first_conf"] = json!(ix.first_conf);
            entry["total"] = json!(ix.total);
            entry["total_conf"] = json!(ix.total_conf);
        }
        Err(why) => entry["indices_error"] = json!(why),
    }
    match &a.spread {
        Ok(s) => {
            entry["mean"] = json!(s.mean);
            entry["sd"] = json!(s.sd);
            entry["quantiles"] =
                json!({"5": s.quantiles[0], "50": s.quantiles[1], "95": s.quantiles[2]});
            entry["noise"] = json!(s.noise.is_finite().then_some(s.noise));
        }
        Err(why) => entry["spread_error"] = json!(why),
    }
    entry
}

/// What the user must read before trusting the numbers.
pub fn warnings(spec: &SensitivityScene, study: &Study) -> Vec<String> {
    let mut out = Vec::new();
    for i in &spec.inputs {
        let cut = i.cut();
        if cut > 0.0 {
            out.push(format!(
                "{}: the distribution is truncated to the key's range ({}); {:.3e} of it is cut off",
                i.key,
                i.range.expected(),
                cut
            ));
        }
    }
    if study.dropped > 0 {
        out.push(format!(
            "{} of {} base rows dropped (a run of theirs failed: {}); the indices are conditioned \
             on the rows kept",
            study.dropped,
            study.rows,
            study.reasons.join("; ")
        ));
    }
    for a in &study.analyses {
        if a.noisy() {
            let noise = a.spread.as_ref().map_or(0.0, |s| s.noise);
            out.push(format!(
                "{}: the model's noise (mean SE^2) is {:.1} % of the output's variance, above {} %: \
                 the indices carry it; tighten simulation.step_tolerance",
                a.quantity.text(),
                100.0 * noise,
                100.0 * NOISE_WARNING
            ));
        }
        if let Err(why) = &a.indices {
            out.push(format!("{}: no indices: {why}", a.quantity.text()));
        }
    }
    out
}

/// The samples' CSV: per run its base row, matrix (A, AB_i, B), inputs,
/// status and outputs with their SEs, in SALib's row order.
pub fn samples_csv(spec: &SensitivityScene, study: &Study) -> String {
    let k = spec.inputs.len();
    let mut out = String::from("row,matrix");
    for i in &spec.inputs {
        write!(out, ",{}", i.key).unwrap();
    }
    out.push_str(",status");
    for a in &study.analyses {
        let name = a.quantity.text();
        write!(out, ",\"{name}\",\"{name}_se\"").unwrap();
    }
    out.push('\n');
    for (n, (values, run)) in study
        .samples
        .values
        .iter()
        .zip(&study.samples.runs)
        .enumerate()
    {
        let (row, col) = (n / (k + 2), n % (k + 2));
        let matrix = match col {
            0 => "A".to_owned(),
            c if c == k + 1 => "B".to_owned(),
            c => format!("AB_{c}"),
        };
        write!(out, "{row},{matrix}").unwrap();
        for v in values {
            write!(out, ",{v:e}").unwrap();
        }
        match run {
            Ok(r) => {
                write!(out, ",{}", r.record.status).unwrap();
                for a in &study.analyses {
                    let v = a.quantity.value(&r.record, r.frequency);
                    write!(out, ",{:e},{:e}", v.value, v.se).unwrap();
                }
            }
            Err(_) => {
                out.push_str(",refused");
                out.push_str(&",nan".repeat(2 * study.analyses.len()));
            }
        }
        out.push('\n');
    }
    out
}

/// The table `pidm sensitivity` prints.
pub fn table(spec: &SensitivityScene, study: &Study) -> String {
    let mut out = String::new();
    for a in &study.analyses {
        writeln!(out, "{} [{}]", a.quantity.text(), a.quantity.units()).unwrap();
        if let Ok(s) = &a.spread {
            writeln!(
                out,
                "  mean {:.6e}  sd {:.3e}  5/50/95 % {:.4e} / {:.4e} / {:.4e}  noise {:.2e}",
                s.mean, s.sd, s.quantiles[0], s.quantiles[1], s.quantiles[2], s.noise
            )
            .unwrap();
        }
        match &a.indices {
            Ok(ix) => {
                writeln!(
                    out,
                    "  {:<32} {:>16} {:>16}",
                    "input", "S1 ± 95 %", "ST ± 95 %"
                )
                .unwrap();
                for (j, i) in spec.inputs.iter().enumerate() {
                    writeln!(
                        out,
                        "  {:<32} {:>7.3} ± {:<6.3} {:>7.3} ± {:<6.3}",
                        i.key, ix.first[j], ix.first_conf[j], ix.total[j], ix.total_conf[j]
                    )
                    .unwrap();
                }
            }
            Err(why) => writeln!(out, "  no indices: {why}").unwrap(),
        }
    }
    out
}

/// SENS.png: one panel of bars per output.
pub fn draw(spec: &SensitivityScene, study: &Study, origin: &Origin, path: &Path) -> Result<()> {
    let keys: Vec<String> = spec.inputs.iter().map(|i| i.key.clone()).collect();
    let panels: Vec<crate::plot::IndexPanel> = study
        .analyses
        .iter()
        .map(|a| {
            let title = format!("{} [{}]", a.quantity.text(), a.quantity.units());
            match &a.indices {
                Ok(ix) => crate::plot::IndexPanel {
                    title,
                    keys: keys.clone(),
                    first: ix.first.clone(),
                    first_conf: ix.first_conf.clone(),
                    total: ix.total.clone(),
                    total_conf: ix.total_conf.clone(),
                    note: a
                        .noisy()
                        .then(|| "noise above 1 % of the variance".to_owned()),
                },
                Err(why) => crate::plot::IndexPanel {
                    title,
                    keys: Vec::new(),
                    first: Vec::new(),
                    first_conf: Vec::new(),
                    total: Vec::new(),
                    total_conf: Vec::new(),
                    note: Some(why.clone()),
                },
            }
        })
        .collect();
    let title = vec![
        format!("pidm sensitivity: {}", origin.scene.display()),
        format!(
            "Sobol' indices, N = {} base rows ({} used), {} runs, seed {}",
            spec.samples,
            study.rows - study.dropped,
            study.samples.runs.len(),
            origin.seed
        ),
    ];
    crate::plot::sensitivity_figure(path, &title, &panels)
}
