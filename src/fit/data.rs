//! The measured steps a fit is calibrated to: a CSV file with a header,
//! one measured instance per row (docs/fit.md).
//!
//! The file may start with a UTF-8 byte-order mark, separate its cells
//! with `,`, `;` or a tab (the header line says which), quote its cells,
//! and hold `#` comment lines and blank lines. Columns named by scene keys
//! set the row's instance as a point would, and every row gives each of
//! them a number. The measured columns ([`super::columns`]) name their
//! unit: `step_x_um`, `velocity_x_um_s`, ...; a bare `step_x` is in metres.
//! Values are kept in SI here: steps in metres, velocities in m/s until
//! [`Data::to_steps`] turns them into steps with each row's own drive
//! frequency (`super::velocity`). An empty step cell means "not measured".
//! Repeated settings are pooled by `super::repeats`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use super::columns::{Column, Layout, MAX_BARE_STEP_M, Measure, Quantity};
use crate::model::{AXES, AXIS_NAMES};

/// The largest data file read [bytes].
const MAX_BYTES: u64 = 64 << 20;

/// The delimiters a file may use, with their names for messages.
const DELIMITERS: [(u8, &str); 3] = [(b',', "`,`"), (b';', "`;`"), (b'\t', "a tab")];

/// One measured row, or after pooling one setting (the mean of its rows).
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Its line in the file (the first line of a pooled setting).
    pub line: usize,
    /// Every line it stands for (its setting's repeats, in file order).
    pub lines: Vec<usize>,
    /// The value of each key column ([`Data::keys`]).
    pub keys: Vec<f64>,
    /// The measured step of each axis [m per own drive cycle] (a velocity
    /// [m/s] until [`Data::to_steps`]).
    pub step: [Option<f64>; AXES],
    /// Its standard error, in the step's units, where known.
    pub se: [Option<f64>; AXES],
}

/// Where each axis' standard errors come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeSource {
    /// The file's error column.
    File,
    /// The spread of repeated rows at one setting (`super::repeats`).
    Repeats,
    /// None known: one scale per axis, estimated from the residuals.
    Residuals,
}

impl SeSource {
    /// Its name in FIT.json's `se_source`.
    pub fn name(self) -> &'static str {
        match self {
            SeSource::File => "file",
            SeSource::Repeats => "repeats",
            SeSource::Residuals => "residuals",
        }
    }
}

/// The pooled spread of an axis' repeats (`super::repeats`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pooled {
    /// The pooled standard deviation of one row [m per own drive cycle].
    pub sd: f64,
    /// Its degrees of freedom: the sum over settings of (rows - 1).
    pub dof: usize,
    /// Settings with more than one measured row on the axis.
    pub settings: usize,
}

/// A data file, read and checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Data {
    pub path: PathBuf,
    /// The delimiter the header line uses.
    pub delimiter: u8,
    /// The key columns, dotted scene keys, in file order.
    pub keys: Vec<String>,
    /// Each axis' measured column and its error column, where given.
    pub value: [Option<Measure>; AXES],
    pub error: [Option<Measure>; AXES],
    /// Whether every measured row has a standard error on each axis (from
    /// the file, or from the repeats once pooled).
    pub has_se: [bool; AXES],
    /// Where each axis' standard errors come from.
    pub se_source: [SeSource; AXES],
    /// Each axis' pooled repeats, once pooled.
    pub pooled: [Option<Pooled>; AXES],
    /// Data lines read (before repeats were pooled).
    pub lines: usize,
    /// Whether velocities have been turned into steps ([`Data::to_steps`]).
    pub in_steps: bool,
    pub rows: Vec<Row>,
}

impl Data {
    /// Reads and checks a data file.
    pub fn read(path: &Path) -> Result<Data> {
        if path.as_os_str().is_empty() {
            bail!(
                "no data file: [fit] has no `data` (the CSV of measured steps, relative to the scene) and no --data was given"
            );
        }
        let size = std::fs::metadata(path)
            .with_context(|| format!("data file {}: cannot be read", path.display()))?
            .len();
        if size > MAX_BYTES {
            bail!(
                "data file {}: {size} bytes, more than the {MAX_BYTES} read",
                path.display()
            );
        }
        let text = std::fs::read_to_string(path).with_context(|| {
            format!("data file {}: cannot be read as UTF-8 text", path.display())
        })?;
        Data::parse(&text, path).with_context(|| format!("data file {}", path.display()))
    }

