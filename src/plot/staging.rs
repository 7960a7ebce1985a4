//! All pictures or none: they are drawn into a hidden staging folder beside
//! the output folder (on the same file system) and moved into it only once
//! every one is written. A failure, a panic or an interrupt while drawing
//! leaves the output folder as it was; the staging folder is removed when
//! the [`Staging`] is dropped (only a killed process leaves it behind, as
//! `.<out>.plotting-<pid>-<n>` beside the output folder).
//!
//! The output folder keeps a manifest of the pictures pidm drew there,
//! [`MANIFEST`], one file name a line. When new pictures are moved in, the
//! ones the manifest lists that the new set does not hold (the ratio maps
//! of an earlier run with baselines, say) are removed, so the folder never
//! shows a mix of two results; nothing the manifest does not list is ever
//! touched. The manifest is rewritten before the first move to list the
//! old and new pictures, so that an interrupted commit still knows every
//! picture it may have left.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{Context, Result, bail};

/// The manifest in an output folder: the file names of the pictures pidm
/// drew there, one a line.
pub const MANIFEST: &str = ".pidm-plot-manifest";

/// The picture names the manifest of `out` lists: plain file names only
/// (no separator, not `.` or `..`, not the manifest itself), so that a
/// damaged or edited manifest can never name anything outside `out`. No
/// manifest, or one that cannot be read, lists nothing.
fn manifest_names(out: &Path) -> Vec<String> {
    let Ok(text) = std::fs::read_to_string(out.join(MANIFEST)) else {
        return Vec::new();
    };
    text.lines()
        .filter(|name| {
            !name.is_empty()
                && *name != MANIFEST
                && Path::new(name).file_name() == Some(std::ffi::OsStr::new(name))
        })
        .map(str::to_owned)
        .collect()
}

/// Writes the manifest of `out` listing `names`, whole or not at all.
fn write_manifest(out: &Path, names: &[String]) -> Result<()> {
    let path = out.join(MANIFEST);
    let temp = out.join(format!("{MANIFEST}.{}", std::process::id()));
    let mut text = names.join("\n");
    text.push('\n');
    std::fs::write(&temp, text)
        .and_then(|()| std::fs::rename(&temp, &path))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// A staging folder for the pictures of one output folder.
pub(super) struct Staging {
    /// The staging folder, removed on drop.
    dir: PathBuf,
    /// The output folder the pictures are for.
    out: PathBuf,
}

impl Staging {
    /// Creates a fresh staging folder beside `out` (creating `out`'s parent
    /// when needed, but not `out` itself).
    pub(super) fn new(out: &Path) -> Result<Staging> {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        // "." or ".." have no name of their own: name them by where they
        // lead.
        let resolved = if out.file_name().is_some() {
            out.to_path_buf()
        } else {
            out.canonicalize()
                .with_context(|| format!("cannot find the folder {}", out.display()))?
        };
        let name = resolved
            .file_name()
            .map_or_else(|| "plots".to_owned(), |n| n.to_string_lossy().into_owned());
        let parent = match resolved.parent() {
            Some(p) if p.as_os_str().is_empty() => Path::new("."),
            Some(p) => p,
            // The root folder has no parent: stage inside it.
            None => resolved.as_path(),
        };
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create the folder {}", parent.display()))?;
        let dir = parent.join(format!(
            ".{name}.plotting-{}-{}",
            std::process::id(),
            COUNT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir(&dir)
            .with_context(|| format!("cannot create the folder {}", dir.display()))?;
        Ok(Staging {
            dir,
            out: out.to_path_buf(),
        })
    }

    /// The folder to draw into.
    pub(super) fn path(&self) -> &Path {
        &self.dir
    }

    /// Moves the pictures `files` (paths in the staging folder) into the
    /// output folder, replacing pictures of the same name, removes the
    /// pictures an earlier plot drew there that are not among them (those
    /// the manifest lists, nothing else), and returns their new paths in
    /// the same order. What could stop a move (the output folder cannot be
    /// made, a folder is in a picture's place) is checked before the first
    /// one, so none is replaced unless all are.
    pub(super) fn commit(self, files: &[PathBuf]) -> Result<Vec<PathBuf>> {
        let targets = files
            .iter()
            .map(|staged| {
                let name = staged
                    .file_name()
                    .with_context(|| format!("{} has no file name", staged.display()))?;
                Ok(self.out.join(name))
            })
            .collect::<Result<Vec<PathBuf>>>()?;
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("cannot create the folder {}", self.out.display()))?;
        if let Some(blocked) = targets.iter().find(|t| t.is_dir()) {
            bail!(
                "cannot write {}: a folder of that name is in the way; no picture was written",
                blocked.display()
            );
        }
        let mut new: Vec<String> = Vec::new();
        for target in &targets {
            let name = target
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            if !new.contains(&name) {
                new.push(name);
            }
        }
        let old = manifest_names(&self.out);
        let stale: Vec<&String> = old.iter().filter(|name| !new.contains(name)).collect();
        // Until the old pictures are gone, the manifest lists them too.
        let mut both = new.clone();
        both.extend(stale.iter().map(|name| (*name).clone()));
        write_manifest(&self.out, &both)?;
        for (k, (staged, target)) in files.iter().zip(&targets).enumerate() {
            // A name drawn twice was overwritten in the staging folder and
            // is moved once.
            if files[..k].contains(staged) {
                continue;
            }
            std::fs::rename(staged, target).with_context(|| {
                format!("cannot move {} to {}", staged.display(), target.display())
            })?;
        }
        for name in stale {
            let path = self.out.join(name);
            // Only a file pidm drew: a folder or a link put there since is
            // left alone.
            if std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
                std::fs::remove_file(&path)
                    .with_context(|| format!("cannot remove the old picture {}", path.display()))?;
            }
        }
        write_manifest(&self.out, &new)?;
        Ok(targets)
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        // Best effort: what is left here was never meant to be seen.
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
