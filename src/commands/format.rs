//! Numbers and words for people, shared by the commands: micrometres,
//! plurals, durations, and the name of an instance in its scene.

use crate::scene::{Layout, Scene};

/// Metres as signed micrometres to 4 decimals; a value that rounds to
/// zero is "0.0000", never "-0.0000".
pub fn um(x: f64) -> String {
    let v = x * 1e6;
    if (v * 1e4).round() == 0.0 {
        "0.0000".to_owned()
    } else {
        format!("{v:+.4}")
    }
}

/// `n` and the singular or plural noun.
pub fn plural(n: u64, one: &'static str, many: &'static str) -> &'static str {
    if n == 1 { one } else { many }
}

/// Formats seconds for people.
pub fn human_duration(seconds: f64) -> String {
    if seconds < 1.0 {
        format!("{:.0} ms", seconds * 1e3)
    } else if seconds < 120.0 {
        format!("{seconds:.1} s")
    } else if seconds < 7200.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

/// Names instance `index` of a scene by what sets it apart: its grid
/// coordinates (`axis.x.voltage = 150, axis.y.voltage = 60`), its point's
/// label, or its flat index.
pub fn instance_name(scene: &Scene, index: u64) -> String {
    match &scene.layout {
        Layout::Grid { axes } if !axes.is_empty() => {
            let mut rest = index;
            let mut parts: Vec<String> = axes
                .iter()
                .rev()
                .map(|axis| {
                    let n = axis.values.len() as u64;
                    let value = axis.values[(rest % n) as usize];
                    rest /= n;
                    let units = if axis.units == "1" {
                        String::new()
                    } else {
                        format!(" {}", axis.units)
                    };
                    format!("{} = {}{units}", axis.key, short_number(value))
                })
                .collect();
            parts.reverse();
            parts.join(", ")
        }
        Layout::Points { labels } if !labels[index as usize].is_empty() => {
            format!("{:?}", labels[index as usize])
        }
        _ => format!("instance {index}"),
    }
}

/// A number to six significant digits, without trailing zeros.
fn short_number(value: f64) -> String {
    let text = format!("{value:.6}");
    let precise = format!("{}", value);
    if precise.len() <= text.len() {
        precise
    } else {
        format!("{value:.6e}")
    }
}
