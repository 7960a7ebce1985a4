//! How numbers and byte counts are written in messages and summaries.

/// Formats a number for messages: integers without a fraction, others in
/// their shortest round-trip form, non-finite values as TOML writes them.
pub(super) fn fmt_num(value: f64) -> String {
    if value.is_nan() {
        "nan".to_owned()
    } else if value.is_infinite() {
        if value > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else if value.fract() == 0.0 && value.abs() < 1e16 {
        format!("{value:.0}")
    } else {
        format!("{value:?}")
    }
}

/// Formats a number for summaries: integers as they are, others to six
/// significant digits.
pub(super) fn fmt_short(value: f64) -> String {
    if !value.is_finite() || value == 0.0 || (value.fract() == 0.0 && value.abs() < 1e16) {
        return fmt_num(value);
    }
    let magnitude = value.abs().log10().floor();
    let text = if (-3.0..7.0).contains(&magnitude) {
        let decimals = (5.0 - magnitude).max(0.0) as usize;
        format!("{value:.decimals$}")
    } else {
        format!("{value:.5e}")
    };
    // Trailing zeros of the mantissa carry nothing.
    let (mantissa, exponent) = match text.find('e') {
        Some(e) => text.split_at(e),
        None => (text.as_str(), ""),
    };
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    format!("{mantissa}{exponent}")
}

/// Formats a byte count with a binary unit, e.g. "8.0 GiB".
pub(super) fn human_bytes(bytes: f64) -> String {
    const UNITS: [&str; 7] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut value = bytes;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{value:.0} bytes")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}
