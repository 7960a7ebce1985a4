//! What `pidm optimize` and `pidm sensitivity` share on the command line:
//! the backend's flags, the seed, the progress, and where the files go.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::backend::{BackendChoice, Precision, Selected, Workload, select_backend};
use crate::progress::ProgressMode;

/// The flags both design commands take.
#[derive(Clone, Debug, clap::Args)]
pub struct DesignArgs {
    /// Worker threads of the CPU path, from 1 to 4 per core (or 64)
    /// [default: every core].
    #[arg(long, value_parser = crate::backend::select::thread_count)]
    pub threads: Option<usize>,
    /// auto, gpu or cpu, as for `pidm run`; a design command runs in f64
    /// only.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Seed of the search or the sample: the same seed gives the same JSON
    /// file on the CPU (but its wall_time_s).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// How progress is shown on stderr: bar, jsonl (as `pidm run`'s: done,
    /// total, elapsed_s, eta_s, instances_per_s, over the runs) or none
    /// [default: bar on a terminal, else none].
    #[arg(long, value_enum)]
    pub progress: Option<ProgressMode>,
}

impl DesignArgs {
    /// The progress mode asked for, or the terminal's default.
    pub fn progress_mode(&self) -> ProgressMode {
        self.progress
            .unwrap_or_else(ProgressMode::default_for_stderr)
    }

    /// The backend for `workload`, in f64.
    pub fn select(&self, workload: &Workload) -> Result<Selected> {
        select_backend(self.backend, Some(Precision::F64), self.threads, workload)
    }
}

/// The JSON file (`out`, or `results/<scene stem>.<kind>.json`) and its
/// siblings of extensions `siblings`, none of them the scene; the JSON's
/// folder is made.
pub fn out_paths(
    out: Option<&Path>,
    scene: &Path,
    kind: &str,
    siblings: &[&str],
) -> Result<Vec<PathBuf>> {
    let out = out.map(Path::to_owned).unwrap_or_else(|| {
        let stem = scene
            .file_stem()
            .map_or(kind.into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("results").join(format!("{stem}.{kind}.json"))
    });
    if out.extension().and_then(|e| e.to_str()) != Some("json") {
        bail!(
            "--out {}: expected a .json file (the {} {} written beside it)",
            out.display(),
            siblings.join(" and "),
            if siblings.len() == 1 {
                "file is"
            } else {
                "files are"
            }
        );
    }
    let mut paths = vec![out.clone()];
    paths.extend(siblings.iter().map(|ext| out.with_extension(ext)));
    for path in &paths {
        if crate::output::claim::is_same_file(path, scene) {
            bail!(
                "--out {}: {} would overwrite the scene file; give another --out",
                out.display(),
                path.display()
            );
        }
    }
    Ok(paths)
}

/// Makes the folder `path` is written into.
pub fn create_parent(path: &Path) -> Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    Ok(())
}
