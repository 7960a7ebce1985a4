//! `pidm sensitivity`: Sobol' indices and the spread of a scene's
//! quantities over distributions of its keys (`crate::design::sensitivity`,
//! docs/design.md), on the backend chosen, in f64.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::backend::{BackendChoice, Precision, select_backend};
use crate::design::model::Model;
use crate::design::sensitivity::{self, report, spec};
use crate::fit::report::write_whole;
use crate::progress::{Progress, ProgressMode};

/// `pidm sensitivity`'s command line.
#[derive(Clone, Debug, clap::Args)]
pub struct SensitivityCommand {
    /// The scene (TOML with a [sensitivity] table).
    pub scene: PathBuf,
    /// SENS.json; SENS.png is written beside it [default:
    /// results/<scene stem>.sens.json].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write every sample's inputs, status and outputs to this CSV,
    /// in SALib's row order per base row: A, AB_1 ... AB_k, B.
    #[arg(long)]
    pub samples_out: Option<PathBuf>,
    /// Worker threads of the CPU path, from 1 to 4 per core (or 64)
    /// [default: every core].
    #[arg(long, value_parser = crate::backend::select::thread_count)]
    pub threads: Option<usize>,
    /// auto, gpu or cpu, as for `pidm run`; a study runs in f64 only.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Seed of the sample and the bootstrap: the same seed gives the same
    /// SENS.json (but its wall_time_s).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// How progress is shown on stderr: bar, jsonl (as `pidm run`'s: done,
    /// total, elapsed_s, eta_s, instances_per_s) or none [default: bar on
    /// a terminal, else none].
    #[arg(long, value_enum)]
    pub progress: Option<ProgressMode>,
}

/// SENS.json and SENS.png for `out` (which must end in .json), neither of
/// them the scene.
fn outputs(out: &Path, scene: &Path) -> Result<(PathBuf, PathBuf)> {
    if out.extension().and_then(|e| e.to_str()) != Some("json") {
        bail!(
            "--out {}: expected a .json file (SENS.png is written beside it)",
            out.display()
        );
    }
    let png = out.with_extension("png");
    for path in [out, &png] {
        if crate::output::claim::is_same_file(path, scene) {
            bail!("--out {}: it would overwrite the scene file", out.display());
        }
    }
    Ok((out.to_owned(), png))
}

/// A sensitivity scene read and checked: the spec, its model (with the
/// inputs at their medians accepted by the scene's rules) and its outputs.
pub fn load(
    path: &Path,
) -> Result<(
    spec::SensitivityScene,
    Vec<crate::design::quantity::Quantity>,
)> {
    let text = crate::scene::read_text(path)?;
    let spec = spec::read(&text).with_context(|| format!("scene {}", path.display()))?;
    let keys = spec.inputs.iter().map(|i| i.key.clone()).collect();
    let model = Model::new(&spec.base_text, "sensitivity", keys, &spec.middle())
        .with_context(|| format!("scene {}", path.display()))?;
    let outputs = spec
        .outputs(model.backward)
        .with_context(|| format!("scene {}", path.display()))?;
    Ok((spec, outputs))
}

/// Runs `pidm sensitivity`.
pub fn sensitivity(cmd: &SensitivityCommand) -> Result<()> {
    crate::run::install_interrupt_handler();
    let started = Instant::now();
    let out = cmd.out.clone().unwrap_or_else(|| {
        let stem = cmd
            .scene
            .file_stem()
            .map_or("sensitivity".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("results").join(format!("{stem}.sens.json"))
    });
    let (json_path, png_path) = outputs(&out, &cmd.scene)?;
    let (spec, quantities) = load(&cmd.scene)?;
    let keys = spec.inputs.iter().map(|i| i.key.clone()).collect();
    let mut model = Model::new(&spec.base_text, "sensitivity", keys, &spec.middle())?;
    let k = spec.inputs.len();
    let runs = spec.samples * (k + 2);
    let selected = select_backend(
        cmd.backend,
        Some(Precision::F64),
        cmd.threads,
        &model.workload(&spec.middle(), runs as u64)?,
    )?;
    let backend = selected.backend();
    model.on(backend);
    eprintln!(
        "pidm: sensitivity of {} {} to {} {}: N = {} base rows, {runs} runs on {}, f64 (seed {})",
        quantities.len(),
        if quantities.len() == 1 {
            "output"
        } else {
            "outputs"
        },
        k,
        if k == 1 { "input" } else { "inputs" },
        spec.samples,
        backend.describe(),
        cmd.seed
    );
    let mode = cmd
        .progress
        .unwrap_or_else(ProgressMode::default_for_stderr);
    let progress = Progress::new(mode, 0, runs as u64);
    let samples =
        sensitivity::run_samples(&mut model, &spec.inputs, spec.samples, cmd.seed, &|n| {
            progress.inc(n)
        });
    let samples = match samples {
        Ok(s) => {
            progress.finish();
            s
        }
        Err(e) => {
            progress.abandon();
            return Err(e);
        }
    };
    let study = sensitivity::analyse(samples, k, &quantities, cmd.seed);
    let origin = report::Origin {
        scene: &cmd.scene,
        backend: backend.describe(),
        seed: cmd.seed,
        wall_time_s: started.elapsed().as_secs_f64(),
    };
    for path in [Some(&json_path), cmd.samples_out.as_ref()]
        .into_iter()
        .flatten()
    {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("cannot create {}", parent.display()))?;
        }
    }
    if let Some(csv) = &cmd.samples_out {
        write_whole(csv, report::samples_csv(&spec, &study).as_bytes())?;
    }
    let json = report::json(&spec, &study, &origin);
    let partial = png_path.with_extension("partial.png");
    report::draw(&spec, &study, &origin, &partial)?;
    std::fs::rename(&partial, &png_path)
        .with_context(|| format!("cannot write {}", png_path.display()))?;
    write_whole(&json_path, format!("{json:#}\n").as_bytes())?;
    print!("{}", report::table(&spec, &study));
    for w in report::warnings(&spec, &study) {
        eprintln!("pidm: warning: {w}");
    }
    let mut written = vec![
        json_path.display().to_string(),
        png_path.display().to_string(),
    ];
    written.extend(cmd.samples_out.iter().map(|p| p.display().to_string()));
    eprintln!("pidm: wrote {}", written.join(", "));
    Ok(())
}
