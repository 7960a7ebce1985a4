//! A data file's header (docs/fit.md): which column holds a scene key, and
//! which an axis' measured value or its standard error, in which unit.
//!
//! The unit is a suffix of the name: `step_x_m`, `step_x_um`, `step_x_nm`
//! (and `_mm`) with errors `step_x_se_um` and so on; velocities
//! `velocity_x_m_s` and `velocity_x_um_s` (and `_mm_s`) with errors
//! `velocity_x_se_um_s`. A bare `step_x` or `step_x_se` is in metres.

use anyhow::{Result, bail};

use crate::model::{AXES, AXIS_NAMES};

/// The largest value a bare `step_x` or `step_x_se` (metres, no unit named)
/// may hold [m per own drive cycle]: 100 um per cycle is beyond any
/// stick-slip drive, so a larger value is almost surely in another unit.
pub const MAX_BARE_STEP_M: f64 = 1e-4;

/// What a measured column holds: a step per own drive cycle, or a velocity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// [m per own drive cycle]
    Step,
    /// [m/s], turned into a step with the row's own drive frequency
    /// (`fit::velocity`).
    Velocity,
}

impl Quantity {
    /// Its name in a column and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Step => "step",
            Quantity::Velocity => "velocity",
        }
    }
}

/// Step units: suffix, units' name, metres per unit.
const STEP_UNITS: [(&str, &str, f64); 4] = [
    ("_m", "m", 1.0),
    ("_mm", "mm", 1e-3),
    ("_um", "um", 1e-6),
    ("_nm", "nm", 1e-9),
];

/// Velocity units: suffix, units' name, metres per second per unit.
const VELOCITY_UNITS: [(&str, &str, f64); 3] = [
    ("_m_s", "m/s", 1.0),
    ("_mm_s", "mm/s", 1e-3),
    ("_um_s", "um/s", 1e-6),
];

/// An axis' measured value or its standard error, as a column names it.
#[derive(Clone, Debug, PartialEq)]
pub struct Measure {
    /// The column's name, as in the header.
    pub name: String,
    pub axis: usize,
    pub quantity: Quantity,
    /// The unit's name ("m", "um", "m/s", ...).
    pub unit: &'static str,
    /// SI units (m or m/s) per unit of the column.
    pub factor: f64,
    /// A bare `step_x` or `step_x_se`: metres, no unit named.
    pub bare: bool,
}

/// What a column holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Column {
    /// A scene key, dotted.
    Key(String),
    /// An axis' measured value.
    Value(Measure),
    /// Its standard error.
    Se(Measure),
}

impl Column {
    /// The column's name, as in the header.
    pub fn name(&self) -> &str {
        match self {
            Column::Key(key) => key,
            Column::Value(m) | Column::Se(m) => &m.name,
        }
    }

    /// The column a header cell names.
    pub fn of(name: &str) -> Result<Column> {
        if let Some(column) = measured(name)? {
            return Ok(column);
        }
        crate::scene::instance_key(name).map_err(|why| {
            anyhow::anyhow!(
                "column `{name}`: not a scene key a row can set ({why}); the columns are scene \
                 keys such as axis.x.voltage, and step_x or step_x_um, step_x_se_um, \
                 velocity_x_um_s and the like for y"
            )
        })?;
        Ok(Column::Key(name.to_owned()))
    }
}

/// The measured column `name` names; `None` when it names none (a key's
/// column); an error for a `step_`/`velocity_` name with no known unit.
fn measured(name: &str) -> Result<Option<Column>> {
    let (quantity, rest) = if let Some(rest) = name.strip_prefix("step_") {
        (Quantity::Step, rest)
    } else if let Some(rest) = name.strip_prefix("velocity_") {
        (Quantity::Velocity, rest)
    } else {
        return Ok(None);
    };
    let Some(axis) = AXIS_NAMES
        .iter()
        .position(|a| rest.starts_with(a) && !rest[a.len()..].starts_with(|c: char| c != '_'))
    else {
        bail!(
            "column `{name}`: expected {0}_x or {0}_y with a unit (axis x or y)",
            quantity.name()
        );
    };
    let rest = &rest[AXIS_NAMES[axis].len()..];
    let (se, suffix) = match rest.strip_prefix("_se") {
        Some(suffix) if suffix.is_empty() || suffix.starts_with('_') => (true, suffix),
        _ => (false, rest),
    };
    let found = match quantity {
        Quantity::Step if suffix.is_empty() => Some(("m", 1.0)),
        Quantity::Step => unit(&STEP_UNITS, suffix),
        Quantity::Velocity => unit(&VELOCITY_UNITS, suffix),
    };
    let Some((unit, factor)) = found else {
        bail!("column `{name}`: {}", expected_units(quantity, axis, se));
    };
    let measure = Measure {
        name: name.to_owned(),
        axis,
        quantity,
        unit,
        factor,
        bare: suffix.is_empty(),
    };
    Ok(Some(if se {
        Column::Se(measure)
    } else {
        Column::Value(measure)
    }))
}

