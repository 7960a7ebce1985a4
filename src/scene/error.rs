//! Why a scene was refused: [`SceneError`], and [`Location`], where in the
//! text the offending value is.
//!
//! Every message is complete on its own: it names the key (or the file), the
//! offending value and what was expected. No variant exposes an underlying
//! error as its `source`, because the message already carries that error's
//! text and a printed error chain would repeat it.

use std::fmt;
use std::path::PathBuf;

use super::file::MAX_SCENE_BYTES;
use super::format::human_bytes;
use super::memory::memory_message;

/// A position in the scene's TOML text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    /// Line, from 1.
    pub line: usize,
    /// Column in characters, from 1.
    pub column: usize,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}, column {}", self.line, self.column)
    }
}

/// Why a scene was refused.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene file {}: {error}", path.display())]
    Io {
        /// The file as named.
        path: PathBuf,
        /// What the operating system said.
        error: std::io::Error,
    },
    /// The scene file holds more than [`MAX_SCENE_BYTES`] bytes (or, for a
    /// device or pipe, would not stop).
    #[error(
        "scene file {} is larger than {} ({MAX_SCENE_BYTES} bytes): expected a scene, a short \
         text file",
        path.display(),
        human_bytes(MAX_SCENE_BYTES as f64)
    )]
    TooLarge {
        /// The file as named.
        path: PathBuf,
    },
    /// The scene file is not text: not UTF-8, or it holds a NUL byte.
    #[error("scene file {} is not a text file: {why}; expected a TOML scene", path.display())]
    NotText {
        /// The file as named.
        path: PathBuf,
        /// What is wrong, with the byte offset.
        why: String,
    },
    /// The text is not valid TOML; the message carries toml's line and column.
    #[error("invalid TOML: {error}")]
    Syntax {
        /// toml's description of the error, with the offending line.
        error: toml::de::Error,
    },
    /// The TOML is valid but the scene is not: a message naming the key, the
    /// value and what was expected, and where it is in the text when known.
    #[error("{message}{}", LocationSuffix(location))]
    Invalid {
        /// The message, without the location.
        message: String,
        /// Where the offending value is, when known.
        location: Option<Location>,
    },
    /// The output maps would not fit the memory budget.
    #[error("{}", memory_message(shape, *points, *instances, *bytes_per_instance, *budget))]
    Memory {
        /// The grid shape, or the number of points.
        shape: Vec<u64>,
        /// Whether the scene is a list of points.
        points: bool,
        /// Instances in the scene.
        instances: u128,
        /// Output bytes per instance.
        bytes_per_instance: u64,
        /// The budget that was exceeded, in bytes.
        budget: u64,
    },
}

impl SceneError {
    /// Prefixes the message of an [`SceneError::Invalid`] with the point
    /// that caused it.
    pub(super) fn in_point(self, index: usize, label: &str) -> SceneError {
        match self {
            SceneError::Invalid { message, location } => SceneError::Invalid {
                message: format!("{}: {message}", point_name(index, label)),
                location,
            },
            other => other,
        }
    }
}

/// Formats " (line L, column C)" after an error message when known.
struct LocationSuffix<'a>(&'a Option<Location>);

impl fmt::Display for LocationSuffix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(location) => write!(f, " ({location})"),
            None => Ok(()),
        }
    }
}

/// Names a point in error messages: `points[2] ("Fig. 7")`.
pub(super) fn point_name(index: usize, label: &str) -> String {
    if label.is_empty() {
        format!("points[{index}]")
    } else {
        format!("points[{index}] ({label:?})")
    }
}