    /// Parses the text of a data file (`path` names it in messages).
    pub fn parse(text: &str, path: &Path) -> Result<Data> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l))
            .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
        let Some((_, header)) = lines.next() else {
            bail!("empty: expected a header line");
        };
        let delimiter = delimiter(header)?;
        let layout = Layout::of(&cells(header, delimiter)?)?;
        let mut rows = Vec::new();
        for (line, text) in lines {
            let cells = cells(text, delimiter).with_context(|| format!("line {line}"))?;
            let cells: Vec<&str> = cells.iter().map(String::as_str).collect();
            rows.push(row(&layout, &cells, line, delimiter)?);
        }
        if rows.is_empty() {
            bail!("no rows after the header: nothing measured");
        }
        let has_se = layout.se.clone().map(|se| se.is_some());
        Ok(Data {
            path: path.to_owned(),
            delimiter,
            keys: layout.keys,
            value: layout.value,
            error: layout.se,
            has_se,
            se_source: has_se.map(|k| {
                if k {
                    SeSource::File
                } else {
                    SeSource::Residuals
                }
            }),
            pooled: [None; AXES],
            lines: rows.len(),
            in_steps: false,
            rows,
        })
    }

    /// Measured values in all (each row's measured axes).
    pub fn measurements(&self) -> usize {
        self.rows
            .iter()
            .map(|r| r.step.iter().flatten().count())
            .sum()
    }

    /// The (row, axis) of each measured value, in the order of a fit's
    /// residuals (row by row, axis by axis).
    pub fn measured_rows(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for (i, row) in self.rows.iter().enumerate() {
            out.extend((0..AXES).filter(|&a| row.step[a].is_some()).map(|a| (i, a)));
        }
        out
    }

    /// Measured values on axis `axis`.
    pub fn measured_on(&self, axis: usize) -> usize {
        self.rows.iter().filter(|r| r.step[axis].is_some()).count()
    }

    /// The axes measured as velocities.
    pub fn velocity_axes(&self) -> Vec<usize> {
        (0..AXES)
            .filter(|&a| {
                self.value[a]
                    .as_ref()
                    .is_some_and(|m| m.quantity == Quantity::Velocity)
            })
            .collect()
    }

    /// Turns each velocity axis' values and errors into steps per own drive
    /// cycle: divided by the row's own drive frequency on that axis
    /// (`frequencies[row][axis]`, Hz). Once: a second call does nothing.
    pub fn to_steps(&mut self, frequencies: &[[f64; AXES]]) {
        if self.in_steps {
            return;
        }
        for axis in self.velocity_axes() {
            for (row, f) in self.rows.iter_mut().zip(frequencies) {
                row.step[axis] = row.step[axis].map(|v| v / f[axis]);
                row.se[axis] = row.se[axis].map(|v| v / f[axis]);
            }
        }
        self.in_steps = true;
    }
}

/// The delimiter of a file's header line: the one of `,`, `;` and tab it
/// holds outside quotes; `,` when it holds none (one column).
fn delimiter(header: &str) -> Result<u8> {
    let mut quoted = false;
    let mut seen = [0usize; DELIMITERS.len()];
    for b in header.bytes() {
        if b == b'"' {
            quoted = !quoted;
        } else if !quoted && let Some(i) = DELIMITERS.iter().position(|(d, _)| *d == b) {
            seen[i] += 1;
        }
    }
    let used: Vec<usize> = (0..DELIMITERS.len()).filter(|&i| seen[i] > 0).collect();
    match used[..] {
        [] => Ok(b','),
        [i] => Ok(DELIMITERS[i].0),
        _ => bail!(
            "the header line mixes {}: separate the columns with one of `,`, `;` or a tab",
            used.iter()
                .map(|&i| DELIMITERS[i].1)
                .collect::<Vec<_>>()
                .join(" and ")
        ),
    }
}

/// The cells of one line, read by the CSV reader: quotes taken off, spaces
/// around a cell trimmed. (Lines are split first, so that comments, blank
/// lines and every row's line number are the file's own; a cell never
/// spans lines.)
fn cells(line: &str, delimiter: u8) -> Result<Vec<String>> {
    let mut reader = csv::ReaderBuilder::new()
        .delimiter(delimiter)
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(line.as_bytes());
    match reader.records().next() {
        Some(record) => Ok(record?.iter().map(str::to_owned).collect()),
        None => Ok(Vec::new()),
    }
}

/// One data line (`line`: its number in the file), in SI units.
fn row(layout: &Layout, cells: &[&str], line: usize, delimiter: u8) -> Result<Row> {
    if cells.len() != layout.columns.len() {
        let hint = decimal_comma_split(layout, cells, delimiter).unwrap_or_default();
        bail!(
            "line {line}: {} cells where the header has {} columns{hint}",
            cells.len(),
            layout.columns.len()
        );
    }
    let mut row = Row {
        line,
        lines: vec![line],
        keys: Vec::new(),
        step: [None; AXES],
        se: [None; AXES],
    };
    for (column, cell) in layout.columns.iter().zip(cells) {
        match column {
            Column::Key(key) => row.keys.push(key_value(cell, key, line)?),
            Column::Value(m) => row.step[m.axis] = measured(cell, m, line)?,
            Column::Se(m) => {
                row.se[m.axis] = measured(cell, m, line)?;
                if let Some(se) = row.se[m.axis]
                    && se <= 0.0
                {
                    bail!(
                        "line {line}, column {}: {cell}: expected a standard error above 0",
                        m.name
                    );
                }
            }
        }
    }
    check_row(layout, &row)?;
    Ok(row)
}

