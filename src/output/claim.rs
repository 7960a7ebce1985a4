//! Owning an output path for the length of one run.
//!
//! A run (or a merge) writes three files beside its output `DIR/NAME`: the
//! temporary result `DIR/.NAME.partial`, renamed to `DIR/NAME` only when it
//! is complete, the checkpoint journal `DIR/.NAME.checkpoint`, and the lock
//! `DIR/.NAME.lock`. Before it touches any of them, a run takes an
//! exclusive, non-blocking `flock` on the lock file and keeps it until it
//! ends; a second run of the same output is refused at that point, before
//! it has read, created, truncated or removed anything. The kernel drops the
//! lock when a process dies, so a killed run never leaves a stale lock
//! behind, only a lock file that the next run takes over.
//!
//! Only a regular file or a path that does not exist yet may be an output:
//! folders, symbolic links, FIFOs, devices and sockets are refused, and so
//! are the same kinds of file at the three side paths. A path must end in a
//! file name (`.`, `..`, `/` and a trailing `/` do not).

use std::fs::{File, Metadata, OpenOptions};
use std::io::ErrorKind;
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

use thiserror::Error;

/// Why an output path cannot be claimed.
#[derive(Debug, Error)]
pub enum ClaimError {
    #[error(
        "{path} is not a file name (give a path that ends in a file name, such as results/map.h5)"
    )]
    NotAFileName { path: String },
    #[error("{path} is {kind}, not a regular file; pidm writes only regular files or new paths")]
    NotARegularFile { path: String, kind: &'static str },
    #[error(
        "another pidm process is writing {path} (it holds the lock {lock}); wait for it to \
         finish, or give another --out"
    )]
    Busy { path: String, lock: String },
    #[error("cannot {what} {path}")]
    Io {
        what: &'static str,
        path: String,
        #[source]
        source: std::io::Error,
    },
}

fn io(what: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> ClaimError {
    let path = path.display().to_string();
    move |source| ClaimError::Io { what, path, source }
}

/// The exclusive right to write one output path, held until dropped.
#[derive(Debug)]
pub struct OutputClaim {
    out: PathBuf,
    lock_path: PathBuf,
    /// The open lock file; its `flock` is the claim.
    _lock: File,
}

/// How a file that is not a regular file is named in messages.
fn kind_of(meta: &Metadata) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_dir() {
        Some("a folder")
    } else if t.is_symlink() {
        Some("a symbolic link")
    } else if t.is_fifo() {
        Some("a FIFO")
    } else if t.is_char_device() {
        Some("a character device")
    } else if t.is_block_device() {
        Some("a block device")
    } else if t.is_socket() {
        Some("a socket")
    } else {
        Some("a special file")
    }
}

/// Refuses `path` unless it is a regular file or does not exist. A
/// symbolic link is refused as such, not followed.
pub fn check_regular_or_absent(path: &Path) -> Result<(), ClaimError> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) => match kind_of(&meta) {
            None => Ok(()),
            Some(kind) => Err(ClaimError::NotARegularFile {
                path: path.display().to_string(),
                kind,
            }),
        },
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io("inspect", path)(e)),
    }
}

/// The file name of an output path, refusing paths that end in a folder
/// (`.`, `..`, `/`, `dir/`, `dir/.`).
fn file_name(out: &Path) -> Result<String, ClaimError> {
    let text = out.as_os_str().to_string_lossy();
    let last = text.rsplit('/').next().unwrap_or("");
    let refused = || ClaimError::NotAFileName {
        path: text.to_string(),
    };
    if last.is_empty() || last == "." || last == ".." {
        return Err(refused());
    }
    out.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(refused)
}

/// A side file of `out`: `DIR/.NAME.suffix`.
fn side_path(out: &Path, suffix: &str) -> Result<PathBuf, ClaimError> {
    let name = file_name(out)?;
    Ok(out.with_file_name(format!(".{name}.{suffix}")))
}

/// The checkpoint journal beside `out`.
pub fn checkpoint_path(out: &Path) -> Result<PathBuf, ClaimError> {
    side_path(out, "checkpoint")
}

