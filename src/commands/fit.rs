//! `pidm fit`: a fit scene's free keys calibrated to its measured steps
//! (`crate::fit`), on the backend chosen, in f64.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::backend::{BackendChoice, Precision, select_backend};
use crate::fit::{FitOptions, Outputs, problem::Problem, solve::Ending};
use crate::progress::ProgressMode;

/// `pidm fit`'s command line.
#[derive(Clone, Debug, clap::Args)]
pub struct FitCommand {
    /// The fit scene (TOML with a [fit] table).
    pub scene: PathBuf,
    /// FIT.json; FIT.toml and FIT.png are written beside it [default:
    /// results/<scene stem>.fit.json].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The CSV of measured steps instead of the scene's [fit] data.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Worker threads of the CPU path, from 1 to 4 per core (or 64)
    /// [default: every core].
    #[arg(long, value_parser = crate::backend::select::thread_count)]
    pub threads: Option<usize>,
    /// auto, gpu or cpu, as for `pidm run`; a fit runs in f64 only.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Seed of the global search: the same seed gives the same fit.
    #[arg(long, default_value_t = crate::fit::DEFAULT_SEED)]
    pub seed: u64,
    /// How progress is shown on stderr: bar (the stage and best chi2),
    /// jsonl (one JSON object per batch: stage, batch, evaluations,
    /// best_chi2) or none [default: bar on a terminal, else none].
    #[arg(long, value_enum)]
    pub progress: Option<ProgressMode>,
    /// Skip the profile-likelihood intervals (68 % and 95 % per free key;
    /// about as many candidates again as the fit, docs/fit.md).
    #[arg(long)]
    pub no_intervals: bool,
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
    let problem =
        Problem::new(&spec, data).with_context(|| format!("scene {}", cmd.scene.display()))?;
    let data_count = problem.data.measurements();
    let selected = select_backend(
        cmd.backend,
        Some(Precision::F64),
        cmd.threads,
        &problem.workload()?,
    )?;
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
        seed: cmd.seed,
        progress: cmd
            .progress
            .unwrap_or_else(ProgressMode::default_for_stderr),
        intervals: !cmd.no_intervals,
    };
    let (answer, table) = crate::fit::fit(&opts, problem, backend)?;
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
