//! What a fit made of its data file, for FIT.json (`data_description`,
//! `se_source`), the terminal's table and `pidm check`: each measured
//! axis' column and unit, a velocity turned into steps, repeats pooled
//! into settings, and where the standard errors came from.

use serde_json::{Value, json};

use super::columns::Quantity;
use super::data::{Data, SeSource};
use crate::model::{AXES, AXIS_NAMES};

/// The delimiter's name.
fn delimiter(data: &Data) -> &'static str {
    match data.delimiter {
        b';' => ";",
        b'\t' => "tab",
        _ => ",",
    }
}

/// The axes the data measure.
fn measured_axes(data: &Data) -> impl Iterator<Item = usize> + '_ {
    (0..AXES).filter(|&a| data.measured_on(a) > 0)
}

/// FIT.json's `se_source`: per measured axis, "file", "repeats" or
/// "residuals".
pub fn se_source(data: &Data) -> Value {
    let mut out = serde_json::Map::new();
    for axis in measured_axes(data) {
        out.insert(AXIS_NAMES[axis].into(), json!(data.se_source[axis].name()));
    }
    Value::Object(out)
}

/// FIT.json's `data_description`: how the file was read.
pub fn json(data: &Data) -> Value {
    let mut axes = serde_json::Map::new();
    for axis in measured_axes(data) {
        let Some(value) = &data.value[axis] else {
            continue;
        };
        let pooled = data.pooled[axis];
        axes.insert(
            AXIS_NAMES[axis].into(),
            json!({
                "column": value.name,
                "quantity": value.quantity.name(),
                "unit": value.unit,
                "fitted_as": match value.quantity {
                    Quantity::Step => "step [m per own drive cycle]",
                    Quantity::Velocity => "step [m per own drive cycle]: the velocity divided by \
                                           the row's own drive frequency on the axis",
                },
                "se_column": data.error[axis].as_ref().map(|m| &m.name),
                "se_source": data.se_source[axis].name(),
                "pooled_sd": pooled.map(|p| p.sd),
                "pooled_dof": pooled.map(|p| p.dof),
                "repeated_settings": pooled.map(|p| p.settings),
            }),
        );
    }
    json!({
        "delimiter": delimiter(data),
        "lines": data.lines,
        "settings": data.rows.len(),
        "axes": axes,
    })
}

/// One sentence per measured axis (and one for pooled repeats): the
/// terminal's `data:` lines and `pidm check`'s.
pub fn lines(data: &Data) -> Vec<String> {
    let mut out = Vec::new();
    if data.rows.len() < data.lines {
        out.push(format!(
            "{} lines in {} ({} repeated): each setting fitted as its mean",
            data.lines,
            count(data.rows.len(), "setting", "settings"),
            data.repeated_settings()
        ));
    }
    for axis in measured_axes(data) {
        let Some(value) = &data.value[axis] else {
            continue;
        };
        let a = AXIS_NAMES[axis];
        let read = match value.quantity {
            Quantity::Step => format!("step {a} from {} [{}]", value.name, value.unit),
            Quantity::Velocity => format!(
                "step {a} from the velocity {} [{}] divided by each row's own drive frequency \
                 on {a}, fitted as a step per own drive cycle",
                value.name, value.unit
            ),
        };
        let se = match (data.se_source[axis], data.pooled[axis]) {
            (SeSource::File, _) => format!(
                "standard errors from the file ({})",
                data.error[axis].as_ref().map_or("", |m| &m.name)
            ),
            (SeSource::Repeats, Some(p)) => format!(
                "standard errors from the repeats: s = {:.4e} m pooled over {} ({}), s/sqrt(n) \
                 for a setting of n rows",
                p.sd,
                count(p.settings, "setting", "settings"),
                count(p.dof, "degree of freedom", "degrees of freedom")
            ),
            _ => "standard errors from the residuals (one scale for the axis; the file gives \
                  none)"
                .into(),
        };
        out.push(format!("{read}; {se}"));
    }
    out
}

/// `n` and its noun, singular or plural.
fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}