/// Whether two metadata describe the same file.
fn same_file(a: &Metadata, b: &Metadata) -> bool {
    a.dev() == b.dev() && a.ino() == b.ino()
}

/// Whether `a` and `b` name the same existing file (hard links and
/// different spellings included).
pub fn is_same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => same_file(&a, &b),
        _ => false,
    }
}

impl OutputClaim {
    /// Checks that `out` may be written and takes its lock. Creates the
    /// output's folder if needed (the lock lives there) and nothing else.
    pub fn acquire(out: &Path) -> Result<OutputClaim, ClaimError> {
        let lock_path = side_path(out, "lock")?;
        check_regular_or_absent(out)?;
        for suffix in ["partial", "checkpoint", "lock"] {
            check_regular_or_absent(&side_path(out, suffix)?)?;
        }
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io("create the folder", dir))?;
        }
        // A finishing run removes its lock file while it still holds the
        // lock, so a lock taken on a file that is no longer at the path
        // guards nothing: take it again on the new file.
        for _ in 0..100 {
            let lock = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
                .open(&lock_path)
                .map_err(io("open the lock", &lock_path))?;
            match lock.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(ClaimError::Busy {
                        path: out.display().to_string(),
                        lock: lock_path.display().to_string(),
                    });
                }
                Err(std::fs::TryLockError::Error(e)) => {
                    return Err(io("lock", &lock_path)(e));
                }
            }
            let held = lock.metadata().map_err(io("inspect", &lock_path))?;
            match std::fs::symlink_metadata(&lock_path) {
                Ok(now) if same_file(&held, &now) => {
                    return Ok(OutputClaim {
                        out: out.to_path_buf(),
                        lock_path,
                        _lock: lock,
                    });
                }
                Ok(_) => continue,
                Err(e) if e.kind() == ErrorKind::NotFound => continue,
                Err(e) => return Err(io("inspect", &lock_path)(e)),
            }
        }
        Err(ClaimError::Busy {
            path: out.display().to_string(),
            lock: lock_path.display().to_string(),
        })
    }

    /// The output path this claim owns.
    pub fn path(&self) -> &Path {
        &self.out
    }

    /// The temporary result file, renamed to [`Self::path`] when complete.
    pub fn partial_path(&self) -> PathBuf {
        side_path(&self.out, "partial").expect("checked when the claim was taken")
    }

    /// The checkpoint journal of this output.
    pub fn checkpoint_path(&self) -> PathBuf {
        side_path(&self.out, "checkpoint").expect("checked when the claim was taken")
    }
}

impl Drop for OutputClaim {
    fn drop(&mut self) {
        // Removed while still locked: a process that opened the old file
        // sees that it is gone once it gets the lock, and tries again.
        let _ = std::fs::remove_file(&self.lock_path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_that_end_in_a_folder_are_not_file_names() {
        for path in [".", "..", "/", "a/", "a/.", "a/..", "", "./"] {
            let got = file_name(Path::new(path));
            assert!(
                matches!(got, Err(ClaimError::NotAFileName { .. })),
                "{path:?} gave {got:?}"
            );
        }
        for (path, name) in [("a.h5", "a.h5"), ("d/a.h5", "a.h5"), ("./a", "a")] {
            assert_eq!(file_name(Path::new(path)).unwrap(), name);
        }
    }

    #[test]
    fn a_second_claim_on_the_same_output_is_refused_until_the_first_ends() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.h5");
        let first = OutputClaim::acquire(&out).unwrap();
        // Another spelling of the same path meets the same lock.
        let other = dir.path().join(".").join("o.h5");
        let second = OutputClaim::acquire(&other);
        assert!(matches!(second, Err(ClaimError::Busy { .. })), "{second:?}");
        assert_eq!(first.partial_path(), dir.path().join(".o.h5.partial"));
        drop(first);
        assert!(!dir.path().join(".o.h5.lock").exists());
        OutputClaim::acquire(&other).unwrap();
    }
}