fn unit(units: &[(&str, &'static str, f64)], suffix: &str) -> Option<(&'static str, f64)> {
    units
        .iter()
        .find(|(s, _, _)| *s == suffix)
        .map(|&(_, unit, factor)| (unit, factor))
}

/// What the columns of a quantity may be called, for a message.
fn expected_units(quantity: Quantity, axis: usize, se: bool) -> String {
    let a = AXIS_NAMES[axis];
    let se = if se { "_se" } else { "" };
    match quantity {
        Quantity::Step => format!(
            "expected step_{a}{se}_m, step_{a}{se}_mm, step_{a}{se}_um or step_{a}{se}_nm (the \
             unit a suffix of the name; a bare step_{a}{se} is in metres)"
        ),
        Quantity::Velocity => format!(
            "expected velocity_{a}{se}_m_s, velocity_{a}{se}_mm_s or velocity_{a}{se}_um_s (a \
             velocity names its unit)"
        ),
    }
}

/// Which column holds what, checked: each key once, at most one measured
/// column and one error column per axis, of the same quantity.
#[derive(Clone, Debug)]
pub struct Layout {
    pub columns: Vec<Column>,
    /// The key columns, dotted scene keys, in file order.
    pub keys: Vec<String>,
    /// Each axis' measured column, and its error column.
    pub value: [Option<Measure>; AXES],
    pub se: [Option<Measure>; AXES],
}

impl Layout {
    /// The layout of a header's cells.
    pub fn of(names: &[String]) -> Result<Layout> {
        if let Some(i) = names.iter().position(String::is_empty) {
            bail!(
                "the header's column {} has no name: every column is named (a delimiter too \
                 many at the end of the line?)",
                i + 1
            );
        }
        let columns: Vec<Column> = names.iter().map(|n| Column::of(n)).collect::<Result<_>>()?;
        let mut layout = Layout {
            columns: columns.clone(),
            keys: Vec::new(),
            value: [None, None],
            se: [None, None],
        };
        for column in columns {
            match column {
                Column::Key(key) if layout.keys.contains(&key) => {
                    bail!("column `{key}` appears twice")
                }
                Column::Key(key) => layout.keys.push(key),
                Column::Value(m) => place(&mut layout.value, m, "measure")?,
                Column::Se(m) => place(&mut layout.se, m, "give the standard error of")?,
            }
        }
        if layout.value.iter().all(Option::is_none) {
            bail!(
                "no step_x or step_y column (nor step_x_um, velocity_x_um_s and the like): \
                 nothing measured to fit"
            );
        }
        for (value, se) in layout.value.iter().zip(&layout.se) {
            let Some(se) = se else { continue };
            let a = AXIS_NAMES[se.axis];
            match value {
                None => bail!(
                    "column {} without a measured {a} column (step_{a}, step_{a}_um, ...)",
                    se.name
                ),
                Some(value) if value.quantity != se.quantity => bail!(
                    "column {} is the standard error of a {}, but axis {a} is measured as {} (a \
                     {}): {}",
                    se.name,
                    se.quantity.name(),
                    value.name,
                    value.quantity.name(),
                    expected_units(value.quantity, se.axis, true)
                ),
                _ => {}
            }
        }
        Ok(layout)
    }
}

/// Puts a measured column in its axis' slot, refusing a second one.
fn place(slots: &mut [Option<Measure>; AXES], m: Measure, what: &str) -> Result<()> {
    if let Some(first) = &slots[m.axis] {
        bail!(
            "columns `{}` and `{}` both {what} axis {}: give one",
            first.name,
            m.name,
            AXIS_NAMES[m.axis]
        );
    }
    let axis = m.axis;
    slots[axis] = Some(m);
    Ok(())
}
