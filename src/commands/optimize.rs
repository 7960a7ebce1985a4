//! `pidm optimize`: the best values of a scene's free keys for an
//! objective under constraints, or the front between two objectives
//! (`crate::design::optimize`, docs/design.md), on the backend chosen, in
//! f64.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use super::design_args::{DesignArgs, create_parent, out_paths};
use crate::design::model::Model;
use crate::design::optimize::{self, report, spec};
use crate::fit::report::write_whole;
use crate::progress::Progress;

/// `pidm optimize`'s command line.
#[derive(Clone, Debug, clap::Args)]
pub struct OptimizeCommand {
    /// The scene (TOML with an [optimize] table).
    pub scene: PathBuf,
    /// OPT.json; OPT.toml and OPT.png are written beside it [default:
    /// results/<scene stem>.opt.json].
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub args: DesignArgs,
}

/// An optimize scene read and checked: its spec and model (the middle of
/// the bounds accepted by the scene's rules).
pub fn load(path: &Path) -> Result<(spec::OptimizeScene, Model<'static>)> {
    let text = crate::scene::read_text(path)?;
    let spec = spec::read(&text).with_context(|| format!("scene {}", path.display()))?;
    let keys = spec.free.iter().map(|f| f.key.clone()).collect();
    let model = Model::new(&spec.base_text, "optimize", keys, &spec.middle())
        .with_context(|| format!("scene {}", path.display()))?;
    Ok((spec, model))
}

/// Runs `pidm optimize`.
pub fn optimize(cmd: &OptimizeCommand) -> Result<()> {
    crate::run::install_interrupt_handler();
    let started = Instant::now();
    let paths = out_paths(cmd.out.as_deref(), &cmd.scene, "opt", &["toml", "png"])?;
    let [json_path, toml_path, png_path] = [0, 1, 2].map(|k| paths[k].clone());
    let (spec, mut model) = load(&cmd.scene)?;
    let selected = cmd
        .args
        .select(&model.workload(&spec.middle(), spec.budget as u64)?)?;
    let backend = selected.backend();
    model.on(backend);
    let objectives: Vec<String> = spec
        .objectives
        .iter()
        .map(|o| format!("{} {}", o.sense.name(), o.quantity.text()))
        .collect();
    eprintln!(
        "pidm: optimize: {} over {} free {}, {} {}, a budget of {} runs on {}, f64 (seed {})",
        objectives.join(" and "),
        spec.free.len(),
        if spec.free.len() == 1 { "key" } else { "keys" },
        spec.constraints.len(),
        if spec.constraints.len() == 1 {
            "constraint"
        } else {
            "constraints"
        },
        spec.budget,
        backend.describe(),
        cmd.args.seed
    );
    let progress = Progress::new(cmd.args.progress_mode(), 0, spec.budget as u64);
    let done = |n| progress.inc(n);
    let mut search = optimize::new_search(&spec, &mut model, cmd.args.seed, &done);
    let found = match optimize::optimize(&mut search) {
        Ok(found) => {
            progress.finish_at(search.model.runs as u64);
            found
        }
        Err(e) => {
            progress.abandon();
            return Err(e);
        }
    };
    let origin = report::Origin {
        scene: &cmd.scene,
        backend: backend.describe(),
        seed: cmd.args.seed,
        wall_time_s: started.elapsed().as_secs_f64(),
    };
    create_parent(&json_path)?;
    let partial = png_path.with_extension("partial.png");
    report::draw(&search, &found, &origin, &partial)?;
    std::fs::rename(&partial, &png_path)
        .with_context(|| format!("cannot write {}", png_path.display()))?;
    if let Some(text) = report::toml(&search, &found, &origin) {
        write_whole(&toml_path, text.as_bytes())?;
    }
    let json = report::json(&search, &found, &origin);
    write_whole(&json_path, format!("{json:#}\n").as_bytes())?;
    print!("{}", report::table(&search, &found));
    eprintln!(
        "pidm: wrote {}, {} and {}",
        json_path.display(),
        toml_path.display(),
        png_path.display()
    );
    Ok(())
}
