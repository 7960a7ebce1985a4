//! The measured steps a fit is calibrated to: a CSV file with a header,
//! one measured instance per row (docs/fit.md). Columns named by scene keys
//! set the row's instance as a point would; `step_x` and `step_y` hold the
//! measured steady steps [m per own drive cycle], `step_x_se` and
//! `step_y_se` their standard errors [m]. An empty cell means "not
//! measured" (a step) or "the scene's value" (a key); NaN or text is
//! refused.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::model::{AXES, AXIS_NAMES};

/// The largest step a row may hold [m per own drive cycle]: 1 mm per cycle
/// is far beyond any impact drive, so a larger value is almost surely in
/// micrometres.
pub const MAX_STEP_M: f64 = 1e-3;

/// The largest data file read [bytes].
const MAX_BYTES: u64 = 64 << 20;

/// One measured row.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Its line in the file (the header is line 1).
    pub line: usize,
    /// The value of each key column ([`Data::keys`]), `None` where empty.
    pub keys: Vec<Option<f64>>,
    /// The measured step of each axis [m per own drive cycle].
    pub step: [Option<f64>; AXES],
    /// Its standard error [m], where the file gives one.
    pub se: [Option<f64>; AXES],
}

/// A data file, read and checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Data {
    pub path: PathBuf,
    /// The key columns, dotted scene keys, in file order.
    pub keys: Vec<String>,
    /// Whether the file gives standard errors for each axis.
    pub has_se: [bool; AXES],
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
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("data file {}: cannot be read as text", path.display()))?;
        Data::parse(&text, path).with_context(|| format!("data file {}", path.display()))
    }

    /// Parses the text of a data file (`path` names it in messages).
    pub fn parse(text: &str, path: &Path) -> Result<Data> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines.next().context("empty: expected a header line")?;
        let columns: Vec<Column> = cells(header)
            .iter()
            .map(|name| Column::of(name))
            .collect::<Result<_>>()?;
        let layout = Layout::of(&columns)?;
        let mut rows = Vec::new();
        for (index, line) in lines {
            rows.push(layout.row(&cells(line), index + 1)?);
        }
        if rows.is_empty() {
            bail!("no rows after the header: nothing measured");
        }
        Ok(Data {
            path: path.to_owned(),
            keys: layout.keys,
            has_se: layout.has_se,
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
}

/// The comma-separated cells of a line, trimmed, quotes around a cell
/// removed.
fn cells(line: &str) -> Vec<String> {
    line.split(',')
        .map(|c| c.trim().trim_matches('"').trim().to_owned())
        .collect()
}

/// What a column holds.
#[derive(Clone, Debug, PartialEq)]
enum Column {
    Key(String),
    Step(usize),
    Se(usize),
}

impl Column {
    fn of(name: &str) -> Result<Column> {
        for (axis, axis_name) in AXIS_NAMES.iter().enumerate() {
            if name == format!("step_{axis_name}") {
                return Ok(Column::Step(axis));
            }
            if name == format!("step_{axis_name}_se") {
                return Ok(Column::Se(axis));
            }
        }
        crate::scene::instance_key(name).map_err(|why| {
            anyhow::anyhow!(
                "column `{name}`: not a scene key a row can set ({why}); the columns are scene \
                 keys such as axis.x.voltage, and step_x, step_y, step_x_se, step_y_se"
            )
        })?;
        Ok(Column::Key(name.to_owned()))
    }
}

/// Which column holds what.
struct Layout {
    columns: Vec<Column>,
    keys: Vec<String>,
    has_se: [bool; AXES],
}

impl Layout {
    fn of(columns: &[Column]) -> Result<Layout> {
        let mut keys = Vec::new();
        let mut has = [[false; 2]; AXES];
        for column in columns {
            let (seen, name) = match column {
                Column::Key(key) => (keys.contains(key), key.clone()),
                Column::Step(a) => (
                    std::mem::replace(&mut has[*a][0], true),
                    format!("step_{}", AXIS_NAMES[*a]),
                ),
                Column::Se(a) => (
                    std::mem::replace(&mut has[*a][1], true),
                    format!("step_{}_se", AXIS_NAMES[*a]),
                ),
            };
            if seen {
                bail!("column `{name}` appears twice");
            }
            if let Column::Key(key) = column {
                keys.push(key.clone());
            }
        }
        if !has.iter().any(|h| h[0]) {
            bail!("no step_x or step_y column: nothing measured to fit");
        }
        for (axis, [step, se]) in has.iter().enumerate() {
            if *se && !step {
                let a = AXIS_NAMES[axis];
                bail!("column step_{a}_se without step_{a}");
            }
        }
        Ok(Layout {
            columns: columns.to_vec(),
            keys,
            has_se: has.map(|h| h[1]),
        })
    }

    /// One data line (`line`: its number in the file).
    fn row(&self, cells: &[String], line: usize) -> Result<Row> {
        if cells.len() != self.columns.len() {
            bail!(
                "line {line}: {} cells where the header has {} columns",
                cells.len(),
                self.columns.len()
            );
        }
        let mut row = Row {
            line,
            keys: Vec::new(),
            step: [None; AXES],
            se: [None; AXES],
        };
        for (column, cell) in self.columns.iter().zip(cells) {
            let value = number(cell, column, line)?;
            match column {
                Column::Key(_) => row.keys.push(value),
                Column::Step(a) => row.step[*a] = value,
                Column::Se(a) => row.se[*a] = value,
            }
        }
        self.check_row(&row)?;
        Ok(row)
    }

    fn check_row(&self, row: &Row) -> Result<()> {
        let line = row.line;
        if row.step.iter().all(Option::is_none) {
            bail!("line {line}: no step measured (step_x and step_y both empty)");
        }
        for (axis, a) in AXIS_NAMES.iter().enumerate() {
            if let Some(step) = row.step[axis]
                && step.abs() > MAX_STEP_M
            {
                bail!(
                    "line {line}: step_{a} = {step}: beyond {MAX_STEP_M} m per cycle; steps are \
                     in metres per own drive cycle (micrometres? divide by 1e6)"
                );
            }
            match (row.step[axis], row.se[axis], self.has_se[axis]) {
                (Some(_), None, true) => {
                    bail!("line {line}: step_{a} without step_{a}_se, which other rows give")
                }
                (None, Some(_), _) => bail!("line {line}: step_{a}_se without step_{a}"),
                (_, Some(se), _) if se <= 0.0 || se > MAX_STEP_M => bail!(
                    "line {line}: step_{a}_se = {se}: expected a standard error in metres, \
                     above 0 and at most {MAX_STEP_M}"
                ),
                _ => {}
            }
        }
        Ok(())
    }
}

/// A cell's number; `None` when empty. NaN, infinities and text are refused.
fn number(cell: &str, column: &Column, line: usize) -> Result<Option<f64>> {
    if cell.is_empty() {
        return Ok(None);
    }
    let name = match column {
        Column::Key(k) => k.clone(),
        Column::Step(a) => format!("step_{}", AXIS_NAMES[*a]),
        Column::Se(a) => format!("step_{}_se", AXIS_NAMES[*a]),
    };
    match cell.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        _ => bail!(
            "line {line}, column {name}: {cell:?} is not a finite number (leave the cell empty \
             for \"not measured\")"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(text: &str, expected: Result<(usize, usize), &str>) {
        match (Data::parse(text, Path::new("d.csv")), expected) {
            (Ok(data), Ok((rows, measured))) => {
                assert_eq!((data.rows.len(), data.measurements()), (rows, measured));
            }
            (Err(e), Err(part)) => assert!(format!("{e:#}").contains(part), "{e:#}"),
            (got, expected) => panic!("got {got:?}, expected {expected:?}"),
        }
    }

    #[test]
    fn reads_rows_and_refuses_bad_ones() {
        let h = "axis.x.voltage,axis.x.frequency,step_x,step_x_se\n";
        check(
            &format!("{h}100,10,-2e-6,1e-8\n120,10,-3e-6,1e-8\n"),
            Ok((2, 2)),
        );
        check(
            "axis.x.voltage,step_x,step_y\n100,-2e-6,\n100,,1e-7\n",
            Ok((2, 2)),
        );
        check(
            &format!("{h}100,10,NaN,1e-8\n"),
            Err("line 2, column step_x: \"NaN\""),
        );
        check(
            &format!("{h}100,ten,-2e-6,1e-8\n"),
            Err("column axis.x.frequency"),
        );
        check(&format!("{h}100,10,-2.5,0.01\n"), Err("micrometres"));
        check(&format!("{h}100,10,-2e-6,\n"), Err("without step_x_se"));
        check(&format!("{h}100,10,-2e-6,-1e-8\n"), Err("above 0"));
        check(&format!("{h}100,10,,\n"), Err("no step measured"));
        check(
            &format!("{h}100,10,-2e-6\n"),
            Err("3 cells where the header has 4"),
        );
        check(
            "axis.x.volts,step_x\n1,1e-6\n",
            Err("column `axis.x.volts`: not a scene key"),
        );
        check("axis.x.voltage\n100\n", Err("no step_x or step_y column"));
        check(
            "step_x_se,step_y\n1e-8,1e-6\n",
            Err("step_x_se without step_x"),
        );
        check(h, Err("no rows"));
        check("", Err("empty"));
    }
}
