//! All pictures or none: they are drawn into a hidden staging folder beside
//! the output folder (on the same file system) and moved into it only once
//! every one is written. A failure, a panic or an interrupt while drawing
//! leaves the output folder as it was; the staging folder is removed when
//! the [`Staging`] is dropped (only a killed process leaves it behind, as
//! `.<out>.plotting-<pid>-<n>` beside the output folder).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{Context, Result, bail};

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
    /// output folder, replacing pictures of the same name, and returns
    /// their new paths in the same order. What could stop a move (the
    /// output folder cannot be made, a folder is in a picture's place) is
    /// checked before the first one, so none is replaced unless all are.
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
        Ok(targets)
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        // Best effort: what is left here was never meant to be seen.
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
