//! What can be wrong with a result file, as `pidm plot` reports it: every
//! message names the file and the object (dataset, group or attribute) that
//! is wrong, and for a wrong shape both the shape found and the one
//! expected.

use std::path::PathBuf;

use thiserror::Error;

/// A result file that `pidm plot` cannot draw.
#[derive(Debug, Error)]
pub enum ResultFileError {
    /// The file does not exist, cannot be read, or is not HDF5 (empty,
    /// truncated, or another format).
    #[error("cannot open {} as an HDF5 result file: {reason}", file.display())]
    Open { file: PathBuf, reason: String },
    /// The file is one shard of a sharded run, whose maps hold only that
    /// shard's instances.
    #[error(
        "{} is one shard of a sharded run (its maps hold only that shard's instances); join \
         the shards with `pidm merge OUT.h5 SHARDS...` and plot OUT.h5",
        file.display()
    )]
    Shard { file: PathBuf },
    /// One object of the file is missing or does not fit the others.
    #[error("{}: {object} {problem}", file.display())]
    Invalid {
        file: PathBuf,
        /// What is wrong, with its path in the file, e.g. "dataset
        /// /maps/step_x" or "attribute period_s of /trajectories/0".
        object: String,
        problem: Problem,
    },
}

/// What is wrong with one object of a result file.
#[derive(Debug, Error)]
pub enum Problem {
    #[error("is missing")]
    Missing,
    /// The object exists but is of another kind (a group where a dataset
    /// belongs, or the reverse).
    #[error("is not a {expected}")]
    WrongKind { expected: &'static str },
    #[error("holds {found} values, expected {expected}")]
    WrongType {
        found: String,
        expected: &'static str,
    },
    #[error("has shape {found:?}, expected {expected:?} ({reason})")]
    WrongShape {
        found: Vec<usize>,
        expected: Vec<usize>,
        reason: String,
    },
    /// Values that are not finite or beyond ±1e100 where only finite,
    /// plausible ones can be.
    #[error(
        "holds {count} values that are not finite or beyond ±1e100, the first at index {first} \
         ({reason})"
    )]
    Implausible {
        count: usize,
        first: usize,
        reason: &'static str,
    },
    /// Any other value that cannot be: a decreasing time, an empty grid
    /// dimension, a missing sibling.
    #[error("{0}")]
    Invalid(String),
    /// The HDF5 library could not read the object (a damaged file).
    #[error("cannot be read: {0}")]
    Unreadable(String),
}
