//! The scene's `name`: a name, not a path.
//!
//! The name makes the default output file, `results/<name>.h5` (and
//! `results/<name>.shard-K-of-N.h5` for a shard), so a name that holds a
//! path, such as `../../escaped` or `/home/me/data`, would write outside
//! `results/` or overwrite any file it points at. A name must therefore be a
//! plain file name: not empty, at most [`MAX_NAME_BYTES`] bytes, no `/` or
//! `\`, no control characters, and not starting with `.` (which also refuses
//! `.` and `..`) or `-` (which a command line would read as an option).
//!
//! The default name, the scene file's stem, must pass the same rule; it is
//! refused, not rewritten, so that the output file is always named exactly
//! as the scene says, and the message asks for a `name = "..."`.

/// Longest accepted name [bytes of UTF-8]: with `.shard-K-of-N.h5` added, a
/// file name stays well under the 255 bytes most file systems allow.
pub const MAX_NAME_BYTES: usize = 100;

/// Longest part of a refused name quoted in a message [characters].
const QUOTED_CHARS: usize = 60;

/// Checks that `name` is a plain file name. On refusal, returns the name as
/// quoted in messages followed by what was expected, e.g.
/// `"a/b": expected a name, not a path: ...`.
pub(super) fn check_name(name: &str) -> Result<(), String> {
    let problem = if name.trim().is_empty() {
        Some("expected a non-empty string".to_owned())
    } else if name.contains(['/', '\\']) {
        Some("expected a name, not a path: no `/` or `\\`".to_owned())
    } else if name == "." || name == ".." {
        Some("expected a name, not `.` or `..`".to_owned())
    } else if name.starts_with('.') {
        Some("expected a name that does not start with `.` (a hidden file)".to_owned())
    } else if name.starts_with('-') {
        Some(
            "expected a name that does not start with `-` (a command line would read it as an \
             option)"
                .to_owned(),
        )
    } else if let Some((at, c)) = name.char_indices().find(|(_, c)| c.is_control()) {
        Some(format!(
            "expected no control characters, found U+{:04X} at byte {at}",
            c as u32
        ))
    } else if name.len() > MAX_NAME_BYTES {
        Some(format!(
            "expected at most {MAX_NAME_BYTES} bytes, found {}",
            name.len()
        ))
    } else {
        None
    };
    match problem {
        None => Ok(()),
        Some(problem) => Err(format!(
            "{}: {problem}; the name makes the default output file results/<name>.h5",
            quoted(name)
        )),
    }
}

/// The name as quoted in messages: escaped, and shortened when long.
fn quoted(name: &str) -> String {
    if name.chars().count() > QUOTED_CHARS {
        let short: String = name.chars().take(QUOTED_CHARS - 3).collect();
        format!("{short:?}...")
    } else {
        format!("{name:?}")
    }
}
