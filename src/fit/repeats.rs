//! Repeated measurements at one setting (docs/fit.md): rows whose key
//! columns are all equal are one setting. When the file gives no standard
//! errors, each setting is fitted as its mean, and where some setting
//! repeats an axis, the mean's standard error is s / sqrt(n): n the
//! setting's measured rows on that axis, s the standard deviation pooled
//! over every setting that repeats it,
//!
//!   s^2 = sum_k sum_i (y_ki - mean_k)^2 / sum_k (n_k - 1),
//!
//! over the settings k with n_k >= 2. A setting of a single row gets s / 1.

use std::collections::HashMap;

use super::data::{Data, Pooled, Row, SeSource};
use crate::model::AXES;

/// The smallest pooled standard deviation used [m per own drive cycle]:
/// the integrator's own error (docs/model.md section 4), so that repeats
/// that agree exactly still give every value a finite weight.
pub const MIN_SD: f64 = 1e-10;

impl Data {
    /// Pools repeated settings when the file gives no error column: the
    /// rows of each setting become one row, their mean on each axis, and
    /// each axis some setting repeats gets the standard errors of those
    /// means from the pooled spread (the module's doc). Nothing changes
    /// when the file gives an error column or no setting repeats; an axis
    /// no setting repeats keeps its scale from the residuals.
    pub fn pool_repeats(&mut self) {
        if self.error.iter().any(Option::is_some) {
            return;
        }
        let settings = settings(&self.rows);
        if settings.iter().all(|s| s.len() == 1) {
            return;
        }
        let mut rows: Vec<Row> = settings.iter().map(|s| mean(&self.rows, s)).collect();
        for axis in 0..AXES {
            let Some(pooled) = pool(&self.rows, &settings, axis) else {
                continue;
            };
            let sd = pooled.sd.max(MIN_SD);
            for (row, setting) in rows.iter_mut().zip(&settings) {
                let n = measured(&self.rows, setting, axis).count();
                if n > 0 {
                    row.se[axis] = Some(sd / (n as f64).sqrt());
                }
            }
            self.pooled[axis] = Some(pooled);
            self.has_se[axis] = true;
            self.se_source[axis] = SeSource::Repeats;
        }
        self.rows = rows;
    }

    /// Settings with more than one row.
    pub fn repeated_settings(&self) -> usize {
        self.rows.iter().filter(|r| r.lines.len() > 1).count()
    }
}

/// The settings of `rows`: the indices of each setting's rows in file
/// order, settings in the order of their first row.
fn settings(rows: &[Row]) -> Vec<Vec<usize>> {
    let mut index: HashMap<Vec<u64>, usize> = HashMap::new();
    let mut settings: Vec<Vec<usize>> = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        // + 0.0 makes -0 and 0 one setting, as they compare equal.
        let key = row.keys.iter().map(|v| (v + 0.0).to_bits()).collect();
        let next = settings.len();
        let k = *index.entry(key).or_insert(next);
        if k == next {
            settings.push(Vec::new());
        }
        settings[k].push(i);
    }
    settings
}

/// The measured values of `setting` on `axis`.
fn measured<'a>(
    rows: &'a [Row],
    setting: &'a [usize],
    axis: usize,
) -> impl Iterator<Item = f64> + 'a {
    setting.iter().filter_map(move |&r| rows[r].step[axis])
}

/// One setting as one row: the mean of its measured values on each axis.
fn mean(rows: &[Row], setting: &[usize]) -> Row {
    let first = &rows[setting[0]];
    Row {
        line: first.line,
        lines: setting.iter().map(|&r| rows[r].line).collect(),
        keys: first.keys.clone(),
        step: std::array::from_fn(|axis| {
            let values: Vec<f64> = measured(rows, setting, axis).collect();
            (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
        }),
        se: [None; AXES],
    }
}

/// The spread of `axis` pooled over the settings that repeat it; `None`
/// when none does.
fn pool(rows: &[Row], settings: &[Vec<usize>], axis: usize) -> Option<Pooled> {
    let (mut squares, mut dof, mut repeated) = (0.0, 0, 0);
    for setting in settings {
        let values: Vec<f64> = measured(rows, setting, axis).collect();
        if values.len() < 2 {
            continue;
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        squares += values.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
        dof += values.len() - 1;
        repeated += 1;
    }
    (dof > 0).then(|| Pooled {
        sd: (squares / dof as f64).sqrt(),
        dof,
        settings: repeated,
    })
}
