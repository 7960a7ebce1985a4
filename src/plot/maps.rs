//! The maps of a grid with two or more axes: step, ratio and regime
//! heatmaps for every 2-D slice.

use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::style::RGBColor;

use super::MAX_SLICES;
use super::colour::{Diverging, FAILED, NOT_STEADY, UNDEFINED};
use super::heatmap::{MapLegend, heatmap};
use super::read::{AxisData, Data};
use super::regime::{Regime, ZERO_STEP_M};
use super::text::{short, with_unit};
use crate::cpu::integrate::constants::STATUS_NOT_STEADY;
use crate::model::AXIS_NAMES;

/// The two dimensions a grid's pictures span: those with the most values
/// (the earlier on ties), in grid order.
pub fn plane_dims(shape: &[usize]) -> (usize, usize) {
    let mut dims: Vec<usize> = (0..shape.len()).collect();
    dims.sort_by_key(|&d| std::cmp::Reverse(shape[d]));
    let (a, b) = (dims[0], dims[1]);
    (a.min(b), a.max(b))
}

/// The combinations of indices of the dimensions of sizes `rest` to draw
/// (all, or [`MAX_SLICES`] evenly spaced ones), and how many there are.
fn slices(rest: &[usize]) -> (Vec<Vec<usize>>, usize) {
    let total: usize = rest.iter().product();
    let chosen: Vec<usize> = if total <= MAX_SLICES {
        (0..total).collect()
    } else {
        (0..MAX_SLICES)
            .map(|k| k * (total - 1) / (MAX_SLICES - 1))
            .collect()
    };
    let combos = chosen
        .into_iter()
        .map(|mut flat| {
            let mut idx = vec![0; rest.len()];
            for d in (0..rest.len()).rev() {
                idx[d] = flat % rest[d];
                flat /= rest[d];
            }
            idx
        })
        .collect();
    (combos, total)
}

/// The per-axis words for map titles.
fn per_cycle(axis: usize) -> String {
    format!("µm per {} drive cycle", AXIS_NAMES[axis])
}

