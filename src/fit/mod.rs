//! `pidm fit`: the model calibrated to measured steps (docs/fit.md).
//!
//! A fit scene is a scene with a `[fit]` table ([`spec`]) naming a CSV of
//! measured steady steps ([`data`], its header's units in [`columns`];
//! velocities become steps in [`velocity`], repeated settings are pooled
//! in [`repeats`]) and the free keys with their bounds.
//! Each candidate set of values becomes a scene with one point per data
//! row ([`problem`]), so every scene rule applies to it; a batch of
//! candidates is integrated at once on one backend. The search
//! ([`solve`]) runs differential evolution over the bounds
//! ([`crate::search::evolution`]),
//! then Levenberg-Marquardt ([`lsq`]) with finite-difference Jacobians,
//! weighing each measurement by [`weights`]; [`judge`] turns the Jacobian
//! at the best point into standard errors, correlations and warnings;
//! [`report`] writes FIT.json and FIT.toml, [`curves`] FIT.png.

pub mod columns;
pub mod curves;
pub mod data;
pub mod describe;
pub mod goodness;
pub mod jacobian;
pub mod judge;
pub mod lsq;
pub mod problem;
pub mod profile;
pub mod repeats;
pub mod report;
pub mod solve;
pub mod spec;
pub mod ticker;
pub mod velocity;
pub mod weights;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::backend::Backend;
use crate::progress::ProgressMode;

/// The default `--seed`: a fit is reproducible unless asked otherwise.
pub const DEFAULT_SEED: u64 = 1;

/// What `pidm fit` was asked.
#[derive(Clone, Debug)]
pub struct FitOptions {
    pub scene: PathBuf,
    /// `FIT.json`; `FIT.toml` and `FIT.png` are written beside it.
    pub out: PathBuf,
    pub seed: u64,
    pub progress: ProgressMode,
    /// Whether the profile-likelihood intervals are walked.
    pub intervals: bool,
}

/// The three files a fit writes.
pub struct Outputs {
    pub json: PathBuf,
    pub toml: PathBuf,
    pub png: PathBuf,
}

impl Outputs {
    /// `out` and its `.toml` and `.png` siblings; `out` must end in `.json`,
    /// and none of them may be the scene file itself.
    pub fn beside(out: &Path, scene: &Path) -> Result<Outputs> {
        if out.extension().and_then(|e| e.to_str()) != Some("json") {
            bail!(
                "--out {}: expected a .json file (FIT.toml and FIT.png are written beside it)",
                out.display()
            );
        }
        let outputs = Outputs {
            json: out.to_owned(),
            toml: out.with_extension("toml"),
            png: out.with_extension("png"),
        };
        for path in [&outputs.json, &outputs.toml, &outputs.png] {
            if crate::output::claim::is_same_file(path, scene) {
                bail!(
                    "--out {}: {} would overwrite the scene file; give another --out",
                    out.display(),
                    path.display()
                );
            }
        }
        Ok(outputs)
    }
}

/// A fit scene read and checked: its `[fit]` and its data (from `data`
/// when given, instead of `[fit] data`).
pub fn load(scene: &Path, data: Option<&Path>) -> Result<(spec::FitScene, data::Data)> {
    let text = crate::scene::read_text(scene)?;
    let mut fit = spec::read(&text, scene).with_context(|| format!("scene {}", scene.display()))?;
    if let Some(data) = data {
        fit.data = data.to_owned();
    }
    let data = data::Data::read(&fit.data)?;
    Ok((fit, data))
}

/// Runs a fit of `problem` (its scene and data read by [`load`]) on
/// `backend` and writes its files; the answer, for the caller to print.
pub fn fit<'a>(
    opts: &FitOptions,
    mut problem: problem::Problem<'a>,
    backend: &'a dyn Backend,
) -> Result<(judge::Answer, String)> {
    let outputs = Outputs::beside(&opts.out, &opts.scene)?;
    problem.on(backend);
    let mut search = solve::Search::new(&mut problem, ticker::Ticker::new(opts.progress));
    search.intervals = opts.intervals;
    let found = search.run(opts.seed)?;
    let answer = judge::judge(&problem, found);
    let origin = report::Origin {
        scene: &opts.scene,
        backend: backend.describe(),
        seed: opts.seed,
    };
    let json = report::json(&problem, &answer, &origin);
    report::write_whole(&outputs.json, format!("{json:#}\n").as_bytes())?;
    let toml = report::fitted_toml(&problem, &answer, &origin);
    report::write_whole(&outputs.toml, toml.as_bytes())?;
    if answer.ending != solve::Ending::Interrupted {
        let partial = outputs.png.with_extension("partial.png");
        curves::draw(&problem, &answer, &partial)?;
        std::fs::rename(&partial, &outputs.png)
            .with_context(|| format!("cannot write {}", outputs.png.display()))?;
    }
    Ok((answer.clone(), report::table(&problem, &answer)))
}
