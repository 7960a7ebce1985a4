//! Reading a scene file: bounded in size, and text only.
//!
//! A scene is a short text file; the largest shipped one is a few kB. The
//! file is read through [`std::io::Read::take`], so that a device or a pipe
//! that never ends (`pidm check /dev/zero`) is refused after
//! [`MAX_SCENE_BYTES`] instead of filling the memory, and a regular file
//! that is larger is refused by its size before anything is read.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::error::SceneError;

/// Largest scene file accepted [bytes]: 16 MiB, thousands of times the
/// largest shipped scene, and room for a points scene of about 20,000
/// random instances (`pidm random-scene` writes about 680 bytes each;
/// with `--compact` any number of them as a `[random]` table of a few
/// lines).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

/// Reads the scene file at `path` as text, refusing one larger than
/// [`MAX_SCENE_BYTES`] or that is not UTF-8 text without NUL bytes.
pub fn read(path: &Path) -> Result<String, SceneError> {
    let io = |error: std::io::Error| SceneError::Io {
        path: path.to_owned(),
        error,
    };
    let file = File::open(path).map_err(io)?;
    let metadata = file.metadata().map_err(io)?;
    if metadata.is_file() && metadata.len() > MAX_SCENE_BYTES {
        return Err(SceneError::TooLarge {
            path: path.to_owned(),
        });
    }
    let mut bytes = Vec::new();
    file.take(MAX_SCENE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_SCENE_BYTES {
        return Err(SceneError::TooLarge {
            path: path.to_owned(),
        });
    }
    if let Some(at) = bytes.iter().position(|&b| b == 0) {
        return Err(SceneError::NotText {
            path: path.to_owned(),
            why: format!("it holds a NUL byte at byte {at}"),
        });
    }
    String::from_utf8(bytes).map_err(|error| SceneError::NotText {
        path: path.to_owned(),
        why: format!(
            "it is not UTF-8 (invalid byte at byte {})",
            error.utf8_error().valid_up_to()
        ),
    })
}
