//! `FIT.png`'s curves: the fitted model along the data's most varied key,
//! one curve per group of rows that share every other key, integrated as
//! one batch.

use std::path::Path;

use anyhow::Result;

use super::judge::Answer;
use super::problem::Problem;
use crate::model::{AXES, AXIS_NAMES};
use crate::plot::{FitPanel, FitSeries};

/// Points along each curve.
const CURVE_POINTS: usize = 41;

/// Draws `FIT.png` at `path`.
pub fn draw(problem: &Problem, answer: &Answer, path: &Path) -> Result<()> {
    let data = &problem.data;
    let x_key = (0..data.keys.len()).max_by_key(|&k| distinct(problem, k).len());
    let groups = groups(problem, x_key);
    let mut points = Vec::new();
    for (keys, _) in &groups {
        points.extend(curve_points(problem, x_key, keys));
    }
    let curves = problem.evaluate_points(&answer.values, &points)?;
    let mut panels = Vec::new();
    for axis in (0..AXES).filter(|&a| data.measured_on(a) > 0) {
        panels.push(panel(problem, answer, axis, x_key, &groups, &curves));
    }
    panels.push(residuals(problem, answer));
    let below = profiles(problem, answer);
    // One line per key, so that a one-panel figure shows them all.
    let mut title = vec![format!("pidm fit: {}", data.path.display())];
    title.extend(
        answer
            .keys
            .iter()
            .zip(&answer.values)
            .zip(&answer.se)
            .map(|((k, v), se)| format!("{k} = {v:.5e} ± {se:.2e}")),
    );
    crate::plot::fit_figure(path, &title, &panels, &below)
}

/// The normalized residuals, (model - data) / se, by data line and axis.
fn residuals(problem: &Problem, answer: &Answer) -> FitPanel {
    let data = &problem.data;
    let lines = data.rows.iter().map(|r| r.line as f64);
    let (first, last) = lines.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), l| {
        (a.min(l), b.max(l))
    });
    let series = (0..AXES)
        .filter(|&a| data.measured_on(a) > 0)
        .map(|axis| FitSeries {
            label: format!("step {}", AXIS_NAMES[axis]),
            points: data
                .rows
                .iter()
                .zip(&answer.models)
                .filter_map(|(row, model)| {
                    let step = row.step[axis]?;
                    let se = answer.weights.data_se(row.se[axis], axis);
                    Some((row.line as f64, (model.step[axis] - step) / se, 0.0))
                })
                .collect(),
            curve: vec![(first, 0.0), (last, 0.0)],
        })
        .collect();
    FitPanel {
        title: "normalized residuals, (model - data) / se".into(),
        x_label: "data line".into(),
        y_label: "residual [standard errors]".into(),
        series,
    }
}

/// The rise of chi2 shown in a profile panel, at most (the walk goes on
/// to where it stays above the 95 % threshold).
const PROFILE_TOP: f64 = 10.0;

/// Each free key's profile: the rise of chi2 with the other keys refitted,
/// against the key, with the 68 % and 95 % thresholds.
fn profiles(problem: &Problem, answer: &Answer) -> Vec<FitPanel> {
    problem
        .free
        .iter()
        .zip(&answer.profiles)
        .map(|(free, walked)| {
            let curve: Vec<(f64, f64)> = walked
                .iter()
                .filter(|(_, rise)| rise.is_finite())
                .map(|&(u, rise)| (free.value(u), rise.min(PROFILE_TOP)))
                .collect();
            let (lo, hi) = curve
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                    (a.min(p.0), b.max(p.0))
                });
            let level = |label: &str, rise: f64| FitSeries {
                label: label.into(),
                points: Vec::new(),
                curve: vec![(lo, rise), (hi, rise)],
            };
            FitPanel {
                title: format!("profile of {}", free.key),
                x_label: format!("{} [{}]", free.key, free.units),
                y_label: "rise of chi2, others refitted".into(),
                series: vec![
                    FitSeries {
                        label: "profile".into(),
                        points: curve.iter().map(|&(x, y)| (x, y, 0.0)).collect(),
                        curve,
                    },
                    level(
                        &format!("68 %: rise {:.3}", answer.thresholds[0]),
                        answer.thresholds[0],
                    ),
                    level(
                        &format!("95 %: rise {:.3}", answer.thresholds[1]),
                        answer.thresholds[1],
                    ),
                ],
            }
        })
        .collect()
}

