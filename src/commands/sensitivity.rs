//! `pidm sensitivity`: Sobol' indices and the spread of a scene's
//! quantities over distributions of its keys (`crate::design::sensitivity`,
//! docs/design.md), on the backend chosen, in f64.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use super::design_args::{DesignArgs, create_parent, out_paths};
use crate::design::model::Model;
use crate::design::sensitivity::{self, report, spec};
use crate::fit::report::write_whole;
use crate::progress::Progress;

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
    #[command(flatten)]
    pub args: DesignArgs,
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
    let paths = out_paths(cmd.out.as_deref(), &cmd.scene, "sens", &["png"])?;
    let (json_path, png_path) = (paths[0].clone(), paths[1].clone());
    let (spec, quantities) = load(&cmd.scene)?;
    let keys = spec.inputs.iter().map(|i| i.key.clone()).collect();
    let mut model = Model::new(&spec.base_text, "sensitivity", keys, &spec.middle())?;
    let k = spec.inputs.len();
    let runs = spec.samples * (k + 2);
    let selected = cmd
        .args
        .select(&model.workload(&spec.middle(), runs as u64)?)?;
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
        cmd.args.seed
    );
    let progress = Progress::new(cmd.args.progress_mode(), 0, runs as u64);
    let samples = sensitivity::run_samples(
        &mut model,
        &spec.inputs,
        spec.samples,
        cmd.args.seed,
        &|n| progress.inc(n),
    );
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
    let study = sensitivity::analyse(samples, k, &quantities, cmd.args.seed);
    let origin = report::Origin {
        scene: &cmd.scene,
        backend: backend.describe(),
        seed: cmd.args.seed,
        wall_time_s: started.elapsed().as_secs_f64(),
    };
    for path in [Some(&json_path), cmd.samples_out.as_ref()]
        .into_iter()
        .flatten()
    {
        create_parent(path)?;
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
