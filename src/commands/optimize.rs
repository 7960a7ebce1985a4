//! `pidm optimize`: the best values of a scene's free keys for an
//! objective under constraints, or the front between two objectives
//! (`crate::design::optimize`, docs/design.md), on the backend chosen, in
//! f64.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::backend::{BackendChoice, Precision, select_backend};
use crate::design::model::Model;
use crate::design::optimize::{self, report, spec};
use crate::fit::report::write_whole;
use crate::progress::{Progress, ProgressMode};

/// `pidm optimize`'s command line.
#[derive(Clone, Debug, clap::Args)]
pub struct OptimizeCommand {
    /// The scene (TOML with an [optimize] table).
    pub scene: PathBuf,
    /// OPT.json; OPT.toml and OPT.png are written beside it [default:
    /// results/<scene stem>.opt.json].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads of the CPU path, from 1 to 4 per core (or 64)
    /// [default: every core].
    #[arg(long, value_parser = crate::backend::select::thread_count)]
    pub threads: Option<usize>,
    /// auto, gpu or cpu, as for `pidm run`; a search runs in f64 only.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Seed of the search: the same seed gives the same OPT.json (but its
    /// wall_time_s).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// How progress is shown on stderr: bar, jsonl (as `pidm run`'s, over
    /// the budget's runs) or none [default: bar on a terminal, else none].
    #[arg(long, value_enum)]
    pub progress: Option<ProgressMode>,
}

/// OPT.json, OPT.toml and OPT.png for `out` (a .json), none the scene.
fn outputs(out: &Path, scene: &Path) -> Result<[PathBuf; 3]> {
    if out.extension().and_then(|e| e.to_str()) != Some("json") {
        bail!(
            "--out {}: expected a .json file (OPT.toml and OPT.png are written beside it)",
            out.display()
        );
    }
    let paths = [
        out.to_owned(),
        out.with_extension("toml"),
        out.with_extension("png"),
    ];
    for path in &paths {
        if crate::output::claim::is_same_file(path, scene) {
            bail!(
                "--out {}: {} would overwrite the scene file",
                out.display(),
                path.display()
            );
        }
    }
    Ok(paths)
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
    let out = cmd.out.clone().unwrap_or_else(|| {
        let stem = cmd
            .scene
            .file_stem()
            .map_or("optimize".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("results").join(format!("{stem}.opt.json"))
    });
    let [json_path, toml_path, png_path] = outputs(&out, &cmd.scene)?;
    let (spec, mut model) = load(&cmd.scene)?;
    let selected = select_backend(
        cmd.backend,
        Some(Precision::F64),
        cmd.threads,
        &model.workload(&spec.middle(), spec.budget as u64)?,
    )?;
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
        cmd.seed
    );
    let mode = cmd
        .progress
        .unwrap_or_else(ProgressMode::default_for_stderr);
    let progress = Progress::new(mode, 0, spec.budget as u64);
    let done = |n| progress.inc(n);
    let mut search = optimize::new_search(&spec, &mut model, cmd.seed, &done);
    let found = match optimize::optimize(&mut search) {
        Ok(found) => {
            progress.finish();
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
        seed: cmd.seed,
        wall_time_s: started.elapsed().as_secs_f64(),
    };
    if let Some(parent) = json_path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
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
