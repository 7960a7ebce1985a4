//! Words and numbers on the pictures: axis titles, short numbers and file
//! name parts.

/// A plain-words name of a scene key's last part.
fn key_meaning(key: &str) -> Option<String> {
    let mut parts = key.split('.');
    let table = parts.next()?;
    let axis = if table == "axis" { parts.next() } else { None };
    let field = parts.next_back()?;
    let what = match field {
        "voltage" => "drive amplitude",
        "frequency" => "drive frequency",
        "frequency_ratio" => "drive frequency / x drive frequency",
        "phase" => "drive phase",
        "duty" => "drive rise fraction",
        "gain" => "actuator gain",
        "stage_mass" => "stage mass",
        "stiffness" => "stage stiffness",
        "damping" => "stage damping",
        "resonance_hz" => "stage resonance",
        "quality_factor" => "stage quality factor",
        "slider_mass" => "slider mass",
        "static_friction" => "static friction",
        "coulomb_friction" => "sliding friction",
        "velocity_band" => "velocity band",
        "cycles" => "simulated periods",
        "settle" => "settle periods",
        "max_cycles" => "most simulated periods",
        "step_tolerance" => "steady step tolerance",
        _ => return None,
    };
    Some(match axis {
        Some(a) => format!("{a} {what}"),
        None => what.to_owned(),
    })
}

/// An axis title: key, meaning and unit, e.g. "axis.x.voltage (x drive
/// amplitude) [V]".
pub(super) fn axis_title(key: &str, units: &str) -> String {
    let meaning = key_meaning(key).map_or(String::new(), |m| format!(" ({m})"));
    let unit = if units == "1" || units.is_empty() {
        String::new()
    } else {
        format!(" [{units}]")
    };
    format!("{key}{meaning}{unit}")
}

/// A number for labels: up to four significant digits, no trailing zeros.
pub(super) fn short(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return format!("{value}");
    }
    let magnitude = value.abs().log10().floor();
    if (-3.0..6.0).contains(&magnitude) {
        let decimals = (3.0 - magnitude).max(0.0) as usize;
        let text = format!("{value:.decimals$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            text
        }
    } else {
        format!("{value:.2e}")
    }
}

/// A value with its unit, e.g. "100 V".
pub(super) fn with_unit(value: f64, units: &str) -> String {
    if units == "1" || units.is_empty() {
        short(value)
    } else {
        format!("{} {units}", short(value))
    }
}

/// A file name part from free text: lower-case letters, digits, '-' and
/// '_' for anything else.
pub(super) fn slug(text: &str) -> String {
    let mut out = String::new();
    for c in text.chars() {
        if c.is_ascii_alphanumeric() || c == '-' {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    out.trim_matches('_').to_owned()
}