/// Every measured row gives an error where the file has an error column,
/// and no error stands without its value.
fn check_row(layout: &Layout, row: &Row) -> Result<()> {
    let line = row.line;
    if row.step.iter().all(Option::is_none) {
        let names: Vec<&str> = layout.value.iter().flatten().map(|m| &*m.name).collect();
        bail!(
            "line {line}: nothing measured ({} empty): a row needs at least one value",
            names.join(" and ")
        );
    }
    for axis in 0..AXES {
        let (Some(value), Some(error)) = (&layout.value[axis], &layout.se[axis]) else {
            continue;
        };
        match (row.step[axis], row.se[axis]) {
            (Some(_), None) => bail!(
                "line {line}, column {}: empty, but the row gives {}: a file with an error \
                 column needs an error on every row that measures the axis",
                error.name,
                value.name
            ),
            (None, Some(_)) => bail!(
                "line {line}, column {}: an error without a value ({} is empty)",
                error.name,
                value.name
            ),
            _ => {}
        }
    }
    Ok(())
}

/// A key column's cell: a finite number; an empty cell or NaN is refused
/// (a row sets every key column: the scene's value is never taken).
fn key_value(cell: &str, key: &str, line: usize) -> Result<f64> {
    if cell.is_empty() {
        bail!(
            "line {line}, column {key}: empty: expected a number (every row gives every key \
             column a value; drop the column to keep the scene's)"
        );
    }
    match number(cell, key, line)? {
        Some(v) => Ok(v),
        None => bail!(
            "line {line}, column {key}: {cell:?}: expected a finite number (a key column \
             needs a value on every row)"
        ),
    }
}

/// A measured cell in SI units; `None` when empty ("not measured"). A bare
/// step or error beyond 100 um per cycle is refused.
fn measured(cell: &str, m: &Measure, line: usize) -> Result<Option<f64>> {
    if cell.is_empty() {
        return Ok(None);
    }
    let Some(value) = number(cell, &m.name, line)? else {
        bail!(
            "line {line}, column {}: {cell:?}: expected a finite number (leave the cell empty \
             for \"not measured\")",
            m.name
        );
    };
    if m.bare && value.abs() > MAX_BARE_STEP_M {
        let a = AXIS_NAMES[m.axis];
        bail!(
            "line {line}, column {}: {cell}: over 100 um per cycle in metres, the unit of a \
             bare {}; name the unit in the header: step_{a}_um for micrometres, step_{a}_nm \
             for nanometres (step_{a}_se_um for the errors)",
            m.name,
            m.name
        );
    }
    Ok(Some(value * m.factor))
}

/// A cell's number: `Some` when finite, `None` for NaN, an infinity or a
/// word; a decimal comma is refused with a hint.
fn number(cell: &str, column: &str, line: usize) -> Result<Option<f64>> {
    if let Ok(v) = cell.parse::<f64>() {
        return Ok(v.is_finite().then_some(v));
    }
    if cell.contains(',') && cell.replace(',', ".").parse::<f64>().is_ok() {
        bail!(
            "line {line}, column {column}: {cell:?}: a decimal comma; pidm reads numbers with \
             a decimal point ({}): save the file with decimal points",
            cell.replace(',', ".")
        );
    }
    Ok(None)
}

/// A hint for a `,`-separated row with too many cells: a number split at
/// a decimal comma (`0,25` read as `0` and `25`), naming its column.
fn decimal_comma_split(layout: &Layout, cells: &[&str], delimiter: u8) -> Option<String> {
    if delimiter != b',' || cells.len() <= layout.columns.len() {
        return None;
    }
    let integer = |c: &str| {
        let digits = c.strip_prefix('-').unwrap_or(c);
        !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
    };
    let fraction =
        |c: &str| c.starts_with(|ch: char| ch.is_ascii_digit()) && c.parse::<f64>().is_ok();
    let mut pairs = (0..cells.len() - 1).filter(|&i| integer(cells[i]) && fraction(cells[i + 1]));
    // One cell too many: the split is ambiguous (`100,0,25`); the last pair
    // is likelier, keys being whole numbers more often than steps. More:
    // the first split is where the cells stop lining up.
    let i = if cells.len() == layout.columns.len() + 1 {
        pairs.next_back()
    } else {
        pairs.next()
    }?;
    let column = layout.columns.get(i).map_or("?", Column::name);
    Some(format!(
        " (column {column}: {},{} looks like a number with a decimal comma; pidm reads a \
         decimal point, {}.{})",
        cells[i],
        cells[i + 1],
        cells[i],
        cells[i + 1]
    ))
}