/// Writes the heatmaps of a grid with two or more axes.
pub(super) fn grid_maps(
    data: &Data,
    axes: &[AxisData],
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let shape = &data.shape;
    let (p, q) = plane_dims(shape);
    let rest: Vec<usize> = (0..shape.len()).filter(|&d| d != p && d != q).collect();
    let rest_shape: Vec<usize> = rest.iter().map(|&d| shape[d]).collect();
    let mut strides = vec![1; shape.len()];
    for d in (0..shape.len().saturating_sub(1)).rev() {
        strides[d] = strides[d + 1] * shape[d + 1];
    }
    let (combos, total) = slices(&rest_shape);
    if combos.len() < total {
        notes.push(format!(
            "{total} slices over {} per map; drew {} evenly spaced ones",
            rest.iter()
                .map(|&d| axes[d].key.as_str())
                .collect::<Vec<_>>()
                .join(" x "),
            combos.len()
        ));
    }
    let (n0, n1) = (shape[p], shape[q]);
    let (across, up) = (&axes[p], &axes[q]);
    for combo in &combos {
        let offset: usize = combo.iter().zip(&rest).map(|(&i, &d)| i * strides[d]).sum();
        let flat = |i: usize, j: usize| i * strides[p] + j * strides[q] + offset;
        let at: Vec<String> = combo
            .iter()
            .zip(&rest)
            .map(|(&i, &d)| {
                format!(
                    "{} = {}",
                    axes[d].key,
                    with_unit(axes[d].values[i], &axes[d].units)
                )
            })
            .collect();
        let suffix: String = combo
            .iter()
            .zip(&rest)
            .map(|(&i, &d)| format!("__{}={}", axes[d].key, short(axes[d].values[i])))
            .collect();
        let slice_line = if at.is_empty() {
            None
        } else {
            Some(format!("slice at {}", at.join(", ")))
        };
        let cells: Vec<usize> = (0..n0)
            .flat_map(|i| (0..n1).map(move |j| (i, j)))
            .map(|(i, j)| flat(i, j))
            .collect();
        let unsteady = cells
            .iter()
            .filter(|&&k| data.status[k] == STATUS_NOT_STEADY)
            .count();
        let failed = cells.iter().filter(|&&k| data.status[k] != 0).count() - unsteady;
        let failed_line = (failed > 0).then(|| {
            format!(
                "dark grey: {failed} of {} instances ended with a non-zero status (see \
                 /maps/status); no value is drawn",
                cells.len()
            )
        });
        let unsteady_line = (unsteady > 0).then(|| {
            format!(
                "light grey: {unsteady} of {} instances did not converge by max_cycles (status \
                 6); their estimates and standard errors are in the file, not drawn",
                cells.len()
            )
        });
        for axis in 0..2 {
            let steps_um: Vec<f64> = cells
                .iter()
                .filter(|&&k| data.status[k] == 0)
                .map(|&k| data.step[axis][k] * 1e6)
                .collect();
            let scale = Diverging::covering(steps_um, 0.0, ZERO_STEP_M * 1e6, f64::INFINITY);
            let mut title = vec![
                format!(
                    "{}: slider step along {} (2-DOF) [{}]",
                    data.name,
                    AXIS_NAMES[axis],
                    per_cycle(axis)
                ),
                format!(
                    "red: moves towards +{a}, blue: towards -{a}, white: no motion; symmetric \
                     colour limits ±{} µm",
                    short(scale.half_width),
                    a = AXIS_NAMES[axis]
                ),
            ];
            title.extend(slice_line.clone());
            title.extend(failed_line.clone());
            title.extend(unsteady_line.clone());
            let path = dir.join(format!("step_{}{suffix}.png", AXIS_NAMES[axis]));
            let mut swatches = Vec::new();
            if failed > 0 {
                swatches.push((FAILED, "not computed (status ≠ 0, 6)".to_owned()));
            }
            if unsteady > 0 {
                swatches.push((NOT_STEADY, "not steady (status 6)".to_owned()));
            }
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| {
                    let k = flat(i, j);
                    match data.status[k] {
                        0 => scale.colour(data.step[axis][k] * 1e6),
                        STATUS_NOT_STEADY => NOT_STEADY,
                        _ => FAILED,
                    }
                },
                &MapLegend::Bar {
                    scale,
                    title: format!("step along {} [{}]", AXIS_NAMES[axis], per_cycle(axis)),
                    swatches,
                },
            )?;
            files.push(path);

            if let Some(se) = &data.step_se {
                // Status 6 ("not steady") keeps its estimate's error too.
                let shown = |k: usize| data.status[k] == 0 || data.status[k] == STATUS_NOT_STEADY;
                let errors_um: Vec<f64> = cells
                    .iter()
                    .filter(|&&k| shown(k))
                    .map(|&k| se[axis][k] * 1e6)
                    .collect();
                if errors_um.iter().any(|&e| e > 0.0) {
                    let escale = Diverging::covering(errors_um, 0.0, 1e-3, f64::INFINITY);
                    let hidden = cells.iter().filter(|&&k| !shown(k)).count();
                    let mut title = vec![
                        format!(
                            "{}: standard error of the step along {} [{}]",
                            data.name,
                            AXIS_NAMES[axis],
                            per_cycle(axis)
                        ),
                        format!(
                            "white: exact (the motion repeats); red: the statistical error of a \
                             motion that does not; colour limit {} µm",
                            short(escale.half_width)
                        ),
                    ];
                    title.extend(slice_line.clone());
                    if hidden > 0 {
                        title.push(format!(
                            "grey: {hidden} of {} instances failed (see /maps/status)",
                            cells.len()
                        ));
                    }
                    let path = dir.join(format!("step_{}_se{suffix}.png", AXIS_NAMES[axis]));
                    let mut swatches = Vec::new();
                    if hidden > 0 {
                        swatches.push((FAILED, "failed (status ≠ 0, 6)".to_owned()));
                    }
                    heatmap(
                        &path,
                        &title,
                        across,
                        up,
                        &|i, j| {
                            let k = flat(i, j);
                            if shown(k) {
                                escale.colour(se[axis][k] * 1e6)
                            } else {
                                FAILED
                            }
                        },
                        &MapLegend::Bar {
                            scale: escale,
                            title: format!(
                                "standard error along {} [{}]",
                                AXIS_NAMES[axis],
                                per_cycle(axis)
                            ),
                            swatches,
                        },
                    )?;
                    files.push(path);
                }
            }

            let Some((base, base_status)) = &data.baseline else {
                continue;
            };
            let ok = |k: usize| data.status[k] == 0 && base_status[k] == 0;
            let ratio = |k: usize| {
                let one = base[axis][k];
                if ok(k) && one.abs() >= ZERO_STEP_M {
                    Some(data.step[axis][k] / one)
                } else {
                    None
                }
            };
            let ratios: Vec<f64> = cells.iter().filter_map(|&k| ratio(k)).collect();
            let rscale = Diverging::covering(ratios.iter().copied(), 1.0, 0.25, RATIO_HALF_WIDTH);
            let other = AXIS_NAMES[1 - axis];
            let a = AXIS_NAMES[axis];
            let mut title = vec![
                format!(
                    "{}: 2-DOF step / 1-DOF step along {a} (the effect of driving {other} too)",
                    data.name
                ),
                format!(
                    "1-DOF: {a} driven alone at the same settings. White = 1 (unchanged), red > 1 \
                     amplified, blue < 1 reduced, below 0 reversed"
                ),
                format!(
                    "colour limits {} to {}{}",
                    short(rscale.limits().0),
                    short(rscale.limits().1),
                    if ratios.iter().any(|r| (r - 1.0).abs() > rscale.half_width) {
                        " (values beyond are drawn at the ends)"
                    } else {
                        ""
                    }
                ),
            ];
            title.extend(slice_line.clone());
            let path = dir.join(format!("ratio_{a}{suffix}.png"));
            let mut swatches = vec![(UNDEFINED, "1-DOF step < 0.001 µm: no ratio".to_owned())];
            if cells.iter().any(|&k| !ok(k)) {
                swatches.push((FAILED, "not computed (status ≠ 0)".to_owned()));
            }
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| {
                    let k = flat(i, j);
                    match ratio(k) {
                        Some(r) => rscale.colour(r),
                        None if ok(k) => UNDEFINED,
                        None => FAILED,
                    }
                },
                &MapLegend::Bar {
                    scale: rscale,
                    title: format!("2-DOF step / 1-DOF step along {a}"),
                    swatches,
                },
            )?;
            files.push(path);

            let regime = |k: usize| Regime::classify(data.step[axis][k], base[axis][k], ok(k));
            let mut counts = [0usize; Regime::ALL.len()];
            for &k in &cells {
                if let Some(r) = Regime::ALL.iter().position(|&r| r == regime(k)) {
                    counts[r] += 1;
                }
            }
            let items: Vec<(RGBColor, String)> = Regime::ALL
                .iter()
                .zip(counts)
                .filter(|(_, n)| *n > 0)
                .map(|(r, n)| (r.colour(), format!("{} ({n})", r.describe())))
                .collect();
            let mut title = vec![
                format!(
                    "{}: how driving {other} changes the motion along {a}",
                    data.name
                ),
                format!(
                    "each cell compares the 2-DOF step along {a} with the 1-DOF step ({a} driven \
                     alone);"
                ),
                "a step below 0.001 µm counts as no motion. Counts of instances in brackets."
                    .to_owned(),
            ];
            title.extend(slice_line.clone());
            let path = dir.join(format!("regime_{a}{suffix}.png"));
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| regime(flat(i, j)).colour(),
                &MapLegend::Categories(items),
            )?;
            files.push(path);
        }
    }
    Ok(())
}

/// Ratio colour scales reach at most this far from 1.
const RATIO_HALF_WIDTH: f64 = 3.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pictures_span_the_two_longest_axes() {
        let cases: [(&[usize], (usize, usize)); 5] = [
            (&[3, 4], (0, 1)),
            (&[61, 61], (0, 1)),
            (&[2, 13, 8], (1, 2)),
            (&[13, 2, 8], (0, 2)),
            (&[5, 5, 5, 9], (0, 3)),
        ];
        for (shape, want) in cases {
            assert_eq!(plane_dims(shape), want, "{shape:?}");
        }
    }
}
