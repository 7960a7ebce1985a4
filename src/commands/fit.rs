//! `pidm fit`: a fit scene's free keys calibrated to its measured steps
//! (`crate::fit`), on the backend chosen, in f64.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::backend::{BackendChoice, Precision, select_backend};
use crate::fit::{FitOptions, Outputs, problem::Problem, solve::Ending};
use crate::progress::ProgressMode;

/// Options of `pidm fit`.
#[derive(Clone, Debug)]
pub struct FitCommand {
    pub scene: PathBuf,
    /// FIT.json [default: results/<scene stem>.fit.json].
    pub out: Option<PathBuf>,
    /// The data file instead of the scene's `[fit] data`.
    pub data: Option<PathBuf>,
    pub threads: Option<usize>,
    pub backend: BackendChoice,
    pub seed: u64,
    pub progress: Option<ProgressMode>,
}

/// Runs `pidm fit`; returns whether it was interrupted (the best point so
/// far is written either way).
pub fn fit(cmd: &FitCommand) -> Result<bool> {
    crate::run::install_interrupt_handler();
    let out = cmd.out.clone().unwrap_or_else(|| {
        let stem = cmd
            .scene
            .file_stem()
            .map_or("fit".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("results").join(format!("{stem}.fit.json"))
    });
    let outputs = Outputs::beside(&out, &cmd.scene)?;
    let (spec, data) = crate::fit::load(&cmd.scene, cmd.data.as_deref())?;
    let data_count = data.measurements();
    let problem =
        Problem::new(&spec, data).with_context(|| format!("scene {}", cmd.scene.display()))?;
    let selected = select_backend(
        cmd.backend,
        Some(Precision::F64),
        cmd.threads,
        &problem.workload()?,
    )?;
    drop(problem);
    let backend = selected.backend();
    eprintln!(
        "pidm: fitting {} free {} to {} measured values of {} on {}, f64 (seed {})",
        spec.free.len(),
        if spec.free.len() == 1 { "key" } else { "keys" },
        data_count,
        spec.data.display(),
        backend.describe(),
        cmd.seed
    );
    if let Some(parent) = outputs.json.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    let opts = FitOptions {
        scene: cmd.scene.clone(),
        out: outputs.json.clone(),
        data: cmd.data.clone(),
        seed: cmd.seed,
        progress: cmd
            .progress
            .unwrap_or_else(ProgressMode::default_for_stderr),
    };
    let (answer, table) = crate::fit::fit(&opts, backend)?;
    print!("{table}");
    let written = if answer.ending == Ending::Interrupted {
        format!("{} and {}", outputs.json.display(), outputs.toml.display())
    } else {
        format!(
            "{}, {} and {}",
            outputs.json.display(),
            outputs.toml.display(),
            outputs.png.display()
        )
    };
    eprintln!("pidm: wrote {written}");
    Ok(answer.ending == Ending::Interrupted)
}