/// The distinct values of key column `k`.
fn distinct(problem: &Problem, k: usize) -> Vec<f64> {
    let mut values: Vec<f64> = problem.data.rows.iter().map(|r| r.keys[k]).collect();
    values.sort_by(f64::total_cmp);
    values.dedup();
    values
}

/// The rows grouped by every key but `x_key`: each group's keys and rows.
type Group = (Vec<(String, f64)>, Vec<usize>);

fn groups(problem: &Problem, x_key: Option<usize>) -> Vec<Group> {
    let mut groups: Vec<Group> = Vec::new();
    for (i, row) in problem.data.rows.iter().enumerate() {
        let keys: Vec<(String, f64)> = problem
            .row_keys(row)
            .into_iter()
            .filter(|(k, _)| x_key.is_none_or(|x| *k != problem.data.keys[x]))
            .collect();
        match groups.iter_mut().find(|g| g.0 == keys) {
            Some(group) => group.1.push(i),
            None => groups.push((keys, vec![i])),
        }
    }
    groups
}

/// A curve's points: its group's keys and `x_key` across the data's range
/// (the rows themselves when there is no key to run along).
fn curve_points(
    problem: &Problem,
    x_key: Option<usize>,
    keys: &[(String, f64)],
) -> Vec<Vec<(String, f64)>> {
    let Some(x) = x_key else {
        return vec![keys.to_vec()];
    };
    let values = distinct(problem, x);
    let (lo, hi) = (values[0], values[values.len() - 1]);
    (0..CURVE_POINTS)
        .map(|i| {
            let v = lo + (hi - lo) * i as f64 / (CURVE_POINTS - 1) as f64;
            let mut point = keys.to_vec();
            point.push((problem.data.keys[x].clone(), v));
            point
        })
        .collect()
}

/// One axis' panel, steps in micrometres per own drive cycle.
fn panel(
    problem: &Problem,
    answer: &Answer,
    axis: usize,
    x_key: Option<usize>,
    groups: &[Group],
    curves: &[Option<super::problem::RowModel>],
) -> FitPanel {
    let data = &problem.data;
    let per_curve = if x_key.is_some() { CURVE_POINTS } else { 1 };
    let x_of = |row: usize| match x_key {
        Some(x) => data.rows[row].keys[x],
        None => row as f64 + 1.0,
    };
    let series = groups.iter().enumerate().map(|(g, (keys, rows))| {
        let points = rows
            .iter()
            .filter_map(|&r| {
                let step = data.rows[r].step[axis]?;
                let se = answer.weights.data_se(data.rows[r].se[axis], axis);
                Some((x_of(r), step * 1e6, se * 1e6))
            })
            .collect();
        let curve = match x_key {
            Some(x) => {
                let start = g * per_curve;
                let values = distinct(problem, x);
                (0..per_curve)
                    .filter_map(|i| {
                        let model = curves[start + i]?;
                        let v = values[0]
                            + (values[values.len() - 1] - values[0]) * i as f64
                                / (per_curve - 1) as f64;
                        Some((v, model.step[axis] * 1e6))
                    })
                    .collect()
            }
            None => rows
                .iter()
                .map(|&r| (x_of(r), answer.models[r].step[axis] * 1e6))
                .collect(),
        };
        let label = keys
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect::<Vec<_>>()
            .join(", ");
        FitSeries {
            label: if label.is_empty() {
                "data and model".into()
            } else {
                label
            },
            points,
            curve,
        }
    });
    FitPanel {
        title: format!("step {} (data ± se, fitted model)", AXIS_NAMES[axis]),
        x_label: x_key.map_or("row".into(), |x| {
            let key = &data.keys[x];
            let units = crate::scene::instance_key(key).unwrap_or("");
            format!("{key} [{units}]")
        }),
        y_label: format!("step {} [um per cycle]", AXIS_NAMES[axis]),
        series: series.collect(),
    }
}
