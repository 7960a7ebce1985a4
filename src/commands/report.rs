//! `pidm report`: the paper report of the shipped (or given) scenes.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::scenes::load_scenes;

/// `pidm report`: writes the paper report to `out`.
pub fn report(paths: &[PathBuf], out: &Path) -> Result<()> {
    let defaults: Vec<PathBuf> = crate::scene::SHIPPED
        .iter()
        .map(|(path, _)| PathBuf::from(path))
        .collect();
    let paths = if paths.is_empty() {
        &defaults[..]
    } else {
        paths
    };
    let scenes = load_scenes(paths)?;
    let md = crate::run::report::report(&scenes)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    // Written whole to a temporary name, then renamed: complete or absent.
    let temp = out.with_extension("md.partial");
    std::fs::write(&temp, &md).with_context(|| format!("cannot write {}", temp.display()))?;
    std::fs::rename(&temp, out).with_context(|| format!("cannot write {}", out.display()))?;
    println!("wrote {}", out.display());
    Ok(())
}
