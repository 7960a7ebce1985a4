//! Environment knobs: values that override a tuning constant for
//! measurements, read once per process by their owners (`gpu::knobs`,
//! `laws::floor::check`). A value a knob refuses is reported on stderr and the
//! default stands: a knob never stops a run.

use std::str::FromStr;

/// The value of the environment variable `name`, or `default` where it is
/// unset. A value that does not parse or is not `valid` is reported, with
/// what was `expected`, and the default is used.
pub fn knob<T: FromStr + std::fmt::Display>(
    name: &str,
    default: T,
    valid: impl Fn(&T) -> bool,
    expected: &str,
) -> T {
    let text = std::env::var(name).ok();
    match parse_knob(text.as_deref(), valid) {
        Ok(value) => value.unwrap_or(default),
        Err(text) => {
            eprintln!("pidm: ignoring {name} = {text:?}: expected {expected}; using {default}");
            default
        }
    }
}

/// A knob's value from its text: `None` where unset, the text itself as the
/// error where it does not parse or is not `valid`.
pub fn parse_knob<T: FromStr>(
    text: Option<&str>,
    valid: impl Fn(&T) -> bool,
) -> Result<Option<T>, &str> {
    let Some(text) = text else {
        return Ok(None);
    };
    match text.trim().parse::<T>() {
        Ok(value) if valid(&value) => Ok(Some(value)),
        _ => Err(text),
    }
}

#[cfg(test)]
mod tests {
    use super::parse_knob;

    /// Parses `text` as a power-of-two workgroup knob.
    fn check(text: Option<&str>, expected: Result<Option<u32>, &str>) {
        let power_of_two = |n: &u32| n.is_power_of_two() && *n <= 256;
        assert_eq!(parse_knob(text, power_of_two), expected, "{text:?}");
    }

    #[test]
    fn knobs_take_valid_values_and_refuse_the_rest() {
        check(None, Ok(None));
        check(Some("64"), Ok(Some(64)));
        check(Some(" 8 "), Ok(Some(8)));
        check(Some("300"), Err("300"));
        check(Some("0"), Err("0"));
        check(Some("many"), Err("many"));
    }
}
